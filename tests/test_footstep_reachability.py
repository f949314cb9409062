"""The relaxed flood fill that proves a goal cut off for every lattice (reachability.py)."""

import dataclasses
import math
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from repertoire.planning.footstep import (
    DynamicEnvironment,
    OccupancyGrid,
    PlannerOptions,
    PlanStatus,
    nominal_action_table,
    plan_footsteps,
    plan_footsteps_anytime,
)
from repertoire.planning.footstep.biped_model import BipedStepModel
from repertoire.planning.footstep.reachability import goal_cut_off

RES = 0.025
START, GOAL = (0.4, 1.0, 0.0), (1.9, 1.0)


def _stairs(rise: float, treads: int = 3) -> OccupancyGrid:
    """Free ground rising by ``rise`` every 0.3 m from x = 1 m (heights on free cells)."""
    heights = np.zeros((88, 80))
    for k in range(treads):
        heights[int(round((1.0 + 0.3 * k) / RES)) :, :] = rise * (k + 1)
    return OccupancyGrid(np.zeros(heights.shape, bool), RES, (0.0, 0.0), heights)


def _model(grid, opts: PlannerOptions, goal=GOAL) -> BipedStepModel:
    return BipedStepModel(grid, START, "left", goal, nominal_action_table(), opts)


@pytest.mark.parametrize("up", [0.03, 0.035])
def test_a_rise_above_the_step_up_limit_is_unreachable_without_refining(up):
    grid = _stairs(0.05)
    opts = PlannerOptions(max_step_up=up, max_height_range=0.01, time_limit=60.0)
    assert goal_cut_off(_model(grid, opts))
    plan = plan_footsteps(grid, START, "left", GOAL, nominal_action_table(), opts)
    # the 5 cm lattice ran out of states and no finer one was tried: none can get through
    assert plan.status is PlanStatus.UNREACHABLE
    assert (plan.xy_resolution, plan.yaw_bins) == (0.05, 36)
    assert max(p[0] for p in plan.poses) < 1.0  # the best partial plan stays below the stairs
    runs = plan_footsteps_anytime(grid, START, "left", GOAL, nominal_action_table(), opts)
    assert [r.plan.status for r in runs] == [PlanStatus.UNREACHABLE]
    assert runs[0].plan.xy_resolution == 0.05


def test_stairs_within_the_limits_are_not_cut_off_and_are_climbed():
    grid = _stairs(0.05)
    opts = PlannerOptions(max_step_up=0.06, max_height_range=0.01, time_limit=60.0)
    assert not goal_cut_off(_model(grid, opts))
    plan = plan_footsteps(grid, START, "left", GOAL, nominal_action_table(), opts)
    assert plan.status is PlanStatus.SUCCESS
    # levels are heights apart: a 5 cm rise is cut off at 4 cm, not at exactly 5 cm
    edge = PlannerOptions(max_step_up=0.04, max_height_range=0.01)
    assert goal_cut_off(_model(grid, edge))
    assert not goal_cut_off(_model(grid, dataclasses.replace(edge, max_step_up=0.05)))
    # without a flatness limit a stance straddling the edge stands on the stair's height,
    # and no stance below reaches that level: cut off all the same
    assert goal_cut_off(_model(grid, PlannerOptions(max_step_up=0.03)))
    assert not goal_cut_off(_model(grid, PlannerOptions(max_step_up=0.05)))


def test_a_band_wider_than_any_step_is_cut_off_and_a_narrow_one_is_not():
    for width, cut in ((0.40, True), (0.12, False)):
        occ = np.zeros((88, 80), dtype=bool)
        occ[40 : 40 + int(round(width / RES)), :] = True
        grid = OccupancyGrid(occ, RES)
        assert goal_cut_off(_model(grid, PlannerOptions())) is cut
        plan = plan_footsteps(
            grid, START, "left", GOAL, nominal_action_table(), PlannerOptions(time_limit=60.0)
        )
        assert plan.status is (PlanStatus.UNREACHABLE if cut else PlanStatus.SUCCESS)
        if cut:
            assert plan.xy_resolution == 0.05


