"""JSON text as other programs read it: strict JSON, with ``null`` for a number that is not one.

Python's ``json`` writes ``NaN`` and ``Infinity``, which strict parsers (``jq``, a browser's
``JSON.parse``) refuse. Every JSON document viscorig prints or serves goes through
:func:`dumps`, so a parameter without a standard error reads ``"stderr": null`` everywhere.
"""

from __future__ import annotations

import json
import math
from typing import Any

__all__ = ["dumps", "finite_or_none"]


def finite_or_none(value: Any) -> Any:
    """``value`` with every NaN or infinite number (at any depth) as ``None``, numpy scalars
    as Python numbers and tuples as lists."""
    if isinstance(value, dict):
        return {key: finite_or_none(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite_or_none(item) for item in value]
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return value
    if hasattr(value, "item") and callable(value.item) and getattr(value, "ndim", 1) == 0:
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def dumps(document: Any, *, indent: int | None = None, compact: bool = False,
          ensure_ascii: bool = True) -> str:
    """``document`` as strict JSON text (through :func:`finite_or_none` when ``json`` refuses
    it as it is), indented by ``indent`` or, ``compact``, without spaces; ``ensure_ascii=False``
    keeps non-ASCII characters."""
    options: dict[str, Any] = {"allow_nan": False, "indent": indent, "ensure_ascii": ensure_ascii,
                               "separators": (",", ":") if compact else None}
    try:  # most documents are clean: written as they are, they cost half (the live view's)
        return json.dumps(document, **options)
    except (ValueError, TypeError):  # a NaN or an infinity, or a numpy scalar json cannot write
        return json.dumps(finite_or_none(document), **options)
