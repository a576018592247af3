"""The result of a fit: values, uncertainties, error measures, and the fitted model."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from viscorig.models import Context, Model


class Estimate(NamedTuple):
    """One fitted parameter: value, standard error (0 when fixed), SI unit."""

    value: float
    stderr: float
    unit: str


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
        Standard error of every free parameter (0 for fixed ones).
    free
        Names of the fitted parameters, in the order of ``covariance``.
    covariance
        Covariance of the free parameters (SI units), scaled by the residual variance.
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
        """Correlation matrix of the free parameters."""
        sigma = np.sqrt(np.diag(self.covariance))
        with np.errstate(invalid="ignore", divide="ignore"):
            return self.covariance / np.outer(sigma, sigma)

    def predict(
        self,
        frequency_hz: ArrayLike,
        time_s: ArrayLike | None = None,
        reference_amplitude: ArrayLike | None = None,
    ) -> dict[str, NDArray[np.complex128]]:
        """The fitted model's accelerances on any frequency grid."""
        ctx = Context(np.asarray(frequency_hz, dtype=float), time_s, reference_amplitude)  # type: ignore[arg-type]
        return self.model.predict(ctx, self.values)

    def kstar(self, frequency_hz: ArrayLike) -> NDArray[np.complex128]:
        """The fitted ``K*`` (after modifiers) on any frequency grid, N/m."""
        return self.model.kstar(Context(np.asarray(frequency_hz, dtype=float)), self.values)

    def to_json(self, run: str) -> dict[str, Any]:
        """The ``identify --json`` object of design.md (plus ``frfs``).

        A parameter held fixed in this fit (the table's, taken from the bare-table run) has
        ``stderr`` null: it was not estimated here, and 0 would read as exactly known.
        """
        return {
            "run": run,
            "model": self.spec,
            "band_hz": [float(self.band_hz[0]), float(self.band_hz[1])],
            "points": int(self.points),
            "frfs": list(self.frfs),
            "rms_error": float(self.rms_error),
            "noise_floor": float(self.noise_floor),
            "parameters": {
                name: {
                    "value": float(e.value),
                    "stderr": float(e.stderr) if name in self.free else None,
                    "unit": e.unit,
                }
                for name, e in self.parameters.items()
            },
        }
