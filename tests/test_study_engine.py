"""Tests of the Monte-Carlo study engine (repertoire.studies.engine / store / registry)."""

import dataclasses
import json
import os
import signal
import sqlite3
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
from conftest import group_alive
from repertoire.studies import registry
from repertoire.studies.engine import (
    EpisodeError,
    comparable,
    get_study,
    is_timing_field,
    load_records,
    register_study,
    run_study,
    study_main,
    study_names,
    summary_rows,
)
from repertoire.studies.pendulum import PendulumConfig, PendulumRecord, smoke_config
from repertoire.studies.store import EpisodeStore, canonical_json, from_plain, to_plain

from repertoire.errors import RepertoireError, UnknownNameError

# ---------------------------------------------------------------------------
# Test-only studies (inline executor; removed from the registry after each test).


@dataclasses.dataclass
class ToyConfig:
    scale: float = 2.0
    offsets: list[float] = dataclasses.field(default_factory=lambda: [1.0, -1.0])


@dataclasses.dataclass
class ToyRecord:
    value: float
    parity: int
    even: bool
    samples: list[float]
    wall_time_s: float


def toy_episode(config: ToyConfig, seed: int) -> ToyRecord:
    return ToyRecord(
        value=config.scale * seed,
        parity=seed % 2,
        even=seed % 2 == 0,
        samples=[o * seed for o in config.offsets],
        wall_time_s=0.0,
    )


def wrong_record_episode(config: ToyConfig, seed: int) -> dict:
    return {"value": float(seed)}


def failing_episode(config: ToyConfig, seed: int) -> ToyRecord:
    if seed == 3:
        raise FloatingPointError("diverged at seed 3")
    return toy_episode(config, seed)


def exiting_episode(config: ToyConfig, seed: int) -> ToyRecord:
    if seed == 2:
        sys.exit(4)
    return toy_episode(config, seed)


@pytest.fixture
def toy_studies():
    names = {
        "_toy": toy_episode,
        "_toy_wrong_record": wrong_record_episode,
        "_toy_failing": failing_episode,
        "_toy_exiting": exiting_episode,
    }
    for name, fn in names.items():
        register_study(
            name,
            config_type=ToyConfig,
            record_type=ToyRecord,
            run_episode=fn,
            description="test-only study",
        )
    yield names
    for name in names:
        registry._REGISTRY.pop(name, None)


def _kw(tmp_path: Path, tag: str = "s") -> dict:
    return dict(store=tmp_path / f"{tag}.sqlite", out_dir=tmp_path / f"out_{tag}", progress=False)


# ---------------------------------------------------------------------------
# Registry and bad input.


def test_pendulum_is_discovered_and_unknown_name_lists_known_ones():
    assert "pendulum" in study_names()
    entry = get_study("pendulum")
    assert entry.module == "repertoire.studies.pendulum"
    assert entry.config_type is PendulumConfig and entry.record_type is PendulumRecord
    with pytest.raises(UnknownNameError, match=r"unknown study 'no_such_study'.*pendulum"):
        run_study("no_such_study", episodes=1, progress=False)


def test_register_rejects_non_dataclass_and_nested_function():
    def local_episode(config, seed):
        return None

    with pytest.raises(RepertoireError, match="config_type must be a dataclass"):
        register_study(
            "_bad", config_type=int, record_type=ToyRecord, run_episode=toy_episode, description=""
        )
    with pytest.raises(RepertoireError, match="module-level function"):
        register_study(
            "_bad",
            config_type=ToyConfig,
            record_type=ToyRecord,
            run_episode=local_episode,
            description="",
        )
    assert "_bad" not in registry._REGISTRY


@pytest.mark.parametrize("episodes", [0, -3])
def test_non_positive_episodes_is_refused_and_creates_nothing(tmp_path, episodes):
    with pytest.raises(
        RepertoireError, match=r"--episodes \(episodes\) must be an int >= 1, got -?\d"
    ):
        run_study("pendulum", smoke_config(), episodes=episodes, executor="inline", **_kw(tmp_path))
    assert list(tmp_path.iterdir()) == []


