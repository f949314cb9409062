"""Tests of the generic search core and the LittleDog crawl step model."""

import math
import re

import numpy as np
import pytest
from repertoire.models.littledog.kinematics import (
    FOOT_RADIUS,
    LEG_GEOMETRY,
    leg_ik,
    leg_ik_feasible,
    nominal_foot_positions,
)
from repertoire.models.terrain import TerrainParams, generate_board
from repertoire.planning.footstep.height_map import HeightMap, height_map_from_board
from repertoire.planning.footstep.quadruped import (
    CrawlParams,
    _point_in_triangle_margin,
    plan_crawl,
)
from repertoire.planning.footstep.search import anytime_search, search
from repertoire.planning.footstep.types import FootstepError, GridError, PlanStatus
from repertoire.planning.littledog_crawl import (
    MAX_LEG_EXTENSION,
    CrawlError,
    heading_of,
    step_reachable,
    swing_pose,
)
from repertoire.planning.littledog_crawl import CrawlParams as ExecParams
from repertoire.planning.littledog_crawl import CrawlStep as ExecStep
from repertoire.planning.littledog_crawl import plan_crawl as execute

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
    # the plan of weight 3 reports a bound below 1.5: weights 2 and 1.5 are skipped
    assert [r.weight for r in results] == [3.0, 1.2, 1.0]
    assert 1.2 < results[0].bound < 1.5
    every = anytime_search(GridWalk(free, (6, 0), (6, 11)), weights=[3.0, 1.3], time_limit=5.0)
    assert [r.weight for r in every] == [3.0, 1.3] and every[0].cost == results[0].cost
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
    # not numbers: named, not a TypeError from math.isfinite
    with pytest.raises(FootstepError, match="time_limit must be a number of seconds, got '1'"):
        search(ok, time_limit="1")
    with pytest.raises(FootstepError, match="search weight must be a number, got None"):
        search(ok, weight=None)
    with pytest.raises(FootstepError, match="search max_expansions must be a number, got '9'"):
        search(ok, max_expansions="9")


def _board_map(kind, seed=1):
    board = generate_board(TerrainParams(kind=kind, size_x=1.0, size_y=0.6), seed=seed)
    return height_map_from_board(board, (-0.3, 0.7), (-0.3, 0.3), 0.01)


def _execute(plan, board):
    """The planned steps executed by the scripted crawl from a level start (raises if not)."""
    lift = np.array([0.0, 0.0, FOOT_RADIUS])
    feet = plan.start_stance + lift
    pose = np.r_[feet[:, :2].mean(axis=0), feet[:, 2].mean() - FOOT_RADIUS + 0.14, 0, 0, 0]
    pose[5] = heading_of(feet)
    steps = [ExecStep(s.foot, s.p_WF + lift) for s in plan.steps]
    return execute(feet, pose, steps, board, ExecParams())


def _check_plan(plan, hm, params, board=None):
    """Every step executable by the crawl's leg IK, every swing statically stable."""
    prev = plan.start_stance
    for step in plan.steps:
        moved = np.flatnonzero(np.any(step.stance != prev, axis=1))
        assert moved.tolist() == [step.foot]
        np.testing.assert_array_equal(step.stance[step.foot], step.p_WF)
        r, c = hm.cell(step.p_WF[0], step.p_WF[1])
        assert step.p_WF[2] == hm.heights[r, c]
        stance = [i for i in range(4) if i != step.foot]
        tri = prev[stance, :2]
        sway = 0.5 * prev[:, :2].mean(axis=0) + 0.5 * tri.mean(axis=0)
        assert _point_in_triangle_margin(sway, tri) >= params.support_margin
        prev = step.stance
    # Exact: the crawl's own IK over every sample of every step (CrawlError if any fails).
    executed = _execute(plan, hm if board is None else board)
    assert len(executed.steps) == len(plan.steps)


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
    with pytest.raises(FootstepError, match="crawl goal must be a finite \\(x, y\\), got 'ab'"):
        plan_crawl(hm, start, "ab")
    with pytest.raises(FootstepError, match="time_limit must be a number of seconds, got '1'"):
        plan_crawl(hm, start, (0.2, 0.0), time_limit="1")
    with pytest.raises(GridError, match="height map resolution must be positive, got 'x'"):
        HeightMap(origin=(0.0, 0.0), resolution="x", heights=np.zeros((3, 3)))
    heights = np.zeros((61, 101))
    heights[:, 40:] = 0.03  # an edge at x = 0.1 m, under the left front foot (x = 0.101 m)
    steep = HeightMap(origin=(-0.3, -0.3), resolution=0.01, heights=heights)
    with pytest.raises(FootstepError, match=r"lf at \[0.101, 0.06\] is on ground too steep"):
        plan_crawl(steep, start, (0.2, 0.0))


