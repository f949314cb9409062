"""The Monte-Carlo study engine: run N seeds of a registered study, store, summarize.

A study (see :mod:`repertoire.studies.registry`) is a config dataclass, a record
dataclass and a module-level ``run_episode(config, seed)`` that builds its own
diagram. :func:`run_study` runs the seeds ``first_seed .. first_seed+episodes-1``

- ``executor="inline"``: in this process;
- ``executor="process"``: on a local pool of ``workers`` spawned processes
  (default: all cores);
- ``executor="dask"``: on a Dask distributed cluster at ``scheduler_address``,

and writes every record to an SQLite store the moment it finishes (see
:mod:`repertoire.studies.store`); a rerun runs only the missing seeds. Workers
receive only ``(module name, study name, config JSON, seed)`` and send back
plain dicts: nothing from pydrake is pickled, every worker rebuilds the study
from the config. Records are identical whatever the executor or worker count
(fields named ``wall*_s`` are timing fields and excepted).

At the end the engine writes ``summary.csv``, ``summary.md`` and
``episodes.csv`` to ``out_dir``, plus the study's own figures (its
``summarize``), or one histogram per numeric field when it has none.

This module imports neither pydrake nor dask at import time.
"""

import argparse
import csv
import dataclasses
import json
import math
import multiprocessing
import os
import re
import socket
import sys
import threading
import time
import traceback
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from repertoire.studies.registry import (
    StudyEntry,
    get_study,
    lookup_in_module,
    register_study,
    study_names,
)
from repertoire.studies.store import (
    EpisodeStore,
    canonical_json,
    from_plain,
    read_store,
    to_plain,
)

from repertoire.errors import RepertoireError
from repertoire.limits import require_writable_dir, require_writable_file

__all__ = [
    "EXECUTORS",
    "EpisodeError",
    "StudyEntry",
    "StudyResult",
    "add_study_arguments",
    "comparable",
    "get_study",
    "is_timing_field",
    "load_records",
    "register_study",
    "run_study",
    "run_study_from_args",
    "study_main",
    "study_names",
]

EXECUTORS = ("inline", "process", "dask")
DASK_CONNECT_TIMEOUT_S = 3.0
WINDOW_PER_WORKER = 4  # seeds submitted ahead per worker


class EpisodeError(RuntimeError):
    """``run_episode`` raised for some seed; the message carries the worker's traceback."""


@dataclasses.dataclass
class StudyResult:
    """What :func:`run_study` returns.

    Attributes:
        name: the study name.
        config: the config the episodes ran with.
        records: the records of the requested seeds, sorted by seed.
        seeds: the requested seeds, in the order of ``records``.
        store: the SQLite store path.
        out_dir: the output folder.
        tables: ``{"summary.csv": path, "summary.md": path, "episodes.csv": path}``.
        figures: ``{label: png_path}``.
        elapsed_s: wall time of the whole call.
        n_run: episodes run by this call.
        n_reused: episodes found in the store.
        executor: the executor used.
        workers: worker processes used (1 for inline; None for dask).
    """

    name: str
    config: Any
    records: list
    seeds: list[int]
    store: Path
    out_dir: Path
    tables: dict[str, Path]
    figures: dict[str, Path]
    elapsed_s: float
    n_run: int
    n_reused: int
    executor: str
    workers: int | None


# Seeds are below this; ``load(0, STORE_SEED_LIMIT)`` is every stored seed.
STORE_SEED_LIMIT = 2**62


def is_timing_field(name: str) -> bool:
    """True for timing fields (``wall*_s``), which may differ between runs."""
    return name.startswith("wall") and name.endswith("_s")


