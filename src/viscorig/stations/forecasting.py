"""The predicted test time of a sequence before anything moves, and the floors of its adaptive
steps on the embedded simulated rig (``viscorig plan``, ``run`` and the bench's queue)."""

from __future__ import annotations

import numpy as np

from viscorig.acquisition.forecast import Floor, forecast_sequence
from viscorig.sequences import PromptStep, Sequence, SweepStep
from viscorig.stations.opening import embedded_chamber_station

__all__ = ["FIRST_PRESET", "mounted_presets", "preset_floor", "sequence_forecast",
           "simulated_floors"]

#: Rig preset mounted before any prompt names one (as the embedded rig starts).
FIRST_PRESET = "table"
#: The sweep that describes a preset's rig for its floor: every hertz of the band, settled.
FLOOR_SWEEP_STEP_HZ = 1.0
FLOOR_SWEEP_CYCLES = (100, 20)


def sequence_forecast(sequence: Sequence, station, status=lambda run: None):
    """The forecast of every step (floors from the simulated presets without a station)."""
    floors = simulated_floors(sequence) if station is None else {}
    table_known = station is not None and station.table is not None
    force_limit = None if station is None else station.shaker_force_limit_n
    if station is None:
        from rigsim.rigfile import load_preset

        force_limit = load_preset(FIRST_PRESET).shaker.force_limit_n
    chamber = station.chamber if station is not None else None
    if station is None and sequence.soaks:
        chamber = embedded_chamber_station(sequence)
    thermal = {} if chamber is None else chamber.soak_forecast()
    return forecast_sequence(sequence, table_known=table_known, floors=floors,
                             force_limit_n=force_limit, status=status, **thermal)


def mounted_presets(sequence: Sequence) -> dict[str, str]:
    """The simulated rig preset each sweep measures: the last one a prompt mounted before it."""
    preset, out = FIRST_PRESET, {}
    for step in sequence.steps:
        if isinstance(step, PromptStep) and step.simulated_rig:
            preset = step.simulated_rig
        elif isinstance(step, SweepStep):
            out[step.run] = preset
    return out


def simulated_floors(sequence: Sequence) -> dict[str, Floor]:
    """The floor of every adaptive step on the preset it measures (:func:`preset_floor`)."""
    presets = mounted_presets(sequence)
    return {step.run: preset_floor(presets[step.run], step) for step in sequence.sweeps
            if step.adaptive}


def preset_floor(preset: str, step: SweepStep, seed: int = 1) -> Floor:
    """The floor of an adaptive step on a simulated rig preset.

    The rig is swept every :data:`FLOOR_SWEEP_STEP_HZ` over the step's band, settled, at the
    step's level (the simulator in the time domain, as the analyser measures); the step's model
    is fitted to it (the table at the preset's values), the noise of the points is estimated,
    and the optimal design for the step's targets gives the floor
    (:func:`viscorig.planning.design_bound`). A model that leaves the noise far behind (more
    than the plan's own limit) marks the floor a misfit: the plan will stop once it has covered
    the band.
    """
    from rigsim.rigfile import load_preset

    # keeps the command's start fast: scipy loads only for an adaptive step
    from viscorig.acquisition.adaptive import adaptive_settings
    from viscorig.fitting import fit
    from viscorig.planning import design_bound, fit_noise_forecast, point_noise_power, shared_noise
    from viscorig.stations.simpoints import SimulatedRig

    rig = load_preset(preset)
    simulated = SimulatedRig(rig, step.level_m_per_s2, seed=seed,
                             tolerance_db=step.tolerance_db)
    lo, hi = step.band_hz
    frequencies = np.arange(np.ceil(lo), np.floor(hi) + 1e-9, FLOOR_SWEEP_STEP_HZ)
    points = simulated.measure(frequencies, *FLOOR_SWEEP_CYCLES)
    table = rig.table
    fixed = None if step.bare_table else {"M_s": table.mass_kg, "K_s": table.stiffness_n_per_m,
                                          "C_s": table.damping_ns_per_m}
    settings = adaptive_settings(step, step.level_m_per_s2, fixed, rig.shaker.force_limit_n)
    result = fit(settings.spec, points.frf_data(preset), fixed=dict(fixed or {}),
                 noise=shared_noise(points), weighting="noise")
    power, source = point_noise_power(points, result.noise)
    noise = fit_noise_forecast(points, power, source)
    bound = design_bound(result.model, result.values, result.free, noise, step.level_m_per_s2,
                         step.band_hz, settings.targets, resolution_hz=settings.resolution_hz,
                         force_limit_n=rig.shaker.force_limit_n,
                         max_integrate_cycles=settings.integrate_cap)  # fmt: skip
    return Floor(bound.plan_time_s, bound.integration_floor_s,
                 misfit=result.misfit_scale > settings.misfit_limit,
                 source=f"simulated rig '{preset}'")
