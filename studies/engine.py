"""The Monte-Carlo study engine: run N seeds of a registered study, store, summarize.

A study (see :mod:`repertoire.studies.registry`) is a config dataclass, a record
dataclass and a module-level ``run_episode(config, seed)`` that builds its own
diagram. :func:`run_study` runs the seeds ``first_seed .. first_seed+episodes-1``

- ``executor="inline"``: in this process;
- ``executor="process"``: on a local pool of ``workers`` processes (default:
  all cores), forked from a fork server that has imported pydrake once
  (:mod:`repertoire.studies.engine_pool`);
- ``executor="dask"``: on a Dask distributed cluster at ``scheduler_address``
  (:mod:`repertoire.studies.engine_dask`),

and writes every record to an SQLite store the moment it finishes (see
:mod:`repertoire.studies.store`), with the episode's wall and CPU time; a
rerun runs only the missing seeds. Workers receive only ``(module name, study
name, config JSON, seed)`` and send back plain dicts: nothing from pydrake is
pickled, every worker rebuilds the study from the config. Records are
identical whatever the executor or worker count (fields named ``wall*_s`` are
timing fields and excepted): every episode runs with one BLAS thread
(:func:`repertoire.studies.engine_pool.one_blas_thread`). An episode that kills its pool worker (a
segfault, the out-of-memory killer) is recorded in the store's ``crashes``
table, the other seeds run on, and the call then raises :class:`EpisodeError`
naming the crashed seeds; a rerun tries them again.

At the end the engine writes ``summary.csv``, ``summary.md`` and
``episodes.csv`` to ``out_dir``, plus the study's own figures (its
``summarize``), or one histogram per numeric field when it has none
(:mod:`repertoire.studies.engine_summary`); tables and figures alike cover every
seed stored for the config, not only this call's.

This module imports neither pydrake nor dask at import time.
"""

import argparse
import dataclasses
import json
import numbers
import os
import sys
import time
from pathlib import Path
from typing import Any

from repertoire.studies.engine_dask import (
    DASK_CONNECT_TIMEOUT_S,
    DASK_WORKER_WAIT_S,
    check_wait_s,
    connect_dask,
    iter_dask,
    parse_scheduler_address,
)
from repertoire.studies.engine_pool import (
    EpisodeError,
    WorkerPool,
    iter_inline,
    prestart_fork_server,
    raise_task_error,
)
from repertoire.studies.engine_summary import (
    comparable,
    is_identifier_field,
    is_timing_field,
    summary_figures,
    summary_rows,
    use_agg,
    write_histograms,
    write_tables,
)
from repertoire.studies.registry import (
    StudyEntry,
    get_study,
    register_study,
    study_names,
)
from repertoire.studies.store import (
    EpisodeStore,
    canonical_json,
    config_from_json,
    config_to_json,
    copy_store,
    from_plain,
    read_store,
    to_plain,
)

from repertoire.errors import RepertoireError
from repertoire.interrupts import exit_process, interruptible
from repertoire.limits import (
    path_argument,
    require_memory,
    require_writable_dir,
    require_writable_file,
)

__all__ = [
    "EXECUTORS",
    "EpisodeError",
    "StudyEntry",
    "StudyResult",
    "add_study_arguments",
    "comparable",
    "get_study",
    "is_identifier_field",
    "is_timing_field",
    "connect_dask",
    "load_records",
    "parse_scheduler_address",
    "register_study",
    "run_study",
    "run_study_command",
    "run_study_from_args",
    "study_main",
    "study_names",
    "summary_figures",
    "summary_rows",
    "write_histograms",
    "write_tables",
]

EXECUTORS = ("inline", "process", "dask")


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
# Memory the engine keeps per requested episode (seed lists, a stored row, a record).
EPISODE_BOOKKEEPING_BYTES = 200


# ---------------------------------------------------------------------------
# The engine.


