"""FRFs as CSV: one row per frequency point, units in the column names, metadata beside it.

The CSV opens as it is in a spreadsheet and in ``pandas.read_csv(path)``: RFC 4180 (comma,
CRLF, UTF-8), one header row, then numbers only; an empty cell is a missing value (the support
FRF of a bare-table run, the time of an imported point)::

    frequency_hz,time_s,accelerance_table_real_m_per_s2_per_n,accelerance_table_imag_m_per_s2_per_n,
    accelerance_support_real_m_per_s2_per_n,accelerance_support_imag_m_per_s2_per_n,flags

Numbers are written with Python's shortest round-trip repr, so reading the file back gives the
same float64 values bit for bit.

What a header comment used to say (campaign, run, specimen, what each column means, the flag
bits) is in a sidecar ``NAME.csv-metadata.json`` in the W3C "CSV on the Web" form, the file name
CSVW tools look for next to a CSV: the columns with their units and descriptions, and the run's
metadata under ``notes``.

Reading accepts these files, older ones whose first lines are ``#`` comments, and the same
table as a spreadsheet saves it under a regional setting with a decimal comma: cells separated
by ``;`` or a tab, ``-0,0997`` (:mod:`viscorig.exchange.cells`). A line longer
than any row of this table, a cell that is not a number or not finite (``nan``, ``inf``), an
empty cell where a value is needed, a frequency given twice, or more rows than a run holds is
an error naming the line (and the column); nothing is imported from a file with an error. Rows
may come in any frequency order: the run stores them by rising frequency.
"""

from __future__ import annotations

import csv
import math
from dataclasses import asdict
from pathlib import Path
from typing import IO

import numpy as np

from viscorig import jsontext
from viscorig.errors import InputError
from viscorig.exchange.atomicfile import replace_atomically
from viscorig.exchange.cells import DELIMITERS, parse_number
from viscorig.exchange.frfset import FrfSet
from viscorig.storage import FLAG_NAMES, RunRecord
from viscorig.storage.layout import MAX_RUN_POINTS
from viscorig.version import __version__

COLUMNS = (
    "frequency_hz",
    "time_s",
    "accelerance_table_real_m_per_s2_per_n",
    "accelerance_table_imag_m_per_s2_per_n",
    "accelerance_support_real_m_per_s2_per_n",
    "accelerance_support_imag_m_per_s2_per_n",
    "flags",
)
#: What each column holds, for the sidecar.
DESCRIPTIONS = {
    "frequency_hz": "frequency, Hz",
    "time_s": "time since the run started at the end of the point, s (empty when unknown)",
    "accelerance_table_real_m_per_s2_per_n":
        "real part of x''_s/F_e, table acceleration / excitation force, m/s^2/N",
    "accelerance_table_imag_m_per_s2_per_n": "imaginary part of x''_s/F_e, m/s^2/N",
    "accelerance_support_real_m_per_s2_per_n":
        "real part of x''_v/F_v, disc acceleration / load-cell force, m/s^2/N "
        "(empty on a bare-table run)",
    "accelerance_support_imag_m_per_s2_per_n": "imaginary part of x''_v/F_v, m/s^2/N",
    "flags": "bit mask: " + ", ".join(f"{int(flag)} {name}" for flag, name in FLAG_NAMES.items()),
}
#: The longest line read: a row of seven numbers is under 200 characters.
MAX_LINE_CHARACTERS = 4096


def sidecar_path(path: Path) -> Path:
    """Where the CSVW metadata of CSV file ``path`` goes (``NAME.csv-metadata.json``)."""
    path = Path(path)
    return path.with_name(f"{path.name}-metadata.json")


def _number(value: float) -> str:
    return "" if math.isnan(value) else repr(float(value))


