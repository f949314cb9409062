"""DMP studies: smoke runs through the study engine, determinism, the headline effects."""

import re

import numpy as np
import pytest
from repertoire.studies import dmp_chaining, dmp_goals, dmp_grid, dmp_obstacles
from repertoire.studies.engine import comparable, run_study
from repertoire.studies.registry import get_study

from repertoire.errors import RepertoireError


def _smoke_run(module, tmp_path, episodes: int = 1):
    """One inline run of a study's smoke config through the engine."""
    name = module.__name__.rsplit(".", 1)[-1]
    return run_study(
        name,
        get_study(name).smoke_config(),
        episodes=episodes,
        store=tmp_path / f"{name}.sqlite",
        out_dir=tmp_path / name,
        executor="inline",
        progress=False,
    )


def test_goals_study_smoke_shows_old_form_failures(tmp_path):
    result = _smoke_run(dmp_goals, tmp_path)
    assert len(result.records) == 1
    for r in result.records:
        assert r.flip_mirrored_old and not r.flip_mirrored_new
        assert r.near_start_peak_acc_new < 5
        assert r.near_start_peak_acc_old > 10 * r.near_start_peak_acc_new
    assert set(result.figures) >= {
        "fig2",
        "near_start",
        "table",
        "orientation",
        "sparse",
        "start_velocity",
        "tau_invariance",
    }
    assert all(p.exists() for p in result.figures.values())


def test_goals_fig2_draws_the_first_episodes_seed(tmp_path, monkeypatch):
    """Fig. 2 (and the re-timing figure) redraw the first stored episode, not seed 0."""
    config = get_study("dmp_goals").smoke_config()
    records = [dmp_goals.run_episode(config, s) for s in (41, 43)]
    assert [r.seed for r in records] == [41, 43]
    drawn, retimed = [], []
    sample = dmp_goals.sample_episode
    monkeypatch.setattr(
        dmp_goals, "sample_episode", lambda c, seed: drawn.append(seed) or sample(c, seed)
    )
    for name in ("orientation_figure", "sparse_demo_figure", "start_velocity_figure"):
        monkeypatch.setattr(dmp_goals, name, lambda *a: tmp_path / "skipped.png")
    monkeypatch.setattr(
        dmp_goals, "tau_invariance_figure", lambda c, seed, d: retimed.append(seed) or d
    )
    figures = dmp_goals.summarize(records, config, tmp_path)
    assert drawn == [41] and retimed == [41]
    assert figures["fig2"].exists()
    with pytest.raises(RepertoireError, match="no episodes to summarise"):
        dmp_goals.summarize([], config, tmp_path)


def test_goals_start_velocity_figure_runs_the_old_form_in_the_system_as_its_rollout():
    """The old form sent twice as far starts at twice v0 in the DmpSystem, as in rollout."""
    d = dmp_goals.start_velocity_runs()
    old = d["old"]
    assert dmp_goals.OLD_GOAL_FACTOR == 2.0
    (xs, xds), (xr, xdr) = old["system"], old["rollout"]
    assert xs.shape == xr.shape == d["t"].shape
    assert old["gap"] == float(np.max(np.abs(xs - xr))) < 1e-9
    assert xds[0] == pytest.approx(xdr[0], rel=1e-12)
    assert xds[0] == pytest.approx(2.0 * d["v0"], rel=1e-9)  # the demonstration's v0, twice
    # eq. 1 scales the whole run about x0: twice the demonstration's displacement
    assert xr - xr[0] == pytest.approx(2.0 * (d["x"] - d["x"][0]), abs=0.05)
    assert old["goal"] - xr[0] == pytest.approx(2.0 * (d["x"][-1] - d["x"][0]), rel=1e-9, abs=0.02)
    # from the learned v0 unscaled the run leaves x0 at half the speed: it lags
    assert np.max(np.abs(old["unscaled"] - xr)) > 0.05


def test_goals_retimed_demonstration_takes_the_same_path():
    config = get_study("dmp_goals").smoke_config()
    runs = dmp_goals.tau_invariance_runs(config, 5)["runs"]
    assert set(runs) == {(f, c) for f in dmp_goals.TAU_FACTORS for c in (False, True)}
    for (factor, coupled), (t, _x, gap) in runs.items():
        assert t[-1] == pytest.approx(config.sim_factor * factor * config.duration_s)
        # the same path at the same phase t / tau, to the fixed step's discretisation
        # (default config, seed 5: free 6.5e-6 / 5.5e-7 m, around the ball 0.37 / 0.19 mm)
        assert gap == 0.0 if factor == 1.0 else gap < (2e-3 if coupled else 1e-4)


