"""UNREACHABLE only when the lattice is exhausted: refinement against a fine-lattice search."""

import functools

import numpy as np
import pytest
from repertoire.planning.footstep import (
    OccupancyGrid,
    PlannerOptions,
    PlanStatus,
    nominal_action_table,
    plan_footsteps,
)
from repertoire.planning.footstep.scenes import stepping_stones_grid
from repertoire.planning.footstep.types import FootstepError

START, GOAL = (0.2, 0.45, 0.0), (1.8, 0.4)


@pytest.mark.parametrize(("seed", "gap"), [(0, 0.10), (4, 0.10), (1, 0.08), (2, 0.06)])
def test_no_unreachable_where_a_fine_lattice_finds_a_plan(seed, gap):
    grid = stepping_stones_grid(seed, gap)
    table = nominal_action_table()
    fine = plan_footsteps(
        grid, START, "left", GOAL, table,
        PlannerOptions(time_limit=20.0, xy_resolution=0.01, yaw_bins=144, refinements=0),
    )  # fmt: skip
    plan = plan_footsteps(grid, START, "left", GOAL, table, PlannerOptions(time_limit=20.0))
    assert fine.status is PlanStatus.SUCCESS
    assert plan.status is PlanStatus.SUCCESS
    coarse = plan_footsteps(
        grid, START, "left", GOAL, table, PlannerOptions(time_limit=20.0, refinements=0)
    )
    assert coarse.xy_resolution == 0.05 and coarse.yaw_bins == 36
    if coarse.status is PlanStatus.UNREACHABLE:  # seeds 0 and 4: the 5 cm lattice merged
        assert (seed, plan.xy_resolution, plan.yaw_bins) in ((0, 0.025, 72), (4, 0.025, 72))
    else:
        assert plan.xy_resolution == 0.05


def test_unreachable_reported_at_the_finest_lattice_tried(monkeypatch):
    occ = np.zeros((120, 60), dtype=bool)
    occ[50:90, :] = True  # a 40 cm band across the room: no step crosses it
    grid = OccupancyGrid(occ, 0.01)

    def plan():
        return plan_footsteps(
            grid, (0.2, 0.3, 0.0), "left", (1.1, 0.3), nominal_action_table(),
            PlannerOptions(time_limit=20.0, refinements=1),
        )  # fmt: skip

    # the relaxed flood fill proves the band uncrossable: the first lattice's answer stands
    proved = plan()
    assert proved.status is PlanStatus.UNREACHABLE
    assert (proved.xy_resolution, proved.yaw_bins) == (0.05, 36)
    # without that proof, the planner refines and reports the finest lattice it tried
    monkeypatch.setattr("repertoire.planning.footstep.planner.goal_cut_off", lambda *a: False)
    plan = plan()
    assert plan.status is PlanStatus.UNREACHABLE
    assert (plan.xy_resolution, plan.yaw_bins) == (0.025, 72)
    assert max(p[0] for p in plan.poses) < 0.5
    with pytest.raises(FootstepError, match="gap must be >= 0 m, got -0.1"):
        stepping_stones_grid(0, -0.1)
    with pytest.raises(FootstepError, match="refinements must be an integer in"):
        PlannerOptions(refinements=7).validate()


def test_maze_grid_is_seeded_and_connected():
    from repertoire.planning.footstep.scenes import maze_grid
    from scipy import ndimage

    a, b = maze_grid(3), maze_grid(3)
    np.testing.assert_array_equal(a.occupied, b.occupied)
    assert not np.array_equal(a.occupied, maze_grid(4).occupied)
    labels, count = ndimage.label(~a.occupied)
    assert count == 1  # every room reachable through 0.5 m doorways
    assert a.shape == (240, 240)
    assert a.occupied[:, 0].all() and a.occupied[0, :].all()  # walled boundary
    with pytest.raises(FootstepError, match="do not fit"):
        maze_grid(0, door=1.2)


