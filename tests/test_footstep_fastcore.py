"""The compiled search core gives the Python loop's plans; its parts against references."""

import heapq
import itertools
import os
from pathlib import Path

import numpy as np
import pytest
from repertoire.planning.footstep import (
    OccupancyGrid,
    PlannerOptions,
    PlanStatus,
    RectObstacle,
    nominal_action_table,
    plan_footsteps,
)
from repertoire.planning.footstep.scenes import random_static_scene, stepping_stones_grid
from repertoire.planning.footstep.types import FootstepError


def _both(grid, start, foot, goal, table, **opts):
    # A generous wall-time budget: the comparison is of plans, not of speed, and a loaded
    # machine must not make the slower Python core stop on its clock first.
    opts.setdefault("time_limit", 60.0)
    plans = [
        plan_footsteps(grid, start, foot, goal, table, PlannerOptions(backend=b, **opts))
        for b in ("python", "compiled")
    ]
    py, cc = plans
    assert py.status is cc.status
    assert py.poses == cc.poses and py.actions == cc.actions and py.times == cc.times
    assert py.cost == cc.cost and py.cost_to_go == cc.cost_to_go
    assert (py.nodes_expanded, py.nodes_generated) == (cc.nodes_expanded, cc.nodes_generated)
    assert (py.xy_resolution, py.yaw_bins) == (cc.xy_resolution, cc.yaw_bins)
    return cc


def _anytime_both(sc, table, **opts):
    # ARA* on both cores, one lattice, a generous wall-time budget (as _both)
    from repertoire.planning.footstep import plan_footsteps_anytime

    return [
        plan_footsteps_anytime(
            sc.grid,
            sc.start,
            sc.start_foot,
            sc.goal,
            table,
            PlannerOptions(time_limit=60.0, refinements=0, backend=b, **opts),
        )  # fmt: skip
        for b in ("python", "compiled")
    ]


@pytest.mark.parametrize("seed", [0, 3, 7])
def test_identical_plans_on_study_maps(seed):
    sc = random_static_scene(seed, n_strips=8, n_blocks=4)
    table = nominal_action_table()
    plan = _both(sc.grid, sc.start, sc.start_foot, sc.goal, table, time_limit=30.0)
    assert plan.status is PlanStatus.SUCCESS
    # the Euclidean heuristic (expansion budget); and a short budget: the same partial plan
    _both(
        sc.grid, sc.start, sc.start_foot, sc.goal, table,
        time_limit=30.0, heuristic="euclidean", max_expansions=3000, refinements=0,
    )  # fmt: skip
    cut = _both(sc.grid, sc.start, sc.start_foot, sc.goal, table, max_expansions=50)
    assert cut.status is PlanStatus.NODE_LIMIT and cut.nodes_expanded == 50


def test_identical_plans_on_stepping_stones_with_refinement():
    grid = stepping_stones_grid(0, 0.10)
    table = nominal_action_table()
    plan = _both(grid, (0.2, 0.45, 0.0), "left", (1.8, 0.4), table, time_limit=30.0)
    assert plan.status is PlanStatus.SUCCESS and plan.xy_resolution == 0.025


def test_identical_plans_with_heights_clearance_and_flatness():
    wall = OccupancyGrid.from_rectangles((2.0, 1.0), [RectObstacle([1.0, 0.5], [0.05, 1.0])])
    heights = 0.3 * wall.occupied
    heights[50:60, :] += np.linspace(0.0, 0.02, 40)[None, :]  # a gentle ramp across the room
    grid = OccupancyGrid(wall.occupied, wall.resolution, wall.origin, heights)
    table = nominal_action_table()
    args = (grid, (0.4, 0.595, 0.0), "left", (1.6, 0.5), table)
    blocked = _both(*args, time_limit=30.0, swing_clearance=0.1, refinements=0)
    assert blocked.status is PlanStatus.UNREACHABLE
    crossed = _both(*args, time_limit=30.0, max_height_range=0.5, height_cost_weight=5.0)
    assert crossed.status is PlanStatus.SUCCESS
    plain = plan_footsteps(*args, PlannerOptions(time_limit=30.0))
    assert crossed.cost > plain.cost  # the height cost is paid on the ramp


def test_unreachable_band_on_both_backends(monkeypatch):
    occ = np.zeros((60, 30), dtype=bool)
    occ[25:41, :] = True  # a 40 cm band across the room: no step crosses it
    grid = OccupancyGrid(occ, 0.025)
    args = (grid, (0.2, 0.3, 0.0), "left", (1.2, 0.3), nominal_action_table())
    plan = _both(*args, time_limit=30.0, refinements=1)
    assert plan.status is PlanStatus.UNREACHABLE and plan.xy_resolution == 0.05  # proved cut off
    monkeypatch.setattr("repertoire.planning.footstep.planner.goal_cut_off", lambda *a: False)
    plan = _both(*args, time_limit=30.0, refinements=1)  # no proof: the next lattice is tried
    assert plan.status is PlanStatus.UNREACHABLE and plan.xy_resolution == 0.025
    assert max(p[0] for p in plan.poses) < 0.625


