"""One executor for independent work: local processes, or a Dask cluster on loopback."""

from __future__ import annotations

import operator
import os

import pytest

from viscorig.cli import main
from viscorig.errors import InputError
from viscorig.executor import DaskExecutor, LocalExecutor, check_scheduler, executor


def pid_of(_: int) -> int:
    return os.getpid()


def test_local_map_keeps_order_across_processes():
    with LocalExecutor(2) as pool:
        assert pool.map(operator.mul, [(i, i) for i in range(20)]) == [i * i for i in range(20)]
        pids = set(pool.map(pid_of, [(i,) for i in range(8)]))
    assert os.getpid() not in pids


def test_local_unordered_gives_every_result_once():
    with executor(2) as pool:
        assert sorted(pool.unordered(abs, range(-5, 5))) == sorted(abs(i) for i in range(-5, 5))


def test_a_single_piece_started_goes_to_a_worker_and_a_single_mapped_one_stays():
    """This process does other work while a started piece runs (a diagnosis step's frame
    screening during its scan); a piece mapped alone is waited for, so it is made here."""
    with LocalExecutor(2) as pool:
        assert pool.start(pid_of, [(1,)])() != [os.getpid()]
        assert pool.map(pid_of, [(1,)]) == [os.getpid()]


def test_one_job_runs_in_this_process():
    with LocalExecutor(1) as pool:
        assert set(pool.map(pid_of, [(1,), (2,)])) == {os.getpid()}
        assert list(pool.unordered(pid_of, [1, 2])) == [os.getpid()] * 2


def test_work_started_now_is_collected_later_in_order():
    """``start`` hands the work out at once on workers; with one job it is done only when the
    results are asked for (a diagnosis scans for modes meanwhile)."""
    with LocalExecutor(2) as pool:
        pending = pool.start(pid_of, [(i,) for i in range(6)])
        later = pool.start(operator.mul, [(i, 2) for i in range(6)])
        assert os.getpid() not in set(pending())
        assert later() == [2 * i for i in range(6)]
    calls: list[int] = []
    with LocalExecutor(1) as pool:
        pending = pool.start(calls.append, [(1,), (2,), (3,)])
        assert calls == []
        assert pending() == [None] * 3 and calls == [1, 2, 3]


@pytest.mark.parametrize("address", ["localhost:8786", "tcp://:8786", "tcp://host:0",
                                     "tcp://host:70000", "http://host:8786", "tcp://a b:1"])
def test_bad_scheduler_address_is_refused(address):
    with pytest.raises(InputError, match="scheduler address"):
        check_scheduler(address)


def test_report_with_bad_scheduler_gives_one_line(tmp_path, capsys):
    status = main(["report", str(tmp_path / "none.h5"), "--scheduler", "localhost"])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2
    assert len(err) == 1 and "--scheduler" in err[0]


def test_dask_cluster_runs_the_same_work():
    distributed = pytest.importorskip("distributed")
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                       host="127.0.0.1", protocol="tcp://",
                                       dashboard_address="127.0.0.1:0")
    with cluster, executor(scheduler=cluster.scheduler_address) as pool:
        assert isinstance(pool, DaskExecutor)
        assert pool.workers == 2
        assert pool.map(operator.mul, [(i, 3) for i in range(10)]) == [3 * i for i in range(10)]
        pending = pool.start(operator.add, [(i, 1) for i in range(5)])
        assert pending() == [1, 2, 3, 4, 5]
        assert sorted(pool.unordered(abs, range(-3, 3))) == [0, 1, 1, 2, 2, 3]


def test_no_scheduler_listening_is_one_clear_error(monkeypatch):
    pytest.importorskip("distributed")
    import socket

    import viscorig.executor

    monkeypatch.setattr(viscorig.executor, "CONNECT_TIMEOUT_S", 0.5)

    with socket.socket() as probe:  # a free loopback port nobody listens on
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    with pytest.raises(InputError, match="no Dask scheduler answers"):
        DaskExecutor(f"tcp://127.0.0.1:{port}")
