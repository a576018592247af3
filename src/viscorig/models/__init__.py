"""Composable models of the rig's FRFs: one K* term plus any effect terms.

Write a term as a subclass of :class:`Term` (or :class:`ModulusTerm` for a new K*), declare its
:class:`Parameter` list, override the pipeline stages it takes part in (see
:mod:`viscorig.models.base`), and decorate it with :func:`register_term`; then
``parse_spec("voigt+myterm")`` knows it and every fitter can fit it, unchanged. Modules holding
terms are imported below so that their registration runs; the order of registration is the
order of effect terms in canonical spec strings.
"""

from viscorig.models.base import (
    DISC_MASS,
    FRF_NAMES,
    TABLE_PARAMETERS,
    TERMS,
    Context,
    Model,
    ModulusTerm,
    Parameter,
    Term,
    register_term,
    stage_methods,
    table_dynamic_stiffness,
)
from viscorig.models.effects import EFFECTS, Amplitude, Drift, Fixture, Frame, LoadCell
from viscorig.models.modulus import MAXWELL_MAX_ORDER, Fractional, Maxwell, TableOnly, Voigt
from viscorig.models.sensors import CHANNELS, Delay, Gain, Highpass, Lowpass
from viscorig.models.spec import parse_spec

__all__ = [
    "CHANNELS",
    "DISC_MASS",
    "EFFECTS",
    "FRF_NAMES",
    "MAXWELL_MAX_ORDER",
    "TABLE_PARAMETERS",
    "TERMS",
    "Amplitude",
    "Context",
    "Delay",
    "Drift",
    "Fixture",
    "Fractional",
    "Frame",
    "Gain",
    "Highpass",
    "LoadCell",
    "Lowpass",
    "Maxwell",
    "Model",
    "ModulusTerm",
    "Parameter",
    "TableOnly",
    "Term",
    "Voigt",
    "parse_spec",
    "register_term",
    "stage_methods",
    "table_dynamic_stiffness",
]