def metadata(run: RunRecord, csv_name: str, campaign_name: str) -> dict:
    """The CSVW sidecar document of a run's CSV."""
    columns = [
        {"name": name, "titles": name, "datatype": "integer" if name == "flags" else "double",
         "dc:description": DESCRIPTIONS[name]}
        for name in COLUMNS
    ]
    run_metadata = asdict(run.metadata)  # NaN (unknown) is written null, as everywhere
    return {
        "@context": "http://www.w3.org/ns/csvw",
        "url": csv_name,
        "dc:title": f"viscorig FRF export, campaign {campaign_name}, run {run.name}",
        "dc:source": campaign_name,
        "dc:creator": f"viscorig {__version__}",
        "dialect": {"header": True, "encoding": "utf-8"},
        "tableSchema": {"columns": columns},
        "notes": [{"run": run.name, "points": run.points, "metadata": run_metadata}],
    }


def write_csv(run: RunRecord, path: Path, campaign_name: str = "") -> Path:
    """Write a run's FRFs to ``path`` and its metadata beside it (each replaced atomically).

    Parameters
    ----------
    run
        The run, as read from a campaign file.
    path
        The CSV file to write.
    campaign_name
        Name of the campaign file, for the metadata.

    Returns
    -------
    Path
        The sidecar written (:func:`sidecar_path`).
    """
    path = Path(path)
    table, support = run.accelerance_table, run.accelerance_support
    columns = (run.frequency_hz, run.time_s, table.real, table.imag, support.real, support.imag)
    rows = [[_number(column[i]) for column in columns] + [str(int(run.flags[i]))]
            for i in range(run.points)]

    def write(handle: IO[str]) -> None:
        writer = csv.writer(handle)  # RFC 4180: comma, CRLF
        writer.writerow(COLUMNS)
        writer.writerows(rows)

    def write_sidecar(handle: IO[str]) -> None:
        handle.write(jsontext.dumps(metadata(run, path.name, campaign_name), indent=1,
                                    ensure_ascii=False))
        handle.write("\n")

    replace_atomically(path, write, text=True)
    sidecar = sidecar_path(path)
    replace_atomically(sidecar, write_sidecar, text=True)
    return sidecar


def _lines(path: Path):
    """(line number, text without its line end) of each line; refuses an overlong line
    without reading the rest of it."""
    try:
        handle = open(path, encoding="utf-8-sig", newline="")  # noqa: SIM115
    except OSError as error:
        raise InputError(f"cannot read the CSV file ({error.strerror})", str(path)) from None
    with handle:
        number = 0
        while True:
            number += 1
            try:
                line = handle.readline(MAX_LINE_CHARACTERS + 1)
            except (OSError, UnicodeDecodeError) as error:
                raise InputError(f"cannot be read as UTF-8 text ({error})",
                                 f"{path}:{number}") from None
            if not line:
                return
            if len(line) > MAX_LINE_CHARACTERS and not line.endswith(("\n", "\r")):
                raise InputError(
                    f"line longer than {MAX_LINE_CHARACTERS} characters; a row of this table "
                    f"has {len(COLUMNS)} numbers", f"{path}:{number}")
            yield number, line.rstrip("\r\n")


def _cells(line: str, where: str, delimiter: str = ",") -> list[str]:
    try:
        return [cell.strip() for cell in next(csv.reader([line], delimiter=delimiter))]
    except (csv.Error, StopIteration) as error:
        raise InputError(f"not a CSV row ({error})", where) from None


def _delimiter(header: str, where: str) -> str:
    """The separator of the header's cells: the one that gives the most of :data:`COLUMNS`
    (a comma when none does, for the message about the columns)."""
    found = {delimiter: len(set(_cells(header, where, delimiter)) & set(COLUMNS))
             for delimiter in DELIMITERS}
    best = max(DELIMITERS, key=lambda delimiter: found[delimiter])
    return best if found[best] else ","


#: Columns whose cell may be empty (a missing value); every other cell holds a number.
MAY_BE_EMPTY = frozenset({"time_s", "accelerance_support_real_m_per_s2_per_n",
                          "accelerance_support_imag_m_per_s2_per_n"})


