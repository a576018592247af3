"""A low-level probe of a newly mounted rig: its dynamic stiffness at the band's edges.

Before the first sweep on a newly mounted specimen nothing measured tells how stiff it is: an
estimate carried over from the previous specimen can be several times too low (a hard rubber
after a medium one). So the runner measures one point at each edge of the band, in manual
sweep mode, at a tenth of the run's level (:data:`~viscorig.acquisition.limits.
PROBE_LEVEL_FRACTION`), with the run's own source and input limits set first, and reads the
rig's dynamic stiffness ``F_e/X_s`` there. The table accelerance ``ẍ_s/F_e`` is a ratio of two
channels, valid whatever level the controller reached, so even a probe held back by the limits
gives the stiffness.

Probe points are not run data (the run's datasets are fixed by data-format.md and the probe is
at another level): the runner records them as attributes of the run it precedes.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from numpy.typing import ArrayLike

from viscorig.acquisition.limits import PROBE_LEVEL_FRACTION, ProbeReading, point_flags
from viscorig.acquisition.protocol import Analyser, MeasuredSegment, SweepProgressReport
from viscorig.acquisition.sweep import (
    FREQUENCY_MATCH_HZ,
    SweepHooks,
    SweepInterrupted,
    SweepSettings,
    Wiring,
    configure,
)
from viscorig.analyser import FREQUENCY_STEP_HZ
from viscorig.errors import InstrumentError
from viscorig.sequences import SweepStep, point_durations_s

#: Frequencies the analyser sets are multiples of this (Hz).
#: Settle and integration of a probe point before an adaptive plan, whose own are bounds:
#: enough to settle a damping ratio of a few hundredths, integrated as the plan's first look.
ADAPTIVE_PROBE_CYCLES = (100, 10)


def probe_frequencies_hz(step: SweepStep) -> tuple[float, ...]:
    """The band's lowest and highest grid frequencies (one when the grid has one point); for
    an adaptive plan, the band's edges as the analyser sets them."""
    if step.adaptive:
        lo = math.ceil(step.band_hz[0] / FREQUENCY_STEP_HZ - 1e-9) * FREQUENCY_STEP_HZ
        hi = math.floor(step.band_hz[1] / FREQUENCY_STEP_HZ + 1e-9) * FREQUENCY_STEP_HZ
    else:
        grid = step.frequencies_hz()
        lo, hi = float(grid.min()), float(grid.max())
    return (lo,) if hi <= lo else (lo, hi)


def probe_cycles(step: SweepStep) -> tuple[int, int]:
    """Settle and integration cycles of a probe point before ``step``: the step's own, or for an
    adaptive plan :data:`ADAPTIVE_PROBE_CYCLES` within its bounds."""
    if not step.adaptive and step.settle_cycles is not None \
            and step.integrate_cycles is not None:
        return step.settle_cycles, step.integrate_cycles
    settle, integrate = ADAPTIVE_PROBE_CYCLES
    if step.settle_cycles is not None:
        settle = min(settle, step.settle_cycles)
    if step.integrate_cycles is not None:
        integrate = min(integrate, step.integrate_cycles)
    return settle, integrate


def probe_test_time_s(step: SweepStep) -> float:
    """Settle and integration time of a probe before ``step``, s."""
    frequencies = np.array(probe_frequencies_hz(step))
    return float(point_durations_s(frequencies, *probe_cycles(step)).sum())


def probe_settings(settings: SweepSettings, lowest_level_m_per_s2: float = 0.0
                   ) -> SweepSettings:
    """The run's settings at :data:`PROBE_LEVEL_FRACTION` of its level, with the same source and
    input limits, the controller starting as far down; never below ``lowest_level_m_per_s2``
    (the lowest the analyser's auto level holds, :meth:`Wiring.lowest_reference_level`) nor
    above the run's level."""
    level = min(settings.level_m_per_s2,
                max(settings.level_m_per_s2 * PROBE_LEVEL_FRACTION, lowest_level_m_per_s2))
    fraction = level / settings.level_m_per_s2
    return replace(settings, level_m_per_s2=level,
                   start_level_v=settings.start_level_v * fraction)


