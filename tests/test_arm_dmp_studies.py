"""Smoke tests of the arm DMP studies (dmp_grid, dmp_pick_place, dmp_serving): short episodes."""

import dataclasses

import numpy as np
import pytest
from repertoire.studies import dmp_grid, dmp_obstacle_arm, dmp_pick_place, dmp_serving
from repertoire.studies.registry import get_study

from repertoire.errors import RepertoireError

# Seed 3 at smoke size (0.2-0.3 s of simulation): the figures each record must hold
# (measured once; deterministic; re-measured in session 31 when the IK's joint-limit barrier
# came in: up to 8e-6 m apart; in session 34 when the arm worlds' contact became SAP: the
# bottle in hand 2e-5 m apart), and the files each summary writes.
SMOKE_EXPECTED = {
    "dmp_grid": (
        {"cell": 0, "reached": False, "grasp_reach_error_m": 0.27987759600990875},
        {"grid", "results"},
    ),
    "dmp_pick_place": (
        {
            "success": False,
            "collision_free": True,
            # 0.23674460168219336 before session 36: the grasp (tau 2.5 s) now gets eq. 10
            # with the carry's gain in the paper's v, 5/6 of the dx/dt term it had
            "grasp_reach_error_m": 0.23657955226430738,
            "min_ball_gap_m": 0.023225822639641416,  # the thumb's double gain (session 35)
            "cup_to_coaster_m": 0.35630108377405284,
            "outcome": "missed",  # 0.3 s: the cup is not yet held
            "grasp_slip_m": 0.0,
        },
        {"errors", "results", "top_view", "joint_limits"},
    ),
    "dmp_serving": (
        {"success": False, "cups_served": 0, "bottle_in_hand_m": 0.25106585336618764},
        {"results", "top_view"},
    ),
    "dmp_obstacle_arm": (
        {
            "success": {"coupled": False, "uncoupled": False},
            "uncoupled_path_gap_m": -0.05430767892268275,
            "min_ball_gap_m": {"coupled": 0.019954150481016827, "uncoupled": 0.019954150481016827},
        },
        {"gaps", "paths", "results"},
    ),
}


@pytest.mark.parametrize("module", [dmp_grid, dmp_pick_place, dmp_serving, dmp_obstacle_arm])
def test_smoke_episode_is_deterministic_and_summarizes(module, tmp_path):
    config = get_study(module.__name__.rsplit(".", 1)[1]).smoke_config()
    first = module.run_episode(config, 3)
    figures, file_keys = SMOKE_EXPECTED[module.__name__.rsplit(".", 1)[1]]
    for key, value in figures.items():
        if isinstance(value, str):
            assert getattr(first, key) == value, key
        else:
            assert getattr(first, key) == pytest.approx(value, rel=1e-6), key
    again = module.run_episode(config, 3)
    a, b = dataclasses.asdict(first), dataclasses.asdict(again)
    for key in a:
        if not key.startswith("wall"):
            assert a[key] == b[key] or (a[key] != a[key] and b[key] != b[key]), key
    assert first.failure in ("", {"coupled": "", "uncoupled": ""})
    if module is dmp_pick_place:  # 0.3 s from home: every joint far from its limits
        assert len(first.joint_margins_rad) == 7 and min(first.joint_margins_rad) > 0.1
        assert first.joint_held_steps == [0] * 7
    assert first.wall_sim_s > 0.0
    files = module.summarize([first], config, tmp_path)
    assert set(files) == file_keys
    for path in files.values():
        assert path.is_file() and path.stat().st_size > 0
    if module is dmp_grid:  # 0.3 s: the grasp is 280 mm short, the place never started
        text = files["results"].read_text()
        assert "| 279.88 | n/a | " in text and text.count("| no |") == 1
        assert "no: error" not in text
        assert text.endswith(
            "0 of 1 cells reached within 5 mm; max grasp error 279.88 mm, max place error "
            "n/a mm. n/a: the run stopped (or its simulated time ended) before that segment; "
            "a max is n/a when no run got that far.\n"
        )


def _grid_record(cell: int, grasp_mm: float, place_mm: float, reached: bool):
    return dmp_grid.GridRecord(
        cell=cell,
        grasp_goal=[0.5, -0.2, 0.1],
        place_goal=[0.5, 0.2, 0.1],
        grasp_reach_error_m=grasp_mm / 1000,
        place_reach_error_m=place_mm / 1000,
        grasp_orientation_error_rad=np.radians(1.5),
        reached=reached,
        failure="",
        path_x=[],
        path_y=[],
        path_z=[],
        wall_time_s=0.0,
        wall_sim_s=0.0,
    )


