"""Round 4 of unusual and bad input to the command line, scenario loading and the study engine."""

import dataclasses
import math
import sqlite3

import pytest
from conftest import PendulumScenario
from repertoire.diagrams.scenario import load_scenario
from repertoire.studies import registry
from repertoire.studies.engine import register_study, run_study

from repertoire.cli import main
from repertoire.errors import RepertoireError, ScenarioError


@dataclasses.dataclass
class FuzzConfig:
    scale: float = 1.0


@dataclasses.dataclass
class FuzzRecord:
    value: float = 0.0


def fuzz_episode(config: FuzzConfig, seed: int) -> FuzzRecord:
    if not config.scale > 0.0:
        raise RepertoireError(f"scale must be > 0, got {config.scale}")
    return FuzzRecord(value=config.scale * seed)


@pytest.fixture
def fuzz_study():
    register_study(
        "_fuzz4",
        config_type=FuzzConfig,
        record_type=FuzzRecord,
        run_episode=fuzz_episode,
        description="test-only study",
    )
    yield "_fuzz4"
    registry._REGISTRY.pop("_fuzz4", None)


def _run(tmp_path, config=None, **kw):
    kw = dict(episodes=2, executor="inline", progress=False, out_dir=tmp_path / "out") | kw
    return run_study("_fuzz4", config or FuzzConfig(), **kw)


# ---------------------------------------------------------------------------
# Scenario / config YAML.


@pytest.mark.parametrize(
    "text, key, line",
    [("angle: 1.0\nangle: 2.0\n", "angle", 2), ("angle: 1.0\ntorque: 0\ntorque: 1\n", "torque", 3)],
)
def test_a_key_given_twice_is_refused_not_silently_overwritten(text, key, line):
    with pytest.raises(ScenarioError) as e:
        load_scenario(PendulumScenario, data=text)
    assert f"key '{key}' is given twice (again on line {line})" in str(e.value)


def test_a_key_given_twice_inside_a_nested_mapping_is_refused():
    with pytest.raises(ScenarioError, match="key 'a' is given twice"):
        load_scenario(PendulumScenario, data="angle: 1.0\nx: {a: 1, a: 2}\n")


@dataclasses.dataclass
class Inner:
    k: float = 1.0


@dataclasses.dataclass
class Outer:
    xs: list[float] = dataclasses.field(default_factory=lambda: [0.0, 1.0])
    gains: dict[str, float] = dataclasses.field(default_factory=dict)
    inner: Inner = dataclasses.field(default_factory=Inner)


@pytest.mark.parametrize(
    "text, reason",
    [
        ("inner: {k: x}", "field 'inner.k' expects a number (float), got 'x' (str)"),
        ("inner: 3", "field 'inner' expects a mapping of Inner fields, got 3 (int)"),
        ("xs: 1", "field 'xs' expects a list, got 1 (int)"),
        ("xs: [0.5, a]", "field 'xs[1]' expects a number (float), got 'a' (str)"),
        ("gains: 3", "field 'gains' expects a mapping, got 3 (int)"),
        ("gains: {kp: [1]}", "field 'gains.kp' expects a number (float), got [1] (list)"),
    ],
)
def test_a_wrong_type_inside_a_list_dict_or_nested_field_names_that_field(text, reason):
    with pytest.raises(ScenarioError) as e:
        load_scenario(Outer, data=text)
    assert f"from scenario YAML text: {reason}. Expected keys: ['xs', 'gains', 'inner']" in str(
        e.value
    )


@dataclasses.dataclass
class Holder:
    items: list[Inner] = dataclasses.field(default_factory=list)
    by_name: dict[str, Inner] = dataclasses.field(default_factory=dict)


@pytest.mark.parametrize(
    "schema, text, reason",
    [
        (Outer, "inner: {kk: 2.0}", "field 'inner' has unknown keys ['kk']; Inner expects ['k']"),
        (Holder, "items: [{k: 1.0}, {k: 2.0, kk: 3.0}]", "field 'items[1]' has unknown keys"),
        (Holder, "by_name: {a: {K: 1.0}}", "field 'by_name.a' has unknown keys ['K']"),
    ],
)
def test_an_unknown_key_of_a_nested_mapping_names_where_it_is_and_what_fits(schema, text, reason):
    # Drake's loader says only "The fields ['kk'] were unknown to the schema", and the
    # top-level keys listed after it do not hold the nested field's name.
    with pytest.raises(ScenarioError) as e:
        load_scenario(schema, data=text)
    assert reason in str(e.value)


def test_an_unknown_top_level_key_keeps_the_loaders_message():
    with pytest.raises(ScenarioError, match=r"The fields \['xz'\] were unknown to the schema"):
        load_scenario(Outer, data="xz: [1.0]")


@dataclasses.dataclass
class Scalars:
    n: int = 0
    enabled: bool = False