def test_swing_clearance_blocks_tall_walls_only():
    from repertoire.planning.footstep import RectObstacle

    wall = OccupancyGrid.from_rectangles((2.0, 1.0), [RectObstacle([1.0, 0.5], [0.05, 1.0])])
    table = nominal_action_table()
    args = ((0.4, 0.595, 0.0), "left", (1.6, 0.5), table)
    opts = PlannerOptions(time_limit=20.0, swing_clearance=0.1, refinements=1)
    for height, status in ((0.5, PlanStatus.UNREACHABLE), (0.05, PlanStatus.SUCCESS)):
        grid = OccupancyGrid(wall.occupied, wall.resolution, wall.origin, height * wall.occupied)
        plan = plan_footsteps(grid, *args, opts)
        assert plan.status is status, height
        if status is PlanStatus.UNREACHABLE:
            assert max(p[0] for p in plan.poses) < 1.0  # never past the wall
    # without a clearance (the default) the 5 cm thick wall of any height is stepped over
    tall = OccupancyGrid(wall.occupied, wall.resolution, wall.origin, 0.5 * wall.occupied)
    assert plan_footsteps(tall, *args, PlannerOptions(time_limit=20.0)).succeeded
    with pytest.raises(FootstepError, match=r"cell \(0, 0\) is -0.2 m"):
        OccupancyGrid(wall.occupied, wall.resolution, wall.origin, -0.2 * np.ones(wall.shape))
    with pytest.raises(FootstepError, match=r"cell \(0, 0\) is nan"):
        OccupancyGrid(wall.occupied, wall.resolution, wall.origin, np.full(wall.shape, np.nan))
    with pytest.raises(FootstepError, match="swing_clearance must be > 0 m, got -1"):
        PlannerOptions(swing_clearance=-1.0).validate()


def test_landing_only_on_flat_enough_ground():
    occ = np.zeros((80, 40), dtype=bool)
    heights = np.zeros((80, 40))
    heights[30:50, :] = np.linspace(0.0, 0.3, 40)[None, :]  # a steep ramp band across y
    occ_grid = OccupancyGrid(occ, 0.025, (0.0, 0.0), heights)
    table = nominal_action_table()
    opts = PlannerOptions(time_limit=20.0, max_height_range=0.01, refinements=0)
    plan = plan_footsteps(occ_grid, (0.2, 0.5, 0.0), "left", (1.8, 0.5), table, opts)
    assert plan.status is PlanStatus.UNREACHABLE  # the 0.5 m band is too wide to step over
    xs = [p[0] for p in plan.poses]
    assert max(xs) < 0.75 + 0.08 + 0.025  # no sole centre on the ramp band x in [0.75, 1.25]
    flat = PlannerOptions(time_limit=20.0)
    assert plan_footsteps(occ_grid, (0.2, 0.5, 0.0), "left", (1.8, 0.5), table, flat).succeeded
    with pytest.raises(FootstepError, match="start at \\(1.000, 0.500\\) stands on ground too"):
        plan_footsteps(occ_grid, (1.0, 0.5, 0.0), "left", (1.8, 0.5), table, opts)


def test_default_refinements_reach_the_lattice_a_stepping_stone_field_needs():
    # 10 cm gaps between short stones: UNREACHABLE down to 1.25 cm / 144 bins (the old
    # default, 2 refinements), a plan on 0.625 cm / 288 (the default's finest)
    grid = stepping_stones_grid(534926, 0.10, stone_length=(0.18, 0.24))
    table = nominal_action_table()
    two = plan_footsteps(
        grid, START, "left", GOAL, table, PlannerOptions(time_limit=20.0, refinements=2)
    )
    assert two.status is PlanStatus.UNREACHABLE
    assert (two.xy_resolution, two.yaw_bins) == (0.0125, 144)
    plan = plan_footsteps(grid, START, "left", GOAL, table, PlannerOptions(time_limit=20.0))
    assert PlannerOptions().refinements == 3
    assert plan.status is PlanStatus.SUCCESS
    assert (plan.xy_resolution, plan.yaw_bins) == (0.00625, 288)