def test_grid_table_explains_n_a_only_when_a_cell_is_n_a():
    done = [_grid_record(0, 1.25, 2.5, True), _grid_record(1, 3.0, 7.75, False)]
    lines = dmp_grid.results_lines(done)
    assert lines[2:] == [
        "| 0 | [0.5, -0.2, 0.1] | [0.5, 0.2, 0.1] | 1.25 | 2.50 | 1.50 | yes |",
        "| 1 | [0.5, -0.2, 0.1] | [0.5, 0.2, 0.1] | 3.00 | 7.75 | 1.50 | no |",
        "\n1 of 2 cells reached within 5 mm; max grasp error 3.00 mm, max place error 7.75 mm.",
    ]
    assert not any("n/a" in line for line in lines)  # nothing to explain
    short = [done[0], _grid_record(1, 3.0, np.nan, False)]  # cell 1 never placed
    lines = dmp_grid.results_lines(short)
    assert lines[3] == "| 1 | [0.5, -0.2, 0.1] | [0.5, 0.2, 0.1] | 3.00 | n/a | 1.50 | no |"
    assert lines[4] == (
        "\n1 of 2 cells reached within 5 mm; max grasp error 3.00 mm, max place error "
        "2.50 mm. n/a: the run stopped (or its simulated time ended) before that segment; "
        "a max is n/a when no run got that far."
    )


def test_seeds_draw_layouts_inside_the_ranges():
    config = dmp_pick_place.PickPlaceConfig()
    for seed in range(20):
        s = dmp_pick_place.sample_scenario(config, seed)
        assert config.cup_x[0] <= s.cup_xy[0] <= config.cup_x[1]
        assert config.coaster_y[0] <= s.coaster_xy[1] <= config.coaster_y[1]
        shift = np.linalg.norm(np.subtract(s.coaster_final_xy, s.coaster_xy))
        assert config.coaster_shift[0] - 1e-12 <= shift <= config.coaster_shift[1] + 1e-12
    serving = dmp_serving.ServingConfig()
    s = dmp_serving.sample_scenario(serving, 7)
    ys = [xy[1] for xy in s.cup_xys]
    assert ys == sorted(ys) and min(np.diff(ys)) >= 0.08  # the cups cannot overlap
    grid = dmp_grid.GridConfig()
    goals = {tuple(np.round(grid.cell(k)[0], 6)) for k in range(9)}
    assert len(goals) == 9 and grid.cell(9)[0].tolist() == grid.cell(0)[0].tolist()


def test_bad_configs():
    with pytest.raises(RepertoireError, match="cup_x must be \\[min, max\\]"):
        dmp_pick_place.run_episode(dmp_pick_place.PickPlaceConfig(cup_x=[0.6, 0.5]), 0)
    with pytest.raises(RepertoireError, match="needs 3 ranges"):
        dmp_serving.run_episode(dmp_serving.ServingConfig(cup_y=[[0.0, 0.1]]), 0)
    with pytest.raises(RepertoireError, match="integer >= 1"):
        dmp_grid.run_episode(dmp_grid.GridConfig(n=0), 0)


def test_obstacle_study_puts_the_ball_on_the_carry_path():
    from repertoire.diagrams.arm_dmp_scenarios import carry_path
    from repertoire.planning.arm_library import home_tcp_pose

    config = dmp_obstacle_arm.ObstacleArmConfig()
    home = home_tcp_pose().translation()
    for seed in range(6):
        coupled, gap = dmp_obstacle_arm.sample_scenario(config, seed)
        uncoupled, _ = dmp_obstacle_arm.sample_scenario(config, seed, coupling=False)
        assert coupled.obstacle_xyz == uncoupled.obstacle_xyz  # same layout in both arms
        assert coupled.obstacle_coupling and not uncoupled.obstacle_coupling
        o = np.asarray(coupled.obstacle_xyz)
        path = carry_path(coupled.cup_xy, coupled.coaster_xy)
        # The uncoupled tcp runs through the ball (4-6 cm inside its surface).
        assert gap == pytest.approx(np.min(np.linalg.norm(path - o, axis=1)) - 0.06, abs=1e-4)
        assert gap < -0.03
        assert np.linalg.norm(o - home) >= dmp_obstacle_arm.HOME_CLEARANCE


def test_obstacle_study_draws_again_a_ball_that_touches_the_arm_at_home():
    # seed 1118's first draw clears the hand by HOME_CLEARANCE but overlaps the arm at home
    # by 0.5 cm (the scenario refused it in both arms); the sampler now draws again
    from repertoire.diagrams.arm_dmp_scenarios import ball_gap_at_home

    config = dmp_obstacle_arm.ObstacleArmConfig()
    scenario, gap = dmp_obstacle_arm.sample_scenario(config, 1118)
    assert ball_gap_at_home(np.asarray(scenario.obstacle_xyz)) > 0.0
    scenario.validate()
    assert gap < 0.0  # still on the uncoupled carry path


