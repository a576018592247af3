"""The campaign file (HDF5, shared/docs/data-format.md): write while measuring, read to analyse.

Every change is an atomic commit, so a writer killed at any instant leaves a file that opens
with every committed segment intact (:mod:`viscorig.storage.atomic`).

A layer under the public API (:mod:`viscorig.api`, ``viscorig.open_campaign``): importable for work
the API does not wrap, not documented as a second API; its names may change between versions.
"""

from viscorig.storage.campaign import CampaignFile
from viscorig.storage.flags import (
    FLAG_NAMES,
    FORCE_ABOVE_SHAKER_LIMIT,
    INPUT_OVERLOAD,
    LEVEL_NOT_REACHED,
    SOURCE_AT_LIMIT,
    PointFlag,
    count_flags,
)
from viscorig.storage.records import (
    FitRecord,
    JointFitRecord,
    RunMetadata,
    RunRecord,
    RunSettings,
    Segment,
)

__all__ = [
    "FLAG_NAMES",
    "FORCE_ABOVE_SHAKER_LIMIT",
    "INPUT_OVERLOAD",
    "LEVEL_NOT_REACHED",
    "SOURCE_AT_LIMIT",
    "CampaignFile",
    "FitRecord",
    "JointFitRecord",
    "PointFlag",
    "RunMetadata",
    "RunRecord",
    "RunSettings",
    "Segment",
    "count_flags",
]
