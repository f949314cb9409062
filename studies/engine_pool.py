"""How the study engine runs episodes: the per-episode task, inline, and a local worker pool.

:func:`run_task` is the one function every executor runs for a seed (in this
process, in a pool worker, on a Dask worker). It takes and returns plain data:
``(module name, study name, config JSON, seed)`` in, a dict out, with the
record, the episode's wall time ``episode_s`` and its CPU time ``cpu_s``.

:class:`WorkerPool` is the local process pool. Its workers are forked from
multiprocessing's fork server, which imports pydrake once (``PRELOAD``) and
stays up for the life of this process: the first pool of a process pays one
pydrake import (started in a background thread, so it overlaps whatever the
caller does meanwhile, such as opening the store), later pools start in
milliseconds. Where there is no fork server, workers are spawned. Seeds go to
each worker over its own pipe, a few ahead of the one it runs, and come back
one result per seed in order, so the pool always knows which seed a worker was
running: a worker that dies (segfault, out-of-memory kill) costs exactly that
seed, reported as a ``"crash"`` result with the exit code; its queued seeds go
to the other workers and a fresh worker takes its place.

This module imports neither pydrake nor dask at import time.
"""

import collections
import contextlib
import multiprocessing
import os
import signal
import socket
import sys
import threading
import time
import traceback
from collections.abc import Iterator
from multiprocessing.connection import wait as wait_for
from typing import Any

from repertoire.studies.registry import lookup_in_module
from repertoire.studies.store import config_from_json, to_plain

from repertoire.errors import RepertoireError
from repertoire.interrupts import check_interrupted, sigint_blocked

# Imported once by the fork server, before it forks any worker.
PRELOAD = (
    "numpy",
    "repertoire.studies.engine",
    "pydrake.systems.framework",
    "pydrake.systems.analysis",
    "pydrake.multibody.plant",
)
SEEDS_AHEAD = 2  # seeds a worker holds: the one it runs and the next
STOP_TIMEOUT_S = 5.0
MAX_LOST_STARTS = 5


class EpisodeError(RuntimeError):
    """``run_episode`` failed for some seed (raised, or killed its worker); says which."""


# ---------------------------------------------------------------------------
# The task.

_CONFIG_CACHE: dict[tuple[str, str], Any] = {}


_ONE_THREAD_DEPTH = 0  # one_blas_thread contexts open in this process


@contextlib.contextmanager
def one_blas_thread() -> Iterator[None]:
    """A context in which every BLAS and OpenMP thread pool of this process has one thread.

    Each episode runs in it, whatever the executor. A BLAS with several threads
    splits its sums among them, so the same episode computed with two threads
    (an inline run on a two-core machine) and with one (a Dask worker, which
    sets ``OMP_NUM_THREADS=1``) differs in the last bits, and a count decided
    by a threshold can then differ too (``littledog_transfer_matching``, seed
    12345: 45 placements with two BLAS threads, 43 with one). numpy and
    scipy.linalg are imported first so that their BLAS libraries are loaded and
    limited; the previous limits come back on exit. Setting the limits costs
    about 0.7 ms (threadpoolctl reads the loaded libraries), so inline runs and
    pool workers open one context for all their seeds and the per-episode one
    inside it costs nothing.
    """
    global _ONE_THREAD_DEPTH
    if _ONE_THREAD_DEPTH:
        yield
        return
    import numpy  # noqa: F401  (loads numpy's BLAS)
    import scipy.linalg  # noqa: F401  (loads scipy's BLAS)
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):
        _ONE_THREAD_DEPTH += 1
        try:
            yield
        finally:
            _ONE_THREAD_DEPTH -= 1