def _check_int(label: str, value: Any, minimum: int) -> int:
    """``value`` as an int (a Python or numpy whole number) >= ``minimum``, or an error."""
    # numbers.Integral as repertoire.checks.is_whole, which would import numpy here
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < minimum:
        raise RepertoireError(f"{label} must be an int >= {minimum}, got {value!r}")
    return int(value)


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
        except (ValueError, TypeError) as e:  # not JSON, or not the record's fields
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
    missing = [key for key in ("study", "config_json") if key not in meta]
    if missing:  # a damaged store: not "unknown study 'None'" nor a bare KeyError
        raise RepertoireError(
            f"store '{store}' has no {' and no '.join(missing)} in its meta table, so its "
            f"{len(rows)} episodes cannot be read as a study's records"
        )
    if name is not None and stored != name:
        raise RepertoireError(f"store '{store}' holds study '{stored}', not '{name}'")
    entry = get_study(stored)
    try:
        config = config_from_json(entry.config_type, meta["config_json"])
    except (RepertoireError, ValueError) as e:  # a field renamed or dropped since
        raise RepertoireError(
            f"store '{store}': its config no longer fits study '{stored}' "
            f"({entry.config_type.__name__}): {e}"
        ) from e
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
    dask_worker_wait_s: float = DASK_WORKER_WAIT_S,
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
        workers: process-pool size (default: all cores); only with ``executor="process"``
            (``"inline"`` takes 1).
        scheduler_address: the Dask scheduler (``executor="dask"`` only).
        fresh: drop what the store holds and start afresh (needed when the
            config changed); when an episode rejects the new config before any
            episode of it is stored, the store is put back as it was.
        progress: show a tqdm progress bar with rate and ETA.
        summarize: write tables and figures (False: only run and store).
        dask_timeout_s: how long to try to reach the Dask scheduler.
        dask_worker_wait_s: how long seeds may wait for a Dask worker when
            every worker has left mid-run (one that joins runs them) before the
            run stops with an EpisodeError.

    Returns:
        The :class:`StudyResult`.

    Raises:
        RepertoireError: bad arguments, a config of the wrong type or that does
            not round-trip through plain data, a store with another config
            (unless ``fresh``), an unreachable Dask scheduler, a record of the
            wrong type.
        UnknownNameError: ``name`` is not a registered study.
        EpisodeError: ``run_episode`` raised, or every Dask worker left for
            ``dask_worker_wait_s`` (finished episodes stay stored).
    """
    t_start = time.perf_counter()
    episodes = _check_int("--episodes (episodes)", episodes, 1)
    first_seed = _check_int("--first-seed (first_seed)", first_seed, 0)
    if first_seed + episodes > STORE_SEED_LIMIT:
        raise RepertoireError(
            f"seeds must stay below 2**62 = {STORE_SEED_LIMIT}, got --first-seed (first_seed) "
            f"{first_seed} with --episodes (episodes) {episodes}"
        )
    require_memory(
        episodes * EPISODE_BOOKKEEPING_BYTES, f"the seed lists and records of episodes={episodes}"
    )
    if executor not in EXECUTORS:
        raise RepertoireError(f"executor must be one of {list(EXECUTORS)}, got {executor!r}")
    if workers is not None:
        workers = _check_int("--workers (workers)", workers, 1)
        # as --scheduler without dask: not silently ignored (inline is one worker)
        if executor == "dask" or (executor == "inline" and workers > 1):
            where = "one at a time in this process" if executor == "inline" else "on the cluster"
            raise RepertoireError(
                f"--workers (workers) is only used with --executor process (executor="
                f"'process'); --executor {executor} runs its episodes {where}"
            )
    if executor == "dask":
        dask_timeout_s = check_wait_s("dask_timeout_s", dask_timeout_s)
        dask_worker_wait_s = check_wait_s(
            "--dask-worker-wait (dask_worker_wait_s)", dask_worker_wait_s
        )
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
    plain_config = to_plain(config, "config")
    nan_field = _nan_field(plain_config, "config")
    if nan_field:  # no study means anything by NaN; refused before the store is touched
        raise RepertoireError(f"study '{name}': {nan_field} is NaN; expected a number")
    # The config as the workers rebuild it: typed (an int given for a float field is
    # that float, as a YAML config would load it), so the store's config is one text.
    rebuilt = config_from_json(entry.config_type, canonical_json(plain_config))
    config_json = config_to_json(rebuilt)
    if config_to_json(config_from_json(entry.config_type, config_json)) != config_json:
        raise RepertoireError(
            f"study '{name}': the config does not survive the trip to plain data and back "
            "(workers could not rebuild it); use plain dataclass fields"
        )
    out_path = Path(out_dir) if out_dir is not None else Path("out") / "studies" / name
    store_path = Path(store) if store is not None else out_path / "episodes.sqlite"
    require_writable_dir(out_path, "--out-dir (out_dir)")
    require_writable_file(store_path, "--store (store)", folder_too=True)  # -wal, -shm
    if summarize:
        for table in ("summary.csv", "summary.md", "episodes.csv"):
            require_writable_file(out_path / table, "--out-dir (out_dir)")

    client = None
    if executor == "dask":  # fail fast, before touching the store
        client = connect_dask(scheduler_address, dask_timeout_s)
    elif scheduler_address is not None:
        raise RepertoireError(
            "--scheduler (scheduler_address) is only used with --executor dask (executor='dask')"
        )
    n_workers = {"inline": 1, "process": workers or _all_cores(), "dask": None}[executor]
    pool = None
    if executor == "process" and (fresh or not store_path.exists()):
        # Every seed will run: start the workers now, while the store is being opened.
        pool = WorkerPool(entry.module, name, config_json, min(n_workers, episodes))
    # A store this call creates is removed again when an episode rejects the config
    # (RepertoireError: bad input) before anything was stored, so bad input writes nothing.
    store_is_new = not store_path.exists()
    new_folder = _first_missing_folder(store_path.parent)
    discard = False
    # ``fresh`` drops the store's episodes; a copy of them is put back when an episode
    # rejects the new config before any of its episodes was stored (bad input keeps data)
    before_fresh = Path(f"{store_path}.before-fresh") if fresh and not store_is_new else None
    if before_fresh is not None and not copy_store(store_path, before_fresh):
        before_fresh.unlink(missing_ok=True)  # not a store: the open below says so
        before_fresh = None
    restore = False
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
            if executor == "process" and missing:
                n_workers = min(n_workers, len(missing))
                if pool is None:
                    pool = WorkerPool(entry.module, name, config_json, n_workers)
            if executor == "inline":
                results = iter_inline(entry.module, name, config_json, missing)
            elif executor == "process":
                results = pool.run(missing) if missing else iter([])
            else:
                results = iter_dask(
                    client, entry.module, name, config_json, missing, dask_worker_wait_s
                )
            try:
                _store_results(name, db, results, len(present), episodes, progress)
            except RepertoireError:
                nothing_new = db.count() == 0 and not db.crashes()
                discard = store_is_new and nothing_new
                restore = before_fresh is not None and nothing_new
                raise
            if pool is not None:
                pool.close()
                pool = None
            rows = db.load(first_seed, episodes)
            stored = db.load(0, STORE_SEED_LIMIT)  # every stored seed of this config
    finally:
        if pool is not None:
            pool.close(abort=True)
        if client is not None:
            client.close()
        if discard:
            _remove_new_store(store_path, new_folder)
        if before_fresh is not None:
            if restore:
                copy_store(before_fresh, store_path)
            before_fresh.unlink(missing_ok=True)
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
        use_agg()
        if entry.summarize is not None:
            made = entry.summarize(stored_records, rebuilt, out_path)  # as summary.md: all
            if not isinstance(made, dict):
                raise RepertoireError(
                    f"study '{name}': summarize must return a dict label -> path, got {made!r}"
                )
            figures = {str(k): Path(v) for k, v in made.items()}
        else:
            figures = write_histograms(entry.record_type, stored_records, out_path)
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


def _nan_field(plain: Any, path: str) -> str | None:
    """The path (``config.a.b[2]``) of the first NaN in plain data, or None."""
    if isinstance(plain, float) and plain != plain:
        return path
    if isinstance(plain, dict):
        items = ((f"{path}.{k}", v) for k, v in plain.items())
    elif isinstance(plain, list):
        items = ((f"{path}[{i}]", v) for i, v in enumerate(plain))
    else:
        return None
    return next((p for p in (_nan_field(v, k) for k, v in items) if p), None)


def _first_missing_folder(folder: Path) -> Path | None:
    """The outermost missing folder on the way to ``folder`` (None if ``folder`` exists)."""
    missing = None
    for parent in (folder, *folder.parents):
        if parent.exists():
            break
        missing = parent
    return missing


def _remove_new_store(store_path: Path, new_folder: Path | None) -> None:
    """Removes a store file this run created, and the folders it created for it."""
    for suffix in ("", "-wal", "-shm", "-journal"):
        Path(f"{store_path}{suffix}").unlink(missing_ok=True)
    if new_folder is not None:
        folder = store_path.parent
        while True:
            try:
                folder.rmdir()  # only empty folders go
            except OSError:
                return
            if folder == new_folder:
                return
            folder = folder.parent


def _all_cores() -> int:
    """Cores this process may use (its CPU affinity where the OS reports it)."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0)) or 1
    return os.cpu_count() or 1


