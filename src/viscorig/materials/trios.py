"""The text layout of TA Instruments TRIOS exports ("Export to LIMS", ``.txt``), split into the
steps of a measurement.

The layout, as public TRIOS exports show it: tab-separated lines; a first section
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

#: The line after ``[Version]`` that marks a TRIOS LIMS text export.
MARKER = "TA Instruments LIMS export format"


def is_trios_export(text: str) -> bool:
    """Whether ``text`` is a TRIOS LIMS text export (told by its first lines)."""
    head = [line.strip() for line in text.splitlines()[:5] if line.strip()]
    return len(head) >= 2 and head[0] == "[Version]" and head[1].startswith(MARKER)


def trios_steps(text: str, where: str) -> list[tuple[str, list[tuple[int, list[str]]]]]:
    """The ``[Step]`` sections of a TRIOS export: for each, its name and its rows (file line
    number, cells): the ``Variables`` row, the ``Units`` row, then the ``Data point`` rows.

    Raises
    ------
    InputError
        No step holds data, a step lacks its ``Variables`` or ``Units`` line, or its data rows
        are not as many as ``Number of points`` says: one line naming the file and the row.
    """
    steps: list[tuple[str, list[tuple[int, list[str]]]]] = []
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
