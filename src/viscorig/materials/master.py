"""The master curve of a material: shift factors, shift functions, Prony and fractional models,
and the checks of superposition and Kramers-Kronig consistency, as one result.

Vertical shift: with ``vertical="ferry"`` the moduli are first reduced by Ferry's factor
``b_T`` (:mod:`~viscorig.materials.vertical`). Ignored where the data carry it, that factor is
taken up by the horizontal shifts wherever a modulus is flat. The master curve, its series and
its checks are then those of the reduced moduli ``E_p = E b_T``; the modulus at temperature
``T`` is ``E_p(f·aT) / b_T``.

:func:`build_master` is what ``viscorig master`` and ``open_campaign(...).master(...)`` call;
:meth:`MasterCurve.to_json` is the JSON contract of ``master --json`` (design.md).
"""

from __future__ import annotations

import html
import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from viscorig.errors import InputError
from viscorig.materials.joint import JointFit, refine_jointly
from viscorig.materials.kkcheck import KramersKronigCheck, check_kramers_kronig
from viscorig.materials.prony import (
    MAX_TERMS,
    SCATTER_MARGIN,
    FractionalModel,
    ModelFit,
    PronySeries,
    fit_fractional,
    fit_prony,
    fit_prony_terms,
    model_fit,
)
from viscorig.materials.shift import (
    TEMPERATURE_RESOLUTION_K,
    ShiftFactors,
    estimate_shift_factors,
)
from viscorig.materials.shiftfunctions import (
    ShiftFunction,
    best_shift_function,
    fit_shift_function,
)
from viscorig.materials.superposition import SuperpositionCheck, check_superposition
from viscorig.materials.table import ModulusTable
from viscorig.materials.vertical import MAX_EXPANSION_PER_K, VERTICAL_SHIFTS, ferry_factor
from viscorig.numbers import with_uncertainty
from viscorig.storage.layout import TEMPERATURE_RANGE_C

#: Without a shift function, a set within this many kelvin of the reference temperature asked
#: for is taken as the reference itself (with one, the shifts are moved to it exactly).
SAME_TEMPERATURE_K = 0.5
#: The other vertical shift is suggested where its scatter about the master curve (storage and
#: loss together) is below this fraction of the one chosen.
VERTICAL_EVIDENCE = 0.8


