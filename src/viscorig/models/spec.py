"""Model spec strings: ``"maxwell(3)+load_cell+fixture(58)"`` to a :class:`Model`.

Its own module so that the term registry (:mod:`viscorig.models.base`) and the loader of
third-party terms (:mod:`viscorig.models.entry_points`) do not import each other.
"""

from __future__ import annotations

import re

from viscorig.errors import InputError
from viscorig.models.base import TERMS, Model, Term
from viscorig.models.entry_points import load_entry_point_terms

_TERM_PATTERN = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*(?:\(\s*([^()]*?)\s*\))?\s*$")
#: A ``+`` that joins terms: not one inside parentheses (``fixture(1e+2)``).
_JOIN = re.compile(r"\+(?![^()]*\))")
#: Copies of one repeatable term (local modes) a model may hold: far more than a band shows
#: (the paper's rig has three), and each copy costs every fit a few parameters more.
MAX_COPIES = 12


def parse_spec(spec: str) -> Model:
    """Build a model from a spec string such as ``"maxwell(3)+load_cell+fixture(58)"``.

    Raises
    ------
    InputError
        Unknown term, malformed term, no or several K* terms.
    """
    if not isinstance(spec, str) or not spec.strip():
        raise InputError("empty model spec", "model spec")
    terms: list[Term] = []
    for part in _JOIN.split(spec):
        match = _TERM_PATTERN.match(part)
        if match is None:
            raise InputError(f"malformed term '{part.strip()}' in '{spec}'", "model spec")
        keyword, argument = match.group(1).lower(), match.group(2)
        if keyword not in TERMS:  # perhaps a term of another package (viscorig.terms)
            problems = "".join(f"; not loaded: {text}" for text in load_entry_point_terms())
            if keyword not in TERMS:
                known = ", ".join(sorted(TERMS))
                raise InputError(
                    f"unknown term '{keyword}' in '{spec}' (known: {known}{problems})",
                    "model spec",
                )
        terms.append(TERMS[keyword].from_argument(argument or None))
        copies = sum(term.keyword == keyword for term in terms)
        if copies > MAX_COPIES:
            raise InputError(f"'{keyword}' is given {copies} times; a model holds at most "
                             f"{MAX_COPIES}", "model spec")
    model = Model(terms)
    if model.modulus_term is None:
        moduli = ", ".join(k for k, cls in TERMS.items() if cls.kind == "modulus")
        raise InputError(f"'{spec}' has no K* term (one of: {moduli})", "model spec")
    return model
