"""The study engine's Dask executor: a scheduler that is not there, not a scheduler, or
without workers is a one-line error within the timeout, not a hang, and writes no store."""

import contextlib
import signal
import socket

import pytest
from repertoire.studies.engine import run_study
from repertoire.studies.pendulum import smoke_config

from repertoire.errors import RepertoireError


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