def test_compiled_heap_pops_in_tuple_order():
    from repertoire.planning.footstep.fastkernels import _heap_pop, _heap_push

    rng = np.random.default_rng(0)
    n = 500
    f = rng.integers(0, 20, n).astype(float)  # many ties on f, broken by h, then tie
    h = rng.integers(0, 5, n).astype(float)
    heap = np.empty((n, 4))
    for k in range(n):
        _heap_push(heap, k, f[k], h[k], k, 7 * k + 1)  # the node rides along
    ref = [(f[k], h[k], k) for k in range(n)]
    heapq.heapify(ref)
    for size in range(n, 0, -1):
        want = heapq.heappop(ref)
        assert tuple(heap[0, :3]) == want and heap[0, 3] == 7 * want[2] + 1
        _heap_pop(heap, size)


def test_heap_rows_put_child_groups_on_lines_and_growth_keeps_rows():
    from repertoire.planning.footstep.fastkernels import _grow_heap, _heap_rows

    base = np.empty((64 + 4, 4))[1:]  # numpy aligns to 16 bytes: any 32-byte offset may come
    rows = _heap_rows(base)
    assert base.shape[0] - 3 <= rows.shape[0] <= base.shape[0]
    assert (rows.ctypes.data + 32) % 128 in (0, 112)  # 112: a base not on 32 bytes
    rows[:50] = np.arange(200.0).reshape(50, 4)
    new = _grow_heap(base, rows, 50)
    assert new.shape == (2 * base.shape[0], 4)
    assert (_heap_rows(new)[:50] == rows[:50]).all()


def test_grid_dijkstra_matches_scipy():
    from repertoire.planning.footstep.heuristic import grid_dijkstra, grid_graph
    from scipy.sparse.csgraph import dijkstra

    rng = np.random.default_rng(1)
    cost = rng.choice([1.0, 3.0, 30.0, np.inf], size=(37, 23), p=[0.6, 0.2, 0.1, 0.1])
    sources = np.array([5 * 23 + 7, 30 * 23 + 2])
    cost.flat[sources] = 1.0
    ref = dijkstra(grid_graph(cost, 0.05), directed=True, indices=sources, min_only=True)
    got = grid_dijkstra(cost, 0.05, sources)
    np.testing.assert_allclose(got.ravel(), ref, rtol=1e-12)
    assert np.array_equal(np.isinf(got.ravel()), np.isinf(ref))
    # closed form: one source on a free 3 x 3 grid; the corner is one diagonal + one straight
    d = grid_dijkstra(np.ones((3, 3)), 1.0, np.array([0]))
    assert d[2, 1] == pytest.approx(np.sqrt(2.0) + 1.0) and d[0, 2] == 2.0


def test_backend_option_errors():
    with pytest.raises(FootstepError, match="unknown backend 'fortran'"):
        PlannerOptions(backend="fortran").validate()
    from repertoire.planning.footstep.scenes import strings_scene

    sc = strings_scene(0)
    with pytest.raises(FootstepError, match="compiled backend plans on static grids only"):
        plan_footsteps(
            sc.env, sc.start, sc.start_foot, sc.goal, nominal_action_table(),
            PlannerOptions(heuristic="euclidean", backend="compiled"),
        )  # fmt: skip


def test_ara_star_compiled_matches_python_and_bounds_hold():
    sc = random_static_scene(2, size=2.0, n_strips=3, n_blocks=2)
    table = nominal_action_table()
    py, cc = _anytime_both(sc, table, heuristic="euclidean")
    # 1.2 is skipped: the plan of 1.5 already reported a bound below it
    assert [a.weight for a in cc] == [3.0, 2.0, 1.5, 1.0] and cc[2].bound <= 1.2
    assert all(b.weight < a.bound for a, b in itertools.pairwise(cc))
    for a, b in zip(py, cc, strict=True):
        assert a.plan.poses == b.plan.poses and a.plan.cost == b.plan.cost
        assert a.bound == b.bound and a.plan.nodes_expanded == b.plan.nodes_expanded
    assert all(a.plan.status is PlanStatus.SUCCESS for a in cc)
    optimum = cc[-1].plan.cost  # weight 1, admissible and consistent heuristic
    costs = [a.plan.cost for a in cc]
    assert costs == sorted(costs, reverse=True)
    assert all(a.plan.cost <= a.bound * optimum + 1e-9 for a in cc)
    assert all(1.0 <= a.bound <= a.weight for a in cc) and cc[-1].bound == 1.0
    fresh = plan_footsteps(
        sc.grid, sc.start, sc.start_foot, sc.goal, table,
        PlannerOptions.admissible(time_limit=60.0, xy_resolution=0.05, yaw_bins=36),
    )  # fmt: skip
    assert fresh.cost == pytest.approx(optimum, rel=1e-12)


