"""FE material cards of a master curve: the Prony series and the shift function as Abaqus, ANSYS
and LS-DYNA read them.

Every card is in SI units (Pa, s, °C for temperatures) and begins with a comment block naming
the data, the units, the reference temperature, the shift function, the fit's error, and which
of the card's conventions the vendor's public documentation confirms and which it does not. The
moduli of the series become shear and bulk relaxation functions by a constant Poisson's ratio
``ν`` (``G = E/(2(1+ν))``, ``K = E/(3(1−2ν))``; from a shear modulus the other way round), so the
relative (normalised) series of shear and bulk are the same.

Conventions, and the documentation each rests on (``docs/materials.md`` lists the sources):

- Abaqus. ``*VISCOELASTIC, TIME=PRONY``: one data line per term, ``g_i^P, k_i^P, τ_i`` (shear
  modulus ratio, bulk modulus ratio, relaxation time), any number of terms (Abaqus Keywords
  Reference, *VISCOELASTIC, data lines for TIME=PRONY). The ratios are of the instantaneous
  moduli given by ``*ELASTIC, MODULI=INSTANTANEOUS``. ``*TRS, DEFINITION=WLF``: one data line
  ``θ0, C1, C2`` (Abaqus Keywords Reference, *TRS); the shift function ``A`` divides the time
  (``dτ/dt = 1/A``) and ``log10 A = −C1 (θ−θ0)/(C2+θ−θ0)`` (Abaqus Theory Guide,
  Viscoelasticity; Abaqus Materials Guide, Thermorheologically simple temperature effects), so
  the project's ``C1, C2`` go in unchanged. ``DEFINITION=ARRHENIUS``: ``ln A = (E0/R)(1/(θ−θZ) −
  1/(θ0−θZ))`` with ``θZ`` the absolute zero of the temperature scale (Materials Guide, same
  section); the fields of its data line after ``θ0`` are not confirmed.
- ANSYS. ``TB,PRONY,MAT,NTEMP,NPTS,TBOPT`` with ``TBOPT`` ``SHEAR`` or ``BULK`` and ``NPTS`` the
  number of terms (Command Reference, TB); ``TBDATA`` carries six values a command (Command
  Reference, TBDATA); the pairs ``a_i, τ_i`` (``a_i`` relative to the instantaneous modulus) are
  not confirmed from the manual. ``TB,SHIFT,,,3,WLF`` with ``Tr, C1, C2``: the order is
  confirmed only by a third-party example, and ANSYS's sign (its ``A`` multiplies the time, so
  ``log10 A = +C1 (T−Tr)/(C2+T−Tr)`` with the same positive ``C1``) is not confirmed.
  ``TB,SHIFT,,,2,TN`` with ``Tr`` and ``H/R``: unconfirmed form; ``Tr`` is given in °C and
  ``TOFFST,273.15`` states the offset from absolute zero (Command Reference, TOFFST), as the
  card's temperatures are in °C.
- LS-DYNA. ``*MAT_GENERAL_VISCOELASTIC`` (MAT_076): card 1 ``MID, RO, BULK, PCF, EF, TREF, A,
  B`` (``EF`` is the elastic flag, 0 = viscoelastic; ``TREF`` must be greater than zero), card 2
  ``LCID, NT, BSTART, TRAMP, LCIDK, NTK, BSTARTK, TRAMPK`` (zero: no relaxation curve to fit),
  then at most six cards ``GI, BETAI, KI, BETAKI`` (LS-DYNA Keyword User's Manual, MAT_076, as
  transcribed field by field in Ansys's PyDyNA keyword classes). Decay constants ``β = 1/τ``; the
  long-term moduli are a card of ``β = 0``, so :data:`LSDYNA_MAX_TERMS` decaying terms fit and a
  longer series is refitted with that many, the card stating that series' error. The WLF form
  written (``A = C1 ln 10``, ``B = C2``, natural logarithm, same sign as Abaqus) is not
  confirmed; neither is the Arrhenius form, so no shift is written for an Arrhenius fit and the
  card says so, with its error at the reference-temperature series alone. ``BULK`` is left 0
  since the bulk series is given: not confirmed either.

No card is written from a series the data do not hold (:func:`check_card_series`): an
instantaneous modulus beyond :data:`CARD_MODULUS_LIMIT` times the largest measured one, or a
relaxation time more than :data:`CARD_TAU_DECADES` decades outside the data's reduced times, is
refused with one line.
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
from viscorig.materials.shiftfunctions import GAS_CONSTANT_J_PER_MOL_K, KELVIN

FORMATS = ("abaqus", "ansys", "lsdyna")
#: Cards ``GI, BETAI, KI, BETAKI`` that *MAT_GENERAL_VISCOELASTIC reads (LS-DYNA manual, MAT_076).
LSDYNA_MAX_CARDS = 6
#: Decaying terms on those cards: one card holds the long-term moduli (``β = 0``).
LSDYNA_MAX_TERMS = LSDYNA_MAX_CARDS - 1
DEFAULT_POISSON = 0.49
#: Largest instantaneous modulus of a card's series, times the largest measured ``|E*|``.
CARD_MODULUS_LIMIT = 100.0
#: Decades a card's relaxation time may lie outside ``1/(2π f_max) .. 1/(2π f_min)`` of the
#: reduced frequencies.
CARD_TAU_DECADES = 3.0


def check_card_series(master: MasterCurve, series: PronySeries) -> None:
    """Refuse a series no card should hold (see the module text).

    Raises
    ------
    InputError
        A modulus or relaxation time that is not a positive finite number, an instantaneous
        modulus beyond :data:`CARD_MODULUS_LIMIT` times the largest measured one, or a
        relaxation time more than :data:`CARD_TAU_DECADES` decades outside the data's.
    """
    table = master.table
    where = f"{table.source or ', '.join(master.runs)}: Prony series"
    largest = float(np.hypot(table.storage_pa, table.loss_pa).max())
    e0 = series.instantaneous_modulus_pa
    values = np.concatenate([[series.long_term_modulus_pa], series.moduli_pa, series.tau_s])
    if not (np.all(np.isfinite(values)) and np.all(values[1:] > 0)
            and series.long_term_modulus_pa >= 0):
        raise InputError("a modulus or relaxation time is not a positive number; no card "
                         "written", where)
    if e0 > CARD_MODULUS_LIMIT * largest:
        raise InputError(f"instantaneous modulus {e0:.3g} Pa is {e0 / largest:.3g} times the "
                         f"largest measured ({largest:.3g} Pa), more than "
                         f"{CARD_MODULUS_LIMIT:g}: the data do not hold it; no card written",
                         where)
    reduced = master.reduced_frequency_hz
    fast, slow = 1.0 / (2 * np.pi * float(reduced.max())), 1.0 / (2 * np.pi * float(reduced.min()))
    margin = 10.0**CARD_TAU_DECADES
    outside = series.tau_s[(series.tau_s < fast / margin) | (series.tau_s > slow * margin)]
    if outside.size:
        raise InputError(f"relaxation time {outside[0]:.3g} s is more than "
                         f"{CARD_TAU_DECADES:g} decades outside the data's reduced times "
                         f"{fast:.3g}..{slow:.3g} s: the data do not hold it; no card written",
                         where)


def _split(master: MasterCurve, poisson: float) -> tuple[float, float]:
    """Factors from the measured modulus to shear and bulk modulus."""
    if master.table.modulus == "E":
        return 1.0 / (2 * (1 + poisson)), 1.0 / (3 * (1 - 2 * poisson))
    young = 2 * (1 + poisson)
    return 1.0, young / (3 * (1 - 2 * poisson))


def _young(master: MasterCurve, poisson: float) -> float:
    """Factor from the measured modulus to Young's modulus."""
    return 1.0 if master.table.modulus == "E" else 2 * (1 + poisson)