def test_numpy_whole_numbers_count_as_ints_and_floats_or_bools_do_not(tmp_path, toy_studies):
    import numpy as np

    kw = dict(executor="inline", **_kw(tmp_path))
    result = run_study("_toy", episodes=np.int64(2), first_seed=np.uint8(3), **kw)
    assert result.seeds == [3, 4] and all(type(s) is int for s in result.seeds)
    assert [r.value for r in result.records] == [6.0, 8.0]
    for bad in (2.0, True, np.float64(2.0)):
        with pytest.raises(RepertoireError, match=r"--episodes \(episodes\) must be an int >= 1"):
            run_study("_toy", episodes=bad, **kw)


def test_other_bad_arguments(tmp_path, toy_studies):
    with pytest.raises(RepertoireError, match="executor must be one of"):
        run_study("_toy", episodes=2, executor="threads", **_kw(tmp_path))
    with pytest.raises(RepertoireError, match=r"--first-seed \(first_seed\) must be an int >= 0"):
        run_study("_toy", episodes=2, first_seed=-1, executor="inline", **_kw(tmp_path))
    with pytest.raises(RepertoireError, match="takes a ToyConfig config, got PendulumConfig"):
        run_study("_toy", smoke_config(), episodes=2, executor="inline", **_kw(tmp_path))
    with pytest.raises(RepertoireError, match=r"--executor dask needs --scheduler"):
        run_study("_toy", episodes=2, executor="dask", **_kw(tmp_path))
    for bad in ("127.0.0.1:8786", "tcp://host", "tcp://host:99999", "http://h:1", "tcp://a b:1"):
        with pytest.raises(RepertoireError, match=r"is not a Dask address; expected PROTOCOL"):
            run_study("_toy", episodes=2, executor="dask", scheduler_address=bad, **_kw(tmp_path))
    with pytest.raises(RepertoireError, match=r"--scheduler \(scheduler_address\) is only used"):
        run_study("_toy", episodes=2, scheduler_address="tcp://h:1", **_kw(tmp_path))
    (tmp_path / "a_file").write_text("x")
    with pytest.raises(RepertoireError, match=r"--out-dir \(out_dir\) .*is a file, expected a"):
        run_study("_toy", episodes=2, out_dir=tmp_path / "a_file" / "sub", store=None)
    with pytest.raises(RepertoireError, match=r"--store \(store\) .* is a folder, expected a file"):
        run_study("_toy", episodes=2, out_dir=tmp_path / "o", store=tmp_path)
    (tmp_path / "a_file").unlink()
    with pytest.raises(RepertoireError, match="damping_min <= damping_max"):
        run_study(
            "pendulum",
            PendulumConfig(damping_min=1.0, damping_max=0.5),
            episodes=2,
            executor="inline",
            **_kw(tmp_path),
        )
    assert list(tmp_path.iterdir()) == []


def test_wrong_record_type_is_a_clear_error(tmp_path, toy_studies):
    with pytest.raises(
        RepertoireError,
        match=r"returned builtins\.dict, expected the registered "
        r"record_type .*ToyRecord",
    ):
        run_study("_toy_wrong_record", episodes=2, executor="inline", **_kw(tmp_path))


def test_failing_episode_raises_with_seed_and_keeps_finished_rows(tmp_path, toy_studies):
    with pytest.raises(EpisodeError, match=r"seed 3: FloatingPointError: diverged at seed 3"):
        run_study("_toy_failing", episodes=6, executor="inline", **_kw(tmp_path))
    with sqlite3.connect(tmp_path / "s.sqlite") as db:
        assert [r[0] for r in db.execute("SELECT seed FROM episodes ORDER BY seed")] == [0, 1, 2]


def test_episode_calling_sys_exit_is_an_episode_error_not_a_silent_exit(tmp_path, toy_studies):
    # Inline, sys.exit() in an episode used to end the whole program without a word.
    with pytest.raises(EpisodeError, match=r"seed 2: SystemExit\(4\): the episode tried to exit"):
        run_study("_toy_exiting", episodes=4, executor="inline", **_kw(tmp_path))
    with sqlite3.connect(tmp_path / "s.sqlite") as db:
        assert [r[0] for r in db.execute("SELECT seed FROM episodes ORDER BY seed")] == [0, 1]


