"""The text layouts of TA Instruments TRIOS exports, split into the steps of a measurement:
"Export to LIMS" (``.txt``, :func:`trios_steps`), and the export of every step to text or CSV
(:func:`trios_step_sections`, whose layout that function describes).

The LIMS layout, as public TRIOS exports show it: tab-separated lines; a first section
``[Version]`` whose next line begins ``TA Instruments LIMS export format version``; header
sections (``[Header]``, ``[Sample]``, ``[Geometry]``, ``[Procedure]``, ``[Parameters...]``) of
``name<TAB>value`` lines; then one ``[Step]`` section per step of the procedure (in a
time-temperature sweep, one frequency sweep per temperature, e.g. ``Step name<TAB>Frequency
sweep (150.0 °C)``) with ``Number of points<TAB>N``, a line ``Variables<TAB>name<TAB>...``, a
line ``Units<TAB>unit<TAB>...`` aligned with it, and ``N`` lines ``Data point<TAB>value<TAB>...``.
Variable names are TRIOS's own: ``Temperature`` (°C), ``Frequency`` (Hz), ``Angular frequency``
(rad/s), ``Storage modulus``, ``Loss modulus``, ``Complex modulus``, ``Tan(delta)``. TRIOS uses
the same names for shear (rheometers) and tensile (DMA) moduli, so the kind is not in the file.
"""

from __future__ import annotations

from viscorig.errors import InputError

#: One step: its name, and its rows (file line number, cells): the names row, the units row,
#: then one row per point.
Step = tuple[str, list[tuple[int, list[str]]]]

#: The line after ``[Version]`` that marks a TRIOS LIMS text export.
MARKER = "TA Instruments LIMS export format"


def is_trios_export(text: str) -> bool:
    """Whether ``text`` is a TRIOS LIMS text export (told by its first lines)."""
    head = [line.strip() for line in text.splitlines()[:5] if line.strip()]
    return len(head) >= 2 and head[0] == "[Version]" and head[1].startswith(MARKER)


def trios_steps(text: str, where: str) -> list[Step]:
    """The ``[Step]`` sections of a TRIOS export: for each, its name and its rows (file line
    number, cells): the ``Variables`` row, the ``Units`` row, then the ``Data point`` rows.

    Raises
    ------
    InputError
        No step holds data, a step lacks its ``Variables`` or ``Units`` line, or its data rows
        are not as many as ``Number of points`` says: one line naming the file and the row.
    """
    steps: list[Step] = []
    current: list[tuple[int, list[str]]] | None = None
    name, declared, declared_at = "", None, 0

    def close() -> None:
        if not current:
            return
        kinds = [cells[0].strip() for _, cells in current]
        if kinds[:2] != ["Variables", "Units"]:
            missing = "Variables" if "Variables" not in kinds else "Units"
            raise InputError(f"step {name!r} has no {missing} line before its data points",
                             f"{where}: row {declared_at}")
        points = len(current) - 2
        if declared is not None and points != declared:
            raise InputError(f"step {name!r} declares {declared} points but holds {points}",
                             f"{where}: row {declared_at}")
        if points:
            steps.append((name, current))

    for number, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if stripped.startswith("[") and stripped.endswith("]"):
            close()
            current = [] if stripped == "[Step]" else None
            name, declared, declared_at = "", None, number
            continue
        if current is None or not stripped:
            continue
        cells = line.rstrip("\r\n").split("\t")
        key = cells[0].strip()
        if key == "Step name":
            name = cells[1].strip() if len(cells) > 1 else ""
        elif key == "Number of points":
            try:
                declared = int(cells[1])
            except (IndexError, ValueError):
                raise InputError("'Number of points' is not a whole number",
                                 f"{where}: row {number}, column 2") from None
            declared_at = number
        elif key in ("Variables", "Units"):
            if any(cells[0].strip() == key for _, cells in current):
                raise InputError(f"a second {key} line in one step", f"{where}: row {number}")
            current.append((number, cells))
        elif key == "Data point":
            if len(current) < 2:
                raise InputError("a data point before the step's Variables and Units lines",
                                 f"{where}: row {number}")
            current.append((number, cells))
    close()
    if not steps:
        raise InputError("a TRIOS export without any [Step] holding data points", where)
    return steps


def is_trios_step_export(text: str) -> str | None:
    """The cell separator of a TRIOS export of every step to text or CSV (its first line
    ``Filename<SEP>...``, a ``[step]`` section), or ``None`` for any other text."""
    lines = text.splitlines()
    first = next((line for line in lines[:5] if line.strip()), "")
    for separator in ("\t", ","):
        if first.startswith("Filename" + separator):
            break
    else:
        return None
    return separator if any(line.strip().lower() == "[step]" for line in lines) else None


def trios_step_sections(text: str, separator: str, where: str) -> list[Step]:
    """The ``[step]`` sections of a TRIOS export of every step to text or CSV: each a line
    with the step's name (``Amplitude sweep - 7``), a row of column names, a row of units
    aligned with it, then one row per point up to a blank line or the next section.

    Raises
    ------
    InputError
        A step lacks its names or units row: one line naming the file and the row.
    """
    steps: list[Step] = []
    lines = text.splitlines()
    number = 0
    while number < len(lines):
        if lines[number].strip().lower() != "[step]":
            number += 1
            continue
        start = number + 1
        missing = next((i for i in range(start, start + 3)
                        if i >= len(lines) or not lines[i].strip()), None)
        if missing is not None:
            raise InputError("a [step] without its name, column names and units rows",
                             f"{where}: row {missing + 1}")
        name = lines[start].strip()
        rows = [(i + 1, lines[i].split(separator)) for i in (start + 1, start + 2)]
        number = start + 3
        while number < len(lines) and lines[number].strip() and not lines[number].startswith("["):
            rows.append((number + 1, lines[number].split(separator)))
            number += 1
        if len(rows) > 2:
            steps.append((name, rows))
    if not steps:
        raise InputError("a TRIOS export without any [step] holding data points", where)
    return steps
