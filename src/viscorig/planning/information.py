"""Fisher information of swept-sine points about a model's parameters.

A point at frequency ``f`` integrated for ``T`` seconds gives, for each FRF, a complex relative
error ``ε`` with ``E|ε|² = rate(f)/T`` (:mod:`viscorig.planning.noise`), circular (real and
imaginary parts independent, each of half the power). With ``j = ∂ log H/∂u`` the sensitivity
of the FRF to the parameters in *relative* coordinates ``u_k = p_k/p̂_k`` (so that variances of
``u`` are squared relative standard errors), the point's information is ::

    I(f, T) = T · Σ_frf 2 Re(j^H j) / rate_frf(f)

linear in the integration time. :class:`InformationModel` gives this per second of
integration for any frequency, which is all the design needs.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from viscorig.models import Model
from viscorig.planning.noise import NoiseForecast, model_amplitudes
from viscorig.planning.sensitivity import log_sensitivities

__all__ = ["InformationModel", "log_sensitivities"]


@dataclass
class InformationModel:
    """Information per second of integration about ``names``, anywhere in the band.

    Attributes
    ----------
    model, values
        The model of the rig and its current parameter values (fixed ones included).
    names
        The parameters estimated (the fit's free ones), in the order of every matrix here.
    noise
        The noise model.
    level_m_per_s2
        Reference acceleration held by the controller.
    force_limit_n
        The shaker's force limit, if any (amplitudes scale down beyond it).
    """

    model: Model
    values: Mapping[str, float]
    names: tuple[str, ...]
    noise: NoiseForecast
    level_m_per_s2: float
    force_limit_n: float | None = None

    def rate(self, frequency_hz: ArrayLike) -> NDArray[np.float64]:
        """Information per second of integration at each frequency: (points, k, k)."""
        f = np.atleast_1d(np.asarray(frequency_hz, dtype=float))
        sensitivity = log_sensitivities(
            self.model, self.values, self.names, f, level_m_per_s2=self.level_m_per_s2
        )
        amplitudes = model_amplitudes(
            self.model, self.values, f, self.level_m_per_s2, force_limit_n=self.force_limit_n
        )
        total = np.zeros((f.size, len(self.names), len(self.names)))
        for frf, j in sensitivity.items():
            if frf not in self.noise.frfs:
                continue
            rate = self.noise.rate(frf, amplitudes)
            total += 2.0 * np.einsum("pi,pj->pij", j.conj(), j).real / rate[:, None, None]
        return total

    def noise_power(
        self, frequency_hz: ArrayLike, integrate_s: ArrayLike
    ) -> dict[str, NDArray[np.float64]]:
        """Predicted ``E|ε|²`` of each FRF for points at these frequencies and integrations."""
        f = np.atleast_1d(np.asarray(frequency_hz, dtype=float))
        amplitudes = model_amplitudes(
            self.model, self.values, f, self.level_m_per_s2, force_limit_n=self.force_limit_n
        )
        return {frf: self.noise.power(frf, amplitudes, integrate_s) for frf in self.noise.frfs}

    def of_points(self, frequency_hz: ArrayLike, integrate_s: ArrayLike) -> NDArray[np.float64]:
        """Total information (k, k) of points measured at these frequencies and integrations."""
        rate = self.rate(frequency_hz)
        return np.einsum("p,pij->ij", np.atleast_1d(np.asarray(integrate_s, float)), rate)

    def of_measured(
        self, frequency_hz: ArrayLike, power: Mapping[str, ArrayLike]
    ) -> NDArray[np.float64]:
        """Total information (k, k) of measured points whose noise power ``E|ε_i|²`` of each
        FRF is known point by point (the analyser's variance): what a noise-weighted fit of
        exactly these points holds."""
        f = np.atleast_1d(np.asarray(frequency_hz, dtype=float))
        sensitivity = log_sensitivities(
            self.model, self.values, self.names, f, level_m_per_s2=self.level_m_per_s2
        )
        total = np.zeros((len(self.names), len(self.names)))
        for frf, j in sensitivity.items():
            if frf in power:
                weight = 2.0 / np.asarray(power[frf], dtype=float)
                total += np.einsum("p,pi,pj->ij", weight, j.conj(), j).real
        return total