def test_a_goal_within_reach_of_the_start_is_never_cut_off():
    occ = np.ones((88, 80), dtype=bool)
    occ[6:26, 24:56] = False  # a free pocket around the start feet only
    grid = OccupancyGrid(occ, RES)
    assert not goal_cut_off(_model(grid, PlannerOptions(), goal=(0.45, 1.0)))


@pytest.mark.parametrize("seed", range(12))
def test_never_cut_off_where_a_plan_exists(seed):
    """Sound on random 2.5-D maps: wherever any lattice finds a plan, no proof says otherwise."""
    rng = np.random.default_rng(seed)
    occ = np.zeros((88, 80), dtype=bool)
    heights = rng.uniform(0.0, 0.02, occ.shape).round(3) * (rng.random() < 0.5)
    for _ in range(rng.integers(2, 7)):  # blocks: low ones stepped over, tall ones not
        i, j = rng.integers(26, 70), rng.integers(0, 70)
        w, h = rng.integers(2, 12, 2)
        occ[i : i + w, j : j + h] = True
    for _ in range(rng.integers(0, 4)):  # raised free platforms
        i, j = rng.integers(26, 70), rng.integers(0, 60)
        heights[i : i + rng.integers(4, 20), j : j + rng.integers(4, 20)] += rng.uniform(0, 0.08)
    occ[:20, 30:50] = False  # room for the start feet
    heights[:20, 30:50] = 0.0
    goal = (float(rng.uniform(1.8, 2.0)), float(rng.uniform(0.3, 1.7)))
    occ[int(goal[0] / RES), int(goal[1] / RES)] = False
    grid = OccupancyGrid(occ, RES, (0.0, 0.0), heights)
    limits = {
        "max_step_up": float(rng.choice([0.02, 0.04, math.inf])),
        "max_step_down": float(rng.choice([0.03, math.inf])),
        "max_height_range": float(rng.choice([0.015, 0.03, math.inf])),
    }
    found = False
    for xy, bins in ((0.05, 36), (0.02, 90)):  # the default lattice, then a fine one
        opts = PlannerOptions(time_limit=30.0, xy_resolution=xy, yaw_bins=bins, **limits)
        plan = plan_footsteps(grid, START, "left", goal, nominal_action_table(), opts)
        found = found or plan.status is PlanStatus.SUCCESS
    if found:
        assert not goal_cut_off(_model(grid, PlannerOptions(**limits), goal=goal))


def test_dynamic_worlds_are_never_claimed_cut_off():
    occ = np.zeros((88, 80), dtype=bool)
    occ[40:60, :] = True
    grid = OccupancyGrid(occ, RES)
    world = DynamicEnvironment(np.array([0.0, 1.0]), [grid, grid], max_time_gap=1.0)
    model = BipedStepModel(
        world, START, "left", GOAL, nominal_action_table(), PlannerOptions(heuristic="euclidean")
    )
    assert goal_cut_off(model) is False


def test_a_proof_cut_short_by_the_clock_proves_nothing(monkeypatch):
    import time

    import repertoire.planning.footstep.reachability as reach

    opts = PlannerOptions(max_step_up=0.03, max_height_range=0.01, time_limit=60.0)
    model = _model(_stairs(0.05), opts)
    assert goal_cut_off(model, time.perf_counter() + 60.0)
    assert not goal_cut_off(model, time.perf_counter())  # no time left: nothing proved
    # the level table or the fill interrupted: each says so, and nothing is proved
    assert not goal_cut_off(model, -math.inf)
    levels = reach._levels.py_func
    fill = reach._fill_reaches.py_func
    monkeypatch.setattr(reach, "_now", lambda: math.inf)
    monkeypatch.setattr(reach, "_levels", levels)
    monkeypatch.setattr(reach, "_fill_reaches", fill)
    monkeypatch.setattr(reach.time, "perf_counter", lambda: 0.0)
    assert not goal_cut_off(model, 1.0)  # the levels' clock reads "late": cut short
    monkeypatch.setattr(reach, "_levels", lambda *a: levels(*a[:-1], math.inf))
    assert not goal_cut_off(model, 1.0)  # the fill's clock reads "late": cut short
    monkeypatch.setattr(reach, "_now", lambda: 0.0)
    assert goal_cut_off(model, 1.0)  # both on time: the proof stands