# ---------------------------------------------------------------------------
# Store, resume and config change.


def test_resume_runs_only_missing_seeds_and_tables_are_exact(tmp_path, toy_studies):
    first = run_study("_toy", episodes=4, executor="inline", **_kw(tmp_path))
    assert (first.n_run, first.n_reused) == (4, 0)
    more = run_study("_toy", episodes=6, executor="inline", **_kw(tmp_path))
    assert (more.n_run, more.n_reused) == (2, 4)
    assert more.seeds == [0, 1, 2, 3, 4, 5]
    assert [r.value for r in more.records] == [0.0, 2.0, 4.0, 6.0, 8.0, 10.0]
    assert more.records[5].samples == [5.0, -5.0]
    shifted = run_study(
        "_toy",
        episodes=3,
        first_seed=4,
        executor="inline",
        store=tmp_path / "s.sqlite",
        out_dir=tmp_path / "out_shifted",
        progress=False,
    )
    assert (shifted.n_run, shifted.n_reused, shifted.seeds) == (1, 2, [4, 5, 6])

    rows = {r["field"]: r for r in summary_rows(ToyRecord, more.records)}
    assert set(rows) == {"value", "parity", "even", "wall_time_s"}  # lists are skipped
    assert rows["value"]["mean"] == pytest.approx(5.0)
    assert rows["value"]["std"] == pytest.approx((70.0 / 6.0) ** 0.5 * 1.0)
    assert (rows["value"]["min"], rows["value"]["max"], rows["value"]["n"]) == (0.0, 10.0, 6)
    assert rows["even"]["true_rate"] == pytest.approx(0.5)
    csv_text = more.tables["summary.csv"].read_text().splitlines()
    assert csv_text[0] == "field,n,mean,std,min,max,true_rate"
    assert csv_text[1].startswith("value,6,5.0,")
    summary_md = more.tables["summary.md"].read_text()
    assert "| field | n | mean | std | min | max | true_rate |" in summary_md
    assert "| even | 6 |  |  |  |  | 0.5 |" in summary_md
    # a bool field's rate is named for what it is, not a "success" rate (a `failed`
    # or `fell` field's rate is a failure rate)
    assert "`true_rate` is, for a yes/no field, the fraction of episodes in which it is true" in (
        summary_md.replace("\n", " ")
    )
    # No summarize(): one histogram per numeric field.
    assert set(more.figures) == {"hist_value", "hist_parity", "hist_wall_time_s"}
    assert all(p.read_bytes()[:4] == b"\x89PNG" for p in more.figures.values())


def test_changed_config_is_refused_unless_fresh(tmp_path, toy_studies):
    run_study("_toy", ToyConfig(scale=2.0), episodes=3, executor="inline", **_kw(tmp_path))
    with pytest.raises(RepertoireError, match=r"another config.*scale: 2\.0 -> 3\.0.*fresh=True"):
        run_study("_toy", ToyConfig(scale=3.0), episodes=3, executor="inline", **_kw(tmp_path))
    with sqlite3.connect(tmp_path / "s.sqlite") as db:  # the refusal changed nothing
        assert db.execute("SELECT COUNT(*) FROM episodes").fetchone()[0] == 3
    again = run_study(
        "_toy", ToyConfig(scale=3.0), episodes=2, executor="inline", fresh=True, **_kw(tmp_path)
    )
    assert (again.n_run, again.n_reused) == (2, 0)
    assert [r.value for r in again.records] == [0.0, 3.0]
    with sqlite3.connect(tmp_path / "s.sqlite") as db:
        assert db.execute("SELECT COUNT(*) FROM episodes").fetchone()[0] == 2
        meta = dict(db.execute("SELECT key, value FROM meta"))
    assert meta["study"] == "_toy"
    assert json.loads(meta["config_json"]) == {"offsets": [1.0, -1.0], "scale": 3.0}
    with pytest.raises(RepertoireError) as refused:
        run_study("pendulum", smoke_config(), episodes=1, executor="inline", **_kw(tmp_path))
    assert str(refused.value) == (
        f"store '{tmp_path / 's.sqlite'}' holds study '_toy', not 'pendulum' (2 episodes of it); "
        "use another store path (--store, or --out-dir for the default one); --fresh "
        "(fresh=True) would discard them"
    )


