"""The fit: values, uncertainties, error measures, and the fitted model.

:class:`FitResult` is the one representation of a fit in the package: fitting makes it,
:func:`viscorig.identify.store_fit` writes it to the campaign file and
:func:`viscorig.identify.read_fit` reads it back, and :mod:`viscorig.compare`, the report and the
public API (:class:`viscorig.api.Fit` shows one in a notebook) consume it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from viscorig.fitting.noise import NoiseModel
from viscorig.models import Context, Model, parse_spec
from viscorig.numbers import Estimate


@dataclass
class FitResult:
    """Everything a fit found, and the means to evaluate the fitted model.

    Attributes
    ----------
    model
        The concrete fitted model (its ``spec`` is the canonical spec string).
    values
        Every parameter's value (fixed ones included), by global name.
    stderr
        Standard error of every parameter: fitted ones, and those held fixed at values taken
        from elsewhere with an uncertainty (inherited); 0 for values held fixed exactly.
    free
        Names of the fitted parameters, in the order of ``covariance``.
    covariance
        Covariance of the fitted parameters (SI units): noise, misfit scale and inherited
        uncertainty (:mod:`viscorig.fitting.uncertainty`).
    rms_error
        ``sqrt(mean |H_model/H_measured − 1|²)`` over every point of every FRF fitted.
    noise_floor
        The value a perfect model would reach (:mod:`viscorig.fitting.noise`).
    band_hz
        Lowest and highest frequency fitted.
    points
        Frequency points fitted (per FRF).
    frfs
        Names of the FRFs fitted (``"table"``, ``"support"``).
    frequency_hz, residuals
        Frequencies of the points and ``H_model/H_measured − 1`` per FRF.
    bic
        Bayesian information criterion ``n ln(RSS/n) + k ln n`` with ``n`` real residuals.
    warnings
        Human-readable warnings (strongly correlated parameters, values at a bound).
    candidates
        When the spec left a choice open: ``(spec, bic, rms_error)`` of every variant tried.
    noise
        The noise model of the data fitted (shared with diagnosis).
    covariance_names, joint_covariance
        The fitted parameters then the inherited ones, and their joint covariance.
    noise_covariance
        Covariance of the fitted parameters from the noise alone (no misfit scale, nothing
        inherited).
    misfit_scale
        Factor by which the noise part was scaled for the misfit (the Birge ratio
        ``(rms_error/noise_floor)²``, at least 1).
    fits_noise
        The model fits to the noise (``rms_error`` within 1.25 times the floor): the ± are
        measurement uncertainties. Otherwise they are those of the model's band-average.
    inherited_from
        Where the inherited parameters came from (``"run 'table'"``), or ``""``.
    weighting
        How the points were weighted: ``"noise"`` (the project's estimate, generalised least
        squares under :attr:`noise`) or ``"uniform"`` (the paper's method)
        (:mod:`viscorig.fitting.nonlinear`).
    influence
        First-order response of the fitted parameters (SI) to the stacked relative residual
        ``[Re; Im]`` of the points (``free × 2N``, FRFs in the order of ``frfs``, points in the
        order of ``frequency_hz``): ``δp = −influence @ ε``. Two fits of runs measured at the
        same frequencies are compared through it (:mod:`viscorig.compare`).
    source
        Where the fit comes from, in words for legends and the page (``"fitted here"``,
        ``"stored fit 0002"``, ``"diagnosis ladder"``).
    stored
        Read back from a campaign file: only what the file keeps is known (values, standard
        errors, their correlation, the error measures); every parameter with a standard error
        counts as fitted, and there are no residuals.
    """

    model: Model
    values: dict[str, float]
    stderr: dict[str, float]
    free: tuple[str, ...]
    covariance: NDArray[np.float64] = field(repr=False)
    rms_error: float
    noise_floor: float
    band_hz: tuple[float, float]
    points: int
    frfs: tuple[str, ...]
    frequency_hz: NDArray[np.float64] = field(repr=False)
    residuals: dict[str, NDArray[np.complex128]] = field(repr=False)
    bic: float
    nfev: int = 0
    warnings: list[str] = field(default_factory=list)
    candidates: list[tuple[str, float, float]] = field(default_factory=list)
    noise: NoiseModel | None = None
    covariance_names: tuple[str, ...] = ()
    joint_covariance: NDArray[np.float64] | None = None
    noise_covariance: NDArray[np.float64] | None = None
    misfit_scale: float = 1.0
    fits_noise: bool = True
    inherited_from: str = ""
    weighting: str = "uniform"
    influence: NDArray[np.float64] | None = field(default=None, repr=False)
    source: str = ""
    stored: bool = False

    def __post_init__(self) -> None:
        if not self.covariance_names:
            self.covariance_names = tuple(self.free)
        if self.joint_covariance is None:
            self.joint_covariance = np.asarray(self.covariance)

    def __getstate__(self) -> dict[str, Any]:
        # a Model keys its terms by id(): it travels as its spec and is rebuilt on arrival
        state = dict(self.__dict__)
        state["model"] = self.model.spec
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        state = dict(state)
        state["model"] = parse_spec(state["model"])
        self.__dict__.update(state)

    @property
    def has_disc(self) -> bool:
        """A specimen model (it predicts K*), not the bare table."""
        term = self.model.modulus_term
        return term is not None and term.has_disc

    def standard_error(self, name: str) -> float:
        """Standard uncertainty of one parameter from :attr:`joint_covariance` (NaN when the
        parameter has none: held fixed exactly, or not in the model)."""
        if name not in self.covariance_names:
            return math.nan
        i = self.covariance_names.index(name)
        return float(math.sqrt(max(np.asarray(self.joint_covariance)[i, i], 0.0)))

    def block(self, rows: Sequence[str], columns: Sequence[str]) -> NDArray[np.float64]:
        """The joint covariance between two lists of parameter names."""
        r = [self.covariance_names.index(name) for name in rows]
        c = [self.covariance_names.index(name) for name in columns]
        return np.asarray(self.joint_covariance)[np.ix_(r, c)]

    @property
    def inherited(self) -> tuple[str, ...]:
        """Parameters held fixed at values from elsewhere with an uncertainty."""
        return tuple(name for name in self.covariance_names if name not in self.free)

    @property
    def spec(self) -> str:
        """Canonical spec of the fitted model."""
        return self.model.spec

    @property
    def parameters(self) -> dict[str, Estimate]:
        """``{name: Estimate(value, stderr, unit)}`` in the model's parameter order."""
        return {
            p.name: Estimate(self.values[p.name], self.stderr.get(p.name, 0.0), p.unit)
            for p in self.model.parameters
        }

    @property
    def correlation(self) -> NDArray[np.float64]:
        """Correlation matrix of :attr:`covariance_names` (fitted, then inherited)."""
        covariance = np.asarray(self.joint_covariance)
        sigma = np.sqrt(np.abs(np.diag(covariance)))
        with np.errstate(invalid="ignore", divide="ignore"):
            rho = covariance / np.outer(sigma, sigma)
        return np.where(np.isfinite(rho), rho, 0.0)

    def predict(
        self,
        frequency_hz: ArrayLike,
        time_s: ArrayLike | None = None,
        reference_amplitude: ArrayLike | None = None,
        temperature_c: ArrayLike | None = None,
    ) -> dict[str, NDArray[np.complex128]]:
        """The fitted model's accelerances on any frequency grid."""
        ctx = Context(np.asarray(frequency_hz, dtype=float), time_s, reference_amplitude,  # type: ignore[arg-type]
                      temperature_c)  # type: ignore[arg-type]
        return self.model.predict(ctx, self.values)

    def kstar(self, frequency_hz: ArrayLike) -> NDArray[np.complex128]:
        """The fitted ``K*`` (after modifiers) on any frequency grid, N/m."""
        return self.model.kstar(Context(np.asarray(frequency_hz, dtype=float)), self.values)

    @property
    def excludes(self) -> list[str]:
        """What the ± cannot include: effects the data cannot tell that this model leaves out."""
        out = ["a constant calibration error of the transducers (no sweep can see it)"]
        keywords = {term.keyword for term in self.model.effects}
        if "frame" not in keywords:
            coupled = (", and a load cell's K_c reads stiffer with them (by 1 to 3 of its "
                       "standard errors on the simulated paper campaign)"
                       if "load_cell" in keywords else "")
            out.append(
                "the inertial frame under the table: springs to it read (M_s+M_v)/M_f stiffer "
                f"(0.17 % for 3.4 kg on 2000 kg) at the noise floor{coupled}; model it with "
                "frame(M_f)"
            )
        if self.frfs == ("table",) and "support" in self.model.frfs and "load_cell" not in keywords:
            out.append(
                "a link between table and device that is not rigid (X_s/F_e alone cannot tell): "
                "K* reads low by about |K*|²/K_c; fit both FRFs or add load_cell"
            )
        return out

    def to_json(self, run: str) -> dict[str, Any]:
        """The ``identify --json`` object of design.md, plus ``frfs``, ``fits_noise``,
        ``uncertainty`` (what the ± include) and ``correlation``.

        A parameter held fixed exactly (no uncertainty known) has ``stderr`` null: it was not
        estimated here, and 0 would read as exactly known. One inherited with an uncertainty
        (the table's, from the bare-table run) has its standard error.
        """
        names = list(self.covariance_names)
        rho = self.correlation
        return {
            "run": run,
            "model": self.spec,
            "band_hz": [float(self.band_hz[0]), float(self.band_hz[1])],
            "points": int(self.points),
            "frfs": list(self.frfs),
            "rms_error": float(self.rms_error),
            "noise_floor": float(self.noise_floor),
            "fits_noise": bool(self.fits_noise),
            "parameters": {
                name: {
                    "value": float(e.value),
                    "stderr": float(e.stderr) if name in names else None,
                    "unit": e.unit,
                }
                for name, e in self.parameters.items()
            },
            "weighting": self.weighting,
            "uncertainty": {
                "basis": "noise" if self.fits_noise else "band-average (misfit)",
                "misfit_scale": float(self.misfit_scale),
                "inherited": list(self.inherited),
                "inherited_from": self.inherited_from or None,
                "noise": self.noise.describe() if self.noise is not None else [],
                "excludes": self.excludes,
            },
            "correlation": {
                "parameters": names,
                "matrix": [[round(float(v), 6) for v in row] for row in rho],
            },
        }
