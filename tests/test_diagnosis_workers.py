"""A diagnosis whose candidate fits run on worker processes gives the same numbers, in the same
order, as one that makes them all in this process (``diagnose --jobs``)."""

from __future__ import annotations

import json
import logging
import os
import pickle
import time

import numpy as np
import pytest
from simdata import DEFAULT_NOISE, rig_text, simulate_run

from viscorig.cli import main
from viscorig.diagnosis import diagnose
from viscorig.diagnosis.workers import fit_all, fitting_on
from viscorig.executor import LocalExecutor, default_jobs
from viscorig.models import parse_spec

TABLE = {"M_s": 3.4, "K_s": 50194.0, "C_s": 5.05}
VOIGT = {"mass_kg": 0.25, "model": "voigt", "stiffness_n_per_m": 1.5e5, "damping_ns_per_m": 114.59}
FIXTURE = {"frequency_hz": 58.0, "damping_ratio": 0.02, "mass_kg": 0.003}
QUIET = {key: value / 10 for key, value in DEFAULT_NOISE.items()}


def summary(steps) -> list:
    return [(step.model, step.rms_error,
             [(f.effect, f.term, f.delta_chi2, f.significant, f.note) for f in step.findings])
            for step in steps]


def climb(data) -> list:
    """One step's candidates fitted and tested, and a final model's unpaid term taken out."""
    first = diagnose(data, "voigt", table=TABLE)
    lighter = diagnose(data, "voigt+fixture(58)+fixture(83)", table=TABLE).without_unpaid()
    assert lighter is not None
    return summary([first, lighter])


@pytest.mark.slow
def test_the_fits_on_two_workers_are_the_fits_in_one_process() -> None:
    run = simulate_run(rig_text(VOIGT, noise=QUIET, fixtures=[FIXTURE]), seed=3, step_hz=0.5)
    data = run.frf_data("run")
    with np.errstate(all="ignore"):
        here = climb(data)
        with LocalExecutor(2) as workers, fitting_on(workers):
            there = climb(data)
    assert len(here[0][2]) >= 5 and here[1][0] == "voigt+fixture(58)"
    assert there == here  # exactly: the same arithmetic on the same inputs


def test_a_model_crosses_to_a_process_whole() -> None:
    model = parse_spec("maxwell(2)+load_cell+fixture(58)+fixture(92)+delay(x_s)")
    copy = pickle.loads(pickle.dumps(model))
    assert copy.spec == model.spec and copy.names == model.names
    for old, new in zip(model.effects, copy.effects, strict=True):
        assert copy.local_names(new) == model.local_names(old)


@pytest.mark.parametrize("jobs", ["0", "two"])
def test_jobs_must_be_a_whole_number_of_at_least_one(jobs: str, tmp_path, capsys) -> None:
    with pytest.raises(SystemExit) as stop:
        main(["diagnose", str(tmp_path / "none.h5"), "--run", "x", "--jobs", jobs])
    assert stop.value.code == 2
    assert "--jobs" in capsys.readouterr().err


@pytest.mark.parametrize("command", ["diagnose", "report"])
def test_jobs_beyond_four_per_core_are_refused_before_any_process_is_forked(
        command: str, tmp_path, capsys) -> None:
    # local workers are forked all at once: a mistyped --jobs 99999 forked for minutes
    arguments = [command, str(tmp_path / "none.h5")] + (["--run", "x"] if command == "diagnose"
                                                         else [])
    start = time.perf_counter()
    with pytest.raises(SystemExit) as stop:
        main([*arguments, "--jobs", "99999"])
    assert stop.value.code == 2 and time.perf_counter() - start < 5
    most = 4 * default_jobs()
    assert f"--jobs: at most {most} (4 per core of this machine), got 99999" in \
        capsys.readouterr().err
    assert main([*arguments, "--jobs", str(most)]) == 2  # accepted: the file is what is refused
    assert "no such file" in capsys.readouterr().err


def test_diagnose_json_is_the_same_with_one_job_and_two(tmp_path, capsys) -> None:
    from test_diagnosis import write_campaign

    run = simulate_run(rig_text(VOIGT, noise=QUIET, fixtures=[FIXTURE]), seed=3, step_hz=0.5)
    path = write_campaign(tmp_path / "c.h5", [("soft-0", run, 1.0, "up", 0.0)])
    documents = []
    for jobs in ("1", "2"):
        assert main(["diagnose", str(path), "--run", "soft-0", "--json", "--jobs", jobs]) == 0
        documents.append(json.loads(capsys.readouterr().out))
    assert documents[0] == documents[1]
    assert documents[0]["findings"][0]["effect"] == "fixture_resonance"


PARENT = os.getpid()


def square_here_only(x: int) -> int:
    """x², in the test's own process; a worker process that runs it dies at once."""
    if os.getpid() != PARENT:
        os._exit(1)
    return x * x


def test_a_worker_that_dies_costs_no_result(caplog) -> None:
    with caplog.at_level(logging.WARNING), LocalExecutor(2) as workers, fitting_on(workers):
        assert fit_all(square_here_only, [(3,), (4,), (5,)]) == [9, 16, 25]
        assert fit_all(square_here_only, [(6,), (7,)]) == [36, 49]  # the rest made here
    assert "worker process stopped" in caplog.text


@pytest.mark.slow
def test_forward_tests_made_together_are_those_made_one_after_another() -> None:
    """A rung whose forward tests accept several effects after the lead (the load cell and
    three local modes next to a Maxwell K*): the tests that follow one base are fitted two at a
    time on the workers, those after an accepted one again, and the ladder is the same."""
    from ladder_reference import measured_run

    from viscorig.diagnosis.data import combine

    data = combine([("medium-10", measured_run("medium-10"))], table=TABLE)
    with np.errstate(all="ignore"):
        here = summary(diagnose(data, "voigt").auto())
        with LocalExecutor(2) as workers, fitting_on(workers):
            there = summary(diagnose(data, "voigt").auto())
    accepted_after_lead = max(sum(1 for f in rung[2] if f[3]) - 1 for rung in here)
    assert accepted_after_lead >= 2
    assert there == here
