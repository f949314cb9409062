"""Tests of the engine's worker pool (engine_pool), the store's cpu_s and crashes, and the
engine's module split (engine_* modules are not studies)."""

import importlib
import json
import sqlite3
import subprocess
import sys
import textwrap
import types

import pytest
from conftest import start_pool_study
from repertoire.studies import registry
from repertoire.studies.engine import EpisodeError, run_study
from repertoire.studies.engine_pool import WorkerPool, describe_exit, run_task
from repertoire.studies.store import EpisodeStore, read_store

from repertoire.errors import RepertoireError

_MODULE = textwrap.dedent(
    """
    import dataclasses
    import os
    import signal

    from repertoire.studies.engine import register_study


    @dataclasses.dataclass
    class PoolConfig:
        exit_seeds: list[int] = dataclasses.field(default_factory=list)
        segv_seeds: list[int] = dataclasses.field(default_factory=list)


    @dataclasses.dataclass
    class PoolRecord:
        seed_cubed: int
        pid: int


    def run_episode(config, seed):
        if seed in config.exit_seeds:
            os._exit(7)
        if seed in config.segv_seeds:
            os.kill(os.getpid(), signal.SIGSEGV)  # as a crashing simulation would
        return PoolRecord(seed_cubed=seed**3, pid=os.getpid())


    register_study("_pool_study", config_type=PoolConfig, record_type=PoolRecord,
                   run_episode=run_episode, description="test-only")
    """
)


@pytest.fixture
def pool_study(tmp_path, monkeypatch):
    (tmp_path / "pool_study_module.py").write_text(_MODULE)
    monkeypatch.syspath_prepend(str(tmp_path))  # workers take the engine's sys.path
    module = importlib.import_module("pool_study_module")
    yield module
    registry._REGISTRY.pop("_pool_study", None)
    sys.modules.pop("pool_study_module", None)


def _config_json_of(config) -> str:
    import dataclasses

    from repertoire.studies.store import canonical_json

    return canonical_json(dataclasses.asdict(config))


def _config_json(module, **kw) -> str:
    return _config_json_of(module.PoolConfig(**kw))


def test_pool_crash_costs_exactly_the_crashing_seeds_and_the_rest_runs(pool_study):
    config_json = _config_json(pool_study, exit_seeds=[1, 6], segv_seeds=[4])
    with WorkerPool("pool_study_module", "_pool_study", config_json, 2) as pool:
        results = list(pool.run(list(range(9))))
    by_seed = {r["seed"]: r for r in results}
    assert sorted(by_seed) == list(range(9))  # one result per seed, none twice
    crashed = {s: r for s, r in by_seed.items() if r.get("error") == "crash"}
    assert sorted(crashed) == [1, 4, 6]
    assert crashed[1]["exitcode"] == 7 and crashed[6]["exitcode"] == 7
    assert crashed[4]["exitcode"] == -11
    assert "killed by signal SIGSEGV) while running seed 4" in crashed[4]["message"]
    for seed in (0, 2, 3, 5, 7, 8):
        assert by_seed[seed]["record"]["seed_cubed"] == seed**3
        assert by_seed[seed]["cpu_s"] >= 0.0 and by_seed[seed]["episode_s"] >= 0.0
    # Three distinct workers died; each was replaced, so 2 + 3 processes ran in all.
    dead = {r["worker"] for r in crashed.values()}
    pids = {by_seed[s]["record"]["pid"] for s in (0, 2, 3, 5, 7, 8)}
    assert len(dead) == 3 and len(pids | {int(w.split(":")[1]) for w in dead}) <= 5


