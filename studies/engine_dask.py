"""The Dask executor of the study engine: address check, connection, task stream.

The scheduler address is parsed before any connection is tried, so a typo is
a one-line error naming the expected form rather than a timeout. Tasks are
:func:`repertoire.studies.engine_pool.run_task_pinned` calls with plain arguments;
a bounded window of submitted seeds keeps the scheduler's load flat. When every
worker has left mid-run the seeds wait on the scheduler for one to join (they
resume there); after ``worker_wait_s`` without one the run stops with a one-line
error (finished episodes stay stored). dask is imported only when a study runs on it.
"""

import math
import numbers
import re
import threading
import time
from collections.abc import Iterator
from typing import Any

from repertoire.studies.engine_pool import EpisodeError, run_task_pinned

from repertoire.errors import RepertoireError

DASK_CONNECT_TIMEOUT_S = 3.0
CONNECT_GRACE_S = 2.0  # past the Client's own timeout, before a connection is given up
WINDOW_PER_WORKER = 4  # seeds submitted ahead per worker thread
# How long seeds wait for a worker when every worker has left mid-run (one may rejoin,
# e.g. a restarted machine), before the run stops; the poll is a quarter of it, at most 1 s.
DASK_WORKER_WAIT_S = 60.0
IDLE_POLL_S = 0.02  # sleep between looks at finished seeds while none is


_ADDRESS = re.compile(r"^(tcp|tls|ws|wss|ucx)://(\[[0-9a-fA-F:]+\]|[A-Za-z0-9._-]+):(\d{1,5})$")


def parse_scheduler_address(address: Any) -> str:
    """Checks a Dask scheduler address before any connection is tried.

    Args:
        address: ``PROTOCOL://HOST:PORT`` with PROTOCOL tcp, tls, ws, wss or ucx
            and PORT in 1..65535, for example ``tcp://127.0.0.1:8786``.

    Returns:
        The address.

    Raises:
        RepertoireError: a missing or malformed address (says what is expected).
    """
    example = "expected PROTOCOL://HOST:PORT, e.g. tcp://127.0.0.1:8786"
    if not isinstance(address, str) or not address:
        raise RepertoireError(
            f"--executor dask needs --scheduler (scheduler_address); {example}; got "
            + ("none" if address is None else repr(address))
        )
    m = _ADDRESS.match(address)
    if m is None or not 1 <= int(m.group(3)) <= 65535:
        raise RepertoireError(f"--scheduler {address!r} is not a Dask address; {example}")
    return address


def check_wait_s(label: str, value: Any) -> float:
    """``value`` as a float number of seconds, finite and > 0, or an error naming ``label``."""
    if (
        isinstance(value, bool)
        or not isinstance(value, numbers.Real)
        or not math.isfinite(value)
        or value <= 0
    ):
        raise RepertoireError(f"{label} must be a finite number of seconds > 0, got {value!r}")
    return float(value)


def connect_dask(scheduler_address: str, timeout_s: float = DASK_CONNECT_TIMEOUT_S):
    """Connects a ``dask.distributed.Client`` to a scheduler, failing fast.

    Args:
        scheduler_address: e.g. ``tcp://10.0.0.5:8786``.
        timeout_s: how long to wait for the connection, and then for a worker.

    Raises:
        RepertoireError: dask.distributed is not installed, the scheduler is
            not reachable within ``timeout_s``, or no worker joined it within
            ``timeout_s`` (names the address).
    """
    scheduler_address = parse_scheduler_address(scheduler_address)
    try:
        from distributed import Client
    except ImportError as e:
        raise RepertoireError(
            "--executor dask (executor='dask') needs dask.distributed: "
            "pip install 'repertoire[dask]'"
        ) from e
    try:
        client = _client_within(Client, scheduler_address, timeout_s)
    except Exception as e:
        raise RepertoireError(
            f"could not connect to the Dask scheduler at '{scheduler_address}' within "
            f"{timeout_s:g} s ({type(e).__name__}: {e}); start one with `dask scheduler` "
            "and `dask worker <address>`, or use --executor process"
        ) from e
    try:  # a scheduler without workers would take the seeds and never run one
        client.wait_for_workers(1, timeout=timeout_s)
    except Exception as e:  # TimeoutError (dask's own in some versions)
        client.close()
        raise RepertoireError(
            f"the Dask scheduler at '{scheduler_address}' has no workers (none joined within "
            f"{timeout_s:g} s), so no episode would run; start one with "
            f"`dask worker {scheduler_address}`, or use --executor process"
        ) from e
    return client