def test_obstacle_study_bad_config():
    with pytest.raises(RepertoireError, match="path_fraction must be \\[min, max\\]"):
        dmp_obstacle_arm.run_episode(
            dmp_obstacle_arm.ObstacleArmConfig(path_fraction=[0.7, 0.6]), 0
        )
    with pytest.raises(RepertoireError, match="must lie in \\[0, 1\\]"):
        dmp_obstacle_arm.run_episode(
            dmp_obstacle_arm.ObstacleArmConfig(path_fraction=[0.5, 1.2]), 0
        )
    with pytest.raises(RepertoireError, match="no ball placement"):
        dmp_obstacle_arm.sample_scenario(
            dmp_obstacle_arm.ObstacleArmConfig(path_fraction=[0.5, 0.5], coaster_y=[0.0, 0.0]), 0
        )


def test_outcome_handles_name_only_the_outcomes_drawn():
    from repertoire.studies._dmp_common import OUTCOME_COLOURS, outcome_handles

    def entries(handles):
        return [(h.get_label(), h.get_color()) for h in handles]

    both = [
        (f"tcp path, {w}", OUTCOME_COLOURS[ok]) for ok, w in ((True, "success"), (False, "failure"))
    ]
    assert entries(outcome_handles([False, True, np.True_], "tcp path")) == both
    assert entries(outcome_handles([1, 1], "tcp path")) == both[:1]
    assert entries(outcome_handles([False], "tcp path")) == both[1:]
    assert outcome_handles([], "tcp path") == []
    (h,) = outcome_handles([0], "tip", words=("served", "spilled"), lw=1.2)
    assert (h.get_label(), h.get_linewidth()) == ("tip, spilled", 1.2)


@pytest.mark.parametrize("height_in", [2.0, 6.0])
def test_legend_below_sits_a_fixed_distance_under_the_axes(height_in):
    # the same gap in inches for a flat and a tall axes (a fraction of the height was not)
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from repertoire.studies._dmp_common import legend_below

    fig = Figure(figsize=(5.0, height_in + 2.0), dpi=100)
    ax = fig.add_axes((0.1, 1.5 / (height_in + 2.0), 0.8, height_in / (height_in + 2.0)))
    handles = [Line2D([], [], label="a"), Line2D([], [], ls=":", label="b")]
    legend = legend_below(ax, handles, ncols=2, below_in=0.5)
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    renderer = FigureCanvasAgg(fig).get_renderer()
    box, frame = ax.get_window_extent(renderer), legend.get_window_extent(renderer)
    assert frame.y1 == pytest.approx(box.y0 - 0.5 * fig.dpi, abs=1.0)
    assert frame.x0 + frame.x1 == pytest.approx(box.x0 + box.x1, abs=1.0)  # centred
    assert [t.get_text() for t in legend.get_texts()] == ["a", "b"]


def test_limit_margins_closed_form():
    from repertoire.diagrams.arm_dmp_results import limit_margins

    q = np.array([[0.0, 1.0], [0.5, -0.25], [0.9, 0.0]])
    # joint 0 in [-1, 1]: margins 1, 0.5, 0.1 -> 0.1; joint 1 in [-0.5, 2]: 1, 0.25, 0.5
    assert np.allclose(limit_margins(q, [-1.0, -0.5], [1.0, 2.0]), [0.1, 0.25], atol=1e-15)
    assert limit_margins([[1.5]], [-1.0], [1.0])[0] == -0.5  # past the upper limit
    with pytest.raises(RepertoireError, match=r"limit_margins needs .* got \(0, 2\)"):
        limit_margins(np.zeros((0, 2)), [0, 0], [1, 1])
    with pytest.raises(RepertoireError, match=r"got \(1, 2\), \(3,\) and \(3,\)"):
        limit_margins([[0.0, 0.0]], [0, 0, 0], [1, 1, 1])


def test_joint_limit_probe_stops_at_the_wrist_limits_and_is_drawn(tmp_path):
    from repertoire.studies._dmp_common import joint_limit_probe

    recorder, report = joint_limit_probe()
    assert recorder.times[-1] == pytest.approx(1.92)
    assert "tracking lost at the joint limits" in report
    assert "wrist_flexion (upper, 1.2 rad), wrist_abduction (lower, -0.6 rad)" in report
    assert recorder.held[-1].tolist() == [0, 0, 0, 0, 0, 1.0, -1.0]
    assert recorder.q.shape == (len(recorder.times), 7)
    record = dmp_pick_place.run_episode(dmp_pick_place.PickPlaceConfig(sim_duration_s=0.2), 5)
    out = dmp_pick_place.joint_limits_figure([record], tmp_path / "limits.png")
    assert out.is_file() and out.stat().st_size > 10_000
