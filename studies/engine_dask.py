"""The Dask executor of the study engine: address check, connection, task stream.

The scheduler address is parsed before any connection is tried, so a typo is
a one-line error naming the expected form rather than a timeout. Tasks are
:func:`repertoire.studies.engine_pool.run_task` calls with plain arguments;
a bounded window of submitted seeds keeps the scheduler's load flat. dask is
imported only when a study runs on it.
"""

import re
import threading
from collections.abc import Iterator
from typing import Any

from repertoire.studies.engine_pool import EpisodeError, run_task

from repertoire.errors import RepertoireError

DASK_CONNECT_TIMEOUT_S = 3.0
CONNECT_GRACE_S = 2.0  # past the Client's own timeout, before a connection is given up
WINDOW_PER_WORKER = 4  # seeds submitted ahead per worker thread


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


def iter_dask(client, module: str, name: str, config_json: str, seeds: list[int]) -> Iterator[dict]:
    import uuid

    from distributed import as_completed

    token = uuid.uuid4().hex[:8]
    todo = iter(seeds)
    seed_of: dict = {}
    threads = sum(client.nthreads().values()) or 1
    window = max(64, threads * WINDOW_PER_WORKER)
    ac = as_completed(loop=client.loop)

    def submit_next() -> None:
        seed = next(todo, None)
        if seed is not None:
            key = f"{name}-{token}-{seed}"
            fut = client.submit(run_task, module, name, config_json, seed, key=key, pure=False)
            seed_of[fut] = seed
            ac.add(fut)

    try:
        # A bounded window of submitted seeds keeps the scheduler's load flat.
        for _ in range(window):
            submit_next()
        for fut in ac:
            try:
                result = fut.result()
            except Exception as e:  # KilledWorker, lost scheduler, ...
                raise EpisodeError(
                    f"study '{name}': the Dask cluster could not run seed {seed_of[fut]} "
                    f"({type(e).__name__}: {e}); finished episodes are stored, rerun to resume"
                ) from e
            del seed_of[fut]
            submit_next()
            yield result
    finally:
        client.cancel(list(seed_of))
