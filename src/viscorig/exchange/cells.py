"""Numbers as spreadsheets write them in a table's cells: a decimal point, or the decimal comma
of a regional setting that separates cells with ``;`` or a tab (``-0,0997``, ``1.234,5``)."""

from __future__ import annotations

#: Cell separators a spreadsheet's CSV export uses, the decimal comma's two first.
DELIMITERS = ("\t", ";", ",")


def parse_number(cell: str, decimal_comma: bool) -> float:
    """The number in ``cell``; with ``decimal_comma``, ``,`` is the decimal mark and a ``.``
    beside one is a thousands separator. Raises ``ValueError`` as :class:`float` does."""
    text = cell.strip()
    if decimal_comma:
        if text.count(",") == 1 and text.count(".") >= 1:
            text = text.replace(".", "")
        text = text.replace(",", ".")
    return float(text)
