"""Hold conditions (suspenders) on their own: what holds, what clears, and the journal they
write to; no rig."""

from __future__ import annotations

import numpy as np
import pytest

from viscorig.acquisition.holds import (
    AnalyserNotAnswering,
    ForceNearLimit,
    HoldCondition,
    InputOverloading,
    LevelNotHeld,
)
from viscorig.errors import InputError
from viscorig.storage import CampaignFile, Segment


def segment(flags, force=None, start_hz: float = 20.0) -> Segment:
    n = len(flags)
    return Segment(
        frequency_hz=start_hz + 0.25 * np.arange(n), time_s=np.arange(1.0, n + 1),
        accelerance_table=np.ones(n, complex), accelerance_support=np.ones(n, complex),
        reference_amplitude=np.ones(n), source_amplitude=np.full(n, np.nan),
        force_amplitude=np.ones(n) if force is None else np.asarray(force, float),
        flags=np.asarray(flags, np.uint16))


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def test_points_in_a_row_are_counted_across_segments_and_only_in_a_row() -> None:
    clock = Clock()
    level = LevelNotHeld(points=4, retry_s=10.0, clock=clock)
    assert isinstance(level, HoldCondition)
    assert level.observe(segment([1, 0, 1, 1, 0, 1])) is None  # never four in a row
    assert level.observe(segment([1, 1])) is None               # 1 carried + 2 = 3
    reason = level.observe(segment([1, 0, 0], start_hz=30.0))   # 4 in a row across segments
    assert reason == "level not held for 4 points in a row (last at 30 Hz)"
    assert not level.cleared()
    clock.now = 10.0
    assert level.cleared()
    assert level.observe(segment([1, 1, 1])) is None
    level.reset()  # a new run: the three carried are forgotten
    assert level.observe(segment([1])) is None
    overload = InputOverloading(points=2, retry_s=0.0)
    assert overload.observe(segment([1, 1, 1])) is None  # level bits are not overloads
    assert overload.observe(segment([2, 3])).startswith("input overloading for 2 points")


def test_force_near_the_limit_and_force_over_it() -> None:
    force = ForceNearLimit(limit_n=100.0, fraction=0.97, retry_s=0.0)
    assert force.observe(segment([0, 0], force=[96.9, 50.0])) is None
    assert force.observe(segment([0, 0], force=[20.0, 97.0])) == (
        "force 97 N near the shaker limit 100 N (at 20.25 Hz)")
    assert force.observe(segment([8, 0], force=[np.nan, 1.0])) is not None  # flagged over it
    assert force.fault(RuntimeError("x")) is None


class SilentError(Exception):
    pass


def test_a_silent_analyser_holds_until_it_answers_and_is_asked_at_most_once_a_second() -> None:
    clock = Clock()
    answers = {"now": False, "asked": 0}

    def identify() -> str:
        answers["asked"] += 1
        if not answers["now"]:
            raise SilentError("no reply to '*IDN?'")
        return "HEWLETT-PACKARD,35670A"

    condition = AnalyserNotAnswering(identify, (SilentError,), every_s=1.0, clock=clock)
    assert condition.fault(ValueError("a bad setting")) is None  # not a silence: fails as before
    assert condition.fault(SilentError("no reply\nwithin 5 s")) == (
        "analyser not answering (no reply; within 5 s)")
    assert not condition.cleared() and answers["asked"] == 1
    answers["now"] = True
    assert not condition.cleared() and answers["asked"] == 1  # not asked again so soon
    clock.now = 1.0
    assert condition.cleared() and answers["asked"] == 2


def test_the_journal_takes_known_kinds_and_bounded_texts(tmp_path) -> None:
    path = tmp_path / "journal.h5"
    with CampaignFile.create(path, sequence_text="") as campaign:
        assert campaign.journal == []
        campaign.add_journal_entry("note", "  humid today  ", run="soft-0")
        with pytest.raises(InputError, match="journal kind 'gossip'"):
            campaign.add_journal_entry("gossip", "x")
        with pytest.raises(InputError, match="empty text"):
            campaign.add_journal_entry("note", "   ")
        with pytest.raises(InputError, match="at most 2000"):
            campaign.add_journal_entry("note", "x" * 2001)
    entries = CampaignFile.open(path).journal
    assert [(e.kind, e.run, e.text) for e in entries] == [("note", "soft-0", "humid today")]


