"""One input channel of the analyser (``INPn``, ``[SENSe:]VOLTn``): coupling, range, units."""

from __future__ import annotations

import math
from collections.abc import Iterable
from numbers import Integral
from typing import NamedTuple

from .errors import SettingOutOfRange
from .properties import (
    Parent,
    Subsystem,
    boolean,
    control,
    number_text,
    on_off_text,
    one_of,
    parse_bool,
    parse_float,
    parse_keyword,
    strict_range,
)

__all__ = ["TRANSDUCER_LABELS", "InputChannel", "InputSetting", "check_inputs", "range_dbvrms"]

#: Transducer labels of ``VOLTn:RANG:UNIT:XDCR:LAB`` (chapter 18). A whitelist: free text would
#: end up inside a SCPI message, where ``;`` or a quote could inject commands.
TRANSDUCER_LABELS = ("PA", "G", "M/S2", "M/S", "M", "KG", "N", "DYN", "INCH/S2", "INCH/S",
                     "INCH", "MIL", "LB")


def range_dbvrms(value: object, owner: object) -> float:
    """An input range: +27 down to -51 dBVrms in 2 dB steps (the analyser rounds others up,
    so the driver refuses them rather than let a range differ from the one asked for)."""
    number = strict_range(-51.0, 27.0, "dBVrms")(value, owner)
    index = (27.0 - number) / 2.0
    if abs(index - round(index)) > 1e-9:
        raise SettingOutOfRange(f"{number:g} dBVrms is not one of 27 to -51 dBVrms in 2 dB steps")
    return 27.0 - 2.0 * round(index)


def _label(value: object, owner: object) -> str:
    text = str(value).strip().upper()
    if text not in TRANSDUCER_LABELS:
        raise SettingOutOfRange(f"label {value!r} is not one of {', '.join(TRANSDUCER_LABELS)}")
    return text


class InputSetting(NamedTuple):
    """What one input measures: its number, engineering-unit label and transducer sensitivity.

    A plain tuple, so a caller can pass ``(1, "N", 0.01124)`` without importing this class.
    Which transducer sits on which input is the caller's (the rig's wiring); the driver only
    checks that the values are ones the analyser takes.

    Attributes
    ----------
    number
        The input, 1..4.
    label
        Engineering-unit label, one of :data:`TRANSDUCER_LABELS` (``"N"``, ``"M/S2"``...).
    sensitivity_v_per_eu
        Transducer sensitivity in V per unit of ``label``, 1e-9 to 1e6 V/EU.
    """

    number: int
    label: str
    sensitivity_v_per_eu: float


def check_inputs(inputs: Iterable[tuple[int, str, float]],
                 owner: object = None) -> tuple[InputSetting, ...]:
    """Validate input settings before anything is sent.

    Parameters
    ----------
    inputs
        ``(number, label, sensitivity_v_per_eu)`` for each input in use; input 1 (always on)
        must be among them, each input at most once.
    owner
        The part named in the messages.

    Returns
    -------
    tuple of InputSetting
        The settings, in input order, labels upper-cased.

    Raises
    ------
    SettingOutOfRange
        An input outside 1..4, repeated, input 1 missing, a label off the list or a
        sensitivity outside 1e-9..1e6 V/EU.
    """
    checked: dict[int, InputSetting] = {}
    for entry in inputs:
        try:
            number, label, sensitivity = entry
        except (TypeError, ValueError):
            raise SettingOutOfRange(
                f"input setting {entry!r} is not (number, label, sensitivity_v_per_eu)"
            ) from None
        if not isinstance(number, Integral) or isinstance(number, bool) or not 1 <= number <= 4:
            raise SettingOutOfRange(f"input {number!r} is not 1..4")
        number = int(number)
        if number in checked:
            raise SettingOutOfRange(f"input {number} is given twice")
        checked[number] = InputSetting(
            number, _label(label, owner),
            strict_range(1e-9, 1e6, "V/EU")(sensitivity, owner),
        )
    if 1 not in checked:
        raise SettingOutOfRange("input 1 (always on) has no setting")
    return tuple(checked[number] for number in sorted(checked))