def test_the_planner_reports_time_limit_when_the_proof_runs_out_of_time(monkeypatch):
    import time

    grid = _stairs(0.05)
    opts = PlannerOptions(max_step_up=0.03, max_height_range=0.01, time_limit=0.5)
    seen = []

    def out_of_time(model, deadline=math.inf):  # a fill on a map too large for the limit
        seen.append(deadline)
        time.sleep(max(deadline - time.perf_counter(), 0.0))
        return False

    monkeypatch.setattr("repertoire.planning.footstep.planner.goal_cut_off", out_of_time)
    t0 = time.perf_counter()
    plan = plan_footsteps(grid, START, "left", GOAL, nominal_action_table(), opts)
    assert len(seen) == 1 and t0 + 0.5 <= seen[0] <= time.perf_counter()  # its own deadline
    assert plan.status is PlanStatus.TIME_LIMIT  # not UNREACHABLE: nothing was proved
    assert (plan.xy_resolution, plan.yaw_bins) == (0.05, 36)
    runs = plan_footsteps_anytime(grid, START, "left", GOAL, nominal_action_table(), opts)
    assert len(seen) == 2 and [r.plan.status for r in runs] == [PlanStatus.TIME_LIMIT]


@pytest.mark.parametrize("seed", range(6))
def test_the_component_labels_agree_with_the_fill(seed, monkeypatch):
    import repertoire.planning.footstep.reachability as reach

    rng = np.random.default_rng(seed)
    occ = rng.random((96, 96)) < 0.25 + 0.05 * seed  # 2.4 m of clutter
    ii, jj = np.mgrid[:96, :96]
    d = np.hypot(ii - 76, jj - 76)
    if seed % 2:  # a ring wall around the goal, 0.2-0.45 m thick
        occ |= (d > 10) & (d < 10 + 8 + 2 * seed)
    occ[(d <= 4) | (np.hypot(ii - 16, jj - 16) <= 14)] = False
    grid = OccupancyGrid(occ, RES)
    model = BipedStepModel(
        grid, (0.4, 0.4, 0.0), "left", (1.9, 1.9), nominal_action_table(), PlannerOptions()
    )
    both = goal_cut_off(model)
    monkeypatch.setattr(reach, "_discs_connect", lambda *a: True)  # the fill alone
    assert goal_cut_off(model) == both
    if seed == 5:  # a wall 0.45 m thick, wider than any step: proved without the fill
        monkeypatch.undo()
        monkeypatch.setattr(reach, "_fill_reaches", lambda *a: pytest.fail("fill ran"))
        monkeypatch.setattr(reach, "_levels", lambda *a: pytest.fail("levels built"))
        assert goal_cut_off(model)
        limited = BipedStepModel(  # with step limits too: heights play no part in it
            grid, (0.4, 0.4, 0.0), "left", (1.9, 1.9), nominal_action_table(),
            PlannerOptions(max_step_up=0.04, max_step_down=0.04),
        )  # fmt: skip
        assert goal_cut_off(limited)


def test_warm_up_compiles_the_proof_so_no_plan_pays_for_it_inside_its_limit():
    # In a fresh process: the first plan that ends UNREACHABLE runs the proof inside its
    # time limit, so warm_up (outside the limit) must have compiled or loaded its kernels;
    # it used not to, and the first proof's ~2 s cache load overran a 1 s limit.
    code = textwrap.dedent(
        """
        from repertoire.planning.footstep.fastcore import warm_up
        from repertoire.planning.footstep import reachability

        warm_up()
        print(len(reachability._levels.signatures), len(reachability._fill_reaches.signatures))
        """
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=600, cwd="/"
    )
    assert done.returncode == 0, done.stderr
    levels, fill = map(int, done.stdout.split())
    assert levels >= 1 and fill >= 1


