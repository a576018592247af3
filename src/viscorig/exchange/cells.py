"""Numbers as spreadsheets write them in a table's cells: a decimal point, or the decimal comma
of a regional setting that separates cells with ``;`` or a tab (``-0,0997``, ``1.234,5``), with
thousands grouped by the other mark (``1.234,5`` and ``1,234.5`` are both 1234.5)."""

from __future__ import annotations

import re

#: Cell separators a spreadsheet's CSV export uses, the decimal comma's two first.
DELIMITERS = ("\t", ";", ",")
#: A number as a spreadsheet or a program writes one: ASCII digits, an optional exponent, or a
#: NaN or infinity; not Python's own additions (``1_000``, digits of other scripts: ``１２``).
NUMBER = re.compile(r"[+-]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|nan|inf(?:inity)?)",
                    re.IGNORECASE | re.ASCII)


def parse_number(cell: str, decimal_comma: bool) -> float:
    """The number in ``cell``; with ``decimal_comma``, ``,`` is the decimal mark unless a
    ``.`` follows it, and the other mark, before the decimal one, groups thousands. Raises
    ``ValueError`` as :class:`float` does, also for marks that group no thousands and for what
    only Python reads as a number (:data:`NUMBER`)."""
    text = cell.strip()
    if decimal_comma and "," in text:
        if "." in text:
            mark = "," if text.rfind(",") > text.rfind(".") else "."
            grouping = "." if mark == "," else ","
            whole, _, fraction = text.rpartition(mark)
            if not re.fullmatch(rf"[+-]?\d{{1,3}}(?:{re.escape(grouping)}\d{{3}})+", whole):
                raise ValueError(f"could not convert string to float: {cell!r}")
            text = f"{whole.replace(grouping, '')}.{fraction}"
        else:
            text = text.replace(",", ".")
    if not NUMBER.fullmatch(text):
        raise ValueError(f"could not convert string to float: {cell!r}")
    return float(text)