def test_whole_numbers_given_for_float_fields_are_the_same_config_as_their_floats(
    tmp_path, toy_studies
):
    # ToyConfig(scale=2) is what a YAML "scale: 2" loads as (2.0): one config, one store.
    first = run_study(
        "_toy", ToyConfig(scale=2, offsets=[1, -1]), episodes=2, executor="inline", **_kw(tmp_path)
    )
    assert first.config == ToyConfig(scale=2.0, offsets=[1.0, -1.0])
    assert type(first.config.scale) is float and [r.value for r in first.records] == [0.0, 2.0]
    again = run_study("_toy", ToyConfig(), episodes=3, executor="inline", **_kw(tmp_path))
    assert (again.n_run, again.n_reused) == (1, 2)
    with sqlite3.connect(tmp_path / "s.sqlite") as db:
        meta = dict(db.execute("SELECT key, value FROM meta"))
    assert meta["config_json"] == '{"offsets":[1.0,-1.0],"scale":2.0}'


def test_store_never_duplicates_and_rejects_foreign_files(tmp_path):
    path = tmp_path / "x.sqlite"
    with EpisodeStore.open(path, study="a", config_json="{}", record_fields=["v"]) as db:
        assert db.insert(7, '{"v": 1}', 0.1, "h:1") is True
        assert db.insert(7, '{"v": 2}', 0.1, "h:2") is False
        assert db.count() == 1
        assert [r.record_json for r in db.load(0, 10)] == ['{"v": 1}']
        assert db.meta()["record_fields"] == '["v"]'
    with pytest.raises(RepertoireError, match="now returns"):
        EpisodeStore.open(path, study="a", config_json="{}", record_fields=["v", "w"])
    text = tmp_path / "notes.sqlite"
    text.write_text("not a database at all, just some text " * 20)
    with pytest.raises(RepertoireError, match="is not a study store"):
        EpisodeStore.open(text, study="a", config_json="{}", record_fields=["v"])


def test_plain_round_trip_and_errors():
    @dataclasses.dataclass
    class Inner:
        gains: list[float] = dataclasses.field(default_factory=list)
        label: str | None = None

    @dataclasses.dataclass
    class Outer:
        inner: Inner = dataclasses.field(default_factory=Inner)
        table: dict[str, int] = dataclasses.field(default_factory=dict)
        rate: float = 1.0

    value = Outer(Inner([1.0, 2.5], None), {"a": 3}, 2.0)
    plain = to_plain(value)
    assert plain == {"inner": {"gains": [1.0, 2.5], "label": None}, "table": {"a": 3}, "rate": 2.0}
    assert from_plain(Outer, json.loads(canonical_json(plain))) == value
    assert from_plain(Outer, {"rate": 3}) == Outer(rate=3.0)
    with pytest.raises(RepertoireError, match=r"value\.inner: unknown keys \['gain'\]"):
        from_plain(Outer, {"inner": {"gain": [1.0]}})
    with pytest.raises(RepertoireError, match=r"value\.table\.a: expected int, got 'x'"):
        from_plain(Outer, {"table": {"a": "x"}})
    with pytest.raises(RepertoireError, match=r"rec\.extra has type object"):
        to_plain({"extra": object()}, "rec")
    nan_record = ToyRecord(float("nan"), 1, True, [float("inf")], 3.0)
    assert comparable(nan_record) == comparable(dataclasses.replace(nan_record, wall_time_s=4.0))
    assert comparable(nan_record) == {"value": "nan", "parity": 1, "even": True, "samples": ["inf"]}
    assert is_timing_field("wall_time_s") and is_timing_field("wall_build_s")
    assert not is_timing_field("time_s") and not is_timing_field("wall_clock")


# ---------------------------------------------------------------------------
# Same records whatever the executor; resume after SIGKILL.