class InputChannel(Subsystem):
    """Input channel ``number`` (1..4) of the analyser.

    Parameters
    ----------
    parent
        The analyser (settings go through its ``configure``, error queue checked).
    number
        The input, 1..4.
    """

    enabled = control(
        "INP{ch} {value}", "INP{ch}?",
        """Channel on (bool). Channel 1 is always on; channels 3 and 4 need option AY6 and go
        on and off together (four-channel mode).""",
        validator=boolean, to_text=on_off_text, parse=parse_bool,
    )
    coupling = control(
        "INP{ch}:COUP {value}", "INP{ch}:COUP?",
        """Input coupling: ``"AC"`` or ``"DC"`` (preset DC).""",
        validator=one_of(("AC", "DC")), parse=parse_keyword,
    )
    low_side = control(
        "INP{ch}:LOW {value}", "INP{ch}:LOW?",
        """Low side of the input: ``"GRO"`` grounded or ``"FLO"`` floating (preset FLO).""",
        validator=one_of(("GRO", "FLO")), parse=parse_keyword,
    )
    icp_bias = control(
        "INP{ch}:BIAS {value}", "INP{ch}:BIAS?",
        """ICP (constant-current) supply for accelerometers and force sensors (bool).""",
        validator=boolean, to_text=on_off_text, parse=parse_bool,
    )
    range_dbvrms = control(
        "VOLT{ch}:RANG {value} DBVRMS", "VOLT{ch}:RANG?",
        """Fixed input range in dBVrms: +27 down to -51 in 2 dB steps. Turns autorange off.""",
        validator=range_dbvrms, to_text=number_text, parse=parse_float, unit="DBVRMS",
        implies={"autorange": False},
    )
    autorange = control(
        "VOLT{ch}:RANG:AUTO {value}", "VOLT{ch}:RANG:AUTO?",
        """Autorange (bool); in swept sine the analyser re-ranges at every point.""",
        validator=boolean, to_text=on_off_text, parse=parse_bool,
        implies={"range_dbvrms": None},
    )
    transducer_label = control(
        "VOLT{ch}:RANG:UNIT:XDCR:LAB {value}", "VOLT{ch}:RANG:UNIT:XDCR:LAB?",
        f"""Engineering-unit label, one of {", ".join(TRANSDUCER_LABELS)}.""",
        validator=_label, parse=parse_keyword,
    )
    sensitivity_v_per_eu = control(
        "VOLT{ch}:RANG:UNIT:USER:SFAC {value} V/EU", "VOLT{ch}:RANG:UNIT:USER:SFAC?",
        """Transducer sensitivity in volts per engineering unit, 1e-9 to 1e6 V/EU.""",
        validator=strict_range(1e-9, 1e6, "V/EU"), to_text=number_text, parse=parse_float,
        tolerance=1e-9,
    )
    user_units = control(
        "VOLT{ch}:RANG:UNIT:USER {value}", "VOLT{ch}:RANG:UNIT:USER?",
        """Show this channel in engineering units (bool); set label and sensitivity first.""",
        validator=boolean, to_text=on_off_text, parse=parse_bool,
    )

    def __init__(self, parent: Parent, number: int) -> None:
        super().__init__(parent, f"channel {number}", ch=number)
        self.number = number

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

    def range_in_use_dbvrms(self) -> float:
        """The range the analyser uses now (after autorange), dBVrms."""
        reply = self.ask(f"VOLT{self.number}:RANG?")
        unit = self.ask(f"VOLT{self.number}:RANG? UNIT").strip().strip('"').upper()
        value = parse_float(reply)
        if unit == "DBVRMS":
            return value
        if unit in ("VPK", "V"):
            return 20 * math.log10(value / math.sqrt(2.0))
        if unit == "VRMS":
            return 20 * math.log10(value)
        if unit in ("DBVPK", "DBV"):
            return value - 20 * math.log10(math.sqrt(2.0))
        raise SettingOutOfRange(f"{self.label}: range reported in {unit}, not a voltage unit")