def _nan_safe(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return repr(value)  # 'nan', 'inf', '-inf': equal to themselves
    if isinstance(value, list):
        return [_nan_safe(v) for v in value]
    if isinstance(value, dict):
        return {k: _nan_safe(v) for k, v in value.items()}
    return value


def comparable(record: Any) -> dict[str, Any]:
    """A record as plain data without its timing fields, for determinism checks.

    Non-finite floats become the strings ``'nan'``, ``'inf'``, ``'-inf'`` so that
    two runs that both produced NaN compare equal.
    """
    plain = to_plain(record, type(record).__name__)
    return {k: _nan_safe(v) for k, v in plain.items() if not is_timing_field(k)}


# ---------------------------------------------------------------------------
# Work done per episode (the same function in-process, in pool workers and on
# Dask workers). It takes and returns plain data only.

_CONFIG_CACHE: dict[tuple[str, str], Any] = {}


def _run_task(module: str, name: str, config_json: str, seed: int) -> dict[str, Any]:
    """Runs one episode; returns ``{"seed", "record", "episode_s", "worker"}`` or an error dict."""
    try:
        entry = lookup_in_module(module, name)
        key = (name, config_json)
        config = _CONFIG_CACHE.get(key)
        if config is None:
            config = from_plain(entry.config_type, json.loads(config_json), "config")
            _CONFIG_CACHE.clear()
            _CONFIG_CACHE[key] = config
        t0 = time.perf_counter()
        record = entry.run_episode(config, seed)
        episode_s = time.perf_counter() - t0
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
            "worker": f"{socket.gethostname()}:{os.getpid()}",
        }
    except RepertoireError as e:
        return {
            "seed": seed,
            "error": "repertoire",
            "message": str(e),
            "traceback": traceback.format_exc(),
        }
    except Exception as e:
        return {
            "seed": seed,
            "error": "exception",
            "message": f"{type(e).__name__}: {e}",
            "traceback": traceback.format_exc(),
        }


def _raise_task_error(name: str, result: dict[str, Any]) -> None:
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


def _watch_parent(parent_pid: int) -> None:
    """Exits this worker when the process that started it is gone (e.g. SIGKILLed)."""
    while True:
        time.sleep(0.5)
        if os.getppid() != parent_pid:
            os._exit(1)


def _worker_init(parent_pid: int, module: str, name: str) -> None:
    threading.Thread(target=_watch_parent, args=(parent_pid,), daemon=True).start()
    try:
        lookup_in_module(module, name)  # import the study (and pydrake) once, up front
    except Exception:  # reported per task by _run_task, with its traceback
        pass


# ---------------------------------------------------------------------------
# Executors: each yields result dicts as episodes finish.


def _iter_inline(module: str, name: str, config_json: str, seeds: list[int]) -> Iterator[dict]:
    for seed in seeds:
        yield _run_task(module, name, config_json, seed)


def _iter_process(
    module: str, name: str, config_json: str, seeds: list[int], workers: int
) -> Iterator[dict]:
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    # spawn: pydrake and fork do not mix; every worker rebuilds the study from its name.
    pool = ProcessPoolExecutor(
        max_workers=workers,
        mp_context=multiprocessing.get_context("spawn"),
        initializer=_worker_init,
        initargs=(os.getpid(), module, name),
    )
    finished = False
    todo = iter(seeds)
    seed_of: dict = {}

    def submit_next() -> None:
        seed = next(todo, None)
        if seed is not None:
            seed_of[pool.submit(_run_task, module, name, config_json, seed)] = seed

    try:
        # A bounded window of submitted seeds keeps memory flat for long studies.
        for _ in range(workers * WINDOW_PER_WORKER):
            submit_next()
        pending = set(seed_of)
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for fut in done:
                try:
                    result = fut.result()
                except BrokenProcessPool as e:
                    raise EpisodeError(
                        f"study '{name}': a worker process died (crash or out of memory) while "
                        f"running seed {seed_of[fut]}; finished episodes are stored, rerun to "
                        "resume"
                    ) from e
                del seed_of[fut]
                submit_next()
                yield result
            pending = set(seed_of)
        finished = True
    finally:
        pool.shutdown(wait=finished, cancel_futures=True)


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
            f"--executor dask needs --scheduler (scheduler_address); {example}; got {address!r}"
        )
    m = _ADDRESS.match(address)
    if m is None or not 1 <= int(m.group(3)) <= 65535:
        raise RepertoireError(f"--scheduler {address!r} is not a Dask address; {example}")
    return address