@dataclass(frozen=True)
class MasterCurve:
    """Everything ``master`` finds; see :func:`build_master`.

    Attributes
    ----------
    table
        The data.
    runs
        Names of the runs it came from.
    reference_temperature_c
        Temperature of the master curve (``log10 aT = 0``).
    temperature_c, log10_at, log10_at_stderr
        Shift factor of each set (ascending temperature), relative to the reference.
    shift_functions
        Every shift function fitted (WLF, Arrhenius), relative to the reference.
    shift_function
        The better one (lowest AIC), or ``None``.
    reduced_frequency_hz
        ``f·aT`` of every point of the table.
    prony, prony_fit, ladder
        The Prony series, its errors, and the errors of every number of terms tried.
    fractional, fractional_fit
        The fractional model and its errors.
    superposition, kramers_kronig, shifts
        The checks, and the first shift estimate (spline master curve, and the data's scatter
        about it).
    jointly_refined
        Whether the shifts were then refined together with the Prony series (they are unless
        that made the fit worse); their errors are then at least the spline estimate's where
        the refinement stayed near it (:func:`_joint_covariance`).
    left_out
        The points of the data whose storage or loss modulus is not a number within
        :data:`~viscorig.materials.table.MODULUS_RANGE_PA`
        (:meth:`ModulusTable.unusable_points`); ``table`` holds the others.
    vertical
        ``"none"``, or ``"ferry"``: ``table`` then holds the reduced moduli ``E b_T``
        (:meth:`set_log10_bt`, :meth:`measured_scale`).
    alternative_scatter
        The scatter of ``ln E'`` and ``ln E''`` about the master curve the other vertical
        shift gives (``None`` where its sweeps do not superpose): the evidence for the choice
        (:meth:`vertical_verdict`).
    expansion_per_k
        The volumetric thermal expansion in ``b_T`` (1/K; 0: the density constant).
    """

    table: ModulusTable
    runs: tuple[str, ...]
    reference_temperature_c: float
    temperature_c: NDArray[np.float64]
    log10_at: NDArray[np.float64]
    log10_at_stderr: NDArray[np.float64]
    shift_functions: tuple[ShiftFunction, ...]
    shift_function: ShiftFunction | None
    reduced_frequency_hz: NDArray[np.float64]
    prony: PronySeries
    prony_fit: ModelFit
    ladder: list[dict]
    fractional: FractionalModel
    fractional_fit: ModelFit
    superposition: SuperpositionCheck
    kramers_kronig: KramersKronigCheck
    shifts: ShiftFactors
    jointly_refined: bool = False
    left_out: tuple[dict, ...] = ()
    vertical: str = "none"
    alternative_scatter: tuple[float, float] | None = None
    expansion_per_k: float = 0.0

    def scatter_text(self) -> str:
        """The scatter the Prony series was judged against, in words: the data's about the
        spline master curve, or that scatter named as the spline's own misfit where terms were
        added past it (:func:`_more_terms`)."""
        values = f"{self.shifts.storage_scatter:.3f}, {self.shifts.loss_scatter:.3f}"
        if any(entry.get("shifts_refined") for entry in self.ladder):
            return (f"scatter about the spline master curve {values}, mostly the spline's own "
                    "misfit: more terms tried, the shifts refined with each, and kept while "
                    "BIC fell")
        return f"data scatter {values}"

    def vertical_verdict(self) -> str:
        """Whether the data superpose better with the other vertical shift, in one sentence."""
        other = self.alternative_scatter
        this = (self.shifts.storage_scatter, self.shifts.loss_scatter)
        if other is None:
            return ""
        better = math.hypot(*other) < VERTICAL_EVIDENCE * math.hypot(*this)
        if self.vertical == "none":
            if not better:
                return ""
            return (f"vertical shift: reduced by b_T = T_ref ρ_ref/(T ρ) (Ferry), the sweeps "
                    f"superpose with rms ln {other[0]:.3f}, {other[1]:.3f} instead of "
                    f"{this[0]:.3f}, {this[1]:.3f}: try --vertical-shift ferry")
        better_without = " (the data superpose better without: --vertical-shift none)"
        return (f"vertical shift b_T = T_ref ρ_ref/(T ρ): rms ln {this[0]:.3f}, {this[1]:.3f} "
                f"about the master curve, {other[0]:.3f}, {other[1]:.3f} without"
                + (better_without if better else ""))

    def set_log10_bt(self) -> NDArray[np.float64]:
        """``log10 b_T`` of each set (zeros without a vertical shift)."""
        if self.vertical != "ferry":
            return np.zeros(self.temperature_c.size)
        return np.log10(ferry_factor(self.temperature_c, self.reference_temperature_c,
                                     self.expansion_per_k))

    def measured_scale(self) -> NDArray[np.float64]:
        """The factor ``1/b_T`` of each point of ``table`` back to the moduli measured."""
        if self.vertical != "ferry":
            return np.ones(self.table.points)
        return 1.0 / ferry_factor(self.table.temperature_c, self.reference_temperature_c,
                                  self.expansion_per_k)

    def log10_at_of(self, temperature_c: float) -> float:
        """``log10 aT`` at any temperature from the shift function (NaN without one)."""
        if self.shift_function is None:
            return math.nan
        return float(self.shift_function(temperature_c))

    def flagged_points(self) -> list[dict]:
        """The points the Kramers-Kronig check names."""
        kk = self.kramers_kronig
        out = []
        for name, mask, residual in (("storage", kk.flagged_storage, kk.residual_storage),
                                     ("loss", kk.flagged_loss, kk.residual_loss)):
            for i in np.flatnonzero(mask):
                out.append({"point": int(i) + 1, "modulus": name,
                            "temperature_c": float(self.table.temperature_c[i]),
                            "frequency_hz": float(self.table.frequency_hz[i]),
                            "log_deviation": float(residual[i])})
        return sorted(out, key=lambda p: -abs(p["log_deviation"]))

    def text(self) -> str:
        """The master curve in a few lines for a person (what ``viscorig master`` prints)."""
        master = self
        m = master.table.modulus
        lines = [f"{', '.join(master.runs)}: {master.table.points} points, "
                 f"{master.temperature_c.size} temperatures, modulus {m}, reference "
                 f"{master.reference_temperature_c:.2f} °C",
                 "shift factors (reduced frequency f·aT):"]
        if master.vertical == "ferry":
            density = (f", ρ_ref/ρ = exp({master.expansion_per_k:g}/K · (T − T_ref))"
                       if master.expansion_per_k else "")
            lines[-1] = ("shift factors (reduced frequency f·aT; moduli reduced by "
                         f"b_T = T_ref ρ_ref/(T ρ), Ferry's vertical factor{density}):")
        for t, a, e, b in zip(master.temperature_c, master.log10_at, master.log10_at_stderr,
                              master.set_log10_bt(), strict=True):
            line = f"  {t:8.2f} °C   log10 aT = {with_uncertainty(a, e, signed=True)}"
            lines.append(line + (f"   log10 bT = {b:+.4f}" if master.vertical == "ferry" else ""))
        chosen = master.shift_function
        for function in master.shift_functions:
            data = function.to_json()
            values = function.parameters_text()
            chi = function.reduced_chi2
            fit = "" if math.isnan(chi) else f" (χ²/dof {chi:.2f}"
            fit += ("" if not fit else ", describes the shifts)" if data["describes_shifts"]
                    else ", does not describe the shifts within their errors)")
            best = ""
            if function is chosen:
                best = "  <- better"
                if function.at_bound:
                    best += (f" by AIC, though {', '.join(function.at_bound)} at the bound of "
                             "its fit: its curve over the measured temperatures follows the "
                             "shifts, its parameters are not determined by them")
            lines.append(f"{function.kind}: {values}{fit}{best}")
        swept_why = (ISOLATED_SWEEP, UNDETERMINED_SWEEP)
        points = [p for p in master.left_out if p["why"] not in swept_why]
        if points:
            named = "; ".join(f"{p['temperature_c']:.1f} °C, {p['frequency_hz']:.4g} Hz "
                              f"({p['why']})" for p in points[:8])
            more = f" and {len(points) - 8} more" if len(points) > 8 else ""
            lines.append(f"left out: {len(points)} point(s): {named}{more}")
        for why in swept_why:
            swept = sorted({p["temperature_c"] for p in master.left_out if p["why"] == why})
            if swept:
                named = ", ".join(f"{t:.1f} °C" for t in swept)
                lines.append(f"left out: the sweep(s) at {named}: {why}")
        lines.append(master.superposition.verdict)
        if master.vertical_verdict():
            lines.append(master.vertical_verdict())
        flagged = master.flagged_points()
        if flagged:
            named = "; ".join(f"{p['modulus']} at {p['temperature_c']:.1f} °C, "
                              f"{p['frequency_hz']:.4g} Hz ({p['log_deviation']:+.2f})"
                              for p in flagged[:8])
            more = f" and {len(flagged) - 8} more" if len(flagged) > 8 else ""
            lines.append(f"Kramers-Kronig: {len(flagged)} point(s) no linear viscoelastic "
                         f"material gives: {named}{more}")
        else:
            lines.append("Kramers-Kronig: every point is consistent with a linear viscoelastic "
                         "material")
        prony_fit = master.prony_fit
        lines.append(f"Prony series: {master.prony.terms} terms, {m}_inf = "
                     f"{master.prony.long_term_modulus_pa:.4g} Pa, {m}_0 = "
                     f"{master.prony.instantaneous_modulus_pa:.4g} Pa; rms log error "
                     f"storage {prony_fit.storage_rms_log_error:.3f}, "
                     f"loss {prony_fit.loss_rms_log_error:.3f} ({master.scatter_text()})")
        frac = master.fractional_fit
        lines.append(f"fractional model (4 parameters): rms log error storage "
                     f"{frac.storage_rms_log_error:.3f}, loss {frac.loss_rms_log_error:.3f}")
        return "\n".join(lines)

    def __repr__(self) -> str:
        return (f"<MasterCurve {', '.join(self.runs) or self.table.source}: "
                f"{self.temperature_c.size} temperatures, reference "
                f"{self.reference_temperature_c:.2f} °C, {self.prony.terms}-term Prony series>")

    def _repr_html_(self) -> str:
        return f"<pre>{html.escape(self.text())}</pre>"

    def to_json(self) -> dict:
        """The ``master --json`` object (design.md contract, then more keys)."""
        best = self.shift_function
        fractional_better = (self.fractional_fit.storage_rms_log_error
                             <= self.prony_fit.storage_rms_log_error
                             and self.fractional_fit.loss_rms_log_error
                             <= self.prony_fit.loss_rms_log_error)
        flagged = self.flagged_points()
        return {
            "run": list(self.runs),
            "modulus": self.table.modulus,
            "reference_temperature_c": self.reference_temperature_c,
            "shift_method": ("spline master curve of both moduli, then refined together with "
                             "the Prony series" if self.jointly_refined
                             else "spline master curve of both moduli"),
            "shift_factors": [
                {"temperature_c": float(t), "log10_aT": float(a), "log10_aT_stderr": float(e),
                 "log10_bT": float(b)}
                for t, a, e, b in zip(self.temperature_c, self.log10_at, self.log10_at_stderr,
                                      self.set_log10_bt(), strict=True)],
            "vertical_shift": {
                "kind": self.vertical,
                "thermal_expansion_per_k": self.expansion_per_k,
                "other_storage_scatter": (None if self.alternative_scatter is None
                                          else self.alternative_scatter[0]),
                "other_loss_scatter": (None if self.alternative_scatter is None
                                       else self.alternative_scatter[1]),
                "verdict": self.vertical_verdict(),
            },
            "shift_function": (best.to_json() if best is not None
                               else {"kind": "none", "parameters": {}}),
            "shift_functions": [f.to_json() for f in self.shift_functions],
            "prony": self.prony.to_json(),
            "fit": {
                "storage_rms_log_error": self.prony_fit.storage_rms_log_error,
                "loss_rms_log_error": self.prony_fit.loss_rms_log_error,
                "terms": self.prony.terms,
                "storage_scatter": self.shifts.storage_scatter,
                "loss_scatter": self.shifts.loss_scatter,
                "log": "natural",
                "ladder": self.ladder,
            },
            "fractional": {
                "parameters": self.fractional.to_json(),
                "storage_rms_log_error": self.fractional_fit.storage_rms_log_error,
                "loss_rms_log_error": self.fractional_fit.loss_rms_log_error,
                "better_than_prony": bool(fractional_better),
            },
            "superposition": self.superposition.to_json(),
            "kramers_kronig": {
                "consistent": self.kramers_kronig.consistent,
                "points_checked": self.table.points,
                "threshold_storage": self.kramers_kronig.threshold_storage,
                "threshold_loss": self.kramers_kronig.threshold_loss,
                "flagged": flagged,
            },
            "points": self.table.points,
            "left_out": list(self.left_out),
            "source": self.table.source,
        }


