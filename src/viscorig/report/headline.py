"""The answer first: for one run, the model reached, its error against the noise, the main
parameters with their ±, where it still fails, and the finding in one sentence.

Shared by the report page and the notebook API, so both say the same thing in the same words.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from viscorig.compare import kstar_at
from viscorig.numbers import with_uncertainty
from viscorig.report.analysis import RunAnalysis
from viscorig.report.words import (
    at_floor,
    error_words,
    finding_sentence,
    times,
)
from viscorig.storage import RunRecord

#: Names of the FRFs for people.
FRF_WORDS = {"table": "table FRF ẍ_s/F_e", "support": "disc FRF ẍ_v/F_v"}
#: Parameters shown as they are in a headline, when the model has them.
PLAIN_PARAMETERS = ("K_v", "C_v", "M_v", "M_s", "K_s", "C_s", "K_c")


@dataclass
class Headline:
    """The first things to say about a run."""

    run: str
    what: str
    """Specimen, preload, status in a few words."""
    model: str
    """Spec of the model shown ("" when none)."""
    source: str
    error: str
    """Its error against the noise, in words."""
    ratio: float
    parameters: list[str] = field(default_factory=list)
    """Main parameters with ±, one string each."""
    fails: str = ""
    finding: str = ""
    at_floor: bool = False


def describe_specimen(run: RunRecord, bare: bool) -> str:
    """``"soft, 25 Shore A, preload 0.104"``, or ``"bare table"``."""
    m = run.metadata
    if bare:
        return "bare table"
    text = m.specimen + (f", {m.hardness_shore_a:g} Shore A"
                         if math.isfinite(m.hardness_shore_a) else "")
    return text + (f", preload {m.preload_strain:g}" if m.preload_strain else ", no preload")


def describe_run(run: RunAnalysis) -> str:
    """The specimen in a few words, plus the status when the run is not complete."""
    text = describe_specimen(run.run, run.bare)
    m = run.run.metadata
    if m.status != "complete":
        text += f" ({m.status}, {run.run.points} points)"
    return text


def main_parameters(run: RunAnalysis) -> list[str]:
    """The parameters a reader wants first, with ±.

    Voigt and the bare table: their parameters. Any other K*: ``K'`` and ``η`` at both ends of
    the band (propagated from the fit's covariance), then the disc mass and the link.
    """
    shown = run.shown
    if shown is None:
        return []
    parameters = shown.parameters
    out = []
    kstar_term = shown.model.modulus_term
    if shown.has_disc and kstar_term is not None and kstar_term.keyword != "voigt":
        lo, hi = run.band_hz
        try:
            (k_lo, u_k_lo), (eta_lo, u_eta_lo) = kstar_at(shown, lo)
            (k_hi, u_k_hi), (eta_hi, u_eta_hi) = kstar_at(shown, hi)
        except (ValueError, ArithmeticError, KeyError):
            pass
        else:
            out.append(f"K′ {with_uncertainty(k_lo, u_k_lo, 'N/m')} → "
                       f"{with_uncertainty(k_hi, u_k_hi, 'N/m')}")
            out.append(f"η {with_uncertainty(eta_lo, u_eta_lo)} → "
                       f"{with_uncertainty(eta_hi, u_eta_hi)} ({lo:g} → {hi:g} Hz)")
    for name in PLAIN_PARAMETERS:
        if name not in parameters or (name in ("M_s", "K_s", "C_s") and not run.bare):
            continue
        value, stderr, unit = parameters[name]
        stderr = stderr if name in shown.free else math.nan
        out.append(f"{name} {with_uncertainty(value, stderr, unit)}")
    return out


def failure_words(run: RunAnalysis, most: int = 2) -> str:
    """Where the model shown still fails, in a few words (the first band described)."""
    if run.climb is None:
        return "not diagnosed" if not run.bare else "–"
    bands = run.failures
    if not bands:
        shown = run.shown
        if shown is not None and at_floor(shown.rms_error, shown.noise_floor):
            return "nowhere: at the noise floor, what is left is noise"
        return "nowhere above the noise"
    first = bands[0]
    parts = [f"{FRF_WORDS.get(first.frf, first.frf)} {first.band_hz[0]:.0f}–"
             f"{first.band_hz[1]:.0f} Hz: {first.what}"]
    parts += [f"{FRF_WORDS.get(b.frf, b.frf).split(' ')[0]} {b.band_hz[0]:.0f}–"
              f"{b.band_hz[1]:.0f} Hz" for b in bands[1:most]]
    more = f" and {len(bands) - most} more" if len(bands) > most else ""
    return "; ".join(parts) + more


def finding(run: RunAnalysis) -> str:
    """The run's finding in one sentence."""
    shown = run.shown
    if run.bare:
        if shown is None:
            return "Too few points to identify the table."
        values = shown.values
        if {"M_s", "K_s"} <= set(values):
            # a stored fit is shown only with values of the right sign (identify.read_fit)
            f_n = math.sqrt(values["K_s"] / values["M_s"]) / (2 * math.pi)
            return (f"The table suspension rings at {f_n:.2f} Hz; its M_s, K_s and C_s are held "
                    "fixed in every specimen fit.")
        return "The table suspension, identified on its own."
    if run.climb is None:
        if run.diagnosis_error:
            return f"Not diagnosed: {run.diagnosis_error}."
        return "Not diagnosed."
    climb = run.climb
    removed = {term for rung in climb.rungs for term in rung.removed}
    effects = [(added.effect, added.term) for rung in climb.rungs[1:] for added in rung.added
               if added.term not in removed]
    missing = (climb.missing[0].effect, climb.missing[0].term) if climb.missing else None
    return finding_sentence(climb.rungs[0].model, effects, climb.final.values,
                            climb.final.rms_error, climb.final.noise_floor, missing,
                            climb.climbed)


def headline(run: RunAnalysis) -> Headline:
    """The headline of one run."""
    shown = run.shown
    if shown is None:
        return Headline(run.name, describe_run(run), "", "", "no model", math.nan,
                        fails=failure_words(run), finding=finding(run))
    ratio = (shown.rms_error / shown.noise_floor if shown.noise_floor > 0 else math.nan)
    return Headline(run.name, describe_run(run), shown.spec, shown.source,
                    error_words(shown.rms_error, shown.noise_floor), ratio,
                    main_parameters(run), failure_words(run), finding(run),
                    at_floor(shown.rms_error, shown.noise_floor))


__all__ = ["FRF_WORDS", "Headline", "describe_run", "failure_words", "finding", "headline",
           "main_parameters", "times"]