def test_obstacles_study_smoke_and_determinism(tmp_path):
    config = get_study("dmp_obstacles").smoke_config()
    a, b = dmp_obstacles.run_episode(config, 3), dmp_obstacles.run_episode(config, 3)
    assert comparable(a) == comparable(b)
    assert a.clearance_with_m > a.clearance_without_m
    assert not a.success_without  # the obstacle is placed on the learned path
    with pytest.raises(RepertoireError, match="radius_m must be > 0"):
        dmp_obstacles.run_episode(dmp_obstacles.DmpObstaclesConfig(radius_m=0.0), 0)
    figures = dmp_obstacles.summarize([a, b], config, tmp_path)
    assert set(figures) == {"paths_and_clearance", "table"}
    assert all(p.exists() for p in figures.values())
    assert "| fraction with clearance > r | 0.00 | 1.00 |" in figures["table"].read_text()
    # the straight case (phi = 0 all along): through the centre without coupling, around it with
    (row,) = [r for r in figures["table"].read_text().splitlines() if "straight path" in r]
    without, with_ = (float(c) for c in row.strip("|").split("|")[1:])
    assert without < 1e-3 < 0.03 < with_


def test_chaining_study_smoke(tmp_path):
    result = _smoke_run(dmp_chaining, tmp_path)
    (r,) = result.records
    assert r.vel_jump_velocity < 1e-12 and r.vel_jump_none > 0.1
    assert r.acc_jump_acceleration < 1e-9 < r.acc_jump_velocity
    assert r.drake_vs_numpy < 1e-10
    assert result.figures["fig5"].exists()
    # the record keeps what ran: its square, switches and traces (within trace_tolerance)
    config = get_study("dmp_chaining").smoke_config()
    switch, side, goals = dmp_chaining.square(config, 0)
    assert (r.seed, r.switch, r.side_m) == (0, switch, side)
    assert r.goals_m == [g.tolist() for g in goals]
    t_kept = np.array(r.trace_t_s)
    for h in dmp_chaining.HANDOFF_NAMES:
        t, x, xd, xdd, steps, _, times = dmp_chaining.run_chain(config, switch, goals, h)
        assert r.switch_times_s == pytest.approx(times[1:], abs=1e-12)
        for kept, full in ((r.speed[h], xd), (r.acc_norm[h], xdd)):
            full = np.linalg.norm(full, axis=1)
            gap = np.abs(np.interp(t, t_kept, kept) - full).max()
            assert gap <= config.trace_tolerance * full.max() + 1e-6
        if h == "velocity":
            path = np.array(r.path_velocity_m)
            for i in (0, 1):
                gap = np.abs(np.interp(t, t_kept, path[:, i]) - x[:, i]).max()
                assert gap <= config.trace_tolerance * np.abs(x[:, i]).max() + 1e-6
            assert np.allclose(r.switch_points_m, x[steps], atol=1e-6, rtol=0)
    # and the figure draws them: (a) the path leg by leg, (b) in the square's frame
    fig = dmp_chaining.fig5(result.records)
    a, b, c, d = fig.axes[:4]
    legs = [line.get_xydata() for line in a.lines[:4]]
    assert np.array_equal(np.vstack([leg[:-1] for leg in legs[:3]] + [legs[3]]), path)
    assert np.array_equal(b.lines[0].get_xydata(), dmp_chaining.square_frame(goals, path))
    assert np.array_equal(c.lines[1].get_ydata(), r.acc_norm["velocity"])
    assert np.array_equal(d.lines[0].get_xdata(), t_kept)


def test_chaining_square_frame_maps_every_square_onto_the_unit_square():
    config = dmp_chaining.DmpChainingConfig()
    unit = [[1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.0, 0.0]]
    for seed in range(50, 60):
        _, _, goals = dmp_chaining.square(config, seed)
        assert dmp_chaining.square_frame(goals, np.array(goals)) == pytest.approx(
            np.array(unit), abs=1e-12
        )


