"""The Agilent (HP) 35670A: its parts, and one call per measurement.

The analyser is put together from small parts, each with its own settings, in the manner of
PyMeasure's channels: :attr:`Agilent35670A.channels` (inputs), :attr:`~Agilent35670A.sweep`
(the swept sine's band, grid and timing), :attr:`~Agilent35670A.source` (level, limits, auto
level), :attr:`~Agilent35670A.fft` and :attr:`~Agilent35670A.fft_source` (FFT mode),
:attr:`~Agilent35670A.traces` (data), :attr:`~Agilent35670A.status` (errors, registers) and
:attr:`~Agilent35670A.runner` (start and wait). Facts come from the programming guide; what it
leaves open is in :class:`~agilent35670a.quirks.Quirks`. What a measurement returns:
:mod:`agilent35670a.segment`.

The driver knows no rig. Generic primitives (:meth:`~Agilent35670A.configure_inputs` from a
list of ``(input, label, sensitivity)`` settings, :meth:`~Agilent35670A.set_reference_channel`,
``sweep.reference_pairing``, :meth:`~Agilent35670A.read_trace`) and one composite per
measurement take the rig's wiring as arguments; viscorig keeps that wiring in
``viscorig.acquisition.sweep.Wiring``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable, Sequence

import numpy as np

from .blocks import check_axis
from .channels import InputChannel, InputSetting, check_inputs
from .connection import Connection
from .errors import (
    ConnectionLost,
    InstrumentError,
    InstrumentTimeout,
    MalformedReply,
    MissingOption,
    SCPIError,
    SettingNotApplied,
    SettingOutOfRange,
    WrongInstrument,
)
from .fft import FftAnalysis
from .properties import (
    Subsystem,
    control,
    measurement,
    one_of,
    parse_int,
    parse_keyword,
    strict_range,
)
from .quirks import Quirks
from .running import Runner
from .segment import Spectra, SweepProgress, SweepSegment
from .source import DEFAULT_SLEW_V_PER_S, MAX_SOURCE_VPK, FftSource, Source
from .status import Status
from .swept_sine import MAX_POINTS, SweptSine, round_down
from .traces import Traces

__all__ = ["Agilent35670A"]

#: Highest frequency with one or two channels, and with four (Hz).
MAX_FREQUENCY_HZ = 51200.0
MAX_FREQUENCY_FOUR_CHANNELS_HZ = 25600.0
Progress = Callable[[SweepProgress], None]


class Agilent35670A(Subsystem):
    """Agilent (HP) 35670A dynamic signal analyser.

    Open with :meth:`open` (any pyvisa resource string). Settings are attributes of its parts:
    assigning one validates it against the manual's range (nothing is sent if it is out of
    range), writes it and checks the error queue (:class:`~agilent35670a.errors.SCPIError` if
    the analyser refused it); :meth:`verify_configuration` reads every setting sent back.

    Parameters
    ----------
    connection
        An open :class:`~agilent35670a.connection.Connection`.
    """

    instrument_mode = control(
        "INST:SEL {value}", "INST:SEL?",
        """Measurement mode: ``"SINE"`` (swept sine, option 1D2) or ``"FFT"`` (power-up).""",
        validator=one_of(("SINE", "FFT")), parse=parse_keyword,
    )
    identity = measurement("*IDN?", """``*IDN?`` reply (names a 35670A).""")
    operation_condition = measurement(
        "STAT:OPER:COND?", """``STAT:OPER:COND?``: 1 calibrating, 2 settling, 4 ranging,
        16 measuring.""", parse=parse_int)

    def __init__(self, connection: Connection) -> None:
        super().__init__(self, "35670A")
        self.connection = connection
        where = connection.description
        self.status = Status(self, where)
        self.channels = tuple(InputChannel(self, number) for number in range(1, 5))
        self.sweep = SweptSine(self, lambda: self.max_frequency_hz)
        self.source = Source(self)
        self.fft = FftAnalysis(self)
        self.fft_source = FftSource(self)
        self.traces = Traces(self, where, connection.query_block)
        self.runner = Runner(self.write, self.status, where)
        self._options: frozenset[str] | None = None
        self.channels_in_use: tuple[int, ...] = (1, 2, 3, 4)

    @classmethod
    def open(cls, resource: str, *, adapter: str | None = None, gpib_address: int = 11,
             timeout_s: float = 5.0, backend: str | None = None) -> Agilent35670A:
        """Connect to a 35670A and check it is one (see :class:`Connection` for the arguments).

        Raises
        ------
        ConnectionLost
            The resource cannot be opened.
        WrongInstrument
            ``*IDN?`` does not name a 35670A.
        """
        connection = Connection(resource, adapter=adapter, gpib_address=gpib_address,
                                timeout_s=timeout_s, backend=backend)
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

    @property
    def parts(self) -> tuple[Subsystem, ...]:
        """Every part with settings, this one included."""
        return (self, self.traces, *self.channels, self.sweep, self.source, self.fft,
                self.fft_source)

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
        self.status.check_errors(command)

    def read_errors(self) -> list[tuple[int, str]]:
        """Read the error queue empty; return its ``(code, text)`` entries."""
        return self.status.read_errors()

    def check_errors(self, after: str | None = None) -> None:
        """Raise :class:`SCPIError` if the error queue is not empty."""
        self.status.check_errors(after)

    def verify_configuration(self, parts: Iterable[Subsystem] | None = None) -> None:
        """Read back every setting sent on this connection.

        Raises
        ------
        SettingNotApplied
            Naming each setting the analyser does not hold as sent (or as it rounds it).
        """
        problems = [p for part in (self.parts if parts is None else parts)
                    for p in part.mismatches()]
        if problems:
            raise SettingNotApplied("; ".join(problems), self.resource)

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
        """Upper frequency limit: 25.6 kHz with four channels in use, else 51.2 kHz."""
        if 3 in self.channels_in_use and self._options is not None and "AY6" in self._options:
            return MAX_FREQUENCY_FOUR_CHANNELS_HZ
        return MAX_FREQUENCY_HZ

    # -- generic set-up primitives --------------------------------------------------------------
    def configure_inputs(self, inputs: Iterable[tuple[int, str, float]], *,
                         pairing: str | None = None) -> None:
        """Switch the inputs in use on and set each one's engineering units and autorange.

        What each input measures is the caller's to say (the rig's wiring): the driver only
        validates the values, every one before anything is sent. Inputs 2..4 not listed are
        switched off where the analyser allows it (input 2 of a two-channel analyser stays on).

        Parameters
        ----------
        inputs
            ``(number, label, sensitivity_v_per_eu)`` per input in use (see
            :class:`~agilent35670a.channels.InputSetting`): input 1..4, a label of
            :data:`~agilent35670a.channels.TRANSDUCER_LABELS`, 1e-9..1e6 V/EU. Input 1 is
            always among them; inputs 3 and 4 need option AY6.
        pairing
            ``"PAIR"`` (1 is the reference of 2, 3 of 4) or ``"SING"`` (1 of all) for
            ``REF``; ``None`` leaves it as it is.

        Raises
        ------
        SettingOutOfRange, SCPIError, MissingOption
        """
        settings = check_inputs(inputs, self)
        if pairing is not None:
            SweptSine.reference_pairing.validator(pairing, self.sweep)
        channels = tuple(setting.number for setting in settings)
        if any(number in (3, 4) for number in channels) and "AY6" not in self.options:
            installed = ", ".join(sorted(self.options)) or "none"
            raise MissingOption(f"option AY6 (channels 3 and 4) is not installed; *OPT? lists: "
                                f"{installed}", ("AY6",), self.resource)
        self.channels_in_use = channels
        for number in (2, 3, 4):
            if number in channels:
                self.channel(number).enabled = True
            elif "AY6" in self.options and number != 2:
                self.channel(number).enabled = False
        if pairing is not None:
            self.sweep.reference_pairing = pairing
        for setting in settings:
            channel = self.channel(setting.number)
            channel.set_engineering_units(setting.label, setting.sensitivity_v_per_eu)
            channel.autorange = True

    def set_reference_channel(self, channel: int, level_eu: float, *,
                              tolerance_db: float = 2.0) -> None:
        """Auto level: hold input ``channel`` at ``level_eu`` (peak, in that input's
        engineering unit) within ``tolerance_db``.

        Parameters
        ----------
        channel
            Auto-level reference input, one of the inputs in use (1..4).
        level_eu
            Reference amplitude, peak, in the input's engineering unit (> 0, ≤ 1e6).
        tolerance_db
            Accepted deviation from the reference level, dB.
        """
        if channel not in self.channels_in_use:
            raise SettingOutOfRange(f"reference channel {channel} is not in use")
        self.source.reference_channel = channel
        self.source.reference_eu = level_eu
        self.source.tolerance_db = tolerance_db

    # -- one composite per measurement -----------------------------------------------------------
    def configure_swept_sine(
        self, *, inputs: Iterable[tuple[int, str, float]], reference_channel: int,
        reference_level_eu: float, source_limit_vpk: float, input_limit_eu: float | None = None,
        pairing: str | None = "PAIR", resolution_hz: float = 0.25, start_hz: float = 10.0,
        stop_hz: float = 60.0, settle_cycles: float = 100.0, integrate_cycles: float = 100.0,
        direction: str = "UP", tolerance_db: float = 2.0, start_level_vpk: float = 0.1,
        data_format: str = "REAL,64", source_slew_v_per_s: float = DEFAULT_SLEW_V_PER_S,
    ) -> None:
        """Set up an auto-levelled swept sine and read every setting back.

        Every value is validated before anything is sent (:meth:`_check_swept_sine`); then
        swept-sine mode, the data format, the inputs (:meth:`configure_inputs`), the linear
        grid and timing (:meth:`SweptSine.set_linear_sweep`) and the auto-level controller
        (:meth:`_set_auto_level`), the error queue checked after each setting. Which transducer
        is on which input (so the reference) is the caller's: the driver knows no rig.

        Parameters
        ----------
        inputs
            ``(number, label, sensitivity_v_per_eu)`` per input in use.
        reference_channel, reference_level_eu, tolerance_db
            Auto-level reference input (one of ``inputs``), the amplitude (peak, in its unit,
            > 0, ≤ 1e6) the controller holds on it, within ``tolerance_db`` dB.
        source_limit_vpk, start_level_vpk
            Highest source level (≤ 5 Vpk) and the level the controller starts from (≤ limit).
        input_limit_eu
            Auto-level input limit (peak, in each input's unit); ``None`` for none.
        pairing
            ``"PAIR"``, ``"SING"`` or ``None`` (not sent), see :meth:`configure_inputs`.
        resolution_hz, start_hz, stop_hz, direction
            Linear grid (Hz; at most 801 points over the band), the first band (:meth:`measure`
            sets each segment's) and ``"UP"``/``"DOWN"``.
        settle_cycles, integrate_cycles, data_format
            Settle (0..1e6) and integration (1..234) cycles per point; ``"REAL,64"`` (falls
            back to ASCII if refused, :meth:`set_data_format`).
        source_slew_v_per_s
            Source ramp rate (``SOUR:VOLT:SLEW``, 0 to 10000 V/s, 0 for none): the source
            ramps up as a sweep starts and down to 0 when it ends or is aborted, so the shaker
            never sees a step (module :mod:`.running`).

        Raises
        ------
        SettingOutOfRange, SCPIError, SettingNotApplied, MissingOption
        """
        settings = self._check_swept_sine(
            inputs, reference_channel, reference_level_eu, pairing,
            (start_hz, stop_hz, resolution_hz), (settle_cycles, integrate_cycles),
            (source_limit_vpk, start_level_vpk, source_slew_v_per_s))
        self.identify()
        channels = tuple(setting.number for setting in settings)
        self.require_options(any(number in (3, 4) for number in channels))
        self.channels_in_use = channels
        self.instrument_mode = "SINE"
        self.set_data_format(data_format)
        self.configure_inputs(settings, pairing=pairing)
        self.sweep.set_linear_sweep(start_hz, stop_hz, resolution_hz, direction)
        self.sweep.set_timing(settle_cycles, integrate_cycles, "CYCLE")
        self._set_auto_level(source_limit_vpk, source_slew_v_per_s, start_level_vpk,
                             (reference_channel, reference_level_eu, tolerance_db),
                             input_limit_eu)
        self.verify_configuration()

    def _check_swept_sine(
        self, inputs: Iterable[tuple[int, str, float]], reference_channel: int,
        reference_level_eu: float, pairing: str | None, grid: tuple[float, float, float],
        cycles: tuple[float, float], source: tuple[float, float, float],
    ) -> tuple[InputSetting, ...]:
        """Validate a swept-sine set-up before anything is sent: the inputs and reference, the
        pairing, the band on its grid (``start, stop, resolution``), the settle and integration
        ``cycles``, and the ``source`` (limit, start level within it, slew rate). Returns the
        input settings.

        Raises
        ------
        SettingOutOfRange
            Naming the first value out of range.
        """
        settings = check_inputs(inputs, self)
        if reference_channel not in (setting.number for setting in settings):
            raise SettingOutOfRange(f"reference channel {reference_channel} is not in use")
        strict_range(0.0, 1e6, "EU", low_inclusive=False)(reference_level_eu, self)
        if pairing is not None:
            SweptSine.reference_pairing.validator(pairing, self.sweep)
        self._check_band(*grid)
        limit_vpk, start_level_vpk, slew_v_per_s = source
        strict_range(0.0, MAX_SOURCE_VPK, "Vpk", low_inclusive=False)(limit_vpk, self)
        Source.slew_v_per_s.validator(slew_v_per_s, self.source)
        strict_range(0.0, 1e6, "cycles")(cycles[0], self)
        strict_range(1.0, 234.0, "cycles")(cycles[1], self)
        if not 0.0 < start_level_vpk <= limit_vpk:
            raise SettingOutOfRange(
                f"start level {start_level_vpk:g} Vpk must be above 0 and at most the source "
                f"limit {limit_vpk:g} Vpk"
            )
        return settings

    def _set_auto_level(self, limit_vpk: float, slew_v_per_s: float, start_level_vpk: float,
                        reference: tuple[int, float, float], input_limit_eu: float | None) -> None:
        """Set the source and switch auto level on, in the only safe order: the limit first,
        then the slew rate (before the source can start: it ramps up), the start level, the
        ``reference`` (input, level in its unit, tolerance in dB,
        :meth:`set_reference_channel`), the input limit if any, and auto level last."""
        source = self.source
        source.limit_vpk = limit_vpk
        source.slew_v_per_s = slew_v_per_s
        source.level_vpk = start_level_vpk
        channel, level_eu, tolerance_db = reference
        self.set_reference_channel(channel, level_eu, tolerance_db=tolerance_db)
        if input_limit_eu is not None:
            source.input_limit_eu = input_limit_eu
        source.auto_level = True

    def set_data_format(self, data_format: str = "REAL,64") -> str:
        """Select the data format; if the analyser refuses ``REAL``, fall back to ``ASC,12``.

        Returns the format in use.
        """
        try:
            self.traces.data_format = data_format
        except SCPIError:
            if not data_format.upper().startswith("REAL"):
                raise
            self.traces.data_format = "ASC,12"
        return str(self.traces.sent["data_format"])

    # -- measuring -----------------------------------------------------------------------------
    def measure(
        self,
        start_hz: float,
        stop_hz: float,
        *,
        resolution_hz: float | None = None,
        settle_cycles: float | None = None,
        integrate_cycles: float | None = None,
        start_level_vpk: float | None = None,
        progress: Progress | None = None,
        timeout_s: float | None = None,
        poll_interval_s: float = 0.2,
        switch_source_off: bool = True,
    ) -> SweepSegment:
        """Measure the linear sub-band ``start_hz`` .. ``stop_hz``.

        Sets the band (and, when given, this call's resolution, settle and integration cycles),
        reads them back, starts (``ABOR;:INIT:IMM;*OPC``), waits by polling status (never
        blocking past a time-out; calibration and pauses do not count against the deadline),
        then reads both frequency responses, the linear spectra and normalized variances of the
        channels in use, their frequency axis, and the overload latches.

        Parameters
        ----------
        start_hz, stop_hz
            Band in Hz; ``(stop - start) / resolution + 1`` must be at most 801 points.
        resolution_hz, settle_cycles, integrate_cycles
            This segment's grid and timing (default: as configured).
        start_level_vpk
            The source level the auto-level controller starts this segment from (default: as
            set), within the source limit.
        progress
            Called at each poll with a :class:`SweepProgress`; it may call :meth:`pause`,
            :meth:`resume` or :meth:`abort`.
        timeout_s
            Overall deadline in seconds (pauses and calibration excluded); default twice the
            expected time plus 30 s.
        poll_interval_s
            Longest time between polls (polling starts at 1 ms and doubles).
        switch_source_off
            End with ``ABOR`` (the sweep drives the source), also after an error; the source
            ramps down at the slew rate set (:meth:`source_ramp_down_s`).

        Raises
        ------
        MeasurementAborted, InstrumentTimeout, SCPIError, MalformedReply, SettingNotApplied
        """
        resolution = resolution_hz if resolution_hz is not None else self.sweep.sent.get(
            "resolution_hz")
        if resolution is None:
            raise SettingOutOfRange("set a resolution (or call configure_swept_sine) first")
        start, stop, points = self._check_band(start_hz, stop_hz, float(resolution))
        self.runner.end_requested.clear()  # a request left from an earlier sweep
        sweep = self.sweep
        sweep.sweep_mode = "AUTO"
        sweep.set_band(start, stop)
        sweep.resolution_hz = resolution
        if settle_cycles is not None or integrate_cycles is not None:
            sweep.set_timing(
                sweep.sent.get("settle_cycles", 0.0) if settle_cycles is None else settle_cycles,
                sweep.sent.get("integrate_cycles", 1.0) if integrate_cycles is None
                else integrate_cycles, "CYCLE")
        if start_level_vpk is not None:
            limit = self.source.sent.get("limit_vpk")
            self.source.level_vpk = (min(start_level_vpk, limit) if limit is not None
                                     else start_level_vpk)
        self.verify_configuration([sweep])
        grid = start + float(resolution) * np.arange(points)
        segment = self._run(grid, points, progress, timeout_s, poll_interval_s, switch_source_off,
                            may_end_early=True)
        if segment.ended_early:  # the first points of the sweep, in its order
            count = segment.frequency_hz.size
            if count:
                ordered = grid[::-1] if abs(segment.frequency_hz[0] - grid[-1]) < abs(
                    segment.frequency_hz[0] - grid[0]) else grid
                check_axis(segment.frequency_hz, ordered[:count], float(resolution),
                           self.resource)
        else:
            check_axis(segment.frequency_hz, grid, float(resolution), self.resource)
        return segment

    def measure_point(self, frequency_hz: float, *, progress: Progress | None = None,
                      timeout_s: float | None = None, poll_interval_s: float = 0.2,
                      switch_source_off: bool = True) -> SweepSegment:
        """Measure one frequency in manual sweep mode (see :meth:`measure_points`)."""
        return self.measure_points([frequency_hz], progress=progress, timeout_s=timeout_s,
                                   poll_interval_s=poll_interval_s,
                                   switch_source_off=switch_source_off)

    def measure_points(
        self,
        frequencies_hz: Sequence[float],
        *,
        settle_cycles: float | None = None,
        integrate_cycles: float | None = None,
        start_levels_vpk: Sequence[float] | None = None,
        progress: Progress | None = None,
        timeout_s: float | None = None,
        poll_interval_s: float = 0.2,
        switch_source_off: bool = True,
    ) -> SweepSegment:
        """Measure arbitrary frequencies, in the order given, in manual sweep mode.

        For each frequency: ``FREQ:MAN`` (read back: the analyser rounds down to 15.625 mHz),
        a measurement, the traces read. The band is set to cover all the frequencies (a manual
        frequency must lie within start..stop). Settle and integration cycles given here apply
        to these points (and stay set). Each measurement starts the auto-level controller at
        the source level (``SOUR:VOLT``): ``start_levels_vpk`` sets it before each point (the
        level the controller is expected to land at, so that a point starts where the one
        before it left the rig), within the source limit.

        :meth:`end_after_point` ends it after the point in flight: the segment then holds the
        first points, with ``ended_early`` true.

        Returns
        -------
        SweepSegment
            One row per frequency, in the order given, on the analyser's own frequency axis.
        """
        frequencies = [float(f) for f in frequencies_hz]
        if not frequencies:
            raise SettingOutOfRange("no frequency to measure")
        for frequency in frequencies:
            strict_range(0.015625, self.max_frequency_hz, "Hz")(frequency, self)
        sweep = self.sweep
        low, high = round_down(min(frequencies)), max(frequencies)
        # the band needs two grid points: below the top frequency when a point is at it
        low = min(low, self.max_frequency_hz - 0.015625)
        sweep.set_band(low, max(high, low + 0.015625))
        sweep.sweep_mode = "MAN"
        if settle_cycles is not None or integrate_cycles is not None:
            sweep.set_timing(
                sweep.sent.get("settle_cycles", 0.0) if settle_cycles is None else settle_cycles,
                sweep.sent.get("integrate_cycles", 1.0) if integrate_cycles is None
                else integrate_cycles, "CYCLE")
        sweep.manual_frequency_hz = frequencies[0]
        self.verify_configuration([sweep])
        manual = type(sweep).manual_frequency_hz
        if start_levels_vpk is not None and len(start_levels_vpk) != len(frequencies):
            raise SettingOutOfRange(f"{len(start_levels_vpk)} start levels for "
                                    f"{len(frequencies)} frequencies")
        limit = self.source.sent.get("limit_vpk")
        pieces: list[SweepSegment] = []
        self.runner.end_requested.clear()  # a request left from an earlier sweep
        for number, frequency in enumerate(frequencies):
            if pieces and self.runner.end_requested.is_set():  # ended after the point before
                return dataclasses.replace(_joined(pieces), ended_early=True)
            if start_levels_vpk is not None:
                start = float(start_levels_vpk[number])
                self.source.level_vpk = min(start, limit) if limit is not None else start
            sweep.manual_frequency_hz = frequency
            problem = manual.check(sweep)
            if problem is not None:
                raise SettingNotApplied(problem, self.resource)
            segment = self._run(np.array([frequency]), None, progress, timeout_s,
                                poll_interval_s, switch_source_off)
            # the trace holds the manual point (an instrument may keep earlier points of the
            # band beside it: the one at the manual frequency is taken, inferred)
            index = int(np.argmin(np.abs(segment.frequency_hz - round_down(frequency))))
            if abs(segment.frequency_hz[index] - round_down(frequency)) > 0.5 * 0.015625 + 1e-9:
                raise MalformedReply(
                    f"the analyser measured {segment.frequency_hz[index]:g} Hz for a manual "
                    f"frequency of {frequency:g} Hz", self.resource)
            pieces.append(_picked(segment, index))
        return _joined(pieces)

    def measure_at_source(
        self,
        frequencies_hz: Sequence[float],
        source_vpk: float,
        *,
        settle_cycles: float | None = None,
        integrate_cycles: float | None = None,
        progress: Progress | None = None,
        timeout_s: float | None = None,
        poll_interval_s: float = 0.2,
    ) -> SweepSegment:
        """Measure chosen frequencies (manual sweep mode, see :meth:`measure_points`) with the
        auto-level controller off and the source held at ``source_vpk``: what each input reads
        per source volt, such as the shaker's force per volt, which the 35670A does not report
        for a point measured under auto level.

        The source limit must be set (:meth:`configure_swept_sine`) and ``source_vpk`` lie above
        0 and within it. Auto level is switched on again afterwards, after an error too.

        Raises
        ------
        SettingOutOfRange, SCPIError, SettingNotApplied, MeasurementAborted, InstrumentTimeout
        """
        limit = self.source.sent.get("limit_vpk")
        if limit is None:
            raise SettingOutOfRange("set the source limit (configure_swept_sine) first")
        strict_range(0.0, float(limit), "Vpk", low_inclusive=False)(source_vpk, self)
        restore = self.source.sent.get("auto_level", True)
        self.source.auto_level = False
        measured = False
        try:
            self.source.level_vpk = source_vpk
            segment = self.measure_points(frequencies_hz, settle_cycles=settle_cycles,
                                          integrate_cycles=integrate_cycles, progress=progress,
                                          timeout_s=timeout_s, poll_interval_s=poll_interval_s)
            measured = True
        finally:
            if restore:
                try:
                    self.source.auto_level = True
                except Exception:  # after a failed measurement, its own error says more
                    if measured:
                        raise
        return segment

    def expected_duration_s(self, grid_hz: Iterable[float]) -> float:
        """Time the analyser takes for these points from the settings sent (s): settle,
        integration and its own time per point."""
        frequencies = np.asarray(list(grid_hz), dtype=float)
        return float(sum(self.sweep.point_time_s(f) + Quirks.POINT_OVERHEAD_S
                         for f in frequencies))

    def _check_band(self, start_hz: float, stop_hz: float,
                    resolution_hz: float) -> tuple[float, float, int]:
        """Validate a band on a linear grid; return start, stop and the number of points."""
        check = strict_range(0.015625, self.max_frequency_hz, "Hz")
        start, stop = check(start_hz, self), check(stop_hz, self)
        if stop <= start:
            raise SettingOutOfRange(f"stop {stop:g} Hz must be above start {start:g} Hz")
        strict_range(0.015625, 51200.0, "Hz")(resolution_hz, self)
        points = round((stop - start) / resolution_hz) + 1
        if points > MAX_POINTS:
            raise SettingOutOfRange(
                f"{start:g}..{stop:g} Hz at {resolution_hz:g} Hz is {points} points; "
                f"at most {MAX_POINTS} per sweep"
            )
        return start, stop, points

    def _run(self, grid_hz: np.ndarray, points: int | None, progress: Progress | None,
             timeout_s: float | None, poll_interval_s: float,
             switch_source_off: bool, may_end_early: bool = False) -> SweepSegment:
        expected_s = self.expected_duration_s(grid_hz)
        deadline_s = 2.0 * expected_s + 30.0 if timeout_s is None else float(timeout_s)
        fault: BaseException | None = None
        try:
            started, finished = self.runner.run(expected_s, deadline_s, progress,
                                                poll_interval_s, may_end_early=may_end_early)
            if self.runner.ended_early:  # the points measured: those before the first gap
                segment = self._read_segment(None, started, finished)
                missing = np.asarray(segment.no_data, dtype=bool)
                measured = int(np.argmax(missing)) if missing.any() else missing.size
                return dataclasses.replace(_picked(segment, slice(0, measured)),
                                           ended_early=True)
            return self._read_segment(points, started, finished)
        except BaseException as error:
            fault = error
            raise
        finally:
            if switch_source_off:
                self._stop_source(fault)

    def _stop_source(self, fault: BaseException | None) -> None:
        """End the measurement so that the source stops, however it ended: ``ABOR`` (in swept
        sine the sweep drives the source), and ``OUTP OFF`` in FFT mode. With a slew rate set
        (``SOUR:VOLT:SLEW``) the analyser ramps the source down rather than cutting it (module
        :mod:`.running`).

        After a lost connection or a time-out the session is reopened first: a write to a
        socket the peer has closed still "succeeds", so the source would stay on. No error-queue
        check here, and a failure does not replace the fault that ended the measurement.
        """
        try:
            if isinstance(fault, ConnectionLost | InstrumentTimeout):
                self.connection.reconnect()
            self.write("ABOR")
            if self.instrument_mode_sent() == "FFT":
                self.write("OUTP OFF")
                self.fft_source.sent["output"] = False
        except InstrumentError:
            if fault is None:
                raise

    def instrument_mode_sent(self) -> str | None:
        """The mode this connection selected, if any."""
        return self.sent.get("instrument_mode")

    def pause(self) -> None:
        """Pause the running measurement (``INIT:CONT OFF``); the deadline stops counting."""
        self.runner.pause()

    def resume(self) -> None:
        """Resume a paused measurement (``INIT:CONT ON``)."""
        self.runner.resume()

    def end_after_point(self) -> None:
        """End the running measurement at the next point boundary: the point being integrated
        is finished, the analyser stopped (``ABOR``; the source ramps down at the slew rate)
        before the next one and the points measured so far read; the segment returned holds
        them, with ``ended_early`` true. :meth:`measure` ends inside its sweep;
        :meth:`measure_points` (manual sweep mode, one measurement per point) after the point
        in flight, before the next one starts. Safe from the progress callback or another
        thread."""
        self.runner.end_after_point()

    def source_ramp_down_s(self) -> float:
        """The longest time the source takes to ramp down to 0 after ``ABOR``: the source
        limit over the slew rate sent on this connection (the level the auto-level controller
        reached is not readable in swept sine), 0 without a slew rate."""
        slew = float(self.source.sent.get("slew_v_per_s") or 0.0)
        limit = self.source.sent.get("limit_vpk")
        if slew <= 0.0:
            return 0.0
        return float(MAX_SOURCE_VPK if limit is None else limit) / slew

    def abort(self) -> None:
        """Stop the measurement (``ABOR``; the source ramps down at the slew rate); a waiting
        measurement raises :class:`MeasurementAborted`."""
        self.runner.abort()
        if self.instrument_mode_sent() == "FFT":
            self.write("OUTP OFF")

    # -- data ----------------------------------------------------------------------------------
    def _read_segment(self, points: int | None, started: float,
                      finished: float) -> SweepSegment:
        channels = self.channels_in_use
        traces = self.traces
        traces.show("XFR:POW:RAT 2,1")
        frequency_hz, count = traces.axis()
        if points is not None and count != points:
            raise MalformedReply(f"the analyser's trace holds {count} measured points, "
                                 f"{points} were asked for", self.resource)
        frf_21 = traces.data("XFR:POW:RAT 2,1", count)
        frf_43 = None
        extras: dict[str, np.ndarray] = {}
        if self.sweep.sent.get("reference_pairing") == "SING":
            # input 1 is every input's reference: 4/3 is the ratio of the two responses
            for number in (3, 4):
                if number in channels:
                    traces.show(f"XFR:POW:RAT {number},1")
                    extras[f"frf_{number}1"] = traces.data(f"XFR:POW:RAT {number},1", count)
            if "frf_31" in extras and "frf_41" in extras:
                with np.errstate(divide="ignore", invalid="ignore"):
                    frf_43 = extras["frf_41"] / extras["frf_31"]
        elif 3 in channels and 4 in channels:
            traces.show("XFR:POW:RAT 4,3")
            frf_43 = traces.data("XFR:POW:RAT 4,3", count)
        amplitude, variance = {}, {}
        for channel in channels:
            traces.show(f"XFR:POW:LIN {channel}")
            amplitude[channel] = np.abs(traces.data(f"XFR:POW:LIN {channel}", count))
            traces.show(f"XFR:POW:VAR {channel}")
            variance[channel] = traces.data(f"XFR:POW:VAR {channel}", count, real=True)
        overload, half_range = self.status.read_overload()
        missing = np.isnan(frf_21) | np.any([np.isnan(v) for v in amplitude.values()], axis=0)
        if frf_43 is not None:
            missing |= np.isnan(frf_43)
        labels = {ch: str(self.channel(ch).sent.get("transducer_label", "V")) for ch in channels}
        return SweepSegment(
            frequency_hz=frequency_hz, frf_21=frf_21, frf_43=frf_43, amplitude_eu=amplitude,
            variance=variance, eu_labels=labels, overload_channels=overload,
            half_range_channels=half_range, started_at_s=started, finished_at_s=finished,
            no_data=missing, extras=extras,
        )

    def read_trace(self, feed: str, points: int | None = None, *, real: bool = False,
                   with_axis: bool = False) -> tuple[np.ndarray | None, np.ndarray]:
        """Feed trace A with ``feed`` and read it untransformed through register D1.

        Returns
        -------
        (frequency_hz or None, values)
            The measured points only (a swept-sine trace's empty slots are left out); NaN where
            the analyser put its no-data marker.
        """
        self.traces.show(feed)
        axis, count = self.traces.axis()
        if points is not None and count != points:
            raise MalformedReply(f"{feed}: {count} measured points, expected {points}",
                                 self.resource)
        values = self.traces.data(feed, count, real=real)
        return (axis if with_axis else None), values

    def read_values(self, query: str) -> np.ndarray:
        """Send a data query and decode its reply in the data format in use."""
        return self.traces.read_values(query)

    def read_overload(self) -> tuple[tuple[int, ...], tuple[int, ...]]:
        """Read and clear ``STAT:QUES:VOLT:EVEN?``: (overloaded channels, half-range channels)."""
        return self.status.read_overload()

    # -- FFT: spectra with the source off (noise floors) or driving --------------------------------
    def measure_spectra(
        self,
        *,
        span_hz: float,
        lines: int = 400,
        averages: int = 10,
        window: str = "HANN",
        channels: Sequence[int] = (1, 2, 3, 4),
        timeout_s: float | None = None,
        poll_interval_s: float = 0.1,
    ) -> Spectra:
        """An FFT measurement of each input's power spectrum with the source off.

        Baseband ``0 .. span_hz`` (the analyser takes the next allowed span), RMS averaging,
        autorange at the start (the analyser does not range during an averaged measurement).
        """
        self.identify()
        self.channels_in_use = tuple(channels)
        self.instrument_mode = "FFT"
        self.set_data_format("REAL,64")
        self.fft_source.output = False
        for number in (2, 3, 4):
            if number in channels:
                self.channel(number).enabled = True
        for number in channels:
            self.channel(number).autorange = True
        fft = self.fft
        fft.start_frequency_hz = 0.0
        fft.span_hz = span_hz
        fft.lines = str(lines)
        fft.window = window
        fft.averaging = True
        fft.average_count = averages
        fft.average_type = "RMS"
        self.verify_configuration([self, self.fft, self.fft_source])
        span = float(self.fft.span_hz)
        record_s = lines / span
        expected_s = averages * max(record_s, 1 / 33.0) + 20.0
        deadline = 3.0 * expected_s + 30.0 if timeout_s is None else timeout_s
        self.runner.run(expected_s, deadline, None, poll_interval_s)
        power = {}
        frequency = np.zeros(0)
        for number in channels:
            self.traces.show(f"XFR:POW {number}")
            values = self.traces.read_values("TRAC:X? D1")
            frequency = values[: lines + 1]
            raw = self.traces.read_values("TRAC:DATA? D1")[: lines + 1].copy()
            raw[raw < -1e37] = np.nan
            power[number] = raw
        overload, _ = self.status.read_overload()
        ranges = {number: self.channel(number).range_in_use_dbvrms() for number in channels}
        return Spectra(frequency_hz=frequency, power=power, line_width_hz=span / lines,
                       ranges_dbvrms=ranges, overload_channels=overload)


def _picked(segment: SweepSegment, index: int | slice) -> SweepSegment:
    """One point of a segment (or the points of a slice)."""
    pick = index if isinstance(index, slice) else slice(index, index + 1)
    return SweepSegment(
        frequency_hz=segment.frequency_hz[pick], frf_21=segment.frf_21[pick],
        frf_43=None if segment.frf_43 is None else segment.frf_43[pick],
        amplitude_eu={ch: v[pick] for ch, v in segment.amplitude_eu.items()},
        variance={ch: v[pick] for ch, v in segment.variance.items()},
        eu_labels=segment.eu_labels, overload_channels=segment.overload_channels,
        half_range_channels=segment.half_range_channels, started_at_s=segment.started_at_s,
        finished_at_s=segment.finished_at_s,
        no_data=None if segment.no_data is None else segment.no_data[pick],
        extras={name: values[pick] for name, values in segment.extras.items()},
    )


def _joined(pieces: list[SweepSegment]) -> SweepSegment:
    """One segment of several one-point measurements, in order."""
    first = pieces[0]

    frf_43 = [p.frf_43 for p in pieces if p.frf_43 is not None]
    return SweepSegment(
        frequency_hz=np.concatenate([p.frequency_hz for p in pieces]),
        frf_21=np.concatenate([p.frf_21 for p in pieces]),
        frf_43=None if first.frf_43 is None else np.concatenate(frf_43),
        amplitude_eu={ch: np.concatenate([p.amplitude_eu[ch] for p in pieces])
                      for ch in first.amplitude_eu},
        variance={ch: np.concatenate([p.variance[ch] for p in pieces]) for ch in first.variance},
        eu_labels=first.eu_labels,
        overload_channels=tuple(sorted({c for p in pieces for c in p.overload_channels})),
        half_range_channels=tuple(sorted({c for p in pieces for c in p.half_range_channels})),
        started_at_s=first.started_at_s,
        finished_at_s=pieces[-1].finished_at_s,
        no_data=np.concatenate([p.no_data if p.no_data is not None else np.zeros(len(p), bool)
                                for p in pieces]),
        extras={name: np.concatenate([p.extras[name] for p in pieces]) for name in first.extras},
    )
