"""The anytime footstep planner's corridor searches (planning/footstep/corridor.py, planner.py)."""

import dataclasses
import itertools
import math

import numpy as np
import pytest
from repertoire.planning.footstep import (
    OccupancyGrid,
    PlannerOptions,
    PlanStatus,
    nominal_action_table,
    plan_footsteps,
    plan_footsteps_anytime,
)
from repertoire.planning.footstep.biped_model import BipedStepModel
from repertoire.planning.footstep.corridor import OUTSIDE_HEIGHT, corridor_grid
from repertoire.planning.footstep.scenes import maze_grid, random_static_scene
from repertoire.planning.footstep.types import FootstepError


def _distance_to_polyline(points, x, y):
    """Brute force: distance of each (x, y) to the polyline through ``points``."""
    p = np.stack([x, y], axis=-1)
    pts = np.asarray(points, dtype=float)
    d = np.linalg.norm(p - pts[0], axis=-1)
    for a, b in itertools.pairwise(pts):
        ab = b - a
        t = np.clip(((p - a) @ ab) / max(ab @ ab, 1e-300), 0.0, 1.0)
        d = np.minimum(d, np.linalg.norm(p - (a + t[..., None] * ab), axis=-1))
    return d


def test_corridor_grid_blocks_the_cells_far_from_the_polyline_only():
    rng = np.random.default_rng(5)
    for trial in range(60):
        nx, ny = (int(v) for v in rng.integers(4, 50, 2))
        res = float(rng.choice([0.01, 0.025, 0.05]))
        origin = (float(rng.uniform(-1, 1)), float(rng.uniform(-1, 1)))
        heights = rng.uniform(0.0, 0.3, (nx, ny)) if trial % 2 else None
        grid = OccupancyGrid(rng.random((nx, ny)) < 0.3, res, origin, heights)
        k = int(rng.integers(1, 6))  # points, some a little off the map
        points = np.stack([
            origin[0] + rng.uniform(-0.1, nx * res + 0.1, k),
            origin[1] + rng.uniform(-0.1, ny * res + 0.1, k),
        ], axis=1)  # fmt: skip
        radius = float(rng.uniform(0.02, 0.3))
        out = corridor_grid(grid, points, radius)
        cx = origin[0] + (np.arange(nx) + 0.5) * res
        cy = origin[1] + (np.arange(ny) + 0.5) * res
        d = _distance_to_polyline(points, *np.meshgrid(cx, cy, indexing="ij"))
        blocked = out.occupied & ~grid.occupied
        # within radius - 0.71 res of the polyline: the cell is as it was; beyond
        # radius + 0.71 res: blocked (cell centres against the polyline's cells' centres)
        assert not (blocked & (d <= radius - 0.71 * res - 1e-9)).any(), trial
        assert out.occupied[d > radius + 0.71 * res + 1e-9].all(), trial
        assert (out.occupied | ~grid.occupied).all()  # only ever adds obstacles
        assert out.resolution == res and out.origin == grid.origin
        if heights is None:
            assert out.heights is None
        else:
            near, far = d <= radius - 0.71 * res - 1e-9, d > radius + 0.71 * res + 1e-9
            np.testing.assert_array_equal(out.heights[near], heights[near])
            np.testing.assert_array_equal(out.heights[far | blocked], OUTSIDE_HEIGHT)
            changed = out.heights != heights
            np.testing.assert_array_equal(out.heights[changed], OUTSIDE_HEIGHT)
    grid = OccupancyGrid(np.zeros((10, 10), dtype=bool), 0.1)
    one = corridor_grid(grid, [(0.55, 0.55)], 0.1)  # one point: its cell and 4 neighbours
    assert np.argwhere(~one.occupied).tolist() == [[4, 5], [5, 4], [5, 5], [5, 6], [6, 5]]
    for bad in (0.0, -0.2, math.nan, math.inf):
        with pytest.raises(FootstepError, match="corridor radius"):
            corridor_grid(grid, [(0.5, 0.5)], bad)
    with pytest.raises(FootstepError, match="at least one point"):
        corridor_grid(grid, [], 0.2)


