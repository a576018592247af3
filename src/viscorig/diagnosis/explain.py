"""Sentences for people: what is missing, why we think so, what to do, which run would decide."""

from __future__ import annotations

from viscorig.diagnosis.data import DiagnosisData
from viscorig.diagnosis.findings import Finding


def _value(finding: Finding, local: str) -> float:
    """Value of the added parameter with local name ``local`` (suffix ``_1``, ``_2`` allowed)."""
    for name, estimate in finding.parameters().items():
        suffix = name[len(local) + 1 :]
        if name == local or (name.startswith(local + "_") and suffix.isdigit()):
            return float(estimate["value"])
    return float("nan")


def explain(finding: Finding, data: DiagnosisData) -> str:
    """One or two sentences a technician can act on, for one finding."""
    effect = finding.effect
    why = finding.evidence
    if not finding.significant:
        return (
            f"No clear sign of {effect.replace('_', ' ')}: adding {finding.term} leaves the "
            f"error at {finding.rms_error:.3g} (ΔBIC {finding.delta_bic:+.0f}), within what "
            "noise explains."
        )
    if effect == "fixture_resonance":
        f_n, zeta, m = (_value(finding, p) for p in ("f_n", "zeta", "m"))
        return (
            f"A local mode near {f_n:.1f} Hz ({m * 1e3:.2g} g, damping {zeta * 100:.1g} %) rings "
            f"with the disc: {why}. Tap-test the disc, bolts, load cell and sensor mounts for a "
            f"part resonating near {f_n:.0f} Hz and tighten or stiffen it, or keep "
            f"fixture({f_n:.2f}) in the model."
        )
    if effect == "load_cell_compliance":
        k_c = _value(finding, "K_c")
        return (
            f"The link between table and device is not rigid (K_c = {k_c:.3g} N/m): {why}. "
            "Stiffen the load cell's linkage (stinger, bolts) or keep load_cell in the model; "
            "use the support FRF (Eq. 5) for K*, which does not need a rigid link."
        )
    if effect == "sensor_delay":
        tau = _value(finding, "tau_d")
        lagging = "response (acceleration)" if tau > 0 else "force"
        return (
            f"The {lagging} channel lags by {abs(tau) * 1e6:.1f} µs: {why}. Check that force "
            "and acceleration channels use the same conditioning (filters, amplifier settings, "
            "cable lengths), or keep delay in the model."
        )
    if effect == "frequency_dependent_modulus":
        return (
            f"The rubber's stiffness and damping change with frequency: {why}. A Voigt spring "
            f"and dashpot cannot follow that; use {finding.term} for K*."
        )
    if effect == "amplitude_dependence":
        beta = _value(finding, "beta")
        change = (1 - 2 ** (-beta)) * 100
        return (
            f"The rubber's stiffness depends on the vibration amplitude ({abs(change):.2g} % "
            f"{'softer' if change > 0 else 'stiffer'} per doubling of displacement): {why}. "
            "Report K* with the amplitude it was measured at, or test at the amplitude of use."
        )
    if effect == "thermal_drift":
        kappa = _value(finding, "kappa")
        return (
            f"The modulus drifts by {kappa * 3600 * 100:+.2f} % per hour of test: {why}. Let "
            "the specimens settle thermally before sweeping (a wait step), record the "
            "temperature, or keep drift in the model."
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
