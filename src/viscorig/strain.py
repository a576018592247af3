"""The strain-amplitude dependence of a specimen (Payne effect, Kraus's model) from runs of the
same specimen at several levels, with standard errors.

At constant acceleration a run's displacement amplitude falls as 1/f², so within one run the
amplitude dependence looks like frequency dependence. Between runs at different levels the
frequencies are the same and only the amplitude differs: the difference of their K* (Eq. 5,
``K* = F_v/X_v + ω² M_v``; ``M_v`` cancels, and so does the matrix rubber, whatever its model)
is the difference of the filler network's stiffness at the two amplitudes,
``K_f(x_a) − K_f(x_b)`` of :func:`viscorig.models.effects.kraus_stiffness`. Those differences,
at every frequency of the run at the lowest level that another run shares, are fitted by
generalized least squares: the noise of each run's K* from the analyser's normalized variance
of the support FRF, and the differences against one base run correlated through its noise
(covariance ``diag(σ_j²) + σ_0² 11ᵀ`` at each frequency; taken as independent, the errors of
``L_f`` and ``m_k`` from three levels came out 16 to 18 % too small over 50 simulated
campaigns). Standard errors from the whitened Jacobian, scaled by the
reduced chi-square.

A fit is stored in the campaign file under ``/fits/<id>``, beside ``/runs`` (a fit of several
runs belongs to none of them; :meth:`viscorig.storage.CampaignFile.add_joint_fit`):
:func:`store_payne_fit` writes it, :func:`stored_payne_fits` reads every one back.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from viscorig.errors import InputError
from viscorig.models.effects import KRAUS_PARAMETERS, kraus_stiffness
from viscorig.numbers import Estimate
from viscorig.storage import CampaignFile, JointFitRecord

__all__ = ["PayneFit", "identify_payne", "read_payne_fit", "store_payne_fit",
           "stored_payne_fits"]

#: The model name a Payne fit is stored under (``/fits/<id>`` attribute ``model``).
PAYNE_MODEL = "kraus"


@dataclass(frozen=True)
class PayneFit:
    """What :func:`identify_payne` found.

    Attributes
    ----------
    runs
        The runs, lowest level first (the reference of the differences).
    parameters
        ``K_f``, ``L_f``, ``x_c``, ``m_k``, each an :class:`~viscorig.numbers.Estimate`.
    points
        Differences fitted (complex values).
    reduced_chi_square
        Of the weighted fit (1 when the misfit is the noise).
    displacement_range_m
        Smallest and largest displacement amplitude of the runs.
    band_hz
        Lowest and highest frequency of the differences fitted.
    correlation
        Correlation matrix of the parameters, in the order of ``parameters`` (``None`` when
        the file stores none).
    fit_id, created
        The id under ``/fits`` and the time it was stored (``""`` for a fit made here).
    """

    runs: tuple[str, ...]
    parameters: dict[str, Estimate]
    points: int
    reduced_chi_square: float
    displacement_range_m: tuple[float, float]
    band_hz: tuple[float, float] = (math.nan, math.nan)
    correlation: NDArray[np.float64] | None = field(default=None, repr=False, compare=False)
    fit_id: str = ""
    created: str = ""

    def to_json(self) -> dict[str, object]:
        document: dict[str, object] = {
            "runs": list(self.runs), "model": PAYNE_MODEL, "points": self.points,
            "reduced_chi_square": self.reduced_chi_square,
            "displacement_range_m": list(self.displacement_range_m),
            "band_hz": list(self.band_hz),
            "parameters": {name: p.to_json() for name, p in self.parameters.items()},
        }
        if self.correlation is not None:
            document["correlation"] = {
                "parameters": list(self.parameters),
                "matrix": [[round(float(v), 6) for v in row] for row in self.correlation]}
        return document


@dataclass(frozen=True)
class _Level:
    name: str
    frequency_hz: NDArray[np.float64]
    kstar_difference_base: NDArray[np.complex128]  # F_v / X_v  (M_v cancels in differences)
    sigma: NDArray[np.float64]
    displacement_m: NDArray[np.float64]


def _level(campaign: CampaignFile, name: str, band_hz: tuple[float, float] | None) -> _Level:
    run = campaign.run(name)
    if run.points == 0:
        raise InputError("has no points", f"{campaign.path}: run {name}")
    support = np.asarray(run.accelerance_support, dtype=complex)
    if not np.any(np.isfinite(support)):
        raise InputError("has no support FRF (a bare-table run?)", f"{campaign.path}: run {name}")
    f = np.asarray(run.frequency_hz, dtype=float)
    keep = np.isfinite(support) & (np.abs(support) > 0) & (run.flags == 0)
    if band_hz is not None:
        keep &= (f >= band_hz[0]) & (f <= band_hz[1])
    omega = 2.0 * np.pi * f
    dynamic = -(omega**2) / np.where(keep, support, 1.0)
    variance = (np.full(f.size, np.nan) if run.variance_support is None
                else np.asarray(run.variance_support, dtype=float))
    sigma = np.abs(dynamic) * np.sqrt(np.where(np.isfinite(variance), variance, np.nan))
    displacement = np.abs(np.asarray(run.reference_amplitude, dtype=float)) / omega**2
    return _Level(name, f[keep], dynamic[keep], sigma[keep], displacement[keep])


#: Runs whose temperatures differ by more than this are two material states, K.
SAME_TEMPERATURE_K = 1.0


def _one_specimen_at_several_levels(campaign: CampaignFile, runs: list[str]) -> None:
    """Refuse runs of different specimens (text, hardness, preload, temperature beyond
    :data:`SAME_TEMPERATURE_K`) or two at one level: their differences would be fitted as a
    strain dependence."""
    metadata = {name: campaign.run_metadata(name) for name in runs}
    first, reference = runs[0], metadata[runs[0]]

    def same(a: object, b: object, tolerance: float = 0.0) -> bool:
        if isinstance(a, float) and isinstance(b, float):
            return (math.isnan(a) and math.isnan(b)) or abs(a - b) <= tolerance
        return a == b

    for name in runs[1:]:
        other = metadata[name]
        for attribute, words, tolerance in (
                ("specimen", "specimen", 0.0), ("hardness_shore_a", "hardness", 0.0),
                ("preload_strain", "preload", 0.0),
                ("temperature_c", "temperature", SAME_TEMPERATURE_K)):
            a, b = getattr(reference, attribute), getattr(other, attribute)
            if not same(a, b, tolerance):
                raise InputError(f"runs '{first}' and '{name}' differ in {words} ({a!r} and "
                                 f"{b!r}): the Payne effect is fitted from one specimen at "
                                 "several levels", "runs")
    by_level: dict[float, str] = {}
    for name in runs:
        level = metadata[name].level_m_per_s2
        if level in by_level:
            raise InputError(f"runs '{by_level[level]}' and '{name}' are both at {level:g} "
                             "m/s^2: the Payne effect is fitted between different levels",
                             "runs")
        by_level[level] = name


def identify_payne(campaign: CampaignFile, runs: Sequence[str],
                   band_hz: tuple[float, float] | None = None) -> PayneFit:
    """Identify Kraus's Payne-effect parameters from runs of one specimen at several levels
    (module text).

    Parameters
    ----------
    campaign
        The campaign file.
    runs
        Two or more runs of the same specimen, at the same temperature, at different levels.
    band_hz
        Fit only this band.

    Raises
    ------
    InputError
        Fewer than two runs, no common frequency, a run without support FRF.
    """
    from scipy.optimize import least_squares

    if len(set(runs)) < 2:
        raise InputError("needs two or more runs at different levels", "runs")
    _one_specimen_at_several_levels(campaign, list(dict.fromkeys(runs)))
    levels = [_level(campaign, name, band_hz) for name in dict.fromkeys(runs)]
    levels.sort(key=lambda level: float(np.median(level.displacement_m)))
    x, differences, whitening, frequency = _aligned(levels, str(campaign.path))
    x_low, x_high = x[:, :1], x[:, 1:]
    valid = np.isfinite(differences)
    measured = np.where(valid, differences, 0.0)
    names = [p.name for p in KRAUS_PARAMETERS]

    def unpack(theta: NDArray[np.float64]) -> dict[str, float]:
        return {"K_f": math.exp(theta[0]), "L_f": math.exp(theta[1]),
                "x_c": math.exp(theta[2]), "m_k": float(theta[3])}

    def residual(theta: NDArray[np.float64]) -> NDArray[np.float64]:
        p = unpack(theta)
        model = kraus_stiffness(np.where(valid, x_high, 1.0), p) - kraus_stiffness(x_low, p)
        error = np.einsum("nij,nj->ni", whitening, np.where(valid, model - measured, 0.0))[valid]
        return np.concatenate([error.real, error.imag])

    span = float(np.max(np.abs(measured.real))) or 1.0
    best = None
    for x_c in np.geomspace(max(x_low.min(), 1e-8), x_high[valid].max(), 5):
        for m in (0.5, 1.0, 1.5):
            start = np.array([math.log(2 * span), math.log(0.2 * span), math.log(x_c), m])
            fit = least_squares(residual, start, method="trf", x_scale="jac",
                                bounds=([math.log(1.0), math.log(1e-2), math.log(1e-8), 0.1],
                                        [math.log(1e8), math.log(1e8), math.log(1e-2), 4.0]))
            if best is None or fit.cost < best.cost:
                best = fit
    assert best is not None
    dof = max(best.fun.size - best.x.size, 1)
    chi2 = float(2.0 * best.cost / dof)
    jac = best.jac
    covariance = np.linalg.pinv(jac.T @ jac) * max(chi2, 1e-300)
    theta_err = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
    # the values' correlation is their logarithms' (each a positive multiple of its own)
    scale = np.where(theta_err > 0, theta_err, 1.0)
    correlation = np.clip(covariance / np.outer(scale, scale), -1.0, 1.0)
    values = unpack(best.x)
    # log-parameters: stderr of the value is value * stderr of its logarithm
    errors = {"K_f": values["K_f"] * theta_err[0], "L_f": values["L_f"] * theta_err[1],
              "x_c": values["x_c"] * theta_err[2], "m_k": float(theta_err[3])}
    units = {p.name: p.unit for p in KRAUS_PARAMETERS}
    displacement = np.concatenate([x_low.ravel(), x_high[valid]])
    return PayneFit(
        runs=tuple(level.name for level in levels),
        parameters={name: Estimate(values[name], errors[name], units[name]) for name in names},
        points=int(valid.sum()), reduced_chi_square=chi2,
        displacement_range_m=(float(displacement.min()), float(displacement.max())),
        band_hz=(float(frequency.min()), float(frequency.max())),
        correlation=correlation,
    )


def store_payne_fit(campaign: CampaignFile, fit: PayneFit) -> str:
    """Store a Payne fit under ``/fits/<id>`` in one commit (all of it or nothing) and return
    its id; each call adds a fit, as re-identifying a run does."""
    names = tuple(fit.parameters)
    return campaign.add_joint_fit(
        fit.runs, model=PAYNE_MODEL, band_hz=fit.band_hz,
        reduced_chi_square=fit.reduced_chi_square, points=fit.points,
        parameters=fit.parameters,
        correlation=None if fit.correlation is None else (names, fit.correlation),
        weighting="noise",
        attributes={"displacement_range_m": fit.displacement_range_m})


def read_payne_fit(record: JointFitRecord) -> PayneFit:
    """A Payne fit stored in a campaign file (:meth:`CampaignFile.joint_fits`), as
    :func:`identify_payne` returns it.

    Raises
    ------
    InputError
        The stored fit is not a ``kraus`` fit, or lacks some of its parameters.
    """
    where = f"/fits/{record.id}"
    if record.model != PAYNE_MODEL:
        raise InputError(f"is a {record.model!r} fit, not {PAYNE_MODEL!r}", where)
    names = [p.name for p in KRAUS_PARAMETERS]
    missing = [name for name in names if name not in record.parameters]
    if missing:
        raise InputError(f"lacks {', '.join(missing)}", where)
    correlation = None
    if record.correlation is not None:
        index = {name: i for i, name in enumerate(record.correlation[0])}
        if all(name in index for name in names):
            order = [index[name] for name in names]
            correlation = np.asarray(record.correlation[1], dtype=float)[np.ix_(order, order)]
    span = np.asarray(record.extra.get("displacement_range_m", (math.nan, math.nan)),
                      dtype=float).ravel()
    low, high = (float(span[0]), float(span[1])) if span.size == 2 else (math.nan, math.nan)
    return PayneFit(
        runs=record.runs, parameters={name: record.parameters[name] for name in names},
        points=record.points, reduced_chi_square=record.reduced_chi_square,
        displacement_range_m=(low, high), band_hz=record.band_hz, correlation=correlation,
        fit_id=record.id, created=record.created)


def stored_payne_fits(campaign: CampaignFile) -> list[PayneFit]:
    """The Payne fits the file stores (``/fits``), oldest first; a stored fit of another
    model, or one that is not whole, is left out."""
    out = []
    for record in campaign.joint_fits():
        try:
            out.append(read_payne_fit(record))
        except InputError:
            continue
    return out


def _aligned(levels: list[_Level], path: str) -> tuple[
        NDArray[np.float64], NDArray[np.complex128], NDArray[np.float64], NDArray[np.float64]]:
    """At each frequency of the base run (the lowest level) that another run shares: the
    displacements ``(n, L)``, the differences of K* against the base ``(n, L − 1)`` (NaN where a
    run lacks the frequency), the whitening ``W`` (``W C Wᵀ = I``) of their covariance per
    component, ``C = diag(s_j²) + s_0² 11ᵀ`` (``s`` a run's K* noise per component), and the
    frequencies ``(n,)``."""
    base = levels[0]
    keys = np.round(base.frequency_hz, 6)
    n, k = keys.size, len(levels) - 1
    x = np.full((n, k + 1), np.nan)
    x[:, 0] = base.displacement_m
    differences = np.full((n, k), np.nan + 0j)
    spread = np.full((n, k + 1), np.nan)
    spread[:, 0] = base.sigma / math.sqrt(2.0)
    for column, other in enumerate(levels[1:]):
        common, i, j = np.intersect1d(keys, np.round(other.frequency_hz, 6),
                                      return_indices=True)
        if common.size == 0:
            raise InputError(f"no frequency in common with run {base.name!r}",
                             f"{path}: run {other.name}")
        x[i, column + 1] = other.displacement_m[j]
        differences[i, column] = other.kstar_difference_base[j] - base.kstar_difference_base[i]
        spread[i, column + 1] = other.sigma[j] / math.sqrt(2.0)
    shared = np.any(np.isfinite(differences), axis=1)
    x, differences, spread = x[shared], differences[shared], spread[shared]
    frequency = base.frequency_hz[shared]
    valid = np.isfinite(differences)
    if not np.all(np.isfinite(spread[:, 0]) & (spread[:, 0] > 0)) or not np.all(
            np.isfinite(spread[:, 1:][valid]) & (spread[:, 1:][valid] > 0)):
        # no usable variance: every run's noise alike, from the scatter of the differences
        # (a difference's variance per component, |d|²/2, is twice a run's s²)
        spread = np.full(spread.shape, float(np.std(differences[valid])) / 2.0 or 1.0)
    own = np.where(valid, spread[:, 1:] ** 2, 1.0)
    common_part = np.where(valid[:, :, None] & valid[:, None, :],
                           spread[:, :1, None] ** 2, 0.0)
    covariance = common_part + own[:, :, None] * np.eye(k)[None]
    whitening = np.linalg.inv(np.linalg.cholesky(covariance))
    return x, differences, whitening, frequency