def _wall(height: float, door: tuple[float, float] | None = None, occupied: bool = True):
    """A 5 cm wall ``height`` m high across the 2.2 m x 2 m map at x = 1.2 m (free ground of
    that height if not ``occupied``), with an opening between ``door`` (y, m) if given."""
    occ, heights = np.zeros((88, 80), bool), np.zeros((88, 80))
    rows = slice(round(1.2 / RES), round(1.25 / RES))
    cols = np.ones(80, bool)
    if door is not None:
        cols[round(door[0] / RES) : round(door[1] / RES)] = False
    occ[rows, cols], heights[rows, cols] = occupied, height
    return OccupancyGrid(occ, RES, (0.0, 0.0), heights)


@pytest.mark.parametrize(
    ("height", "door", "occupied", "cut_off"),
    [
        (0.5, None, True, True),  # too tall to swing over: proved at once
        (0.101, None, True, True),
        (0.5, None, False, True),  # a ridge of free ground, too steep to stand on
        (0.09, None, True, False),  # low enough to step over
        (0.5, (0.7, 1.3), True, False),  # a 0.6 m doorway
    ],
)
def test_a_wall_too_tall_for_any_swing_is_cut_off_at_the_first_lattice(
    height, door, occupied, cut_off
):
    # before: the proof left the swing clearance out, so a full wall too tall to swing over
    # was searched on every finer lattice until the time limit (3.4-3.6 s, TIME_LIMIT)
    grid = _wall(height, door, occupied)
    limits = dict(swing_clearance=0.1, max_height_range=0.02)
    assert goal_cut_off(_model(grid, PlannerOptions(**limits))) is cut_off
    plan = plan_footsteps(
        grid, START, "left", GOAL, nominal_action_table(), PlannerOptions(time_limit=60.0, **limits)
    )
    if cut_off:
        assert plan.status is PlanStatus.UNREACHABLE and plan.xy_resolution == 0.05
    else:
        assert plan.status is PlanStatus.SUCCESS


def test_the_swing_wall_is_judged_against_the_ground_near_it():
    # a 0.5 m block to stand on, 0.9 m from a 0.55 m wall: too far for a swing over the wall
    # to start or land on it, so the wall still blocks every swing
    grid = _wall(0.55)
    grid.heights[:12, :12] = 0.5
    limits = dict(swing_clearance=0.1, max_height_range=0.02)
    assert goal_cut_off(_model(grid, PlannerOptions(**limits)))
    grid.heights[30:42, :12] = 0.5  # a block within a swing's reach of the wall: no proof
    assert not goal_cut_off(_model(grid, PlannerOptions(**limits)))


@pytest.mark.parametrize("seed", range(6))
def test_walls_with_doorways_are_never_cut_off(seed):
    """Sound on random walls too tall to swing over, each with a 0.5 m doorway."""
    rng = np.random.default_rng(seed)
    occ, heights = np.zeros((88, 80), bool), np.zeros((88, 80))
    for x in (0.8, 1.4):
        i, door = round(x / RES) + int(rng.integers(-3, 4)), int(rng.integers(0, 60))
        rows = slice(i, i + int(rng.integers(1, 4)))
        occ[rows], heights[rows] = True, float(rng.uniform(0.15, 0.6))
        occ[rows, door : door + 20], heights[rows, door : door + 20] = False, 0.0
    grid = OccupancyGrid(occ, RES, (0.0, 0.0), heights)
    opts = PlannerOptions(time_limit=30.0, swing_clearance=0.1)
    plan = plan_footsteps(grid, START, "left", GOAL, nominal_action_table(), opts)
    assert plan.status is PlanStatus.SUCCESS
    assert not goal_cut_off(_model(grid, opts))


