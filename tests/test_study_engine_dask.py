"""The study engine's Dask executor: a scheduler that is not there, not a scheduler,
without workers, or whose workers all leave mid-run is a one-line error within its
timeout, not a hang (a worker that joins meanwhile runs the seeds), and writes no store."""

import contextlib
import re
import signal
import socket
import time

import pytest
from repertoire.studies.engine import run_study, study_names
from repertoire.studies.pendulum import smoke_config

from repertoire.errors import RepertoireError


@pytest.fixture(autouse=True, scope="module")
def _studies_imported():
    """Imports the study modules before any test's hang alarm: under load that takes
    longer than the alarm, which would then interrupt an import (the registry reports
    the module as failed and leaves it out)."""
    study_names()


def _kw(tmp_path):
    return dict(store=tmp_path / "s.sqlite", out_dir=tmp_path / "out_s", progress=False)


@contextlib.contextmanager
def _no_hang(seconds: int, what: str):
    """Fails the test if its body takes more than ``seconds`` (a SIGALRM on the main thread).

    Not a helper thread: a pydrake Meshcat left by an earlier test in this worker
    would be garbage-collected there, and Drake aborts when a Meshcat is destroyed
    off the thread that made it.
    """

    def hung(signum, frame):
        raise AssertionError(f"run_study hung on {what}")

    previous = signal.signal(signal.SIGALRM, hung)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


def _run_on(address: str, tmp_path, **timeout) -> None:
    """Two pendulum episodes on the Dask scheduler at ``address`` (``dask_timeout_s=``)."""
    run_study(
        "pendulum",
        smoke_config(),
        episodes=2,
        executor="dask",
        scheduler_address=address,
        **timeout,
        **_kw(tmp_path),
    )


def test_unreachable_dask_scheduler_fails_fast_and_names_the_address(tmp_path):
    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    address = f"tcp://127.0.0.1:{port}"

    with _no_hang(30, "an unreachable scheduler"), pytest.raises(RepertoireError) as error:
        _run_on(address, tmp_path)
    assert f"Dask scheduler at '{address}'" in str(error.value)
    assert not (tmp_path / "s.sqlite").exists()


def test_a_port_that_is_not_a_dask_scheduler_is_a_clear_error_not_a_hang(tmp_path):
    # Something listens but never speaks Dask (as the scheduler's dashboard port 8787
    # next to its 8786): the Client's own timeout does not cover its handshake.
    with _no_hang(30, "a port that is not a Dask scheduler"):
        with socket.socket() as listener:
            listener.bind(("127.0.0.1", 0))
            listener.listen()  # connections complete in the backlog, nothing answers
            address = f"tcp://127.0.0.1:{listener.getsockname()[1]}"
            with pytest.raises(RepertoireError) as error:
                _run_on(address, tmp_path, dask_timeout_s=0.5)
    assert str(error.value) == (
        f"could not connect to the Dask scheduler at '{address}' within 0.5 s (TimeoutError: "
        "no Dask handshake in 2.5 s: something else listens there (a dashboard?)); start one "
        "with `dask scheduler` and `dask worker <address>`, or use --executor process"
    )
    assert not (tmp_path / "s.sqlite").exists()


def test_a_dask_scheduler_without_workers_is_a_clear_error_not_a_hang(tmp_path):
    distributed = pytest.importorskip("distributed", reason="dask.distributed not installed")
    with distributed.LocalCluster(
        n_workers=0, processes=False, dashboard_address=None, protocol="tcp://"
    ) as cluster:  # a scheduler alone: it would take the seeds and never run one
        address = cluster.scheduler_address
        with _no_hang(30, "a scheduler without workers"), pytest.raises(RepertoireError) as error:
            _run_on(address, tmp_path, dask_timeout_s=0.5)
    assert str(error.value) == (
        f"the Dask scheduler at '{address}' has no workers (none joined within 0.5 s), so "
        f"no episode would run; start one with `dask worker {address}`, or use --executor process"
    )
    assert not (tmp_path / "s.sqlite").exists()


def _quick_task(module: str, name: str, config_json: str, seed: int) -> dict:
    """A stand-in for an episode's task (what ``run_task`` returns for ``seed``), instant."""
    return {"seed": seed, "record": {}, "episode_s": 0.0, "cpu_s": 0.0, "worker": 0}