def test_a_start_on_steep_exact_ground_names_its_height_range():
    # lf stands on a rock's edge; before, the message gave no range
    board = generate_board(TerrainParams(kind="rocks", size_x=1.0, size_y=0.6,
                                         rock_height=[0.02, 0.06]), seed=9300)  # fmt: skip
    hm = height_map_from_board(board, (-0.55, 0.55), (-0.3, 0.3), 0.01)
    start = nominal_foot_positions()[:, :2] + [-0.25, 0.0]
    with pytest.raises(FootstepError, match=r"crawl start foothold of lf at \[-0.149, 0.06\] is "
                       r"on ground too steep: height range 0.0589 m within 0.0103 m on the exact "
                       r"ground > max_roughness 0.006 m"):  # fmt: skip
        plan_crawl(hm, start, (0.25, 0.0), ground=board)


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda hm, s: plan_crawl(hm, s, (0.2, 0.0), CrawlParams(order=[0, 1, 2, 3.0])),
         r"crawl order must be a permutation of 0..3, got \[0, 1, 2, 3.0\]"),
        (lambda hm, s: plan_crawl(hm, s, (0.2, 0.0), CrawlParams(offsets_x=["a"])),
         r"crawl offsets_x must be finite numbers, got \['a'\]"),
        (lambda hm, s: plan_crawl(hm, s, (0.2, 0.0), CrawlParams(flat_radius="a")),
         "crawl flat_radius must be a number, got 'a'"),
        (lambda hm, s: plan_crawl(hm, s, (0.2, 0.0), ground=object()),
         r"crawl ground must have a height\(x, y\) method"),
        (lambda hm, s: plan_crawl(hm.heights, s, (0.2, 0.0)),
         "crawl height_map must be a HeightMap, got array"),
        (lambda hm, s: plan_crawl(hm, s, (0.2, 0.0), {"step_cost": 1.0}),
         "crawl params must be a CrawlParams, got {'step_cost': 1.0}"),
        (lambda hm, s: plan_crawl(hm, s, (0.2, 0.0), anytime="yes"),
         "plan_crawl anytime must be True or False, got 'yes'"),
        (lambda hm, s: plan_crawl(hm, {"lf": 1}, (0.2, 0.0)),
         r"crawl start footholds must be finite, shape \(4, 2\) or \(4, 3\); got {'lf': 1}"),
        (lambda hm, s: height_map_from_board(hm, 5, (0.0, 1.0), 0.01),
         "height map ranges must be finite .* got x_range=5"),
        (lambda hm, s: height_map_from_board(hm, (0.0, 1.0), (0.0, 1.0), None),
         "height map ranges must be finite .* resolution=None"),
        (lambda hm, s: height_map_from_board(None, (0.0, 1.0), (0.0, 1.0), 0.01),
         r"height map board must have a height\(x, y\) method, got None"),
        (lambda hm, s: HeightMap(("a", 0.0), 0.01, np.zeros((3, 3))),
         r"height map origin must be a finite \(x, y\), got \('a', 0.0\)"),
        (lambda hm, s: HeightMap((0.0, 0.0), 0.01, np.full((3, 3), 0.1 + 1j)),
         "height map heights must be real numbers \\(m\\), got dtype complex128"),
    ],
)  # fmt: skip
def test_crawl_and_height_map_refuse_wrong_types_by_name(call, message):
    # before, each of these raised a bare TypeError, AttributeError or IndexError (or, for
    # complex heights, dropped the imaginary part with a warning)
    hm = _board_map("flat")
    with pytest.raises(RepertoireError, match=message):
        call(hm, nominal_foot_positions()[:, :2])


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


