"""FRFs as CSV: one row per frequency point, units in the column names, '#' comment header.

Layout (``#`` lines describe the run; any CSV reader skips them with ``comment='#'``)::

    # viscorig FRF export, campaign paper.h5, run soft-0
    # ...
    frequency_hz,time_s,accelerance_table_real_m_per_s2_per_n,accelerance_table_imag_m_per_s2_per_n,
    accelerance_support_real_m_per_s2_per_n,accelerance_support_imag_m_per_s2_per_n,flags

(one header line). Numbers are written with Python's shortest round-trip repr, so reading the
file back gives the same float64 values bit for bit; ``nan`` marks a missing value (the support
FRF of a bare-table run, the time of an imported point).
"""

from __future__ import annotations

import csv
import math
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from viscorig.errors import InputError
from viscorig.exchange.atomicfile import replace_atomically
from viscorig.exchange.frfset import FrfSet
from viscorig.storage import FLAG_NAMES, Run

COLUMNS = (
    "frequency_hz",
    "time_s",
    "accelerance_table_real_m_per_s2_per_n",
    "accelerance_table_imag_m_per_s2_per_n",
    "accelerance_support_real_m_per_s2_per_n",
    "accelerance_support_imag_m_per_s2_per_n",
    "flags",
)


def _number(value: float) -> str:
    return "nan" if math.isnan(value) else repr(float(value))


def header_lines(run: Run, campaign_name: str) -> list[str]:
    """The ``#`` comment lines describing a run."""
    m = run.metadata
    flags = ", ".join(f"{int(flag)} {name}" for flag, name in FLAG_NAMES.items())
    return [
        f"viscorig FRF export, campaign {campaign_name}, run {run.name}",
        f"specimen {m.specimen}; hardness_shore_a {m.hardness_shore_a:g}; "
        f"preload_strain {m.preload_strain:g}; level_m_per_s2 {m.level_m_per_s2:g}; "
        f"status {m.status}; points {run.points}",
        "accelerance_table = table acceleration / excitation force (x''_s/F_e), in m/s^2/N",
        "accelerance_support = disc acceleration / load-cell force (x''_v/F_v), in m/s^2/N "
        "(nan on a bare-table run)",
        "frequency_hz in Hz; time_s in s since the run started; "
        f"flags is a bit mask: {flags}",
    ]


def write_csv(run: Run, path: Path, campaign_name: str = "") -> None:
    """Write a run's FRFs to ``path`` (replaced atomically).

    Parameters
    ----------
    run
        The run, as read from a campaign file.
    path
        The CSV file to write.
    campaign_name
        Name of the campaign file, for the header.
    """
    rows: list[Iterable[str]] = []
    for i in range(run.points):
        table, support = run.accelerance_table[i], run.accelerance_support[i]
        rows.append((
            _number(run.frequency_hz[i]), _number(run.time_s[i]),
            _number(table.real), _number(table.imag),
            _number(support.real), _number(support.imag),
            str(int(run.flags[i])),
        ))

    def write(handle) -> None:
        for line in header_lines(run, campaign_name):
            handle.write(f"# {line}\n")
        writer = csv.writer(handle, lineterminator="\n")
        writer.writerow(COLUMNS)
        writer.writerows(rows)

    replace_atomically(Path(path), write, text=True)


def read_csv(path: Path) -> FrfSet:
    """Read a CSV written by :func:`write_csv` (or any file with the same columns).

    Raises
    ------
    InputError
        Missing file, missing or unknown columns, a value that is not a number.
    """
    path = Path(path)
    where = str(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        raise InputError(f"cannot read the CSV file ({error})", where) from None
    lines = [(number, line) for number, line in enumerate(text.splitlines(), start=1)
             if line.strip() and not line.lstrip().startswith("#")]
    if not lines:
        raise InputError("no header line and no data", where)
    header_number, header_line = lines[0]
    header = [name.strip() for name in next(csv.reader([header_line]))]
    missing = [name for name in COLUMNS if name not in header]
    unknown = [name for name in header if name not in COLUMNS]
    if missing or unknown:
        raise InputError(
            (f"missing columns {', '.join(missing)}" if missing else "")
            + ("; " if missing and unknown else "")
            + (f"unknown columns {', '.join(unknown)} (units must be those of the names)"
               if unknown else ""),
            f"{where}:{header_number}",
        )
    index = [header.index(name) for name in COLUMNS]
    values = np.empty((len(lines) - 1, len(COLUMNS)))
    for row, (number, line) in enumerate(lines[1:]):
        cells = next(csv.reader([line]))
        if len(cells) != len(header):
            raise InputError(f"{len(cells)} cells, the header has {len(header)}",
                             f"{where}:{number}")
        try:
            values[row] = [float(cells[i]) for i in index]
        except ValueError:
            raise InputError("a cell is not a number", f"{where}:{number}") from None
    if values.shape[0] == 0:
        raise InputError("no data rows", where)
    flags = values[:, 6]
    if np.any((flags < 0) | (flags > 0xFFFF) | (flags != np.round(flags))):
        raise InputError("flags must be integers 0..65535", where)
    return FrfSet(
        frequency_hz=values[:, 0],
        time_s=values[:, 1],
        accelerance_table=values[:, 2] + 1j * values[:, 3],
        accelerance_support=values[:, 4] + 1j * values[:, 5],
        flags=flags.astype(np.uint16),
        source=f"CSV {path.name}",
    )