def test_ara_star_earlier_plans_keep_their_own_paths():
    """A later weight that reroutes through an earlier plan's goal leaves that plan alone.

    On this dense map ARA*'s weight-2 search gives the goal node of the weight-3 plan a
    cheaper parent; the weight-3 plan must still be the 29 steps it was found as (its
    cost 31.15), as the Python core and a fresh weighted A* at weight 3 give it.
    """
    from repertoire.planning.footstep import plan_footsteps_anytime

    sc = random_static_scene(1, n_strips=8, n_blocks=4)
    args = (sc.grid, sc.start, sc.start_foot, sc.goal, nominal_action_table())
    py, cc = (
        plan_footsteps_anytime(
            *args, PlannerOptions(time_limit=60.0, backend=b), weights=(3.0, 2.0), restarts=False
        )
        for b in ("python", "compiled")
    )
    assert [a.plan.cost for a in cc] == [a.plan.cost for a in py]
    assert cc[0].plan.cost > cc[1].plan.cost  # the weight-2 plan is another, cheaper path
    for a, b in zip(py, cc, strict=True):
        assert a.plan.poses == b.plan.poses and a.plan.times == b.plan.times
    fresh = plan_footsteps(*args, PlannerOptions(time_limit=60.0, heuristic_weight=3.0))
    assert cc[0].plan.poses == fresh.poses and cc[0].plan.cost == fresh.cost


def test_bad_inputs_named(monkeypatch):
    from repertoire.limits import ResourceLimitError

    table = nominal_action_table()
    with pytest.raises(ResourceLimitError, match=r"400000 x 400000 occupancy grid"):
        OccupancyGrid.empty((10_000.0, 10_000.0), 0.025)
    grid = OccupancyGrid.empty((2.0, 2.0), 0.025)
    with monkeypatch.context() as m:
        m.setenv("REPERTOIRE_MAX_MEMORY_BYTES", "100000")  # the grid fits, planning does not
        with pytest.raises(ResourceLimitError, match=r"planning fields .* of a 80 x 80 map"):
            plan_footsteps(grid, (0.3, 0.3, 0.0), "left", (1.5, 1.5), table)
    with pytest.raises(FootstepError, match="successors are empty: the action_filter allows"):
        plan_footsteps(
            grid, (0.3, 0.3, 0.0), "left", (1.5, 1.5), table, action_filter=lambda *_: []
        )
    occ = np.zeros((80, 80), dtype=bool)
    occ[58:62, 58:62] = True
    with pytest.raises(FootstepError, match=r"goal \(1.500, 1.500\) lies inside an obstacle"):
        plan_footsteps(OccupancyGrid(occ, 0.025), (0.3, 0.3, 0.0), "left", (1.5, 1.5), table)


def test_step_up_and_step_down_limits():
    occ = np.zeros((80, 40), dtype=bool)
    heights = np.zeros((80, 40))
    heights[40:, :] = 0.15  # a free platform 15 cm up for x >= 1 m
    grid = OccupancyGrid(occ, 0.025, (0.0, 0.0), heights)
    table = nominal_action_table()
    up = (grid, (0.3, 0.595, 0.0), "left", (1.7, 0.5), table)
    down = (grid, (1.7, 0.595, np.pi), "right", (0.3, 0.5), table)
    common = {"time_limit": 30.0, "refinements": 0}
    assert _both(*up, max_step_up=0.1, **common).status is PlanStatus.UNREACHABLE
    climbed = _both(*up, max_step_up=0.2, max_step_down=0.0, **common)
    assert climbed.status is PlanStatus.SUCCESS
    assert _both(*down, max_step_down=0.1, **common).status is PlanStatus.UNREACHABLE
    assert _both(*down, max_step_down=0.2, max_step_up=0.0, **common).succeeded
    blocked = _both(*up, max_step_up=0.1, **common)
    assert max(p[0] for p in blocked.poses) < 1.0 + 0.09  # never stood on the platform
    with pytest.raises(FootstepError, match="max_step_up must be >= 0 m, got nan"):
        PlannerOptions(max_step_up=float("nan")).validate()
    with pytest.raises(FootstepError, match="max_step_down must be >= 0 m, got -0.1"):
        PlannerOptions(max_step_down=-0.1).validate()