class Source:
    """What the engine needs of an analyser to pause: its abort (the source off)."""

    def __init__(self) -> None:
        self.aborts = 0

    def abort(self) -> None:
        self.aborts += 1


def test_the_engine_pauses_at_a_checkpoint_and_goes_on_where_it_was(tmp_path) -> None:
    import io
    import threading
    import time

    from viscorig.acquisition.console import Console
    from viscorig.acquisition.engine import EngineState, Msg, Rig, RunEngine

    steps: list[int] = []

    def plan():
        for step in range(60):
            steps.append(step)
            yield Msg("checkpoint")
            time.sleep(0.002)
        return "done"

    source = Source()
    campaign = CampaignFile.create(tmp_path / "pause.h5", sequence_text="")
    engine = RunEngine(campaign, Rig(source, None), Console(out=io.StringIO()))
    result = []
    worker = threading.Thread(target=lambda: result.append(engine.run(plan(), signals=False)))
    worker.start()
    while len(steps) < 5:
        time.sleep(0.001)
    assert engine.request_pause()
    while engine.state is not EngineState.PAUSED:
        time.sleep(0.001)
    held_at = len(steps)
    time.sleep(0.1)
    assert len(steps) == held_at and source.aborts == 1  # nothing runs; the source is off
    assert not engine.request_pause()
    assert engine.request_resume()
    worker.join(10)
    assert result == ["done"] and steps == list(range(60))
    assert [state.value for state, _ in engine.history] == [
        "idle", "running", "pausing", "paused", "running", "done"]
    assert [entry.kind for entry in campaign.journal] == ["pause", "resume"]


def test_a_silent_analyser_holds_the_measurement_which_is_measured_again_when_it_answers(
        tmp_path) -> None:
    import io

    from viscorig.acquisition.console import Console
    from viscorig.acquisition.engine import MeasureRequest, Msg, Rig, RunEngine

    calls = {"measure": 0, "identify": 0}

    def measure(analyser, progress, poll_interval_s):
        calls["measure"] += 1
        if calls["measure"] == 1:
            raise SilentError("no reply to 'SYST:ERR?'")
        return "the segment"

    def identify() -> str:
        calls["identify"] += 1
        if calls["identify"] < 3:
            raise SilentError("no reply to '*IDN?'")
        return "HEWLETT-PACKARD,35670A"

    request = MeasureRequest("soft-0", "GPIB0::11::INSTR", np.array([20.0]), np.array([1.0]),
                             0.0, measure)

    def plan():
        return (yield Msg("measure", (request,)))

    campaign = CampaignFile.create(tmp_path / "silent.h5", sequence_text="")
    holds = [AnalyserNotAnswering(identify, (SilentError,), every_s=0.0)]
    engine = RunEngine(campaign, Rig(Source(), None), Console(out=io.StringIO()), holds=holds,
                       hold_resume="auto")
    assert engine.run(plan(), signals=False) == "the segment"
    assert calls == {"measure": 2, "identify": 3}
    assert "held" in [state.value for state, _ in engine.history]
    journal = campaign.journal
    assert [entry.kind for entry in journal] == ["hold", "hold_cleared"]
    assert journal[0].text == "analyser not answering (no reply to 'SYST:ERR?')"

    calls["measure"] = 0  # an error no condition claims ends the run as before
    engine = RunEngine(campaign, Rig(Source(), None), Console(out=io.StringIO()), holds=[])
    with pytest.raises(SilentError):
        engine.run(plan(), signals=False)


def test_a_specimen_out_of_its_band_holds_until_its_thermocouple_is_back_in_it() -> None:
    from viscorig.acquisition.chamber import Soak
    from viscorig.acquisition.holds import SpecimenOutOfBand

    class Chamber:
        soak = Soak(set_point_c=-10.0, band_k=0.5)
        reading = -8.0

        def specimen_c(self) -> float:
            return self.reading

    clock = Clock()
    chamber = Chamber()
    condition = SpecimenOutOfBand(points=3, chamber=chamber, every_s=10.0, clock=clock)
    assert condition.observe(segment([16, 16, 0, 16, 16])) is None
    assert condition.observe(segment([16, 1])).startswith(
        "specimen out of its temperature band for 3 points in a row")
    assert not condition.cleared()          # -8 °C: still 2 K out
    chamber.reading = -10.3
    assert not condition.cleared()          # not read again before every_s
    clock.now = 10.0
    assert condition.cleared()