def card_error(master: MasterCurve, series: PronySeries,
               shifted: bool = True) -> tuple[float, float]:
    """Rms ``ln(card/measured)`` of E' and E'' over every point, as the card reproduces them:
    the series shifted by the shift function (the measured shift factors where none was
    fitted), or not shifted at all where the card holds no shift (``shifted=False``). A card
    carries no vertical shift: the moduli compared are those measured, not reduced."""
    table = master.table
    scale = master.measured_scale()
    if not shifted:
        reduced = table.frequency_hz
    elif master.shift_function is None:
        reduced = master.reduced_frequency_hz
    else:
        reduced = table.frequency_hz * 10.0 ** master.shift_function(table.temperature_c)
    value = series.complex_modulus(2 * np.pi * reduced)
    return (float(np.sqrt(np.mean(np.log(value.real / (table.storage_pa * scale)) ** 2))),
            float(np.sqrt(np.mean(np.log(value.imag / (table.loss_pa * scale)) ** 2))))


def _comment(master: MasterCurve, series: PronySeries, poisson: float, mark: str,
             note: str = "", conventions: tuple[str, ...] = (),
             shifted: bool = True) -> list[str]:
    fit = master.prony_fit
    function = master.shift_function
    shift = "none fitted" if function is None else function.parameters_text()
    if function is not None and function.at_bound:
        shift += (f"; CAUTION: {', '.join(function.at_bound)} at the bound of the fit: the "
                  "shifts do not determine the parameters, only the curve over the measured "
                  "temperatures; do not extrapolate")
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
        "this card (series {} terms, {}) over every point: rms ln(card/measured) storage "
        "{:.4f}, loss {:.4f}".format(series.terms,
                                     "shifted by the shift function" if shifted
                                     else "no shift function written",
                                     *card_error(master, series, shifted)),
        f"Poisson's ratio {poisson} assumed constant (shear and bulk share the relative series)",
    ]
    if master.vertical == "ferry":
        density = (f", rho_ref/rho = exp({master.expansion_per_k:g} (T - Tref))"
                   if master.expansion_per_k else "")
        lines.append(f"vertical shift: the moduli were reduced by bT = Tref rho_ref/(T rho) "
                     f"(kelvin{density}) before fitting; this card carries no vertical shift, so "
                     "at T it gives the modulus at Tref of the shifted frequency (the measured "
                     "one is 1/bT times it; the rms ln(card/measured) above includes that)")
    if note:
        lines.append(note)
    lines += [f"convention: {line}" for line in conventions]
    return [f"{mark} {line}" for line in lines]