def test_dynamic_grids_carry_heights_and_the_swing_clearance_uses_them():
    from repertoire.planning.footstep.biped_model import BipedStepModel, swing_crosses
    from repertoire.planning.footstep.scenes import strings_scene

    sc = strings_scene(0, t_end=12.0)
    assert np.unique(sc.env.grids[0].heights).tolist() == [0.0, 0.005, 0.02]
    table = nominal_action_table()
    opts = PlannerOptions(heuristic="euclidean", time_limit=30.0, swing_clearance=0.01)
    plan = plan_footsteps(sc.env, sc.start, sc.start_foot, sc.goal, table, opts)
    assert plan.succeeded
    opts.validate()
    model = BipedStepModel(sc.env, sc.start, sc.start_foot, sc.goal, table, opts)
    assert model.tall_at(0) is not None and (model.tall_at(0) > 0.01).sum() > 0  # 2 cm blocks
    swing = [plan.initial_swing_pose[:2]] + [p[:2] for p in plan.poses[:-1]]
    res, (ox, oy) = sc.env.resolution, sc.env.reference.origin
    for k in range(1, len(plan.poses)):  # step k swings during [times[k-1], times[k]]
        idx = model.checkers.index
        tall = model.tall_during(idx(plan.times[k - 1]), idx(plan.times[k]))
        if tall is not None:
            x0, y0 = swing[k - 1]
            # the soles stand on free ground of height 0: the swing's top is the clearance
            top = opts.swing_clearance
            assert not swing_crosses(tall, top, x0, y0, *plan.poses[k][:2], ox, oy, 1.0 / res)


def test_compiled_distance_transform_matches_scipy():
    from repertoire.planning.footstep.footprint import distance_to_features
    from scipy import ndimage

    rng = np.random.default_rng(3)
    for shape, p in (((37, 23), 0.1), ((60, 70), 0.02), ((40, 9), 0.5)):
        features = rng.random(shape) < p
        want = ndimage.distance_transform_edt(~features)
        np.testing.assert_array_equal(distance_to_features(features), want)
    assert np.isinf(distance_to_features(np.zeros((4, 3), dtype=bool))).all()
    one = np.zeros((5, 5), dtype=bool)
    one[0, 0] = True
    assert distance_to_features(one)[3, 4] == 5.0  # the 3-4-5 triangle


def test_anytime_refines_before_unreachable():
    from repertoire.planning.footstep import plan_footsteps_anytime

    grid = stepping_stones_grid(0, 0.10)  # the 5 cm lattice merges the only way across
    args = (grid, (0.2, 0.45, 0.0), "left", (1.8, 0.4), nominal_action_table())
    coarse = plan_footsteps_anytime(*args, PlannerOptions(time_limit=30.0, refinements=0))
    assert coarse[-1].plan.status is PlanStatus.UNREACHABLE
    runs = plan_footsteps_anytime(*args, PlannerOptions(time_limit=30.0), weights=(2.0, 1.0))
    # ARA* on 2.5 cm at weights 2 and 1, then the admissible search on 1.25 cm / 144 bins
    # proves the cost that lattice's optimum too (bound 1, as cheap)
    assert [r.plan.status for r in runs] == [PlanStatus.SUCCESS] * 3
    assert [r.plan.xy_resolution for r in runs] == [0.025, 0.025, 0.0125]
    assert [r.bound for r in runs[1:]] == [1.0, 1.0]
    assert runs[-1].plan.cost == runs[-2].plan.cost


def test_lazy_cost_to_go_equals_the_full_dijkstra_bit_for_bit():
    from repertoire.planning.footstep.heuristic import LazyCostToGo, dijkstra_cost_to_go

    rng = np.random.default_rng(3)
    for trial in range(40):
        nx, ny = (int(v) for v in rng.integers(3, 30, 2))
        res = float(rng.choice([0.01, 0.025, 0.1]))
        grid = OccupancyGrid(rng.random((nx, ny)) < rng.uniform(0.0, 0.6), res, (-0.3, 0.2))
        goal = (-0.3 + rng.uniform(0, nx * res), 0.2 + rng.uniform(0, ny * res))
        toward = (-0.3 + rng.uniform(0, nx * res), 0.2 + rng.uniform(0, ny * res))
        kw = {
            "obstacle_cost": float(rng.choice([1.0, 3.0])),
            "impassable_depth": float(rng.choice([np.inf, res, 2.5 * res, 20 * res])),
            "deep_cost": 30.0,
        }
        full = dijkstra_cost_to_go(grid, goal, 0.1, **kw).ravel()
        lazy = LazyCostToGo(grid, goal, 0.1, toward, retarget_cells=int(trial % 3), **kw)
        order = rng.permutation(full.size)
        got = np.array([lazy.value(int(c)) for c in order])
        np.testing.assert_array_equal(got, full[order], err_msg=f"trial {trial}")
    # open floor, goal cell in a corner, query the cell next to it: only a handful settle
    grid = OccupancyGrid(np.zeros((50, 50), dtype=bool), 0.1)
    lazy = LazyCostToGo(grid, (0.05, 0.05), 0.0, (0.15, 0.05))
    assert lazy.value(1 * 50 + 0) == pytest.approx(0.1)
    assert lazy.settled < 10
    assert lazy.value(49 * 50 + 49) == pytest.approx(49 * 0.1 * np.sqrt(2.0))


