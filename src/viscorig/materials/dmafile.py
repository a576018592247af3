"""Reading the CSV tables DMA users exchange into a :class:`ModulusTable`.

Layouts read:

- one row of column names, then one row of units (the layout pyvisco reads:
  ``f,E_stor,E_loss,T,Set`` / ``Hz,MPa,MPa,C,-``);
- units inside the names: ``E' [MPa]``, ``Frequency (Hz)``, ``T/°C``;
- TA Instruments TRIOS text exports ("Export to LIMS", and the export of every step to text
  or CSV), told by their first lines, each frequency sweep step one set
  (:mod:`viscorig.materials.trios` describes the layouts);
- RepTate's oscillatory-shear files (``.osc``): a first line of parameters
  (``T=40;Mw=225.9;...``; its ``T``, in °C, is the temperature of every row when no column
  gives one), names and units separated by tabs, numbers aligned with spaces;
- comma, semicolon or tab between cells; decimal point, or decimal comma with semicolons or
  tabs; a UTF-8 byte-order mark; ``#`` comment lines before the header. A row holding none of
  the header's separators is split at runs of spaces.

Columns are found by their usual names: frequency (``f``, ``freq``, ``frequency``; or angular
frequency ``omega`` in rad/s), temperature (``T``, ``temp``, ``temperature``), storage and loss
modulus (``E'``, ``E''``, ``E_stor``, ``E_loss``, ``storage modulus``...; ``G...`` for shear;
the prime written as ``'``, ``’`` or ``′``, the double prime as ``''``, ``"``, ``″`` or ``”``),
or ``|E*|`` with ``tan δ``, and a set number (``set``). Other columns (a sample name...) are
ignored. Without a set column, points are grouped by temperature (within 1 K of each other, in
file order). Units: Pa, kPa, MPa, GPa, psi, N/mm²; Hz, kHz, rad/s; °C or K. A column without a
unit is refused where a unit matters (moduli, frequency in rad/s vs Hz is told by the name),
except temperature (°C) and frequency (Hz); temperatures without a unit that all lie between
150 and 700 are refused (almost surely kelvin: the unit must be given).

The row after the column names is a units row when none of its cells under a dimensioned column
(frequency, temperature, modulus) is a number, and at least one of them is filled; otherwise it
is the first data row.

Excel workbooks (``.xls`` through xlrd, ``.xlsx`` through openpyxl, the optional extra
``excel``) are read the same way from their "Exported Data" sheet (Eplexor's export) or their
first sheet: :func:`read_dma_file` chooses by the suffix.

Every problem is one :class:`InputError` naming the file, the row and the column.
"""

from __future__ import annotations

import csv
import io
import logging
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from viscorig.errors import InputError
from viscorig.exchange.cells import DELIMITERS, parse_number
from viscorig.exchange.units import (
    ANGULAR_FREQUENCY_UNITS,
    FREQUENCY_UNITS,
    MODULUS_UNITS,
    TEMPERATURE_OFFSETS,
    factor,
    normalised,
)
from viscorig.materials.table import FREQUENCY_RANGE_HZ, ModulusTable
from viscorig.materials.trios import (
    Step,
    is_trios_export,
    is_trios_step_export,
    trios_step_sections,
    trios_steps,
)
from viscorig.storage.layout import TEMPERATURE_RANGE_C

#: Largest file read (a DMA table of 100 000 points is under 10 MB).
MAX_FILE_BYTES = 32 * 1024 * 1024
MAX_POINTS = 100_000
#: Rows named one by one in the warning about moduli that are not positive.
MAX_NAMED_POINTS = 5

log = logging.getLogger(__name__)