def run_task(module: str, name: str, config_json: str, seed: int) -> dict[str, Any]:
    """Runs one episode.

    Returns:
        ``{"seed", "record", "episode_s", "cpu_s", "worker"}``, or
        ``{"seed", "error", "message"[, "traceback"]}`` when it failed, with
        ``error`` one of ``"record_type"``, ``"repertoire"``, ``"exception"``.
    """
    try:
        entry = lookup_in_module(module, name)
        key = (name, config_json)
        config = _CONFIG_CACHE.get(key)
        if config is None:
            config = config_from_json(entry.config_type, config_json)
            _CONFIG_CACHE.clear()
            _CONFIG_CACHE[key] = config
        with one_blas_thread():
            t0, c0 = time.perf_counter(), time.process_time()
            record = entry.run_episode(config, seed)
        episode_s, cpu_s = time.perf_counter() - t0, time.process_time() - c0
        if type(record) is not entry.record_type:
            return {
                "seed": seed,
                "error": "record_type",
                "message": (
                    f"study '{name}': run_episode(config, seed={seed}) returned "
                    f"{type(record).__module__}.{type(record).__qualname__}, expected the "
                    f"registered record_type {entry.record_type.__module__}."
                    f"{entry.record_type.__qualname__}"
                ),
            }
        plain = to_plain(record, f"{entry.record_type.__name__}(seed={seed})")
        return {
            "seed": seed,
            "record": plain,
            "episode_s": episode_s,
            "cpu_s": cpu_s,
            "worker": f"{socket.gethostname()}:{os.getpid()}",
        }
    except RepertoireError as e:
        return {
            "seed": seed,
            "error": "repertoire",
            "message": str(e),
            "traceback": traceback.format_exc(),
        }
    except (Exception, SystemExit) as e:  # sys.exit() in an episode: its error, not ours
        message = f"{type(e).__name__}: {e}"
        if isinstance(e, SystemExit):
            message = f"SystemExit({e.code!r}): the episode tried to exit the process"
        return {
            "seed": seed,
            "error": "exception",
            "message": message,
            "traceback": traceback.format_exc(),
        }


_BLAS_PINNED = False  # this process's BLAS is held to one thread for good (a Dask worker)
_BLAS_PIN_LOCK = threading.Lock()


def run_task_pinned(module: str, name: str, config_json: str, seed: int) -> dict[str, Any]:
    """:func:`run_task` in a process whose BLAS is held to one thread for the rest of its life.

    The task Dask runs. A Dask worker runs as many episodes at once as it has threads,
    and :func:`one_blas_thread` cannot hold them there: the limits are per process, one
    episode's context puts them back when it ends while another runs, and threadpoolctl
    lets only one thread set OpenBLAS's limit (the others' calls do nothing). A Dask
    nanny starts its workers with ``OMP_NUM_THREADS=1``; a worker started without one
    (``dask worker --no-nanny --nthreads 2``) ran some episodes with two BLAS threads.
    The first task in a worker now sets one thread for good, as the nanny would.
    """
    global _BLAS_PINNED
    with _BLAS_PIN_LOCK:
        if not _BLAS_PINNED:
            import numpy  # noqa: F401  (loads numpy's BLAS)
            import scipy.linalg  # noqa: F401  (loads scipy's BLAS)
            from threadpoolctl import threadpool_limits

            threadpool_limits(limits=1)  # never put back: the worker only runs episodes
            _BLAS_PINNED = True
    return run_task(module, name, config_json, seed)


def raise_task_error(name: str, result: dict[str, Any]) -> None:
    """Raises the error a failed :func:`run_task` result stands for."""
    seed = result["seed"]
    if result["error"] == "record_type":
        raise RepertoireError(result["message"])
    if result["error"] == "repertoire":
        raise RepertoireError(f"study '{name}', seed {seed}: {result['message']}")
    raise EpisodeError(
        f"study '{name}': run_episode failed for seed {seed}: {result['message']}\n"
        f"worker traceback:\n{result['traceback']}"
        "Episodes finished before the failure are stored; rerun to resume."
    )


