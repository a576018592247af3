"""Before a run: the force it will need, and the level it may run at (plan steps).

The prediction comes from:

- a low-level probe (:mod:`viscorig.acquisition.probe`) whenever the mounting may have changed
  since the last run measured (after a prompt, or at the start of a session): the measured
  dynamic stiffness at the band's edges plus the known table;
- the previous run's specimen when no prompt came between (same mounting);
- the table alone for a bare-table run whose table is known (station, identified run, /rig).

A sweep predicted over the shaker limit is refused or run at a reduced level (the sweep's
``over_limit``, or the command line's). A probe whose reference reads nothing that could be real
refuses the run and names what to check, instead of advising an absurd level.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from viscorig.acquisition import stubs
from viscorig.acquisition.engine import Plan, RunRefused
from viscorig.acquisition.limits import (
    DEAD_REFERENCE_DB,
    PROBE_LEVEL_FRACTION,
    UNDRIVEN_FORCE_FRACTION,
    ForceEstimate,
    ProbeReading,
    estimate_force,
    estimate_force_from_probe,
    motion_ratio,
    specimen_from_accelerance,
)
from viscorig.acquisition.probe import probe_frequencies_hz, probe_settings, probe_test_time_s
from viscorig.acquisition.session import Session
from viscorig.sequences import SweepStep

__all__ = ["ABSURD_REDUCTION", "MAX_MOTION_RATIO", "learn_from_run", "level_for", "predict"]

#: The table cannot move this many times more than the disc linked to it through a load cell
#: (about 1.1 times for the paper's hard rubber under preload); a probe that says so misread.
MAX_MOTION_RATIO = 10.0
#: Advice to run at a level this many times below the one asked for is never given: a reading
#: that leads there is a sign of wrong wiring or mounting, and says so instead.
ABSURD_REDUCTION = 1000.0


def learn_from_run(session: Session, step: SweepStep) -> Plan:
    """Keep a rough specimen stiffness from a finished specimen run (read from the file)."""
    if step.bare_table or session.table is None:
        return
    if (yield from stubs.status(step.run, "learn")) is None:
        return
    run = (yield from stubs.read_run(step.run, "learn")).merged()
    keep = run.flags == 0
    found = specimen_from_accelerance(run.frequency_hz[keep], run.accelerance_table[keep],
                                      session.table)
    if found is not None:
        ratio = motion_ratio(run.accelerance_table[keep], run.force_amplitude[keep],
                             run.reference_amplitude[keep])
        session.specimen = (*found, ratio, step.run)


def level_for(session: Session, step: SweepStep) -> Plan:
    """The level a new run is measured at: predicted, and reduced below the shaker's limit if
    the step allows. Returns ``(level, estimate or None)``.

    Raises
    ------
    RunRefused
        Over the limit and refused, or a probe that cannot be right.
    """
    level = step.level_m_per_s2
    estimate = yield from predict(session, step, level)
    if estimate is not None and estimate.peak_n > session.station.shaker_force_limit_n:
        level = yield from _over_limit(session, step, estimate)
    return level, estimate


def predict(session: Session, step: SweepStep, level: float) -> Plan:
    """The force a new run will need (see the module text), printed with where it comes
    from; ``None`` when nothing is known."""
    known_table = step.bare_table and session.table is not None
    same_mounting = (not step.bare_table and session.mounting_known
                     and session.specimen is not None)
    if known_table or same_mounting:
        return (yield from _estimate(session, step, level))
    estimate = yield from _probe(session, step, level)
    if estimate is None:
        return (yield from _estimate(session, step, level, "the probe gave no usable reading; "))
    yield from _say_estimate(session, step, estimate)
    return estimate


def _probe(session: Session, step: SweepStep, level: float) -> Plan:
    """Measure the probe points of a newly mounted rig and predict from them."""
    frequencies = " and ".join(f"{f:g}" for f in probe_frequencies_hz(step))
    lowest = session.wiring.lowest_reference_level(step.bare_table)
    probe_level = probe_settings(session.sweep_settings(step, level), lowest).level_m_per_s2
    why = ("a tenth of the level" if probe_level <= level * PROBE_LEVEL_FRACTION * (1 + 1e-9)
           else "the lowest level the analyser's auto level holds")
    yield from stubs.say(
        f"run '{step.run}': newly mounted; probing at {frequencies} Hz at "
        f"{probe_level:.3g} m/s^2 ({why}; {probe_test_time_s(step):.0f} s "
        "of test time, not part of the run)", "probe")
    readings = yield from stubs.probe(session.sweep_settings(step, level), "probe")
    for reading in readings:
        stiffness = complex(reading.dynamic_stiffness_n_per_m)
        yield from stubs.say(
            f"  probe {reading.frequency_hz:g} Hz: |F_e/X_s| {abs(stiffness):.4g} N/m, "
            f"force {reading.force_n:.3g} N at {reading.reference_m_per_s2:.3g} m/s^2"
            + ("" if reading.usable else "  (not usable)"), "probe")
    _check_probe(session, step, readings)
    if not readings[0].usable:
        return None
    table = ("the table unknown" if session.table is None
             else f"the table of {session.table.basis}")
    basis = f"a probe of the mounted rig at {frequencies} Hz and {table}"
    return estimate_force_from_probe(_grid(step), level, readings, session.table, basis)


def _grid(step: SweepStep):
    """The frequencies the run may measure (a full plan's grid; an adaptive plan's band)."""
    if step.adaptive:
        return np.array(probe_frequencies_hz(step))
    return step.frequencies_hz()


def _check_probe(session: Session, step: SweepStep, readings: tuple[ProbeReading, ...]) -> None:
    """Refuse a run whose probe shows that the reference does not see the rig it drives:
    a reference :data:`DEAD_REFERENCE_DB` or more below the level asked for, or a table
    moving more than :data:`MAX_MOTION_RATIO` times the disc linked to it.

    Raises
    ------
    RunRefused
        With what was read and what to check.
    """
    def dead(reading: ProbeReading) -> bool:
        ratio = reading.motion_ratio
        return reading.shortfall_db >= DEAD_REFERENCE_DB or (
            not step.bare_table and math.isfinite(ratio) and ratio > MAX_MOTION_RATIO)

    reading = next((r for r in readings if dead(r)), None)
    if reading is None:
        return
    wiring = session.wiring
    if step.bare_table:
        name, channel = "table", wiring.table_acceleration
    else:
        name, channel = "disc", wiring.device_acceleration
    sensitivity = wiring.sensitivities_v_per_eu[channel]
    read = (f"run '{step.run}': the probe at {reading.frequency_hz:g} Hz asked "
            f"{reading.level_m_per_s2:.3g} m/s^2 of the {name} accelerometer (input "
            f"{channel}) and read {reading.reference_m_per_s2:.2g} m/s^2 "
            f"({reading.shortfall_db:.0f} dB short) while the shaker gave "
            f"{reading.force_n:.3g} N")
    check = (f"the {name} accelerometer is on input {channel} with the sensitivity the "
             f"station file gives ({sensitivity:g} V/(m/s^2))")
    if not reading.force_n >= UNDRIVEN_FORCE_FRACTION * session.station.shaker_force_limit_n:
        why = ("the shaker is hardly driven. Check the amplifier (on, gain), the cable from "
               f"the analyser's source, and that {check}")
    elif step.bare_table:
        why = f"the table accelerometer does not see the motion. Check that {check}"
    else:
        why = (f" and the table {reading.table_acceleration_m_per_s2:.3g} m/s^2: the disc "
               f"cannot move {reading.motion_ratio:.3g} times less than the table it is "
               "linked to. The wiring or the mounting is wrong: check that the damper device "
               f"is mounted and linked to the table, and that {check}")
    separator = "" if why.startswith(" ") else ": "
    raise RunRefused(f"{read}{separator}{why}. Nothing was measured")


def _say_estimate(session: Session, step: SweepStep, estimate: ForceEstimate) -> Plan:
    yield from stubs.say(
        f"run '{step.run}': estimated force up to {estimate.peak_n:.3g} N at "
        f"{estimate.peak_frequency_hz:g} Hz (shaker limit "
        f"{session.station.shaker_force_limit_n:g} N; from {estimate.basis})", "predict")


def _estimate(session: Session, step: SweepStep, level: float, why: str = "") -> Plan:
    if session.table is None:
        yield from stubs.warn(
            f"run '{step.run}': {why}table parameters unknown (no [table] in the station, no "
            "identified table run): no force estimate", "predict")
        return None
    rig = session.table
    if not step.bare_table:
        if session.specimen is None:
            rig = replace(rig, basis=f"{why}{rig.basis} only; specimen unknown, a lower bound")
        else:
            stiffness, damping, mass, ratio, source = session.specimen
            same = "" if why else " (same mounting)"
            rig = replace(rig, specimen_stiffness_n_per_m=stiffness,
                          specimen_damping_ns_per_m=damping, specimen_mass_kg=mass,
                          motion_ratio=ratio,
                          basis=f"{why}{rig.basis} and the specimen of run '{source}'{same}")
    else:
        rig = replace(rig, basis=f"{why}{rig.basis}")
    estimate = estimate_force(_grid(step), level, rig)
    yield from _say_estimate(session, step, estimate)
    return estimate


def _over_limit(session: Session, step: SweepStep, estimate: ForceEstimate) -> Plan:
    """The level to run at when the estimate exceeds the shaker limit.

    Raises
    ------
    RunRefused
        The sweep refuses (``over_limit``), or the level that would fit is absurdly low.
    """
    limit = session.station.shaker_force_limit_n
    reduced = estimate.level_for(limit, step.level_m_per_s2)
    what = (f"run '{step.run}': estimated force {estimate.peak_n:.3g} N at "
            f"{estimate.peak_frequency_hz:g} Hz exceeds the shaker limit {limit:g} N "
            f"(level {step.level}; estimate from {estimate.basis})")
    yield from stubs.warn(what, "over limit")
    if reduced * ABSURD_REDUCTION < step.level_m_per_s2:
        raise RunRefused(
            f"{what}; not measured. Holding it under the limit would need "
            f"{reduced:.2g} m/s^2, over {ABSURD_REDUCTION:g} times below the level asked "
            "for: no specimen is that stiff, so the estimate rests on readings that cannot "
            "be right. The wiring or the mounting is wrong: check that the device is "
            "mounted and each transducer is on the input the station file names")
    mode, source = session.over_limit_mode(step)
    chosen = "--over-limit" if source == "command line" else "over_limit in the sequence"
    if mode == "reduce":
        yield from stubs.warn(f"run '{step.run}': level reduced to {reduced:.4g} m/s^2 "
                              f"(requested {step.level}; {chosen} is \"reduce\")", "over limit")
        return reduced
    raise RunRefused(
        f"{what}; not measured ({chosen} is \"refuse\"). Lower the level, set "
        f"over_limit = \"reduce\" in the sequence, or continue with: viscorig resume "
        f"{session.campaign_path} --over-limit reduce (level {reduced:.3g} m/s^2)"
    )