#: Column role -> accepted names (normalised: lower case, no spaces, ``_``/``-`` removed).
ROLES: dict[str, tuple[str, ...]] = {
    "frequency": ("f", "freq", "frequency", "frequencyhz", "frq"),
    "angular": ("omega", "w", "angularfrequency", "angfrequency", "ω"),
    "temperature": ("t", "temp", "temperature", "tc", "θ"),
    "storage": ("estor", "e'", "estorage", "storagemodulus", "e1", "eprime",
                "gstor", "g'", "gstorage", "storagemodulusg", "g1", "gprime",
                "storageshearmodulus", "shearstoragemodulus", "tensilestoragemodulus"),
    "loss": ("eloss", "e''", "elossmodulus", "lossmodulus", "e2",
             "edoubleprime", "gloss", "g''", "g2", "gdoubleprime",
             "lossshearmodulus", "shearlossmodulus", "tensilelossmodulus"),
    "complex": ("e*", "|e*|", "ecomplex", "complexmodulus", "estar", "|e|",
                "g*", "|g*|", "gcomplex", "gstar", "|g|", "complexshearmodulus"),
    "tan_delta": ("tand", "tandelta", "tanδ", "tandel", "tan(delta)", "tan(δ)", "lossfactor",
                  "eta", "η"),
    "set": ("set", "setno", "setnumber", "segment", "sweep", "step"),
}
#: Roles whose unit matters: a units row has no number under any of them.
DIMENSIONED = ("frequency", "angular", "temperature", "storage", "loss", "complex")
#: Primes as typed by word processors and spreadsheets (and ``"`` for a double prime) -> ``'``.
_PRIMES = str.maketrans({"\u2019": "'", "\u2018": "'", "\u2032": "'", "\u00b4": "'",
                         "`": "'", "\u2033": "''", "\u201d": "''", "\u201c": "''",
                         '"': "''"})
_SHEAR_HINT = re.compile(r"^\s*g|shear", re.IGNORECASE)
_UNIT_IN_NAME = re.compile(r"^(.*?)\s*(?:\[([^\]]*)\]|\(([^)]*)\)|/\s*([^/()\[\]]+))\s*$")


@dataclass(frozen=True)
class _Column:
    index: int
    name: str
    unit: str | None
    #: The row the unit was read from (the names row, or the units row), for messages.
    row: int

    def where(self, where: str) -> str:
        return f"{where}: row {self.row}, column {self.name!r}"


def _key(name: str) -> str:
    return re.sub(r"[\s_\-.]", "", name.translate(_PRIMES)).lower()


def _split_unit(name: str) -> tuple[str, str | None]:
    """``"E' [MPa]"`` -> ``("E'", "MPa")``; a name without a unit -> ``(name, None)``."""
    match = _UNIT_IN_NAME.match(name)
    if match and match.group(1).strip():
        unit = next(group for group in match.groups()[1:] if group is not None)
        return match.group(1).strip(), unit.strip()
    return name.strip(), None


def _role(name: str) -> str | None:
    key = _key(name)
    for role, names in ROLES.items():
        if key in names:
            return role
    return None


#: A parameter of RepTate's first line (``T=40;Mw=225.9;chem=PI;``).
_PARAMETER = re.compile(r"[A-Za-z_][\w.]*=[^=\t]*")


def _parameter_line(text: str) -> tuple[str, dict[str, str]]:
    """The text with a leading parameter line blanked (row numbers are kept), and its pairs."""
    lines = text.split("\n")
    first = next((i for i, line in enumerate(lines)
                  if line.strip() and not line.startswith("#")), None)
    if first is None:
        return text, {}
    items = [item.strip() for item in lines[first].strip().split(";") if item.strip()]
    if not items or not all(_PARAMETER.fullmatch(item) for item in items):
        return text, {}
    lines[first] = ""
    return "\n".join(lines), dict(item.split("=", 1) for item in items)


def _dialect(text: str, where: str) -> tuple[str, bool]:
    """Delimiter and whether numbers use a decimal comma, told from the first lines."""
    lines = [line for line in text.splitlines() if line.strip() and not line.startswith("#")][:5]
    if not lines:
        raise InputError("no table in the file", where)
    for delimiter in DELIMITERS:
        counts = {line.count(delimiter) for line in lines}
        if min(counts) >= 1 and len(counts) == 1:
            break
    else:
        delimiter = max(DELIMITERS, key=lines[0].count)
    decimal_comma = delimiter != "," and any(
        re.search(r"\d,\d", line) for line in lines[1:])
    return delimiter, decimal_comma


