"""Automatic holds, in the manner of Bluesky's suspenders: conditions that pause a run by
themselves, keeping what was measured, and say when it may go on.

The run engine (:mod:`viscorig.acquisition.engine`) shows every committed segment to each
condition (:meth:`HoldCondition.observe`) and every instrument fault of a measurement
(:meth:`HoldCondition.fault`); a condition that answers with a reason holds the run at that
point. While held, the engine asks the condition that held it whether it has cleared
(:meth:`HoldCondition.cleared`), and, as the station says (``[bench] hold_resume``), resumes
by itself when it has, or waits for the technician.

A condition is any object with these three members (and optionally ``reset()``, called when
a run ends), so others plug in without touching the engine (a specimen out of its temperature
band is one more class that observes a reading).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Protocol, runtime_checkable

import numpy as np

from viscorig.storage import FORCE_ABOVE_SHAKER_LIMIT, INPUT_OVERLOAD, LEVEL_NOT_REACHED, Segment
from viscorig.storage.flags import PointFlag

__all__ = ["AnalyserNotAnswering", "ForceNearLimit", "HoldCondition", "InputOverloading",
           "LevelNotHeld", "RetryAfter", "SpecimenOutOfBand", "standard_conditions"]


class SpecimenThermometer(Protocol):
    """What reads the specimen's temperature (a ``ChamberMonitor``; its ``soak``, if any, is
    the band)."""

    def specimen_c(self) -> float:
        """The specimen thermocouple's reading, °C."""
        ...


@runtime_checkable
class HoldCondition(Protocol):
    """A reason to hold a run (module text)."""

    def observe(self, segment: Segment) -> str | None:
        """A committed segment: the reason to hold now, or None."""

    def fault(self, error: BaseException) -> str | None:
        """An error of the analyser while it measured: the reason to hold instead of
        failing, or None (the error then ends the run as before)."""

    def cleared(self) -> bool:
        """While this condition holds the run: may it go on?"""


class RetryAfter:
    """Cleared once ``retry_s`` have passed since the hold began (a condition seen only by
    measuring again: the run goes on and is held again if it still holds)."""

    def __init__(self, retry_s: float, clock: Callable[[], float] = time.monotonic) -> None:
        self.retry_s = float(retry_s)
        self.clock = clock
        self._since = clock()

    def _held(self) -> None:
        self._since = self.clock()

    def fault(self, error: BaseException) -> str | None:
        return None

    def cleared(self) -> bool:
        return self.clock() - self._since >= self.retry_s


def _run_length(mask: np.ndarray, carried: int) -> tuple[int, int]:
    """(longest run of true values, with ``carried`` true values before it; the run of true
    values at the end)."""
    longest, current = 0, carried
    for value in mask:
        current = current + 1 if value else 0
        longest = max(longest, current)
    return longest, current


class _FlaggedInARow(RetryAfter):
    flag = 0
    what = ""

    def __init__(self, points: int, retry_s: float,
                 clock: Callable[[], float] = time.monotonic) -> None:
        super().__init__(retry_s, clock)
        self.points = int(points)
        self._carried = 0

    def reset(self) -> None:
        """A new run: nothing carried over."""
        self._carried = 0

    def observe(self, segment: Segment) -> str | None:
        mask = (np.asarray(segment.flags, dtype=np.uint16) & self.flag) != 0
        longest, self._carried = _run_length(mask, self._carried)
        if longest < self.points:
            return None
        self._carried = 0
        self._held()
        frequency = float(np.asarray(segment.frequency_hz)[mask][-1])
        return f"{self.what} for {longest} points in a row (last at {frequency:g} Hz)"


class LevelNotHeld(_FlaggedInARow):
    """The level controller missed its tolerance on ``points`` points in a row."""

    flag = int(LEVEL_NOT_REACHED)
    what = "level not held"


class InputOverloading(_FlaggedInARow):
    """An input overloaded on ``points`` points in a row."""

    flag = int(INPUT_OVERLOAD)
    what = "input overloading"