#: A shift the Prony series moved by no more than this many of the spline estimate's standard
#: errors keeps at least that estimate's error (:func:`_joint_covariance`).
JOINT_MOVE_STANDARD_ERRORS = 2.0


def _joint_covariance(log10_at: NDArray[np.float64], covariance: NDArray[np.float64],
                      shifts: ShiftFactors) -> NDArray[np.float64]:
    """The jointly refined shifts' covariance, each variance raised to the spline estimate's
    where the refinement stayed within :data:`JOINT_MOVE_STANDARD_ERRORS` of it (correlations
    kept).

    The joint problem's marginal errors assume the Prony series follows the data to their
    scatter; where it does not (a rig's storage modulus measured to a tenth of a per cent) the
    series holds the shifts tighter than the data do, and those errors came out a third too
    small on the simulated chamber campaign. The spline estimate asks nothing of a model. Where
    the refinement moved a shift further, the two disagree about the data themselves (a flat
    modulus, sweeps barely overlapping) and the joint problem's own error is kept.
    """
    joint_error = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
    spline_error = shifts.log10_at_stderr
    near = np.abs(log10_at - shifts.log10_at) <= JOINT_MOVE_STANDARD_ERRORS * spline_error
    wanted = np.where(near, np.maximum(joint_error, spline_error), joint_error)
    scale = np.divide(wanted, joint_error, out=np.ones_like(wanted), where=joint_error > 0)
    return covariance * np.outer(scale, scale)


