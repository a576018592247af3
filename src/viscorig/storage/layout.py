"""The campaign file's layout as data: object names, dtypes and units (data-format.md).

Reading and writing both use these tables, so the contract is written down once.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

#: Run, fit-parameter and attribute names: they become HDF5 object names.
NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._+-]{0,63}\Z")
NAME_RULE = "letters, digits, '.', '_', '+', '-'; at most 64"

FORMAT_NAME = "viscorig"
FORMAT_VERSION = 1

RUNS_GROUP = "runs"
RIG_GROUP = "rig"
FITS_GROUP = "fits"
#: Where the sequence and station texts a campaign ran with are kept (our addition to the
#: contract): scalar UTF-8 string datasets, with attributes naming the original files.
SETUP_GROUP = "setup"
#: Where imported DMA sweeps are kept (our addition; :mod:`viscorig.materials.dmastore`).
DMA_GROUP = "dma"
SEQUENCE_TEXT = "sequence_toml"
STATION_TEXT = "station_toml"

RUN_STATUSES = ("running", "complete", "aborted")
#: Temperatures a specimen is measured at (°C): above absolute zero, and at most where any
#: material has long melted or burnt (a DMA oven reaches 600 °C, a furnace 1500 °C).
TEMPERATURE_RANGE_C = (-273.15, 1500.0)
DIRECTIONS = ("up", "down")


@dataclass(frozen=True)
class NumberRange:
    """The values a numeric attribute (of a run, of ``/rig``) may hold: from ``low`` (excluded
    when ``low_open``) to ``high``, a whole number when ``integer``, NaN ("unknown") otherwise.
    The bounds lie beyond any rig, so that only a damaged number falls outside; the reader and
    the writer both test with :meth:`holds`."""

    low: float
    high: float
    low_open: bool = False
    integer: bool = False

    def holds(self, value: float) -> bool:
        """``value`` is one the attribute may hold."""
        if math.isnan(value):
            return not self.integer
        above = value > self.low or (value == self.low and not self.low_open)
        whole = not self.integer or value == int(value)
        return bool(math.isfinite(value) and above and value <= self.high and whole)

    def describe(self) -> str:
        """``a finite number above 0 and at most 10000`` (for messages)."""
        kind = "a whole number" if self.integer else "a finite number"
        return (f"{kind} {'above' if self.low_open else 'at least'} {self.low:g} and at most "
                f"{self.high:g}")


#: The run attributes that are numbers, and the values each may hold.
RUN_NUMBERS = {
    "hardness_shore_a": NumberRange(0.0, 100.0),
    "preload_strain": NumberRange(-1.0, 1.0),
    "temperature_c": NumberRange(*TEMPERATURE_RANGE_C, low_open=True),
    "level_m_per_s2": NumberRange(0.0, 1e4, low_open=True),  # 1,000 g
    "settle_cycles": NumberRange(0, 1e9, integer=True),
    "integrate_cycles": NumberRange(0, 1e9, integer=True),
    "resolution_hz": NumberRange(0.0, 1e6, low_open=True),
}

#: Attributes of /rig, all optional, and the values each may hold: a mass, stiffness or length
#: above 0, a damping or ± at least 0 (any of them NaN, unknown); beyond any vibration table.
RIG_NUMBERS = {
    "table_mass_kg": NumberRange(0.0, 1e5, low_open=True),
    "table_stiffness_n_per_m": NumberRange(0.0, 1e12, low_open=True),
    "table_damping_ns_per_m": NumberRange(0.0, 1e9),
    "specimen_diameter_m": NumberRange(0.0, 10.0, low_open=True),
    "specimen_height_m": NumberRange(0.0, 10.0, low_open=True),
    "geometry_factor_m": NumberRange(0.0, 1e6, low_open=True),
    "table_mass_stderr_kg": NumberRange(0.0, 1e5),
    "table_stiffness_stderr_n_per_m": NumberRange(0.0, 1e12),
    "table_damping_stderr_ns_per_m": NumberRange(0.0, 1e9),
    "specimen_count": NumberRange(0, 1e6, integer=True),
}

#: Dataset of a fit group holding the correlation matrix of its parameters.
FIT_CORRELATION = "correlation"
#: Fits of several runs together (our addition to the contract): ``/fits/<id>``, beside
#: ``/runs``; each names the runs it used in its attribute ``runs`` (data-format.md keeps
#: ``/runs/<name>/fits`` for fits of one run).
JOINT_FITS_GROUP = "fits"
#: The attributes of a joint fit the layout defines; any other is the fit's own.
JOINT_FIT_ATTRIBUTES = frozenset({"model", "runs", "band_hz", "reduced_chi_square", "points",
                                  "created", "weighting"})

#: Elements of each dataset: 1-D, chunked, resizable.
CHUNK_POINTS = 256

# -- bounds: what a campaign file may declare before anything in it is read -------------------
# A file from elsewhere is checked against these before a value is read, so that memory stays
# bounded (a few hundred MB at most) whatever sizes the file declares.

#: Points in one run: the bound a sequence accepts (over a day of dwell at 100+100 cycles; the
#: analyser's 801-point limit applies per segment, and runs are split into segments).
MAX_RUN_POINTS = 100_000
#: Points in all the runs of a file together.
MAX_CAMPAIGN_POINTS = 1_000_000
#: Runs in one file, fits of one run.
MAX_RUNS = 1_000
MAX_FITS = 1_000
#: Objects in one run group (datasets and ``fits``) or one fit group (parameters).
MAX_MEMBERS = 64
#: Attributes of one object, values in one attribute, and the bytes of one attribute.
MAX_ATTRIBUTES = 256
MAX_ATTRIBUTE_VALUES = 16
MAX_ATTRIBUTE_BYTES = 64 * 1024
#: Characters of a ``/setup`` text (a sequence or station file).
MAX_SETUP_TEXT = 1024 * 1024
#: Bytes of one chunk of a dataset (HDF5 reads a whole chunk to read one value of it).
MAX_CHUNK_BYTES = 16 * 1024 * 1024
#: Bytes of a campaign file; also bounds what a variable-length text can hold.
MAX_FILE_BYTES = 256 * 1024 * 1024


@dataclass(frozen=True)
class DatasetSpec:
    """One per-point dataset of a run.

    Parameters
    ----------
    name
        Dataset name under ``/runs/<name>``.
    kind
        ``"float"``, ``"complex"``, ``"flags"`` or ``"count"`` (whole numbers, int64).
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
    # where settle or integration vary from point to point (an adaptive plan's runs); a run
    # without them has the run attributes settle_cycles, integrate_cycles at every point
    DatasetSpec("settle_cycles", "count", "1"),
    DatasetSpec("integrate_cycles", "count", "1"),
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