@pytest.fixture(scope="module")
def dask_cluster():
    distributed = pytest.importorskip("distributed", reason="dask.distributed not installed")
    cluster = distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    )
    yield cluster
    cluster.close()


def test_same_records_inline_process_and_dask(tmp_path, dask_cluster):
    config = smoke_config()
    n = 8
    runs = {
        "inline": run_study(
            "pendulum", config, episodes=n, executor="inline", **_kw(tmp_path, "inline")
        ),
        "process1": run_study(
            "pendulum", config, episodes=n, executor="process", workers=1, **_kw(tmp_path, "p1")
        ),
        "process2": run_study(
            "pendulum", config, episodes=n, executor="process", workers=2, **_kw(tmp_path, "p2")
        ),
        "dask2": run_study(
            "pendulum",
            config,
            episodes=n,
            executor="dask",
            scheduler_address=dask_cluster.scheduler_address,
            **_kw(tmp_path, "dask"),
        ),
    }
    reference = [comparable(r) for r in runs["inline"].records]
    assert len(reference) == n and len({r["initial_angle_rad"] for r in reference}) == n
    for label, result in runs.items():
        assert result.seeds == list(range(n)), label
        assert [comparable(r) for r in result.records] == reference, label
        assert result.figures["energy_vs_damping"].is_file()
    assert runs["process2"].workers == 2
    with sqlite3.connect(runs["process2"].store) as db:
        workers = {r[0] for r in db.execute("SELECT worker FROM episodes")}
    assert len(workers) == 2  # both pool processes ran episodes


_KILL_SCRIPT = textwrap.dedent(
    """
    import sys
    from repertoire.studies.engine import run_study
    from repertoire.studies.pendulum import demo_config

    if __name__ == "__main__":
        run_study("pendulum", demo_config(), episodes=int(sys.argv[2]), store=sys.argv[1],
                  out_dir=sys.argv[1] + ".out", executor="process", workers=2, progress=False)
    """
)


def _count_rows(path: Path) -> int:
    if not path.exists():
        return 0
    try:
        with sqlite3.connect(f"file:{path}?mode=ro", uri=True, timeout=1.0) as db:
            return db.execute("SELECT COUNT(*) FROM episodes").fetchone()[0]
    except sqlite3.OperationalError:  # tables not created yet
        return 0


def test_resume_after_sigkill_loses_nothing_and_duplicates_nothing(tmp_path):
    n = 16
    store = tmp_path / "killed.sqlite"
    script = tmp_path / "run_pendulum.py"
    script.write_text(_KILL_SCRIPT)
    proc = subprocess.Popen(
        [sys.executable, str(script), str(store), str(n)],
        start_new_session=True,
        stderr=subprocess.PIPE,
    )
    try:
        deadline = time.monotonic() + 60.0
        while _count_rows(store) < 3 and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.02)
        assert proc.poll() is None, proc.stderr.read().decode()
        os.kill(proc.pid, signal.SIGKILL)  # only the engine's process, as `kill -9 PID` would
        proc.wait(timeout=10.0)
        # The orphaned pool workers notice their parent is gone and exit by themselves.
        deadline = time.monotonic() + 15.0
        while group_alive(proc.pid) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not group_alive(proc.pid), "pool workers outlived the killed engine"
    finally:
        if group_alive(proc.pid):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.stderr.close()

    landed = _count_rows(store)
    assert 3 <= landed < n
    with sqlite3.connect(store) as db:
        assert db.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
        for (text,) in db.execute("SELECT record FROM episodes"):
            json.loads(text)

    resumed = run_study(
        "pendulum",
        get_study("pendulum").demo_config(),
        episodes=n,
        executor="inline",
        store=store,
        out_dir=tmp_path / "resumed",
        progress=False,
    )
    assert (resumed.n_reused, resumed.n_run) == (landed, n - landed)
    with sqlite3.connect(store) as db:
        counts = db.execute("SELECT seed, COUNT(*) FROM episodes GROUP BY seed ORDER BY seed")
        assert [tuple(r) for r in counts] == [(s, 1) for s in range(n)]
    clean = run_study(
        "pendulum",
        get_study("pendulum").demo_config(),
        episodes=n,
        executor="inline",
        **_kw(tmp_path, "clean"),
    )
    assert [comparable(r) for r in resumed.records] == [comparable(r) for r in clean.records]


