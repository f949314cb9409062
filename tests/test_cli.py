"""The `repertoire` command line and `repertoire demo`, on test-only worlds and studies."""

import dataclasses
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import PendulumScenario, build_pendulum

from repertoire.cli import main
from repertoire.demo import run_demo


@dataclasses.dataclass
class ToyConfig:
    scale: float = 2.0


@dataclasses.dataclass
class ToyRecord:
    value: float = 0.0
    wall_time_s: float = 0.0


def run_toy_episode(config: ToyConfig, seed: int) -> ToyRecord:
    return ToyRecord(value=config.scale * float(np.random.default_rng(seed).random()))


def run_broken_episode(config: ToyConfig, seed: int) -> ToyRecord:
    raise RuntimeError(f"episode {seed} exploded")


def build_broken(scenario: PendulumScenario, *, meshcat=None):
    raise RuntimeError("this world cannot be built")


def build_diverging(scenario: PendulumScenario, *, meshcat=None):
    return build_pendulum(PendulumScenario(torque=1e200), meshcat=meshcat)


@pytest.fixture
def registries(isolated_registry, monkeypatch):
    """Diagram registry with test_pendulum; study registry with toy_study only."""
    from repertoire.studies import registry as study_registry

    monkeypatch.setattr(study_registry, "_REGISTRY", {})
    monkeypatch.setattr(study_registry, "_LOADED", True)
    study_registry.register_study(
        "toy_study",
        config_type=ToyConfig,
        record_type=ToyRecord,
        run_episode=run_toy_episode,
        description="test-only toy study",
        demo_config=lambda: ToyConfig(scale=3.0),
        demo_episodes=3,
        smoke_config=lambda: ToyConfig(scale=1.0),
    )
    return isolated_registry, study_registry


@pytest.fixture
def broken_parts(registries):
    diagrams, studies = registries
    diagrams.register_diagram(
        "test_broken", scenario_type=PendulumScenario, description="a world whose builder fails"
    )(build_broken)
    diagrams.register_diagram(
        "test_diverging", scenario_type=PendulumScenario, description="a world that blows up"
    )(build_diverging)
    studies.register_study(
        "broken_study",
        config_type=ToyConfig,
        record_type=ToyRecord,
        run_episode=run_broken_episode,
        description="a failing study",
    )
    return registries


def test_help_works_as_a_module_and_shows_every_command_with_examples():
    run = subprocess.run(
        [sys.executable, "-m", "repertoire", "--help"], capture_output=True, text=True, timeout=60
    )
    assert run.returncode == 0, run.stderr
    for command in (
        "list",
        "render",
        "simulate",
        "study",
        "demo",
        "examples:",
        "repertoire simulate littledog_stand",
        "Exit codes",
    ):
        assert command in run.stdout


@pytest.mark.parametrize(
    "command, option",
    [
        ("render", "--max-depth"),
        ("simulate", "--replay"),
        ("simulate", "--live"),
        ("study", "--episodes"),
        ("study", "--scheduler"),
        ("demo", "--quick"),
    ],
)
def test_subcommand_help(capsys, command, option):
    with pytest.raises(SystemExit) as exit_info:
        main([command, "--help"])
    assert exit_info.value.code == 0
    out = capsys.readouterr().out
    assert option in out and "example" in out


def test_simulate_help_states_the_duration_limit(capsys):
    from repertoire.diagrams.simulate import MAX_DURATION_S

    with pytest.raises(SystemExit):
        main(["simulate", "--help"])
    assert f"at most {MAX_DURATION_S:g}" in capsys.readouterr().out


def test_usage_errors_exit_2(capsys):
    for argv in ([], ["frobnicate"], ["render"], ["render", "x", "--max-depth", "two"]):
        with pytest.raises(SystemExit) as exit_info:
            main(argv)
        assert exit_info.value.code == 2