def test_planned_steps_pass_the_crawls_leg_ik_where_the_four_feet_body_did_not():
    # The start where the old reach model (body over the four feet, yaw 0) planned lf's
    # step with hip roll 0.607 > 0.6 rad: the crawl's body over three feet cannot do it.
    board = generate_board(TerrainParams(kind="gaps", size_x=1.0, size_y=0.6), seed=1)
    hm = height_map_from_board(board, (-0.3, 0.7), (-0.3, 0.3), 0.01)
    c, s = math.cos(0.008275), math.sin(0.008275)
    start = nominal_foot_positions()[:, :2] @ np.array([[c, s], [-s, c]]) + [0.02703, -0.02135]
    params = CrawlParams()
    plan = plan_crawl(hm, start, (0.25, 0.0), params, time_limit=10.0, ground=board)
    assert plan.status is PlanStatus.SUCCESS
    _check_plan(plan, hm, params, board)


def _flat_feet():
    feet = nominal_foot_positions()
    feet[:, 2] = FOOT_RADIUS  # foot centres on flat ground at height 0
    return feet


def test_swing_pose_closed_form():
    p = ExecParams()
    feet = _flat_feet()
    new = feet[2] + [0.03, 0.0, 0.0]  # lh steps 3 cm forward
    pose = swing_pose(feet, 2, new, p)
    centroid = feet[[0, 1, 3], :2].mean(axis=0)
    away = (centroid - feet[2, :2]) / np.linalg.norm(centroid - feet[2, :2])
    np.testing.assert_allclose(pose[:2], centroid + p.shift_margin * away, atol=1e-15)
    assert pose[2] == pytest.approx(p.standing_height, abs=1e-15)  # within reach: not lowered
    assert pose[3] == 0.0 and pose[4] == 0.0
    # Heading of the four feet after the step: front midpoint (0.101, 0), hind (-0.086, 0).
    assert pose[5] == pytest.approx(math.atan2(0.0, 0.101 + 0.086), abs=1e-15)
    far = feet[0] + [0.08, 0.0, 0.0]  # lf 8 cm ahead: beyond MAX_LEG_EXTENSION at 0.14 m
    low = swing_pose(feet, 0, np.stack([feet[0], far]), p)
    assert low.shape == (2, 6) and low[0, 2] == pytest.approx(p.standing_height, abs=1e-15)
    assert low[1, 2] < p.standing_height
    body = np.r_[low[1, :3]]
    hip = body + LEG_GEOMETRY["lf"].p_BH
    assert np.linalg.norm(far - [0, 0, p.press] - hip) <= MAX_LEG_EXTENSION


def test_step_reachable_agrees_with_the_crawls_execution():
    p = ExecParams()
    board = HeightMap(origin=(-0.5, -0.5), resolution=0.01, heights=np.zeros((101, 101)))
    feet = _flat_feet()
    g = np.arange(-0.08, 0.081, 0.02)
    dx, dy = np.meshgrid(g, g)
    cand = feet[0] + np.stack([dx.ravel(), dy.ravel(), np.zeros(dx.size)], axis=-1)
    mask = step_reachable(feet, 0, cand, p, board)
    level = np.r_[feet[:, :2].mean(axis=0), p.standing_height, 0.0, 0.0, 0.0]
    executed = []
    for q in cand:
        try:
            execute(feet, level, [ExecStep(0, q)], board, p)
            executed.append(True)
        except CrawlError:
            executed.append(False)
    assert 0 < mask.sum() < len(mask)  # both kinds among the candidates
    np.testing.assert_array_equal(mask, executed)
    # no candidates: no poses and an empty mask (a reshape of the empty stack raised)
    assert swing_pose(feet, 0, np.zeros((0, 3)), p).shape == (0, 6)
    assert step_reachable(feet, 0, np.zeros((0, 3)), p, board).shape == (0,)
    assert step_reachable(feet, 0, np.zeros((0, 3)), p, board).dtype == bool


