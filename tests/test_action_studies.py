import dataclasses

import numpy as np
import pytest
from repertoire.studies.actions_goto_pose import (
    FEATURE_FUNCS,
    GoToPoseEpisodesConfig,
    GoToPoseRecord,
    sample_parameters,
    smoke_config,
    summarize,
)
from repertoire.studies.engine import load_records, run_study

from repertoire.errors import RepertoireError


def test_sampling_is_seeded_and_in_range():
    c = GoToPoseEpisodesConfig()
    a, b = sample_parameters(c, 7), sample_parameters(c, 7)
    assert a == b and sample_parameters(c, 8) != a
    for seed in range(50):
        start, goal = sample_parameters(c, seed)
        assert c.x_range[0] <= start[0] <= c.x_range[1]
        assert c.y_range[0] <= start[1] <= c.y_range[1]
        assert np.hypot(start[0] - 1.0, start[1] - 0.5) >= c.min_start_clearance
        d = np.hypot(goal[0] - 1.0, goal[1] - 0.5)
        assert c.goal_distance_range[0] - 1e-9 <= d <= c.goal_distance_range[1] + 1e-9


def test_config_rejects_off_field_ranges():
    with pytest.raises(RepertoireError, match="x_range must lie on the field"):
        GoToPoseEpisodesConfig(x_range=[-4.0, 0.0]).validate()
    with pytest.raises(RepertoireError, match="lo <= hi"):
        GoToPoseEpisodesConfig(v_range=[1.0, 0.0]).validate()
    # faster than the wheels turn (1.17 m/s): the world refuses such a start, so every
    # episode would fail; the config says so before any runs
    with pytest.raises(
        RepertoireError,
        match=r"^v_range must lie within \[-1.17\d*, 1.17\d*\], got \[0.0, 2.0\]$",
    ):
        GoToPoseEpisodesConfig(v_range=[0.0, 2.0]).validate()
    GoToPoseEpisodesConfig(v_range=[0.0, 12.0 * 0.0975]).validate()  # the edge is allowed
    # a negative goal speed is never reached (arrival at ~0 m/s, tolerance 0.1 m/s): every
    # such episode would time out and be stored as a failure
    with pytest.raises(RepertoireError, match=r"v_g_range must be >= 0 m/s, got \[-0.2, 0.1\]"):
        GoToPoseEpisodesConfig(v_g_range=[-0.2, 0.1]).validate()


def test_study_smoke_and_load_records(tmp_path):
    result = run_study(
        "actions_goto_pose",
        smoke_config(),
        episodes=2,
        executor="inline",
        store=tmp_path / "s.sqlite",
        out_dir=tmp_path,
        fresh=True,
    )
    _, records = load_records(tmp_path / "s.sqlite", "actions_goto_pose")
    assert sorted(records) == [0, 1]
    for rec in records.values():
        assert rec.status in ("SUCCEEDED", "FAILED", "TIMED_OUT")
        assert rec.duration > 0
        assert len(rec.states) == 4 * smoke_config().n_states
        assert rec.failed == (rec.touched_ball or rec.status != "SUCCEEDED")
    # too few episodes: the summary says how many are needed
    assert "at least" in result.figures["tables"].read_text()


def test_summarize_fits_on_synthetic_records(tmp_path):
    rng = np.random.default_rng(0)
    recs = []
    for _ in range(120):
        x, y, phi = rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-3, 3)
        d = np.hypot(x - 1, y - 0.5)
        recs.append(
            GoToPoseRecord(
                x, y, phi, 0.0, 1.0, 0.5, 0.0, 0.0, 1 + d, "SUCCEEDED", d < 0.8, d < 0.8, [], 0.0
            )
        )
    paths = summarize(recs, GoToPoseEpisodesConfig(), tmp_path)
    text = paths["tables"].read_text()
    assert "| goToPose (soccer, sim), paper (Table 1) | 1000 (750) | 6.2 | 0.22 |" in text
    assert "Table 2: failure (ball collision) tree" in text and "paper ~89%" in text
    assert paths["polar"].stat().st_size > 0 and paths["learning_curves"].stat().st_size > 0
    assert FEATURE_FUNCS["dist"](recs[0]) == pytest.approx(np.hypot(recs[0].x - 1, recs[0].y - 0.5))
    assert dataclasses.is_dataclass(recs[0])


def test_generic_fit_on_an_existing_study(tmp_path, capsys):
    from repertoire.studies.actions_fit import field_getters, main
    from repertoire.studies.pendulum import smoke_config as pendulum_smoke

    store = tmp_path / "pendulum" / "episodes.sqlite"
    store.parent.mkdir()
    run_study(
        "pendulum",
        pendulum_smoke(),
        episodes=28,
        executor="inline",
        store=store,
        out_dir=tmp_path,
        fresh=True,
    )
    args = [
        "--store",
        str(store),
        "--features",
        "initial_angle_rad",
        "damping",
        "--out-dir",
        str(tmp_path / "fit"),
    ]
    # a signed target (numerical noise makes one pendulum's fraction -0.001) is refused as a
    # duration, and fitted with --signed-target
    assert main([*args, "--target", "energy_lost_fraction"]) == 2
    out = capsys.readouterr().out
    assert "durations are negative (the least: 'energy_lost_fraction' of record" in out
    assert "--signed-target" in out
    assert main([*args, "--target", "energy_lost_fraction", "--signed-target"]) == 0
    out = capsys.readouterr().out
    assert "held-out MAE" in out and "train 21, held out 7" in out
    assert (tmp_path / "fit" / "pendulum_energy_lost_fraction.json").exists()
    assert main([*args, "--target", "lost_half_energy"]) == 0
    assert "held-out accuracy" in capsys.readouterr().out
    assert main([*args, "--target", "nope"]) == 2
    assert "no target field 'nope'" in capsys.readouterr().out
    with pytest.raises(RepertoireError, match="index"):
        field_getters(["cup_xy.x"])
    rec = type("R", (), {"cup_xy": [0.25, 0.5]})()
    assert field_getters(["cup_xy.1"])["cup_xy.1"](rec) == 0.5
