"""How long a sequence will hold the rig, before anything is measured.

A full sweep's test time is known (its points, settle and integration); a probe before a newly
mounted specimen adds its two points; a wait its seconds. An adaptive plan's time is a range
(:func:`viscorig.planning.expected_time_s`): its first look exactly, the band's coverage within
bounds, and the points it chooses between 0.9 and 1.3 times the *floor* of the rig when the
floor is known (:func:`viscorig.planning.design_bound`: the least rig time any plan needs for
the targets). Without a floor (a station's specimen is known only once measured) the range has
no upper end but the step's dwell limit.

``viscorig plan`` prints this per step with the total; ``viscorig run`` prints it before its
first prompt and counts it in the time left.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

from viscorig.acquisition.console import format_duration
from viscorig.acquisition.probe import probe_test_time_s
from viscorig.sequences import (
    IdentifyTableStep,
    PromptStep,
    Sequence,
    SweepStep,
    TemperatureStep,
    WaitStep,
)

__all__ = ["Floor", "StepForecast", "forecast_sequence", "format_forecast", "probe_expected"]


@dataclass(frozen=True)
class Floor:
    """What is known before an adaptive run of the rig it will measure.

    Attributes
    ----------
    plan_time_s
        Rig time of the optimal design for the step's targets (the floor).
    integration_floor_s
        Certified lower bound on the integration time of any plan.
    misfit
        The step's model does not fit the rig to the noise: the plan stops once the band is
        covered (its targets would be the precision of a biased value).
    source
        Where the rig's description comes from (``"simulated rig 'soft-0'"``).
    """

    plan_time_s: float
    integration_floor_s: float
    misfit: bool = False
    source: str = ""


@dataclass(frozen=True)
class StepForecast:
    """The predicted test time of one step.

    Attributes
    ----------
    index, kind, name
        The step.
    low_s, high_s
        Shortest and longest test time expected (equal when known; ``inf``: no upper end).
    probe_s
        Of which the probe before it (and, before an adaptive run, the gain points).
    floor
        An adaptive step's floor, when known.
    note
        What the figure rests on.
    """

    index: int
    kind: str
    name: str
    low_s: float
    high_s: float
    probe_s: float = 0.0
    floor: Floor | None = None
    note: str = ""

    @property
    def expected_s(self) -> float:
        """One figure for the time left: the middle of the range (its low end when open)."""
        return self.low_s if math.isinf(self.high_s) else 0.5 * (self.low_s + self.high_s)

    def to_json(self) -> dict[str, object]:
        return {
            "step": self.index, "kind": self.kind, "name": self.name,
            "low_s": self.low_s, "high_s": None if math.isinf(self.high_s) else self.high_s,
            "probe_s": self.probe_s,
            "floor_s": None if self.floor is None else self.floor.plan_time_s,
            "integration_floor_s": None if self.floor is None
            else self.floor.integration_floor_s,
            "note": self.note,
        }


def probe_expected(steps: tuple, index: int, table_known: bool,
                   status: Callable[[str], str | None] = lambda run: None) -> bool:
    """Will the sweep at ``index`` be probed (decided when it comes: a newly mounted rig)?"""
    step = steps[index]
    if not isinstance(step, SweepStep) or status(step.run) is not None:
        return False
    if step.bare_table and (table_known or any(
            isinstance(s, IdentifyTableStep) for s in steps[:index])):
        return False
    for before in reversed(steps[:index]):
        if isinstance(before, PromptStep):
            return True
        if isinstance(before, SweepStep):
            return False
    return True


def forecast_sequence(
    sequence: Sequence,
    *,
    table_known: bool = False,
    floors: Mapping[str, Floor | None] | None = None,
    force_limit_n: float | None = None,
    status: Callable[[str], str | None] = lambda run: None,
    chamber_start_c: float = 25.0,
    specimen_time_constant_s: float = 600.0,
    heating_rate_k_per_min: float | None = None,
    cooling_rate_k_per_min: float | None = None,
) -> list[StepForecast]:
    """The predicted test time of every step (prompts and table fits take none).

    Parameters
    ----------
    sequence
        The sequence.
    table_known
        The station (or the file) gives the table: a bare-table run is not probed.
    floors
        The floor of each adaptive run's rig, by run name, where known.
    force_limit_n
        The shaker's limit (an adaptive plan keeps its forces below it).
    status
        A run's status in the campaign file (a run already measured is not probed again).
    chamber_start_c, specimen_time_constant_s, heating_rate_k_per_min, cooling_rate_k_per_min
        The specimens' temperature before the first temperature step, how slowly they follow
        the chamber, and how fast its air heats and cools (a soak is its ramp, the lag into the
        band, and the soak time: :meth:`~viscorig.sequences.TemperatureStep.duration_s`).
    """
    floors = floors or {}
    out = []
    temperature_c = chamber_start_c
    for index, step in enumerate(sequence.steps):
        if isinstance(step, TemperatureStep):
            seconds = step.duration_s(temperature_c, specimen_time_constant_s,
                                      heating_rate_k_per_min, cooling_rate_k_per_min)
            out.append(StepForecast(index, "soak", f"{step.set_point_c:g} °C", seconds, seconds,
                                    note=f"from {temperature_c:g} °C"))
            temperature_c = step.set_point_c
            continue
        if isinstance(step, WaitStep):
            out.append(StepForecast(index, "wait", f"{step.seconds:g} s", step.seconds,
                                    step.seconds, note="waited on a real rig"))
            continue
        if not isinstance(step, SweepStep):
            kind = "prompt" if isinstance(step, PromptStep) else "identify_table"
            out.append(StepForecast(index, kind, getattr(step, "run", "") or "", 0.0, 0.0))
            continue
        probe = (probe_test_time_s(step)
                 if probe_expected(sequence.steps, index, table_known, status) else 0.0)
        if not step.adaptive:
            seconds = step.duration_s() + probe
            out.append(StepForecast(index, "sweep", step.run, seconds, seconds, probe,
                                    note=f"{step.points} points"))
            continue
        # keeps the command's start fast: scipy loads only when needed
        from viscorig.acquisition.adaptive import adaptive_settings
        from viscorig.planning import expected_time_s

        probe += probe_test_time_s(step)  # the shaker's gain, measured at the probe's points

        settings = adaptive_settings(step, step.level_m_per_s2, None, force_limit_n)
        floor = floors.get(step.run)
        if floor is not None and floor.misfit:  # look and coverage only: no chosen point
            low, high = expected_time_s(settings, 0.0)
            note = (f"'{step.model}' does not fit {floor.source} to the noise: the plan stops "
                    "once the band is covered; diagnose says which model does")
        else:
            low, high = expected_time_s(settings, None if floor is None else floor.plan_time_s)
            note = ("the points it chooses within 0.9 to 1.3 times the floor of "
                    f"{floor.source}" if floor is not None else
                    "the points it chooses are not known before the rig is: no upper end "
                    "but the dwell limit")
        out.append(StepForecast(index, "adaptive sweep", step.run, low + probe, high + probe,
                                probe, floor, note))
    return out


def format_forecast(forecasts: list[StepForecast], heading: str = "") -> str:
    """The forecast as text: one line per sweep or wait, the total, what it rests on."""
    def span(low: float, high: float) -> str:
        if math.isinf(high):
            return f"{format_duration(low)} or more"
        if abs(high - low) < 0.5:
            return format_duration(low)
        return f"{format_duration(low)} to {format_duration(high)}"

    lines = [heading] if heading else []
    for item in forecasts:
        if item.kind in ("prompt", "identify_table"):
            continue
        text = (f"  steps[{item.index}] {item.kind:<14} {item.name:<12} "
                f"{span(item.low_s, item.high_s)}")
        if item.probe_s:
            text += f" (probe {format_duration(item.probe_s)})"
        if item.floor is not None and not item.floor.misfit:
            text += (f"; floor {format_duration(item.floor.plan_time_s)} (integration at "
                     f"least {format_duration(item.floor.integration_floor_s)})")
        if item.kind == "adaptive sweep" and item.note:
            text += f"; {item.note}"
        lines.append(text)
    low = sum(item.low_s for item in forecasts)
    high = sum(item.high_s for item in forecasts)
    soaks = [item for item in forecasts if item.kind == "soak"]
    if soaks:
        lines.append(f"  {len(soaks)} soak{'s' if len(soaks) != 1 else ''}: "
                     f"{format_duration(sum(item.low_s for item in soaks))} of the total")
    lines.append(f"  total test time {span(low, high)}")
    return "\n".join(lines)