def test_anytime_improves_a_plan_in_its_corridor_and_keeps_the_searches_order():
    sc = random_static_scene(1, n_strips=8, n_blocks=4)
    args = (sc.grid, sc.start, sc.start_foot, sc.goal, nominal_action_table())
    opts = PlannerOptions(time_limit=60.0)  # every search runs to its end
    runs = plan_footsteps_anytime(*args, opts, corridor=0.5)
    ara = plan_footsteps_anytime(*args, opts, restarts=False)  # corridor=0: ARA* alone
    # the first plan, ARA* on the whole map (its plans as cheap with a tighter bound kept),
    # the corridor of its best plan at the later weights (only 1.5 gave a cheaper plan),
    # then the restarts on the finer lattice, and the admissible search there, as cheap
    # (bound 1: the proof)
    assert [(r.weight, r.corridor_m, r.plan.xy_resolution) for r in runs] == [
        (3.0, 0.0, 0.05), (2.0, 0.0, 0.05), (1.5, 0.0, 0.05), (1.2, 0.0, 0.05),
        (1.0, 0.0, 0.05), (1.5, 0.5, 0.025), (2.0, 0.0, 0.025), (1.5, 0.0, 0.025),
        (1.0, 0.0, 0.025),
    ]  # fmt: skip
    assert runs[-1].bound == 1.0 and runs[-1].plan.cost == runs[-2].plan.cost
    # the first plan is weighted A*'s at weight 3 (its own search: the compiled ARA* gives
    # its first result the poses of its second, see the note); the others ARA*'s, unchanged
    first = plan_footsteps(*args, dataclasses.replace(opts, heuristic_weight=3.0, refinements=0))
    assert runs[0].plan.poses == first.poses and runs[0].plan.cost == first.cost
    for a, b in zip(ara, runs[:5], strict=True):
        assert a.plan.cost == b.plan.cost and a.bound == b.bound
    assert all(a.plan.poses == b.plan.poses for a, b in zip(ara[1:], runs[1:5], strict=True))
    costs = [r.plan.cost for r in runs]
    assert all(b <= a for a, b in itertools.pairwise(costs))
    assert costs[5] == pytest.approx(24.95) and costs[4] == pytest.approx(26.05)
    assert costs[-1] == pytest.approx(21.8)
    assert all(r.plan.status is PlanStatus.SUCCESS for r in runs)
    elapsed = [r.elapsed_s for r in runs]
    assert elapsed == sorted(elapsed) and elapsed[-1] < 60.0
    # the corridor plan is the weighted A* on the map cut to the previous plan's corridor
    prev, cor = runs[4].plan, runs[5]
    feet = [prev.initial_swing_pose, *prev.poses, prev.goal]
    cut = corridor_grid(sc.grid, feet, 0.5)
    again = plan_footsteps(cut, *args[1:], dataclasses.replace(
        opts, heuristic_weight=1.5, xy_resolution=0.025, yaw_bins=72, refinements=0,
    ))  # fmt: skip
    assert cor.plan.poses == again.poses and cor.plan.cost == again.cost
    assert 1.0 <= cor.bound <= cor.weight
    # and a plan on the whole map: every foot (with the margin) is on free ground there
    model = BipedStepModel(sc.grid, *args[1:], opts)
    assert all(model.checkers.checker(0).is_free(*pose, shortcut=False) for pose in cor.plan.poses)


def test_anytime_corridor_must_be_a_half_width():
    sc = random_static_scene(1, size=2.0, n_strips=3, n_blocks=2)
    args = (sc.grid, sc.start, sc.start_foot, sc.goal, nominal_action_table())
    for bad in (-0.5, math.nan, math.inf, True):
        with pytest.raises(FootstepError, match=f"corridor must be a half-width >= 0 m, got {bad}"):
            plan_footsteps_anytime(*args, PlannerOptions(time_limit=5.0), corridor=bad)
    with pytest.raises(FootstepError, match="anytime weights must be numbers >= 1, got '3'"):
        plan_footsteps_anytime(*args, PlannerOptions(time_limit=5.0), weights="3")


def test_anytime_corridor_too_narrow_for_the_feet_runs_no_corridor_search():
    sc = random_static_scene(1, n_strips=8, n_blocks=4)
    args = (sc.grid, sc.start, sc.start_foot, sc.goal, nominal_action_table())
    opts = PlannerOptions(time_limit=60.0)
    runs = plan_footsteps_anytime(*args, opts, corridor=0.02)  # narrower than a foot
    plain = plan_footsteps_anytime(*args, opts)
    assert all(r.corridor_m == 0.0 for r in runs)
    assert [r.plan.cost for r in runs] == [r.plan.cost for r in plain]