def iter_inline(module: str, name: str, config_json: str, seeds: list[int]) -> Iterator[dict]:
    """Runs the seeds one after the other in this process (one BLAS thread for all)."""
    with one_blas_thread():
        for seed in seeds:
            check_interrupted()
            yield run_task(module, name, config_json, seed)


# ---------------------------------------------------------------------------
# Pool workers.


def _watch_parent(parent_pid: int) -> None:
    """Exits this worker when the engine's process is gone (e.g. SIGKILLed)."""
    while True:
        time.sleep(0.5)
        try:
            os.kill(parent_pid, 0)
        except ProcessLookupError:
            os._exit(1)
        except PermissionError:  # the pid now belongs to another user's process
            os._exit(1)


def _worker_main(
    conn, parent_pid: int, sys_path: list[str], module: str, name: str, config_json: str
) -> None:
    """A pool worker: runs the seed lists it receives, sends one result per seed, in order."""
    sys.path[:] = sys_path  # the fork server's path may predate the engine's additions
    # Ctrl-C reaches the whole process group: the engine alone handles it and stops the
    # workers (a KeyboardInterrupt traceback from every worker would bury its message).
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    threading.Thread(target=_watch_parent, args=(parent_pid,), daemon=True).start()
    try:
        lookup_in_module(module, name)  # import the study once, before the first seed
    except Exception:  # reported per seed by run_task, with its traceback
        pass
    try:
        conn.send({"ready": os.getpid()})  # from here on, a death is the running seed's
    except (BrokenPipeError, OSError):
        return
    with one_blas_thread():  # for the worker's life: its episodes' contexts cost nothing
        _serve(conn, module, name, config_json)


def _serve(conn, module: str, name: str, config_json: str) -> None:
    """The worker's loop: seed lists in, one result per seed out, until told to stop."""
    while True:
        try:
            seeds = conn.recv()
        except (EOFError, OSError):  # the engine is gone
            return
        if seeds is None:
            return
        for seed in seeds:
            result = run_task(module, name, config_json, seed)
            try:
                conn.send(result)
            except (BrokenPipeError, OSError):
                return


def pool_context():
    """The multiprocessing context of pool workers: the fork server where there is one.

    Workers are never forked from the engine's own process (pydrake and fork
    do not mix there); the fork server is a fresh interpreter that has only
    imported ``PRELOAD``.
    """
    if "forkserver" in multiprocessing.get_all_start_methods():
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(list(PRELOAD))
        return ctx
    return multiprocessing.get_context("spawn")


@contextlib.contextmanager
def _children_without_sigint() -> Iterator[None]:
    """A context in which the processes this thread starts block SIGINT for life.

    Only the engine takes Ctrl-C: see :func:`repertoire.interrupts.sigint_blocked`.
    The resource tracker is started first, outside: starting it unblocks SIGINT
    in the calling thread (it ignores SIGINT itself).
    """
    from multiprocessing import resource_tracker

    resource_tracker.ensure_running()
    with sigint_blocked():
        yield


def prestart_fork_server() -> threading.Thread | None:
    """Starts the fork server (and its pydrake import) in the background, if there is one.

    A command line calls this first thing, so that the server's imports overlap
    the caller's own (study discovery, config loading); the pool it later makes
    forks its workers at once.

    Returns:
        The thread doing it (None where workers are spawned).
    """
    ctx = pool_context()
    if ctx.get_start_method() != "forkserver":
        return None
    from multiprocessing import forkserver

    def start() -> None:
        with _children_without_sigint():
            forkserver.ensure_running()

    thread = threading.Thread(target=start, daemon=True)
    thread.start()
    return thread


def describe_exit(exitcode: int | None) -> str:
    """``-11`` -> ``'killed by signal SIGSEGV'``; ``3`` -> ``'exit code 3'``."""
    if exitcode is None:
        return "no exit code"
    if exitcode < 0:
        try:
            return f"killed by signal {signal.Signals(-exitcode).name}"
        except ValueError:
            return f"killed by signal {-exitcode}"
    return f"exit code {exitcode}"


