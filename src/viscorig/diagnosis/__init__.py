"""Diagnosis: where a model departs from the measurements, which physical effect is missing,
and the model with it.

``d = diagnose_run(campaign, "soft-0", "voigt")`` (or ``diagnose(frf_data, "voigt",
table=...)``) fits the model and gives ``d.failures`` (bands where it fails), ``d.findings``
(candidate effects fitted and tested, best first), ``d.residuals()`` (magnitude error in %,
phase error in degrees); ``d.with_effect("fixture(58)")`` adds an effect in one step and
``d.auto()`` climbs the ladder until the error reaches the noise floor.

A layer under the public API (:mod:`viscorig.api`, ``viscorig.open_campaign``): importable for work
the API does not wrap, not documented as a second API; its names may change between versions.
"""

from viscorig.diagnosis.core import (
    AT_FLOOR_RATIO,
    DEFAULT_MODEL,
    DiagnosisResult,
    analyse,
    diagnose,
    diagnose_run,
)
from viscorig.diagnosis.data import DiagnosisData, combine, companions, from_campaign
from viscorig.diagnosis.findings import Finding
from viscorig.diagnosis.residuals import FailureBand, FrfResidual, failure_bands, residuals
from viscorig.diagnosis.scan import ScanResult
from viscorig.diagnosis.screening import Candidate, screen
from viscorig.diagnosis.significance import FAMILY_ALPHA

__all__ = [
    "AT_FLOOR_RATIO",
    "DEFAULT_MODEL",
    "FAMILY_ALPHA",
    "Candidate",
    "DiagnosisData",
    "DiagnosisResult",
    "FailureBand",
    "Finding",
    "FrfResidual",
    "ScanResult",
    "analyse",
    "combine",
    "companions",
    "diagnose",
    "diagnose_run",
    "failure_bands",
    "from_campaign",
    "residuals",
    "screen",
]