def test_crawl_model_bad_execution_params():
    hm = _board_map("flat")
    with pytest.raises(CrawlError, match="standing_height"):
        plan_crawl(
            hm, nominal_foot_positions()[:, :2], (0.2, 0.0), crawl=ExecParams(standing_height=0.5)
        )


def test_leg_ik_feasible_is_where_leg_ik_succeeds():
    rng = np.random.default_rng(0)
    for leg in ("lf", "rf", "lh", "rh"):
        hip = LEG_GEOMETRY[leg].p_BH
        pts = hip + rng.uniform([-0.12, -0.12, -0.2], [0.12, 0.12, 0.05], size=(400, 3))
        mask = leg_ik_feasible(leg, pts)
        for p, ok in zip(pts, mask, strict=True):
            try:
                leg_ik(leg, p)
                assert ok
            except RepertoireError:
                assert not ok
        assert 50 < mask.sum() < 350  # both kinds among the samples
    assert leg_ik_feasible("lf", np.zeros((2, 5, 3))).shape == (2, 5)


def test_swing_support_margin_closed_form_and_the_filler_holds_placing_moves_to_it():
    from repertoire.planning.footstep.quadruped import swing_support_margin
    from repertoire.planning.transfer_crawl_filler import CrawlGapFiller
    from repertoire.planning.transfer_search import PlannedStep

    feet = _flat_feet()  # a 0.202 m x 0.12 m rectangle
    # lh lifts: the body sways half way to the centroid of lf, rf, rh; the nearest edge is
    # the diagonal lf-rh: distance |cross| / |edge| with the sway point (0.101/3/2, -0.01).
    sway = np.array([0.101 / 6.0, -0.01])
    e, a = feet[3, :2] - feet[0, :2], sway - feet[0, :2]
    expected = abs(e[0] * a[1] - e[1] * a[0]) / math.hypot(*e)
    assert swing_support_margin(feet, 2, CrawlParams()) == pytest.approx(expected, abs=1e-15)
    assert expected == pytest.approx(0.0171, abs=1e-4)
    hm = HeightMap(origin=(-0.5, -0.5), resolution=0.01, heights=np.zeros((101, 101)))
    after = feet.copy()
    after[2, 0] += 0.02
    step = PlannedStep(feet, after, 2)
    assert CrawlGapFiller(hm).usable_prefix([step]) == 1
    strict = CrawlParams(support_margin=0.02)  # more than the step's 1.71 cm
    assert CrawlGapFiller(hm, params=strict).usable_prefix([step]) == 0


# The flat-board crawl to (0.25, 0) planned in world axes before the body could turn.
_STRAIGHT_FOOTHOLDS = [
    [-0.04, 0.06], [0.18, 0.06], [-0.01, -0.06], [0.22, -0.06], [0.05, 0.06],
    [0.27, 0.06], [0.09, -0.06], [0.32, -0.06], [0.14, 0.06], [0.33, 0.06],
]  # fmt: skip


def test_crawl_with_heading_zero_keeps_the_world_axis_footholds():
    hm = _board_map("flat")
    start = nominal_foot_positions()[:, :2]
    plans = [plan_crawl(hm, start, (0.25, 0.0), goal_heading=h) for h in (None, 0.0, 2 * math.pi)]
    for plan in plans:
        assert plan.status is PlanStatus.SUCCESS
        np.testing.assert_allclose(
            [s.p_WF[:2] for s in plan.steps], _STRAIGHT_FOOTHOLDS, atol=1e-12
        )
        assert heading_of(plan.steps[-1].stance) == 0.0