def test_list_names_diagrams_and_studies(registries, capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    assert "test_pendulum" in out and "test-only pendulum [0.2 s]" in out
    assert "toy_study" in out and "test-only toy study" in out


@pytest.mark.parametrize(
    "argv, what",
    [
        (["render", "nope", "--out", "{out}"], "diagram"),
        (["simulate", "nope", "--replay", "--out", "{out}"], "diagram"),
        (["study", "nope", "--out-dir", "{out}", "--store", "{out}/s.sqlite"], "study"),
    ],
)
def test_unknown_name_lists_known_names_exits_2_writes_nothing(
    registries, tmp_path, capsys, argv, what
):
    out = tmp_path / "out"
    assert main([a.format(out=out) for a in argv]) == 2
    err = capsys.readouterr().err
    assert f"unknown {what} 'nope'" in err
    assert ("test_pendulum" if what == "diagram" else "toy_study") in err
    assert not out.exists()


def test_render_writes_graph_files(registries, tmp_path, capsys):
    assert main(["render", "test_pendulum", "--out", str(tmp_path), "--max-depth", "1"]) == 0
    for suffix in (".dot", ".svg", ".png"):
        assert (tmp_path / f"test_pendulum{suffix}").is_file()
    assert f"wrote {tmp_path / 'test_pendulum.svg'}" in capsys.readouterr().out


def test_simulate_prints_check_figures_and_writes_replay(registries, tmp_path, capsys):
    assert main(["simulate", "test_pendulum", "--duration", "0.1"]) == 0
    out = capsys.readouterr().out
    assert "test_pendulum: simulated 0.1 s" in out and "angle_rad = " in out
    scenario = tmp_path / "hanging.yaml"
    scenario.write_text("angle: 0.0\n")
    assert (
        main(
            [
                "simulate",
                "test_pendulum",
                "--scenario",
                str(scenario),
                "--replay",
                "--out",
                str(tmp_path / "sim"),
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert "angle_rad = 0\n" in out and "energy_J = -4.905\n" in out
    assert (tmp_path / "sim" / "test_pendulum.html").stat().st_size > 100_000


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--duration", "-1"], "duration must be a finite number of seconds > 0"),
        (
            ["--duration", "1e12"],
            "duration must be at most 3600 s (one simulated hour per run), got 1e+12",
        ),
        (["--duration", "3600.5"], "duration must be at most 3600 s"),
        (["--scenario", "{tmp}/bad.yaml"], "could not load PendulumScenario"),
        (["--scenario", "{tmp}/missing.yaml"], "does not exist"),
        (["--live-seconds", "3"], "--live-seconds needs --live"),
    ],
)
def test_simulate_bad_input_exits_2_writes_nothing(registries, tmp_path, capsys, extra, message):
    (tmp_path / "bad.yaml").write_text("angle: 0.1\nspeed: 3\n")
    out = tmp_path / "sim"
    argv = ["simulate", "test_pendulum", "--replay", "--out", str(out)]
    assert main(argv + [a.format(tmp=tmp_path) for a in extra]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_study_runs_stores_and_summarizes(registries, tmp_path, capsys):
    argv = [
        "study",
        "toy_study",
        "--episodes",
        "3",
        "--executor",
        "inline",
        "--no-progress",
        "--store",
        str(tmp_path / "toy.sqlite"),
        "--out-dir",
        str(tmp_path / "toy"),
    ]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "study toy_study: 3 episodes" in out
    assert (tmp_path / "toy.sqlite").is_file()
    assert (tmp_path / "toy" / "summary.csv").is_file()
    assert main(argv[:2] + ["--episodes", "0"] + argv[4:]) == 2
    assert "episodes" in capsys.readouterr().err


def test_demo_reports_every_part_and_exits_1_when_one_fails(broken_parts, tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--quick"]) == 1
    printed = capsys.readouterr().out
    # The healthy world and study still produced everything.
    for rel in (
        "diagrams/test_pendulum.svg",
        "diagrams/test_pendulum.png",
        "diagrams/test_pendulum.dot",
        "replays/test_pendulum.html",
        "studies/toy_study/summary.csv",
        "studies/toy_study/episodes.sqlite",
        "index.md",
    ):
        assert (out / rel).is_file(), rel
    assert "angle_rad = " in printed and "energy_J = " in printed
    assert "3 part(s) FAILED" in printed
    assert (out / "diagrams" / "test_diverging.svg").is_file()  # rendered before it blew up
    assert "diagram test_diverging: errored: simulate/replay: SimulationDivergedError" in printed
    assert "replay html (up to the failure): " in printed
    assert (
        "diagram test_broken: errored: render: RuntimeError: this world cannot be built" in printed
    )
    assert "study broken_study:" in printed and "exploded" in printed
    index = (out / "index.md").read_text()
    assert "### test_pendulum - passed" in index and "### toy_study - passed" in index
    assert "[replays/test_pendulum.html](replays/test_pendulum.html)" in index
    assert "### test_broken - errored" in index and "### broken_study - errored" in index


def test_demo_all_ok(registries, tmp_path):
    result = run_demo(tmp_path / "demo", quick=True, printer=lambda line: None)
    assert result.ok and result.failures == []
    assert [(i.kind, i.name) for i in result.items] == [
        ("diagram", "test_pendulum"),
        ("study", "toy_study"),
    ]
    pendulum, toy = result.items
    assert pendulum.figures["sim_time_s"] == pytest.approx(0.2)
    assert toy.figures["episodes"] == 2  # quick: at most 2 episodes of the smoke config
    assert [i.status for i in result.items] == ["passed", "passed"]
    index = result.index_path.read_text()
    assert "## Failures\n\nnone" in index
    assert "Written by `repertoire demo --quick`" in index
    assert "Its figures show truncated runs" in index


def test_demo_fails_a_world_whose_figures_miss_its_criteria(registries, tmp_path, capsys):
    from repertoire.diagrams import registry

    from repertoire.criteria import Bound

    entry = registry.get_diagram_entry("test_pendulum")
    entry.criteria = {"energy_J": Bound(lo=1e9)}
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--quick"]) == 1
    printed = capsys.readouterr().out
    assert "diagram test_pendulum: failed" in printed
    assert "failed criterion: energy_J = " in printed and "expected >= 1e+09" in printed
    assert "study toy_study: passed" in printed
    assert "### test_pendulum - failed" in (out / "index.md").read_text()


def test_simulate_live_prints_the_url_first_and_serves_for_the_given_time(registries, capsys):
    argv = ["simulate", "test_pendulum", "--duration", "0.05", "--live", "--live-seconds", "0.2"]
    assert main(argv) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("live view at http://localhost:")
    assert lines[1].startswith("test_pendulum: simulated 0.05 s")
    assert lines[-1].startswith("serving http://localhost:") and "Ctrl-C or 0.2 s" in lines[-1]


def test_output_paths_are_checked_before_any_work(registries, tmp_path, capsys):
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    for argv in (
        ["render", "test_pendulum", "--out", str(a_file)],
        ["simulate", "test_pendulum", "--replay", "--out", str(a_file / "sub")],
        ["demo", "--quick", "--out", str(a_file)],
        ["study", "toy_study", "--out-dir", str(a_file), "--executor", "inline"],
    ):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert "is a file, expected a folder" in err and err.count("\n") == 1, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file"]


def test_unwritable_folders_are_refused_before_any_work_even_for_root(registries, tmp_path, capsys):
    # /proc refuses new files even to root, so this runs the real check whoever runs the tests.
    unwritable = Path("/proc/repertoire-test-out")
    if not Path("/proc").is_dir():
        pytest.skip("no /proc on this system")
    for argv in (
        ["render", "test_pendulum", "--out", str(unwritable)],
        ["simulate", "test_pendulum", "--replay", "--out", str(unwritable)],
        ["demo", "--quick", "--out", str(unwritable / "demo")],
        ["study", "toy_study", "--out-dir", str(unwritable), "--executor", "inline"],
        ["study", "toy_study", "--store", "/proc/s.sqlite", "--out-dir", str(tmp_path / "o")],
    ):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert "cannot write in folder '/proc'" in err and err.count("\n") == 1, err
    assert list(tmp_path.iterdir()) == []
    assert not [p for p in Path("/proc").glob(".repertoire-write-probe-*")]


def test_writable_checks_probe_and_leave_nothing_behind(tmp_path):
    from repertoire.errors import RepertoireError
    from repertoire.limits import require_writable_dir, require_writable_file

    existing = tmp_path / "kept.sqlite"
    existing.write_bytes(b"abc")
    require_writable_dir(tmp_path / "new" / "deeper", "--out")
    require_writable_file(existing, "--store")
    require_writable_file(tmp_path / "new.sqlite", "--store")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["kept.sqlite"]
    assert existing.read_bytes() == b"abc"
    with pytest.raises(RepertoireError, match="--store '.*' is a folder, expected a file path"):
        require_writable_file(tmp_path, "--store")
    with pytest.raises(RepertoireError, match="'.*kept.sqlite' is a file, expected a folder"):
        require_writable_dir(existing / "sub", "--out")


def test_demo_holds_a_study_to_its_criteria_on_summary_figures(registries, tmp_path, capsys):
    from repertoire.criteria import Bound

    _, studies = registries
    studies.get_study("toy_study").criteria = {"mean_value": Bound(hi=-1e9)}
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--quick"]) == 1
    printed = capsys.readouterr().out
    assert "study toy_study: failed" in printed
    assert "failed criterion: mean_value = " in printed and "expected <= -1e+09" in printed


def test_a_failing_episode_is_a_failed_run_exit_1_without_an_engine_traceback(
    broken_parts, tmp_path, capsys
):
    argv = ["study", "broken_study", "--executor", "inline", "--out-dir", str(tmp_path / "b")]
    assert main([*argv, "-n", "2", "--no-progress"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("repertoire study: run failed: study 'broken_study': run_episode failed")
    assert "RuntimeError: episode 0 exploded" in err and "rerun to resume" in err


def test_output_piped_into_a_reader_that_stops_early_ends_without_a_traceback():
    # `repertoire list | head -1`: the reader is gone before the command prints.
    proc = subprocess.Popen(
        [sys.executable, "-m", "repertoire", "list"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    proc.stdout.close()
    err = proc.stderr.read()
    assert proc.wait(timeout=120) == 141
    assert "Traceback" not in err and "BrokenPipeError" not in err, err


@pytest.mark.parametrize(
    "name, yaml_text, message",
    [
        # a start faster than the wheels turn: was Drake's bare "factorization not ready"
        # (soccer_goto_pose) or a run to a chassis 4e10 m away (soccer_plan), exit 0
        (
            "soccer_goto_pose",
            "initial_speed: 1.0e6\n",
            "initial_speed must be finite and within +-1.17 m/s (wheel speed limit 12 rad/s "
            "x radius 0.0975 m), got 1000000.0",
        ),
        ("soccer_plan", "initial_speed: -1.2\n", "within +-1.17 m/s"),
        # was "LittleDogTransferScenario: unknown library terrain 'bogus'", no field named
        (
            "littledog_transfer",
            "source: bogus\n",
            "source must be a library terrain, one of ['terrain_a', 'terrain_b'], got 'bogus'",
        ),
    ],
)
def test_registered_world_bad_scenario_is_one_line_naming_the_field(
    tmp_path, capsys, name, yaml_text, message
):
    (tmp_path / "s.yaml").write_text(yaml_text)
    out = tmp_path / "sim"
    argv = ["simulate", name, "--scenario", str(tmp_path / "s.yaml"), "--replay", "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("repertoire simulate: error: ") and err.count("\n") == 1  # one line
    assert message in err
    assert not out.exists()


def test_initial_speed_up_to_the_wheels_limit_is_accepted():
    from repertoire.diagrams.scenario import load_scenario
    from repertoire.diagrams.soccer import MAX_FORWARD_SPEED, GoToPoseScenario

    assert MAX_FORWARD_SPEED == 12.0 * 0.0975
    for speed in (-MAX_FORWARD_SPEED, 0.0, MAX_FORWARD_SPEED):
        scenario = load_scenario(GoToPoseScenario, data=f"initial_speed: {speed!r}")
        assert scenario.initial_speed == speed


@pytest.mark.parametrize(
    "argv, option",
    [
        (["study", "toy_study", "--episodes", "1", "--out-dir", ""], "--out-dir"),
        (["study", "toy_study", "--store", " "], "--store"),
        (["study", "toy_study", "--config", ""], "--config"),
        (["render", "test_pendulum", "--out", ""], "--out"),
        (["simulate", "test_pendulum", "--replay", "--out", ""], "--out"),
        (["simulate", "test_pendulum", "--scenario", ""], "--scenario"),
        (["demo", "--out", ""], "--out"),
    ],
)
def test_an_empty_path_is_refused_not_taken_as_the_current_folder(
    registries, tmp_path, monkeypatch, capsys, argv, option
):
    # Path("") is "."; `--out-dir "$OUT"` with OUT unset wrote the store, tables and
    # figures into the folder the command ran in.
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.splitlines()[-1]
    empty = argv[argv.index(option) + 1]
    assert err == (
        f"repertoire {argv[0]}: error: argument {option}: empty path {empty!r}; give a folder "
        "or file name ('.' for the current folder)"
    )
    assert list(tmp_path.iterdir()) == []
