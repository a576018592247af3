"""Fitting: linear starts, bounded nonlinear least squares, uncertainties, order selection.

``fit(model_or_spec, FrfData(...), frfs=..., band_hz=..., fixed=..., known=...) -> FitResult``; no
user guess is ever needed. The project's estimate weights each point by its noise under the noise
model (``weighting="noise"``: maximum likelihood under white noise; what ``identify``, ``summary``
and the adaptive plans use); the paper's uniform weighting (``"uniform"``) is kept to reproduce its
Table 1: it minimises the design's error measure ``rms_error`` itself, which diagnosis reports
for each model (diagnosis compares models by its own maximum-likelihood fits,
:mod:`viscorig.diagnosis.weighted`). The noise model shared by the whole
core (noise floor, standard errors, significance tests) is in :mod:`viscorig.fitting.noise`
(estimated from the data by :mod:`viscorig.fitting.noise_estimation`); how it and the inherited
parameters enter the standard errors is in :mod:`viscorig.fitting.uncertainty`.

A layer under the public API (:mod:`viscorig.api`, ``viscorig.open_campaign``): importable for work
the API does not wrap, not documented as a second API; its names may change between versions.
"""

from viscorig.fitting.baseline import nelder_mead_fit
from viscorig.fitting.data import MIN_POINTS, FrfData
from viscorig.fitting.noise import FrfNoise, NoiseModel
from viscorig.fitting.noise_estimation import (
    estimate_frf_noise,
    estimate_noise,
    local_noise_power,
    noise_floor,
)
from viscorig.fitting.nonlinear import CORRELATION_WARNING, WEIGHTINGS, fit
from viscorig.fitting.result import FitResult
from viscorig.fitting.starts import disc_stiffness_samples, linear_start, table_linear_fit
from viscorig.fitting.uncertainty import MISFIT_RATIO, Known
from viscorig.numbers import Estimate

__all__ = [
    "CORRELATION_WARNING",
    "MIN_POINTS",
    "MISFIT_RATIO",
    "WEIGHTINGS",
    "Estimate",
    "FitResult",
    "FrfData",
    "FrfNoise",
    "Known",
    "NoiseModel",
    "disc_stiffness_samples",
    "estimate_frf_noise",
    "estimate_noise",
    "fit",
    "linear_start",
    "local_noise_power",
    "nelder_mead_fit",
    "noise_floor",
    "table_linear_fit",
]
