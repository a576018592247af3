"""The vocabulary of a sweep: how a run is measured (settings, wiring), how the analyser is set
up for it, and how what the analyser returns becomes a stored segment with its flags.

The plans that measure runs segment by segment are in :mod:`viscorig.acquisition.plans`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from datetime import datetime

import numpy as np
from numpy.typing import NDArray

from viscorig.acquisition.limits import AT_FORCE_LIMIT_DB, point_flags
from viscorig.acquisition.protocol import Analyser, MeasuredSegment
from viscorig.analyser import FREQUENCY_STEP_HZ, MIN_REFERENCE_VPK
from viscorig.errors import InstrumentError
from viscorig.sequences import (
    Station,
    SweepStep,
)
from viscorig.storage import SOURCE_AT_LIMIT, Segment
from viscorig.storage.flags import OUTSIDE_SOAK_BAND

#: ``time_s`` clocks: "wall" is seconds of real time since the run started (a real rig);
#: "test" is accumulated settle and integration time (a simulated rig running faster than
#: real time, whose physics advances by test time).
TIME_BASES = ("wall", "test")
#: Source level the auto-level controller starts a run from, V peak (at most the limit).
START_LEVEL_V = 0.1
#: Ramp rate of the source when a station gives none, V/s: a 2 Vpk drive is down in 2 s, slowly
#: enough that the shaker and the specimen see no step, quickly enough for a pause.
SOURCE_SLEW_V_PER_S = 1.0
#: Half the analyser's frequency step tells points apart.
FREQUENCY_MATCH_HZ = FREQUENCY_STEP_HZ / 2


class SweepInterrupted(Exception):  # noqa: N818 (an outcome, not a fault)
    """The operator stopped the sweep; every committed segment is kept."""


@dataclass(frozen=True)
class Wiring:
    """Which analyser input carries which transducer (from the station file).

    This is where the rig's wiring lives; the driver knows none of it. From it come the
    inputs' labels and sensitivities (:meth:`inputs`), the auto-level reference
    (:meth:`reference_channel`), the ``REF PAIR`` pairing and which measured ratio is which
    accelerance (:func:`segment_of`): the analyser pairs inputs (1 → 2, 3 → 4), the pair of the
    excitation force gives the table accelerance, the other pair the support accelerance.
    """

    excitation_force: int
    table_acceleration: int
    device_force: int
    device_acceleration: int
    sensitivities_v_per_eu: Mapping[int, float]

    @classmethod
    def from_station(cls, station: Station) -> Wiring:
        """The wiring a station file describes."""
        channels, sensitivity = station.channels, station.sensitivity
        return cls(
            excitation_force=channels.excitation_force,
            table_acceleration=channels.table_acceleration,
            device_force=channels.device_force,
            device_acceleration=channels.device_acceleration,
            sensitivities_v_per_eu={
                channels.excitation_force: sensitivity.excitation_force_v_per_n,
                channels.table_acceleration: sensitivity.table_acceleration_v_per_m_s2,
                channels.device_force: sensitivity.device_force_v_per_n,
                channels.device_acceleration: sensitivity.device_acceleration_v_per_m_s2,
            },
        )

    #: Engineering-unit labels the analyser shows forces and accelerations in.
    FORCE_LABEL = "N"
    ACCELERATION_LABEL = "M/S2"
    #: ``REF PAIR``: input 1 is the reference of 2 and 3 of 4, so each force must sit on an
    #: odd input with its acceleration on the next one.
    PAIRING = "PAIR"

    def inputs(self) -> list[tuple[int, str, float]]:
        """``(input, label, sensitivity V/EU)`` for each transducer, in input order: forces in
        N, accelerations in m/s² (the driver's input settings)."""
        labels = {
            self.excitation_force: self.FORCE_LABEL,
            self.device_force: self.FORCE_LABEL,
            self.table_acceleration: self.ACCELERATION_LABEL,
            self.device_acceleration: self.ACCELERATION_LABEL,
        }
        missing = sorted(set(labels) - set(self.sensitivities_v_per_eu))
        if missing:
            raise ValueError(f"wiring: no transducer sensitivity for input(s) {missing}")
        return [(number, labels[number], float(self.sensitivities_v_per_eu[number]))
                for number in sorted(labels)]

    def reference_channel(self, bare_table: bool) -> int:
        """The input the auto level holds: the table's accelerometer on a bare-table run, the
        device's otherwise."""
        return self.table_acceleration if bare_table else self.device_acceleration

    def lowest_reference_level(self, bare_table: bool) -> float:
        """The lowest level the auto level can hold on :meth:`reference_channel`, m/s²
        (:data:`~viscorig.analyser.MIN_REFERENCE_VPK` over the accelerometer's sensitivity)."""
        channel = self.reference_channel(bare_table)
        return MIN_REFERENCE_VPK / float(self.sensitivities_v_per_eu[channel])

    @property
    def force_limit_acts_on_excitation(self) -> bool:
        """The analyser's input limit (``SOUR:VOLT:LIM:INP``) holds every input but the
        auto-level reference, each in its own unit (programming guide, chapter 19); the
        reference is an accelerometer, so the excitation force input is always held."""
        return self.excitation_force not in (self.table_acceleration, self.device_acceleration)


@dataclass(frozen=True)
class SweepSettings:
    """How one run is measured: the step, the level held and the limits in force."""

    step: SweepStep
    level_m_per_s2: float
    force_limit_n: float
    source_limit_v: float
    time_base: str = "wall"
    poll_interval_s: float = 0.2
    start_level_v: float = START_LEVEL_V
    """Source level the auto-level controller starts from, V peak (capped at the limit)."""
    source_slew_v_per_s: float = SOURCE_SLEW_V_PER_S
    """Ramp rate of the source at the start and end of a sweep, V/s (0: none)."""

    def __post_init__(self) -> None:
        if self.time_base not in TIME_BASES:
            raise ValueError(f"time_base must be one of {TIME_BASES}, not {self.time_base!r}")


@dataclass(frozen=True)
class SegmentDone:
    """One committed segment, for progress displays and logs."""

    run: str
    number: int
    """1-based segment number within this session's plan of the run."""
    count: int
    """Segments planned this session."""
    points_done: int
    points_total: int
    frequency_hz: NDArray[np.float64]
    reference_amplitude: NDArray[np.float64]
    force_amplitude: NDArray[np.float64]
    flags: NDArray[np.uint16]
    remeasured: bool
    """The segment was measured again after an input overload."""
    seconds_left: float
    """Test time left in the run, s."""


@dataclass
class SweepHooks:
    """Callbacks of a sweep: stop request, progress while measuring, segment committed."""

    should_stop: Callable[[], bool] = lambda: False
    on_poll: Callable[[float, float], None] | None = None
    """Called with (estimated current frequency Hz, test time left in the run s)."""
    on_segment: Callable[[SegmentDone], None] | None = None
    measuring: list[bool] = field(default_factory=lambda: [False])
    """``measuring[0]`` is true while the analyser is measuring (for signal handlers)."""


def configure(
    analyser: Analyser,
    wiring: Wiring,
    settings: SweepSettings,
    *,
    band_hz: tuple[float, float] | None = None,
    resolution_hz: float | None = None,
    settle_cycles: int | None = None,
    integrate_cycles: int | None = None,
) -> None:
    """Set the analyser up for a run; the source limit is part of it and precedes the source.

    The analyser's input limit (shaker force) is used only when it watches the excitation
    force (input 1); otherwise the source limit alone bounds the drive. The grid and timing are
    the step's (a full plan), or given here (an adaptive plan, whose measurements then set
    their own for each sub-sweep or point).
    """
    step = settings.step
    if band_hz is None:
        grid = np.sort(step.frequencies_hz())
        band_hz = (float(grid[0]), float(grid[min(grid.size - 1, 800)]))
    resolution = step.resolution_hz if resolution_hz is None else resolution_hz
    settle = step.settle_cycles if settle_cycles is None else settle_cycles
    integrate = step.integrate_cycles if integrate_cycles is None else integrate_cycles
    if resolution is None or settle is None or integrate is None:
        raise ValueError("an adaptive step is configured with its resolution and cycles given")
    analyser.configure_swept_sine(
        inputs=wiring.inputs(),
        reference_channel=wiring.reference_channel(step.bare_table),
        reference_level_eu=settings.level_m_per_s2,
        source_limit_vpk=settings.source_limit_v,
        input_limit_eu=settings.force_limit_n if wiring.force_limit_acts_on_excitation else None,
        pairing=Wiring.PAIRING,
        resolution_hz=resolution,
        start_hz=float(band_hz[0]),
        stop_hz=float(band_hz[1]),
        settle_cycles=settle,
        integrate_cycles=integrate,
        direction=step.direction.upper(),
        tolerance_db=step.tolerance_db,
        start_level_vpk=min(settings.start_level_v, settings.source_limit_v),
        source_slew_v_per_s=settings.source_slew_v_per_s,
    )


def no_data(measured: MeasuredSegment) -> NDArray[np.bool_]:
    """Points where the driver flagged no data (the analyser's marker), if it says."""
    flags = getattr(measured, "no_data", None)
    count = np.asarray(measured.frequency_hz).size
    if flags is None:
        return np.zeros(count, dtype=bool)
    return np.asarray(flags, dtype=bool)


def iso_to_epoch(text: str) -> float | None:
    """An ISO 8601 time as seconds since the epoch (``None`` when it does not read)."""
    try:
        return datetime.fromisoformat(text.replace("Z", "+00:00")).timestamp()
    except ValueError:
        return None


def check_axis(measured: MeasuredSegment, frequencies: NDArray[np.float64],
               resource: str) -> None:
    """The analyser measured the frequencies asked for (within half its frequency step).

    Raises
    ------
    InstrumentError
        It did not.
    """
    axis = np.asarray(measured.frequency_hz, dtype=float)
    if axis.shape != frequencies.shape or not np.allclose(
        axis, frequencies, rtol=0.0, atol=FREQUENCY_MATCH_HZ
    ):
        shown = f"{axis.size} points" + (f" from {axis[0]:g} to {axis[-1]:g} Hz"
                                         if axis.size else "")
        raise InstrumentError(
            f"{resource}: the analyser returned {shown}; expected "
            f"{frequencies.size} from {frequencies[0]:g} to {frequencies[-1]:g} Hz"
        )


def check_piece(measured: MeasuredSegment, frequencies: NDArray[np.float64],
                resource: str) -> None:
    """The analyser measured ``frequencies``, or their first ones when it ended the sweep at a
    point boundary for a pause (``ended_early``).

    Raises
    ------
    InstrumentError
        Other frequencies than asked.
    """
    if getattr(measured, "ended_early", False):
        frequencies = frequencies[:np.asarray(measured.frequency_hz).size]
    check_axis(measured, frequencies, resource)


def segment_of(
    measured: MeasuredSegment,
    wiring: Wiring,
    settings: SweepSettings,
    time_s: NDArray[np.float64],
    cycles: tuple[NDArray[np.int64], NDArray[np.int64]] | None = None,
) -> Segment:
    """The storage segment of a measured one: FRFs by wiring, amplitudes, time, flags (and the
    per-point settle and integration cycles, when given)."""
    step = settings.step
    count = np.asarray(measured.frequency_hz).size
    excitation_first = wiring.excitation_force == 1
    frf_43 = measured.frf_43
    if frf_43 is None:
        frf_43 = np.full(count, complex(math.nan, math.nan))
    table, support = (measured.frf_21, frf_43) if excitation_first else (frf_43,
                                                                          measured.frf_21)
    amplitude, variance = measured.amplitude_eu, measured.variance
    nan = np.full(count, math.nan)
    reference_channel = wiring.reference_channel(step.bare_table)
    reference = np.asarray(amplitude.get(reference_channel, nan), dtype=float)
    force = np.asarray(amplitude.get(wiring.excitation_force, nan), dtype=float)

    def pair_variance(a: int, b: int) -> NDArray[np.float64]:
        if a in variance and b in variance:
            return np.asarray(variance[a], float) + np.asarray(variance[b], float)
        return nan

    variance_table = pair_variance(wiring.excitation_force, wiring.table_acceleration)
    variance_support = pair_variance(wiring.device_force, wiring.device_acceleration)
    if step.bare_table:
        support = np.full(count, complex(math.nan, math.nan))
        variance_support = nan
    flags = point_flags(
        reference, force,
        level_m_per_s2=settings.level_m_per_s2,
        tolerance_db=step.tolerance_db,
        force_limit_n=settings.force_limit_n,
        overloaded=bool(measured.overload_channels),
    )
    if wiring.force_limit_acts_on_excitation:
        # the input limit also holds the device force: a level missed while the device
        # force sat at the limit was held by the input limit, not by the source limit
        device = np.asarray(amplitude.get(wiring.device_force, nan), dtype=float)
        held = device >= settings.force_limit_n * 10.0 ** (-AT_FORCE_LIMIT_DB / 20.0)
        flags[held] &= np.uint16(~int(SOURCE_AT_LIMIT) & 0xFFFF)
    extra = {}
    temperatures = getattr(measured, "specimen_temperature_c", None)
    if temperatures is not None:  # a segment measured in a temperature chamber
        extra["temperature_c"] = (np.asarray(temperatures, dtype=float), "degC")
        outside = np.asarray(getattr(measured, "outside_soak_band", False), dtype=np.bool_)
        flags = np.where(outside, flags | np.uint16(OUTSIDE_SOAK_BAND), flags)
    return Segment(
        frequency_hz=np.asarray(measured.frequency_hz, dtype=float),
        time_s=time_s,
        accelerance_table=np.asarray(table, dtype=complex),
        accelerance_support=np.asarray(support, dtype=complex),
        reference_amplitude=reference,
        source_amplitude=nan,
        force_amplitude=force,
        flags=flags,
        variance_table=variance_table,
        variance_support=variance_support,
        settle_cycles=None if cycles is None else cycles[0],
        integrate_cycles=None if cycles is None else cycles[1],
        extra=extra,
    )


def point_times_s(
    measured: MeasuredSegment, durations_s: NDArray[np.float64], time_base: str
) -> NDArray[np.float64]:
    """Rig time each point took: its settle and integration on a simulated rig's test clock;
    on a real one the segment's wall-clock time shared out in proportion to them, never less
    than them (no point takes less than its settle and integration; an analyser that answers
    faster is a simulation)."""
    durations = np.asarray(durations_s, dtype=float)
    if time_base == "test":
        return durations
    wall = float(measured.finished_at_s) - float(measured.started_at_s)
    if not (math.isfinite(wall) and wall > 0):
        return durations
    return np.maximum(wall * durations / durations.sum(), durations)