def test_a_kerb_low_over_a_platform_is_not_cut_off():
    grid = _stairs(0.1)  # 0.3 m platform from x = 1.6 m, then a kerb 5 cm above it
    grid.occupied[round(1.9 / RES) : round(1.95 / RES)] = True
    grid.heights[round(1.9 / RES) : round(1.95 / RES)] = 0.35
    opts = PlannerOptions(swing_clearance=0.1, max_step_up=0.12, max_height_range=0.02)
    assert not goal_cut_off(_model(grid, opts, goal=(2.1, 1.0)))
    grid.heights[round(1.9 / RES) : round(1.95 / RES)] = 0.45  # 15 cm above it
    assert goal_cut_off(_model(grid, opts, goal=(2.1, 1.0)))


def _ramp_under_goal() -> OccupancyGrid:
    """A ramp rising 0.5 m over x in [1.25, 2.0) m (1.7 cm per cell), flat ground before it."""
    heights = np.zeros((88, 80))
    heights[50:80, :] = np.linspace(0.0, 0.5, 30)[:, None]
    return OccupancyGrid(np.zeros(heights.shape, bool), RES, (0.0, 0.0), heights)


def test_a_goal_on_ground_too_steep_or_too_cramped_for_a_sole_is_named():
    from repertoire.planning.footstep.types import FootstepError

    # before: UNREACHABLE after a search (and the proof), with no word on why
    table, flat = nominal_action_table(), PlannerOptions(max_height_range=0.01)
    with pytest.raises(FootstepError, match=r"goal \(1.700, 1.000\) lies on ground too steep: .* "
                       r"at least 0.034 m > max_height_range 0.01 m"):  # fmt: skip
        plan_footsteps(_ramp_under_goal(), START, "left", (1.7, 1.0), table, flat)
    # 2 cells of the ramp under the inscribed disc (1.7 cm each): not refused at 4 cm (the
    # check is a relaxation: a sole's outer mask spans more of the ramp, so it may be refused
    # by the search), and a plan stands there at 20 cm
    _model(_ramp_under_goal(), PlannerOptions(max_height_range=0.04), goal=(1.7, 1.0))
    loose = PlannerOptions(max_height_range=0.2, time_limit=20.0)
    assert plan_footsteps(_ramp_under_goal(), START, "left", (1.7, 1.0), table, loose).succeeded
    # a foothold on the flat ground before the ramp is within the tolerance: no error
    near = plan_footsteps(_ramp_under_goal(), START, "left", (1.3, 1.0), table, flat)
    assert near.succeeded
    occ = np.ones((88, 80), bool)
    occ[:30, 20:60] = False  # the start's room
    occ[60:62, 39:41] = False  # a 5 cm free pocket round the goal: no sole fits
    with pytest.raises(FootstepError, match=r"goal \(1.520, 1.000\): no foot fits within "
                       r"goal_tolerance 0.15 m of it"):  # fmt: skip
        plan_footsteps(OccupancyGrid(occ, RES), START, "left", (1.52, 1.0), table)
    # the start already meets the goal: nothing to judge (a plan of no step)
    steep = _ramp_under_goal()
    assert plan_footsteps(steep, (0.4, 1.0, 0.0), "left", (0.45, 1.0), table, flat).succeeded