@pytest.mark.parametrize(
    "schema, text, reason",
    [
        # 1e-3 and "0.5" load as numbers (PyYAML alone reads them as strings)
        (Outer, "xs: [1e-3, '0.5']\ninner: {k: x}", "field 'inner.k' expects a number"),
        (Outer, "xs: [1e-3]\nxz: 1", "The fields ['xz'] were unknown to the schema"),
        (Scalars, "n: 2.0\nenabled: 'true'\nzz: 1", "The fields ['zz'] were unknown to the schema"),
        (Scalars, "n: 2.5", "field 'n' expects a whole number (int), got 2.5 (float)"),
        (
            Scalars,
            "enabled: 'yes'",
            "field 'enabled' expects true or false (bool), got 'yes' (str)",
        ),
    ],
)
def test_a_value_the_loader_takes_is_never_blamed_for_another_error(schema, text, reason):
    with pytest.raises(ScenarioError) as e:
        load_scenario(schema, data=text)
    assert reason in str(e.value)
    assert load_scenario(Outer, data="xs: [1e-3, '0.5']").xs == [0.001, 0.5]


def test_malformed_yaml_is_reported_on_one_line():
    with pytest.raises(ScenarioError) as e:
        load_scenario(PendulumScenario, data="angle: [1\n")
    assert "\n" not in str(e.value)
    assert "expected ',' or ']'" in str(e.value)


# ---------------------------------------------------------------------------
# Study engine.


def test_a_stored_record_that_is_not_json_is_a_clear_error(tmp_path, fuzz_study):
    _run(tmp_path)
    with sqlite3.connect(tmp_path / "out" / "episodes.sqlite") as conn:
        conn.execute("UPDATE episodes SET record='{not json' WHERE seed=1")
    with pytest.raises(RepertoireError, match="stored record for seed 1 does not fit FuzzRecord"):
        _run(tmp_path)


@pytest.mark.parametrize("table", ["summary.csv", "summary.md", "episodes.csv"])
def test_a_folder_in_place_of_a_table_is_refused_before_any_episode(tmp_path, fuzz_study, table):
    (tmp_path / "out" / table).mkdir(parents=True)
    with pytest.raises(RepertoireError, match=f"'{tmp_path / 'out' / table}' is a folder"):
        _run(tmp_path)
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [table]


def test_an_episode_rejecting_the_config_leaves_no_store_and_no_folder(tmp_path, fuzz_study):
    with pytest.raises(RepertoireError, match="seed 0: scale must be > 0, got -1.0"):
        _run(tmp_path, FuzzConfig(scale=-1.0), out_dir=tmp_path / "a" / "b")
    assert list(tmp_path.iterdir()) == []


def test_an_episode_rejecting_the_config_keeps_an_existing_store(tmp_path, fuzz_study):
    store = tmp_path / "s.sqlite"
    _run(tmp_path, store=store)
    with pytest.raises(RepertoireError, match="scale must be > 0"):
        _run(tmp_path, FuzzConfig(scale=-1.0), store=store, fresh=True)
    # --fresh with a config no episode accepts: the store holds its episodes and config still
    again = _run(tmp_path, store=store)
    assert (again.n_run, again.n_reused) == (0, 2)
    assert [r.value for r in again.records] == [0.0, 1.0]
    assert sorted(p.name for p in tmp_path.iterdir() if "before-fresh" in p.name) == []
    # a config that runs replaces them as asked
    fresh = _run(tmp_path, FuzzConfig(scale=3.0), store=store, fresh=True)
    assert (fresh.n_run, [r.value for r in fresh.records]) == (2, [0.0, 3.0])
    assert _run(tmp_path, FuzzConfig(scale=3.0), store=store).n_reused == 2


def test_fresh_over_a_file_that_is_no_store_is_refused_and_left_alone(tmp_path, fuzz_study):
    junk = tmp_path / "s.sqlite"
    junk.write_bytes(b"not a database at all" * 100)
    with pytest.raises(RepertoireError, match="is not a study store"):
        _run(tmp_path, store=junk, fresh=True)
    assert junk.read_bytes() == b"not a database at all" * 100
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.sqlite"]


def test_cli_bad_config_found_by_an_episode_exits_2_and_writes_nothing(
    tmp_path, fuzz_study, capsys
):
    config = tmp_path / "c.yaml"
    config.write_text("scale: -2.0\n")
    out = tmp_path / "out"
    argv = ["study", "_fuzz4", "--config", str(config), "--out-dir", str(out), "--no-progress"]
    assert main([*argv, "--executor", "inline", "-n", "1"]) == 2
    err = capsys.readouterr().err
    assert err == "repertoire study: error: study '_fuzz4', seed 0: scale must be > 0, got -2.0\n"
    assert not out.exists()


# ---------------------------------------------------------------------------
# render / simulate output paths and options, checked before any work.


