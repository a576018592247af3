"""Data exchange: FRFs to and from universal files (dataset 58), CSV, and SDF files (35665A,
35670A and their family).

Every reader returns a :class:`FrfSet` in viscorig's units (Hz, m/s²/N), converting the units
the file declares; :func:`import_run` stores it as a new campaign run.
"""

from viscorig.exchange.csvfile import read_csv, write_csv
from viscorig.exchange.frfset import FrfSet, ImportSettings, import_run
from viscorig.exchange.sdf import SdfFile, SdfTrace, read_sdf_file
from viscorig.exchange.sdffrf import SdfFrf, read_sdf, read_sdf_frfs
from viscorig.exchange.uff import read_uff, uff_records, write_uff

__all__ = [
    "FrfSet",
    "ImportSettings",
    "SdfFile",
    "SdfFrf",
    "SdfTrace",
    "import_run",
    "read_csv",
    "read_sdf",
    "read_sdf_file",
    "read_sdf_frfs",
    "read_uff",
    "uff_records",
    "write_csv",
    "write_uff",
]