def read_dma_csv(path: Path, modulus: str | None = None) -> ModulusTable:
    """Read a DMA table from a CSV file (see the module text for the layouts).

    Parameters
    ----------
    path
        The file.
    modulus
        ``"E"`` or ``"G"``; ``None`` tells it from the column names (``G'``... is shear).

    Raises
    ------
    InputError
        The file cannot be read, a needed column is missing, a unit is unknown, or a cell is
        not a number: one line naming the file, row and column.
    """
    where = str(path)
    try:
        size = path.stat().st_size
        if size > MAX_FILE_BYTES:
            raise InputError(f"{size} bytes; a DMA table holds at most {MAX_FILE_BYTES}", where)
        text = path.read_bytes().decode("utf-8-sig")
    except UnicodeDecodeError:
        try:
            text = path.read_bytes().decode("cp1252")
        except UnicodeDecodeError:
            raise InputError("not a text file (neither UTF-8 nor Windows-1252)", where) from None
    except FileNotFoundError:
        raise InputError("no such file", where) from None
    except OSError as error:
        raise InputError(f"cannot be read ({error.strerror})", where) from None
    if "\x00" in text:
        raise InputError("not a text table (holds NUL bytes)", where)
    text = text.replace("\r\n", "\n").replace("\r", "\n")  # lines ended the old Mac way too
    if is_trios_export(text):
        return _from_trios(trios_steps(text, where), modulus, where)
    separator = is_trios_step_export(text)
    if separator is not None:
        return _from_trios(trios_step_sections(text, separator, where), modulus, where)
    text, parameters = _parameter_line(text)
    delimiter, decimal_comma = _dialect(text, where)
    try:
        rows = [(number, _aligned(row, delimiter)) for number, row in enumerate(
            csv.reader(io.StringIO(text), delimiter=delimiter), start=1)
            if row and any(cell.strip() for cell in row)
            and not row[0].lstrip().startswith("#")]
    except csv.Error as error:
        raise InputError(f"not a readable table ({error})", where) from None
    return _from_rows(rows, decimal_comma, modulus, where, parameters)


def _aligned(row: list[str], delimiter: str) -> list[str]:
    """A row read as one cell holding several space-separated fields, split at the spaces."""
    if len(row) == 1 and delimiter != " " and len(row[0].split()) > 1:
        return row[0].split()
    return row


def _from_trios(steps: list[Step], modulus: str | None, where: str) -> ModulusTable:
    """A TRIOS text export's steps (:mod:`viscorig.materials.trios`): every frequency sweep is
    one set, its columns found by name as in a CSV table with a units row."""
    steps = _frequency_sweeps(steps, where)
    names = [cell.strip() for cell in steps[0][1][0][1]]
    rows: list[tuple[int, list[str]]] = [
        (steps[0][1][0][0], [*names, "Step"]),
        (steps[0][1][1][0], [*steps[0][1][1][1], *[""] * (len(names) - len(steps[0][1][1][1])),
                             "-"])]
    first_units = {name: unit.strip() for name, unit in zip(names, rows[1][1], strict=False)
                   if _role(_split_unit(name)[0]) is not None}
    for ordinal, (_, step) in enumerate(steps):
        (_, variables), (units_row, units) = step[0], step[1]
        position = {cell.strip(): i for i, cell in enumerate(variables)}
        for name, i in position.items():
            unit = units[i].strip() if i < len(units) else ""
            if name in first_units and unit != first_units[name]:
                raise InputError(f"column {name!r} in {unit or 'no unit'!r}, where the first "
                                 f"frequency sweep gives {first_units[name] or 'no unit'!r}: "
                                 "steps in different units are not read", f"{where}: row "
                                 f"{units_row}")
        for number, cells in step[2:]:
            mapped = [cells[position[name]] if name in position and position[name] < len(cells)
                      else "" for name in names]
            rows.append((number, [*mapped, str(ordinal)]))
    decimal_comma = any(re.fullmatch(r"-?\d+,\d+(?:[eE][-+]?\d+)?", cell.strip())
                        for _, cells in rows[2:12] for cell in cells)
    return _from_rows(rows, decimal_comma, modulus, where)


