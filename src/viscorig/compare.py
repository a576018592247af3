"""Compare two fits: how much a quantity changed from one run to another, with its ±.

``compare_fits(before, after, ["K_v", "C_v"])`` gives, for each quantity, the relative change
``after/before − 1`` and its standard uncertainty; ``kstar_changes(before, after, [20, 70])``
does the same for the storage stiffness ``K' = Re K*`` and the loss factor ``η = Im K*/Re K*``
of the two fitted models at chosen frequencies, whatever their K* terms are.

Uncertainty. A quantity ``g(θ)`` of one fit gets the first-order (GUM) variance
``J Σ Jᵀ``, with ``Σ`` the covariance of the fit's free parameters and ``J = ∂g/∂θ`` by central
differences. The two fits are of different runs, so their errors are taken as independent and
the relative variances add: ``u(r)² = (a/b)² (u(a)²/a² + u(b)²/b²)``. A fit read back from a
campaign file has standard errors but no covariance; its parameters are then taken as
uncorrelated (exact for a parameter compared as is, approximate for ``K'`` and ``η``).

Everything that compares two runs goes through this module, so a better propagation (a shared
table between the runs, for example) changes it in one place.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from viscorig.models import Context, Model, parse_spec

#: A change is called a change when it exceeds this many standard uncertainties.
CHANGE_SIGMAS = 2.0


@dataclass(frozen=True)
class Estimates:
    """What a comparison needs of a fit: the model, every value, and the free parameters'
    covariance (SI units, in the order of ``free``)."""

    model: Model
    values: Mapping[str, float]
    free: tuple[str, ...]
    covariance: NDArray[np.float64]

    @classmethod
    def of(cls, fit: object) -> Estimates:
        """From a :class:`~viscorig.fitting.FitResult` (with its covariance) or a stored
        :class:`~viscorig.storage.Fit` (standard errors only, taken as uncorrelated)."""
        if isinstance(fit, Estimates):
            return fit
        covariance = getattr(fit, "covariance", None)
        if covariance is not None:
            return cls(fit.model, dict(fit.values), tuple(fit.free),  # type: ignore[attr-defined]
                       np.asarray(covariance, dtype=float))
        parameters = fit.parameters  # type: ignore[attr-defined]
        values = {name: float(p.value) for name, p in parameters.items()}
        free = tuple(name for name, p in parameters.items()
                     if math.isfinite(p.stderr) and p.stderr > 0)
        variance = [float(parameters[name].stderr) ** 2 for name in free]
        return cls(parse_spec(fit.model), values, free, np.diag(variance))  # type: ignore[attr-defined]

    def propagate(self, quantity: Callable[[Mapping[str, float]], float]) -> tuple[float, float]:
        """``(g(θ), u(g))`` of a scalar function of the parameters."""
        value = float(quantity(self.values))
        if not self.free:
            return value, math.nan
        gradient = np.zeros(len(self.free))
        sigma = np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))
        for index, name in enumerate(self.free):
            centre = self.values[name]
            step = sigma[index] * 1e-3 if sigma[index] > 0 else abs(centre) * 1e-6 or 1e-9
            up, down = dict(self.values), dict(self.values)
            up[name], down[name] = centre + step, centre - step
            gradient[index] = (quantity(up) - quantity(down)) / (2 * step)
        variance = float(gradient @ self.covariance @ gradient)
        return value, math.sqrt(variance) if variance >= 0 else math.nan


@dataclass(frozen=True)
class Change:
    """One quantity in two fits, and its relative change with the standard uncertainty."""

    quantity: str
    unit: str
    before: float
    before_stderr: float
    after: float
    after_stderr: float

    @property
    def relative(self) -> float:
        """``after/before − 1``."""
        return self.after / self.before - 1.0

    @property
    def relative_stderr(self) -> float:
        """Standard uncertainty of :attr:`relative` (independent fits)."""
        ratio = self.after / self.before
        return abs(ratio) * math.hypot(self.after_stderr / self.after,
                                       self.before_stderr / self.before)

    @property
    def significant(self) -> bool:
        """The change exceeds :data:`CHANGE_SIGMAS` standard uncertainties."""
        return abs(self.relative) > CHANGE_SIGMAS * self.relative_stderr

    def percent(self) -> str:
        """``"+9.3 ± 0.4 %"``: the change and its uncertainty, to the uncertainty's first
        significant digit (two when it is a 1 or a 2), at most three decimals."""
        value, error = 100 * self.relative, 100 * self.relative_stderr
        if not math.isfinite(error) or error == 0:
            return f"{value:+.2f} %"
        exponent = math.floor(math.log10(error))
        digits = max(0, min(3, (1 if error / 10**exponent < 3 else 0) - exponent))
        return f"{value:+.{digits}f} ± {max(error, 10**-digits):.{digits}f} %"

    def words(self) -> str:
        """``"K_v rose 9.3 ± 0.4 %"``, or that it did not change beyond its uncertainty."""
        if not self.significant:
            return f"{self.quantity} did not change beyond its uncertainty ({self.percent()})"
        verb = "rose" if self.relative > 0 else "fell"
        return f"{self.quantity} {verb} {self.percent().lstrip('+-')}"


def compare_fits(before: object, after: object, names: Iterable[str]) -> list[Change]:
    """The change of parameters ``names`` from fit ``before`` to fit ``after``.

    Parameters missing from either fit are left out.
    """
    first, second = Estimates.of(before), Estimates.of(after)
    changes = []
    for name in names:
        if name not in first.values or name not in second.values:
            continue
        unit = first.model.by_name[name].unit if name in first.model.by_name else ""
        a = first.propagate(lambda values, name=name: values[name])
        b = second.propagate(lambda values, name=name: values[name])
        changes.append(Change(name, unit, a[0], a[1], b[0], b[1]))
    return changes


def _kstar(estimates: Estimates, frequency_hz: float) -> Callable[[Mapping[str, float]], complex]:
    context = Context(np.array([float(frequency_hz)]))

    def kstar(values: Mapping[str, float]) -> complex:
        return complex(estimates.model.kstar(context, values)[0])

    return kstar


def kstar_at(fit: object, frequency_hz: float) -> tuple[tuple[float, float], tuple[float, float]]:
    """``((K', u), (η, u))`` of a fit's K* at one frequency."""
    estimates = Estimates.of(fit)
    kstar = _kstar(estimates, frequency_hz)
    storage = estimates.propagate(lambda values: kstar(values).real)
    loss = estimates.propagate(lambda values: kstar(values).imag / kstar(values).real)
    return storage, loss


def kstar_changes(before: object, after: object, frequencies_hz: Sequence[float]) -> list[Change]:
    """Changes of ``K'`` and of ``η`` at each frequency, from the two fits' K*."""
    changes = []
    for frequency in frequencies_hz:
        (k0, u_k0), (eta0, u_eta0) = kstar_at(before, frequency)
        (k1, u_k1), (eta1, u_eta1) = kstar_at(after, frequency)
        changes.append(Change(f"K' at {frequency:g} Hz", "N/m", k0, u_k0, k1, u_k1))
        changes.append(Change(f"η at {frequency:g} Hz", "", eta0, u_eta0, eta1, u_eta1))
    return changes