def test_chaining_traces_keep_the_breakpoints_and_both_sides_of_each_switch():
    t = np.arange(11.0)
    corner = np.abs(t - 4.0)  # piecewise linear: its chords are exact through 0, 4, 10
    assert dmp_chaining.trace_indices(t, [corner], [], 1e-3).tolist() == [0, 4, 10]
    assert dmp_chaining.trace_indices(t, [corner], [7], 1e-3).tolist() == [0, 4, 6, 7, 10]
    bump = np.where(t == 8.0, 0.05, 0.0) + corner  # 0.05 off the chord: 0.5 % of the peak
    assert dmp_chaining.trace_indices(t, [bump], [], 1e-2).tolist() == [0, 4, 10]
    assert dmp_chaining.trace_indices(t, [bump], [], 1e-3).tolist() == [0, 4, 7, 8, 9, 10]


def test_study_configs_refuse_infinite_and_inverted_ranges():
    with pytest.raises(RepertoireError, match=r"side_max_m must be finite and > 0, got inf"):
        dmp_chaining.DmpChainingConfig(side_max_m=float("inf")).validate()
    with pytest.raises(RepertoireError, match="needs side_min_m <= side_max_m"):
        dmp_chaining.DmpChainingConfig(side_min_m=0.6, side_max_m=0.5).validate()
    with pytest.raises(RepertoireError, match=r"finite bulge_min_m <= bulge_max_m, got 0.2, inf"):
        dmp_goals.DmpGoalsConfig(bulge_max_m=float("inf")).validate()
    with pytest.raises(RepertoireError, match="rise_min_m <= rise_max_m"):
        dmp_goals.DmpGoalsConfig(rise_min_m=0.2, rise_max_m=0.1).validate()
    # a negative shift was numpy's "high - low < 0" inside every episode (exit 1)
    with pytest.raises(
        RepertoireError, match=r"^DmpGoalsConfig.goal_shift_m must be finite and >= 0, got -1.0$"
    ):
        dmp_goals.DmpGoalsConfig(goal_shift_m=-1.0).validate()
    dmp_goals.DmpGoalsConfig(goal_shift_m=0.0).validate()  # no shift: the edge is allowed
    dmp_goals.DmpGoalsConfig().validate()
    dmp_chaining.DmpChainingConfig().validate()
    obstacles = dmp_obstacles.DmpObstaclesConfig
    for kwargs, message in (
        ({"length_max_m": 0.1}, "finite length_min_m <= length_max_m, got 0.3, 0.1"),
        ({"length_max_m": float("inf")}, "finite length_min_m <= length_max_m, got 0.3, inf"),
        ({"offset_max": -1.0}, "offset_max must be finite and >= 0, got -1.0"),
        ({"gamma": float("nan")}, "finite gamma, beta >= 0, got nan"),
        ({"beta": float("inf")}, "finite gamma, beta >= 0, got 1000.0, inf"),
        ({"n_samples": 2}, "n_samples >= 3 and 1 <= n_basis <= n_samples, got 2, 30"),
        ({"n_basis": 0}, "n_samples >= 3 and 1 <= n_basis <= n_samples, got 500, 0"),
    ):
        with pytest.raises(RepertoireError, match=re.escape(message)):
            obstacles(**kwargs).validate()
    obstacles().validate()
    with pytest.raises(RepertoireError, match=re.escape("1 <= n_basis <= n_samples, got 0, 500")):
        dmp_chaining.DmpChainingConfig(n_basis=0).validate()
    for config in (dmp_chaining.DmpChainingConfig, dmp_goals.DmpGoalsConfig):
        with pytest.raises(
            RepertoireError,
            match="n_samples and n_basis must be integers|n_basis and n_samples must be integers",
        ):
            config(n_basis=float("nan")).validate()
    with pytest.raises(RepertoireError, match=r"GridConfig.n must be an integer >= 1, got inf"):
        dmp_grid.GridConfig(n=float("inf")).validate()
    with pytest.raises(RepertoireError, match=r"GridConfig.time_step must be finite and > 0"):
        dmp_grid.GridConfig(time_step=float("nan")).validate()
    with pytest.raises(RepertoireError, match=r"finite sim_duration_s >= 0 and path_every_s > 0"):
        dmp_grid.GridConfig(sim_duration_s=float("inf")).validate()