def _store_results(
    name: str, db: EpisodeStore, results, n_present: int, episodes: int, progress: bool
) -> None:
    """Stores each result as it arrives; records crashes and raises for them at the end.

    Raises:
        RepertoireError, EpisodeError: an episode raised (at once), or one or
            more episodes killed their worker (after every other seed ran).
    """
    from tqdm import tqdm

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
    crashes = []
    try:
        for result in results:
            if result.get("error") == "crash":
                db.record_crash(
                    result["seed"], result["exitcode"], result["message"], result["worker"]
                )
                crashes.append(result)
                continue
            if "error" in result:
                raise_task_error(name, result)
            db.insert(
                result["seed"],
                json.dumps(result["record"]),
                result["episode_s"],
                result["worker"],
                cpu_s=result.get("cpu_s"),
            )
            bar.update(1)
    finally:
        bar.close()
        close = getattr(results, "close", None)
        if close is not None:
            close()
    if crashes:
        seeds = sorted(c["seed"] for c in crashes)
        raise EpisodeError(
            f"study '{name}': a worker process died (crash or out of memory) while running "
            f"seed{'s' if len(seeds) > 1 else ''} {seeds[:10]}{' ...' if len(seeds) > 10 else ''} "
            f"({crashes[0]['message']}); every other episode is stored and the crashes are in "
            f"the store's crashes table; rerun to resume (crashed seeds are tried again)"
        )