def connect_dask(scheduler_address: str, timeout_s: float = DASK_CONNECT_TIMEOUT_S):
    """Connects a ``dask.distributed.Client`` to a scheduler, failing fast.

    Args:
        scheduler_address: e.g. ``tcp://10.0.0.5:8786``.
        timeout_s: connection timeout.

    Raises:
        RepertoireError: dask.distributed is not installed, or the scheduler is
            not reachable within ``timeout_s`` (names the address).
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
        return Client(scheduler_address, timeout=f"{timeout_s}s", set_as_default=False)
    except Exception as e:
        raise RepertoireError(
            f"could not connect to the Dask scheduler at '{scheduler_address}' within "
            f"{timeout_s:g} s ({type(e).__name__}: {e}); start one with `dask scheduler` "
            "and `dask worker <address>`, or use --executor process"
        ) from e


def _iter_dask(
    client, module: str, name: str, config_json: str, seeds: list[int]
) -> Iterator[dict]:
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
            fut = client.submit(_run_task, module, name, config_json, seed, key=key, pure=False)
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


# ---------------------------------------------------------------------------
# Summaries.


def is_identifier_field(name: str) -> bool:
    """Fields that name an episode rather than measure it (``seed``, ``*_seed``, ``*_id``)."""
    return name in ("seed", "id", "index") or name.endswith(("_seed", "_id", "_index"))


def _numeric_fields(record_type: type, records: list) -> tuple[list[str], list[str]]:
    """(numeric field names, bool field names) of the record type, in field order.

    None is a missing value (for example "no path"); identifiers are skipped.
    """
    numeric, boolean = [], []
    for f in dataclasses.fields(record_type):
        if is_identifier_field(f.name):
            continue
        values = [getattr(r, f.name) for r in records if getattr(r, f.name) is not None]
        if values and all(isinstance(v, bool) for v in values):
            boolean.append(f.name)
        elif values and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in values
        ):
            numeric.append(f.name)
    return numeric, boolean


def _present(value: Any) -> bool:
    """False for a missing value: None or NaN."""
    return value is not None and not (isinstance(value, float) and math.isnan(value))


def summary_rows(record_type: type, records: list) -> list[dict[str, Any]]:
    """One summary row per numeric or bool record field.

    Numeric fields get ``n`` (finite values), ``mean``, ``std`` (population),
    ``min``, ``max``; bool fields get ``n`` and ``success_rate``. Missing values
    (None, NaN) and identifier fields (``seed``) are left out.
    """
    numeric, boolean = _numeric_fields(record_type, records)
    rows = []
    for name in numeric:
        vals = [float(v) for r in records if _present(v := getattr(r, name))]
        finite = [v for v in vals if math.isfinite(v)]
        n = len(finite)
        mean = sum(finite) / n if n else math.nan
        std = math.sqrt(sum((v - mean) ** 2 for v in finite) / n) if n else math.nan
        rows.append(
            {
                "field": name,
                "n": n,
                "mean": mean,
                "std": std,
                "min": min(finite) if n else math.nan,
                "max": max(finite) if n else math.nan,
                "success_rate": "",
            }
        )
    for name in boolean:
        vals = [bool(v) for r in records if _present(v := getattr(r, name))]
        rows.append(
            {
                "field": name,
                "n": len(vals),
                "mean": "",
                "std": "",
                "min": "",
                "max": "",
                "success_rate": sum(vals) / len(vals) if vals else math.nan,
            }
        )
    return rows


def summary_figures(record_type: type, records: list) -> dict[str, float]:
    """The summary as named figures, the ones study criteria bound.

    ``mean_<field>``, ``std_<field>``, ``min_<field>``, ``max_<field>`` of numeric
    fields and ``rate_<field>`` of bool fields.
    """
    figures: dict[str, float] = {}
    for row in summary_rows(record_type, records):
        if row["success_rate"] != "":
            figures[f"rate_{row['field']}"] = float(row["success_rate"])
        else:
            for key in ("mean", "std", "min", "max"):
                figures[f"{key}_{row['field']}"] = float(row[key])
    return figures


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)


def write_tables(
    name: str, record_type: type, records: list, seeds: list[int], out_dir: Path
) -> dict[str, Path]:
    """Writes summary.csv, summary.md and episodes.csv; returns their paths."""
    rows = summary_rows(record_type, records)
    cols = ["field", "n", "mean", "std", "min", "max", "success_rate"]
    csv_path = out_dir / "summary.csv"
    with csv_path.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=cols)
        w.writeheader()
        for row in rows:
            w.writerow({k: (repr(v) if isinstance(v, float) else v) for k, v in row.items()})
    md_path = out_dir / "summary.md"
    lines = [
        f"# Study `{name}`: {len(records)} episodes (seeds {seeds[0]}..{seeds[-1]})",
        "",
        f"Every one of the {len(records)} episodes stored for this config (the store may hold "
        "more seeds than the last run asked for). `n` counts the finite values of a field; "
        "missing values (no result) are left out.",
        "",
        "| " + " | ".join(cols) + " |",
        "|" + "|".join(["---"] + ["---:"] * (len(cols) - 1)) + "|",
    ]
    lines += ["| " + " | ".join(_fmt(row[c]) for c in cols) + " |" for row in rows]
    md_path.write_text("\n".join(lines) + "\n")
    ep_path = out_dir / "episodes.csv"
    fields = [f.name for f in dataclasses.fields(record_type)]
    with ep_path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["seed", *fields])
        for seed, rec in zip(seeds, records):
            row = [seed]
            for f in fields:
                v = getattr(rec, f)
                row.append(
                    repr(v)
                    if isinstance(v, float)
                    else (v if isinstance(v, (int, str, bool)) else json.dumps(to_plain(v)))
                )
            w.writerow(row)
    return {"summary.csv": csv_path, "summary.md": md_path, "episodes.csv": ep_path}


def _use_agg() -> None:
    import matplotlib

    if matplotlib.get_backend().lower() != "agg":
        try:
            matplotlib.use("Agg")
        except Exception:  # a GUI backend already in use: our figures use Figure() anyway
            pass


def write_histograms(record_type: type, records: list, out_dir: Path) -> dict[str, Path]:
    """One histogram PNG per numeric record field; returns ``{label: path}``."""
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator

    numeric, _ = _numeric_fields(record_type, records)
    figures = {}
    for name in numeric:
        vals = [float(v) for r in records if _present(v := getattr(r, name))]
        finite = [v for v in vals if math.isfinite(v)]
        fig = Figure(figsize=(5, 3.5), layout="constrained")
        ax = fig.add_subplot()
        ax.hist(finite, bins=min(30, max(5, len(finite) // 3)), color="tab:blue", alpha=0.8)
        ax.set_xlabel(name)
        ax.set_ylabel("episodes")
        ax.yaxis.set_major_locator(MaxNLocator(integer=True))  # counts: whole ticks
        missing = len(records) - len(finite)
        left_out = f" ({missing} missing or non-finite left out)" if missing else ""
        ax.set_title(f"{name} over {len(finite)} episodes{left_out}", fontsize=9)
        path = out_dir / f"hist_{name}.png"
        fig.savefig(path, dpi=100)
        figures[f"hist_{name}"] = path
    return figures


# ---------------------------------------------------------------------------
# The engine.


def _check_int(label: str, value: Any, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise RepertoireError(f"{label} must be an int >= {minimum}, got {value!r}")
    return value


def _records_from_rows(entry: StudyEntry, rows) -> list:
    records = []
    for row in rows:
        try:
            records.append(
                from_plain(
                    entry.record_type,
                    json.loads(row.record_json),
                    f"{entry.record_type.__name__}(seed={row.seed})",
                )
            )
        except (RepertoireError, TypeError) as e:
            raise RepertoireError(
                f"stored record for seed {row.seed} does not fit {entry.record_type.__name__}: "
                f"{e}; pass --fresh (fresh=True) to start the store afresh"
            ) from e
    return records


def load_records(store: str | Path, name: str | None = None) -> tuple[Any, dict[int, Any]]:
    """Reads every stored episode of a study store as typed records.

    For programs that learn from a study's episodes (for example an action
    model): no episode is run and the config is not checked against anything.

    Args:
        store: the SQLite store written by :func:`run_study`.
        name: the study expected in the store (default: whatever it holds).

    Returns:
        ``(config, {seed: record})`` with the store's config and records.

    Raises:
        RepertoireError: missing or foreign file, another study than ``name``,
            or records that no longer fit the study's record type.
        UnknownNameError: the stored study is not registered.
    """
    meta, rows = read_store(store)
    stored = meta.get("study")
    if name is not None and stored != name:
        raise RepertoireError(f"store '{store}' holds study '{stored}', not '{name}'")
    entry = get_study(stored)
    config = from_plain(entry.config_type, json.loads(meta["config_json"]), "config")
    records = _records_from_rows(entry, rows)
    return config, {row.seed: rec for row, rec in zip(rows, records)}


def run_study(
    name: str,
    config: Any = None,
    *,
    episodes: int = 100,
    first_seed: int = 0,
    store: str | Path | None = None,
    out_dir: str | Path | None = None,
    executor: str = "process",
    workers: int | None = None,
    scheduler_address: str | None = None,
    fresh: bool = False,
    progress: bool = True,
    summarize: bool = True,
    dask_timeout_s: float = DASK_CONNECT_TIMEOUT_S,
) -> StudyResult:
    """Runs the missing seeds of a study, stores every record, writes summaries.

    Args:
        name: a registered study name.
        config: an instance of the study's config type (default: its demo config,
            else ``config_type()``).
        episodes: number of seeds, ``first_seed .. first_seed + episodes - 1``.
        first_seed: the first seed (>= 0).
        store: the SQLite file (default ``<out_dir>/episodes.sqlite``).
        out_dir: folder for the store, tables and figures (default ``out/studies/<name>``).
        executor: ``"inline"``, ``"process"`` or ``"dask"``.
        workers: process-pool size (default: all cores); ignored by dask.
        scheduler_address: the Dask scheduler (``executor="dask"`` only).
        fresh: drop what the store holds and start afresh (needed when the
            config changed).
        progress: show a tqdm progress bar with rate and ETA.
        summarize: write tables and figures (False: only run and store).
        dask_timeout_s: how long to try to reach the Dask scheduler.

    Returns:
        The :class:`StudyResult`.

    Raises:
        RepertoireError: bad arguments, a config of the wrong type or that does
            not round-trip through plain data, a store with another config
            (unless ``fresh``), an unreachable Dask scheduler, a record of the
            wrong type.
        UnknownNameError: ``name`` is not a registered study.
        EpisodeError: ``run_episode`` raised (finished episodes stay stored).
    """
    t_start = time.perf_counter()
    episodes = _check_int("episodes", episodes, 1)
    first_seed = _check_int("first_seed", first_seed, 0)
    if executor not in EXECUTORS:
        raise RepertoireError(f"executor must be one of {list(EXECUTORS)}, got {executor!r}")
    if workers is not None:
        workers = _check_int("workers", workers, 1)
    entry = get_study(name)
    if config is None:
        config = entry.default_config()
    if not isinstance(config, entry.config_type):
        raise RepertoireError(
            f"study '{name}' takes a {entry.config_type.__name__} config, "
            f"got {type(config).__name__}"
        )
    validate = getattr(config, "validate", None)
    if callable(validate):
        validate()
    config_json = canonical_json(to_plain(config, "config"))
    rebuilt = from_plain(entry.config_type, json.loads(config_json), "config")
    if canonical_json(to_plain(rebuilt, "config")) != config_json:
        raise RepertoireError(
            f"study '{name}': the config does not survive the trip to plain data and back "
            "(workers could not rebuild it); use plain dataclass fields"
        )
    out_path = Path(out_dir) if out_dir is not None else Path("out") / "studies" / name
    store_path = Path(store) if store is not None else out_path / "episodes.sqlite"
    require_writable_dir(out_path, "--out-dir (out_dir)")
    require_writable_file(store_path, "--store (store)")

    client = None
    if executor == "dask":  # fail fast, before touching the store
        client = connect_dask(scheduler_address, dask_timeout_s)
    elif scheduler_address is not None:
        raise RepertoireError(
            "--scheduler (scheduler_address) is only used with --executor dask (executor='dask')"
        )
    try:
        record_fields = [f.name for f in dataclasses.fields(entry.record_type)]
        with EpisodeStore.open(
            store_path,
            study=name,
            config_json=config_json,
            record_fields=record_fields,
            fresh=fresh,
        ) as db:
            present = db.seeds(first_seed, episodes)
            seeds = list(range(first_seed, first_seed + episodes))
            missing = [s for s in seeds if s not in present]
            n_workers = _run_missing(
                entry,
                db,
                config_json,
                missing,
                len(present),
                episodes,
                executor,
                workers,
                client,
                progress,
            )
            rows = db.load(first_seed, episodes)
            stored = db.load(0, STORE_SEED_LIMIT)  # every stored seed of this config
    finally:
        if client is not None:
            client.close()
    if [r.seed for r in rows] != seeds:
        lost = sorted(set(seeds) - {r.seed for r in rows})
        raise RepertoireError(
            f"study '{name}': seeds {lost[:10]} missing from the store after the run"
        )
    records = _records_from_rows(entry, rows)
    stored_records = _records_from_rows(entry, stored)
    stored_seeds = [r.seed for r in stored]

    tables: dict[str, Path] = {}
    figures: dict[str, Path] = {}
    if summarize:
        out_path.mkdir(parents=True, exist_ok=True)
        tables = write_tables(name, entry.record_type, stored_records, stored_seeds, out_path)
        _use_agg()
        if entry.summarize is not None:
            made = entry.summarize(records, rebuilt, out_path)
            if not isinstance(made, dict):
                raise RepertoireError(
                    f"study '{name}': summarize must return a dict label -> path, got {made!r}"
                )
            figures = {str(k): Path(v) for k, v in made.items()}
        else:
            figures = write_histograms(entry.record_type, records, out_path)
    return StudyResult(
        name=name,
        config=rebuilt,
        records=records,
        seeds=seeds,
        store=store_path,
        out_dir=out_path,
        tables=tables,
        figures=figures,
        elapsed_s=time.perf_counter() - t_start,
        n_run=len(missing),
        n_reused=len(present),
        executor=executor,
        workers=n_workers,
    )


def _all_cores() -> int:
    """Cores this process may use (its CPU affinity where the OS reports it)."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0)) or 1
    return os.cpu_count() or 1