def test_anytime_restarts_run_ara_on_the_finer_lattice_then_fresh_searches():
    # ARA* on 5 cm / 36 bins ends at 32.85; the restarts then run ARA* from scratch on
    # 2.5 cm / 72 bins (weights 3 .. 1, its search reused): 26.9 at weight 3 and 22.1 at 2,
    # where a fresh weighted A* at 2 on that lattice finds 33.25
    sc = random_static_scene(7, n_strips=8, n_blocks=4)
    args = (sc.grid, sc.start, sc.start_foot, sc.goal, nominal_action_table())
    opts = PlannerOptions(time_limit=60.0)  # every search runs to its end
    runs = plan_footsteps_anytime(*args, opts)
    assert [(r.weight, r.plan.xy_resolution) for r in runs] == [
        (3.0, 0.05), (2.0, 0.05), (1.5, 0.05), (1.2, 0.05), (1.0, 0.05),
        (3.0, 0.025), (2.0, 0.025),
    ]  # fmt: skip
    assert [round(r.plan.cost, 2) for r in runs] == [33.2, 33.2, 32.9, 32.85, 32.85, 26.9, 22.1]
    fine = dataclasses.replace(opts, xy_resolution=0.025, yaw_bins=72, refinements=0)
    ara = plan_footsteps_anytime(*args, fine, restarts=False)  # ARA* alone on 2.5 cm
    for r in runs[5:]:
        (same,) = [a for a in ara if a.weight == r.weight]
        assert r.plan.poses == same.plan.poses and r.plan.cost == same.plan.cost
        assert r.bound == same.bound and r.plan.yaw_bins == 72
    fresh = plan_footsteps(*args, dataclasses.replace(fine, heuristic_weight=2.0))
    assert fresh.cost == pytest.approx(33.25)
    elapsed = [r.elapsed_s for r in runs]
    assert elapsed == sorted(elapsed)


def test_anytime_ends_with_the_admissible_search_when_time_remains():
    # a 6 m maze: every weight on 5 cm / 36 and 2.5 cm / 72 bins, guided by the Dijkstra
    # cost-to-go, ends at 39.1 well within the limit; the admissible search on 2.5 cm / 72
    # then finds 36.95, the admissible mode's own plan, with its bound 1 on that lattice
    args = (maze_grid(512), (0.6, 0.6, 0.0), "left", (5.4, 5.4), nominal_action_table())
    runs = plan_footsteps_anytime(*args, PlannerOptions(time_limit=60.0))
    ref = plan_footsteps(*args, PlannerOptions.admissible(time_limit=60.0, refinements=0))
    assert round(runs[-2].plan.cost, 2) == 39.1 and round(ref.cost, 2) == 36.95
    last = runs[-1]
    assert last.plan.cost == ref.cost and last.plan.poses == ref.poses
    assert (last.weight, last.bound) == (1.0, 1.0)
    assert (last.plan.xy_resolution, last.plan.yaw_bins) == (0.025, 72)
    no_restarts = plan_footsteps_anytime(*args, PlannerOptions(time_limit=60.0), restarts=False)
    assert round(no_restarts[-1].plan.cost, 2) == 39.25  # ARA* on 5 cm alone


def test_anytime_reports_the_admissible_search_at_equal_cost_with_bound_one():
    # ARA* on 5 cm already finds 11.0; the admissible search on 2.5 cm / 72 ends at the
    # same cost, and its plan is added with bound 1: the proof that 11.0 is that
    # lattice's optimum (the admissible mode's own cost)
    sc = random_static_scene(12)
    args = (sc.grid, sc.start, sc.start_foot, sc.goal, nominal_action_table())
    runs = plan_footsteps_anytime(*args, PlannerOptions(time_limit=60.0))
    ref = plan_footsteps(*args, PlannerOptions.admissible(time_limit=60.0, refinements=0))
    assert [(r.plan.xy_resolution, round(r.plan.cost, 2)) for r in runs[-2:]] == [
        (0.05, 11.0),
        (0.025, 11.0),
    ]
    last = runs[-1]
    assert (last.weight, last.bound, last.corridor_m) == (1.0, 1.0, 0.0)
    assert last.plan.cost == ref.cost and last.plan.status is PlanStatus.SUCCESS
    assert last.elapsed_s >= runs[-2].elapsed_s


def _searches_run(monkeypatch, *args, **kwargs):
    """The (heuristic, weight, lattice) of each single search an anytime call ran, in order."""
    from repertoire.planning.footstep import planner

    calls = []
    inner = planner._search_once

    def spy(model, backend, weight, budget, left):
        calls.append((model.opts.heuristic, weight, model.opts.xy_resolution))
        return inner(model, backend, weight, budget, left)

    monkeypatch.setattr(planner, "_search_once", spy)
    return plan_footsteps_anytime(*args, **kwargs), calls