# ---------------------------------------------------------------------------
# Command line, shared by study scripts (``main()``) and ``repertoire study``.


def add_study_arguments(parser: argparse.ArgumentParser, *, with_name: bool = True) -> None:
    """Adds the study options (and a NAME positional if ``with_name``) to a parser."""
    if with_name:
        parser.add_argument("name", help="registered study name (see `repertoire list`)")
    parser.add_argument(
        "--config",
        type=path_argument,
        default=None,
        help=(
            "YAML file of the study's config; keys it leaves out keep the demo config's "
            "values (default: the demo config, as `repertoire show NAME` prints it)"
        ),
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
        type=path_argument,
        default=None,
        help="SQLite store (default OUT_DIR/episodes.sqlite, OUT_DIR from --out-dir)",
    )
    parser.add_argument(
        "--out-dir",
        type=path_argument,
        default=None,
        help="folder for the store, tables and figures (default out/studies/NAME)",
    )
    parser.add_argument(
        "--executor",
        choices=EXECUTORS,
        default="process",
        help="where episodes run (default: local process pool)",
    )
    parser.add_argument(
        "--workers",
        "-j",
        type=int,
        default=None,
        help="process-pool size, with --executor process (default: all cores)",
    )
    parser.add_argument(
        "--scheduler",
        default=None,
        help="Dask scheduler address, e.g. tcp://host:8786 (with --executor dask)",
    )
    parser.add_argument(
        "--dask-worker-wait",
        type=float,
        default=None,
        metavar="SECONDS",
        help=(
            "with --executor dask: how long seeds wait on the scheduler for a worker when every "
            f"worker has left mid-run, before the run stops (default {DASK_WORKER_WAIT_S:g} s)"
        ),
    )
    parser.add_argument(
        "--fresh",
        action="store_true",
        help=(
            "discard the store's episodes and start afresh (needed after changing the config; "
            "kept when an episode rejects the new config)"
        ),
    )
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")


def run_study_command(args: argparse.Namespace, name: str | None = None, prog: str = "") -> int:
    """The study command of both command lines: run it, 0; an episode that failed, 1.

    With the process executor the fork server starts first, so its pydrake import overlaps
    the config loading and study discovery. Bad input raises :class:`RepertoireError`.

    Args:
        args, name: as :func:`run_study_from_args`.
        prog: the program's name before the "run failed" message ("" or "repertoire study").
    """
    if args.executor == "process":
        prestart_fork_server()
    try:
        run_study_from_args(args, name)
    except EpisodeError as e:  # an episode failed or crashed: a failed run, not bad input
        print(f"{prog + ': ' if prog else ''}run failed: {e}", file=sys.stderr)
        return 1
    return 0


def run_study_from_args(args: argparse.Namespace, name: str | None = None) -> StudyResult:
    """Runs a study from parsed :func:`add_study_arguments` options; prints where outputs went."""
    name = name or args.name
    entry = get_study(name)
    if args.config is not None and args.smoke:
        raise RepertoireError("give either --config or --smoke, not both")
    if args.config is not None:
        from repertoire.diagrams.scenario import load_scenario

        # Keys the file leaves out keep the config the study runs without --config, the
        # one `repertoire show NAME` prints (its demo config), not the bare dataclass's.
        config = load_scenario(
            entry.config_type,
            filename=args.config,
            defaults=entry.default_config(),
            what="config",
        )
    elif args.smoke:
        if entry.smoke_config is None:
            raise RepertoireError(f"study '{name}' has no smoke config")
        config = entry.smoke_config()
    else:
        config = entry.default_config()
    wait = {}
    if args.dask_worker_wait is not None:
        if args.executor != "dask":
            raise RepertoireError(
                "--dask-worker-wait is only used with --executor dask (the other executors "
                "run their own workers)"
            )
        wait["dask_worker_wait_s"] = args.dask_worker_wait
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
        **wait,
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
        The process exit code: 0, 1 a failed run, 2 bad input (a one-line message),
        130 interrupted (Ctrl-C; finished episodes stay stored).
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

    try:  # Ctrl-C: "interrupted", 130; finished episodes are stored, a rerun resumes
        return interruptible(lambda: run_study_command(args, name))
    except RepertoireError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    exit_process(study_main())