def _run_missing(
    entry: StudyEntry,
    db: EpisodeStore,
    config_json: str,
    missing: list[int],
    n_present: int,
    episodes: int,
    executor: str,
    workers: int | None,
    client,
    progress: bool,
) -> int | None:
    """Runs ``missing`` seeds on the executor, storing each result as it arrives.

    Returns:
        The number of worker processes used (None for dask).
    """
    from tqdm import tqdm

    module, name = entry.module, entry.name
    n_workers: int | None
    if executor == "inline":
        n_workers = 1
    elif executor == "process":
        n_workers = workers or _all_cores()
    else:
        n_workers = None
    if not missing:
        return n_workers
    if executor == "inline":
        results = _iter_inline(module, name, config_json, missing)
    elif executor == "process":
        n_workers = min(n_workers, len(missing))
        results = _iter_process(module, name, config_json, missing, n_workers)
    else:
        results = _iter_dask(client, module, name, config_json, missing)
    bar = tqdm(
        total=episodes,
        initial=n_present,
        desc=name,
        unit="ep",
        disable=not progress,
        dynamic_ncols=True,
        # On a terminal, a live bar; in a log file, one line every 10 s instead of a flood.
        mininterval=0.1 if sys.stderr.isatty() else 10.0,
    )
    try:
        for result in results:
            if "error" in result:
                _raise_task_error(name, result)
            db.insert(
                result["seed"], json.dumps(result["record"]), result["episode_s"], result["worker"]
            )
            bar.update(1)
    finally:
        bar.close()
        close = getattr(results, "close", None)
        if close is not None:
            close()
    return n_workers