ABAQUS_CONVENTIONS = (
    "*VISCOELASTIC, TIME=PRONY lines g_i, k_i, tau_i (Abaqus Keywords Reference, *VISCOELASTIC)",
    "*TRS, DEFINITION=WLF line theta0, C1, C2; log10 A = -C1 (T - theta0)/(C2 + T - theta0), "
    "time divided by A (Keywords Reference, *TRS; Theory Guide, Viscoelasticity)",
)
ABAQUS_ARRHENIUS = (
    "*TRS, DEFINITION=ARRHENIUS: ln A = (E0/R)(1/(T - thetaZ) - 1/(theta0 - thetaZ)) (Materials "
    "Guide, thermorheologically simple temperature effects); UNCONFIRMED: the data line after "
    "theta0 (written E0, R, thetaZ) and where Abaqus takes thetaZ from",
)


def abaqus_card(master: MasterCurve, name: str, poisson: float = DEFAULT_POISSON) -> str:
    """The Abaqus keyword lines of the material."""
    series = master.prony
    check_card_series(master, series)
    e0 = series.instantaneous_modulus_pa * _young(master, poisson)
    relative = series.moduli_pa / series.instantaneous_modulus_pa
    function = master.shift_function
    conventions: tuple[str, ...] = ABAQUS_CONVENTIONS
    if function is not None and function.kind == "arrhenius":
        conventions += ABAQUS_ARRHENIUS
    lines = _comment(master, series, poisson, "**", conventions=conventions)
    lines += [f"*MATERIAL, NAME={name}", "*ELASTIC, MODULI=INSTANTANEOUS",
              f"{e0:.10e}, {poisson}", "*VISCOELASTIC, TIME=PRONY"]
    lines += [f"{g:.10e}, {g:.10e}, {t:.10e}" for g, t in zip(relative, series.tau_s,
                                                              strict=True)]
    if function is not None and function.kind == "wlf":
        c1, c2 = function.values
        lines += ["*TRS, DEFINITION=WLF",
                  f"{master.reference_temperature_c:.6f}, {c1:.10e}, {c2:.10e}"]
    elif function is not None and function.kind == "arrhenius":
        lines += ["*TRS, DEFINITION=ARRHENIUS",
                  f"{master.reference_temperature_c:.6f}, {function.values[0]:.10e}, "
                  f"{GAS_CONSTANT_J_PER_MOL_K}, {-KELVIN}"]
    return "\n".join(lines) + "\n"