def _frequency_sweeps(steps: list[Step], where: str) -> list[Step]:
    """The steps that are frequency sweeps: a frequency column and both moduli (or ``|E*|``
    and ``tan δ``), the frequency changing across the step's points. Other steps of the
    procedure (conditioning, flow, amplitude or time sweeps at one frequency) are left out and
    named at the info level; a step of one point stays (and is refused as a set later)."""
    kept, other = [], []
    for name, rows in steps:
        roles: dict[str, int] = {}
        for index, cell in enumerate(rows[0][1]):
            role = _role(_split_unit(cell)[0])
            if role is not None:
                roles.setdefault(role, index)
        column = roles.get("frequency", roles.get("angular"))
        moduli = ({"storage", "loss"} <= roles.keys()) or ({"complex", "tan_delta"} <= roles.keys())
        values = {cells[column].strip() for _, cells in rows[2:]
                  if column is not None and column < len(cells)}
        if column is not None and moduli and (len(values) > 1 or len(rows) == 3):
            kept.append((name, rows))
        else:
            other.append(name or "unnamed")
    if not kept:
        named = ", ".join(other[:6]) + (f" and {len(other) - 6} more" if len(other) > 6 else "")
        raise InputError(f"no frequency sweep among the export's steps ({named})", where)
    if other:
        log.info("%s: %d step(s) that are not frequency sweeps left out: %s", where, len(other),
                 ", ".join(other))
    return kept


#: Workbook suffixes read by :func:`read_dma_workbook`.
WORKBOOK_SUFFIXES = (".xls", ".xlsx", ".xlsm")
#: The sheet DMA software exports its measurement to (Eplexor), preferred when present.
EXPORT_SHEETS = ("Exported Data",)


def read_dma_file(path: Path, modulus: str | None = None) -> ModulusTable:
    """A DMA table from a CSV/text file or an Excel workbook (by the file's suffix)."""
    if Path(path).suffix.lower() in WORKBOOK_SUFFIXES:
        return read_dma_workbook(Path(path), modulus)
    return read_dma_csv(Path(path), modulus)


def _cell_text(value: object) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return repr(value)
    return str(value)


def read_dma_workbook(path: Path, modulus: str | None = None) -> ModulusTable:
    """Read a DMA table from an Excel workbook (``.xls`` with xlrd, ``.xlsx`` with openpyxl).

    The sheet read is "Exported Data" (Eplexor's export) when there is one, else the first
    sheet; its rows are read as a CSV table is (column names, optionally a units row, then one
    row per point).

    Raises
    ------
    InputError
        The reader package is missing, the workbook cannot be read, or the table is bad (row and
        column named as for a CSV file; rows are numbered as the spreadsheet shows them).
    """
    where = str(path)
    if not path.is_file():
        raise InputError("no such file", where)
    if path.stat().st_size > MAX_FILE_BYTES:
        raise InputError(f"{path.stat().st_size} bytes; a DMA table holds at most "
                         f"{MAX_FILE_BYTES}", where)
    suffix = path.suffix.lower()
    package = "xlrd" if suffix == ".xls" else "openpyxl"
    reader: Any
    try:  # imported here: the excel extra is optional
        if package == "xlrd":
            import xlrd  # type: ignore[import-untyped, unused-ignore]
            reader = xlrd
        else:
            import openpyxl  # type: ignore[import-untyped, unused-ignore]
            reader = openpyxl
    except ImportError:
        raise InputError(f"reading {suffix} workbooks needs {package}: pip install "
                         f"\"viscorig[excel]\" (or pip install {package})", where) from None
    try:
        if suffix == ".xls":
            book = reader.open_workbook(str(path), on_demand=True)
            names = book.sheet_names()
            chosen = next((n for n in EXPORT_SHEETS if n in names), names[0])
            sheet = book.sheet_by_name(chosen)
            grid = [sheet.row_values(r) for r in range(min(sheet.nrows, MAX_POINTS + 10))]
        else:
            book = reader.load_workbook(str(path), read_only=True, data_only=True)
            names = book.sheetnames
            chosen = next((n for n in EXPORT_SHEETS if n in names), names[0])
            sheet = book[chosen]
            grid = [list(row) for row in sheet.iter_rows(max_row=MAX_POINTS + 10,
                                                         values_only=True)]
    except InputError:
        raise
    except Exception as error:  # any failure of the reader is a bad file
        reason = str(error).splitlines()[0] if str(error) else type(error).__name__
        raise InputError(f"not a readable workbook ({reason})", where) from None
    rows = [(number, [_cell_text(v) for v in row]) for number, row in enumerate(grid, start=1)
            if any(_cell_text(v).strip() for v in row)]
    return _from_rows(rows, False, modulus, f"{where} (sheet {chosen!r})")