@contextlib.contextmanager
def _one_worker_cluster():
    """A scheduler with one in-process worker, its cluster and a client."""
    distributed = pytest.importorskip("distributed", reason="dask.distributed not installed")
    with distributed.LocalCluster(
        n_workers=1,
        threads_per_worker=1,
        processes=False,
        dashboard_address=None,
        protocol="tcp://",
    ) as cluster:
        with distributed.Client(cluster, set_as_default=False) as client:
            yield cluster, client


def _scale_to(cluster, client, n: int) -> None:
    """Scales ``cluster`` to ``n`` workers and waits until the scheduler has ``n``."""
    cluster.scale(n)
    while len(client.nthreads()) != n:
        time.sleep(0.05)


def test_every_dask_worker_leaving_mid_run_is_a_clear_error_not_a_hang(monkeypatch):
    from repertoire.studies import engine_dask
    from repertoire.studies.engine_pool import EpisodeError

    monkeypatch.setattr(engine_dask, "run_task_pinned", _quick_task)
    seeds = list(range(150))  # more than the window: some are submitted after workers left
    with _no_hang(120, "every worker leaving mid-run"), _one_worker_cluster() as (cluster, client):
        results = engine_dask.iter_dask(client, "m", "pendulum", "{}", seeds, worker_wait_s=0.5)
        got = [next(results)["seed"]]
        _scale_to(cluster, client, 0)  # every worker leaves; seeds are left on the scheduler
        with pytest.raises(EpisodeError) as error:
            got.extend(r["seed"] for r in results)
        address = cluster.scheduler_address
    m = re.fullmatch(
        r"study 'pendulum': no Dask worker for 0\.5 s \(every worker left\) with (\d+) seeds "
        r"left to run; finished episodes are stored; start `dask worker (\S+)` and rerun to "
        r"resume",
        str(error.value),
    )
    assert m is not None, str(error.value)
    assert m.group(2) == address
    # every seed was either yielded (once) or is counted as left
    assert len(set(got)) == len(got) and int(m.group(1)) == len(seeds) - len(got) > 0


def test_seeds_resume_on_a_worker_that_joins_after_every_worker_left(monkeypatch):
    from repertoire.studies import engine_dask

    monkeypatch.setattr(engine_dask, "run_task_pinned", _quick_task)
    seeds = list(range(150))
    with _no_hang(120, "a worker rejoining"), _one_worker_cluster() as (cluster, client):
        results = engine_dask.iter_dask(client, "m", "pendulum", "{}", seeds, worker_wait_s=30.0)
        got = [next(results)["seed"]]
        _scale_to(cluster, client, 0)
        _scale_to(cluster, client, 1)  # a worker elsewhere takes the waiting seeds
        got.extend(r["seed"] for r in results)
    assert sorted(got) == seeds


@pytest.mark.parametrize("bad", [0, -1.0, float("nan"), float("inf"), "60", True])
def test_a_bad_dask_worker_wait_is_a_clear_error_before_any_connection(tmp_path, bad):
    with pytest.raises(RepertoireError) as error:
        _run_on("tcp://127.0.0.1:1", tmp_path, dask_worker_wait_s=bad)
    assert str(error.value) == (
        f"--dask-worker-wait (dask_worker_wait_s) must be a finite number of seconds > 0, "
        f"got {bad!r}"
    )
    assert not (tmp_path / "s.sqlite").exists()


def _cli(tmp_path, *extra: str) -> list[str]:
    return ["--smoke", "-n", "2", "--store", str(tmp_path / "s.sqlite"), "--no-progress", *extra]


def test_the_command_line_sets_the_dask_worker_wait(tmp_path, monkeypatch):
    # was a run_study argument only: `--dask-worker-wait` was an unrecognized argument
    import argparse

    from repertoire.studies import engine

    class StopError(Exception):
        """Ends the run once run_study has been called."""

    calls = []

    def fake_run_study(*args, **kwargs):
        calls.append(kwargs)
        raise StopError

    monkeypatch.setattr(engine, "run_study", fake_run_study)
    parser = argparse.ArgumentParser()
    engine.add_study_arguments(parser, with_name=False)
    dask = ["--executor", "dask", "--scheduler", "tcp://127.0.0.1:8786"]
    for extra in ([*dask, "--dask-worker-wait", "300"], dask):
        with pytest.raises(StopError):
            engine.run_study_from_args(parser.parse_args(_cli(tmp_path, *extra)), "pendulum")
    assert calls[0]["dask_worker_wait_s"] == 300.0
    assert "dask_worker_wait_s" not in calls[1]  # run_study's default, DASK_WORKER_WAIT_S
    with pytest.raises(SystemExit):  # not a number: argparse's usage error (exit 2)
        parser.parse_args(_cli(tmp_path, *dask, "--dask-worker-wait", "5min"))