@pytest.mark.parametrize("fmt", ["dot", "svg", "png"])
def test_render_refuses_a_folder_in_place_of_an_output_file(
    tmp_path, isolated_registry, capsys, fmt
):
    (tmp_path / f"test_pendulum.{fmt}").mkdir()
    assert main(["render", "test_pendulum", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err == (
        f"repertoire render: error: --out '{tmp_path / f'test_pendulum.{fmt}'}' is a folder, "
        "expected a file path\n"
    )
    assert [p.name for p in tmp_path.iterdir()] == [f"test_pendulum.{fmt}"]


def test_simulate_replay_refuses_a_folder_in_place_of_the_html(tmp_path, isolated_registry, capsys):
    (tmp_path / "test_pendulum.html").mkdir()
    assert main(["simulate", "test_pendulum", "--replay", "--out", str(tmp_path)]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    assert f"--out '{tmp_path / 'test_pendulum.html'}' is a folder" in err


@pytest.mark.parametrize("seconds", ["nan", "inf", "-1"])
def test_simulate_refuses_bad_live_seconds_before_simulating(isolated_registry, capsys, seconds):
    assert main(["simulate", "test_pendulum", "--live", "--live-seconds", seconds]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    assert err == (
        "repertoire simulate: error: --live-seconds must be a finite number >= 0, "
        f"got {float(seconds)}\n"
    )


@pytest.mark.parametrize("first_seed", [2**62 - 1, 2**62, 2**63 - 1, 2**70])
def test_seeds_past_the_store_limit_are_refused_before_any_work(tmp_path, fuzz_study, first_seed):
    with pytest.raises(RepertoireError, match=f"below 2\\*\\*62 .*first_seed\\) {first_seed} "):
        _run(tmp_path, first_seed=first_seed)
    assert list(tmp_path.iterdir()) == []


def test_the_last_seed_below_the_store_limit_runs(tmp_path, fuzz_study):
    result = _run(tmp_path, first_seed=2**62 - 1, episodes=1)
    assert result.seeds == [2**62 - 1]


def test_a_huge_episode_count_is_refused_by_its_memory_estimate(tmp_path, fuzz_study):
    with pytest.raises(RepertoireError, match="episodes=100000000 would need about 18.6 GiB"):
        _run(tmp_path, episodes=10**8)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("values", [[4.6e18], [1e16, 1e16, 1e16], [1e300, 1e300 * (1 + 1e-16)]])
def test_histograms_of_huge_nearly_equal_values_are_written(tmp_path, values):
    from repertoire.studies.engine_summary import write_histograms

    figures = write_histograms(FuzzRecord, [FuzzRecord(value=v) for v in values], tmp_path)
    assert figures == {"hist_value": tmp_path / "hist_value.png"}
    assert (tmp_path / "hist_value.png").stat().st_size > 0


def test_a_histogram_of_a_field_with_no_finite_value_says_so_on_a_count_axis_from_zero():
    # It was an empty frame whose count axis ran from -0.05 to 0.05.
    from repertoire.studies.engine_summary import histogram_figure

    fig = histogram_figure("gap_m", [math.nan, None, math.inf], 3)
    (ax,) = fig.axes
    assert ax.get_ylim() == (0.0, 1.0)
    assert [t.get_text() for t in ax.texts] == ["no finite value"]
    assert ax.get_title() == "gap_m over 0 episodes (3 missing or non-finite left out)"
    assert list(ax.get_yticks()) == []
    fig = histogram_figure("gap_m", [1.0, 2.0, math.nan], 3)
    (ax,) = fig.axes
    assert ax.get_ylim()[0] == 0.0 and len(ax.texts) == 0
    assert sum(p.get_height() for p in ax.patches) == 2
    assert ax.get_title() == "gap_m over 2 episodes (1 missing or non-finite left out)"


@dataclasses.dataclass
class NestedConfig:
    scale: float = 1.0
    ranges: dict[str, list[float]] = dataclasses.field(default_factory=dict)


def nested_episode(config: NestedConfig, seed: int) -> FuzzRecord:
    return FuzzRecord(value=float(seed))


@pytest.mark.parametrize(
    "config, where",
    [
        (NestedConfig(scale=float("nan")), "config.scale"),
        (NestedConfig(ranges={"x": [0.0, float("nan")]}), "config.ranges.x[1]"),
    ],
)
def test_a_nan_anywhere_in_a_study_config_is_refused_naming_the_field(tmp_path, config, where):
    register_study(
        "_fuzz4_nested",
        config_type=NestedConfig,
        record_type=FuzzRecord,
        run_episode=nested_episode,
        description="test-only study",
    )
    try:
        with pytest.raises(RepertoireError) as e:
            run_study("_fuzz4_nested", config, executor="inline", out_dir=tmp_path / "o")
    finally:
        registry._REGISTRY.pop("_fuzz4_nested", None)
    assert str(e.value) == f"study '_fuzz4_nested': {where} is NaN; expected a number"
    assert list(tmp_path.iterdir()) == []


def test_a_store_whose_meta_was_lost_is_not_wiped_without_fresh(tmp_path, fuzz_study):
    store = tmp_path / "s.sqlite"
    _run(tmp_path, store=store)
    with sqlite3.connect(store) as conn:
        conn.execute("DELETE FROM meta")
    with pytest.raises(RepertoireError, match="holds 2 episodes but no meta"):
        _run(tmp_path, store=store)
    with sqlite3.connect(store) as conn:
        assert conn.execute("SELECT COUNT(*) FROM episodes").fetchone()[0] == 2
    assert _run(tmp_path, store=store, fresh=True).n_run == 2