class SpecimenOutOfBand(_FlaggedInARow):
    """The specimen's thermocouple left the soak band on ``points`` points in a row (flag 16 of
    the chamber's runs); cleared when it reads within the band again (asked at most once every
    ``every_s``).

    Parameters
    ----------
    chamber
        The :class:`~viscorig.acquisition.chamber.ChamberMonitor` (its ``soak`` and
        ``specimen_c()``).
    """

    flag = int(PointFlag.OUTSIDE_SOAK_BAND)
    what = "specimen out of its temperature band"

    def __init__(self, points: int, chamber: SpecimenThermometer, every_s: float = 10.0,
                 clock: Callable[[], float] = time.monotonic) -> None:
        super().__init__(points, 0.0, clock)
        self.chamber = chamber
        self.every_s = float(every_s)
        self._asked = -float("inf")

    def cleared(self) -> bool:
        """Read the specimen thermocouple (at most once every ``every_s``): back in the band?

        On a simulated rig (a chamber with ``pass_time``) its clock moves only when told to:
        each look lets ``every_s`` of its time pass first, as they would at a real bench while
        the run is held, so that the chamber can bring the specimen back."""
        soak = getattr(self.chamber, "soak", None)
        if soak is None:
            return True
        pass_time = getattr(self.chamber, "pass_time", None)
        if pass_time is not None:
            try:
                pass_time(self.every_s)
            except Exception:
                return False
        elif self.clock() - self._asked < self.every_s:
            return False
        self._asked = self.clock()
        try:
            temperature = float(self.chamber.specimen_c())
        except Exception:
            return False
        return not bool(soak.outside(np.array([temperature]))[0])


class ForceNearLimit(RetryAfter):
    """The force reached ``fraction`` of the shaker's limit (or the point was flagged over it)."""

    def __init__(self, limit_n: float, fraction: float, retry_s: float,
                 clock: Callable[[], float] = time.monotonic) -> None:
        super().__init__(retry_s, clock)
        self.limit_n = float(limit_n)
        self.fraction = float(fraction)

    def observe(self, segment: Segment) -> str | None:
        force = np.asarray(segment.force_amplitude, dtype=float)
        over = (np.nan_to_num(force) >= self.fraction * self.limit_n) | (
            (np.asarray(segment.flags, dtype=np.uint16) & int(FORCE_ABOVE_SHAKER_LIMIT)) != 0)
        if not over.any():
            return None
        self._held()
        at = int(np.flatnonzero(over)[0])
        return (f"force {force[at]:.3g} N near the shaker limit {self.limit_n:g} N "
                f"(at {float(np.asarray(segment.frequency_hz)[at]):g} Hz)")


class AnalyserNotAnswering:
    """The analyser stopped answering while it measured; cleared when it answers again.

    Parameters
    ----------
    answers
        Asks the analyser for its identity; raises while it does not answer.
    kinds
        The driver's exception types that mean the analyser did not answer.
    every_s
        Ask it again no more often than this, s.
    """

    def __init__(self, answers: Callable[[], object], kinds: tuple[type[BaseException], ...],
                 every_s: float = 1.0, clock: Callable[[], float] = time.monotonic) -> None:
        self.answers = answers
        self.kinds = kinds
        self.every_s = float(every_s)
        self.clock = clock
        self._asked = -float("inf")

    def observe(self, segment: Segment) -> str | None:
        return None

    def fault(self, error: BaseException) -> str | None:
        if not (self.kinds and isinstance(error, self.kinds)):
            return None
        text = "; ".join(line.strip() for line in str(error).splitlines() if line.strip())
        return f"analyser not answering ({text[:200]})"

    def cleared(self) -> bool:
        """Ask the analyser (at most once every ``every_s``): does it answer?"""
        if self.clock() - self._asked < self.every_s:
            return False
        self._asked = self.clock()
        try:
            self.answers()
        except Exception:
            return False
        return True


def standard_conditions(bench, force_limit_n: float, answers: Callable[[], object],
                        kinds: tuple[type[BaseException], ...],
                        chamber: SpecimenThermometer | None = None) -> list[HoldCondition]:
    """The holds of a station's ``[bench]`` settings (:class:`BenchSettings`): four, and the
    temperature band's with a chamber."""
    conditions: list[HoldCondition] = [
        LevelNotHeld(bench.hold_level_points, bench.hold_retry_s),
        InputOverloading(bench.hold_overload_points, bench.hold_retry_s),
        ForceNearLimit(force_limit_n, bench.hold_force_fraction, bench.hold_retry_s),
        AnalyserNotAnswering(answers, kinds),
    ]
    if chamber is not None:
        conditions.append(SpecimenOutOfBand(bench.hold_temperature_points, chamber))
    return conditions
