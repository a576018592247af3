"""The campaign file's layout as data: object names, dtypes and units (data-format.md).

Reading and writing both use these tables, so the contract is written down once.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

#: Run, fit-parameter and attribute names: they become HDF5 object names.
NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._+-]{0,63}$")
NAME_RULE = "letters, digits, '.', '_', '+', '-'; at most 64"

FORMAT_NAME = "viscorig"
FORMAT_VERSION = 1

RUNS_GROUP = "runs"
RIG_GROUP = "rig"
FITS_GROUP = "fits"
#: Where the sequence and station texts a campaign ran with are kept (our addition to the
#: contract): scalar UTF-8 string datasets, with attributes naming the original files.
SETUP_GROUP = "setup"
SEQUENCE_TEXT = "sequence_toml"
STATION_TEXT = "station_toml"

RUN_STATUSES = ("running", "complete", "aborted")
DIRECTIONS = ("up", "down")

#: Attributes of /rig; all optional.
RIG_FLOAT_ATTRIBUTES = (
    "table_mass_kg",
    "table_stiffness_n_per_m",
    "table_damping_ns_per_m",
    "specimen_diameter_m",
    "specimen_height_m",
    "geometry_factor_m",
    "table_mass_stderr_kg",
    "table_stiffness_stderr_n_per_m",
    "table_damping_stderr_ns_per_m",
)
RIG_INT_ATTRIBUTES = ("specimen_count",)

#: Dataset of a fit group holding the correlation matrix of its parameters.
FIT_CORRELATION = "correlation"

#: Elements of each dataset: 1-D, chunked, resizable.
CHUNK_POINTS = 256


@dataclass(frozen=True)
class DatasetSpec:
    """One per-point dataset of a run.

    Parameters
    ----------
    name
        Dataset name under ``/runs/<name>``.
    kind
        ``"float"``, ``"complex"`` or ``"flags"``.
    units
        The ``units`` attribute written, and the spelling expected on reading.
    """

    name: str
    kind: str
    units: str


REQUIRED_DATASETS: tuple[DatasetSpec, ...] = (
    DatasetSpec("frequency_hz", "float", "Hz"),
    DatasetSpec("time_s", "float", "s"),
    DatasetSpec("accelerance_table", "complex", "m/s^2/N"),
    DatasetSpec("accelerance_support", "complex", "m/s^2/N"),
    DatasetSpec("reference_amplitude", "float", "m/s^2"),
    DatasetSpec("source_amplitude", "float", "V"),
    DatasetSpec("force_amplitude", "float", "N"),
    DatasetSpec("flags", "flags", "1"),
)
OPTIONAL_DATASETS: tuple[DatasetSpec, ...] = (
    DatasetSpec("variance_table", "float", "1"),
    DatasetSpec("variance_support", "float", "1"),
)
KNOWN_DATASETS = {spec.name: spec for spec in (*REQUIRED_DATASETS, *OPTIONAL_DATASETS)}

#: Other spellings of a unit that readers accept (after removing spaces).
UNIT_ALIASES: dict[str, frozenset[str]] = {
    "Hz": frozenset({"Hz", "hz", "1/s", "s^-1"}),
    "s": frozenset({"s", "sec"}),
    "m/s^2/N": frozenset({"m/s^2/N", "m/s²/N", "m/(s^2*N)", "m/(s^2N)", "ms^-2N^-1", "(m/s^2)/N"}),
    "m/s^2": frozenset({"m/s^2", "m/s²", "ms^-2", "m/s/s"}),
    "V": frozenset({"V", "v", "Vpk", "V_peak"}),
    "N": frozenset({"N"}),
    "1": frozenset({"1", "", "-", "dimensionless", "none", "bitmask", "bit mask"}),
}


def unit_matches(expected: str, found: str) -> bool:
    """Whether a ``units`` attribute spells the expected unit."""
    compact = found.replace(" ", "").replace("**", "^")
    return compact in UNIT_ALIASES.get(expected, frozenset({expected}))