def _tbdata(values: list[float]) -> list[str]:
    out = []
    for start in range(0, len(values), 6):
        chunk = ",".join(f"{v:.10e}" for v in values[start:start + 6])
        out.append(f"TBDATA,{start + 1},{chunk}")
    return out


ANSYS_CONVENTIONS = (
    "TB,PRONY,MAT,NTEMP,NPTS,SHEAR|BULK with NPTS terms (Command Reference, TB); TBDATA six "
    "values a command (Command Reference, TBDATA); UNCONFIRMED: the pairs a_i, tau_i",
)
ANSYS_WLF = (
    "TB,SHIFT,,,3,WLF with Tr, C1, C2 (order from a third-party example only); UNCONFIRMED: "
    "ANSYS's sign, written as log10 A = +C1 (T - Tr)/(C2 + T - Tr) with A multiplying the time",
)
ANSYS_TN = (
    "TB,SHIFT,,,2,TN with Tr (C) and H/R (K), TOFFST,273.15 (Command Reference, TOFFST); "
    "UNCONFIRMED: the Tool-Narayanaswamy form and that it takes the offset from TOFFST",
)


def ansys_card(master: MasterCurve, name: str, poisson: float = DEFAULT_POISSON,
               material: int = 1) -> str:
    """The ANSYS APDL commands of the material."""
    series = master.prony
    check_card_series(master, series)
    e0 = series.instantaneous_modulus_pa * _young(master, poisson)
    pairs: list[float] = []
    for a, t in zip(series.moduli_pa / series.instantaneous_modulus_pa, series.tau_s,
                    strict=True):
        pairs += [float(a), float(t)]
    function = master.shift_function
    conventions: tuple[str, ...] = ANSYS_CONVENTIONS
    if function is not None:
        conventions += ANSYS_WLF if function.kind == "wlf" else ANSYS_TN
    lines = _comment(master, series, poisson, "!", conventions=conventions)
    lines += [f"! material {name}", f"MP,EX,{material},{e0:.10e}",
              f"MP,PRXY,{material},{poisson}"]
    for part in ("SHEAR", "BULK"):
        lines.append(f"TB,PRONY,{material},,{series.terms},{part}")
        lines += _tbdata(pairs)
    if function is not None and function.kind == "wlf":
        c1, c2 = function.values
        lines += [f"TB,SHIFT,{material},,3,WLF",
                  f"TBDATA,1,{master.reference_temperature_c:.6f},{c1:.10e},{c2:.10e}"]
    elif function is not None and function.kind == "arrhenius":
        lines += [f"TOFFST,{KELVIN}", f"TB,SHIFT,{material},,2,TN",
                  f"TBDATA,1,{master.reference_temperature_c:.6f},"
                  f"{function.values[0] / GAS_CONSTANT_J_PER_MOL_K:.10e}"]
    return "\n".join(lines) + "\n"


def _lsdyna_series(master: MasterCurve) -> tuple[PronySeries, str]:
    """The series the card holds: the master's, or where that is longer than the cards hold,
    the best series of :data:`LSDYNA_MAX_TERMS` terms refitted (not truncated) to every point
    at the reduced frequencies the card itself applies (its WLF shift where it writes one)."""
    series = master.prony
    if series.terms <= LSDYNA_MAX_TERMS:
        return series, ""
    table = master.table
    function = master.shift_function
    if function is not None and function.kind == "wlf":
        reduced = table.frequency_hz * 10.0 ** function(table.temperature_c)
    else:
        reduced = master.reduced_frequency_hz
    scatter = (master.shifts.storage_scatter, master.shifts.loss_scatter)
    shorter, fit = fit_prony_terms(2 * np.pi * reduced, table.storage_pa, table.loss_pa, scatter,
                                   LSDYNA_MAX_TERMS)
    note = (f"the {series.terms}-term series is refitted with {LSDYNA_MAX_TERMS} terms, the most "
            f"the {LSDYNA_MAX_CARDS} cards hold with the long-term one: rms ln(model/measured) "
            f"storage {fit.storage_rms_log_error:.4f}, loss {fit.loss_rms_log_error:.4f}")
    return shorter, note