def test_fine_grids_fall_back_to_the_python_core_or_name_the_mask_width():
    # the nominal foot plus the 1 cm margin spans 65 cells of 3.7 mm: past the compiled
    # core's 64-bit footprint rows
    grid = OccupancyGrid(np.zeros((200, 120), dtype=bool), 0.0037)
    table = nominal_action_table()
    args = (grid, (0.1, 0.3, 0.0), "left", (0.5, 0.3), table)
    auto = plan_footsteps(*args, PlannerOptions(time_limit=20.0))
    python = plan_footsteps(*args, PlannerOptions(time_limit=20.0, backend="python"))
    assert auto.succeeded and auto.poses == python.poses and auto.cost == python.cost
    with pytest.raises(FootstepError, match="at most 64 cells across; .* spans 65 cells"):
        plan_footsteps(*args, PlannerOptions(time_limit=20.0, backend="compiled"))
    coarse = OccupancyGrid(np.zeros((80, 48), dtype=bool), 0.01)  # 1 cm: the compiled core
    margin = PlannerOptions(time_limit=20.0, backend="compiled", footprint_margin_m=0.3)
    with pytest.raises(FootstepError, match="footprint_margin_m=0.3 m spans"):
        plan_footsteps(coarse, (0.1, 0.3, 0.0), "left", (0.5, 0.3), table, margin)


@pytest.mark.parametrize("backend", ["compiled", "python"])
def test_bad_weights_and_option_types_are_named_on_both_backends(backend):
    from repertoire.planning.footstep import plan_footsteps_anytime

    grid = OccupancyGrid(np.zeros((80, 40), dtype=bool), 0.025)
    table = nominal_action_table()
    args = (grid, (0.2, 0.5, 0.0), "left", (1.6, 0.5), table)
    opts = PlannerOptions(time_limit=5.0, backend=backend)
    for weights, match in (
        ((0.5,), "numbers >= 1, got \\[0.5\\]"),
        ((float("nan"),), "numbers >= 1, got \\[nan\\]"),
        ((float("inf"), 1.0), "numbers >= 1, got \\[inf, 1.0\\]"),
        ((), "numbers >= 1, got \\[\\]"),
        (("fast",), "numbers >= 1, got \\('fast',\\)"),
        ((1.0, 2.0), "must not increase, got \\[1.0, 2.0\\]"),
    ):
        with pytest.raises(FootstepError, match=match):
            plan_footsteps_anytime(*args, opts, weights=weights)
    for field, value, match in (
        ("heuristic_weight", 0.5, "heuristic_weight must be finite and >= 1 .*got 0.5"),
        ("heuristic_weight", "1", "heuristic_weight must be a number, got '1'"),
        ("refinements", True, "refinements must be a number, got True"),
        ("step_over_depth", float("nan"), "step_over_depth must be .* got nan"),
    ):
        bad = PlannerOptions(time_limit=5.0, backend=backend, **{field: value})
        with pytest.raises(FootstepError, match=match):
            plan_footsteps(*args, bad)
    with pytest.raises(FootstepError, match="corridor must be a half-width >= 0 m, got 'wide'"):
        plan_footsteps_anytime(*args, opts, corridor="wide")


@pytest.mark.parametrize("backend", ["python", "compiled"])
def test_footprint_masks_are_built_before_the_clock_starts(backend, monkeypatch):
    # a resolution no other test uses: the masks of this foot and margin are built by
    # _build_footprint_masks, outside the time limit, and the step model finds them cached
    import repertoire.planning.footstep.planner as planner_module
    from repertoire.planning.footstep.biped_model import BipedStepModel
    from repertoire.planning.footstep.fastcore import warm_up
    from repertoire.planning.footstep.footprint import footprint_masks

    warm_up()  # its own tiny model, before this test's
    res = 0.0173 if backend == "python" else 0.0171
    grid = OccupancyGrid(np.zeros((120, 46), dtype=bool), res)
    opts = PlannerOptions(time_limit=5.0, backend=backend)
    order = []
    built = planner_module._build_footprint_masks
    monkeypatch.setattr(
        planner_module, "_build_footprint_masks", lambda *a: (built(*a), order.append("masks"))
    )
    model_init = BipedStepModel.__init__

    def init(self, *a, **k):
        misses = footprint_masks.cache_info().misses
        model_init(self, *a, **k)
        order.append(("model", footprint_masks.cache_info().misses - misses))

    monkeypatch.setattr(BipedStepModel, "__init__", init)
    plan = plan_footsteps(grid, START, "left", GOAL, nominal_action_table(), opts)
    assert plan.succeeded
    assert order == ["masks", ("model", 0)]  # masks first, no mask built by the model
    masks = footprint_masks(0.16 + 0.02, 0.1 + 0.02, res)
    assert ("outer_rows" in masks.__dict__) is (backend == "python")  # the rows it reads