# ---------------------------------------------------------------------------
# Command line, shared by study scripts (``main()``) and ``repertoire study``.


def add_study_arguments(parser: argparse.ArgumentParser, *, with_name: bool = True) -> None:
    """Adds the study options (and a NAME positional if ``with_name``) to a parser."""
    if with_name:
        parser.add_argument("name", help="registered study name (see `repertoire list`)")
    parser.add_argument(
        "--config",
        type=Path,
        default=None,
        help="YAML file of the study's config (default: its demo config)",
    )
    parser.add_argument(
        "--smoke", action="store_true", help="use the study's tiny smoke-test config instead"
    )
    parser.add_argument(
        "--episodes",
        "-n",
        type=int,
        default=None,
        help="number of seeds to run (default: the study's demo_episodes)",
    )
    parser.add_argument("--first-seed", type=int, default=0, help="first seed (default 0)")
    parser.add_argument(
        "--store",
        type=Path,
        default=None,
        help="SQLite store (default out/studies/NAME/episodes.sqlite)",
    )
    parser.add_argument(
        "--out-dir",
        type=Path,
        default=None,
        help="folder for tables and figures (default out/studies/NAME)",
    )
    parser.add_argument(
        "--executor",
        choices=EXECUTORS,
        default="process",
        help="where episodes run (default: local process pool)",
    )
    parser.add_argument(
        "--workers", "-j", type=int, default=None, help="process-pool size (default: all cores)"
    )
    parser.add_argument(
        "--scheduler",
        default=None,
        help="Dask scheduler address, e.g. tcp://host:8786 (with --executor dask)",
    )
    parser.add_argument(
        "--fresh",
        action="store_true",
        help="discard the store's episodes and start afresh (needed after changing the config)",
    )
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")