def test_study_main_runs_and_reports_bad_input(tmp_path, capsys):
    store = tmp_path / "cli.sqlite"
    code = study_main(
        "pendulum",
        [
            "--smoke",
            "-n",
            "3",
            "--executor",
            "inline",
            "--store",
            str(store),
            "--out-dir",
            str(tmp_path / "cli"),
            "--no-progress",
        ],
    )
    assert code == 0
    out = capsys.readouterr().out
    assert "study pendulum: 3 episodes (3 run, 0 from the store)" in out
    assert "summary.md" in out and "energy_vs_damping" in out
    assert (
        study_main(
            "pendulum", ["-n", "0", "--executor", "inline", "--store", str(store), "--no-progress"]
        )
        == 2
    )
    assert "--episodes (episodes) must be an int >= 1" in capsys.readouterr().err


def test_keys_a_config_file_leaves_out_keep_the_demo_config_show_prints(
    tmp_path, toy_studies, capsys
):
    from repertoire.show import show_text

    registry._REGISTRY["_toy"].demo_config = lambda: ToyConfig(scale=5.0)
    assert "scale: 5.0" in show_text("_toy")  # "keys you leave out keep these defaults"
    (tmp_path / "partial.yaml").write_text("offsets: [2.0]\n")
    argv = ["--config", str(tmp_path / "partial.yaml"), "-n", "2", "--executor", "inline"]
    argv += ["--out-dir", str(tmp_path / "o"), "--no-progress"]
    assert study_main("_toy", argv) == 0
    config, records = load_records(tmp_path / "o" / "episodes.sqlite")
    assert config == ToyConfig(scale=5.0, offsets=[2.0])  # not ToyConfig()'s scale 2.0
    assert [(r.value, r.samples) for r in records.values()] == [(0.0, [0.0]), (5.0, [2.0])]


def interrupted_episode(config: ToyConfig, seed: int) -> ToyRecord:
    if seed == 2:
        raise KeyboardInterrupt  # as Ctrl-C during an episode
    return toy_episode(config, seed)


def test_ctrl_c_in_a_study_script_is_one_line_exit_130_and_keeps_finished_episodes(
    tmp_path, toy_studies, capsys
):
    register_study(
        "_toy_interrupted",
        config_type=ToyConfig,
        record_type=ToyRecord,
        run_episode=interrupted_episode,
        description="test-only study",
    )
    try:
        argv = ["-n", "4", "--executor", "inline", "--out-dir", str(tmp_path), "--no-progress"]
        assert study_main("_toy_interrupted", argv) == 130
        assert capsys.readouterr().err == "interrupted\n"
        assert sorted(load_records(tmp_path / "episodes.sqlite")[1]) == [0, 1]
    finally:
        registry._REGISTRY.pop("_toy_interrupted", None)


_CRASH_MODULE = textwrap.dedent(
    """
    import dataclasses
    import os

    from repertoire.studies.engine import register_study


    @dataclasses.dataclass
    class CrashConfig:
        crash_seed: int = 2


    @dataclasses.dataclass
    class CrashRecord:
        seed_squared: int


    def run_episode(config, seed):
        if seed == config.crash_seed:
            os._exit(3)  # a hard crash, as a segfaulting simulation would
        return CrashRecord(seed_squared=seed * seed)


    register_study("_crash_study", config_type=CrashConfig, record_type=CrashRecord,
                   run_episode=run_episode, description="test-only")
    """
)