@pytest.mark.parametrize(
    "extra, message",
    [
        (
            ["--executor", "dask", "--scheduler", "tcp://127.0.0.1:1", "--dask-worker-wait", "0"],
            "error: --dask-worker-wait (dask_worker_wait_s) must be a finite number of seconds "
            "> 0, got 0.0",
        ),
        (
            ["--executor", "dask", "--scheduler", "tcp://127.0.0.1:1", "--dask-worker-wait", "nan"],
            "error: --dask-worker-wait (dask_worker_wait_s) must be a finite number of seconds "
            "> 0, got nan",
        ),
        (
            ["--executor", "inline", "--dask-worker-wait", "5"],
            "error: --dask-worker-wait is only used with --executor dask (the other executors "
            "run their own workers)",
        ),
    ],
)
def test_a_bad_dask_worker_wait_on_the_command_line_exits_2_before_any_work(
    tmp_path, capsys, extra, message
):
    from repertoire.studies.engine import study_main

    assert study_main("pendulum", _cli(tmp_path, *extra)) == 2
    assert capsys.readouterr().err == message + "\n"
    assert not (tmp_path / "s.sqlite").exists()


def _failing_task(module: str, name: str, config_json: str, seed: int) -> dict:
    """A task that fails on the cluster itself (as a KilledWorker does), not in the episode."""
    raise OSError(f"worker gone on seed {seed}")


def test_a_task_that_fails_on_the_cluster_names_its_seed(monkeypatch):
    from repertoire.studies import engine_dask
    from repertoire.studies.engine_pool import EpisodeError

    monkeypatch.setattr(engine_dask, "run_task_pinned", _failing_task)
    with _no_hang(120, "a failing task"), _one_worker_cluster() as (_, client):
        with pytest.raises(EpisodeError) as error:
            list(engine_dask.iter_dask(client, "m", "pendulum", "{}", [7], worker_wait_s=30.0))
    assert str(error.value) == (
        "study 'pendulum': the Dask cluster could not run seed 7 (OSError: worker gone on "
        "seed 7); finished episodes are stored, rerun to resume"
    )


_THREADED_BLAS_STUDY = """
import dataclasses
import threading

from threadpoolctl import threadpool_info

from repertoire.studies.engine import register_study

A_IN, B_IN = threading.Event(), threading.Event()


@dataclasses.dataclass
class Config:
    pass


@dataclasses.dataclass
class Record:
    most_blas_threads: int


def run_episode(config, seed):
    if seed == 0:  # the first episode: in, then out while the second is still running
        A_IN.set()
        B_IN.wait(10)
    else:
        B_IN.set()
        A_OUT.wait(10)
    blas = [lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"]
    return Record(max(blas))


A_OUT = threading.Event()
register_study("_threaded_blas", config_type=Config, record_type=Record,
               run_episode=run_episode, description="test-only")
"""

_TWO_THREADS = """
import threading, sys
import threaded_blas_study as s
from repertoire.studies.engine_pool import run_task_pinned

out = {}
def first():
    out[0] = run_task_pinned("threaded_blas_study", "_threaded_blas", "{}", 0)
    s.A_OUT.set()
def second():
    s.A_IN.wait(10)
    out[1] = run_task_pinned("threaded_blas_study", "_threaded_blas", "{}", 1)
threads = [threading.Thread(target=first), threading.Thread(target=second)]
for t in threads: t.start()
for t in threads: t.join(20)
print([out[i]["record"]["most_blas_threads"] for i in (0, 1)])
"""


def test_episodes_in_two_threads_of_one_dask_worker_both_run_with_one_blas_thread(tmp_path):
    # A worker with two threads and no nanny (whose OMP_NUM_THREADS=1 hid it): the first
    # episode's one_blas_thread put the BLAS's two threads back when it ended, under the
    # second, still running (measured: 1 of 12 and 3 of 8 episodes ran with two).
    import os
    import subprocess
    import sys

    (tmp_path / "threaded_blas_study.py").write_text(_THREADED_BLAS_STUDY)
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "2", "OMP_NUM_THREADS": "2"}
    env["PYTHONPATH"] = os.pathsep.join([str(tmp_path), *sys.path])
    out = subprocess.run(
        [sys.executable, "-P", "-c", _TWO_THREADS],
        env=env,
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout == "[1, 1]\n"
