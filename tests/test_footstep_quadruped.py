"""Tests of the generic search core and the LittleDog crawl step model."""

import math

import numpy as np
import pytest
from repertoire.models.littledog.kinematics import (
    FOOT_RADIUS,
    LEGS,
    leg_ik,
    nominal_foot_positions,
)
from repertoire.models.terrain import TerrainParams, generate_board
from repertoire.planning.footstep.quadruped import (
    CrawlParams,
    HeightMap,
    _point_in_triangle_margin,
    height_map_from_board,
    plan_crawl,
)
from repertoire.planning.footstep.search import anytime_search, search
from repertoire.planning.footstep.types import FootstepError, PlanStatus

from repertoire.errors import RepertoireError
from repertoire.limits import ResourceLimitError


class GridWalk:
    """A 4-connected walk on a small boolean grid (True = free), unit step cost."""

    def __init__(self, free, start, goal):
        self.free, self._start, self.goal = free, start, goal

    def start(self):
        return self._start

    def key(self, s):
        return s

    def is_goal(self, s):
        return s == self.goal

    def heuristic(self, s):
        return abs(s[0] - self.goal[0]) + abs(s[1] - self.goal[1])

    def successors(self, s):
        out = []
        for dr, dc in ((1, 0), (-1, 0), (0, 1), (0, -1)):
            r, c = s[0] + dr, s[1] + dc
            if 0 <= r < self.free.shape[0] and 0 <= c < self.free.shape[1] and self.free[r, c]:
                out.append(((r, c), 1.0))
        return out


def _bfs_distance(free, start, goal):
    dist = {start: 0}
    frontier = [start]
    while frontier:
        nxt = []
        for s in frontier:
            for t, _ in GridWalk(free, start, goal).successors(s):
                if t not in dist:
                    dist[t] = dist[s] + 1
                    nxt.append(t)
        frontier = nxt
    return dist.get(goal)


def test_search_matches_brute_force_on_random_grids():
    rng = np.random.default_rng(3)
    for _ in range(30):
        free = rng.random((8, 8)) > 0.3
        free[0, 0] = free[0, 1] = free[7, 7] = True
        model = GridWalk(free, (0, 0), (7, 7))
        truth = _bfs_distance(free, (0, 0), (7, 7))
        result = search(model)
        if truth is None:
            assert result.status is PlanStatus.UNREACHABLE
        else:
            assert result.status is PlanStatus.SUCCESS
            assert result.cost == truth
            assert result.path[0] == (0, 0) and result.path[-1] == (7, 7)
            weighted = search(model, weight=2.0)
            assert weighted.cost <= 2.0 * truth


def test_search_node_limit_returns_best_partial():
    free = np.ones((20, 20), dtype=bool)
    result = search(GridWalk(free, (0, 0), (19, 19)), max_expansions=5)
    assert result.status is PlanStatus.NODE_LIMIT
    assert result.expansions == 5
    assert result.path[0] == (0, 0) and len(result.path) > 1


def test_anytime_search_bounds_decrease():
    free = np.ones((12, 12), dtype=bool)
    free[3:9, 5] = False
    results = anytime_search(GridWalk(free, (6, 0), (6, 11)), time_limit=5.0)
    assert [r.weight for r in results] == [3.0, 2.0, 1.5, 1.2, 1.0]
    assert all(r.status is PlanStatus.SUCCESS for r in results)
    optimum = results[-1].cost
    assert optimum == _bfs_distance(free, (6, 0), (6, 11))
    assert all(r.cost <= r.weight * optimum for r in results)


def test_search_bad_input():
    free = np.zeros((3, 3), dtype=bool)
    free[0, 0] = True
    with pytest.raises(FootstepError, match="successors of the start state are empty"):
        search(GridWalk(free, (0, 0), (2, 2)))
    ok = GridWalk(np.ones((3, 3), dtype=bool), (0, 0), (2, 2))
    with pytest.raises(FootstepError, match="weight"):
        search(ok, weight=0.5)
    with pytest.raises(FootstepError, match="time_limit"):
        search(ok, time_limit=float("nan"))
    with pytest.raises(FootstepError, match="must not increase"):
        anytime_search(ok, weights=[1.0, 2.0])


def _board_map(kind, seed=1):
    board = generate_board(TerrainParams(kind=kind, size_x=1.0, size_y=0.6), seed=seed)
    return height_map_from_board(board, (-0.3, 0.7), (-0.3, 0.3), 0.01)


def _check_plan(plan, hm, params):
    """Every stance reachable by the leg IK, every swing statically stable."""
    prev = plan.start_stance
    for step in plan.steps:
        moved = np.flatnonzero(np.any(step.stance != prev, axis=1))
        assert moved.tolist() == [step.foot]
        np.testing.assert_array_equal(step.stance[step.foot], step.p_WF)
        r, c = hm.cell(step.p_WF[0], step.p_WF[1])
        assert step.p_WF[2] == hm.heights[r, c]
        body = np.r_[step.stance[:, :2].mean(axis=0), step.stance[:, 2].mean() + params.body_height]
        for i, leg in enumerate(LEGS):
            leg_ik(leg, step.stance[i] - body + np.array([0.0, 0.0, FOOT_RADIUS]))
        stance = [i for i in range(4) if i != step.foot]
        tri = prev[stance, :2]
        sway = 0.5 * prev[:, :2].mean(axis=0) + 0.5 * tri.mean(axis=0)
        assert _point_in_triangle_margin(sway, tri) >= params.support_margin
        prev = step.stance


