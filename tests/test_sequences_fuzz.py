"""Fuzzing: whatever a sequence or station file holds, the answer is a value or an InputError."""

from __future__ import annotations

import copy
import math

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_sequences import document as sequence_document
from test_sequences_station import document as station_document
from tomlwrite import dumps

from viscorig.errors import InputError
from viscorig.sequences import Sequence, Station, SweepStep, parse_sequence, parse_station
from viscorig.storage import layout

text = st.text(st.characters(blacklist_categories=("Cs",)), max_size=40)
scalars = st.one_of(
    st.integers(-10**20, 10**20), st.floats(allow_nan=True, allow_infinity=True), text,
    st.booleans(), st.sampled_from(["1.4 m/s^2", "0.15 g", "none", "up", "table", "prompt",
                                    "sweep", "GPIB0::11::INSTR"]),
)
values = st.recursive(
    scalars,
    lambda inner: st.one_of(st.lists(inner, max_size=3),
                            st.dictionaries(st.sampled_from(["a", "run", "type"]), inner,
                                            max_size=2)),
    max_leaves=6,
)


def tables(document: dict) -> list[dict]:
    """Every table of a document (the top level, nested tables, tables in arrays)."""
    found = [document]
    for value in document.values():
        if isinstance(value, dict):
            found.extend(tables(value))
        elif isinstance(value, list):
            for item in value:
                if isinstance(item, dict):
                    found.extend(tables(item))
    return found


@st.composite
def mutated(draw: st.DrawFn, base: dict) -> str:
    document = copy.deepcopy(base)
    for _ in range(draw(st.integers(1, 4))):
        table = draw(st.sampled_from(tables(document)))
        keys = sorted(table)
        action = draw(st.sampled_from(["set", "delete", "add"]))
        if action == "delete" and keys:
            del table[draw(st.sampled_from(keys))]
        elif action == "set" and keys:
            table[draw(st.sampled_from(keys))] = draw(values)
        else:
            table[draw(text.filter(bool))] = draw(values)
    return dumps(document)


def outcome_of(parse, source: str) -> object:
    try:
        return parse(source)
    except InputError as error:
        assert str(error).startswith("fuzz.toml"), str(error)
        assert "\n" not in str(error.detail).strip() or "TOML" in str(error)
        return error


FUZZ = settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@pytest.mark.slow
@FUZZ
@given(mutated(sequence_document()))
def test_mutated_sequences_give_a_sequence_or_an_input_error(source: str) -> None:
    result = outcome_of(lambda s: parse_sequence(s, source="fuzz.toml"), source)
    assert isinstance(result, Sequence | InputError)
    if isinstance(result, Sequence):
        for step in result.steps:
            if isinstance(step, SweepStep):  # an accepted sweep can be measured as written
                lo, hi = step.band_hz
                assert 0 < lo < hi and math.isfinite(hi), step
                assert math.isfinite(step.level_m_per_s2) and step.level_m_per_s2 > 0, step
                assert step.settle_cycles > 0 and step.integrate_cycles > 0, step
                assert layout.NAME.match(step.run), step


@pytest.mark.slow
@FUZZ
@given(mutated(station_document()))
def test_mutated_stations_give_a_station_or_an_input_error(source: str) -> None:
    result = outcome_of(lambda s: parse_station(s, source="fuzz.toml"), source)
    assert isinstance(result, Station | InputError)


@settings(max_examples=200, deadline=None)
@given(st.text(max_size=200))
def test_arbitrary_text_gives_an_input_error_or_a_value(source: str) -> None:
    assert isinstance(outcome_of(lambda s: parse_sequence(s, source="fuzz.toml"), source),
                      Sequence | InputError)
    assert isinstance(outcome_of(lambda s: parse_station(s, source="fuzz.toml"), source),
                      Station | InputError)