def measure_probe(
    analyser: Analyser,
    wiring: Wiring,
    settings: SweepSettings,
    hooks: SweepHooks | None = None,
) -> tuple[ProbeReading, ...]:
    """Configure the analyser for a probe of ``settings.step`` and measure its points.

    ``settings`` are the run's (its level, limits and cycles); the probe runs at
    :func:`probe_settings` of them. A point whose input overloaded is measured once more. The
    analyser is left configured for the probe: configure it again before the sweep.

    Raises
    ------
    SweepInterrupted
        ``hooks.should_stop()`` turned true.
    InstrumentError
        The analyser measured another frequency than asked.
    Exception
        Whatever the driver raises on an instrument fault (the caller classifies it).
    """
    hooks = hooks or SweepHooks()
    low = probe_settings(settings, wiring.lowest_reference_level(settings.step.bare_table))
    if settings.step.adaptive:  # no grid of its own: the band's edges at the probe's cycles
        edges = probe_frequencies_hz(settings.step)
        settle, integrate = probe_cycles(settings.step)
        span = max(edges[-1] - edges[0], FREQUENCY_STEP_HZ)
        configure(analyser, wiring, low, band_hz=(edges[0], edges[0] + span), resolution_hz=span,
                  settle_cycles=settle, integrate_cycles=integrate)
    else:
        configure(analyser, wiring, low)
    readings = []
    for frequency in probe_frequencies_hz(settings.step):
        measured = _measure(analyser, frequency, low, hooks)
        if measured.overload_channels:
            measured = _measure(analyser, frequency, low, hooks)
        readings.append(_reading(measured, frequency, wiring, low))
    return tuple(readings)


def _measure(analyser: Analyser, frequency_hz: float, settings: SweepSettings,
             hooks: SweepHooks) -> MeasuredSegment:
    def progress(report: SweepProgressReport) -> None:
        if hooks.should_stop():
            analyser.abort()

    run = settings.step.run
    hooks.measuring[0] = True
    try:
        measured = analyser.measure_point(frequency_hz, progress=progress,
                                          poll_interval_s=settings.poll_interval_s)
    except Exception as error:
        if hooks.should_stop():
            raise SweepInterrupted(run) from error
        raise
    finally:
        hooks.measuring[0] = False
    if hooks.should_stop():
        raise SweepInterrupted(run)
    axis = np.asarray(measured.frequency_hz, dtype=float)
    if axis.shape != (1,) or not abs(axis[0] - frequency_hz) <= FREQUENCY_MATCH_HZ:
        raise InstrumentError(
            f"{analyser.resource}: the analyser returned {axis.size} points for the probe at "
            f"{frequency_hz:g} Hz" + (f" (at {axis[0]:g} Hz)" if axis.size == 1 else "")
        )
    return measured


def _first(values: object) -> float:
    array = np.asarray(values, dtype=float).ravel()
    return float(array[0]) if array.size else math.nan


def _reading(measured: MeasuredSegment, frequency_hz: float, wiring: Wiring,
             settings: SweepSettings) -> ProbeReading:
    step = settings.step
    table_frf: ArrayLike
    if wiring.excitation_force == 1:
        table_frf = measured.frf_21
    else:
        table_frf = measured.frf_43 if measured.frf_43 is not None else [math.nan]
    accelerance = complex(np.asarray(table_frf, dtype=complex).ravel()[0])
    omega = 2.0 * math.pi * frequency_hz
    with np.errstate(divide="ignore", invalid="ignore"):
        stiffness = complex(-(omega**2) / np.complex128(accelerance))
    reference_channel = (wiring.table_acceleration if step.bare_table
                         else wiring.device_acceleration)
    reference = _first(measured.amplitude_eu.get(reference_channel, [math.nan]))
    force = _first(measured.amplitude_eu.get(wiring.excitation_force, [math.nan]))
    flags = point_flags([reference], [force], level_m_per_s2=settings.level_m_per_s2,
                        tolerance_db=step.tolerance_db, force_limit_n=settings.force_limit_n,
                        overloaded=bool(measured.overload_channels))
    duration = point_durations_s(np.array([frequency_hz]), *probe_cycles(step))
    return ProbeReading(
        frequency_hz=float(measured.frequency_hz[0]),
        dynamic_stiffness_n_per_m=stiffness,
        level_m_per_s2=settings.level_m_per_s2,
        reference_m_per_s2=reference,
        force_n=force,
        flags=int(flags[0]),
        test_time_s=float(duration[0]),
    )