@pytest.mark.parametrize("kind", ["flat", "rocks", "gaps"])
def test_crawl_plans_on_boards(kind):
    hm = _board_map(kind)
    params = CrawlParams()
    start = nominal_foot_positions()[:, :2]
    plan = plan_crawl(hm, start, (0.25, 0.0), params, time_limit=10.0)
    assert plan.status is PlanStatus.SUCCESS
    assert plan.resolution == 0.01 and plan.weight == 3.0
    final = plan.steps[-1].stance
    assert math.hypot(*(final[:, :2].mean(axis=0) - [0.25, 0.0])) <= params.goal_radius
    assert [s.foot for s in plan.steps[:4]] == params.order
    _check_plan(plan, hm, params)


def test_crawl_refuses_walls_higher_than_swing_clearance():
    heights = np.zeros((61, 101))
    heights[:, 60:63] = 0.2  # a 3 cm thick, 20 cm high wall across the map at x = 0.3 m
    hm = HeightMap(origin=(-0.3, -0.3), resolution=0.01, heights=heights)
    start = nominal_foot_positions()[:, :2]
    plan = plan_crawl(hm, start, (0.5, 0.0), time_limit=10.0, max_expansions=3000)
    assert plan.status is not PlanStatus.SUCCESS
    feet = np.vstack([plan.start_stance] + [s.stance for s in plan.steps])
    assert np.all(feet[:, 0] < 0.3)
    heights[:, 60:63] = 0.03  # low enough to step over
    low = HeightMap(origin=(-0.3, -0.3), resolution=0.01, heights=heights)
    assert plan_crawl(low, start, (0.5, 0.0), time_limit=10.0).status is PlanStatus.SUCCESS


def test_crawl_bad_input():
    start = nominal_foot_positions()[:, :2]
    heights = np.zeros((30, 30))
    heights[3, 4] = np.nan
    with pytest.raises(RepertoireError, match=r"row 3, col 4\) is nan"):
        HeightMap(origin=(0.0, 0.0), resolution=0.01, heights=heights)
    with pytest.raises(RepertoireError, match="-0.5 m; heights must be >= 0"):
        HeightMap(origin=(0.0, 0.0), resolution=0.01, heights=-0.5 * np.ones((3, 3)))
    board = generate_board(TerrainParams(kind="flat"), seed=0)
    with pytest.raises(ResourceLimitError, match="height map"):
        height_map_from_board(board, (0.0, 1000.0), (0.0, 1000.0), 0.001)
    hm = _board_map("flat")
    with pytest.raises(FootstepError, match="offsets are empty"):
        plan_crawl(hm, start, (0.2, 0.0), CrawlParams(offsets_x=[]))
    with pytest.raises(FootstepError, match="outside the height map"):
        plan_crawl(hm, start, (5.0, 0.0))
    heights = np.zeros((61, 101))
    heights[:, 40:] = 0.03  # an edge at x = 0.1 m, under the left front foot (x = 0.101 m)
    steep = HeightMap(origin=(-0.3, -0.3), resolution=0.01, heights=heights)
    with pytest.raises(FootstepError, match=r"lf at \[0.101, 0.06\] is on ground too steep"):
        plan_crawl(steep, start, (0.2, 0.0))


def test_crawl_plan_figure_has_height_colour_bar_and_legend(tmp_path):
    from repertoire.planning.footstep.plot import crawl_plan_figure

    hm = _board_map("rocks")
    plan = plan_crawl(hm, nominal_foot_positions()[:, :2], (0.2, 0.0), time_limit=10.0)
    out = crawl_plan_figure(hm, plan, tmp_path / "crawl.png", goal=(0.2, 0.0, 0.03))
    assert out.stat().st_size > 10_000
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_crawl_climbs_steps_board():
    board = generate_board(TerrainParams(kind="steps", size_x=1.0, size_y=0.6), seed=0)
    hm = height_map_from_board(board, (-0.55, 0.55), (-0.3, 0.3), 0.01)
    params = CrawlParams()
    start = nominal_foot_positions()[:, :2] + [-0.25, 0.0]
    plan = plan_crawl(hm, start, (0.05, 0.0), params, time_limit=10.0)
    assert plan.status is PlanStatus.SUCCESS
    heights = {round(float(s.p_WF[2]), 4) for s in plan.steps}
    assert len(heights) >= 2  # footholds on more than one band
    prev = plan.start_stance
    for step in plan.steps:
        assert abs(step.p_WF[2] - prev[step.foot, 2]) <= params.max_step_height
        prev = step.stance
    _check_plan(plan, hm, params)
