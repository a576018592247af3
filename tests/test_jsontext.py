"""Every JSON document viscorig prints, serves or writes is strict JSON: no ``NaN`` token."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from viscorig import jsontext

SOURCE = Path(__file__).resolve().parents[1] / "src" / "viscorig"


def strict_loads(text: str):
    def refuse(token: str):
        raise ValueError(f"not JSON: {token}")
    return json.loads(text, parse_constant=refuse)


def test_non_numbers_become_null_at_any_depth() -> None:
    document = {"a": math.nan, "b": [1.0, math.inf, (-math.inf, 2)], "c": {"d": np.float64("nan")},
                "e": np.float32(1.5), "f": np.int64(3), "g": True, "h": None, "i": "NaN"}
    text = jsontext.dumps(document)
    assert strict_loads(text) == {"a": None, "b": [1.0, None, [None, 2]], "c": {"d": None},
                                  "e": 1.5, "f": 3, "g": True, "h": None, "i": "NaN"}


def test_layouts() -> None:
    assert jsontext.dumps({"a": [1, 2]}, compact=True) == '{"a":[1,2]}'
    assert jsontext.dumps({"a": 1}, indent=2) == '{\n  "a": 1\n}'
    assert jsontext.dumps({"t": "25 °C"}, ensure_ascii=False) == '{"t": "25 °C"}'


def test_objects_json_cannot_hold_are_refused() -> None:
    with pytest.raises(TypeError):
        jsontext.dumps({"a": object()})


def test_the_package_writes_json_through_jsontext_only() -> None:
    offenders = [str(path.relative_to(SOURCE)) for path in SOURCE.rglob("*.py")
                 if path.name != "jsontext.py"
                 and re.search(r"\bjson\.dumps?\(", path.read_text(encoding="utf-8"))]
    assert offenders == []
