"""FE material cards of a master curve: the Prony series and the shift function as Abaqus, ANSYS
and LS-DYNA read them.

Every card is in SI units (Pa, s, °C for temperatures) and begins with a comment block naming
the data, the units, the reference temperature, the shift function and the fit's error. The
moduli of the series become shear and bulk relaxation functions by a constant Poisson's ratio
``ν`` (``G = E/(2(1+ν))``, ``K = E/(3(1−2ν))``; from a shear modulus the other way round), so the
relative (normalised) series of shear and bulk are the same.

Conventions written out, because each tool names them differently:

- Abaqus: ``*ELASTIC, MODULI=INSTANTANEOUS`` (``E_0``, ``ν``), ``*VISCOELASTIC, TIME=PRONY``
  lines ``g_i, k_i, τ_i`` with ``g_i = k_i = E_i/E_0``, ``*TRS, DEFINITION=WLF`` line
  ``T_ref, C1, C2`` (``log10 aT = −C1 (T−T_ref)/(C2+T−T_ref)``), or ``DEFINITION=ARRHENIUS``.
- ANSYS: ``MP,EX`` and ``MP,PRXY`` (instantaneous), ``TB,PRONY,,,N,SHEAR`` and ``...,BULK`` with
  ``TBDATA`` pairs ``a_i, τ_i`` (``a_i = E_i/E_0``), ``TB,SHIFT,,,3,WLF`` with ``T_ref, C1, C2``
  (ANSYS's shift ``A = 1/aT``, so ``log10 A = C1 (T−T_ref)/(C2+T−T_ref)`` with the same
  positive ``C1``), or ``TB,SHIFT,,,2,TN`` with ``T_ref`` and ``E_a/R`` (Arrhenius).
- LS-DYNA: ``*MAT_GENERAL_VISCOELASTIC`` (MAT_076): card 1 ``MID, RO, BULK, PCF, EF, TREF, A,
  B``, card 2 zeros (no relaxation curve), then one card per term ``G_i, β_i, K_i, βk_i``
  (comma-separated free format) with decay constants ``β = 1/τ``; the long-term moduli are a
  term of ``β = 0``; ``BULK`` is left 0 since the bulk series is given. The shift is WLF with
  ``A = C1 ln 10`` and ``B = C2`` (LS-DYNA writes WLF with the natural logarithm). At most
  :data:`LSDYNA_MAX_TERMS` terms fit on the cards: a longer series is refitted with that many
  terms, and the card says so with its error.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np

from viscorig import __version__
from viscorig.errors import InputError
from viscorig.exchange.atomicfile import replace_atomically
from viscorig.materials.master import MasterCurve
from viscorig.materials.prony import PronySeries, fit_prony_terms
from viscorig.materials.shiftfunctions import GAS_CONSTANT_J_PER_MOL_K

FORMATS = ("abaqus", "ansys", "lsdyna")
#: Terms of *MAT_GENERAL_VISCOELASTIC given on cards (more need a relaxation curve).
LSDYNA_MAX_TERMS = 6
DEFAULT_POISSON = 0.49


def _split(master: MasterCurve, poisson: float) -> tuple[float, float]:
    """Factors from the measured modulus to shear and bulk modulus."""
    if master.table.modulus == "E":
        return 1.0 / (2 * (1 + poisson)), 1.0 / (3 * (1 - 2 * poisson))
    young = 2 * (1 + poisson)
    return 1.0, young / (3 * (1 - 2 * poisson))


def _young(master: MasterCurve, poisson: float) -> float:
    """Factor from the measured modulus to Young's modulus."""
    return 1.0 if master.table.modulus == "E" else 2 * (1 + poisson)


def card_error(master: MasterCurve, series: PronySeries) -> tuple[float, float]:
    """Rms ``ln(card/measured)`` of E' and E'' over every point, as the card reproduces them:
    the series shifted by the shift function (the measured shift factors where none was
    fitted)."""
    table = master.table
    if master.shift_function is None:
        reduced = master.reduced_frequency_hz
    else:
        reduced = table.frequency_hz * 10.0 ** master.shift_function(table.temperature_c)
    value = series.complex_modulus(2 * np.pi * reduced)
    return (float(np.sqrt(np.mean(np.log(value.real / table.storage_pa) ** 2))),
            float(np.sqrt(np.mean(np.log(value.imag / table.loss_pa) ** 2))))


