"""A sequence's chamber set points against the station's chamber: every temperature step needs a
chamber, and no set point may lie outside the station's limits (``check`` and ``run`` refuse the
sequence before anything moves)."""

from __future__ import annotations

from viscorig.sequences.problems import Problem, Problems
from viscorig.sequences.station import ChamberStation
from viscorig.sequences.steps import Sequence

__all__ = ["set_point_problems"]


def set_point_problems(sequence: Sequence, chamber: ChamberStation | None, text: str = "",
                       station_source: str = "the station") -> list[Problem]:
    """Every temperature step the station's chamber cannot take, one problem each.

    Parameters
    ----------
    sequence
        A valid sequence.
    chamber
        The station's ``[chamber]`` (the embedded rig's when no station is given), or None.
    text
        The sequence's TOML text, for line numbers.
    station_source
        How to name the station in messages.
    """
    problems = Problems(sequence.source, text)
    for step in sequence.soaks:
        # a repeat's set points are written in its temperatures_c
        origin = step.origin or ("steps",)
        path = origin if origin[-1] == "temperatures_c" else (*origin, "set_point_c")
        if chamber is None:
            problems.add(path, f"a temperature step needs a chamber, and {station_source} has "
                         "no [chamber]", "add a [chamber] table to the station file")
            continue
        if not chamber.allows(step.set_point_c):
            problems.add(path, f"set point {step.set_point_c:g} °C is outside {station_source}'s "
                         f"chamber limits [{chamber.low_limit_c:g}, {chamber.high_limit_c:g}] °C",
                         "change the set point, or the station's low_limit_c/high_limit_c if "
                         "the chamber and specimens allow it")
    return problems.items