def _sweep_scatter(shifts: ShiftFactors, member: NDArray[np.int64]
                   ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Each point's scatter: the overall scatter about the spline master curve, or its sweep's
    robust scatter (1.4826 × median |residual|, so one bad point does not hide itself) where
    that is larger: a noisier sweep (a soft rubber's small loss, hot) is judged by its own
    noise."""
    out = []
    for residual, overall in ((shifts.residual_storage, shifts.storage_scatter),
                              (shifts.residual_loss, shifts.loss_scatter)):
        per_sweep = np.array([1.4826 * np.median(np.abs(residual[member == k]))
                              if np.any(member == k) else overall
                              for k in range(int(member.max()) + 1)])
        out.append(np.maximum(per_sweep, overall)[member])
    return out[0], out[1]


#: Terms tried past the last that lowered :func:`_material_criterion` before
#: :func:`_more_terms` stops.
MORE_TERMS_PATIENCE = 2


def _refined_model(joint: JointFit, table: ModulusTable, member: NDArray[np.int64],
                   offset: NDArray[np.float64]) -> NDArray[np.complex128]:
    """The refined series at every point's reduced frequency under the refined shifts."""
    return joint.series.complex_modulus(
        2 * np.pi * table.frequency_hz * 10.0 ** (joint.log10_at[member] + offset))


def _material_criterion(joint: JointFit, table: ModulusTable, member: NDArray[np.int64],
                        offset: NDArray[np.float64]) -> float:
    """BIC of a series refined with the shifts, each modulus's variance estimated from its own
    residuals: ``n ln(RSS'/n) + n ln(RSS''/n) + k ln(2n)``, ``k`` the series' parameters and
    the free shifts."""
    model = _refined_model(joint, table, member, offset)
    n = table.points
    with np.errstate(divide="ignore", invalid="ignore"):
        squares = [float(np.sum(np.log(np.maximum(part, 1e-300) / measured) ** 2))
                   for part, measured in ((model.real, table.storage_pa),
                                          (model.imag, table.loss_pa))]
    k = 2 * joint.series.terms + 1 + joint.log10_at.size - 1
    if not all(math.isfinite(v) for v in squares):
        return math.inf
    return (n * sum(math.log(max(v, 1e-300) / n) for v in squares)
            + k * math.log(2 * n))


def _more_terms(table: ModulusTable, member: NDArray[np.int64], shifts: ShiftFactors,
                sweep_scatter: tuple[NDArray[np.float64], NDArray[np.float64]],
                joint: JointFit) -> tuple[JointFit, list[dict]]:
    """The series refined with the shifts, given more terms while each lowers
    :func:`_material_criterion`, and the ladder's entries of the counts tried (none where the
    spline's scatter was reached).

    :func:`~viscorig.materials.prony.fit_prony` stops at the first series that reaches the
    data's scatter about the spline master curve. With few frequencies per sweep, that scatter
    is mostly the spline's: its knots, no closer than a sweep's frequency step
    (:func:`~viscorig.materials.shift.frequency_step`), cannot follow the loss modulus's
    curvature, and the shifts it puts the sweeps at are off by as much. Refined together with
    a series, the shifts then follow the data closer than the spline did, and the series
    stopped short: on sweeps generated from a 12-term series with 0.5 % noise and 5
    frequencies per sweep, the spline's scatter of ``ln E''`` was 0.07 (14 times the noise),
    the series stopped at 8 terms and missed the truth by 31 % in E'' inside the measured
    range. Where the refined series follows either modulus closer than the spline's scatter
    by more than :data:`~viscorig.materials.prony.SCATTER_MARGIN`, terms are added (the
    shifts refined anew for each count) while the criterion, which asks nothing of the spline,
    falls; it stops :data:`MORE_TERMS_PATIENCE` terms after the last fall or at
    :data:`~viscorig.materials.prony.MAX_TERMS` terms.
    """
    spline = (shifts.storage_scatter, shifts.loss_scatter)
    scatter = (max(spline[0], 1e-4), max(spline[1], 1e-4))
    fit = model_fit(_refined_model(joint, table, member, shifts.point_offset),
                    table.storage_pa, table.loss_pa, scatter, 2 * joint.series.terms + 1)
    if not (fit.storage_rms_log_error * SCATTER_MARGIN < spline[0]
            or fit.loss_rms_log_error * SCATTER_MARGIN < spline[1]):
        return joint, []
    best = (_material_criterion(joint, table, member, shifts.point_offset), joint)
    entries: list[dict] = []
    for terms in range(joint.series.terms + 1, MAX_TERMS + 1):
        if terms - best[1].series.terms > MORE_TERMS_PATIENCE:
            break
        omega = 2 * np.pi * table.frequency_hz * 10.0 ** (best[1].log10_at[member]
                                                          + shifts.point_offset)
        start, _ = fit_prony_terms(omega, table.storage_pa, table.loss_pa, scatter, terms)
        try:
            candidate = refine_jointly(table.frequency_hz, member, shifts.point_offset,
                                       table.storage_pa, table.loss_pa, sweep_scatter, start,
                                       best[1].log10_at, shifts.reference)
        except (ValueError, np.linalg.LinAlgError):
            break
        if not np.all(np.isfinite(candidate.covariance)):
            break
        tried = model_fit(_refined_model(candidate, table, member, shifts.point_offset),
                          table.storage_pa, table.loss_pa, scatter, 2 * terms + 1)
        criterion = _material_criterion(candidate, table, member, shifts.point_offset)
        entries.append({**tried.ladder_entry(terms, 2 * table.points, scatter),
                        "shifts_refined": True, "criterion": criterion})
        if criterion < best[0]:
            best = (criterion, candidate)
    return best[1], entries


#: Why a sweep is left out that no chain of sweeps sharing values joins to the reference's
#: (:func:`_isolated_sets`).
ISOLATED_SWEEP = ("no chain of sweeps that share a storage modulus and a loss factor joins its "
                  "sweep to the reference's (gaps wider than a sweep's largest step between "
                  "frequencies): its shift would rest on the master curve's extrapolation alone")


#: A sweep whose shift the data place no better than this (standard error, decades) is left
#: out of the master curve.
UNDETERMINED_SHIFT_DECADES = 1.0
#: Why (:data:`UNDETERMINED_SHIFT_DECADES`).
UNDETERMINED_SWEEP = ("its sweep's shift is not determined by the data (standard error above "
                      f"{UNDETERMINED_SHIFT_DECADES:g} decade: a flat modulus, or sweeps that "
                      "barely meet): placed anywhere, it would steer the Prony series there")


def _isolated_sets(table: ModulusTable, reference: int) -> NDArray[np.int64]:
    """The sets the ``reference`` set does not reach through sweeps whose ranges of ``ln E'``
    and of ``ln tan δ`` both overlap, each range widened by the sweep's largest change between
    neighbouring frequencies.

    Two sweeps with a reduced frequency in common have, there, the same storage modulus and the
    same loss factor: where either range misses the other's, no shift lets them meet, and a
    sweep apart from every other is placed where the spline's extrapolation across the gap
    meets it, with a standard error that sees the data alone (a sweep at −40 °C generated 2.3
    decades of reduced frequency past its neighbour came out 1.08 decades off, ± 0.06).
    """
    sets = table.sets
    ranges = np.empty((2, sets.size, 2))
    for k, value in enumerate(sets.tolist()):
        at = table.set_index == value
        order = np.argsort(table.frequency_hz[at])
        storage, loss = table.storage_pa[at][order], table.loss_pa[at][order]
        for row, y in enumerate((np.log(storage), np.log(loss / storage))):
            widen = float(np.max(np.abs(np.diff(y)))) if y.size > 1 else 0.0
            ranges[row, k] = y.min() - widen, y.max() + widen
    low, high = ranges[..., 0], ranges[..., 1]
    linked = np.all(np.maximum(low[:, :, None], low[:, None, :])
                    <= np.minimum(high[:, :, None], high[:, None, :]), axis=0)
    reached = sets == reference
    while True:
        grown = reached | linked[reached].any(axis=0)
        if np.array_equal(grown, reached):
            return sets[~reached]
        reached = grown


def _anchor(temperatures: NDArray[np.float64], reference_c: float | None) -> int:
    if reference_c is None:
        middle = 0.5 * (temperatures[0] + temperatures[-1])
        return int(np.argmin(np.abs(temperatures - middle)))
    return int(np.argmin(np.abs(temperatures - reference_c)))


def build_master(table: ModulusTable, runs: tuple[str, ...] = (),
                 reference_temperature_c: float | None = None, *,
                 systematic: ModulusTable | None = None, vertical: str = "none",
                 expansion_per_k: float = 0.0) -> MasterCurve:
    """Build the master curve of ``table`` (see the module text).

    Parameters
    ----------
    table
        Two or more isothermal sets.
    runs
        Names of the runs the table came from (for the result).
    reference_temperature_c
        Temperature of the master curve; default the measured temperature nearest the middle of
        the range. A temperature between the measured ones is reached through the fitted shift
        function (its error added to every shift's).
    systematic
        The same points one standard error of a quantity they share off (the rig's disc mass):
        the change of the shifts it makes is added to their covariance, common to all.
    vertical
        ``"none"`` or ``"ferry"``: the moduli reduced by ``b_T`` first (see the module text).
    expansion_per_k
        With ``"ferry"``: the volumetric thermal expansion ``α_V`` (1/K) of the density in
        ``b_T``; 0 takes the density as constant.

    Raises
    ------
    InputError
        Too few sets, a reference temperature that needs a shift function none could be
        fitted for, or shift factors the data do not determine (:data:`MAX_SPAN_DECADES`,
        :data:`MAX_SHIFT_RATE_DECADES_PER_K`).
    """
    # trial steps of the nonlinear fits overflow on the way; their results are checked
    with np.errstate(over="ignore", invalid="ignore", divide="ignore", under="ignore"):
        return _build(table, runs, reference_temperature_c, systematic, vertical,
                      expansion_per_k)


def _systematic_covariance(shifts: ShiftFactors, systematic: ModulusTable | None
                           ) -> NDArray[np.float64] | float:
    """The shifts' covariance from a shared error (``build_master``'s ``systematic``)."""
    if systematic is None:
        return 0.0
    moved = estimate_shift_factors(systematic.select(systematic.usable()),
                                   reference_set=int(shifts.sets[shifts.reference]))
    change = moved.log10_at - shifts.log10_at
    return np.outer(change, change) if change.shape == shifts.log10_at.shape else 0.0


#: Reduced frequencies spanning more decades than this are no material's master curve (WLF over
#: 200 K spans about 25): shifts that far apart are the estimate failing on these data.
MAX_SPAN_DECADES = 60.0
#: Fastest change of a shift factor with temperature taken from data (decades per kelvin): WLF
#: with the universal constants changes 0.34 decade/K at its reference, Arrhenius with an
#: activation energy of 1,000 kJ/mol 0.84 decade/K at 250 K.
MAX_SHIFT_RATE_DECADES_PER_K = 5.0


def _check_determined(shifts: ShiftFactors, log10_omega: NDArray[np.float64],
                      member: NDArray[np.int64], where: str) -> None:
    """Refuse shift factors that put the master curve over more than
    :data:`MAX_SPAN_DECADES`, naming the sweep whose shift is known worst, and shift factors of
    two sweeps that differ, beyond three standard errors, by more than
    :data:`MAX_SHIFT_RATE_DECADES_PER_K` per kelvin between them (at least
    :data:`~viscorig.materials.shift.TEMPERATURE_RESOLUTION_K` apart). A sweep with a large
    standard error (on a plateau, say) is kept with its ± up to
    :data:`UNDETERMINED_SHIFT_DECADES`, and left out beyond (before this check)."""
    span = float(np.ptp(log10_omega)) if np.all(np.isfinite(log10_omega)) else math.inf
    if span <= MAX_SPAN_DECADES:
        _check_rate(shifts, member, where)
        return
    spread = np.where(np.isfinite(shifts.log10_at_stderr), shifts.log10_at_stderr, np.inf)
    worst = int(np.argmax(spread))
    raise InputError(
        f"these data do not determine the shift factors: the master curve would span {span:.0f} "
        f"decades ({shifts.temperature_c[worst]:.2f} °C shifts by "
        f"{shifts.log10_at[worst]:+.1f} ± {spread[worst]:.3g} decades; the moduli scatter by rms "
        f"ln {shifts.storage_scatter:.2g} and {shifts.loss_scatter:.2g} about the curve); sweeps "
        "that overlap, at temperatures further apart, are needed", where)


def _check_rate(shifts: ShiftFactors, member: NDArray[np.int64], where: str) -> None:
    """The rate part of :func:`_check_determined`: every pair of sweeps, the worst one named
    with each one's scatter about the curve (``member``: each point's sweep).

    Sweeps on one frequency grid under noise comparable to the change of their moduli across it
    can settle on each other's frequencies, decades apart and each with a small ±: 30 sweeps
    within 1.5 K shifted by 14 decades, ± 0.7; so can one sweep far noisier than the others.
    """
    shift, covariance = shifts.log10_at, shifts.covariance
    variance = (np.diag(covariance)[:, None] + np.diag(covariance)[None, :] - 2 * covariance)
    apart = np.abs(shift[:, None] - shift[None, :])
    allowed = MAX_SHIFT_RATE_DECADES_PER_K * np.maximum(np.abs(
        shifts.temperature_c[:, None] - shifts.temperature_c[None, :]), TEMPERATURE_RESOLUTION_K)
    excess = apart - allowed - 3 * np.sqrt(np.clip(variance, 0.0, None))
    if not np.any(np.nan_to_num(excess, nan=0.0) > 0):
        return
    i, j = sorted(np.unravel_index(int(np.nanargmax(excess)), excess.shape))
    squares = shifts.residual_storage**2 + shifts.residual_loss**2
    scatter = [math.sqrt(float(np.mean(squares[member == k])) / 2) for k in (i, j)]
    raise InputError(
        f"these data do not determine the shift factors: the sweeps at "
        f"{shifts.temperature_c[i]:.2f} °C and {shifts.temperature_c[j]:.2f} °C (rms ln "
        f"{scatter[0]:.2g} and {scatter[1]:.2g} about the master curve) shift "
        f"{shift[j] - shift[i]:+.1f} ± {math.sqrt(max(variance[i, j], 0.0)):.2g} decades apart, "
        f"more than {MAX_SHIFT_RATE_DECADES_PER_K:g} decades per kelvin, faster than any "
        "material's shift factor changes; leave the noisier sweep out, or measure sweeps that "
        "overlap at temperatures further apart", where)


def _scaled(table: ModulusTable, factor: NDArray[np.float64] | float) -> ModulusTable:
    """The table with both moduli times ``factor`` (one number, or one per point)."""
    return replace(table, storage_pa=table.storage_pa * factor, loss_pa=table.loss_pa * factor)


def _reduced(table: ModulusTable, reference_c: float, expansion_per_k: float) -> ModulusTable:
    """The moduli reduced by Ferry's ``b_T`` (:func:`ferry_factor`)."""
    return _scaled(table, ferry_factor(table.temperature_c, reference_c, expansion_per_k))


def _alternative_scatter(table: ModulusTable, reference_set: int) -> tuple[float, float] | None:
    """The scatter of ``ln E'`` and ``ln E''`` about the master curve of the other vertical
    shift's moduli (``table``), or ``None`` where those do not superpose."""
    try:
        other = estimate_shift_factors(table, reference_set=reference_set)
    except InputError:
        return None
    return other.storage_scatter, other.loss_scatter


def _build(table: ModulusTable, runs: tuple[str, ...], reference_temperature_c: float | None,
           systematic: ModulusTable | None = None, vertical: str = "none",
           expansion_per_k: float = 0.0) -> MasterCurve:
    if vertical not in VERTICAL_SHIFTS:
        raise InputError(f"{vertical!r} is not a vertical shift ({', '.join(VERTICAL_SHIFTS)})",
                         "--vertical-shift")
    if not (math.isfinite(expansion_per_k) and abs(expansion_per_k) <= MAX_EXPANSION_PER_K):
        raise InputError(f"{expansion_per_k} is not a volumetric thermal expansion in 1/K "
                         f"(at most {MAX_EXPANSION_PER_K:g} either way)", "--thermal-expansion")
    table.check(table.source or "modulus table")
    given = table
    left_out = tuple(table.unusable_points())
    if left_out:
        table = table.select(table.usable())
    usable = table
    low, high = TEMPERATURE_RANGE_C
    if not (reference_temperature_c is None or low < reference_temperature_c <= high):
        raise InputError(f"{reference_temperature_c} is not a temperature in °C above {low:g} "
                         f"and at most {high:g}", "--reference-temperature")
    temperatures = np.sort(table.set_temperatures_c())
    sets_sorted = table.sets[np.argsort(table.set_temperatures_c(), kind="stable")]
    anchor = _anchor(temperatures, reference_temperature_c)
    reduced_at = (float(temperatures[anchor]) if reference_temperature_c is None
                  else float(reference_temperature_c))
    other = _reduced(table, reduced_at, expansion_per_k) if vertical == "none" else table
    if vertical == "ferry":
        table = _reduced(table, reduced_at, expansion_per_k)
        if systematic is not None:
            systematic = _reduced(systematic, reduced_at, expansion_per_k)

    def without(sets: NDArray[np.int64], why: str) -> MasterCurve:
        """The master curve of the other sweeps, with these sweeps' points left out."""
        keep = ~np.isin(usable.set_index, sets)
        kept = _build(usable.select(keep), runs, reference_temperature_c,
                      None if systematic is None else systematic.select(
                          ~np.isin(systematic.set_index, sets)),
                      vertical, expansion_per_k)
        # points the master curve of the others left out, numbered as in the table given
        origin = np.flatnonzero(given.usable())[np.flatnonzero(keep)]
        inner = tuple({**point, "point": int(origin[point["point"] - 1]) + 1}
                      for point in kept.left_out)
        points = given.point_records(np.isin(given.set_index, sets) & given.usable(), why)
        return replace(kept, left_out=left_out + tuple(points) + inner)

    isolated = _isolated_sets(table, int(sets_sorted[anchor]))
    if isolated.size:
        if table.sets.size - isolated.size < 2:
            raise InputError(
                f"no other sweep shares a storage modulus and loss factor with the sweep at "
                f"{temperatures[anchor]:.1f} °C, the reference: no shift is determined by "
                "these data; sweeps that overlap, at temperatures closer together, are needed",
                table.source or "modulus table")
        return without(isolated, ISOLATED_SWEEP)
    shifts = estimate_shift_factors(table, reference_set=int(sets_sorted[anchor]))
    undetermined = shifts.sets[shifts.log10_at_stderr > UNDETERMINED_SHIFT_DECADES]
    if undetermined.size and table.sets.size - undetermined.size >= 2:
        return without(undetermined, UNDETERMINED_SWEEP)
    alternative = _alternative_scatter(other, int(sets_sorted[anchor]))
    anchor_c = float(shifts.temperature_c[shifts.reference])
    scatter = (shifts.storage_scatter, shifts.loss_scatter)
    position = {s: i for i, s in enumerate(shifts.sets.tolist())}
    member = np.array([position[s] for s in table.set_index.tolist()])
    log10_omega = np.log10(2 * np.pi * table.frequency_hz) + shifts.log10_at[member] + (
        shifts.point_offset)
    _check_determined(shifts, log10_omega, member, table.source or "modulus table")
    omega = 10.0 ** log10_omega
    prony, prony_fit, ladder = fit_prony(omega, table.storage_pa, table.loss_pa, scatter)
    log10_at, covariance = shifts.log10_at.copy(), shifts.covariance.copy()
    sweep_scatter = _sweep_scatter(shifts, member)
    joint = refine_jointly(table.frequency_hz, member, shifts.point_offset, table.storage_pa,
                           table.loss_pa, sweep_scatter, prony, shifts.log10_at,
                           shifts.reference)
    joint_fit = model_fit(_refined_model(joint, table, member, shifts.point_offset),
                          table.storage_pa, table.loss_pa, scatter, 2 * prony.terms + 1)
    refined = bool(joint_fit.chi2 <= prony_fit.chi2 and np.all(np.isfinite(joint.covariance)))
    if refined:
        joint, more = _more_terms(table, member, shifts, sweep_scatter, joint)
        if more:
            joint_fit = model_fit(_refined_model(joint, table, member, shifts.point_offset),
                                  table.storage_pa, table.loss_pa, scatter,
                                  2 * joint.series.terms + 1)
            ladder = [*ladder, *more]
        prony, prony_fit = joint.series, joint_fit
        log10_at, covariance = joint.log10_at.copy(), _joint_covariance(joint.log10_at,
                                                                         joint.covariance, shifts)
    covariance = covariance + _systematic_covariance(shifts, systematic)
    stderr = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
    functions = [fit_shift_function(kind, shifts.temperature_c, log10_at, covariance, anchor_c)
                 for kind in ("wlf", "arrhenius")]
    fitted = [f for f in functions if f is not None]
    reference_c = anchor_c if reference_temperature_c is None else float(reference_temperature_c)
    best = best_shift_function(fitted)
    if best is not None and not best.reaches(reference_c):
        raise InputError(
            f"{reference_c:g} °C is at or below the {best.kind.upper()} function's Vogel "
            f"temperature, {best.reference_temperature_c - best.values[1]:.1f} °C, where the "
            f"shift is infinite (the sweeps span {temperatures.min():.1f} to "
            f"{temperatures.max():.1f} °C): give a temperature above it",
            "--reference-temperature")
    fitted = [f for f in fitted if f.reaches(reference_c)]
    if abs(reference_c - anchor_c) > SAME_TEMPERATURE_K or (
            abs(reference_c - anchor_c) > 1e-9 and best is not None):
        if best is None:
            raise InputError(f"{reference_c} °C is not a measured temperature and no shift "
                             "function could be fitted to reach it; give one of "
                             + ", ".join(f"{t:.1f}" for t in temperatures),
                             "--reference-temperature")
        offset, offset_error = float(best(reference_c)), best.stderr_at(reference_c)
        log10_at -= offset
        stderr = np.sqrt(stderr**2 + offset_error**2)
        fitted = [f.rereferenced(reference_c) for f in fitted]
        # the reduced frequency falls by 10^offset: the series' times grow by it
        prony = PronySeries(prony.long_term_modulus_pa, prony.moduli_pa,
                            prony.tau_s * 10.0**offset)
    else:
        reference_c = anchor_c
    if vertical == "ferry" and reference_c != reduced_at:
        # reduced at the temperature asked for, the reference is the set's own: b_T with it
        factor = float(ferry_factor(reduced_at, reference_c, expansion_per_k))
        table = _scaled(table, factor)
        prony = PronySeries(prony.long_term_modulus_pa * factor, prony.moduli_pa * factor,
                            prony.tau_s)
    best = best_shift_function(fitted)
    reduced = table.frequency_hz * 10.0 ** (log10_at[member] + shifts.point_offset)
    omega = 2 * np.pi * reduced
    fractional, fractional_fit = fit_fractional(omega, table.storage_pa, table.loss_pa, scatter)
    return MasterCurve(
        table=table, runs=tuple(runs), reference_temperature_c=reference_c,
        temperature_c=shifts.temperature_c, log10_at=log10_at, log10_at_stderr=stderr,
        shift_functions=tuple(fitted), shift_function=best, reduced_frequency_hz=reduced,
        prony=prony, prony_fit=prony_fit, ladder=ladder, fractional=fractional,
        fractional_fit=fractional_fit, superposition=check_superposition(table),
        kramers_kronig=check_kramers_kronig(omega, table.storage_pa, table.loss_pa,
                                            sweep_scatter),
        shifts=shifts, jointly_refined=refined, left_out=left_out, vertical=vertical,
        alternative_scatter=alternative, expansion_per_k=expansion_per_k,
    )
