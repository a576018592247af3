"""Fitting: linear starts, bounded nonlinear least squares, uncertainties, order selection.

``fit(model_or_spec, FrfData(...), frfs=..., band_hz=..., fixed=...) -> FitResult``; no user
guess is ever needed. The noise floor method is in :mod:`viscorig.fitting.noise`.
"""

from viscorig.fitting.baseline import nelder_mead_fit
from viscorig.fitting.data import MIN_POINTS, FrfData
from viscorig.fitting.noise import local_noise_power, noise_floor
from viscorig.fitting.nonlinear import CORRELATION_WARNING, fit
from viscorig.fitting.result import Estimate, FitResult
from viscorig.fitting.starts import disc_stiffness_samples, linear_start, table_linear_fit

__all__ = [
    "CORRELATION_WARNING",
    "MIN_POINTS",
    "Estimate",
    "FitResult",
    "FrfData",
    "disc_stiffness_samples",
    "fit",
    "linear_start",
    "local_noise_power",
    "nelder_mead_fit",
    "noise_floor",
    "table_linear_fit",
]