@pytest.mark.parametrize("goal_deg", [30.0, -45.0, 135.0, 180.0])
def test_crawl_turns_to_a_goal_heading_on_flat_ground(goal_deg):
    # Turns past 90 degrees used to stall: the turn term stayed flat beyond 90 degrees and
    # the body heading ran up to 60 degrees ahead of the feet (NODE_LIMIT after 2000-4000
    # expansions at a heading of 20-30 degrees); 135 and 180 degrees then took 261 and 961,
    # and with the turn's steps in the heuristic 181 and 150.
    from repertoire.planning.transfer_crawl_filler import executable_prefix
    from repertoire.planning.transfer_search import PlannedStep

    board = generate_board(TerrainParams(kind="flat", size_x=1.0, size_y=0.6), seed=1)
    hm = height_map_from_board(board, (-0.3, 0.7), (-0.3, 0.3), 0.01)
    params = CrawlParams()
    start = nominal_foot_positions()[:, :2]
    goal = math.radians(goal_deg)
    plan = plan_crawl(
        hm, start, (0.1, 0.0), params, time_limit=60.0, max_expansions=3000, goal_heading=goal
    )
    assert plan.status is PlanStatus.SUCCESS
    final = plan.steps[-1].stance
    err = heading_of(final) - goal
    assert abs(math.atan2(math.sin(err), math.cos(err))) <= params.heading_tolerance
    assert math.hypot(*(final[:, :2].mean(axis=0) - [0.1, 0.0])) <= params.goal_radius
    # The body turns by at most turn_step per step: the feet cannot turn 30 degrees at once.
    assert len(plan.steps) >= 4
    _check_plan(plan, hm, params, board)
    lift = np.array([0.0, 0.0, FOOT_RADIUS])
    stances = [plan.start_stance + lift] + [s.stance + lift for s in plan.steps]
    steps = [PlannedStep(a, b, s.foot) for a, b, s in zip(stances, stances[1:], plan.steps)]
    assert executable_prefix(steps, ExecParams(), board) == len(steps)
    # Without a goal heading the same crawl keeps its start heading.
    still = plan_crawl(hm, start, (0.1, 0.0), params, time_limit=30.0)
    assert heading_of(still.steps[-1].stance) == 0.0


@pytest.mark.parametrize("terrain", ["modified", "rocks"])
def test_crawl_half_turn_plans_on_rough_ground(terrain):
    # The transfer scenario's modified terrain (the start of its crossing) and a generated
    # rock board: turning in place among rocks, goal 0.2 m ahead at 180 degrees. Without
    # the turn's steps in the heuristic both ended in TIME_LIMIT at 93-129 degrees after
    # 20 s (1280 and 3136 expansions); now SUCCESS after 310 and 244.
    if terrain == "modified":
        from repertoire.diagrams.littledog_transfer import (
            LittleDogTransferScenario,
            target_board,
        )

        board = target_board(LittleDogTransferScenario(target="modified"))
    else:
        board = generate_board(TerrainParams(kind="rocks", size_x=0.8, size_y=0.8), seed=2)
    x0, x1, y0, y1 = board.bounds()
    hm = height_map_from_board(board, (x0, x1), (y0, y1), 0.01)
    start = nominal_foot_positions()[:, :2] + [-0.26, 0.01]  # the crossing's flat start
    goal = start.mean(axis=0) + [0.2, 0.0]
    params = CrawlParams()
    plan = plan_crawl(
        hm, start, goal, params, time_limit=60.0, max_expansions=600,
        goal_heading=math.pi, ground=board,
    )  # fmt: skip
    assert plan.status is PlanStatus.SUCCESS
    assert plan.expansions <= 600
    final = plan.steps[-1].stance
    err = heading_of(final) - math.pi
    assert abs(math.atan2(math.sin(err), math.cos(err))) <= params.heading_tolerance
    assert math.hypot(*(final[:, :2].mean(axis=0) - goal)) <= params.goal_radius
    _check_plan(plan, hm, params, board)


