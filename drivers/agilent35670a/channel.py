"""One input channel of the analyser (``INPn``, ``VOLTn``): coupling, range, engineering units."""

from __future__ import annotations

from typing import TYPE_CHECKING

from .errors import SettingOutOfRange
from .properties import (
    boolean,
    control,
    number_text,
    on_off_text,
    one_of,
    parse_bool,
    setting,
    stepped_range,
    strict_range,
)

if TYPE_CHECKING:
    from .instrument import Agilent35670A

#: Transducer labels the driver will send (``VOLTn:RANG:UNIT:XDCR:LAB``). A whitelist: free text
#: would end up inside a SCPI message, where ``;`` or a quote could inject commands.
TRANSDUCER_LABELS = ("N", "LB", "M/S2", "G", "IN/S2", "M/S", "IN/S", "M", "IN", "PA", "PSI", "V")


def _label(value: object, owner: object) -> str:
    text = str(value).strip().upper()
    if text not in TRANSDUCER_LABELS:
        raise SettingOutOfRange(f"label {value!r} is not one of {', '.join(TRANSDUCER_LABELS)}")
    return text


class InputChannel:
    """Input channel ``number`` (1..4) of an :class:`Agilent35670A`.

    Settings are written through the analyser (error queue checked after each one).
    """

    enabled = control(
        "INP{ch} {value}",
        "INP{ch}?",
        """Channel on (bool). Channel 1 is always on; channels 3 and 4 need option AY6.""",
        validator=boolean,
        to_text=on_off_text,
        parse=parse_bool,
    )
    coupling = control(
        "INP{ch}:COUP {value}",
        "INP{ch}:COUP?",
        """Input coupling: ``"AC"`` or ``"DC"`` (preset DC).""",
        validator=one_of(("AC", "DC")),
    )
    low_side = control(
        "INP{ch}:LOW {value}",
        "INP{ch}:LOW?",
        """Low side of the input: ``"GRO"`` grounded or ``"FLO"`` floating (preset FLO).""",
        validator=one_of(("GRO", "FLO")),
    )
    icp_bias = control(
        "INP{ch}:BIAS {value}",
        "INP{ch}:BIAS?",
        """ICP (constant-current) supply for accelerometers and force sensors (bool).""",
        validator=boolean,
        to_text=on_off_text,
        parse=parse_bool,
    )
    range_dbvrms = setting(
        "VOLT{ch}:RANG {value} DBVRMS",
        """Fixed input range in dBVrms: +27 down to -51 in 2 dB steps. Turns autorange off.""",
        validator=stepped_range(27.0, -51.0, 2.0, "dBVrms"),
    )
    autorange = control(
        "VOLT{ch}:RANG:AUTO {value}",
        "VOLT{ch}:RANG:AUTO?",
        """Autorange (bool); in swept sine the analyser re-ranges at every point.""",
        validator=boolean,
        to_text=on_off_text,
        parse=parse_bool,
    )
    transducer_label = setting(
        "VOLT{ch}:RANG:UNIT:XDCR:LAB {value}",
        f"""Engineering-unit label, one of {", ".join(TRANSDUCER_LABELS)}.""",
        validator=_label,
        to_text=str,
    )
    sensitivity_v_per_eu = setting(
        "VOLT{ch}:RANG:UNIT:USER:SFAC {value} V/EU",
        """Transducer sensitivity in volts per engineering unit, 1e-9 to 1e6 V/EU.""",
        validator=strict_range(1e-9, 1e6, "V/EU"),
        to_text=number_text,
    )
    user_units = control(
        "VOLT{ch}:RANG:UNIT:USER {value}",
        "VOLT{ch}:RANG:UNIT:USER?",
        """Show this channel in engineering units (bool); set label and sensitivity first.""",
        validator=boolean,
        to_text=on_off_text,
        parse=parse_bool,
    )

    def __init__(self, analyser: Agilent35670A, number: int) -> None:
        self.analyser = analyser
        self.number = number
        self.placeholders = {"ch": number}
        self.label = f"channel {number}"
        self.sent: dict[str, object] = {}

    def ask(self, command: str) -> str:
        """Query through the analyser."""
        return self.analyser.ask(command)

    def configure(self, command: str) -> None:
        """Write a setting through the analyser and check its error queue."""
        self.analyser.configure(command)

    def set_engineering_units(self, label: str, sensitivity_v_per_eu: float) -> None:
        """Label, then sensitivity, then user units on (the order the manual gives).

        Parameters
        ----------
        label
            One of :data:`TRANSDUCER_LABELS` (``"N"``, ``"M/S2"``...).
        sensitivity_v_per_eu
            Transducer sensitivity in V per unit of ``label`` (V/N, V/(m/s²)).
        """
        _label(label, self)
        strict_range(1e-9, 1e6, "V/EU")(sensitivity_v_per_eu, self)
        self.transducer_label = label
        self.sensitivity_v_per_eu = sensitivity_v_per_eu
        self.user_units = True