def _comment(master: MasterCurve, series: PronySeries, poisson: float, mark: str,
             note: str = "") -> list[str]:
    fit = master.prony_fit
    function = master.shift_function
    shift = "none fitted" if function is None else ", ".join(
        f"{name} = {entry['value']:.6g} ± {entry['stderr']:.2g} {entry['unit']}"
        for name, entry in function.to_json()["parameters"].items())
    lines = [
        f"viscorig {__version__}: linear viscoelastic material from a master curve",
        f"data: {master.table.source or ', '.join(master.runs)} (runs: "
        f"{', '.join(master.runs) or '-'}), {master.table.points} points, "
        f"{master.temperature_c.size} temperatures "
        f"{master.temperature_c.min():.1f}..{master.temperature_c.max():.1f} C, "
        f"measured modulus {master.table.modulus}",
        "units: Pa, s, degrees C (SI)",
        f"reference temperature: {master.reference_temperature_c:.4f} C",
        f"shift function: {function.kind if function else 'none'} ({shift}); "
        "log10 aT = -C1 (T - Tref)/(C2 + T - Tref), aT > 1 below Tref",
        f"Prony series: {master.prony.terms} terms; fit over every point with the measured shift "
        f"factors: rms ln(model/measured) storage {fit.storage_rms_log_error:.4f}, loss "
        f"{fit.loss_rms_log_error:.4f}",
        "this card (series {} terms, shifted by the shift function) over every point: rms "
        "ln(card/measured) storage {:.4f}, loss {:.4f}".format(series.terms,
                                                               *card_error(master, series)),
        f"Poisson's ratio {poisson} assumed constant (shear and bulk share the relative series)",
    ]
    if note:
        lines.append(note)
    return [f"{mark} {line}" for line in lines]


def abaqus_card(master: MasterCurve, name: str, poisson: float = DEFAULT_POISSON) -> str:
    """The Abaqus keyword lines of the material."""
    series = master.prony
    e0 = series.instantaneous_modulus_pa * _young(master, poisson)
    relative = series.moduli_pa / series.instantaneous_modulus_pa
    lines = _comment(master, series, poisson, "**")
    lines += [f"*MATERIAL, NAME={name}", "*ELASTIC, MODULI=INSTANTANEOUS",
              f"{e0:.10e}, {poisson}", "*VISCOELASTIC, TIME=PRONY"]
    lines += [f"{g:.10e}, {g:.10e}, {t:.10e}" for g, t in zip(relative, series.tau_s,
                                                              strict=True)]
    function = master.shift_function
    if function is not None and function.kind == "wlf":
        c1, c2 = function.values
        lines += ["*TRS, DEFINITION=WLF",
                  f"{master.reference_temperature_c:.6f}, {c1:.10e}, {c2:.10e}"]
    elif function is not None and function.kind == "arrhenius":
        # Abaqus: ln aT = -(E0/R)(1/(T - T0z) - 1/(Tref - T0z)); E0 given with R and T0z
        lines += ["*TRS, DEFINITION=ARRHENIUS",
                  f"{master.reference_temperature_c:.6f}, {function.values[0]:.10e}, "
                  f"{GAS_CONSTANT_J_PER_MOL_K}, -273.15"]
    return "\n".join(lines) + "\n"


def _tbdata(values: list[float]) -> list[str]:
    out = []
    for start in range(0, len(values), 6):
        chunk = ",".join(f"{v:.10e}" for v in values[start:start + 6])
        out.append(f"TBDATA,{start + 1},{chunk}")
    return out


def ansys_card(master: MasterCurve, name: str, poisson: float = DEFAULT_POISSON,
               material: int = 1) -> str:
    """The ANSYS APDL commands of the material."""
    series = master.prony
    e0 = series.instantaneous_modulus_pa * _young(master, poisson)
    pairs: list[float] = []
    for a, t in zip(series.moduli_pa / series.instantaneous_modulus_pa, series.tau_s,
                    strict=True):
        pairs += [float(a), float(t)]
    lines = _comment(master, series, poisson, "!")
    lines += [f"! material {name}", f"MP,EX,{material},{e0:.10e}",
              f"MP,PRXY,{material},{poisson}"]
    for part in ("SHEAR", "BULK"):
        lines.append(f"TB,PRONY,{material},,{series.terms},{part}")
        lines += _tbdata(pairs)
    function = master.shift_function
    if function is not None and function.kind == "wlf":
        c1, c2 = function.values
        lines += [f"TB,SHIFT,{material},,3,WLF",
                  f"TBDATA,1,{master.reference_temperature_c:.6f},{c1:.10e},{c2:.10e}"]
    elif function is not None and function.kind == "arrhenius":
        lines += [f"TB,SHIFT,{material},,2,TN",
                  f"TBDATA,1,{master.reference_temperature_c + 273.15:.6f},"
                  f"{function.values[0] / GAS_CONSTANT_J_PER_MOL_K:.10e}"]
    return "\n".join(lines) + "\n"