def test_crawl_from_a_yawed_stance_keeps_or_turns_its_heading():
    hm = _board_map("flat")
    params = CrawlParams()
    c, s = math.cos(math.radians(40.0)), math.sin(math.radians(40.0))
    start = nominal_foot_positions()[:, :2] @ np.array([[c, s], [-s, c]])
    assert heading_of(np.column_stack([start, np.zeros(4)])) == pytest.approx(math.radians(40.0))
    kept = plan_crawl(hm, start, (0.1, 0.0), params, time_limit=30.0)
    turned = plan_crawl(hm, start, (0.1, 0.0), params, time_limit=30.0, goal_heading=0.0)
    for plan, heading in ((kept, math.radians(40.0)), (turned, 0.0)):
        assert plan.status is PlanStatus.SUCCESS
        assert abs(heading_of(plan.steps[-1].stance) - heading) <= params.heading_tolerance
        _check_plan(plan, hm, params)


def test_crawl_goal_heading_bad_input():
    hm = _board_map("flat")
    start = nominal_foot_positions()[:, :2]
    for bad in (math.nan, math.inf, "0.5", True, [0.1]):
        with pytest.raises(
            FootstepError, match="goal_heading must be a finite angle.*" + re.escape(repr(bad))
        ):
            plan_crawl(hm, start, (0.2, 0.0), goal_heading=bad)
    with pytest.raises(FootstepError, match="crawl turn_step must be positive, got 0.0"):
        plan_crawl(hm, start, (0.2, 0.0), CrawlParams(turn_step=0.0), goal_heading=0.5)
    with pytest.raises(FootstepError, match="crawl heading_tolerance must be positive, got nan"):
        plan_crawl(hm, start, (0.2, 0.0), CrawlParams(heading_tolerance=math.nan))
    for name, bad in (("turn_step", -0.1), ("heading_tolerance", -0.1)):
        with pytest.raises(FootstepError, match=f"crawl {name} must be positive, got -0.1"):
            plan_crawl(hm, start, (0.2, 0.0), CrawlParams(**{name: bad}), goal_heading=0.5)
    for name in ("turn_step", "heading_tolerance"):
        with pytest.raises(FootstepError, match=f"crawl {name} must be at most pi rad, got 4.0"):
            plan_crawl(hm, start, (0.2, 0.0), CrawlParams(**{name: 4.0}), goal_heading=0.5)
    assert CrawlParams(turn_step=math.pi, heading_tolerance=math.pi).validate() is None


def test_crawl_body_heading_leads_the_feet_by_at_most_turn_lead_steps():
    import dataclasses

    from repertoire.planning.footstep.quadruped import CrawlModel

    hm = _board_map("flat")
    start = nominal_foot_positions()[:, :2]  # the feet's heading: 0
    params = CrawlParams(turn_lead=2)
    model = CrawlModel(hm, start, (0.1, 0.0), params, goal_heading=math.radians(90.0))
    s0 = model.start()
    for turns, allowed in ((0, {0, 1}), (1, {1, 2}), (2, {2}), (3, {3})):
        state = dataclasses.replace(s0, turns=turns)
        got = {t.turns for t, _ in model.successors(state)}
        assert got == allowed, (turns, got)
    # towards the goal only: a body heading past it turns back, within the lead too
    back = dataclasses.replace(s0, turns=-1)
    assert {t.turns for t, _ in model.successors(back)} == {-1, 0}


def test_crawl_turn_lead_bad_input():
    for bad in (0, -1, 1.5, float("nan"), "2"):
        with pytest.raises(FootstepError, match=r"turn_lead must be an integer >= 1, got " +
                           re.escape(repr(bad))):  # fmt: skip
            CrawlParams(turn_lead=bad).validate()
    CrawlParams(turn_lead=1).validate()