def _check_row(row: list[float], cells: list[str], where: str) -> None:
    """Refuse a row with a value that is not finite (``nan``, ``inf`` spelt out), an empty
    cell where a value is needed, a frequency not above 0, or half a complex number."""
    for name, value, cell in zip(COLUMNS, row, cells, strict=True):
        if not cell and name not in MAY_BE_EMPTY:
            raise InputError(f"{name} is empty; only time_s and the ẍ_v/F_v columns may be",
                             where)
        if cell and not math.isfinite(value):
            raise InputError(f"{name} is {cell!r}, not a finite number (leave a missing "
                             "value's cell empty where one may be missing)", where)
    if not row[0] > 0:
        raise InputError(f"frequency_hz is {row[0]:g}; a frequency is above 0 Hz", where)
    if bool(cells[4]) != bool(cells[5]):
        raise InputError("ẍ_v/F_v has one of its real and imaginary parts empty", where)


def read_csv(path: Path) -> FrfSet:
    """Read a CSV written by :func:`write_csv` (or any file with the same columns).

    Raises
    ------
    InputError
        Missing file, missing, unknown or repeated columns, a value that is not a number, an
        overlong line, more rows than a run holds.
    """
    path = Path(path)
    where = str(path)
    header: list[str] | None = None
    index: list[int] = []
    rows: list[list[float]] = []
    lines_of: dict[float, int] = {}
    delimiter = ","
    for number, line in _lines(path):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        if header is None:
            delimiter = _delimiter(line, f"{where}:{number}")
        cells = _cells(line, f"{where}:{number}", delimiter)
        if header is None:
            header = cells
            missing = [name for name in COLUMNS if name not in header]
            unknown = [name for name in header if name not in COLUMNS]
            twice = sorted({name for name in header if header.count(name) > 1})
            if twice:
                raise InputError(f"column {', '.join(twice)} given twice; which one holds the "
                                 "values cannot be told", f"{where}:{number}")
            if missing or unknown:
                raise InputError(
                    (f"missing columns {', '.join(missing)}" if missing else "")
                    + ("; " if missing and unknown else "")
                    + (f"unknown columns {', '.join(unknown)} (units must be those of the "
                       "names)" if unknown else ""),
                    f"{where}:{number}",
                )
            index = [header.index(name) for name in COLUMNS]
            continue
        if len(cells) != len(header):
            raise InputError(f"{len(cells)} cells, the header has {len(header)}",
                             f"{where}:{number}")
        if len(rows) >= MAX_RUN_POINTS:
            raise InputError(f"more than {MAX_RUN_POINTS} rows; a run holds at most "
                             f"{MAX_RUN_POINTS} points", f"{where}:{number}")
        try:
            row = [parse_number(cells[i], delimiter != ",") if cells[i] else math.nan
                   for i in index]
        except ValueError:
            raise InputError("a cell is not a number", f"{where}:{number}") from None
        _check_row(row, [cells[i] for i in index], f"{where}:{number}")
        frequency = row[0]
        if frequency in lines_of:
            raise InputError(f"frequency {frequency:g} Hz is given twice (lines "
                             f"{lines_of[frequency]} and {number}); a run holds one value "
                             "per frequency", f"{where}:{number}")
        lines_of[frequency] = number
        rows.append(row)
    if header is None:
        raise InputError("no header line and no data", where)
    if not rows:
        raise InputError("no data rows", where)
    values = np.asarray(rows)
    flags = values[:, 6]
    if np.any(~np.isfinite(flags) | (flags < 0) | (flags > 0xFFFF) | (flags != np.round(flags))):
        raise InputError("flags must be integers 0..65535", where)
    return FrfSet(
        frequency_hz=values[:, 0],
        time_s=values[:, 1],
        accelerance_table=values[:, 2] + 1j * values[:, 3],
        accelerance_support=values[:, 4] + 1j * values[:, 5],
        flags=flags.astype(np.uint16),
        source=f"CSV {path.name}",
    )