def _lsdyna_series(master: MasterCurve) -> tuple[PronySeries, str]:
    series = master.prony
    if series.terms <= LSDYNA_MAX_TERMS:
        return series, ""
    omega = 2 * np.pi * master.reduced_frequency_hz
    table = master.table
    scatter = (master.shifts.storage_scatter, master.shifts.loss_scatter)
    shorter, fit = fit_prony_terms(omega, table.storage_pa, table.loss_pa, scatter,
                                   LSDYNA_MAX_TERMS)
    note = (f"the {series.terms}-term series is refitted with {LSDYNA_MAX_TERMS} terms, the most "
            f"the cards hold: rms ln(model/measured) storage {fit.storage_rms_log_error:.4f}, "
            f"loss {fit.loss_rms_log_error:.4f}")
    return shorter, note


def _fields(values: list[float | int]) -> str:
    """One card in LS-DYNA's comma-separated free format."""
    return ",".join(str(v) if isinstance(v, int) else f"{v:.9e}" for v in values)


def lsdyna_card(master: MasterCurve, name: str, poisson: float = DEFAULT_POISSON,
                material: int = 1, density_kg_per_m3: float = 1100.0) -> str:
    """The LS-DYNA keyword deck of the material (*MAT_GENERAL_VISCOELASTIC)."""
    series, note = _lsdyna_series(master)
    shear, bulk = _split(master, poisson)
    lines = ["*KEYWORD", *_comment(master, series, poisson, "$", note),
             f"$ material {name}; density {density_kg_per_m3} kg/m^3 (a placeholder to set)",
             "*MAT_GENERAL_VISCOELASTIC"]
    function = master.shift_function
    tref, a, b = 0.0, 0.0, 0.0
    if function is not None and function.kind == "wlf":
        tref, a, b = (master.reference_temperature_c, function.values[0] * math.log(10.0),
                      function.values[1])
    lines.append("$ MID, RO, BULK, PCF, EF, TREF, A, B")
    lines.append(_fields([material, density_kg_per_m3, 0.0, 0.0, 0.0, tref, a, b]))
    lines.append("$ LCID, NT, BSTART, TRAMP, LCIDK, NTK, BSTARTK, TRAMPK")
    lines.append(_fields([0, 0, 0.0, 0.0, 0, 0, 0.0, 0.0]))
    lines.append("$ GI, BETAI, KI, BETAKI")
    terms = [(series.long_term_modulus_pa, 0.0)] + [
        (float(e), 1.0 / float(t)) for e, t in zip(series.moduli_pa, series.tau_s,
                                                   strict=True)]
    for modulus, beta in terms:
        lines.append(_fields([modulus * shear, beta, modulus * bulk, beta]))
    lines.append("*END")
    return "\n".join(lines) + "\n"


WRITERS: dict[str, Callable[..., str]] = {"abaqus": abaqus_card, "ansys": ansys_card,
                                          "lsdyna": lsdyna_card}


def write_card(master: MasterCurve, kind: str, path: Path, name: str,
               poisson: float = DEFAULT_POISSON) -> None:
    """Write the card of ``kind`` to ``path`` (replaced atomically).

    Raises
    ------
    InputError
        Unknown kind, a Poisson's ratio outside (−1, 0.5), or a file that cannot be written.
    """
    if kind not in WRITERS:
        raise InputError(f"unknown material format {kind!r} (one of: {', '.join(FORMATS)})",
                         "--material")
    if not (math.isfinite(poisson) and -1.0 < poisson < 0.5):
        raise InputError(f"{poisson} must be in (-1, 0.5)", "--poisson-ratio")
    text = WRITERS[kind](master, name, poisson)
    replace_atomically(Path(path), lambda stream: stream.write(text), text=True)
