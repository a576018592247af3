"""Sentences for people: what is missing, on which channel, how much (with its ±), what to do,
which run would decide."""

from __future__ import annotations

import math

from viscorig.diagnosis.data import DiagnosisData
from viscorig.diagnosis.findings import Finding, inherited_confusion
from viscorig.diagnosis.screening import RECORDED_DRIFT_K
from viscorig.models.sensors import CHANNELS
from viscorig.numbers import with_uncertainty


def _estimate(finding: Finding, local: str) -> tuple[float, float]:
    """Value and stderr of the added parameter with local name ``local`` (``_1``... allowed)."""
    for name, estimate in finding.parameters().items():
        suffix = name[len(local) + 1 :]
        if name == local or (name.startswith(local + "_") and suffix.isdigit()):
            return float(estimate["value"]), float(estimate["stderr"])
    return math.nan, math.nan


def _pm(value: float, stderr: float, scale: float = 1.0) -> str:
    """``value ± stderr`` in a unit ``scale`` times smaller."""
    return with_uncertainty(value * scale, stderr * scale)


def _channel_of(term: str):
    inside = term[term.index("(") + 1 : term.index(")")] if "(" in term else ""
    return CHANNELS.get(inside)


#: A sensor gain smaller than this (per cent) is below what a transducer's calibration
#: resolves: no sensor is to be checked for it.
CALIBRATION_RESOLUTION_PERCENT = 0.1


def _sensor(finding: Finding) -> str:
    effect, why, term = finding.effect, finding.evidence, finding.term
    channel = _channel_of(term)
    if term == "delay":
        tau, se = _estimate(finding, "tau_d")
        return (
            f"Both accelerometers lag the force channels by {_pm(tau, se, 1e6)} µs (their "
            f"conditioning or filters): {why}. Use the same conditioning on force and "
            f"acceleration channels, or keep `{term}` in the model."
        )
    if channel is None:
        return why
    others = [c for c in CHANNELS.values() if c.frf == channel.frf and c is not channel]
    partner = others[0]
    if effect == "sensor_delay" and term.startswith("lowpass"):
        corner, se = _estimate(finding, f"f_lp_{channel.name}")
        lag = 1e6 / (2 * math.pi * corner)
        return (
            f"The {channel.label} ({channel.quantity}) is low-pass filtered with a corner near "
            f"{_pm(corner, se)} Hz, a lag of about {lag:.0f} µs that also lowers its "
            f"magnitude at high frequency (an anti-alias filter or a long cable): {why}. Check "
            f"its conditioning against the {partner.label}'s, or add `{term}` to the model."
        )
    if effect == "sensor_delay":
        tau, se = _estimate(finding, f"tau_{channel.name}")
        return (
            f"The {channel.label} ({channel.quantity}) lags the {partner.label} "
            f"({partner.quantity}) by {_pm(tau, se, 1e6)} µs (a filter or cable): {why}. Match "
            f"the two channels' conditioning, or add `{term}` to the model."
        )
    if effect == "sensor_highpass":
        corner, se = _estimate(finding, f"f_hp_{channel.name}")
        return (
            f"The {channel.label} ({channel.quantity}) is high-pass filtered with a corner at "
            f"{_pm(corner, se)} Hz (a charge amplifier's time constant, "
            f"{1 / (2 * math.pi * corner):.2g} s): {why}. Set a longer time constant on its "
            f"amplifier, or add `{term}` to the model."
        )
    if effect == "sensor_gain":
        gain, se = _estimate(finding, f"gain_{channel.name}")
        change = (gain - 1) * 100
        direction = "high" if change > 0 else "low"
        opposite = "low" if change > 0 else "high"
        reads = (f"The {channel.label} ({channel.quantity}) reads {_pm(abs(change), se * 100)} "
                 f"% {direction} against the {partner.label} ({partner.quantity}), or that one "
                 f"reads {opposite}: {why}.")
        if abs(change) < CALIBRATION_RESOLUTION_PERCENT:
            return (
                f"{reads} So small a gain is below what any transducer calibration resolves "
                f"(primary calibrations are good to about {CALIBRATION_RESOLUTION_PERCENT:g} "
                "%): it more likely stands for a small misfit elsewhere (the table's inherited "
                f"values, an effect the model lacks) than for a sensor to recalibrate. `{term}` "
                "in the model takes it up."
            )
        return (f"{reads} Check both sensitivities (calibration, the analyser's engineering "
                f"units), or add `{term}` to the model.")
    return why


def explain(finding: Finding, data: DiagnosisData) -> str:
    """One or two sentences a technician can act on, for one finding (and, when these data
    cannot tell it from an error of the table's inherited values, a sentence that says so)."""
    text = _explain(finding, data)
    if finding.significant:
        confusion = inherited_confusion(finding, data)
        if confusion is not None:
            name, share = confusion
            source = data.table_prior.source if data.table_prior is not None else ""
            text += (
                f" These data cannot tell it well from an error of the table's {name} "
                f"inherited from {source or 'the bare-table run'}: {share * 100:.0f} % of its "
                f"uncertainty is that value's; a longer or finer bare-table run would decide."
            )
    return text