def test_worker_crash_is_reported_and_study_outside_the_package_runs(tmp_path, monkeypatch):
    (tmp_path / "crash_study_module.py").write_text(_CRASH_MODULE)
    monkeypatch.syspath_prepend(str(tmp_path))  # spawned workers inherit sys.path
    import crash_study_module

    try:
        config = crash_study_module.CrashConfig(crash_seed=-1)
        ok = run_study(
            "_crash_study", config, episodes=3, executor="process", workers=1, **_kw(tmp_path, "ok")
        )
        assert [r.seed_squared for r in ok.records] == [0, 1, 4]
        with pytest.raises(EpisodeError, match=r"a worker process died .* rerun to resume"):
            run_study(
                "_crash_study",
                crash_study_module.CrashConfig(crash_seed=2),
                episodes=4,
                executor="process",
                workers=1,
                **_kw(tmp_path, "crash"),
            )
        with sqlite3.connect(tmp_path / "crash.sqlite") as db:
            stored = {r[0] for r in db.execute("SELECT seed FROM episodes")}
            crashes = list(db.execute("SELECT seed, exitcode, message FROM crashes"))
        # Exactly the crashing seed is lost; the study went on with the others.
        assert stored == {0, 1, 3}
        assert [(seed, code) for seed, code, _ in crashes] == [(2, 3)]
        assert "died (exit code 3) while running seed 2" in crashes[0][2]
        # A rerun tries the crashed seed again (and it crashes again, alone).
        with pytest.raises(EpisodeError, match=r"while running seed \[2\]"):
            run_study(
                "_crash_study",
                crash_study_module.CrashConfig(crash_seed=2),
                episodes=4,
                executor="process",
                workers=2,
                **_kw(tmp_path, "crash"),
            )
    finally:
        registry._REGISTRY.pop("_crash_study", None)
        sys.modules.pop("crash_study_module", None)