def run_study_from_args(args: argparse.Namespace, name: str | None = None) -> StudyResult:
    """Runs a study from parsed :func:`add_study_arguments` options; prints where outputs went."""
    name = name or args.name
    entry = get_study(name)
    if args.config is not None and args.smoke:
        raise RepertoireError("give either --config or --smoke, not both")
    if args.config is not None:
        from repertoire.diagrams.scenario import load_scenario

        config = load_scenario(entry.config_type, filename=args.config, what="config")
    elif args.smoke:
        if entry.smoke_config is None:
            raise RepertoireError(f"study '{name}' has no smoke config")
        config = entry.smoke_config()
    else:
        config = entry.default_config()
    result = run_study(
        name,
        config,
        episodes=args.episodes if args.episodes is not None else entry.demo_episodes,
        first_seed=args.first_seed,
        store=args.store,
        out_dir=args.out_dir,
        executor=args.executor,
        workers=args.workers,
        scheduler_address=args.scheduler,
        fresh=args.fresh,
        progress=not args.no_progress,
    )
    print(
        f"study {name}: {len(result.records)} episodes ({result.n_run} run, "
        f"{result.n_reused} from the store) in {result.elapsed_s:.1f} s"
    )
    print(f"  store:   {result.store}")
    for label, path in {**result.tables, **result.figures}.items():
        print(f"  {label}: {path}")
    return result


def study_main(
    name: str | None = None, argv: list[str] | None = None, description: str | None = None
) -> int:
    """Command-line entry point; a study module's ``main()`` calls ``study_main("its_name")``.

    Returns:
        The process exit code (2 with a one-line message on bad input).
    """
    prog = f"python -m {get_study(name).module}" if name else "python -m repertoire.studies.engine"
    parser = argparse.ArgumentParser(
        prog=prog,
        description=description or (__doc__ or "").split("\n\n")[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=(
            "examples:\n"
            f"  {prog} {'' if name else 'NAME '}--smoke -n 4 --executor inline\n"
            f"  {prog} {'' if name else 'NAME '}-n 200 -j 2            "
            "# resumable: rerun to finish missing seeds\n"
            f"  {prog} {'' if name else 'NAME '}--config my.yaml --fresh  "
            "# a changed config needs --fresh\n"
            f"  {prog} {'' if name else 'NAME '}--executor dask --scheduler tcp://host:8786"
        ),
    )
    add_study_arguments(parser, with_name=name is None)
    args = parser.parse_args(argv)
    try:
        run_study_from_args(args, name)
    except RepertoireError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(study_main())