def _explain(finding: Finding, data: DiagnosisData) -> str:
    effect = finding.effect
    why = finding.evidence
    if not finding.significant:
        return (
            f"No clear sign of {effect.replace('_', ' ')}: adding {finding.term} leaves the "
            f"error at {finding.rms_error:.3g}; {finding.note or 'it is not significant'}."
        )
    if effect.startswith("sensor_"):
        return _sensor(finding)
    if effect == "fixture_resonance":
        f_n, f_se = _estimate(finding, "f_n")
        zeta, _ = _estimate(finding, "zeta")
        m, m_se = _estimate(finding, "m")
        return (
            f"A local mode at {_pm(f_n, f_se)} Hz ({_pm(m, m_se, 1e3)} g, damping "
            f"{zeta * 100:.2g} %) rings with the disc: {why}. Tap-test the disc, bolts, load "
            f"cell and sensor mounts for a part resonating near {f_n:.0f} Hz and tighten or "
            f"stiffen it, or keep fixture({f_n:.2f}) in the model."
        )
    if effect == "load_cell_compliance":
        k_c, se = _estimate(finding, "K_c")
        return (
            "The link between table and device is not rigid "
            f"(K_c = {with_uncertainty(k_c, se, 'N/m')}): "
            f"{why}. Stiffen the load cell's linkage (stinger, bolts) or keep load_cell in the "
            "model; use the support FRF (Eq. 5) for K*, which does not need a rigid link."
        )
    if effect == "frame_mode":
        mass, mass_se = _estimate(finding, "M_f")
        f_g, f_se = _estimate(finding, "f_g")
        return (
            f"The inertial frame under the table moves on its isolators (a mode near "
            f"{_pm(f_g, f_se)} Hz of a frame of about {with_uncertainty(mass, mass_se, 'kg')}): "
            f"{why}. It "
            "makes the table and the specimens read stiffer; fit the bare-table run with "
            "`frame` too, or keep `frame` in the model, and measure well above the frame's mode."
        )
    if effect == "frequency_dependent_modulus":
        return (
            f"The rubber's stiffness and damping change with frequency: {why}. A Voigt spring "
            f"and dashpot cannot follow that; use {finding.term} for K*."
        )
    if effect == "amplitude_dependence":
        beta, se = _estimate(finding, "beta")
        change = (1 - 2 ** (-beta)) * 100
        change_se = abs(math.log(2) * 2 ** (-beta) * se) * 100
        return (
            f"The rubber's stiffness depends on the vibration amplitude "
            f"({_pm(abs(change), change_se)} % {'softer' if change > 0 else 'stiffer'} per "
            f"doubling of displacement): {why}. Report K* with the amplitude it was measured "
            "at, or test at the amplitude of use."
        )
    if effect == "thermal_drift":
        gamma, gamma_se = _estimate(finding, "gamma")
        recorded = data.temperature_range_c.get(data.run)
        if math.isfinite(gamma) and recorded is not None:
            return (
                f"The modulus changes by {_pm(gamma, gamma_se, 100)} % per kelvin of the "
                f"specimen's recorded temperature, which moved from {recorded[0]:.1f} to "
                f"{recorded[1]:.1f} °C during the run (its temperature_c dataset): {why}. The "
                "sweep started before the specimens had soaked: soak longer (a narrower soak "
                f"band, more soak minutes) before sweeping, or keep {finding.term} in the model.")
        kappa, se = _estimate(finding, "kappa")
        drift = f"The modulus drifts by {_pm(kappa, se, 3600 * 100)} % per hour of test: {why}."
        if recorded is not None and recorded[1] - recorded[0] >= RECORDED_DRIFT_K:
            return (
                f"{drift} The specimen's recorded temperature moved from {recorded[0]:.1f} to "
                f"{recorded[1]:.1f} °C during the run (its temperature_c dataset): the sweep "
                "started before the specimens had soaked. Soak longer (a narrower soak band, "
                "more soak minutes) before sweeping.")
        if recorded is not None:
            return (
                f"{drift} The specimen's recorded temperature held within "
                f"{recorded[1] - recorded[0]:.1f} K, so it is not the rubber's temperature: "
                "look for a transducer or amplifier warming up, or keep drift in the model.")
        return (
            f"{drift} Let the specimens settle thermally before sweeping (a wait step), record "
            "the temperature, or keep drift in the model."
        )
    return why


def extra_runs(finding: Finding, data: DiagnosisData) -> list[str]:
    """Runs that would separate the finding from its alternatives (sequence step wording)."""
    advice = []
    effects = {finding.effect, *finding.alternatives}
    level = data.segments[0].level_m_per_s2
    run = data.run
    if "amplitude_dependence" in effects and len(data.levels) < 2:
        advice.append(
            f"measure the same specimen at a second level: a sweep step with run = "
            f"\"{run}-level2\" and level = \"{2 * level:.3g} m/s^2\" (amplitude dependence "
            "changes with the level, a frequency-dependent modulus does not)"
        )
    if "thermal_drift" in effects and len(data.directions) < 2:
        other = "down" if data.directions[0] == "up" else "up"
        advice.append(
            f"sweep the same specimen the other way: a sweep step with run = \"{run}-{other}\" "
            f"and direction = \"{other}\" (a drift reverses along the band, the other effects "
            "do not)"
        )
    return advice