@pytest.mark.parametrize("seed", range(4))
def test_no_goal_is_refused_where_a_plan_reaches_it(seed, monkeypatch):
    """Sound: bumpy ground with blocks; a goal a fine-lattice plan reaches is never refused."""
    import repertoire.planning.footstep.biped_model as biped_model
    from repertoire.planning.footstep.reachability import goal_foothold_error

    said = []  # the check's verdict per model, the refusal itself switched off
    monkeypatch.setattr(
        biped_model, "goal_foothold_error", lambda m: said.append(goal_foothold_error(m)) or ""
    )
    rng = np.random.default_rng(7100 + seed)
    ii, jj = np.mgrid[:88, :80]
    heights = 0.04 * ((ii + jj) % 2) * (ii >= 40)  # a 4 cm checkerboard past x = 1 m ...
    for i in range(44, 84, 12):  # ... with flat stones of 20 cm, half of them 30 cm apart
        for j in range(2, 76, 12):
            if rng.random() < 0.5:
                heights[i : i + 8, j : j + 8] = 0.02
    occ = np.zeros(heights.shape, bool)
    for _ in range(12):
        i, j = rng.integers(30, 85), rng.integers(0, 76)
        occ[i : i + rng.integers(1, 5), j : j + rng.integers(1, 5)] = True
    occ[:20, 30:50] = False
    grid = OccupancyGrid(occ, RES, (0.0, 0.0), heights)
    opts = PlannerOptions(
        max_height_range=0.015, time_limit=10.0, xy_resolution=0.0125, yaw_bins=144,
        refinements=0, heuristic="euclidean", heuristic_weight=2.0,
    )  # fmt: skip
    verdicts = []
    for goal in rng.uniform((0.7, 0.2), (2.1, 1.8), (16, 2)):
        if occ[int(goal[0] / RES), int(goal[1] / RES)]:
            continue  # a goal in an obstacle: refused before the check
        said.clear()
        plan = plan_footsteps(grid, START, "left", goal, nominal_action_table(), opts)
        verdicts.append((said[0], plan.status))
        if plan.succeeded:
            assert said[0] == ""
    assert any(why for why, _ in verdicts)  # the check refuses some goals on these maps
    assert any(status is PlanStatus.SUCCESS for _, status in verdicts)


def test_a_level_table_that_might_not_fit_in_memory_proves_nothing(monkeypatch):
    # the step model's memory check counts its own fields (150 B a cell); the proof's level
    # table may need up to LEVELS states of 73 B per foothold cell, allocated in the plan's
    # time limit: past the memory limit the proof is skipped (the planner carries on and
    # reports TIME_LIMIT or a finer lattice's status), never allocated
    import repertoire.planning.footstep.reachability as reach

    opts = PlannerOptions(max_step_up=0.03, max_height_range=0.01, time_limit=60.0)
    model = _model(_stairs(0.05), opts)  # 88 x 80 cells: fields ~1 MB, levels up to ~4 MB
    assert goal_cut_off(model)
    monkeypatch.setenv("REPERTOIRE_MAX_MEMORY_BYTES", str(2 * 2**20))
    monkeypatch.setattr(reach, "_levels", lambda *a: pytest.fail("levels built"))
    assert not goal_cut_off(model)
    assert not goal_cut_off(_model(_stairs(0.05), opts))  # the model itself still fits


@pytest.mark.parametrize("flat", [0.015, math.inf])
def test_the_one_cell_foothold_test_agrees_with_the_map_filters(flat):
    import repertoire.planning.footstep.reachability as reach
    from repertoire.planning.footstep.actions import ASIMO_LIKE

    rng = np.random.default_rng(7200)
    occ = rng.random((30, 26)) < 0.08
    heights = rng.choice([0.0, 0.01, 0.03], size=occ.shape)
    occ[:12, :12], heights[:12, :12] = False, 0.0  # a flat free corner: some footholds
    for res in (0.025, 0.01):
        _, valid, _, _ = reach._footholds(~occ, heights, ASIMO_LIKE, res, flat)
        one = [
            [reach._foothold_at(occ[None], heights[None], ASIMO_LIKE, res, i, j, flat)[0]
             for j in range(26)]
            for i in range(30)
        ]  # fmt: skip
        np.testing.assert_array_equal(np.array(one), valid)  # edges included (off the map: free)
        assert 0 < valid.sum() < valid.size
        # a stack of grids: each judged alone (the second without obstacles)
        pair = reach._foothold_at(
            np.stack([occ, np.zeros_like(occ)]),
            np.stack([heights] * 2),
            ASIMO_LIKE,
            res,
            20,
            20,
            flat,
        )
        assert pair.tolist() == [valid[20, 20], bool(reach._footholds(
            np.ones_like(occ), heights, ASIMO_LIKE, res, flat)[1][20, 20])]  # fmt: skip