def test_engine_import_is_cheap():
    code = (
        "import sys, repertoire.studies.engine\n"
        "heavy = [m for m in ('pydrake', 'dask', 'distributed', 'matplotlib', 'numpy') "
        "if m in sys.modules]\n"
        "print(heavy)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_load_records_reads_a_store_back(tmp_path, toy_studies):
    from repertoire.studies.engine import load_records

    run_study("_toy", ToyConfig(scale=4.0), episodes=3, executor="inline", **_kw(tmp_path))
    config, records = load_records(tmp_path / "s.sqlite", "_toy")
    assert config == ToyConfig(scale=4.0)
    assert {seed: r.value for seed, r in records.items()} == {0: 0.0, 1: 4.0, 2: 8.0}
    with pytest.raises(RepertoireError, match="holds study '_toy', not 'pendulum'"):
        load_records(tmp_path / "s.sqlite", "pendulum")
    with pytest.raises(RepertoireError, match="does not exist"):
        load_records(tmp_path / "missing.sqlite")


def test_both_registries_share_one_mechanism_with_the_same_errors(isolated_registry):
    from repertoire.diagrams.registry import get_diagram_entry, register_diagram
    from repertoire.studies import registry as study_registry

    def other_build(scenario, *, meshcat=None):
        return None

    with pytest.raises(RepertoireError, match="diagram name 'test_pendulum' registered twice"):
        register_diagram("test_pendulum", scenario_type=object, description="clash")(other_build)
    with pytest.raises(RepertoireError, match="diagram name must be a non-empty string"):
        register_diagram("", scenario_type=object, description="no name")(other_build)
    with pytest.raises(UnknownNameError, match=r"unknown diagram 'x'; registered diagram names"):
        get_diagram_entry("x")
    with pytest.raises(UnknownNameError, match=r"unknown study 'x'; registered study names"):
        study_registry.get_study("x")
    assert study_registry.broken_modules() == {}


def test_a_study_module_ends_in_one_call_that_runs_main_only_as_a_script(tmp_path, monkeypatch):
    entry = get_study("pendulum")
    assert entry.run_if_main("repertoire.studies.pendulum") is entry
    argv = ["pendulum", "--smoke", "-n", "1", "--executor", "inline", "--out-dir", str(tmp_path)]
    monkeypatch.setattr(sys, "argv", argv)
    with pytest.raises(SystemExit) as stop:
        entry.run_if_main("__main__")
    assert stop.value.code == 0
    assert (tmp_path / "summary.md").read_text().startswith("# Study `pendulum`: 1 episodes")


def test_summaries_skip_identifiers_and_missing_values():
    from repertoire.studies.engine import summary_rows

    @dataclasses.dataclass
    class Rec:
        seed: int
        length_m: float | None
        ok: bool

    rows = summary_rows(Rec, [Rec(0, 2.0, True), Rec(1, None, False), Rec(2, 4.0, True)])
    assert [r["field"] for r in rows] == ["length_m", "ok"]
    assert rows[0]["n"] == 2 and rows[0]["mean"] == 3.0 and rows[0]["min"] == 2.0
    assert rows[1]["n"] == 3 and rows[1]["true_rate"] == pytest.approx(2 / 3)


def test_the_store_lives_in_the_out_dir_and_summaries_cover_every_stored_seed(tmp_path):
    kw = dict(executor="inline", progress=False, out_dir=tmp_path / "o")
    run_study("pendulum", smoke_config(), episodes=3, **kw)
    assert (tmp_path / "o" / "episodes.sqlite").is_file()
    result = run_study("pendulum", smoke_config(), episodes=1, **kw)  # a smaller rerun
    assert result.n_reused == 1 and len(result.records) == 1
    summary = (tmp_path / "o" / "summary.md").read_text()
    assert summary.startswith("# Study `pendulum`: 3 episodes (seeds 0..2)")
    assert "| seed |" not in summary


def test_a_wrong_type_in_yaml_names_its_field_and_a_config_is_called_a_config(tmp_path):
    from repertoire.diagrams.scenario import load_scenario

    with pytest.raises(RepertoireError, match=r"field 'duration_s' expects a number .*'two'"):
        load_scenario(PendulumConfig, data="duration_s: two")
    with pytest.raises(RepertoireError, match=r"^config file '.*nope.yaml' does not exist"):
        load_scenario(PendulumConfig, filename=tmp_path / "nope.yaml", what="config")


def test_figures_cover_every_stored_seed_like_the_tables(tmp_path, toy_studies):
    seen = []
    registry._REGISTRY["_toy"].summarize = lambda records, config, out: (
        seen.append([r.value for r in records]) or {}
    )
    run_study("_toy", episodes=3, executor="inline", **_kw(tmp_path))
    later = run_study("_toy", episodes=2, first_seed=5, executor="inline", **_kw(tmp_path))
    assert later.seeds == [5, 6] and len(later.records) == 2  # the result: this call's
    assert seen == [[0.0, 2.0, 4.0], [0.0, 2.0, 4.0, 10.0, 12.0]]  # the figures: all stored
    assert "Every one of the 5 episodes stored" in later.tables["summary.md"].read_text()
    assert "5 episodes (seeds 0..2, 5..6)" in later.tables["summary.md"].read_text()


def test_seed_ranges_name_exactly_the_stored_seeds():
    from repertoire.studies.engine_summary import seed_ranges

    assert seed_ranges([3]) == "3"
    assert seed_ranges([2, 0, 1, 10, 11, 7]) == "0..2, 7, 10..11"
    assert seed_ranges(list(range(0, 40, 2)), most=2) == "0, 2, ... (20 ranges)"


@dataclasses.dataclass
class SeededRecord:
    seed: int
    value: float


def test_episodes_csv_has_one_seed_column_when_the_record_keeps_its_seed(tmp_path):
    import csv

    from repertoire.studies.engine import write_tables

    rows = lambda p: list(csv.reader(p.read_text().splitlines()))  # noqa: E731
    recs = [SeededRecord(4, 0.5), SeededRecord(9, 1.5)]
    tables = write_tables("x", SeededRecord, recs, [4, 9], tmp_path)
    assert rows(tables["episodes.csv"]) == [["seed", "value"], ["4", "0.5"], ["9", "1.5"]]
    # A record whose seed field disagrees with the store keeps both, under two names.
    tables = write_tables("x", SeededRecord, recs, [4, 8], tmp_path)
    assert rows(tables["episodes.csv"])[0] == ["stored_seed", "seed", "value"]
    assert rows(tables["episodes.csv"])[2] == ["8", "9", "1.5"]
    tables = write_tables("x", ToyRecord, [toy_episode(ToyConfig(), 3)], [3], tmp_path)
    assert rows(tables["episodes.csv"])[0] == ["seed", "value", "parity", "even", "samples"] + [
        "wall_time_s"
    ]