def _from_rows(rows: list[tuple[int, list[str]]], decimal_comma: bool, modulus: str | None,
               where: str, parameters: dict[str, str] | None = None) -> ModulusTable:
    """The table of parsed rows: names, optionally units, then one row per point.
    ``parameters`` are those of a RepTate parameter line (its ``T`` stands for a missing
    temperature column)."""
    if not rows:
        raise InputError("no table in the file", where)
    header_row, header = rows[0]
    columns: dict[str, _Column] = {}
    repeated: list[tuple[str, _Column]] = []  # a second column of a quantity
    for index, cell in enumerate(header):
        name, unit = _split_unit(cell)
        role = _role(name)
        if role is not None and role in columns:
            repeated.append((role, _Column(index, cell.strip(), unit, header_row)))
        elif role is not None:
            columns[role] = _Column(index, cell.strip(), unit, header_row)
    columns = _needed(columns)
    constant_temperature = _parameter_temperature(parameters or {}, columns, header_row, where)
    body = rows[1:]
    if body and _is_units_row(body[0][1], columns, decimal_comma):
        units_row_number, units_row = body[0]
        body = body[1:]
        columns = {role: _with_units_row(column, units_row, units_row_number, where)
                   for role, column in columns.items()}
        repeated = [(role, _with_units_row(column, units_row, units_row_number, where))
                    for role, column in repeated]
    if constant_temperature is not None:
        columns["temperature"] = _Column(-1, "T", "°C", constant_temperature[0])
    _require(columns, header_row, where)
    if len(body) > MAX_POINTS:
        raise InputError(f"{len(body)} rows; a DMA table holds at most {MAX_POINTS}", where)
    width = max(index + 1 for index, cell in enumerate(header) if cell.strip())
    values = {role: np.empty(len(body)) for role in columns}
    for i, (row_number, row) in enumerate(body):
        filled = max((index + 1 for index, cell in enumerate(row) if cell.strip()), default=0)
        if filled > width:
            raise InputError(f"{filled} cells where the header names {width}: a cell too many "
                             "shifts every value after it", f"{where}: row {row_number}")
        for role, column in columns.items():
            if column.index < 0:
                continue
            cell = row[column.index] if column.index < len(row) else ""
            try:
                values[role][i] = parse_number(cell, decimal_comma)
            except ValueError:
                raise InputError(f"{cell.strip()!r} is not a number",
                                 f"{where}: row {row_number}, column {column.name!r}") from None
    if constant_temperature is not None:
        values["temperature"][:] = constant_temperature[1]
    for role, column in repeated:
        if role in columns:
            _same_values(columns[role], column, values[role], body, decimal_comma, where)
    return _table(columns, values, body, modulus, where)


def _with_units_row(column: _Column, units_row: list[str], row_number: int,
                    where: str) -> _Column:
    """``column`` with the unit its cell of the units row gives, if any; a unit in the name
    that the units row contradicts is refused."""
    unit = units_row[column.index].strip() if column.index < len(units_row) else ""
    if unit in ("", "-"):
        return column
    if column.unit is not None and column.unit != unit:
        raise InputError(f"unit {column.unit!r} in the name and {unit!r} in the units row; "
                         "which one holds cannot be told", column.where(where))
    return _Column(column.index, column.name, unit, row_number)


def _same_values(first: _Column, second: _Column, values: np.ndarray, body: list,
                 decimal_comma: bool, where: str) -> None:
    """A quantity given by two columns (an instrument that logs the temperature twice):
    refused where the two give other units, or both hold a value and the values differ, for
    which one holds cannot be told."""
    if second.unit is not None and second.unit != first.unit:
        raise InputError(f"columns {first.name!r} ({first.unit}) and {second.name!r} "
                         f"({second.unit}) give the same quantity in other units; which one "
                         "holds cannot be told", second.where(where))
    for i, (row_number, row) in enumerate(body):
        cell = row[second.index].strip() if second.index < len(row) else ""
        if not cell:
            continue
        try:
            value = parse_number(cell, decimal_comma)
        except ValueError:
            value = math.nan
        if not math.isclose(value, values[i], rel_tol=1e-9, abs_tol=0.0):
            raise InputError(f"columns {first.name!r} and {second.name!r} give the same "
                             f"quantity and differ ({values[i]:g} and {cell}); which one holds "
                             "cannot be told", f"{where}: row {row_number}")


