"""The Agilent (HP) 35670A in swept-sine mode: settings, one call per measurement, data.

Facts used here come from ``shared/docs/35670a.md``; those marked *inferred* there are gathered
in :class:`Quirks` (:mod:`agilent35670a.quirks`) so they can be checked on hardware and changed in
one place. What a measurement returns: :mod:`agilent35670a.segment`.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterable, Mapping

import numpy as np

from .blocks import (
    check_axis,
    check_values,
    decode_ascii,
    decode_real,
    interleaved_to_complex,
    split_definite_block,
)
from .channel import InputChannel
from .connection import Connection
from .errors import (
    ConnectionLost,
    InstrumentError,
    InstrumentTimeout,
    MalformedReply,
    MeasurementAborted,
    MissingOption,
    SCPIError,
    SettingOutOfRange,
    WrongInstrument,
    parse_error_entry,
)
from .properties import (
    boolean,
    control,
    integer_range,
    measurement,
    number_text,
    on_off_text,
    one_of,
    parse_bool,
    parse_channel,
    parse_float,
    parse_int,
    parse_keyword,
    setting,
    strict_range,
)
from .quirks import Quirks
from .segment import SweepProgress, SweepSegment
from .validators import (
    check_data_format,
    check_feed,
    check_frequency,
    check_reference_channel,
    unit_text,
)

__all__ = ["Agilent35670A", "Quirks", "SweepProgress", "SweepSegment", "check_feed"]

#: Most points in one swept-sine sweep.
MAX_POINTS = 801
#: Highest frequency with two channels, and with the four-channel option (Hz).
MAX_FREQUENCY_HZ = 51200.0
MAX_FREQUENCY_FOUR_CHANNELS_HZ = 25600.0
#: Highest source level (volts peak).
MAX_SOURCE_VPK = 5.0
#: ``*ESR?`` bits: operation complete, and the four error bits (query, device, execution, command).
ESR_OPERATION_COMPLETE = 1
ESR_ERRORS = 4 | 8 | 16 | 32
#: First wait between ``*ESR?`` polls (s); the wait doubles up to ``poll_interval_s``.
FIRST_POLL_S = 0.001
#: ``STAT:OPER:COND?`` bits.
OPERATION_SETTLING, OPERATION_RANGING, OPERATION_MEASURING = 2, 4, 16


class Agilent35670A:
    """Agilent (HP) 35670A dynamic signal analyser, swept-sine subset.

    Open with :meth:`open` (any pyvisa resource string). Settings are attributes: assigning one
    validates it against the manual's range (nothing is sent if it is out of range), writes it
    and checks the error queue, raising :class:`SCPIError` if the analyser refused it.

    Parameters
    ----------
    connection
        An open :class:`Connection`.
    """

    label = "35670A"
    placeholders: Mapping[str, object] = {}

    # -- mode (INSTrument) ---------------------------------------------------------------------
    instrument_mode = control(
        "INST:SEL {value}",
        "INST:SEL?",
        """Measurement mode: ``"SINE"`` (swept sine, option 1D2) or ``"FFT"`` (power-up mode).""",
        validator=one_of(("SINE", "FFT")),
        parse=parse_keyword,
    )
    # -- frequency span and grid (SENSe:FREQuency) ---------------------------------------------
    start_frequency_hz = control(
        "FREQ:STAR {value} HZ",
        "FREQ:STAR?",
        """Sweep start frequency in Hz, above 0 and up to 51.2 kHz (25.6 kHz with four
        channels); the analyser rounds it to 15.625 mHz.""",
        validator=check_frequency,
        to_text=number_text,
        parse=parse_float,
    )
    stop_frequency_hz = control(
        "FREQ:STOP {value} HZ",
        "FREQ:STOP?",
        """Sweep stop frequency in Hz, same range as :attr:`start_frequency_hz`.""",
        validator=check_frequency,
        to_text=number_text,
        parse=parse_float,
    )
    manual_frequency_hz = control(
        "FREQ:MAN {value} HZ",
        "FREQ:MAN?",
        """Frequency measured in manual sweep mode, in Hz (same range as the start).""",
        validator=check_frequency,
        to_text=number_text,
        parse=parse_float,
    )
    resolution_hz = setting(
        "FREQ:RES {value} HZ",
        """Linear sweep resolution in Hz (point spacing), above 0 up to 51.2 kHz; LIN only.""",
        validator=strict_range(0.0, MAX_FREQUENCY_HZ, "Hz", low_inclusive=False),
    )
    points_per_sweep = setting(
        "FREQ:RES {value} PNT/SWP",
        """Points per sweep, 2 to 801 (preset 101).""",
        validator=integer_range(2, MAX_POINTS, "points"),
        to_text=str,
    )
    auto_resolution = control(
        "FREQ:RES:AUTO {value}",
        "FREQ:RES:AUTO?",
        """Auto resolution (bool); must be off for a fixed grid such as 0.25 Hz.""",
        validator=boolean,
        to_text=on_off_text,
        parse=parse_bool,
    )
    # -- sweep timing, order, pairing (SENSe:SWEep, SENSe:REFerence) ---------------------------
    settle_cycles = setting(
        "SWE:STIM {value}",
        """Settle time after each frequency change, in cycles of the source, 0 to 1e6.""",
        validator=strict_range(0.0, 1e6, "cycles"),
        to_text=unit_text("CYCLE"),
    )
    settle_s = setting(
        "SWE:STIM {value}",
        """Settle time after each frequency change, in seconds, 0 to 1e5.""",
        validator=strict_range(0.0, 1e5, "s"),
        to_text=unit_text("S"),
    )
    integrate_cycles = setting(
        "SWE:DWEL {value}",
        """Integration (dwell) time per point in cycles, 1 to 1e6 (and at least 250 µs).""",
        validator=strict_range(1.0, 1e6, "cycles"),
        to_text=unit_text("CYCLE"),
    )
    integrate_s = setting(
        "SWE:DWEL {value}",
        """Integration (dwell) time per point in seconds, 250 µs to 1e5 s.""",
        validator=strict_range(250e-6, 1e5, "s"),
        to_text=unit_text("S"),
    )
    spacing = control(
        "SWE:SPAC {value}",
        "SWE:SPAC?",
        """Point spacing: ``"LIN"`` or ``"LOG"`` (preset LIN).""",
        validator=one_of(("LIN", "LOG")),
        parse=parse_keyword,
    )
    direction = control(
        "SWE:DIR {value}",
        "SWE:DIR?",
        """Sweep direction: ``"UP"`` or ``"DOWN"`` (preset UP).""",
        validator=one_of(("UP", "DOWN")),
        parse=parse_keyword,
    )
    sweep_mode = control(
        "SWE:MODE {value}",
        "SWE:MODE?",
        """``"AUTO"`` sweeps start to stop; ``"MAN"`` measures only :attr:`manual_frequency_hz`.""",
        validator=one_of(("AUTO", "MAN")),
        parse=parse_keyword,
    )
    reference_pairing = control(
        "REF {value}",
        "REF?",
        """``"PAIR"``: channel 1 is the reference of 2 and channel 3 of 4; ``"SING"``: channel 1
        is the reference of all.""",
        validator=one_of(("PAIR", "SING")),
        parse=parse_keyword,
    )
    # -- data format of trace queries (FORMat) -------------------------------------------------
    data_format = control(
        "FORM {value}",
        "FORM?",
        """Data format of trace queries: ``"REAL,64"`` (default here), ``"REAL,32"``, ``"ASC"``
        or ``"ASC,<3..12 digits>"``.""",
        validator=check_data_format,
        parse=parse_keyword,
    )

    # -- source and auto level (OUTPut, SOURce) ------------------------------------------------
    source_enabled = control(
        "OUTP {value}",
        "OUTP?",
        """Source output on (bool). Refused (nothing sent) until :attr:`source_limit_vpk` has been
        set on this connection.""",
        validator=lambda value, analyser: analyser._check_source_switch(boolean(value, analyser)),
        to_text=on_off_text,
        parse=parse_bool,
    )
    source_level_vpk = setting(
        "SOUR:VOLT {value} VPK",
        """Source level in volts peak, 0 to 5 Vpk (with auto level: the starting level). A 0 V
        level pauses the measurement with error -221.""",
        validator=strict_range(0.0, MAX_SOURCE_VPK, "Vpk"),
        to_text=number_text,
    )
    source_limit_vpk = setting(
        "SOUR:VOLT:LIM {value} VPK",
        """Highest source level the auto-level controller may use, volts peak, above 0 up to
        5 Vpk (preset 2 Vpk).""",
        validator=strict_range(0.0, MAX_SOURCE_VPK, "Vpk", low_inclusive=False),
        to_text=number_text,
    )
    auto_level = control(
        "SOUR:VOLT:AUTO {value}",
        "SOUR:VOLT:AUTO?",
        """Auto level (bool): adjust the source so the reference channel holds the reference
        level.""",
        validator=boolean,
        to_text=on_off_text,
        parse=parse_bool,
    )
    auto_level_channel = control(
        "SOUR:VOLT:REF:CHAN INP{value}",
        "SOUR:VOLT:REF:CHAN?",
        """Channel (1..4) the auto-level controller holds at the reference level (preset 2).""",
        validator=check_reference_channel,
        parse=parse_channel,
    )
    auto_level_reference_eu = setting(
        "SOUR:VOLT:REF {value} EU",
        """Auto-level reference level in the reference channel's engineering unit (peak),
        above 0 up to 1e6.""",
        validator=strict_range(0.0, 1e6, "EU", low_inclusive=False),
        to_text=number_text,
    )
    auto_level_reference_vpk = setting(
        "SOUR:VOLT:REF {value} VPK",
        """Auto-level reference level in volts peak at the reference input, above 0 up to
        31.7 Vpk (the +27 dBVrms range).""",
        validator=strict_range(0.0, 31.7, "Vpk", low_inclusive=False),
        to_text=number_text,
    )
    auto_level_tolerance_db = setting(
        "SOUR:VOLT:REF:TOL {value}",
        """Auto-level tolerance in dB, 0.1 to 20 dB (preset 2 dB).""",
        validator=strict_range(0.1, 20.0, "dB"),
        to_text=number_text,
    )
    input_limit_eu = setting(
        "SOUR:VOLT:LIM:INP {value} EU",
        """Auto-level input limit in the limited channel's engineering unit (peak), above 0 up
        to 1e6: the controller keeps that input below it (the shaker force limit on channel 1).
        The manual names no unit or channel command; ``EU`` as for the reference level, and the
        limited channel is the analyser's preset (channel 1, inferred).""",
        validator=strict_range(0.0, 1e6, "EU", low_inclusive=False),
        to_text=number_text,
    )
    input_limit_vpk = setting(
        "SOUR:VOLT:LIM:INP {value} VPK",
        """Auto-level input limit in volts peak at the limited input, above 0 up to 31.7 Vpk.""",
        validator=strict_range(0.0, 31.7, "Vpk", low_inclusive=False),
        to_text=number_text,
    )
    source_slew_v_per_s = setting(
        "SOUR:VOLT:SLEW {value}",
        """Auto-level slew rate of the source, volts per second, above 0 up to 1000 V/s.""",
        validator=strict_range(0.0, 1000.0, "V/s", low_inclusive=False),
        to_text=number_text,
    )

    # -- read-only (*IDN?, STATus) -------------------------------------------------------------
    identity = measurement("*IDN?", """``*IDN?`` reply (names a 35670A).""")
    operation_condition = measurement(
        "STAT:OPER:COND?",
        """``STAT:OPER:COND?``: 2 settling, 4 ranging, 16 measuring.""",
        parse=parse_int,
    )

    # -- opening and closing ------------------------------------------------------------------
    def __init__(self, connection: Connection) -> None:
        self.connection = connection
        self.sent: dict[str, object] = {}
        self.channels = tuple(InputChannel(self, number) for number in range(1, 5))
        self._options: frozenset[str] | None = None
        self._abort = threading.Event()
        self._paused_since: float | None = None
        self._paused_total_s = 0.0

    @classmethod
    def open(
        cls,
        resource: str,
        *,
        adapter: str | None = None,
        gpib_address: int = 11,
        timeout_s: float = 5.0,
        backend: str | None = None,
    ) -> Agilent35670A:
        """Connect to a 35670A and check it is one (see :class:`Connection` for the arguments).

        Raises
        ------
        ConnectionLost
            The resource cannot be opened.
        WrongInstrument
            ``*IDN?`` does not name a 35670A.
        """
        connection = Connection(
            resource, adapter=adapter, gpib_address=gpib_address, timeout_s=timeout_s,
            backend=backend,
        )
        analyser = cls(connection)
        try:
            analyser.identify()
        except BaseException:
            connection.close()
            raise
        return analyser

    def close(self) -> None:
        """Close the connection."""
        self.connection.close()

    def __enter__(self) -> Agilent35670A:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def resource(self) -> str:
        """VISA resource string of the analyser."""
        return self.connection.resource_name

    def channel(self, number: int) -> InputChannel:
        """Input channel 1..4."""
        if number not in (1, 2, 3, 4):
            raise SettingOutOfRange(f"channel {number!r} is not 1..4")
        return self.channels[number - 1]

    # -- messages and errors -------------------------------------------------------------------
    def write(self, command: str) -> None:
        """Send a command as is (no error check)."""
        self.connection.write(command)

    def ask(self, command: str) -> str:
        """Send a query and return its reply (retried once only if idempotent)."""
        return self.connection.query(command)

    def configure(self, command: str) -> None:
        """Send a configuration command, then read the error queue and raise if it held any."""
        self.connection.write(command)
        self.check_errors(command)

    def read_errors(self) -> list[tuple[int, str]]:
        """Read ``SYST:ERR?`` until it answers no error; return the ``(code, text)`` entries."""
        entries: list[tuple[int, str]] = []
        for _ in range(Quirks.ERROR_QUEUE_READS):
            reply = self.connection.query("SYST:ERR?")
            code, text = parse_error_entry(reply, self.resource)
            if code == Quirks.NO_ERROR_CODE:
                return entries
            entries.append((code, text))
        raise MalformedReply(
            f"SYST:ERR? still reports errors after {Quirks.ERROR_QUEUE_READS} reads "
            f"(queue depth is 5): {entries}",
            self.resource,
        )

    def check_errors(self, after: str | None = None) -> None:
        """Raise :class:`SCPIError` (first error, the others attached) if the queue is not empty."""
        entries = self.read_errors()
        if entries:
            (code, text), *others = entries
            raise SCPIError(code, text, after, self.resource, tuple(others))

    # -- identity and options ------------------------------------------------------------------
    def identify(self) -> str:
        """Return ``*IDN?``, checking that it names a 35670A."""
        reply = self.identity
        if "35670A" not in reply.upper():
            raise WrongInstrument(f"*IDN? answered {reply!r}, which is not a 35670A", self.resource)
        return reply

    @property
    def options(self) -> frozenset[str]:
        """Installed option codes from ``*OPT?`` (read once per connection)."""
        if self._options is None:
            reply = self.ask("*OPT?").strip().strip('"')
            self._options = frozenset(
                code.strip().strip('"').upper() for code in reply.split(",") if code.strip()
            )
        return self._options

    def require_options(self, four_channels: bool = True) -> None:
        """Check for option 1D2 (swept sine) and, if ``four_channels``, AY6.

        Raises
        ------
        MissingOption
            Naming each missing option and what it is for.
        """
        needed = {"1D2": "swept-sine measurements"}
        if four_channels:
            needed["AY6"] = "channels 3 and 4"
        missing = tuple(code for code in needed if code not in self.options)
        if missing:
            what = "; ".join(f"option {code} ({needed[code]}) is not installed" for code in missing)
            installed = ", ".join(sorted(self.options)) or "none"
            raise MissingOption(f"{what}; *OPT? lists: {installed}", missing, self.resource)

    @property
    def max_frequency_hz(self) -> float:
        """Upper frequency limit: 25.6 kHz once option AY6 is known installed, else 51.2 kHz."""
        if self._options is not None and "AY6" in self._options:
            return MAX_FREQUENCY_FOUR_CHANNELS_HZ
        return MAX_FREQUENCY_HZ

    def _check_source_switch(self, on: bool) -> bool:
        if on and "source_limit_vpk" not in self.sent:
            raise SettingOutOfRange(
                "the source limit (source_limit_vpk) must be set before the source is switched on"
            )
        return on

    # -- the paper's test in one call ----------------------------------------------------------
    def configure_swept_sine(
        self,
        *,
        sensitivities_v_per_eu: Mapping[int, float],
        level_m_per_s2: float,
        source_limit_vpk: float,
        force_limit_n: float | None = None,
        reference_channel: int = 4,
        four_channels: bool = True,
        resolution_hz: float = 0.25,
        start_hz: float = 10.0,
        stop_hz: float = 60.0,
        settle_cycles: float = 100.0,
        integrate_cycles: float = 100.0,
        direction: str = "UP",
        tolerance_db: float = 2.0,
        start_level_vpk: float = 0.1,
        data_format: str = "REAL,64",
    ) -> None:
        """Set up the paper's swept-sine test; the source is left off.

        Swept-sine mode, channels 1..4 on with ``REF PAIR`` (1 → 2, 3 → 4), engineering units
        (channels 1 and 3 force in N, 2 and 4 acceleration in m/s²), autorange, a linear grid of
        ``resolution_hz`` with auto resolution off, settle and integration in cycles, auto level
        holding ``reference_channel`` at ``level_m_per_s2`` within ``tolerance_db``, the source
        limit, and optionally an input limit on the force channel for the shaker. Each step is
        validated before anything is sent and the error queue is checked after each.

        Parameters
        ----------
        sensitivities_v_per_eu
            Channel -> transducer sensitivity: V/N for channels 1 and 3, V/(m/s²) for 2 and 4.
        level_m_per_s2
            Reference acceleration amplitude (peak) held by the controller, m/s².
        source_limit_vpk
            Highest source level, volts peak (≤ 5); set before the source can be switched on.
        force_limit_n
            Shaker force limit (peak, N) applied as the auto-level input limit, which acts on
            channel 1, the excitation force (inferred); ``None`` for none.
        reference_channel
            Auto-level reference channel (4: the disc; 2 on a bare-table run).
        four_channels
            Use channels 3 and 4 (needs option AY6); else channels 1 and 2 only.
        resolution_hz, settle_cycles, integrate_cycles, direction, tolerance_db
            Sweep grid (Hz), settle and integration (cycles), ``"UP"``/``"DOWN"``, auto-level
            tolerance (dB).
        start_hz, stop_hz
            First band (Hz), set before the resolution because the analyser refuses a
            resolution that gives more than 801 points over the band in use; :meth:`measure`
            sets each segment's own band.
        start_level_vpk
            Source level the controller starts from (Vpk, ≤ ``source_limit_vpk``).
        data_format
            ``"REAL,64"``, falling back to ASCII if the analyser refuses it.
        """
        channels = (1, 2, 3, 4) if four_channels else (1, 2)
        missing = [ch for ch in channels if ch not in sensitivities_v_per_eu]
        if missing:
            raise SettingOutOfRange(f"no transducer sensitivity given for channel(s) {missing}")
        if reference_channel not in channels:
            raise SettingOutOfRange(f"reference channel {reference_channel} is not in use")
        strict_range(0.0, 1e6, "m/s²", low_inclusive=False)(level_m_per_s2, self)
        self._check_band(start_hz, stop_hz, resolution_hz)
        strict_range(0.0, MAX_SOURCE_VPK, "Vpk", low_inclusive=False)(source_limit_vpk, self)
        if not 0.0 < start_level_vpk <= source_limit_vpk:
            raise SettingOutOfRange(
                f"start level {start_level_vpk:g} Vpk must be above 0 and at most the source "
                f"limit {source_limit_vpk:g} Vpk"
            )

        self.identify()
        self.require_options(four_channels)
        self.source_enabled = False
        self.instrument_mode = "SINE"
        self.set_data_format(data_format)
        for number in (2, 3, 4):
            if number in channels:
                self.channel(number).enabled = True
            elif "AY6" in self.options:
                self.channel(number).enabled = False
        if four_channels:
            self.reference_pairing = "PAIR"
        for number in channels:
            label = "N" if number in (1, 3) else "M/S2"
            channel = self.channel(number)
            channel.set_engineering_units(label, sensitivities_v_per_eu[number])
            channel.autorange = True
        self.sweep_mode = "AUTO"
        self.spacing = "LIN"
        self.direction = direction
        self.auto_resolution = False
        self._set_band(start_hz, stop_hz)
        self.resolution_hz = resolution_hz
        self.settle_cycles = settle_cycles
        self.integrate_cycles = integrate_cycles
        # the limit always goes first: the source must never run without it
        self.source_limit_vpk = source_limit_vpk
        self.source_level_vpk = start_level_vpk
        self.auto_level_channel = reference_channel
        self.auto_level_reference_eu = level_m_per_s2
        self.auto_level_tolerance_db = tolerance_db
        if force_limit_n is not None:
            self.input_limit_eu = force_limit_n
        self.auto_level = True
        self.sent["channels"] = channels

    def set_data_format(self, data_format: str = "REAL,64") -> str:
        """Select the data format; if the analyser refuses ``REAL``, fall back to ``ASC,12``.

        Returns the format in use.
        """
        try:
            self.data_format = data_format
        except SCPIError:
            if not data_format.upper().startswith("REAL"):
                raise
            self.data_format = "ASC,12"
        return str(self.sent["data_format"])

    # -- running -------------------------------------------------------------------------------
    def measure(
        self,
        start_hz: float,
        stop_hz: float,
        *,
        progress: Callable[[SweepProgress], None] | None = None,
        timeout_s: float | None = None,
        poll_interval_s: float = 0.2,
        switch_source_off: bool = True,
    ) -> SweepSegment:
        """Measure the sub-band ``start_hz`` .. ``stop_hz`` on the configured grid.

        Sets start and stop, switches the source on, starts (``ABOR;:INIT:IMM``), waits by
        polling ``*ESR?`` (never blocking past the VISA timeout), then reads both frequency
        responses, the linear spectra and normalized variances of the channels in use, their
        frequency axis, and the overload latches.

        Parameters
        ----------
        start_hz, stop_hz
            Band in Hz; ``(stop - start) / resolution + 1`` must be at most 801 points.
        progress
            Called at each poll with a :class:`SweepProgress`; it may call :meth:`pause`,
            :meth:`resume` or :meth:`abort`.
        timeout_s
            Overall deadline in seconds (pauses excluded); default twice the settle and
            integration time from the settings plus 30 s.
        poll_interval_s
            Longest time between polls, in seconds. Polling is adaptive: the first poll comes
            :data:`FIRST_POLL_S` after the start and each wait doubles up to this interval, so
            a short segment (or a fast simulated analyser) is read back at once while a long
            one costs only a few extra ``*ESR?`` queries.
        switch_source_off
            Switch the source off when the segment ends (also after an error or abort).

        Raises
        ------
        MeasurementAborted, InstrumentTimeout, SCPIError, MalformedReply
        """
        resolution = self.sent.get("resolution_hz")
        if resolution is None:
            raise SettingOutOfRange("set resolution_hz (or call configure_swept_sine) first")
        start, stop, points = self._check_band(start_hz, stop_hz, float(resolution))
        self.sweep_mode = "AUTO"
        self._set_band(start, stop)
        self.resolution_hz = resolution
        grid = start + float(resolution) * np.arange(points)
        segment = self._run(grid, points, progress, timeout_s, poll_interval_s, switch_source_off)
        check_axis(segment.frequency_hz, grid, float(resolution), self.resource)
        return segment

    def measure_point(
        self,
        frequency_hz: float,
        *,
        progress: Callable[[SweepProgress], None] | None = None,
        timeout_s: float | None = None,
        poll_interval_s: float = 0.2,
        switch_source_off: bool = True,
    ) -> SweepSegment:
        """Measure one frequency in manual sweep mode (``SWE:MODE MAN``, ``FREQ:MAN``).

        The point is picked from the traces by the analyser's own frequency axis (the entry
        nearest ``frequency_hz``); arguments as in :meth:`measure`.
        """
        frequency = check_frequency(frequency_hz, self)
        self.sweep_mode = "MAN"
        self.manual_frequency_hz = frequency
        segment = self._run(
            np.array([frequency]), None, progress, timeout_s, poll_interval_s, switch_source_off
        )
        index = int(np.argmin(np.abs(segment.frequency_hz - frequency)))
        pick = slice(index, index + 1)
        return SweepSegment(
            frequency_hz=segment.frequency_hz[pick],
            frf_21=segment.frf_21[pick],
            frf_43=None if segment.frf_43 is None else segment.frf_43[pick],
            amplitude_eu={ch: values[pick] for ch, values in segment.amplitude_eu.items()},
            variance={ch: values[pick] for ch, values in segment.variance.items()},
            eu_labels=segment.eu_labels,
            overload_channels=segment.overload_channels,
            half_range_channels=segment.half_range_channels,
            started_at_s=segment.started_at_s,
            finished_at_s=segment.finished_at_s,
        )

    def _check_band(
        self, start_hz: float, stop_hz: float, resolution_hz: float
    ) -> tuple[float, float, int]:
        """Validate a band on a linear grid; return start, stop and the number of points."""
        start = check_frequency(start_hz, self)
        stop = check_frequency(stop_hz, self)
        if stop <= start:
            raise SettingOutOfRange(f"stop {stop:g} Hz must be above start {start:g} Hz")
        points = round((stop - start) / resolution_hz) + 1
        if points > MAX_POINTS:
            raise SettingOutOfRange(
                f"{start:g}..{stop:g} Hz at {resolution_hz:g} Hz is {points} points; "
                f"at most {MAX_POINTS} per sweep"
            )
        return start, stop, points

    def _set_band(self, start: float, stop: float) -> None:
        # Quirks.START_BELOW_STOP: write them in the order that keeps start < stop throughout
        current_stop = self.sent.get("stop_frequency_hz")
        if current_stop is None:
            current_stop = self.stop_frequency_hz
        if start >= float(current_stop):
            self.stop_frequency_hz = stop
            self.start_frequency_hz = start
        else:
            self.start_frequency_hz = start
            self.stop_frequency_hz = stop

    def _run(
        self,
        grid_hz: np.ndarray,
        points: int | None,
        progress: Callable[[SweepProgress], None] | None,
        timeout_s: float | None,
        poll_interval_s: float,
        switch_source_off: bool,
    ) -> SweepSegment:
        expected_s = self.expected_duration_s(grid_hz)
        deadline_s = 2.0 * expected_s + 30.0 if timeout_s is None else float(timeout_s)
        self._abort.clear()
        self._paused_since = None
        self._paused_total_s = 0.0
        self.ask("STAT:QUES:VOLT:EVEN?")  # reading clears the latches of the previous segment
        self.ask("*ESR?")  # and the event status register
        fault: BaseException | None = None
        try:
            self.source_enabled = True
            started = time.time()
            self.write("ABOR;:INIT:IMM;*OPC")
            self._wait(started, expected_s, deadline_s, progress, poll_interval_s)
            finished = time.time()
            return self._read_segment(points, started, finished)
        except BaseException as error:
            fault = error
            raise
        finally:
            if switch_source_off:
                self._switch_source_off(fault)

    def _switch_source_off(self, fault: BaseException | None) -> None:
        """Send ``OUTP OFF`` at the end of a segment, however it ended.

        After a lost connection or a timeout the session is reopened first: a write to a socket
        the peer has closed still "succeeds", so the source would stay on. No error-queue check
        here, and a failure does not replace the fault that ended the segment.
        """
        try:
            if isinstance(fault, ConnectionLost | InstrumentTimeout):
                self.connection.reconnect()
            self.write("OUTP OFF")
            self.sent["source_enabled"] = False
        except InstrumentError:
            if fault is None:
                raise

    def _wait(
        self,
        started: float,
        expected_s: float,
        deadline_s: float,
        progress: Callable[[SweepProgress], None] | None,
        poll_interval_s: float,
    ) -> None:
        wait_s = min(FIRST_POLL_S, poll_interval_s)
        while True:
            if self._abort.is_set():
                raise MeasurementAborted("the measurement was aborted", self.resource)
            status = parse_int(self.ask("*ESR?"))
            if status & ESR_ERRORS:
                self.check_errors("ABOR;:INIT:IMM;*OPC")
                raise SCPIError(0, f"*ESR? reported errors (ESR={status}) with an empty queue",
                                "*ESR?", self.resource)
            if status & ESR_OPERATION_COMPLETE:
                return
            now = time.time()
            paused_s = self._paused_total_s + (
                now - self._paused_since if self._paused_since is not None else 0.0
            )
            if now - started - paused_s > deadline_s:
                self.write("ABOR")
                raise InstrumentTimeout(
                    f"the measurement did not complete within {deadline_s:g} s "
                    f"(expected {expected_s:.1f} s of settle and integration); aborted",
                    self.resource,
                )
            if progress is not None:
                condition = self.operation_condition
                progress(
                    SweepProgress(
                        elapsed_s=now - started,
                        expected_s=expected_s,
                        paused=self._paused_since is not None,
                        settling=bool(condition & OPERATION_SETTLING),
                        ranging=bool(condition & OPERATION_RANGING),
                        measuring=bool(condition & OPERATION_MEASURING),
                    )
                )
            if not self._abort.is_set():
                time.sleep(wait_s)
                wait_s = min(2.0 * wait_s, poll_interval_s)

    def expected_duration_s(self, grid_hz: Iterable[float]) -> float:
        """Settle plus integration time of the given points from the settings sent (seconds)."""
        frequencies = np.asarray(list(grid_hz), dtype=float)
        total = 0.0
        for cycles_name, seconds_name in (
            ("settle_cycles", "settle_s"),
            ("integrate_cycles", "integrate_s"),
        ):
            if cycles_name in self.sent:
                total += float(np.sum(float(self.sent[cycles_name]) / frequencies))
            elif seconds_name in self.sent:
                total += float(self.sent[seconds_name]) * frequencies.size
        return total

    def pause(self) -> None:
        """Pause the running measurement (``INIT:CONT OFF``); the deadline stops counting."""
        self.write("INIT:CONT OFF")
        if self._paused_since is None:
            self._paused_since = time.time()

    def resume(self) -> None:
        """Resume a paused measurement (``INIT:CONT ON``)."""
        self.write("INIT:CONT ON")
        if self._paused_since is not None:
            self._paused_total_s += time.time() - self._paused_since
            self._paused_since = None

    def abort(self) -> None:
        """Stop the measurement (``ABOR``) and switch the source off; a waiting
        :meth:`measure` raises :class:`MeasurementAborted`."""
        self._abort.set()
        self.write("ABOR;:OUTP OFF")

    # -- data ----------------------------------------------------------------------------------
    def _read_segment(self, points: int | None, started: float, finished: float) -> SweepSegment:
        channels = tuple(self.sent.get("channels", (1, 2, 3, 4)))
        frequency_hz, frf_21 = self.read_trace("XFR:POW:RAT 2,1", points, with_axis=True)
        count = frequency_hz.size
        frf_43 = None
        if 3 in channels and 4 in channels:
            frf_43 = self.read_trace("XFR:POW:RAT 4,3", count)[1]
        amplitude = {ch: np.abs(self.read_trace(f"XFR:POW:LIN {ch}", count)[1]) for ch in channels}
        variance = {
            ch: self.read_trace(f"XFR:POW:VAR {ch}", count, real=True)[1] for ch in channels
        }
        overload, half_range = self.read_overload()
        labels = {
            ch: str(self.channel(ch).sent.get("transducer_label", "V")) for ch in channels
        }
        return SweepSegment(
            frequency_hz=frequency_hz,
            frf_21=frf_21,
            frf_43=frf_43,
            amplitude_eu=amplitude,
            variance=variance,
            eu_labels=labels,
            overload_channels=overload,
            half_range_channels=half_range,
            started_at_s=started,
            finished_at_s=finished,
        )

    def read_trace(
        self,
        feed: str,
        points: int | None = None,
        *,
        real: bool = False,
        with_axis: bool = False,
    ) -> tuple[np.ndarray | None, np.ndarray]:
        """Feed trace A with ``feed`` and read it untransformed through register D1.

        Parameters
        ----------
        feed
            A swept-sine feed: ``"XFR:POW:RAT 2,1"``, ``"XFR:POW:LIN n"``, ``"XFR:POW:VAR n"``.
        points
            Expected number of points (``None``: any, then the axis or data decide).
        real
            The quantity is real (variance); else complex, read as (real, imag) pairs.
        with_axis
            Also read the frequency axis (``TRAC:X? D1``), in Hz.

        Returns
        -------
        (frequency_hz or None, values)
        """
        feed = check_feed(feed)
        self.configure(f"CALC1:FEED '{feed}';*WAI")
        self.configure("TRAC:DATA D1,TRAC1")
        axis = None
        if with_axis:
            axis = check_values(self.read_values("TRAC:X? D1"), "TRAC:X? D1", points)
            points = axis.size
        raw = self.read_values("TRAC:DATA? D1")
        what = f"TRAC:DATA? D1 ({feed})"
        if real:
            if Quirks.REAL_TRACE_MAY_BE_PAIRED and points is not None and raw.size == 2 * points:
                raw = raw[0::2]
            return axis, check_values(raw, what, points)
        return axis, interleaved_to_complex(raw, what, points)

    def read_values(self, query: str) -> np.ndarray:
        """Send a data query and decode its reply in the data format in use."""
        data_format = str(self.sent.get("data_format", "ASC"))
        if data_format.startswith("REAL"):
            message = self.connection.query_block(query)
            bits = int(data_format.split(",")[1])
            try:
                return decode_real(split_definite_block(message), bits, Quirks.REAL_BIG_ENDIAN)
            except MalformedReply as error:
                raise MalformedReply(f"{query!r}: {error.detail}", self.resource) from None
        try:
            return decode_ascii(self.ask(query))
        except MalformedReply as error:
            raise MalformedReply(f"{query!r}: {error.detail}", self.resource) from None

    def read_overload(self) -> tuple[tuple[int, ...], tuple[int, ...]]:
        """Read and clear ``STAT:QUES:VOLT:EVEN?``: (overloaded channels, half-range channels)."""
        bits = parse_int(self.ask("STAT:QUES:VOLT:EVEN?"))
        overload = tuple(ch for ch in range(1, 5) if bits & (1 << (ch - 1)))
        half_range = tuple(ch for ch in range(1, 5) if bits & (1 << (ch + 7)))
        return overload, half_range