def _fields(values: list[float | int]) -> str:
    """One card in LS-DYNA's comma-separated free format."""
    return ",".join(str(v) if isinstance(v, int) else f"{v:.9e}" for v in values)


LSDYNA_CONVENTIONS = (
    "*MAT_GENERAL_VISCOELASTIC card 1 MID RO BULK PCF EF TREF A B, card 2 LCID NT BSTART TRAMP "
    "LCIDK NTK BSTARTK TRAMPK, at most six cards GI BETAI KI BETAKI (LS-DYNA Keyword User's "
    "Manual, MAT_076); UNCONFIRMED: BULK = 0 when the KI are given",
)
LSDYNA_WLF = (
    "UNCONFIRMED: the WLF form of A, B; written A = C1 ln 10, B = C2 for "
    "ln aT = -A (T - TREF)/(B + T - TREF)",
)
LSDYNA_ARRHENIUS = (
    "UNCONFIRMED: MAT_076's Arrhenius form; no shift function is written (TREF = A = B = 0), "
    "the card holds the series at the reference temperature",
)


def lsdyna_card(master: MasterCurve, name: str, poisson: float = DEFAULT_POISSON,
                material: int = 1, density_kg_per_m3: float = 1100.0,
                held: tuple[PronySeries, str] | None = None) -> str:
    """The LS-DYNA keyword deck of the material (*MAT_GENERAL_VISCOELASTIC); ``held`` is the
    series the cards hold and its note when already found (:func:`card_series`).

    Raises
    ------
    InputError
        A WLF shift at a reference temperature not above 0 °C (MAT_076 needs ``TREF > 0``).
    """
    function = master.shift_function
    wlf = function is not None and function.kind == "wlf"
    if wlf and not master.reference_temperature_c > 0.0:
        raise InputError(f"{master.reference_temperature_c:g} C: LS-DYNA's "
                         "*MAT_GENERAL_VISCOELASTIC needs a reference temperature TREF > 0",
                         "--reference-temperature")
    series, note = _lsdyna_series(master) if held is None else held
    check_card_series(master, series)
    shear, bulk = _split(master, poisson)
    conventions: tuple[str, ...] = LSDYNA_CONVENTIONS
    if function is not None:
        conventions += LSDYNA_WLF if wlf else LSDYNA_ARRHENIUS
    lines = ["*KEYWORD", *_comment(master, series, poisson, "$", note, conventions,
                                   shifted=function is None or wlf),
             f"$ material {name}; density {density_kg_per_m3} kg/m^3 (a placeholder to set)",
             "*MAT_GENERAL_VISCOELASTIC"]
    tref, a, b = 0.0, 0.0, 0.0
    if wlf and function is not None:
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


def card_series(master: MasterCurve, kind: str) -> PronySeries:
    """The Prony series the card of ``kind`` holds: the master's, or for LS-DYNA where that is
    longer than its cards hold, the series refitted with :data:`LSDYNA_MAX_TERMS` terms."""
    return _lsdyna_series(master)[0] if kind == "lsdyna" else master.prony


def write_card(master: MasterCurve, kind: str, path: Path, name: str,
               poisson: float = DEFAULT_POISSON) -> PronySeries:
    """Write the card of ``kind`` to ``path`` (replaced atomically); returns the Prony series
    the card holds (:func:`card_series`).

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
    if kind == "lsdyna":
        held = _lsdyna_series(master)
        text = lsdyna_card(master, name, poisson, held=held)
        series = held[0]
    else:
        text = WRITERS[kind](master, name, poisson)
        series = master.prony
    replace_atomically(Path(path), lambda stream: stream.write(text), text=True)
    return series