def _client_within(client_type: Any, address: str, timeout_s: float):
    """``client_type(address)`` connected within ``timeout_s`` (plus a grace), or an error.

    The Client's own timeout covers a port where nothing listens, but not one
    where something else does (the scheduler's dashboard, 8787 by default, next
    to the scheduler's 8786): its handshake then waits forever. The connection
    is made on a helper thread and given up on after the deadline; a client that
    connects after that is closed.
    """
    outcome: dict[str, Any] = {}
    given_up = threading.Event()

    def connect() -> None:
        try:
            client = client_type(address, timeout=f"{timeout_s}s", set_as_default=False)
        except Exception as e:  # noqa: BLE001  (re-raised on the caller's thread)
            outcome["error"] = e
            return
        if given_up.is_set():
            client.close()
        else:
            outcome["client"] = client

    thread = threading.Thread(target=connect, name="dask-connect", daemon=True)
    thread.start()
    thread.join(timeout_s + CONNECT_GRACE_S)
    if thread.is_alive():
        given_up.set()
        if "client" not in outcome:
            raise TimeoutError(
                f"no Dask handshake in {timeout_s + CONNECT_GRACE_S:g} s: something "
                "else listens there (a dashboard?)"
            )
    if "error" in outcome:
        raise outcome["error"]
    return outcome["client"]


def _no_worker_reason(client) -> str | None:
    """None when the scheduler has a worker, else why no episode can run now.

    A scheduler that is gone fails within dask's connect timeout; a slow answer
    (a busy event loop) is not taken for no worker.
    """
    try:
        threads = client.nthreads()
    except Exception as e:  # noqa: BLE001  (a lost scheduler: counted as no worker)
        return f"the scheduler did not answer: {type(e).__name__}"
    return None if threads else "every worker left"


def iter_dask(
    client,
    module: str,
    name: str,
    config_json: str,
    seeds: list[int],
    worker_wait_s: float = DASK_WORKER_WAIT_S,
) -> Iterator[dict]:
    """Runs ``seeds`` on the Dask cluster of ``client``, yielding each record as it finishes.

    Args:
        client: a connected ``dask.distributed.Client``.
        module: the study's module (imported by the workers).
        name: the study's name.
        config_json: the study's config as canonical JSON.
        seeds: the seeds to run.
        worker_wait_s: how long unfinished seeds may wait with no worker on the
            scheduler (every worker left) before the run stops.

    Raises:
        EpisodeError: a seed's task failed on the cluster (KilledWorker, ...), or
            no worker was there for ``worker_wait_s`` with seeds left to run
            (names the wait, the seeds left and the scheduler).
    """
    import uuid

    from distributed import as_completed

    worker_wait_s = check_wait_s("worker_wait_s", worker_wait_s)
    poll_s = min(1.0, worker_wait_s / 4)
    token = uuid.uuid4().hex[:8]
    todo = iter(seeds)
    seed_of: dict = {}
    threads = sum(client.nthreads().values()) or 1
    window = max(64, threads * WINDOW_PER_WORKER)
    # with_results: a result is gathered on dask's event loop, so one that left with its
    # worker (the task runs again) waits there, never on this thread
    ac = as_completed(loop=client.loop, with_results=True, raise_errors=False)

    def submit_next() -> None:
        seed = next(todo, None)
        if seed is not None:
            key = f"{name}-{token}-{seed}"
            fut = client.submit(
                run_task_pinned, module, name, config_json, seed, key=key, pure=False
            )
            seed_of[fut] = seed
            ac.add(fut)

    try:
        # A bounded window of submitted seeds keeps the scheduler's load flat.
        for _ in range(window):
            submit_next()
        last_check = time.monotonic()
        no_worker_since = None  # monotonic time the scheduler was first seen without one
        while seed_of:
            batch = ac.next_batch(block=False)
            for fut, result in batch:
                # run_task returns a dict; anything else is how dask says the task failed
                # (KilledWorker, cancelled, lost scheduler, ...). Not fut.status: a result
                # in hand whose worker left since is "lost" there, and runs again.
                if not isinstance(result, dict):
                    error = result[1] if isinstance(result, tuple) else result
                    raise EpisodeError(
                        f"study '{name}': the Dask cluster could not run seed {seed_of[fut]} "
                        f"({type(error).__name__}: {error}); finished episodes are stored, "
                        "rerun to resume"
                    )
                del seed_of[fut]
                submit_next()
                yield result
            now = time.monotonic()
            if batch:
                last_check, no_worker_since = now, None
                continue
            time.sleep(IDLE_POLL_S)
            if now - last_check < poll_s:
                continue
            last_check = now
            why = _no_worker_reason(client)
            if why is None:
                no_worker_since = None
                continue
            no_worker_since = now if no_worker_since is None else no_worker_since
            if now - no_worker_since >= worker_wait_s:
                left = len(seed_of) + sum(1 for _ in todo)
                raise EpisodeError(
                    f"study '{name}': no Dask worker for {worker_wait_s:g} s ({why}) with "
                    f"{left} seeds left to run; finished episodes are stored; start "
                    f"`dask worker {client.scheduler.address}` and rerun to resume"
                )
    finally:
        client.cancel(list(seed_of))