def test_crawl_line_and_kept_footholds_are_exact():
    # the swing-clearance line is np.linspace's own arithmetic without its call overhead,
    # and a model keeps each state's footholds; footholds() still hands out a new array
    from repertoire.planning.footstep.quadruped import CrawlModel, _line

    rng = np.random.default_rng(7)
    for _ in range(2000):
        a, b = (int(v) for v in rng.integers(-300, 300, 2))
        n = int(rng.integers(1, 80))
        assert np.array_equal(_line(a, b, n), np.linspace(a, b, n + 1))
    hm = _board_map("flat")
    model = CrawlModel(hm, nominal_foot_positions()[:, :2], (0.1, 0.0), CrawlParams())
    s0 = model.start()
    first = model.footholds(s0)
    first[:] = 99.0  # a caller's edit must not reach the model's kept copy
    again = model.footholds(s0)
    np.testing.assert_array_equal(again[:, :2], nominal_foot_positions()[:, :2])
    assert again is not model.footholds(s0)


def test_crawl_front_line_is_part_of_the_goal_test():
    from repertoire.planning.footstep.quadruped import CrawlModel

    hm = _board_map("flat")
    start = nominal_foot_positions()[:, :2]
    front = float(start[:2, 0].min())  # the front feet's x (lf, rf)
    centroid = tuple(start.mean(axis=0))
    s0 = CrawlModel(hm, start, centroid, CrawlParams()).start()
    assert CrawlModel(hm, start, centroid, CrawlParams()).is_goal(s0)
    # (1, 0, x): both front feet at x or beyond; the normal is normalised
    on = CrawlModel(hm, start, centroid, CrawlParams(), front_line=(2.0, 0.0, 2.0 * front))
    assert on.is_goal(s0)
    past = CrawlModel(hm, start, centroid, CrawlParams(), front_line=(1.0, 0.0, front + 1e-9))
    assert not past.is_goal(s0)
    # the heuristic: the larger of the centroid's and the front feet's travel to the line
    far = CrawlModel(hm, start, centroid, CrawlParams(), front_line=(1.0, 0.0, front + 0.05))
    assert far.heuristic(s0) == pytest.approx(0.1 + 2 * CrawlParams().step_cost, abs=1e-12)
    assert on.heuristic(s0) == CrawlModel(hm, start, centroid, CrawlParams()).heuristic(s0)
    # a plan with the centroid's goal 3 cm ahead and the line 4 cm ahead of the front feet
    # (the centroid alone is within its goal radius at the start) ends with both past it
    line = (1.0, 0.0, front + 0.04)
    plan = plan_crawl(hm, start, (centroid[0] + 0.03, centroid[1]), time_limit=30.0,
                      front_line=line)  # fmt: skip
    assert plan.status is PlanStatus.SUCCESS
    assert plan.steps[-1].stance[:2, 0].min() >= front + 0.04
    for bad in ((0.0, 0.0, 1.0), (1.0, math.nan, 0.0), (1.0, 0.0), "x"):
        with pytest.raises(FootstepError, match="front_line must be a finite.*n != 0"):
            plan_crawl(hm, start, (0.1, 0.0), front_line=bad)


def test_shift_poses_are_the_crawls_commanded_shift_and_end_at_the_target():
    from repertoire.planning.littledog_crawl import shift_poses

    params = ExecParams()
    pose = np.array([0.0, 0.0, 0.2, 0.0, 0.0, 3.1])
    target = np.array([0.02, 0.01, 0.18, 0.0, 0.0, -3.1])  # yaw the short way: +0.083 rad
    poses = shift_poses(pose, target, params)
    assert poses.shape == (round(params.shift_time / params.dt), 6)
    np.testing.assert_allclose(poses[-1, :5], target[:5], atol=1e-15)
    assert poses[-1, 5] == pytest.approx(3.1 + (2 * math.pi - 6.2))
    assert np.all(np.diff(poses[:, 5]) >= 0.0)  # never the long way round
    both = shift_poses(pose, np.stack([target, pose]), params)
    np.testing.assert_array_equal(both[0], poses)
    np.testing.assert_array_equal(both[1], np.repeat(pose[None], len(poses), 0))
    # the executor commands exactly these poses between the hold and the first lift
    board = generate_board(TerrainParams(kind="flat"), seed=0)  # its top at 0.04 m
    feet = np.column_stack([nominal_foot_positions()[:, :2], np.full(4, 0.04 + FOOT_RADIUS)])
    pose0 = np.r_[feet[:, :2].mean(axis=0), 0.18, 0.0, 0.0, 0.0]
    p_new = feet[2] + [0.03, 0.0, 0.0]
    executed = execute(feet, pose0, [ExecStep(2, p_new)], board, params, hold_time=0.0)
    shift = shift_poses(pose0, swing_pose(feet, 2, p_new, params), params)
    np.testing.assert_array_equal(executed.body_pose[1 : 1 + len(shift)], shift)


