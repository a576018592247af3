"""Compare two fits: how much a quantity changed from one run to another, with its ±.

Everything in the project that compares two runs goes through this module: the report, the
``summary`` command's preload variations, and the notebook API (``campaign.compare``).

``compare_fits(before, after, ["K_v", "C_v"])`` gives, for each parameter, the relative change
``after/before − 1`` and its standard uncertainty; :func:`kstar_changes` does the same for the
storage stiffness ``K' = Re K*`` and the loss factor ``η = Im K*/Re K*`` of the two fitted
models at chosen frequencies, :func:`system_changes` for Table 2's ``f_r``, ``ξ`` and ``B_r``,
and :func:`change` for any function of the parameters. A fit is a
:class:`~viscorig.fitting.FitResult`, made here or read back from the campaign file
(:func:`viscorig.identify.read_fit`).

How the two fits' errors are related (first order, GUM):

- **The table they share.** Two specimen fits that inherited the table's ``M_s, K_s, C_s`` from
  the same bare-table run (the same values with the same covariance) are both moved by that
  run's error: a fitted parameter follows the table as ``p = G q + e`` with
  ``G = C_pq C_qq⁻¹``, so the table enters the change once, through ``G_a`` and ``G_b``
  together, and largely cancels in a ratio. A stored fit does not say where its table came
  from; two stored fits that give the table's values with the same standard errors, to the
  last digit, are taken to share it. The covariances come from the stored correlation
  matrices.
- **The misfit they share.** Where a model does not reach the noise floor, its ± are those of
  its band-average (:mod:`viscorig.fitting.uncertainty`): the misfit is spread over the band as
  if it were noise. The same model on the same specimen in two runs misfits in the same way,
  so most of that misfit is common to both and does not move the change. When both fits carry
  their residuals and their influence on the parameters (``FitResult.influence``) and were
  measured at the same frequencies, the residuals are paired point by point and the fitted
  part of the change's variance is the larger of (a) the two runs' noise-only variances
  scaled by how far the *difference* of their residuals is above the noise,
  ``max(1, mean|r_b − r_a|² / (floor_a² + floor_b²))``, and (b) the two fits' joint
  misspecification-robust sandwich (Bartlett weights over neighbouring points, as each fit's
  own, here with the cross products of the two runs' residuals), plus (c) a misfit shift both
  fits share, of the size of their band-average ± beyond the noise: it does not cancel where
  the parameter changed (a shift ``δ`` on both moves ``b/a − 1`` by ``δ (a − b)/a²``). For two
  fits at the noise floor all three stay near the noise-only variance: the runs' noises are
  independent. What no residual shows stays out, as for one fit: where a model error biases a
  parameter more than its band-average ± say, the change carries that bias times the change
  (C_v of a Voigt fit of both FRFs with two fixture modes left out, on the simulator: a 3.5 %
  bias in each fit, 3.7 times its ±, makes the change of C_v 0.32 % low, 2.1 times its ±).
- **Nothing better known.** Otherwise (stored fits, runs on different frequency grids) the
  fitted parts are taken as independent. That is exact for two fits at the noise floor; for a
  misfitting model it overstates the ± of the change, and the change says so
  (:attr:`Change.independent`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray

from viscorig.estimates import TABLE_2_QUANTITIES, derived, gradient
from viscorig.fitting.result import FitResult
from viscorig.fitting.uncertainty import bartlett_meat
from viscorig.models import Context, Model
from viscorig.numbers import Estimate, with_uncertainty

#: A change is called a change when it exceeds this many standard uncertainties.
CHANGE_SIGMAS = 2.0
#: Residuals are paired when at least this fraction of each fit's points has a partner.
PAIRED_FRACTION = 0.9
#: Frequencies closer than this (Hz) are the same point of two sweeps.
SAME_FREQUENCY_HZ = 1e-6

Values = Mapping[str, float]


@dataclass(frozen=True)
class Residuals:
    """A fit's relative residuals and their first-order influence on its fitted parameters.

    Attributes
    ----------
    frequency_hz
        The points, in the order of the data fitted.
    frfs
        FRFs fitted, in the stacked order.
    values
        ``H_model/H_measured − 1``, one row per FRF.
    influence
        ``∂p/∂ε`` (fitted parameters × stacked ``[Re; Im]`` residual), see
        :attr:`viscorig.fitting.FitResult.influence`.
    noise_floor
        The floor of the noise model the fit was weighed with.
    """

    frequency_hz: NDArray[np.float64]
    frfs: tuple[str, ...]
    values: NDArray[np.complex128]
    influence: NDArray[np.float64]
    noise_floor: float

    def columns(self, frf: str, part: int, points: NDArray[np.intp]) -> NDArray[np.intp]:
        """Columns of :attr:`influence` of some points of one FRF (part 0 real, 1 imaginary)."""
        n = self.frequency_hz.size
        return part * len(self.frfs) * n + self.frfs.index(frf) * n + points


def residuals_of(fit: FitResult) -> Residuals | None:
    """A fit's residuals and their influence, for pairing with another run's (``None`` when the
    fit does not carry them whole: a stored fit, one fitted without the influence)."""
    frfs = tuple(fit.frfs)
    influence = fit.influence
    if influence is None or not all(name in fit.residuals for name in frfs):
        return None
    values = np.array([fit.residuals[name] for name in frfs], dtype=complex)
    n = np.asarray(fit.frequency_hz).size
    if values.shape != (len(frfs), n) or influence.shape != (len(fit.free), 2 * len(frfs) * n):
        return None
    # the floor of the noise model the fit was weighed with: the report and the API may show
    # a fit beside another floor (the diagnosis's), which is not the one its residuals have
    floor = fit.noise.floor_of(frfs) if fit.noise is not None else fit.noise_floor
    return Residuals(np.asarray(fit.frequency_hz, dtype=float), frfs, values,
                     np.asarray(influence, dtype=float), float(floor))


@dataclass(frozen=True)
class Change:
    """One quantity in two fits, and its relative change with the standard uncertainty.

    Attributes
    ----------
    quantity, unit
        What changed (``"K_v"``, ``"K' at 20 Hz"``) and the quantity's unit.
    before, before_stderr, after, after_stderr
        The quantity in each fit, with its standard uncertainty in that fit alone.
    relative, relative_stderr
        ``after/before − 1`` and its standard uncertainty (the fits' correlation counted).
    basis
        How the two fits' errors were related, in words (one phrase each).
    independent
        The fits were taken as independent for want of anything better while one of them does
        not fit to the noise: the ± then overstate the uncertainty of the change.
    """

    quantity: str
    unit: str
    before: float
    before_stderr: float
    after: float
    after_stderr: float
    relative: float
    relative_stderr: float
    basis: tuple[str, ...] = ()
    independent: bool = False

    @property
    def significant(self) -> bool:
        """The change exceeds :data:`CHANGE_SIGMAS` standard uncertainties."""
        return abs(self.relative) > CHANGE_SIGMAS * self.relative_stderr

    def percent(self) -> str:
        """``"+9.3 ± 0.4 %"``: the change and its uncertainty, to the uncertainty's first
        significant digit (two when it is a 1 or a 2)."""
        return with_uncertainty(100 * self.relative, 100 * self.relative_stderr, "%", signed=True)

    def words(self, condition: str = "") -> str:
        """``"K_v rose 9.3 ± 0.4 % with preload"``, or that it did not change beyond its
        uncertainty; says when the two fits were taken as independent."""
        where = f" {condition}" if condition else ""
        if self.significant:
            verb = "rose" if self.relative > 0 else "fell"
            text = f"{self.quantity} {verb} {self.percent().lstrip('+-')}{where}"
        else:
            text = f"{self.quantity} did not change beyond its uncertainty{where}: {self.percent()}"
        if self.independent:
            text += " (the two fits taken as independent)"
        return text

    def to_json(self) -> dict[str, float | str]:
        """``{"value", "stderr", "unit"}`` of the change in percent."""
        return Estimate(100 * float(self.relative), 100 * float(self.relative_stderr),
                        "%").to_json()


class Pair:
    """Two fits, and how their errors are related (the module text says how)."""

    def __init__(self, before: FitResult, after: FitResult) -> None:
        self.a = before
        self.b = after
        self.shared = self._shared()
        self.basis: list[str] = []
        if self.shared:
            source = self.a.inherited_from or "the same stored values"
            self.basis.append(f"{', '.join(self.shared)} shared ({source}), counted once")
        self._fitted_a = [n for n in self.a.covariance_names if n not in self.shared]
        self._fitted_b = [n for n in self.b.covariance_names if n not in self.shared]
        self._split = {id(self.a): self._conditional(self.a, self._fitted_a),
                       id(self.b): self._conditional(self.b, self._fitted_b)}
        self._paired = self._pair_residuals()
        misfit = not (self.a.fits_noise and self.b.fits_noise)
        self.independent = self._paired is None and misfit
        if self._paired is not None and misfit:
            self.basis.append(f"misfit shared: residuals paired at {self._paired[2]} "
                              "frequencies (a model that does not fit to the noise: the change "
                              "of its band-averages)")
        elif self._paired is not None:
            self.basis.append(f"residuals paired at {self._paired[2]} frequencies")
        elif misfit:
            self.basis.append("the two fits' errors taken as independent (a misfit they share "
                              "is counted twice)")
        else:
            self.basis.append("the two runs' noise independent")
        if self.a.spec != self.b.spec:
            self.basis.append(f"two models ({self.a.spec}; {self.b.spec}): how far their "
                              "forms differ is not in the ±")

    def _shared(self) -> tuple[str, ...]:
        """Parameters both fits hold at the same inherited values (the same variables)."""
        a, b = self.a, self.b
        if a.inherited_from and a.inherited_from == b.inherited_from:
            candidates = [n for n in a.inherited if n in b.inherited]
        elif a.stored and b.stored:
            candidates = [n for n in a.covariance_names if n in b.covariance_names]
        else:
            return ()
        order = {name: i for i, name in enumerate(a.model.names)}
        return tuple(sorted((n for n in candidates
                             if a.values[n] == b.values[n]
                             and a.standard_error(n) == b.standard_error(n)),
                            key=lambda name: order.get(name, len(order))))

    def _conditional(self, fit: FitResult, own: list[str]
                     ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(G, F)``: the own parameters' response to the shared ones, ``G = C_pq C_qq⁻¹``,
        and their covariance given them, ``F = C_pp − G C_qp``."""
        c_pp = fit.block(own, own)
        if not self.shared:
            return np.zeros((len(own), 0)), c_pp
        c_pq = fit.block(own, self.shared)
        g = c_pq @ np.linalg.pinv(fit.block(self.shared, self.shared))
        return g, c_pp - g @ c_pq.T

    def _pair_residuals(self):
        """``(rows, blocks, count, birge)`` of the two fits' paired residual contributions, or
        ``None`` when they cannot be paired (see the module text)."""
        a, b = self.a, self.b
        ra, rb = residuals_of(a), residuals_of(b)
        if (ra is None or rb is None or a.noise_covariance is None
                or b.noise_covariance is None or a.spec != b.spec or a.free != b.free
                or set(ra.frfs) != set(rb.frfs) or list(a.free) != self._fitted_a
                or list(b.free) != self._fitted_b):
            return None
        fa = np.round(ra.frequency_hz / SAME_FREQUENCY_HZ)
        fb = np.round(rb.frequency_hz / SAME_FREQUENCY_HZ)
        if np.unique(fa).size != fa.size or np.unique(fb).size != fb.size:
            return None  # runs joined side by side: no one-to-one pairing
        common, ia, ib = np.intersect1d(fa, fb, return_indices=True)
        if common.size < PAIRED_FRACTION * max(fa.size, fb.size) or common.size < 10:
            return None
        rows_a, rows_b, blocks, differences = [], [], [], []
        for frf in ra.frfs:
            da = ra.values[ra.frfs.index(frf)][ia]
            db = rb.values[rb.frfs.index(frf)][ib]
            differences.append(np.abs(db - da) ** 2)
            for part, (pa, pb) in enumerate(((da.real, db.real), (da.imag, db.imag))):
                rows_a.append((ra.influence[:, ra.columns(frf, part, ia)] * pa).T)
                rows_b.append((rb.influence[:, rb.columns(frf, part, ib)] * pb).T)
                blocks.append(common.size)
        rows = np.hstack([np.vstack(rows_a), np.vstack(rows_b)])
        floors = ra.noise_floor**2 + rb.noise_floor**2
        birge = max(1.0, float(np.mean(np.concatenate(differences))) / floors) \
            if floors > 0 else math.inf
        return rows, blocks, int(common.size), birge

    @cached_property
    def _robust(self) -> NDArray[np.float64]:
        """The two fits' joint misspecification-robust sandwich over the paired points."""
        rows, blocks, _, _ = self._paired
        n, k = rows.shape[0], max(len(self.a.free), len(self.b.free))
        return bartlett_meat(rows, blocks) * (n / max(n - k, 1))

    @cached_property
    def _common_misfit(self) -> NDArray[np.float64]:
        """Covariance of a misfit shift both fits share: the part of each fit's covariance
        beyond its noise (the misfit scale), averaged, its negative directions left out."""
        parts = []
        for fit in (self.a, self.b):
            own = self._split[id(fit)][1]
            assert fit.noise_covariance is not None  # only paired fits with noise get here
            parts.append(own - fit.noise_covariance)
        eigenvalues, vectors = np.linalg.eigh((parts[0] + parts[1]) / 2)
        return (vectors * np.clip(eigenvalues, 0.0, None)) @ vectors.T

    def variance(self, grad_a: NDArray[np.float64], grad_b: NDArray[np.float64]) -> float:
        """Variance of a quantity with gradients ``grad_a`` (over the first fit's
        ``covariance_names``) and ``grad_b`` (the second's)."""
        a, b = self.a, self.b
        g_a = dict(zip(a.covariance_names, grad_a, strict=True))
        g_b = dict(zip(b.covariance_names, grad_b, strict=True))
        pa = np.array([g_a[n] for n in self._fitted_a])
        pb = np.array([g_b[n] for n in self._fitted_b])
        (lever_a, own_a), (lever_b, own_b) = self._split[id(a)], self._split[id(b)]
        total = 0.0
        if self.shared:
            h = (np.array([g_a[n] + g_b[n] for n in self.shared]) + pa @ lever_a
                 + pb @ lever_b)
            total += float(h @ a.block(self.shared, self.shared) @ h)
        independent = float(pa @ own_a @ pa + pb @ own_b @ pb)
        if self._paired is None:
            return total + independent
        noise = float(pa @ a.noise_covariance @ pa + pb @ b.noise_covariance @ pb)
        g = np.concatenate([pa, pb])
        shift = pa + pb  # a misfit moving both fits' parameters alike, seen by the change
        return (total + max(self._paired[3] * noise, float(g @ self._robust @ g))
                + float(shift @ self._common_misfit @ shift))

    def relative(self, function: Callable[[Values], ArrayLike],
                 after_function: Callable[[Values], ArrayLike] | None = None
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``f_b(after)/f_a(before) − 1`` and its standard uncertainty, for a scalar or an
        array-valued function of the parameters (``K'`` on a frequency grid)."""
        a, b = self.a, self.b
        after_function = after_function or function
        before = np.atleast_1d(np.asarray(function(a.values), dtype=float))
        after = np.atleast_1d(np.asarray(after_function(b.values), dtype=float))
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = after / before
            grad_a = -(ratio / before)[:, None] * _gradient(function, a, before.size)
            grad_b = _gradient(after_function, b, before.size) / before[:, None]
        variance = np.array([self.variance(ga, gb) for ga, gb in zip(grad_a, grad_b,
                                                                     strict=True)])
        stderr = np.sqrt(np.maximum(variance, 0.0))
        return ratio - 1.0, np.where(np.isfinite(ratio), stderr, np.nan)

    def change(self, quantity: str, unit: str, function: Callable[[Values], ArrayLike],
               after_function: Callable[[Values], ArrayLike] | None = None) -> Change:
        """The relative change of ``function`` of the parameters from the first fit to the
        second (``after_function`` for the second when its model differs)."""
        after_function = after_function or function
        before, after = derived(self.a, function, unit), derived(self.b, after_function, unit)
        relative, stderr = self.relative(function, after_function)
        return Change(quantity, unit, before.value, before.stderr, after.value, after.stderr,
                      float(relative[0]), float(stderr[0]), tuple(self.basis), self.independent)


def _gradient(function: Callable[[Values], ArrayLike], fit: FitResult, size: int
              ) -> NDArray[np.float64]:
    """``∂f/∂θ`` over the fit's ``covariance_names``, as ``size × names``."""
    names = list(fit.covariance_names)
    if not names:
        return np.zeros((size, 0))
    return np.asarray(gradient(function, dict(fit.values), names), dtype=float).reshape(size,
                                                                                      len(names))


def change(before: FitResult, after: FitResult, function: Callable[[Values], float],
           quantity: str, unit: str = "") -> Change:
    """The relative change of a function of the parameters, ``f(after)/f(before) − 1``, with
    its uncertainty (``function`` maps a fit's values to a number: ``lambda v: v["C_v"]``)."""
    return Pair(before, after).change(quantity, unit, function)


def _unit(fit: FitResult, name: str) -> str:
    return fit.model.by_name[name].unit if name in fit.model.by_name else ""


def compare_fits(before: FitResult, after: FitResult, names: Iterable[str]) -> list[Change]:
    """The change of parameters ``names`` from fit ``before`` to fit ``after``.

    Parameters missing from either fit are left out.
    """
    pair = Pair(before, after)
    return [pair.change(name, _unit(pair.a, name), _value_of(name))
            for name in names if name in pair.a.values and name in pair.b.values]


def _value_of(name: str) -> Callable[[Values], float]:
    """``values -> values[name]``."""
    return lambda values: values[name]


def system_changes(before: FitResult, after: FitResult) -> list[Change]:
    """Changes of Table 2's ``f_r``, ``xi`` and ``B_r`` (Voigt fits with the table's values)."""
    pair = Pair(before, after)
    return [pair.change(name, unit, function)
            for name, (function, unit) in TABLE_2_QUANTITIES.items()]


def storage_stiffness_of(model: Model, frequency_hz: ArrayLike) -> Callable[[Values], ArrayLike]:
    """``values -> K'`` (N/m) of a model at ``frequency_hz`` (a number or an array)."""
    return _kstar_part(model, frequency_hz, lambda kstar: kstar.real)


def loss_factor_of(model: Model, frequency_hz: ArrayLike) -> Callable[[Values], ArrayLike]:
    """``values -> η = Im K*/Re K*`` of a model at ``frequency_hz`` (a number or an array)."""
    return _kstar_part(model, frequency_hz, lambda kstar: kstar.imag / kstar.real)


def _kstar_part(model: Model, frequency_hz: ArrayLike, part: Callable) -> Callable:
    scalar = np.ndim(frequency_hz) == 0
    context = Context(np.atleast_1d(np.asarray(frequency_hz, dtype=float)))

    def evaluate(values: Values) -> ArrayLike:
        result = part(model.kstar(context, values))
        return float(result[0]) if scalar else result

    return evaluate


def kstar_at(fit: FitResult, frequency_hz: float
             ) -> tuple[tuple[float, float], tuple[float, float]]:
    """``((K', u), (η, u))`` of a fit's K* at one frequency."""
    storage = derived(fit, storage_stiffness_of(fit.model, frequency_hz))
    loss = derived(fit, loss_factor_of(fit.model, frequency_hz))
    return (storage.value, storage.stderr), (loss.value, loss.stderr)


def kstar_changes(before: FitResult, after: FitResult, frequencies_hz: Sequence[float]
                  ) -> list[Change]:
    """Changes of ``K'`` and of ``η`` at each frequency, from the two fits' K* (the two models
    may differ)."""
    pair = Pair(before, after)
    first, second = pair.a.model, pair.b.model
    changes = []
    for f in frequencies_hz:
        changes.append(pair.change(f"K' at {f:g} Hz", "N/m", storage_stiffness_of(first, f),
                                   storage_stiffness_of(second, f)))
        changes.append(pair.change(f"η at {f:g} Hz", "", loss_factor_of(first, f),
                                   loss_factor_of(second, f)))
    return changes