def test_eager_cost_to_go_equals_the_full_dijkstra_bit_for_bit():
    from repertoire.planning.footstep.heuristic import LazyCostToGo, dijkstra_cost_to_go

    rng = np.random.default_rng(5)
    for trial in range(40):
        nx, ny = (int(v) for v in rng.integers(1, 40, 2))
        res = float(rng.choice([0.01, 0.025, 0.1]))
        grid = OccupancyGrid(rng.random((nx, ny)) < rng.uniform(0.0, 0.7), res, (0.4, -0.2))
        goal = (0.4 + rng.uniform(0, nx * res), -0.2 + rng.uniform(0, ny * res))
        kw = {
            # 0: a free-of-charge obstacle (no bucket width), the heap Dijkstra's values
            "obstacle_cost": float(rng.choice([0.0, 0.5, 1.0, 3.0])),
            "impassable_depth": float(rng.choice([np.inf, 0.0, res, 2.5 * res, 20 * res])),
            "deep_cost": float(rng.choice([30.0, 1e3])),
        }
        tol = float(rng.choice([0.0, 0.1]))
        full = dijkstra_cost_to_go(grid, goal, tol, **kw)
        eager = LazyCostToGo(grid, goal, tol, goal, eager_cells=nx * ny, **kw)
        assert eager.settled == nx * ny and eager.size[0] == 0
        np.testing.assert_array_equal(eager.f[:, 0], full.ravel(), err_msg=f"trial {trial}")
        assert eager.value(int(rng.integers(nx * ny))) in full
    # the work arrays are kept: a smaller map after a larger one reuses them (dirty)
    from repertoire.planning.footstep import heuristic

    kept = heuristic._EAGER_WORK[0]
    small = OccupancyGrid(rng.random((9, 7)) < 0.3, 0.05)
    again = LazyCostToGo(small, (0.2, 0.2), 0.05, (0.0, 0.0), eager_cells=63)
    assert heuristic._EAGER_WORK[0] is kept
    full = dijkstra_cost_to_go(small, (0.2, 0.2), 0.05)
    np.testing.assert_array_equal(again.f[:, 0], full.ravel())
    # a map larger than eager_cells settles on demand
    grid = OccupancyGrid(np.zeros((50, 50), dtype=bool), 0.1)
    assert LazyCostToGo(grid, (0.05, 0.05), 0.0, (0.15, 0.05), eager_cells=2499).settled == 0
    assert LazyCostToGo(grid, (0.05, 0.05), 0.0, (0.15, 0.05), eager_cells=2500).settled == 2500


def test_numba_cache_directory_is_writable_for_every_compiled_function():
    import os

    import numba.core.registry
    from repertoire.planning.footstep import fastcore, fastkernels, footprint, heuristic

    fastcore.warm_up()
    compiled = [
        obj
        for mod in (fastcore, fastkernels, footprint, heuristic)
        for obj in vars(mod).values()
        if isinstance(obj, numba.core.registry.CPUDispatcher)
    ]
    assert len(compiled) >= 15
    for fn in compiled:
        assert fn._cache._cache_path, fn.__name__  # cache=True: a cache locator was found
        assert os.access(fn._cache._cache_path, os.W_OK), (fn.__name__, fn._cache._cache_path)
    # the search core ran in this process: compiled here or loaded from that cache
    assert fastcore._arastar.signatures


def test_cost_to_go_is_shared_by_plans_on_the_same_map_and_goal():
    from repertoire.planning.footstep.biped_model import BipedStepModel

    sc = random_static_scene(4)
    table = nominal_action_table()
    opts = PlannerOptions(backend="compiled")
    first = plan_footsteps(sc.grid, sc.start, sc.start_foot, sc.goal, table, opts)
    model = BipedStepModel(sc.grid, sc.start, sc.start_foot, sc.goal, table, opts)
    settled = model.h_lazy.settled
    assert settled > 0  # the first plan's cells are already there
    again = plan_footsteps(sc.grid, sc.start, sc.start_foot, sc.goal, table, opts)
    assert again.poses == first.poses and again.cost == first.cost
    # another start on the same map and goal reuses the field; an edited map does not
    other = BipedStepModel(sc.grid, (0.3, 1.5, 0.0), "left", sc.goal, table, opts)
    assert other.h_lazy is model.h_lazy
    occ = sc.grid.occupied.copy()
    occ[0, 0] = not occ[0, 0]
    edited = OccupancyGrid(occ, sc.grid.resolution, sc.grid.origin, sc.grid.heights)
    fresh = BipedStepModel(edited, sc.start, sc.start_foot, sc.goal, table, opts)
    assert fresh.h_lazy is not model.h_lazy
    assert fresh.h_lazy.f[0, 1] != model.h_lazy.f[0, 1]  # the edited cell's cost


