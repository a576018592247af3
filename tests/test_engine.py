"""The run engine's lifecycle: plans of messages executed in order, refusals, faults and stops
thrown into the plan so that its cleanup runs, and the state each ending leaves."""

from __future__ import annotations

import io
import os
import signal

import pytest

from viscorig.acquisition import Console, EngineState, Msg, RunEngine, RunRefused, Wiring
from viscorig.acquisition.engine import Rig
from viscorig.errors import InstrumentError
from viscorig.storage import CampaignFile


class Analyser:
    resource = "FAKE::1::INSTR"

    def identify(self) -> str:
        return "FAKE,35670A,0,0"


@pytest.fixture
def engine(tmp_path) -> RunEngine:
    campaign = CampaignFile.create(tmp_path / "c.h5", sequence_text="", durable=False)
    rig = Rig(Analyser(), Wiring(1, 2, 3, 4, {1: 0.01, 2: 0.01, 3: 0.01, 4: 0.01}),
              real_time_waits=False)
    return RunEngine(campaign, rig, Console(yes=True, out=io.StringIO(), interactive=False))


def said(engine: RunEngine) -> list[str]:
    return engine.console.out.getvalue().splitlines()


def test_a_plan_is_executed_in_order_and_sent_what_each_message_produced(engine) -> None:
    def plan():
        identity = yield Msg("identify", step="t")
        yield Msg("say", (f"analyser {identity}",), step="t")
        status = yield Msg("status", ("r",), step="t")
        waited = yield Msg("sleep", (5.0, "settling"), step="t")
        yield Msg("checkpoint", step="t")
        return status, waited

    assert engine.state is EngineState.IDLE
    assert engine.run(plan(), signals=False) == (None, False)
    assert engine.state is EngineState.DONE
    assert [state for state, _ in engine.history] == [EngineState.IDLE, EngineState.RUNNING,
                                                       EngineState.DONE]
    assert said(engine) == ["analyser FAKE,35670A,0,0",
                            "settling: 5 s (simulated rig: not waited)"]
    assert {"measure", "commit", "configure", "probe", "checkpoint"} <= set(engine.commands)


def test_a_refusal_ends_in_state_refused(engine) -> None:
    def plan():
        yield Msg("say", ("before",))
        raise RunRefused("not measured")

    with pytest.raises(RunRefused):
        engine.run(plan(), signals=False)
    assert engine.state is EngineState.REFUSED


def test_a_fault_is_thrown_into_the_plan_whose_cleanup_runs_then_it_ends(engine) -> None:
    engine._handlers["fail"] = lambda: (_ for _ in ()).throw(InstrumentError("lost"))

    def plan():
        try:
            yield Msg("fail", step="measure")
        except InstrumentError:
            yield Msg("say", ("cleanup after the fault",))
            raise
        yield Msg("say", ("never",))

    with pytest.raises(InstrumentError, match="lost"):
        engine.run(plan(), signals=False)
    assert engine.state is EngineState.FAULTED
    assert said(engine) == ["cleanup after the fault"]


def test_a_stop_asked_for_ends_the_plan_at_its_next_checkpoint(engine) -> None:
    def plan():
        yield Msg("say", ("segment 1 committed",))
        engine.stop.requested.set()  # Ctrl-C while the segment was measured
        try:
            yield Msg("checkpoint", step="commit")
        except KeyboardInterrupt:
            yield Msg("say", ("run marked aborted",))
            raise
        yield Msg("say", ("segment 2",))

    with pytest.raises(KeyboardInterrupt):
        engine.run(plan(), signals=False)
    assert engine.state is EngineState.STOPPED
    assert EngineState.STOPPING in [state for state, _ in engine.history]
    assert said(engine) == ["segment 1 committed", "run marked aborted"]


def test_an_unknown_message_names_the_step_that_sent_it(engine) -> None:
    def plan():
        yield Msg("teleport", step="adaptive soft-0")

    with pytest.raises(RuntimeError, match="unknown message 'teleport' from adaptive soft-0"):
        engine.run(plan(), signals=False)
    assert engine.state is EngineState.FAULTED


def test_ctrl_c_during_a_write_to_the_file_interrupts_once_the_write_has_ended(engine) -> None:
    def write(campaign: CampaignFile) -> None:
        os.kill(os.getpid(), signal.SIGINT)  # the technician's Ctrl-C, in the middle of a commit
        campaign.add_journal_entry("note", "written after the signal", "r")

    def plan():
        try:
            yield Msg("compute", (write,), step="commit")
            yield Msg("say", ("never",))
        except KeyboardInterrupt:
            yield Msg("say", ("run marked aborted",))
            raise

    with pytest.raises(KeyboardInterrupt):
        engine.run(plan(), signals=True)
    assert engine.state is EngineState.STOPPED
    assert said(engine) == ["run marked aborted"]
    assert [(entry.kind, entry.text) for entry in engine.campaign.journal] == [
        ("note", "written after the signal"), ("abort", "stopped at the terminal (Ctrl-C)")]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