def test_anytime_runs_each_distinct_search_once(monkeypatch):
    # after ARA* (5 cm) and the restarts' ARA* (2.5 cm): fresh weighted A* at the weights
    # after the first on 5 cm, then, with the Dijkstra field only, the admissible search on
    # 2.5 cm. The Euclidean heuristic's weight-1 search on 2.5 cm was ARA*'s own; without a
    # heuristic every weight orders the queue alike, so no search is repeated
    sc = random_static_scene(12)
    args = (sc.grid, sc.start, sc.start_foot, sc.goal, nominal_action_table())
    fresh = [(2.0, 0.05), (1.5, 0.05), (1.2, 0.05), (1.0, 0.05)]
    for heuristic, expected in (
        ("dijkstra", [("dijkstra", w, r) for w, r in fresh] + [("euclidean", 1.0, 0.025)]),
        ("euclidean", [("euclidean", w, r) for w, r in fresh]),
        ("none", []),
    ):
        opts = PlannerOptions(time_limit=60.0, heuristic=heuristic)
        runs, calls = _searches_run(monkeypatch, *args, opts)
        assert calls == expected
        assert runs[-1].plan.status is PlanStatus.SUCCESS
    # uniform-cost search: the first plan is the lattice's optimum, and the only one
    assert [(r.weight, r.bound, round(r.plan.cost, 2)) for r in runs] == [(3.0, 1.0, 11.0)]


def test_anytime_restarts_must_be_a_bool():
    sc = random_static_scene(1, size=2.0, n_strips=3, n_blocks=2)
    args = (sc.grid, sc.start, sc.start_foot, sc.goal, nominal_action_table())
    for bad in ("yes", 1, None):
        with pytest.raises(FootstepError, match=f"restarts must be True or False, got {bad!r}"):
            plan_footsteps_anytime(*args, PlannerOptions(time_limit=5.0), restarts=bad)


@pytest.mark.parametrize("backend", ["compiled", "python"])
def test_anytime_start_meeting_the_goal_is_one_optimal_plan(backend):
    # the goal point within the tolerance of the start foot: ARA*'s first plan costs 0 and
    # is optimal (bound 1), so no later weight runs (before, each weight repeated it with
    # its own weight as bound: five plans of no step)
    grid = OccupancyGrid(np.zeros((40, 40), dtype=bool), 0.025)
    args = (grid, (0.5, 0.6, 0.0), "left", (0.55, 0.6), nominal_action_table())
    runs = plan_footsteps_anytime(*args, PlannerOptions(time_limit=5.0, backend=backend))
    got = [(r.weight, r.bound, r.plan.cost, r.plan.num_steps) for r in runs]
    assert got == [(3.0, 1.0, 0.0, 0)]
    assert runs[0].plan.status is PlanStatus.SUCCESS


def test_anytime_budget_ending_inside_the_admissible_search_keeps_the_plans_before(monkeypatch):
    # the 6 m maze of the test above: an expansion budget that runs out halfway through the
    # admissible search leaves the plans found before it, the last one a SUCCESS (the
    # unfinished search adds no partial plan after a complete one)
    args = (maze_grid(512), (0.6, 0.6, 0.0), "left", (5.4, 5.4), nominal_action_table())
    from repertoire.planning.footstep import planner

    seen = []
    inner = planner._search_once

    def spy(model, backend, weight, budget, left):
        r = inner(model, backend, weight, budget, left)
        seen.append((model.opts.heuristic, budget, r.expansions))
        return r

    monkeypatch.setattr(planner, "_search_once", spy)
    full = plan_footsteps_anytime(*args, PlannerOptions(time_limit=60.0, max_expansions=10**8))
    heuristic, left, used = seen[-1]
    assert heuristic == "euclidean" and used < left  # the admissible search, run to its end
    budget = 10**8 - left + used // 2
    runs = plan_footsteps_anytime(*args, PlannerOptions(time_limit=60.0, max_expansions=budget))
    assert seen[-1][:2] == ("euclidean", used - used // 2) and seen[-1][2] == seen[-1][1]
    assert [r.plan.cost for r in runs] == [r.plan.cost for r in full[:-1]]
    assert round(runs[-1].plan.cost, 2) == 39.1 and round(full[-1].plan.cost, 2) == 36.95
    assert runs[-1].plan.status is PlanStatus.SUCCESS
    elapsed = [r.elapsed_s for r in runs]
    assert elapsed == sorted(elapsed)