def test_study_records_crashes_goes_on_and_a_rerun_retries_them(pool_study, tmp_path):
    kw = dict(store=tmp_path / "s.sqlite", out_dir=tmp_path / "o", progress=False)
    with pytest.raises(EpisodeError, match=r"while running seeds \[3, 5\] .* crashes table"):
        run_study(
            "_pool_study",
            pool_study.PoolConfig(exit_seeds=[3, 5]),
            episodes=8,
            executor="process",
            workers=2,
            **kw,
        )
    meta, rows = read_store(tmp_path / "s.sqlite")
    assert [r.seed for r in rows] == [0, 1, 2, 4, 6, 7]
    assert all(r.cpu_s is not None and r.cpu_s >= 0.0 for r in rows)
    with sqlite3.connect(tmp_path / "s.sqlite") as db:
        assert sorted(r[0] for r in db.execute("SELECT seed FROM crashes")) == [3, 5]
    assert not (tmp_path / "o" / "summary.md").exists()  # no summary over a hole
    with pytest.raises(EpisodeError, match=r"seeds \[3, 5\]"):  # only those two run again
        run_study(
            "_pool_study",
            pool_study.PoolConfig(exit_seeds=[3, 5]),
            episodes=8,
            executor="process",
            workers=2,
            **kw,
        )
    with sqlite3.connect(tmp_path / "s.sqlite") as db:
        assert sorted(r[0] for r in db.execute("SELECT seed FROM crashes")) == [3, 3, 5, 5]
        assert db.execute("SELECT COUNT(*) FROM episodes").fetchone()[0] == 6


def test_inline_and_pool_store_cpu_time_per_episode(tmp_path):
    from repertoire.studies.pendulum import smoke_config

    for executor in ("inline", "process"):
        run_study(
            "pendulum",
            smoke_config(),
            episodes=2,
            executor=executor,
            workers=1,
            store=tmp_path / f"{executor}.sqlite",
            out_dir=tmp_path / executor,
            progress=False,
            summarize=False,
        )
        _, rows = read_store(tmp_path / f"{executor}.sqlite")
        assert len(rows) == 2
        for row in rows:  # a simulation is CPU-bound: its CPU time is most of its wall time
            assert 0.0 < row.cpu_s <= row.episode_s * 1.5 + 0.05


def test_a_store_without_cpu_s_is_brought_up_to_date(tmp_path):
    path = tmp_path / "old.sqlite"
    with sqlite3.connect(path) as db:  # the layout before cpu_s and crashes
        db.execute("CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL)")
        db.execute(
            "CREATE TABLE episodes (seed INTEGER PRIMARY KEY, record TEXT NOT NULL, "
            "episode_s REAL NOT NULL, finished_unix REAL NOT NULL, worker TEXT NOT NULL)"
        )
        from repertoire.studies.store import SCHEMA_VERSION, config_hash

        meta = {
            "schema_version": SCHEMA_VERSION,
            "study": "x",
            "config_json": "{}",
            "config_sha256": config_hash("{}"),
            "record_fields": json.dumps(["a"]),
        }
        db.executemany("INSERT INTO meta VALUES (?, ?)", meta.items())
        db.execute("INSERT INTO episodes VALUES (0, '{\"a\": 1}', 0.5, 1.0, 'h:1')")
    _, rows = read_store(path)  # read-only reader copes with the old layout
    assert rows[0].cpu_s is None
    with EpisodeStore.open(path, study="x", config_json="{}", record_fields=["a"]) as store:
        assert store.insert(1, '{"a": 2}', 0.25, "h:2", cpu_s=0.2)
        store.record_crash(2, -9, "killed", "h:3")
        assert [(r.seed, r.cpu_s) for r in store.load(0, 10)] == [(0, None), (1, 0.2)]
        assert [(c.seed, c.exitcode) for c in store.crashes()] == [(2, -9)]


def test_run_task_and_describe_exit():
    assert describe_exit(-11) == "killed by signal SIGSEGV"
    assert describe_exit(-9) == "killed by signal SIGKILL"
    assert describe_exit(3) == "exit code 3"
    assert describe_exit(None) == "no exit code"
    result = run_task("repertoire.studies.pendulum", "pendulum", "{}", 0)
    assert result["seed"] == 0 and "record" in result and result["cpu_s"] > 0
    bad = run_task("repertoire.studies.pendulum", "pendulum", '{"length_m": "x"}', 0)
    assert bad["error"] == "repertoire" and "length_m" in bad["message"]
    with pytest.raises(RepertoireError, match="workers must be >= 1, got 0"):
        WorkerPool("repertoire.studies.pendulum", "pendulum", "{}", 0)