def test_compiled_yaw_wrap_and_bin_equal_the_modulo_formulas_bit_for_bit():
    import math

    from repertoire.planning.footstep.fastkernels import _wrap, _yaw_bin

    rng = np.random.default_rng(3)
    pi = math.pi
    edge = [-pi, pi, -3 * pi, 3 * pi, 0.0, -0.0, 1e-17, -1e-17, 2 * pi, -2 * pi, 5 * pi, -7.5]
    near = [pi + d for d in (-1e-15, 1e-15)] + [-pi + d for d in (-1e-15, 1e-15)]
    values = edge + near + rng.uniform(-4 * pi, 4 * pi, 3000).tolist()
    for t in values:
        want = (t + pi) % (2.0 * pi) - pi
        got = _wrap(t)
        assert got == want and math.copysign(1.0, got) == math.copysign(1.0, want), t
    for nb in (4, 36, 72, 144):
        scale = nb / (2.0 * pi)
        for th in edge + near + rng.uniform(-pi, pi, 500).tolist():
            assert _yaw_bin(th, scale, nb) == int(th * scale + nb + 0.5) % nb, (th, nb)


def test_lattice_table_finds_keys_and_rehash_keeps_the_node_rows():
    from repertoire.planning.footstep.fastkernels import _rehash, _slot

    n_local = 72
    keys = np.random.default_rng(4).choice(50_000 * n_local, 300, replace=False)
    table = np.full((1024, 2), -1, np.int64)
    tnode = np.full(1024, -1, np.int32)
    inode = np.zeros((300, 2), np.int32)
    for node, key in enumerate(keys.tolist()):
        j = _slot(table, key, key // n_local, key % n_local)
        assert table[j, 0] == -1  # every key is new
        table[j, 0], table[j, 1], tnode[j] = key, 3 * node, node
        inode[node, 1] = j
    new, new_node = np.full((2048, 2), -1, np.int64), np.full(2048, -1, np.int32)
    _rehash(table, tnode, new, new_node, n_local, inode, 1)
    table, tnode = new, new_node
    for node, key in enumerate(keys.tolist()):
        j = _slot(table, key, key // n_local, key % n_local)
        assert table[j, 0] == key and table[j, 1] == 3 * node  # the g column moves with it
        assert tnode[j] == node and inode[node, 1] == j
    missing = int(keys.max()) + 1
    assert table[_slot(table, missing, missing // n_local, missing % n_local), 0] == -1


def test_anytime_restarts_add_only_cheaper_plans_of_fresh_searches():
    import dataclasses

    from repertoire.planning.footstep import plan_footsteps_anytime

    def fresh(args, opts, r):  # weighted A* alone at the restart's weight and lattice
        return plan_footsteps(*args, dataclasses.replace(
            opts, heuristic_weight=r.weight, xy_resolution=r.plan.xy_resolution,
            yaw_bins=r.plan.yaw_bins, refinements=0,
        ))  # fmt: skip

    sc = random_static_scene(1, n_strips=8, n_blocks=4)
    args = (sc.grid, sc.start, sc.start_foot, sc.goal, nominal_action_table())
    opts = PlannerOptions(time_limit=60.0, refinements=0)  # restarts on ARA*'s lattice only
    ara = plan_footsteps_anytime(*args, opts, restarts=False)
    runs = plan_footsteps_anytime(*args, opts)
    assert [r.weight for r in ara] == [3.0, 2.0, 1.5, 1.2, 1.0]
    assert [r.weight for r in runs] == [3.0, 2.0, 1.5, 1.2, 1.0, 2.0, 1.5]
    assert {r.plan.xy_resolution for r in runs} == {0.05}
    for a, b in zip(ara, runs, strict=False):  # ARA*'s plans come first, unchanged
        assert a.plan.poses == b.plan.poses and a.plan.cost == b.plan.cost
    costs = [r.plan.cost for r in runs]
    assert costs[5] < costs[4] and costs[6] < costs[5]  # only cheaper plans are added
    assert costs[6] == pytest.approx(21.8) and costs[4] == pytest.approx(26.05)
    for r in runs[5:]:  # each one is a fresh weighted A* at its weight
        f = fresh(args, opts, r)
        assert r.plan.poses == f.poses and r.plan.cost == f.cost
        assert r.plan.status is PlanStatus.SUCCESS and 1.0 <= r.bound <= r.weight
    elapsed = [r.elapsed_s for r in runs]
    assert elapsed == sorted(elapsed) and elapsed[-1] < 60.0
    # with refinements, the restarts run ARA* on the next finer lattice first (over every
    # weight, its search reused), then the fresh searches. Here the gaps are narrow: the
    # 5 cm lattice runs out (UNREACHABLE), ARA* runs on the first refinement (2.5 cm, 72
    # bins), and on the next (1.25 cm, 144 bins) ARA*'s plan at weight 2 beats its plans
    sc = random_static_scene(2, n_strips=8, n_blocks=4)
    args = (sc.grid, sc.start, sc.start_foot, sc.goal, nominal_action_table())
    opts = PlannerOptions(time_limit=60.0)
    runs = plan_footsteps_anytime(*args, opts)
    ara = [r for r in runs if r.plan.xy_resolution == 0.025]
    fine = [r for r in runs if r.plan.xy_resolution == 0.0125]
    assert runs == ara + fine and [r.weight for r in ara] == [3.0, 2.0, 1.5, 1.2, 1.0]
    # then the admissible search on 1.25 cm ends at 20.3 too: its proof (bound 1) is added
    assert [(r.weight, r.plan.yaw_bins, r.bound) for r in fine[1:]] == [(1.0, 144, 1.0)]
    assert fine[0].weight == 2.0 and fine[1].plan.cost == fine[0].plan.cost
    assert fine[0].plan.cost == pytest.approx(20.3) and ara[-1].plan.cost == pytest.approx(21.45)
    on_fine = dataclasses.replace(opts, xy_resolution=0.0125, yaw_bins=144, refinements=0)
    fine_ara = plan_footsteps_anytime(*args, on_fine, restarts=False)  # ARA* alone there
    same = [r for r in fine_ara if r.weight == 2.0]
    assert fine[0].plan.poses == same[0].plan.poses and fine[0].plan.cost == same[0].plan.cost
    assert fine[0].bound == same[0].bound


def test_anytime_plan_times_leave_out_restarts_that_found_nothing(monkeypatch):
    import time

    from repertoire.planning.footstep import plan_footsteps_anytime, planner

    real = planner._search_once

    def slow(*args):  # every restart takes at least 0.3 s
        time.sleep(0.3)
        return real(*args)

    monkeypatch.setattr(planner, "_search_once", slow)
    sc = random_static_scene(2, size=2.0, n_strips=3, n_blocks=2)
    opts = PlannerOptions(heuristic="euclidean", time_limit=60.0, refinements=0)
    t0 = time.perf_counter()
    runs = plan_footsteps_anytime(sc.grid, sc.start, sc.start_foot, sc.goal,
                                  nominal_action_table(), opts)  # fmt: skip
    wall = time.perf_counter() - t0
    assert [r.weight for r in runs] == [3.0, 2.0, 1.5, 1.0]  # 1.2 skipped, no restart cheaper
    assert runs[-1].elapsed_s + 4 * 0.3 <= wall  # the four restarts are in no plan's time


def test_reused_work_arrays_give_the_fresh_search_and_large_ones_are_dropped(monkeypatch):
    from repertoire.planning.footstep import fastcore
    from repertoire.planning.footstep.biped_model import BipedStepModel

    sc = random_static_scene(2, n_strips=8, n_blocks=4)
    table = nominal_action_table()
    model = BipedStepModel(sc.grid, sc.start, sc.start_foot, sc.goal, table, PlannerOptions())
    floor = BipedStepModel(
        OccupancyGrid(np.zeros((160, 160), dtype=bool), 0.025), (0.3, 0.3, 0.0), "left",
        (3.7, 3.7), table, PlannerOptions(heuristic="euclidean"),
    )  # fmt: skip
    fastcore._WORK.clear()
    fresh = fastcore.compiled_search(model, 1.5, 200_000, 60.0)
    fastcore.compiled_search(floor, 1.0, 5_000, 60.0)  # grows the kept arrays
    (kept,) = fastcore._WORK
    assert kept[0].shape[0] > 1024 and kept[4].shape[0] > 4096  # nodes, lattice table grew
    again = fastcore.compiled_search(model, 1.5, 200_000, 60.0)  # in the grown, used arrays
    assert len(fastcore._WORK) == 1 and fastcore._WORK[0][0] is kept[0]  # reused
    assert again.path == fresh.path and again.cost == fresh.cost
    assert (again.expansions, again.generated, again.merged) == (
        fresh.expansions,
        fresh.generated,
        fresh.merged,
    )
    monkeypatch.setattr(fastcore, "_WORK_KEEP_BYTES", 0)
    fastcore._WORK.clear()
    fastcore.compiled_search(model, 1.5, 200_000, 60.0)
    assert fastcore._WORK == []  # above the size kept: left to the allocator


def test_compiled_planner_caches_under_a_key_of_every_compiled_source(tmp_path):
    """numba tells stale caches by one file's time stamp; ours by all the sources' contents."""
    import shutil

    import numba
    from repertoire.planning.footstep import fastcore, heuristic, jitcache

    key = jitcache.source_key()
    for fn in (fastcore._arastar, heuristic._rra_value):
        assert f"numba-{key}" in fn._cache._cache_path
    # The decorator restored numba's own setting.
    assert numba.config.CACHE_DIR == os.environ.get("NUMBA_CACHE_DIR", "")
    same, edited = tmp_path / "same", tmp_path / "edited"
    for folder in (same, edited):
        folder.mkdir()
        for name in jitcache.SOURCES:
            shutil.copy(Path(jitcache.__file__).parent / name, folder / name)
    assert jitcache.source_key(same) == key
    # An edit to a kernel alone (not to fastcore.py, which calls it) changes the key.
    with open(edited / "fastkernels.py", "a") as f:
        f.write("\n# edited\n")
    assert jitcache.source_key(edited) != key


def test_hot_and_cold_open_list_pops_in_tuple_order():
    # the compiled core's open list: a small hot heap below a threshold, the rest unordered
    # in a cold array (fastcore's module doc); driven here as the core drives it, with
    # pushes between pops and sizes small enough that it spills and refills many times
    from repertoire.planning.footstep.fastkernels import _heap_pop, _heap_push, _refill, _spill

    rng = np.random.default_rng(1)
    n, hot_rows, keep = 4000, 40, 10
    hot, cold = np.empty((n + 4, 4)), np.empty((n + 4, 4))
    hsize = csize = 0
    thr, spill_at = np.inf, hot_rows
    ref, popped, tie = [], [], 0
    spills = refills = 0

    def push(f, h):
        nonlocal hsize, csize, tie
        if f < thr:
            _heap_push(hot, hsize, f, h, tie, 7 * tie + 1)
            hsize += 1
        else:
            cold[csize] = f, h, tie, 7 * tie + 1
            csize += 1
        heapq.heappush(ref, (f, h, tie))
        tie += 1

    for _ in range(200):
        push(float(rng.integers(0, 30)), float(rng.integers(0, 4)))  # many equal f and h
    while hsize or csize:
        if hsize == 0:
            hsize, csize, thr = _refill(hot, cold, csize, max(keep, csize >> 4))
            spill_at, refills = max(hot_rows, 2 * hsize), refills + 1
        elif hsize > spill_at:
            hsize, csize, thr = _spill(hot, hsize, cold, csize, keep)
            spill_at, spills = max(hot_rows, 2 * hsize), spills + 1
        assert (hot[:hsize, 0] < thr).all() and (cold[:csize, 0] >= thr).all()
        want = heapq.heappop(ref)
        assert tuple(hot[0, :3]) == want and hot[0, 3] == 7 * want[2] + 1
        popped.append(want)
        _heap_pop(hot, hsize)
        hsize -= 1
        if tie < n:  # children cost at least their parent, as in A* with a consistent h
            burst = len(popped) % 100 == 0  # now and then many close rows: hot overflows
            for _ in range(3 * hot_rows if burst else rng.integers(0, 4)):
                push(want[0] + float(rng.integers(0, 2 if burst else 6)), float(rng.integers(0, 4)))
    assert not ref and len(popped) == tie >= n
    assert all(a[0] <= b[0] for a, b in itertools.pairwise(popped))  # f never decreases
    assert spills >= 2 and refills > 10, (spills, refills)


def test_tiny_hot_heap_gives_the_same_searches(monkeypatch):
    # a hot heap of 64 rows spills and refills all the time: plans, counts and ARA*'s
    # bounds stay those of the Python loop
    import repertoire.planning.footstep.fastcore as fc

    monkeypatch.setattr(fc, "HOT_ROWS", 64)
    monkeypatch.setattr(fc, "HOT_KEEP", 16)
    table = nominal_action_table()
    for seed in (0, 3):
        sc = random_static_scene(seed, n_strips=8, n_blocks=4)
        plan = _both(sc.grid, sc.start, sc.start_foot, sc.goal, table, heuristic_weight=1.2)
        assert plan.status is PlanStatus.SUCCESS and plan.nodes_expanded > 500
        _both(sc.grid, sc.start, sc.start_foot, sc.goal, table, heuristic="euclidean",
              heuristic_weight=1.0)  # fmt: skip
    py, cc = _anytime_both(random_static_scene(2, size=2.0, n_strips=3, n_blocks=2), table)
    assert len(py) == len(cc) > 1
    for a, b in zip(py, cc, strict=True):
        assert a.plan.poses == b.plan.poses and a.plan.cost == b.plan.cost
        assert a.bound == b.bound and a.plan.nodes_expanded == b.plan.nodes_expanded


def test_borrowed_array_is_the_array_without_its_reference_count():
    # the core hands the margin check borrowed arrays (fastkernels._borrowed): the same
    # memory, shape and strides; dropping one frees nothing (the owner's count is untouched)
    import numba
    from numba.core.runtime import _nrt_python, rtsys
    from repertoire.planning.footstep.fastkernels import _borrowed

    @numba.njit
    def write_through(a):
        b = _borrowed(a[:, 1:])
        b[1, 2] = -5.0
        return b.sum(), b.shape[0], b.shape[1], b.strides[0], b.strides[1]

    a = np.arange(12.0).reshape(3, 4)
    write_through(a.copy())  # compiled before counting
    _nrt_python.memsys_enable_stats()
    try:
        before = rtsys.get_allocation_stats()
        for _ in range(1000):
            total, *layout = write_through(a)
        after = rtsys.get_allocation_stats()
    finally:
        _nrt_python.memsys_disable_stats()
    assert a[1, 3] == -5.0 and total == a[:, 1:].sum() == 42.0
    assert layout == [3, 3, 32, 8]
    assert after.mi_free - before.mi_free == after.mi_alloc - before.mi_alloc  # none twice