def _needed(columns: dict[str, _Column]) -> dict[str, _Column]:
    """The columns the table is made of: storage and loss when both are there (a ``tan δ`` or
    ``|E*|`` beside them is not read, and may be left empty), the frequency in Hz before the
    angular one."""
    drop = set()
    if "storage" in columns and "loss" in columns:
        drop |= {"complex", "tan_delta"}
    if "frequency" in columns:
        drop.add("angular")
    return {role: column for role, column in columns.items() if role not in drop}


def _parameter_temperature(parameters: dict[str, str], columns: dict[str, _Column],
                           header_row: int, where: str) -> tuple[int, float] | None:
    """RepTate's ``T`` (°C) as ``(row, value)`` where no column gives the temperature."""
    if "temperature" in columns or "T" not in parameters:
        return None
    try:
        value = float(parameters["T"])
    except ValueError:
        raise InputError(f"T={parameters['T']!r} is not a number",
                         f"{where}: parameter line") from None
    return max(header_row - 1, 1), value


def _is_units_row(row: list[str], columns: dict[str, _Column], decimal_comma: bool) -> bool:
    """Whether ``row`` (the one after the names) gives units: none of its cells under a
    dimensioned column is a number, and one at least is filled. Cells of other columns (a
    sample name, a row number) and of tan δ or the set number do not count."""
    cells = [row[column.index].strip() if column.index < len(row) else ""
             for role, column in columns.items() if role in DIMENSIONED]
    if not any(cells):
        return False
    for cell in cells:
        try:
            parse_number(cell, decimal_comma)
        except ValueError:
            continue
        return False
    return True


def _require(columns: dict[str, _Column], header_row: int, where: str) -> None:
    here = f"{where}: row {header_row}"
    if "frequency" not in columns and "angular" not in columns:
        raise InputError("no frequency column (f, freq, frequency or omega)", here)
    if "temperature" not in columns:
        raise InputError("no temperature column (T, temp or temperature)", here)
    has_parts = "storage" in columns and "loss" in columns
    has_polar = "complex" in columns and "tan_delta" in columns
    if not (has_parts or has_polar):
        raise InputError("no storage and loss modulus columns (E', E'' or E_stor, E_loss; or "
                         "|E*| and tan delta)", here)


def _unit_factor(column: _Column, table: dict[str, float], quantity: str, where: str,
                 default: str | None) -> float:
    unit = column.unit if column.unit not in (None, "", "-") else default
    if unit is None:
        raise InputError(f"no unit for {quantity} (give it in the name, e.g. "
                         f"\"{column.name} [MPa]\", or in a units row)",
                         column.where(where))
    return factor(unit, table, quantity, column.where(where))


def _table(columns: dict[str, _Column], values: dict[str, np.ndarray], body: list,
           modulus: str | None, where: str) -> ModulusTable:
    if "frequency" in columns:
        column = columns["frequency"]
        unit = column.unit if column.unit not in (None, "", "-") else "Hz"
        if normalised(unit) in ANGULAR_FREQUENCY_UNITS:
            frequency = values["frequency"] * ANGULAR_FREQUENCY_UNITS[normalised(unit)]
        else:
            frequency = values["frequency"] * factor(unit, FREQUENCY_UNITS, "frequency",
                                                     column.where(where))
    else:
        column = columns["angular"]
        frequency = values["angular"] * _unit_factor(
            column, ANGULAR_FREQUENCY_UNITS, "angular frequency", where, "rad/s")
    column = columns["temperature"]
    if column.unit in (None, "", "-"):
        _refuse_unitless_kelvin(column, values["temperature"], where)
    unit = column.unit if column.unit not in (None, "", "-") else "C"
    offset = TEMPERATURE_OFFSETS.get(normalised(unit).replace("º", "°"))
    if offset is None:
        raise InputError(f"unit {unit!r} is not a temperature unit (°C or K)",
                         column.where(where))
    temperature = values["temperature"] + offset
    if "storage" in columns and "loss" in columns:
        storage = values["storage"] * _unit_factor(columns["storage"], MODULUS_UNITS,
                                                   "modulus", where, None)
        loss = values["loss"] * _unit_factor(columns["loss"], MODULUS_UNITS, "modulus",
                                             where, None)
        named = columns["storage"].name
    else:
        magnitude = values["complex"] * _unit_factor(columns["complex"], MODULUS_UNITS,
                                                     "modulus", where, None)
        column = columns["tan_delta"]
        if column.unit not in (None, "", "-", "1"):
            raise InputError(f"unit {column.unit!r} for a loss factor, which is a ratio without "
                             "one (a viscosity in Pa.s, or a phase angle in degrees, is no "
                             "tan δ)", column.where(where))
        delta = np.arctan(values["tan_delta"])
        storage, loss = magnitude * np.cos(delta), magnitude * np.sin(delta)
        named = columns["complex"].name
    if modulus is None:
        modulus = "G" if _SHEAR_HINT.search(named) else "E"
    if "set" in columns:
        _, sets = np.unique(values["set"], return_inverse=True)
    else:
        sets = _sets_by_temperature(temperature)
    table = ModulusTable(frequency_hz=frequency, temperature_c=temperature, storage_pa=storage,
                         loss_pa=loss, set_index=sets.astype(np.int64), modulus=modulus,
                         source=Path(where).name)
    _check_rows(table, body, columns, where)
    return table