def test_planned_crawls_execute_through_every_shift():
    # A steps board (rises 2-4.5 cm) the planner was never tuned on: step 14 (rh) drops the
    # body 5.4 cm while turning; both ends of the shift are reachable, but halfway lf's hip
    # pitch reached 2.504 rad (limit 2.4) and the crawl refused the plan (CrawlError). The
    # states now keep the cell the last foot left, so the shift from that step's pose is
    # checked at every commanded sample.
    board = generate_board(TerrainParams(kind="steps", size_x=1.0, size_y=0.6,
                                         step_rise=[0.02, 0.045]), seed=9609)  # fmt: skip
    hm = height_map_from_board(board, (-0.55, 0.55), (-0.3, 0.3), 0.01)
    start = nominal_foot_positions()[:, :2] + [-0.25, 0.0]
    plan = plan_crawl(hm, start, (0.2, 0.0), time_limit=30.0, ground=board)
    assert plan.status is PlanStatus.SUCCESS
    _check_plan(plan, hm, CrawlParams(), board)  # the crawl's IK at every sample, shifts too


def test_crawl_refuses_a_map_too_large_for_its_planning_arrays_before_allocating(monkeypatch):
    # A 300 x 200 map holds 0.48 MB of heights; the roughness filter needs 24 bytes a cell
    # more (1.44 MB). Before, the crawl model allocated them unchecked.
    hm = HeightMap(origin=(-1.5, -1.0), resolution=0.01, heights=np.zeros((200, 300)))
    monkeypatch.setenv("REPERTOIRE_MAX_MEMORY_BYTES", str(10**6))
    with pytest.raises(ResourceLimitError, match=r"crawl planning \(roughness\) of a 300 x 200 "
                       r"height map at 0.01 m would need about 1.4 MiB"):  # fmt: skip
        plan_crawl(hm, nominal_foot_positions()[:, :2], (0.2, 0.0))
    monkeypatch.setenv("REPERTOIRE_MAX_MEMORY_BYTES", str(2 * 10**6))
    assert plan_crawl(hm, nominal_foot_positions()[:, :2], (0.2, 0.0)).status is PlanStatus.SUCCESS


def test_the_default_step_height_is_the_crawls_reach():
    # From a level stance on flat ground every leg of the executing crawl steps 9 cm up
    # at its nominal foothold and 4 and 6 cm ahead of it (the leg IK over the whole step),
    # and none 9.5 cm: the model's max_step_height (5 cm before session 37) is that reach.
    class Flat:
        def height(self, x, y):
            return np.zeros(np.shape(x))

    nominal = nominal_foot_positions()[:, :2]
    feet = np.column_stack([nominal, np.full(4, FOOT_RADIUS)])
    h = CrawlParams().max_step_height
    reach = [
        step_reachable(
            feet, foot, [[*(nominal[foot] + [dx, 0.0]), z + FOOT_RADIUS]], ExecParams(), Flat()
        )[0]
        for foot in range(4)
        for dx in (0.0, 0.04, 0.06)
        for z in (h, h + 0.005)
    ]
    assert h == 0.09
    assert reach == [True, False] * 12