def test_engine_modules_are_not_taken_for_studies(monkeypatch):
    import pkgutil

    import repertoire.studies as package

    import repertoire.registry as common

    engine_like = {
        info.name
        for info in pkgutil.iter_modules(package.__path__)
        if info.name.startswith("engine") or info.name in ("store", "registry")
    }
    assert engine_like == set(registry.ENGINE_MODULES)
    imported = []

    def recording_import(name):
        imported.append(name)
        return importlib.import_module(name)

    monkeypatch.setattr(common, "importlib", types.SimpleNamespace(import_module=recording_import))
    common.discover("repertoire.studies", registry.ENGINE_MODULES, {})
    assert "repertoire.studies.pendulum" in imported
    assert not [m for m in imported if m.rsplit(".", 1)[-1] in registry.ENGINE_MODULES]


def test_workers_that_die_at_start_up_blame_no_seed_and_give_a_clear_error(tmp_path, monkeypatch):
    (tmp_path / "dies_at_import.py").write_text(
        _MODULE.replace("PoolConfig", "DiesConfig").replace("_pool_study", "_dies_study")
        + "\nimport multiprocessing\nif multiprocessing.parent_process() is not None:\n"
        "    os._exit(5)  # only in pool workers\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    module = importlib.import_module("dies_at_import")
    try:
        config_json = _config_json_of(module.DiesConfig())
        with WorkerPool("dies_at_import", "_dies_study", config_json, 2) as pool:
            with pytest.raises(RepertoireError, match=r"dying before .* exit code 5"):
                list(pool.run([0, 1, 2]))
    finally:
        registry._REGISTRY.pop("_dies_study", None)
        sys.modules.pop("dies_at_import", None)


def test_a_script_without_a_main_guard_is_told_why_its_workers_die(tmp_path):
    # Each worker runs the main script's top level: an unguarded run_study call there
    # starts a pool inside the worker, which multiprocessing refuses, so workers die.
    script = tmp_path / "unguarded.py"
    script.write_text(
        _MODULE.replace("PoolConfig", "UnguardedConfig").replace("_pool_study", "_unguarded")
        + "\nfrom repertoire.studies.engine import run_study\n"
        + f"run_study('_unguarded', episodes=2, executor='process', workers=1, "
        f"out_dir={str(tmp_path / 'out')!r}, progress=False)\n"
    )
    run = subprocess.run(
        [sys.executable, "-P", str(script)], capture_output=True, text=True, timeout=240
    )
    assert run.returncode == 1
    last = run.stderr.strip().splitlines()[-1]
    assert "pool workers keep dying before they run a seed" in last
    assert "must call run_study under `if __name__ == '__main__':`" in last


def test_fewer_seeds_than_workers_and_every_worker_is_gone_after_close(pool_study):
    pool = WorkerPool("pool_study_module", "_pool_study", _config_json(pool_study), 3)
    results = list(pool.run([5]))
    assert [(r["seed"], r["record"]["seed_cubed"]) for r in results] == [(5, 125)]
    procs = [w.proc for w in pool._workers + pool._retired]
    assert len(procs) == 3
    pool.close()
    assert [p.is_alive() for p in procs] == [False] * 3
    assert [p.exitcode for p in procs] == [0, 0, 0]  # asked to stop, not killed


def test_prestart_fork_server_leaves_a_running_server_for_the_pool():
    import multiprocessing
    from multiprocessing import forkserver

    from repertoire.studies.engine_pool import prestart_fork_server

    thread = prestart_fork_server()
    if "forkserver" not in multiprocessing.get_all_start_methods():
        assert thread is None
        return
    thread.join(120.0)
    assert not thread.is_alive()
    pid = forkserver._forkserver._forkserver_pid  # the one server every pool forks from
    assert pid is not None
    prestart_fork_server().join(120.0)  # idempotent: the same server
    assert forkserver._forkserver._forkserver_pid == pid


_SIGINT_MODULE = textwrap.dedent(
    """
    import dataclasses
    import signal

    from repertoire.studies.engine import register_study


    @dataclasses.dataclass
    class SigintConfig:
        pass


    @dataclasses.dataclass
    class SigintRecord:
        sigint_ignored: bool


    def run_episode(config, seed):
        return SigintRecord(signal.getsignal(signal.SIGINT) is signal.SIG_IGN)


    register_study("_sigint_study", config_type=SigintConfig, record_type=SigintRecord,
                   run_episode=run_episode, description="test-only")
    """
)


def test_pool_workers_leave_ctrl_c_to_the_engine(tmp_path, monkeypatch):
    # Ctrl-C signals the whole process group; a worker that took it printed its own
    # KeyboardInterrupt traceback, one per worker, around the engine's one-line message.
    (tmp_path / "sigint_module.py").write_text(_SIGINT_MODULE)
    monkeypatch.syspath_prepend(str(tmp_path))
    importlib.import_module("sigint_module")
    try:
        with WorkerPool("sigint_module", "_sigint_study", "{}", 2) as pool:
            results = list(pool.run([0, 1, 2]))
    finally:
        registry._REGISTRY.pop("_sigint_study", None)
        sys.modules.pop("sigint_module", None)
    assert [r["record"] for r in results] == [{"sigint_ignored": True}] * 3


def test_ctrl_c_on_a_pool_run_prints_one_line_and_keeps_the_store_consistent(tmp_path):
    import os
    import signal
    import time

    out = tmp_path / "out"
    # far more seeds than run before the interrupt (~85 ms each), so the run is still going
    # when Ctrl-C comes even if a loaded machine delays this test's first read of the store
    proc = start_pool_study(4000, out, tmp_path)
    store = out / "episodes.sqlite"
    deadline = time.monotonic() + 120.0
    while time.monotonic() < deadline:  # both workers run once an episode is stored
        try:
            with sqlite3.connect(f"file:{store}?mode=ro", uri=True, timeout=1.0) as db:
                if db.execute("SELECT COUNT(*) FROM episodes").fetchone()[0]:
                    break
        except sqlite3.OperationalError:
            pass
        time.sleep(0.2)
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130
    assert err.strip() == "interrupted", err  # no KeyboardInterrupt traceback per worker
    _, rows = read_store(store)
    assert 0 < len(rows) < 4000 and len({r.seed for r in rows}) == len(rows)
    for _ in range(50):  # the workers and the fork server go with the engine
        try:
            os.killpg(proc.pid, 0)
        except ProcessLookupError:
            break
        time.sleep(0.2)
    else:
        raise AssertionError("processes of the interrupted run are still alive")


_BLAS_MODULE = textwrap.dedent(
    """
    import dataclasses

    from threadpoolctl import threadpool_info

    from repertoire.studies.engine import register_study


    @dataclasses.dataclass
    class BlasConfig:
        pass


    @dataclasses.dataclass
    class BlasRecord:
        most_blas_threads: int
        blas_libraries: int


    def run_episode(config, seed):
        blas = [lib for lib in threadpool_info() if lib["user_api"] == "blas"]
        return BlasRecord(max(lib["num_threads"] for lib in blas), len(blas))


    register_study("_blas_study", config_type=BlasConfig, record_type=BlasRecord,
                   run_episode=run_episode, description="test-only")
    """
)


@pytest.mark.parametrize("executor", ["inline", "process"])
def test_every_episode_runs_with_one_blas_thread_and_inline_restores_the_limit(
    tmp_path, monkeypatch, executor
):
    import scipy.linalg  # noqa: F401  (its BLAS loaded, so `before` lists it)
    from threadpoolctl import threadpool_info, threadpool_limits

    (tmp_path / "blas_study_module.py").write_text(_BLAS_MODULE)
    monkeypatch.syspath_prepend(str(tmp_path))
    importlib.import_module("blas_study_module")
    try:
        with threadpool_limits(limits=2, user_api="blas"):  # as on a two-core machine
            before = [lib["num_threads"] for lib in threadpool_info()]
            result = run_study(
                "_blas_study",
                episodes=3,
                executor=executor,
                workers=2 if executor == "process" else None,
                out_dir=tmp_path / "out",
                progress=False,
                summarize=False,
            )
            after = [lib["num_threads"] for lib in threadpool_info()]
    finally:
        registry._REGISTRY.pop("_blas_study", None)
        sys.modules.pop("blas_study_module", None)
    # numpy's and scipy's BLAS are both loaded and both held to one thread
    assert [(r.most_blas_threads, r.blas_libraries >= 2) for r in result.records] == [(1, True)] * 3
    assert after == before