@pytest.mark.parametrize("bins", [36, 72])
def test_yaw_bins_are_centred_on_the_start_yaw(bins):
    # the nominal turns are 0.35 rad (2.005 bins of 36, 4.011 of 72): every yaw a plan
    # reaches is the start's plus k turns, and 18 turns come back 0.017 rad off. With the
    # bins centred on the start's yaw each such yaw sits within a fifth of a bin of a
    # centre, so a whole turn's remainder never splits one yaw into two states, whatever
    # the start yaw (at 72 bins, 37 % of start yaws split one with bins on the map's axes)
    from repertoire.planning.footstep.biped_model import BipedStepModel
    from repertoire.planning.footstep.types import wrap_angle

    grid = OccupancyGrid(np.zeros((40, 40), dtype=bool), 0.05)
    for yaw0 in np.linspace(-np.pi, np.pi, 37)[:-1] + 0.013:
        opts = PlannerOptions(yaw_bins=bins)
        model = BipedStepModel(
            grid, (1.0, 1.0, yaw0), "left", (1.5, 1.5), nominal_action_table(), opts
        )
        key = functools.partial(model.lattice_key, 1.0, 1.0, foot=0, hist=0, t=0.0)
        turns = [wrap_angle(yaw0 + k * 0.35) for k in range(18)]
        assert len({key(y) for y in turns}) == 18  # one bin per yaw class
        for y in turns:  # a whole turn's remainder and rounding: the same bin
            assert key(wrap_angle(y + 18 * 0.35)) == key(y) == key(wrap_angle(y - 18 * 0.35))
            assert key(np.nextafter(y, 4.0)) == key(y) == key(np.nextafter(y, -4.0))
        # key: ((cell * bins + yaw bin) * 2 + foot) * n_hist + hist
        bin_of_start = (key(yaw0) // model.n_hist // 2) % bins
        u = yaw0 * bins / (2 * np.pi)
        assert bin_of_start == round(u) % bins  # the bin whose centre is the start's yaw


def test_each_refinement_gets_the_time_left_of_the_plans_limit(monkeypatch):
    # a fake clock: every search takes 1 s and ends UNREACHABLE after merging states. The
    # refinements searched with time_limit - 2 x elapsed before (the time left was passed as
    # the finer lattice's limit and the elapsed time taken off it again), so a 5 s plan
    # stopped its last lattice with TIME_LIMIT after 3.8 s
    import types

    import repertoire.planning.footstep.planner as planner_module
    from repertoire.planning.footstep.search import SearchResult

    clock = [0.0]
    monkeypatch.setattr(
        planner_module, "time", types.SimpleNamespace(perf_counter=lambda: clock[0])
    )
    monkeypatch.setattr(planner_module, "goal_cut_off", lambda *a: False)
    given = []

    def one_second(model, backend, weight, budget, left):
        given.append((model.opts.xy_resolution, left))
        clock[0] += 1.0
        return SearchResult(PlanStatus.UNREACHABLE, [model.start()], 0.0, weight, 1, 1.0, merged=1)

    monkeypatch.setattr(planner_module, "_search_once", one_second)
    grid = OccupancyGrid(np.zeros((80, 40), dtype=bool), 0.025)
    opts = PlannerOptions(time_limit=10.0)
    plan = plan_footsteps(grid, START, "left", GOAL, nominal_action_table(), opts)
    assert given == [(0.05, 10.0), (0.025, 9.0), (0.0125, 8.0), (0.00625, 7.0)]
    assert plan.status is PlanStatus.UNREACHABLE and plan.xy_resolution == 0.00625
    given.clear()
    clock[0] = 0.0
    short = plan_footsteps(
        grid, START, "left", GOAL, nominal_action_table(), PlannerOptions(time_limit=2.0)
    )
    assert given == [(0.05, 2.0), (0.025, 1.0)]  # then no time is left: TIME_LIMIT
    assert short.status is PlanStatus.TIME_LIMIT and short.xy_resolution == 0.025