#: Temperatures without a unit all within this range (°C or K?) are refused: kelvin, almost surely.
KELVIN_LIKE = (150.0, 700.0)


def _refuse_unitless_kelvin(column: _Column, temperature: np.ndarray, where: str) -> None:
    """Temperatures without a unit are °C, unless they all lie in :data:`KELVIN_LIKE`: a DMA
    sweep from 150 to 700 °C is rare, one from 150 to 700 K (-123 to 427 °C) is the usual
    one, and reading kelvin as °C shifts every set by 273 K without a word."""
    finite = temperature[np.isfinite(temperature)]
    low, high = KELVIN_LIKE
    if finite.size and low <= finite.min() and finite.max() <= high:
        raise InputError(
            f"temperatures {finite.min():g} to {finite.max():g} without a unit: kelvin, "
            f"almost surely; give the unit (e.g. \"{column.name} [K]\", or "
            f"\"{column.name} [°C]\" if they are °C)", column.where(where))


def _sets_by_temperature(temperature: np.ndarray, tolerance_k: float = 1.0) -> np.ndarray:
    """Consecutive points within ``tolerance_k`` of their set's first point share a set."""
    sets = np.zeros(temperature.size, dtype=np.int64)
    start = temperature[0] if temperature.size else 0.0
    for i in range(1, temperature.size):
        if abs(temperature[i] - start) > tolerance_k:
            sets[i:] += 1
            start = temperature[i]
    return sets


def _check_rows(table: ModulusTable, body: list, columns: dict[str, _Column], where: str) -> None:
    """Name the row and column of the first frequency or temperature no master curve can use.

    Moduli that are not positive are kept as measured (:meth:`ModulusTable.usable`); each is
    named in a warning with its row and column.
    """
    checks = (
        ("frequency" if "frequency" in columns else "angular", table.frequency_hz,
         f"frequency must be a number from {FREQUENCY_RANGE_HZ[0]:g} to "
         f"{FREQUENCY_RANGE_HZ[1]:g} Hz"),
        ("temperature", table.temperature_c + 273.15, "temperature must be above absolute zero "
         f"and at most {TEMPERATURE_RANGE_C[1]:g} °C"),
    )
    for role, value, what in checks:
        good = np.isfinite(value) & (value > 0)
        if role == "temperature":
            good &= table.temperature_c <= TEMPERATURE_RANGE_C[1]
        else:
            good &= (value >= FREQUENCY_RANGE_HZ[0]) & (value <= FREQUENCY_RANGE_HZ[1])
        bad = np.flatnonzero(~good)
        if bad.size:
            row_number = body[int(bad[0])][0]
            raise InputError(what, f"{where}: row {row_number}, column {columns[role].name!r}")
    storage_role = "storage" if "storage" in columns else "complex"
    loss_role = "loss" if "loss" in columns else "tan_delta"
    unusable = table.unusable_points()
    for point in unusable[:MAX_NAMED_POINTS]:
        role = storage_role if point["why"].startswith("storage") else loss_role
        log.warning("%s: row %s, column %r: %s; kept as measured, left out of master curves",
                    where, body[point["point"] - 1][0], columns[role].name, point["why"])
    if len(unusable) > MAX_NAMED_POINTS:
        log.warning("%s: %d more rows with a modulus outside the range a master curve uses",
                    where, len(unusable) - MAX_NAMED_POINTS)
    if int(table.usable().sum()) < 2:
        raise InputError(f"{int(table.usable().sum())} data row(s) with a storage and "
                         "loss modulus in range; a master curve needs more", where)
