"""Numbers and statistics in words, for people who read the report or a notebook.

The error against the noise floor ("at the noise floor", "240× the noise floor"), the weight of
evidence of a candidate effect ("strong evidence", "not worth its parameters"), a value with its
uncertainty to the digits the uncertainty allows ("152.6 ± 0.6 kN/m"), and the one-sentence
finding of a run, built from the rungs of its diagnosis ladder.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence

# "at the noise floor" is the diagnosis's own threshold
from viscorig.diagnosis import AT_FLOOR_RATIO

#: ``rms_error`` within this factor of the noise floor reads "close to the noise floor".
CLOSE_RATIO = 2.0
#: ΔBIC (whitened) below minus this is beyond noise.
SIGNIFICANT_DELTA_BIC = 20.0

def times(ratio: float) -> str:
    """``3.9×``, ``240×``: a ratio to a tenth below 10, whole above."""
    if not math.isfinite(ratio):
        return "?×"
    return f"{ratio:.1f}×" if ratio < 10 else f"{ratio:,.0f}×"


def error_words(rms_error: float, noise_floor: float) -> str:
    """How far a model is from the noise floor, in words."""
    if not (noise_floor > 0 and math.isfinite(rms_error)):
        return "error against the noise unknown"
    ratio = rms_error / noise_floor
    if ratio <= AT_FLOOR_RATIO:
        return f"at the noise floor ({times(ratio)})"
    if ratio <= CLOSE_RATIO:
        return f"close to the noise floor ({times(ratio)})"
    if ratio <= 10:
        return f"{times(ratio)} the noise floor"
    return f"far above the noise: {times(ratio)} the floor"


def at_floor(rms_error: float, noise_floor: float) -> bool:
    """Within :data:`AT_FLOOR_RATIO` of the noise floor."""
    return noise_floor > 0 and rms_error <= AT_FLOOR_RATIO * noise_floor


def evidence_words(delta_bic: float, significant: bool) -> str:
    """The weight of a candidate effect, from its whitened ΔBIC and the diagnosis's verdict."""
    if significant:
        return "strong evidence"
    if not math.isfinite(delta_bic) or delta_bic >= 0:
        return "no improvement"
    if delta_bic < -SIGNIFICANT_DELTA_BIC:
        return "real, but too small to matter"
    return "not worth its parameters"


def _spoken_list(items: Sequence[str]) -> str:
    items = list(items)
    if len(items) <= 1:
        return "".join(items)
    return ", ".join(items[:-1]) + " and " + items[-1]


_FIXTURE = re.compile(r"^fixture\(([-+0-9.e]+)\)\Z")


def effect_phrases(effects: Sequence[tuple[str, str]], values: dict[str, float]) -> list[str]:
    """Phrases for the effects a ladder added: ``[(effect, term), ...]`` with the final model's
    parameter values; fixture modes are grouped into one phrase."""
    phrases: list[str] = []
    fixtures: list[float] = []
    unplaced_fixture = False
    seen: set[str] = set()
    for effect, term in effects:
        match = _FIXTURE.fullmatch(term)
        if effect == "fixture_resonance" or match:
            if match:
                fixtures.append(float(match.group(1)))
            else:
                unplaced_fixture = True
            continue
        if effect in seen:
            continue
        seen.add(effect)
        if effect == "frequency_dependent_modulus":
            phrases.append("stiffness and damping depend on frequency")
        elif effect == "load_cell_compliance":
            k_c = values.get("K_c", math.nan)
            phrases.append("the load-cell link is not rigid"
                           + (f" (K_c ≈ {k_c / 1e6:.3g} MN/m)" if math.isfinite(k_c) else ""))
        elif effect == "sensor_delay":
            tau = values.get("tau_d", math.nan)
            phrases.append("one channel lags the others"
                           + (f" by {abs(tau) * 1e6:.2g} µs" if math.isfinite(tau) else ""))
        elif effect == "amplitude_dependence":
            phrases.append("the rubber's stiffness depends on the vibration amplitude")
        elif effect == "thermal_drift":
            phrases.append("the specimen drifts during the sweep (heating)")
        else:
            phrases.append(effect.replace("_", " "))
    if fixtures:
        where = _spoken_list([f"{f:.0f}" for f in sorted(fixtures)])
        phrases.append(f"{'a fixture mode' if len(fixtures) == 1 else 'fixture modes'} at "
                       f"{where} Hz")
    elif unplaced_fixture:
        phrases.append("a fixture mode")
    return phrases


def capitalised(text: str) -> str:
    """The text with its first letter in upper case."""
    return text[:1].upper() + text[1:]


def finding_sentence(first_model: str, effects: Sequence[tuple[str, str]],
                     values: dict[str, float], rms_error: float, noise_floor: float,
                     missing: str | tuple[str, str] | None, climbed: bool) -> str:
    """The finding of one run in one sentence.

    Parameters
    ----------
    first_model
        The model the diagnosis started from.
    effects
        ``(effect, term)`` of every rung added, in order.
    values
        Parameter values of the model reached.
    rms_error, noise_floor
        Of the model reached.
    missing
        The effect most likely still missing (the best significant candidate), if any: its
        name, or ``(effect, term)``.
    climbed
        The ladder was climbed (else the run was diagnosed once).
    """
    phrases = effect_phrases(effects, values)
    reached = at_floor(rms_error, noise_floor)
    if isinstance(missing, str):
        missing = (missing, missing)
    if not phrases:
        if reached:
            return f"{first_model} explains the measurements to the noise."
        if missing:
            tail = "" if climbed else " (the ladder was not climbed)"
            return (f"{first_model} is {error_words(rms_error, noise_floor)}; most likely "
                    f"missing: {effect_phrases([missing], values)[0]}{tail}.")
        return (f"{first_model} is {error_words(rms_error, noise_floor)} and no effect of the "
                "vocabulary explains the rest.")
    found = capitalised(_spoken_list(phrases))
    if reached:
        return f"{found}: with them the model reaches the noise floor."
    rest = f"; next most likely: {effect_phrases([missing], values)[0]}" if missing \
        else "; no effect of the vocabulary explains the rest"
    return f"{found}; the model is still {error_words(rms_error, noise_floor)}{rest}."