class _Worker:
    def __init__(self, proc, conn):
        self.proc = proc
        self.conn = conn
        self.queued: collections.deque[int] = collections.deque()
        self.ready = False  # it said it is up (a death before that is no seed's fault)


class WorkerPool:
    """A local pool of worker processes for one study and config.

    Workers start in a background thread as soon as the pool is made, so the
    caller can do other work (open the store) meanwhile. Use :meth:`run` once,
    then :meth:`close` (or use it as a context manager).

    Args:
        module: the study's module.
        name: the study name.
        config_json: canonical JSON of the config.
        workers: the number of worker processes (>= 1).
    """

    def __init__(self, module: str, name: str, config_json: str, workers: int):
        if workers < 1:
            raise RepertoireError(f"workers must be >= 1, got {workers}")
        self._args = (module, name, config_json)
        self._n = workers
        self._ctx = pool_context()
        self._workers: list[_Worker] = []
        self._retired: list[_Worker] = []
        self._start_error: BaseException | None = None
        self._lock = threading.Lock()
        self._closed = False
        self._starter = threading.Thread(target=self._start_all, daemon=True)
        self._starter.start()

    def _start_one(self) -> _Worker:
        parent_conn, child_conn = self._ctx.Pipe(duplex=True)
        proc = self._ctx.Process(
            target=_worker_main,
            args=(child_conn, os.getpid(), list(sys.path), *self._args),
            daemon=True,
        )
        with _children_without_sigint():  # the fork server too, if this starts it
            proc.start()
        child_conn.close()  # only the worker holds its end: its death is EOF here
        return _Worker(proc, parent_conn)

    def _start_all(self) -> None:
        try:
            for _ in range(self._n):
                with self._lock:
                    if self._closed:
                        return
                    self._workers.append(self._start_one())
        except BaseException as e:
            self._start_error = e

    def _ready(self) -> None:
        self._starter.join()
        if self._start_error is not None:
            raise RepertoireError(
                f"could not start pool workers: {type(self._start_error).__name__}: "
                f"{self._start_error}"
            ) from self._start_error

    @property
    def size(self) -> int:
        """The number of workers asked for."""
        return self._n

    def run(self, seeds: list[int]) -> Iterator[dict]:
        """Yields one result dict per seed as episodes finish.

        A result is :func:`run_task`'s dict, or for a seed whose worker died
        ``{"seed", "error": "crash", "exitcode", "message", "worker"}``.
        """
        self._ready()
        if not seeds:
            return
        todo = collections.deque(seeds)
        keep = min(len(self._workers), len(seeds))
        for extra in self._workers[keep:]:
            self._stop(extra)  # not needed: asked to exit now, joined by close()
        self._retired += self._workers[keep:]
        self._workers = self._workers[:keep]
        lost_starts = 0  # workers in a row that died before taking a seed

        def feed(worker: _Worker) -> None:
            chunk = []
            # Near the end one seed each, so that no worker idles while another holds two.
            ahead = SEEDS_AHEAD if len(todo) >= SEEDS_AHEAD * len(self._workers) else 1
            while todo and len(worker.queued) + len(chunk) < ahead:
                chunk.append(todo.popleft())
            if not chunk:
                return
            try:
                worker.conn.send(chunk)
            except OSError:  # it died: none of these reached it; its sentinel tells the rest
                todo.extendleft(reversed(chunk))
                if not worker.queued:
                    lost(worker)
                return
            worker.queued.extend(chunk)

        def lost(worker: _Worker) -> None:
            """A worker died with no seed of ours running: count it, replace it."""
            nonlocal lost_starts
            lost_starts += 1
            if lost_starts > MAX_LOST_STARTS:
                raise RepertoireError(
                    f"pool workers keep dying before they run a seed ({lost_starts} in a row, "
                    f"the last {describe_exit(worker.proc.exitcode)}); each worker first runs "
                    "the main script's top level, so a script must call run_study under "
                    "`if __name__ == '__main__':`, and a script read from stdin cannot start "
                    "workers; use --executor inline (executor='inline') to see why"
                )
            self._replace(worker, True)

        while True:
            check_interrupted()
            for worker in list(self._workers):
                feed(worker)
            by_handle = {}
            for w in self._workers:
                if w.queued:
                    by_handle[w.conn] = w
                    by_handle[w.proc.sentinel] = w
            if not by_handle:
                if todo:  # every worker was replaced while feeding: feed the new ones
                    continue
                return
            ready = {id(by_handle[h]): by_handle[h] for h in wait_for(list(by_handle))}
            for worker in ready.values():
                results, crash, dead = self._collect(worker)
                if worker.ready:
                    lost_starts = 0
                if dead:
                    todo.extendleft(reversed(worker.queued))  # the others' turn, in order
                    worker.queued.clear()
                    if worker.ready:
                        self._replace(worker, bool(todo))
                    else:
                        lost(worker)
                else:
                    feed(worker)  # before the caller stores the results: no idle worker
                yield from results
                if crash is not None:
                    yield crash

    def _collect(self, worker: _Worker) -> tuple[list[dict], dict | None, bool]:
        """Reads what a worker sent: (results, the crash of the seed it ran or None, dead)."""
        alive = worker.proc.is_alive()  # first: a dead worker's last words are in the pipe
        results = []
        try:
            while worker.queued and worker.conn.poll():
                result = worker.conn.recv()
                if "ready" in result:
                    worker.ready = True
                    continue
                seed = worker.queued.popleft()
                if result.get("seed") != seed:  # a broken protocol, not an episode's fault
                    raise RepertoireError(
                        f"pool worker {worker.proc.pid} answered seed {result.get('seed')} "
                        f"for seed {seed}"
                    )
                results.append(result)
        except (EOFError, OSError):
            alive = False
        if alive:
            return results, None, False
        worker.proc.join(STOP_TIMEOUT_S)  # for its exit code
        if not worker.queued or not worker.ready:  # died with none of our seeds running
            return results, None, True
        seed = worker.queued.popleft()
        how = describe_exit(worker.proc.exitcode)
        crash = {
            "seed": seed,
            "error": "crash",
            "exitcode": worker.proc.exitcode,
            "worker": f"{socket.gethostname()}:{worker.proc.pid}",
            "message": f"worker process {worker.proc.pid} died ({how}) while running seed {seed}",
        }
        return results, crash, True

    def _replace(self, worker: _Worker, needed: bool) -> None:
        """Drops a dead worker; starts a fresh one in its place if seeds are left."""
        worker.conn.close()
        worker.proc.join(STOP_TIMEOUT_S)
        index = self._workers.index(worker)
        if needed:
            self._workers[index] = self._start_one()
        else:
            del self._workers[index]

    def _stop(self, worker: _Worker) -> None:
        try:
            worker.conn.send(None)
        except (BrokenPipeError, OSError):
            pass

    def close(self, *, abort: bool = False) -> None:
        """Stops the workers: asks them to exit (``abort``: terminates them at once)."""
        with self._lock:
            self._closed = True
        self._starter.join()
        for worker in self._workers:
            if abort:
                worker.proc.terminate()
            else:
                self._stop(worker)
        deadline = time.monotonic() + STOP_TIMEOUT_S
        for worker in self._workers + self._retired:
            worker.proc.join(max(0.0, deadline - time.monotonic()))
            if worker.proc.is_alive():
                worker.proc.kill()
                worker.proc.join(1.0)
            worker.conn.close()
        self._workers, self._retired = [], []

    def __enter__(self) -> "WorkerPool":
        return self

    def __exit__(self, exc_type, *exc) -> None:
        self.close(abort=exc_type is not None)
