"""A minimal TOML writer for tests (tables, arrays of tables, scalars, arrays of scalars)."""

from __future__ import annotations

import json
import math
from typing import Any


def _string(text: str) -> str:
    """A TOML basic string (JSON escapes, plus DEL, which TOML also forbids raw)."""
    return json.dumps(text, ensure_ascii=False).replace("\x7f", "\\u007f")


def _value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return _string(value)
    if isinstance(value, list):
        return "[" + ", ".join(_value(item) for item in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{_string(k)} = {_value(v)}" for k, v in value.items()) + "}"
    raise TypeError(type(value))


def dumps(document: dict[str, Any]) -> str:
    """TOML text for ``document``; top-level dicts become tables, lists of dicts arrays."""
    lines = []
    nested = []
    for key, value in document.items():
        if isinstance(value, dict):
            nested.append((key, value, False))
        elif isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
            nested.append((key, value, True))
        else:
            lines.append(f"{_string(key)} = {_value(value)}")
    for key, value, is_array in nested:
        for table in value if is_array else [value]:
            lines.append(f"[[{_string(key)}]]" if is_array else f"[{_string(key)}]")
            lines.extend(f"{_string(k)} = {_value(v)}" for k, v in table.items())
    return "\n".join(lines) + "\n"
