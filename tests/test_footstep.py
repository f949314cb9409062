"""Footstep planner: tables, grids, footprints, heuristics, A* optimality, limits, bad input."""

import math

import numpy as np
import pytest
from repertoire.planning.footstep import (
    ACTIONS,
    MIRROR,
    STEP_COST,
    ActionTable,
    ActionTableError,
    DynamicEnvironment,
    Foot,
    FootstepError,
    FootstepPlan,
    GridError,
    MovingRectObstacle,
    OccupancyGrid,
    PlannerOptions,
    PlanStatus,
    RectObstacle,
    apply_displacement,
    commanded_displacement,
    nominal_action_table,
    plan_footsteps,
    plan_mobile2d,
    relative_displacement,
    state_dependent_example_table,
)
from repertoire.planning.footstep.environment import rect_overlaps_cells
from repertoire.planning.footstep.footprint import (
    FootprintChecker,
    foot_collides_reference,
    footprint_masks,
)
from repertoire.planning.footstep.heuristic import dijkstra_cost_to_go
from repertoire.planning.footstep.metrics import (
    action_counts,
    body_path_length,
    steps_over_obstacles,
    swing_segments,
)
from repertoire.planning.footstep.mobile2d import inflate
from repertoire.planning.footstep.planner import history_classes

# ----------------------------------------------------------------------------- helpers


def lattice_table() -> ActionTable:
    """Four axis-aligned actions whose displacements are multiples of 2.5 cm (yaw 0)."""
    names = ["fwd1", "fwd2", "side", "stop"]
    n = len(names)
    disp = np.zeros((n, n, 2, n, 3))
    for f in (0, 1):
        s = 1.0 if f == 1 else -1.0  # stance right -> swing left -> +y
        for a, d in enumerate([(0.1, 0.2), (0.2, 0.2), (0.0, 0.25), (0.0, 0.2)]):
            disp[:, :, f, a] = (d[0], s * d[1], 0.0)
    return ActionTable(
        actions=names,
        displacement=disp,
        duration=np.full((n, n, 2, n), 0.5),
        step_cost=np.array([1.0, 1.3, 1.1, 0.9]),
        rest_action="stop",
    )


def follows_table(plan: FootstepPlan, table: ActionTable) -> None:
    """Assert every step of the plan is exactly what T predicts, with its duration."""
    hist = list(plan.initial_history)
    for k, a in enumerate(plan.actions, start=1):
        dx, dy, dyaw, dur = table.lookup(hist[0], hist[1], plan.feet[k - 1], a)
        rel = relative_displacement(plan.poses[k - 1], plan.poses[k])
        np.testing.assert_allclose(rel, (dx, dy, dyaw), atol=1e-9)
        assert plan.times[k] - plan.times[k - 1] == pytest.approx(dur)
        assert plan.feet[k] == 1 - plan.feet[k - 1]
        hist = [hist[1], a]


# ----------------------------------------------------------------------------- pose algebra


def test_apply_displacement_closed_form():
    x, y, th = apply_displacement((1.0, 2.0, math.pi / 2), (0.3, 0.19, 0.2))
    assert (x, y) == pytest.approx((1.0 - 0.19, 2.0 + 0.3))
    assert th == pytest.approx(math.pi / 2 + 0.2)
    back = relative_displacement((1.0, 2.0, math.pi / 2), (x, y, th))
    assert back == pytest.approx((0.3, 0.19, 0.2))


def test_commanded_displacements():
    assert commanded_displacement("forward_long", Foot.LEFT) == pytest.approx((0.30, -0.19, 0))
    assert commanded_displacement("forward_short", Foot.RIGHT) == pytest.approx((0.10, 0.19, 0))
    assert commanded_displacement("side_step", Foot.RIGHT) == pytest.approx((0.0, 0.29, 0))
    assert commanded_displacement("stop", Foot.LEFT) == pytest.approx((0.0, -0.19, 0))
    # a turn rotates the swing foot about the feet midpoint (plus 5 cm forward)
    dx, dy, dth = commanded_displacement("turn_left", Foot.RIGHT)
    assert dth == pytest.approx(0.35)
    assert math.hypot(dx - 0.05, dy - 0.095) == pytest.approx(0.095)
    with pytest.raises(ValueError, match="unknown action"):
        commanded_displacement("jump", Foot.LEFT)


# ----------------------------------------------------------------------------- action tables


def test_nominal_table_lookup_and_history_classes():
    t = nominal_action_table()
    assert t.actions == ACTIONS and t.n == 7
    assert t.lookup("stop", "stop", "left", "forward_long") == pytest.approx((0.3, -0.19, 0, 0.8))
    assert t.max_reach() == pytest.approx(math.hypot(0.30, 0.19))
    assert history_classes(t).max() == 0  # history-independent: one class
    ex = state_dependent_example_table()
    # stop after a long step still moves 40 % of it forward; from standing long is 60 %
    assert ex.lookup("forward_long", "forward_long", "left", "stop")[0] == pytest.approx(0.12)
    assert ex.lookup("stop", "stop", "left", "forward_long")[0] == pytest.approx(0.18)
    assert ex.lookup("stop", "stop", "left", "forward_long")[3] == pytest.approx(1.0)
    cls = history_classes(ex)
    assert 1 < cls.max() + 1 < 49
    # histories with the same previous action (and equal futures) are merged
    assert cls[0, ACTIONS.index("stop")] == cls[3, ACTIONS.index("stop")]


@pytest.mark.parametrize("suffix", [".json", ".npz"])
def test_action_table_roundtrip(tmp_path, suffix):
    t = state_dependent_example_table()
    back = ActionTable.load(t.save(tmp_path / f"t{suffix}"))
    assert back.actions == t.actions and back.rest_action == "stop" and back.mirror == MIRROR
    np.testing.assert_array_equal(back.displacement, t.displacement)
    np.testing.assert_array_equal(back.duration, t.duration)
    np.testing.assert_array_equal(back.step_cost, t.step_cost)


def test_action_table_bad_input(tmp_path):
    t = nominal_action_table()
    disp = t.displacement.copy()
    disp[1, 2, 0, 3, 1] = np.nan
    with pytest.raises(ActionTableError, match=r"non-finite.*forward_medium.*forward_short.*LEFT"):
        ActionTable(t.actions, disp, t.duration, t.step_cost, "stop")
    dur = t.duration.copy()
    dur[0, 0, 1, 0] = np.inf
    with pytest.raises(ActionTableError, match="duration has 1 missing or non-finite"):
        ActionTable(t.actions, t.displacement, dur, t.step_cost, "stop")
    with pytest.raises(ActionTableError, match="must have shape"):
        ActionTable(t.actions, t.displacement[:, :, :, :6], t.duration, t.step_cost, "stop")
    with pytest.raises(ActionTableError, match="durations must be positive"):
        ActionTable(t.actions, t.displacement, 0 * t.duration, t.step_cost, "stop")
    with pytest.raises(ActionTableError, match="rest_action"):
        ActionTable(t.actions, t.displacement, t.duration, t.step_cost, "halt")
    data = t.to_dict()
    data["displacement"][0][0][0].pop()  # one entry missing -> ragged
    with pytest.raises(ActionTableError, match="ragged"):
        ActionTable.from_dict(data)
    with pytest.raises(ActionTableError, match="lacks keys"):
        ActionTable.from_dict({"actions": ACTIONS})
    with pytest.raises(ActionTableError, match="format"):
        t.save(tmp_path / "t.yaml")
    with pytest.raises(ActionTableError, match="does not exist"):
        ActionTable.load(tmp_path / "missing.json")
    with pytest.raises(ActionTableError, match="unknown action"):
        t.lookup("stop", "stop", "left", "moonwalk")


def _samples_from(table: ActionTable, feet=(0,)):
    out = []
    for i2, a2 in enumerate(table.actions):
        for i1, a1 in enumerate(table.actions):
            for f in feet:
                for a, name in enumerate(table.actions):
                    dx, dy, dth = table.displacement[i2, i1, f, a]
                    out.append(
                        (
                            a2,
                            a1,
                            "left" if f == 0 else "right",
                            name,
                            dx,
                            dy,
                            dth,
                            table.duration[i2, i1, f, a],
                        )
                    )
    return out


def test_from_samples_mirror_average_and_missing():
    ex = state_dependent_example_table()
    kw = dict(
        actions=ACTIONS,
        rest_action="stop",
        step_cost=[STEP_COST[a] for a in ACTIONS],
        mirror=MIRROR,
    )
    # 343 sequences measured with the left foot standing: the right foot comes by mirroring
    samples = _samples_from(ex, feet=(0,))
    assert len(samples) == 343
    built = ActionTable.from_samples(samples, **kw)
    np.testing.assert_allclose(built.displacement, ex.displacement, atol=1e-12)
    np.testing.assert_allclose(built.duration, ex.duration)
    # two samples of one key are averaged (yaw by circular mean)
    extra = [
        ("stop", "stop", "left", "turn_left", 0.0, 0.0, 0.1, 1.0),
        ("stop", "stop", "left", "turn_left", 0.2, 0.4, 0.3, 2.0),
    ]
    rest = [s for s in samples if not (s[0] == s[1] == "stop" and s[3] == "turn_left")]
    avg = ActionTable.from_samples(rest + extra, **kw)
    assert avg.lookup("stop", "stop", "left", "turn_left") == pytest.approx((0.1, 0.2, 0.2, 1.5))
    # without mirroring, the right foot is missing
    with pytest.raises(ActionTableError, match="missing or non-finite.*RIGHT"):
        ActionTable.from_samples(samples, fill_missing_foot_by_mirror=False, **kw)
    with pytest.raises(ActionTableError, match="missing or non-finite"):
        ActionTable.from_samples(samples[:-1], **kw)
    with pytest.raises(ActionTableError, match="non-finite values"):
        ActionTable.from_samples([("stop", "stop", 0, "stop", 0, np.nan, 0, 1)], **kw)
    with pytest.raises(ActionTableError, match="sample 0 has 6 fields"):
        ActionTable.from_samples([("stop", "stop", 0, "stop", 0, 0)], **kw)
    with pytest.raises(ActionTableError, match="unknown action"):
        ActionTable.from_samples([("stop", "hop", 0, "stop", 0, 0, 0, 1)], **kw)


# ----------------------------------------------------------------------------- grids


def test_rect_overlaps_cells_closed_form():
    centers = np.array([[0.0, 0.0], [0.2, 0.0], [0.3, 0.0], [0.0, 0.125], [0.18, 0.18]])
    # axis-aligned 0.4 x 0.2 at the origin, cells of half side 0.05: touching is no overlap
    hit = rect_overlaps_cells((0, 0), (0.2, 0.1), 0.0, centers, 0.05)
    assert hit.tolist() == [True, True, False, True, False]
    # rotated 45 deg: the corner direction reaches farther along the diagonal
    hit45 = rect_overlaps_cells((0, 0), (0.2, 0.1), math.pi / 4, centers, 0.05)
    assert hit45.tolist() == [True, True, False, True, True]


def test_grid_rasterisation_exact():
    g = OccupancyGrid.from_rectangles((1.0, 1.0), [RectObstacle([0.5, 0.5], [0.1, 0.05])])
    assert g.shape == (40, 40)
    assert g.occupied.sum() == 8  # 4 x 2 cells, aligned with the cell edges
    assert g.occupied[18:22, 19:21].all()
    g2 = OccupancyGrid.from_rectangles(
        (1.0, 1.0), [RectObstacle([0.5, 0.5], [0.1, 0.06])], with_heights=True
    )
    assert g2.occupied.sum() == 16 and g2.heights.max() == pytest.approx(0.02)
    with pytest.raises(GridError, match="resolution"):
        OccupancyGrid(np.zeros((4, 4)), resolution=0.0)
    with pytest.raises(GridError, match="heights shape"):
        OccupancyGrid(np.zeros((4, 4)), heights=np.zeros((3, 4)))


def test_table_entry_follows_a_table_edited_in_place():
    from repertoire.planning.footstep.biped_model import _table_entry

    table = nominal_action_table()
    first = _table_entry(table)
    assert _table_entry(table) is first  # the same object and content: remembered
    table.step_cost[:] = table.step_cost + 0.5  # edited in place: a new entry
    assert _table_entry(table)["c_min"] == pytest.approx(first["c_min"] + 0.5)
    table.step_cost[:] = table.step_cost - 0.5  # back to the first content
    assert _table_entry(table) is first
    table.rest_action = table.actions[1]  # another rest action: not the first entry
    assert _table_entry(table) is not first


def test_dynamic_environment_nearest_time_and_errors():
    m = MovingRectObstacle([0.1, 0.5], [0.1, 0.1], [0.5, 0.0])
    env = DynamicEnvironment.from_moving_obstacles((1.0, 1.0), moving=[m], t_end=1.0, dt=0.1)
    assert len(env.times) == 11 and env.max_time_gap == pytest.approx(0.05)
    assert env.index_at(0.34) == 3 and env.index_at(0.36) == 4
    # the block moves 0.05 m (two cells) per grid; grid k marks what it sweeps over
    # [0.1 k - 0.05, 0.1 k + 0.05] s: x in [0.025 + 0.05 k, 0.175 + 0.05 k], cells
    # 1 + 2k .. 6 + 2k, rows 18 .. 21
    for t, (i0, i1) in ((0.0, (1, 6)), (0.2, (5, 10))):
        want = np.zeros((40, 40), bool)
        want[i0 : i1 + 1, 18:22] = True
        np.testing.assert_array_equal(env.at(t).occupied, want)
    with pytest.raises(GridError, match="no grid near t = 1.200"):
        env.at(1.2)
    with pytest.raises(GridError, match="no grid near"):
        env.index_at(-0.1)
    coarse = OccupancyGrid.empty((1.0, 1.0), resolution=0.05)
    with pytest.raises(GridError, match="share shape, resolution and origin"):
        DynamicEnvironment([0.0, 1.0], [env.grids[0], coarse], max_time_gap=0.5)
    with pytest.raises(GridError, match="strictly increasing"):
        DynamicEnvironment([0.0, 0.0], env.grids[:2], max_time_gap=0.5)
    path = MovingRectObstacle(
        [0, 0], [0.1, 0.1], waypoints=[[0, 0.2, 0.2], [2, 0.6, 0.2], [4, 0.6, 0.8]]
    )
    assert path.center_at(-1) == [0.2, 0.2] and path.center_at(1) == pytest.approx([0.4, 0.2])
    assert path.center_at(3) == pytest.approx([0.6, 0.5]) and path.center_at(9) == [0.6, 0.8]
    with pytest.raises(GridError, match="increase strictly"):
        MovingRectObstacle([0, 0], [0.1, 0.1], waypoints=[[1, 0, 0], [1, 1, 1]])
    with pytest.raises(GridError, match="2 times but 1 grids"):
        DynamicEnvironment([0.0, 1.0], env.grids[:1], max_time_gap=0.5)


# ----------------------------------------------------------------------------- heuristics, 2-D


def test_dijkstra_cost_to_go_closed_form():
    g = OccupancyGrid.empty((1.0, 1.0))
    d = dijkstra_cost_to_go(g, (0.0125, 0.0125), 0.01)
    # octile distance from cell (0, 0): 10 diagonal + 20 straight moves of 2.5 cm
    assert d[10, 30] == pytest.approx(0.025 * (10 * math.sqrt(2) + 20))
    occ = np.zeros((40, 40), bool)
    occ[5, :] = True  # one column of occupied cells costs 3x to cross
    d2 = dijkstra_cost_to_go(OccupancyGrid(occ), (0.0125, 0.0125), 0.01, obstacle_cost=3.0)
    assert d2[10, 0] == pytest.approx(0.025 * (10 + 2))


def test_mobile2d_closed_form_and_blocked():
    g = OccupancyGrid.empty((2.0, 1.0))
    p = plan_mobile2d(g, (0.3125, 0.5125), (1.5125, 0.5125), radius=0.3)
    assert p.status == PlanStatus.SUCCESS and p.length == pytest.approx(1.2)
    assert p.path[0] == pytest.approx([0.3125, 0.5125]) and p.path[-1] == pytest.approx(
        [1.5125, 0.5125]
    )
    blocked = inflate(g, 0.3)
    assert blocked[:, 0].all() and not blocked[20, 20]
    # a thin strip across the room: the circle cannot pass, the biped steps over it
    wall = OccupancyGrid.from_rectangles((2.0, 1.0), [RectObstacle([1.0, 0.5], [0.05, 1.0])])
    p2 = plan_mobile2d(wall, (0.4, 0.5), (1.6, 0.5), radius=0.3)
    assert p2.status == PlanStatus.UNREACHABLE and "no collision-free path" in p2.reason
    plan = plan_footsteps(wall, (0.4, 0.595, 0.0), "left", (1.6, 0.5), nominal_action_table())
    assert plan.succeeded and steps_over_obstacles(wall, plan) >= 2
    with pytest.raises(FootstepError, match="outside the map"):
        plan_mobile2d(g, (2.5, 0.5), (1.0, 0.5), 0.3)


# ----------------------------------------------------------------------------- planner


def test_straight_walk_follows_table():
    g = OccupancyGrid.empty((2.0, 2.0))
    t = nominal_action_table()
    plan = plan_footsteps(g, (0.3, 1.0, 0.0), "left", (1.5, 1.0), t)
    assert plan.status == PlanStatus.SUCCESS
    assert plan.num_steps == 4 and set(plan.actions) == {"forward_long"}
    assert plan.poses[-1] == pytest.approx([1.5, 1.0, 0.0])
    assert plan.times == pytest.approx([0.0, 0.8, 1.6, 2.4, 3.2])
    assert plan.cost == pytest.approx(4.0) and plan.cost_to_go == 0.0
    assert plan.initial_swing_pose == pytest.approx([0.3, 0.81, 0.0])
    follows_table(plan, t)


def test_state_dependent_table_is_respected():
    g = OccupancyGrid.empty((3.0, 2.0))
    t = state_dependent_example_table()
    plan = plan_footsteps(g, (0.3, 1.0, 0.0), "right", (2.3, 1.3), t, start_time=5.0)
    assert plan.succeeded and plan.times[0] == 5.0
    follows_table(plan, t)
    assert plan.actions[0] != "forward_long" or plan.poses[1][0] == pytest.approx(0.48)


def test_plan_json_roundtrip(tmp_path):
    g = OccupancyGrid.empty((2.0, 2.0))
    plan = plan_footsteps(g, (0.3, 1.0, 0.0), "left", (1.5, 1.2), nominal_action_table())
    back = FootstepPlan.load(plan.save(tmp_path / "plan.json"))
    assert back == plan and back.status is PlanStatus.SUCCESS
    with pytest.raises(FootstepError, match="lacks keys"):
        FootstepPlan.from_dict({"poses": []})


def test_plan_from_commands():
    poses = [[0.0, 0.1, 0.0], [0.3, -0.1, 0.0]]
    plan = FootstepPlan.from_commands(
        poses, [0, 1], ["forward_long"], [0.0, 0.8], [0.0, -0.1, 0.0], ["stop", "stop"]
    )
    assert plan.status is PlanStatus.SUCCESS and plan.num_steps == 1
    assert plan.goal == [0.3, -0.1] and plan.goal_tolerance == 0.1
    assert (plan.cost, plan.cost_to_go, plan.nodes_expanded, plan.planning_time_s) == (0, 0, 0, 0)
    standing = FootstepPlan.from_commands(poses[:1], [0], [], [0.0], [0, 0, 0], ["stop"] * 2)
    assert standing.goal == [0.0, 0.1] and standing.num_steps == 0
    with pytest.raises(FootstepError, match="a plan with 1 actions needs 2 poses"):
        FootstepPlan.from_commands(poses[:1], [0], ["stop"], [0.0], [0, 0, 0], ["stop"] * 2)


def _tiny_problem():
    # the right foot's lane (y = 0.1) is blocked by a block it must step over
    grid = OccupancyGrid.from_rectangles((1.0, 0.6), [RectObstacle([0.5, 0.085], [0.1, 0.17])])
    return grid, (0.15, 0.3, 0.0), "left", (0.85, 0.3)


def _brute_force_min_cost(grid, table, start, goal, tol, depth, bound):
    best = [bound]
    n = table.n

    def rec(pose, foot, g, d):
        if (pose[0] - goal[0]) ** 2 + (pose[1] - goal[1]) ** 2 <= tol * tol:
            best[0] = min(best[0], g)
            return
        if d == depth:
            return
        for a in range(n):
            g2 = g + table.step_cost[a]
            if g2 > best[0] + 1e-9:
                continue
            nxt = apply_displacement(pose, table.displacement[0, 0, foot, a])
            if foot_collides_reference(grid, nxt, 0.16, 0.10):
                continue
            rec(nxt, 1 - foot, g2, d + 1)

    rec(start, 0, 0.0, 0)
    return best[0]


def test_admissible_mode_is_optimal_on_tiny_map():
    grid, start, foot, goal = _tiny_problem()
    t = lattice_table()
    tol = 0.12
    exact = {"footprint_margin_m": 0.0}  # the brute force checks the exact footprint
    astar = plan_footsteps(
        grid,
        start,
        foot,
        goal,
        t,
        PlannerOptions.admissible(goal_tolerance=tol, time_limit=20, **exact),
    )
    ucs = plan_footsteps(
        grid,
        start,
        foot,
        goal,
        t,
        PlannerOptions(
            heuristic="none",
            goal_tolerance=tol,
            time_limit=20,
            xy_resolution=0.025,
            yaw_bins=72,
            **exact,
        ),
    )
    assert astar.succeeded and ucs.succeeded
    assert astar.cost == pytest.approx(ucs.cost, abs=1e-9)
    assert astar.nodes_expanded < ucs.nodes_expanded
    brute = _brute_force_min_cost(
        grid, t, start, goal, tol, depth=astar.num_steps + 2, bound=astar.cost + 1e-6
    )
    assert brute == pytest.approx(astar.cost, abs=1e-9)
    # the inadmissible, weighted Dijkstra heuristic is never better than the optimum
    fast = plan_footsteps(
        grid,
        start,
        foot,
        goal,
        t,
        PlannerOptions(heuristic_weight=3.0, goal_tolerance=tol, time_limit=30),
    )
    assert fast.succeeded and fast.cost >= astar.cost - 1e-9
    follows_table(astar, t)


def test_unreachable_goal_returns_best_partial_plan():
    # a 0.3 m thick wall across the room cannot be stepped over (steps reach 0.2 m)
    grid = OccupancyGrid.from_rectangles((1.2, 0.6), [RectObstacle([0.7, 0.3], [0.3, 0.6])])
    plan = plan_footsteps(
        grid,
        (0.15, 0.3, 0.0),
        "left",
        (1.05, 0.3),
        lattice_table(),
        PlannerOptions(time_limit=30, goal_tolerance=0.1),
    )
    assert plan.status == PlanStatus.UNREACHABLE
    assert plan.num_steps > 0 and plan.cost_to_go > 0
    # the partial plan ends at the wall: as close to the goal as a foot can stand
    assert plan.poses[-1][0] == pytest.approx(0.55 - 0.08, abs=0.0251)


def test_node_and_time_limits_return_partial_plans():
    from repertoire.planning.footstep.scenes import random_static_scene

    sc = random_static_scene(1)
    t = nominal_action_table()
    h0 = plan_footsteps(
        sc.grid,
        sc.start,
        sc.start_foot,
        sc.goal,
        t,
        PlannerOptions(max_expansions=1, time_limit=30),
    ).cost_to_go
    part = plan_footsteps(
        sc.grid,
        sc.start,
        sc.start_foot,
        sc.goal,
        t,
        PlannerOptions(
            heuristic="euclidean", heuristic_weight=1.0, max_expansions=300, time_limit=30
        ),
    )
    assert part.status == PlanStatus.NODE_LIMIT and part.nodes_expanded == 300
    assert 0 < part.num_steps and part.cost_to_go < h0
    follows_table(part, t)
    timed = plan_footsteps(
        sc.grid,
        sc.start,
        sc.start_foot,
        sc.goal,
        t,
        PlannerOptions(heuristic="none", backend="python", time_limit=1e-3),
    )
    assert timed.status == PlanStatus.TIME_LIMIT
    assert timed.poses[0] == pytest.approx(list(sc.start))


def test_dynamic_plan_avoids_moving_block():
    # a block sweeps across the corridor; every landed foot must stay clear of it until it
    # lifts again (one step duration later)
    block = MovingRectObstacle([1.0, -0.3], [0.4, 0.3], [0.0, 0.25])
    env = DynamicEnvironment.from_moving_obstacles((2.0, 1.0), moving=[block], t_end=25.0, dt=0.1)
    t = nominal_action_table()
    plan = plan_footsteps(
        env,
        (0.3, 0.595, 0.0),
        "left",
        (1.7, 0.5),
        t,
        PlannerOptions(heuristic="euclidean", time_limit=30),
    )
    assert plan.succeeded
    follows_table(plan, t)
    for k in range(plan.num_steps + 1):
        for s in np.arange(plan.times[k], plan.times[k] + 0.8 + 1e-9, 0.1):
            grid = env.grids[env.nearest_index_unchecked(s)]
            assert not foot_collides_reference(grid, plan.poses[k], 0.16, 0.10)
    # ignoring the motion (planning on E(0) only) the plan walks straight into the block
    naive = plan_footsteps(env.grids[0], (0.3, 0.595, 0.0), "left", (1.7, 0.5), t)
    hits = [
        foot_collides_reference(env.at(naive.times[k]), naive.poses[k], 0.16, 0.10)
        for k in range(naive.num_steps + 1)
    ]
    assert any(hits)
    assert plan.times[-1] > naive.times[-1]  # the dynamic plan waits or detours


# ----------------------------------------------------------------------------- bad input


def test_bad_inputs_raise_clear_errors():
    grid = OccupancyGrid.from_rectangles((2.0, 2.0), [RectObstacle([1.0, 1.0], [0.4, 0.4])])
    t = nominal_action_table()
    ok = dict(start=(0.3, 0.3, 0.0), start_foot="left", goal=(1.7, 1.7), table=t)

    def call(**kw):
        args = {**ok, **kw}
        return plan_footsteps(
            grid,
            args["start"],
            args["start_foot"],
            args["goal"],
            args["table"],
            args.get("options"),
        )

    with pytest.raises(FootstepError, match=r"start \(2.500, 0.300\) lies outside the map"):
        call(start=(2.5, 0.3, 0.0))
    with pytest.raises(FootstepError, match="goal .* lies outside the map"):
        call(goal=(1.0, -0.2))
    # the map is [x0, x0 + width) x [y0, y0 + height): a goal on its far edge is outside
    with pytest.raises(
        FootstepError,
        match=r"goal \(2.000, 1.000\) lies outside the map \[0.0, 2.0\) x \[0.0, 2.0\) \(its far",
    ):
        call(goal=(2.0, 1.0))
    with pytest.raises(FootstepError, match="start foot .* overlaps an obstacle"):
        call(start=(1.0, 1.0, 0.0))
    with pytest.raises(FootstepError, match="start foot .* overlaps an obstacle or the map edge"):
        call(start=(0.02, 0.5, 0.0))
    with pytest.raises(FootstepError, match="initial swing foot"):
        call(start=(0.65, 1.0, math.pi / 2), start_foot="left")
    with pytest.raises(FootstepError, match="goal .* inside an obstacle"):
        call(goal=(1.05, 0.95))
    for bad in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(FootstepError, match="time_limit must be"):
            call(options=PlannerOptions(time_limit=bad))
    with pytest.raises(FootstepError, match="unknown heuristic"):
        call(options=PlannerOptions(heuristic="manhattan"))
    with pytest.raises(FootstepError, match="finite"):
        call(start=(math.nan, 0.3, 0.0))
    with pytest.raises(FootstepError, match="unknown foot"):
        call(start_foot="middle")
    with pytest.raises(FootstepError, match="ActionTable"):
        call(table={"forward": 0.3})
    with pytest.raises(FootstepError, match="OccupancyGrid or DynamicEnvironment"):
        plan_footsteps(np.zeros((10, 10)), (0.3, 0.3, 0), "left", (1.0, 1.0), t)
    env = DynamicEnvironment.from_moving_obstacles(
        (2.0, 2.0), moving=[MovingRectObstacle([1, 1], [0.2, 0.2], [0.1, 0])], t_end=2.0
    )
    with pytest.raises(FootstepError, match="'dijkstra' heuristic needs a static grid"):
        plan_footsteps(env, (0.3, 0.3, 0), "left", (1.7, 1.7), t)
    with pytest.raises(GridError, match="no grid near t = 10.000"):
        plan_footsteps(
            env,
            (0.3, 0.3, 0),
            "left",
            (1.7, 1.7),
            t,
            PlannerOptions(heuristic="euclidean", time_limit=30),
            start_time=10.0,
        )
    with pytest.raises(FootstepError, match="action_filter returned unknown actions"):
        plan_footsteps(
            grid, ok["start"], "left", ok["goal"], t, action_filter=lambda a2, a1, f: ["fly"]
        )


def test_action_filter_restricts_actions():
    g = OccupancyGrid.empty((2.0, 2.0))
    t = nominal_action_table()
    plan = plan_footsteps(
        g,
        (0.3, 1.0, 0.0),
        "left",
        (1.5, 1.0),
        t,
        action_filter=lambda a2, a1, f: ["forward_short", "stop"],
    )
    assert plan.succeeded and set(plan.actions) == {"forward_short"}
    assert plan.num_steps == 12


def test_metrics_closed_form():
    g = OccupancyGrid.from_rectangles((2.0, 2.0), [RectObstacle([0.75, 1.0], [0.05, 2.0])])
    plan = plan_footsteps(g, (0.3, 1.095, 0.0), "left", (1.5, 1.0), nominal_action_table())
    assert plan.succeeded
    segs = swing_segments(plan)
    assert segs[0][0] == pytest.approx(plan.initial_swing_pose)
    assert segs[1] == (plan.poses[0], plan.poses[2])
    assert steps_over_obstacles(g, plan) == 2  # each foot crosses the strip once
    counts = action_counts(plan)
    assert sum(counts.values()) == plan.num_steps
    # straight walk: the feet midpoints advance 0.15 m, then 0.3 m per step
    straight = plan_footsteps(
        OccupancyGrid.empty((2.0, 2.0)),
        (0.3, 1.095, 0.0),
        "left",
        (1.5, 1.0),
        nominal_action_table(),
    )
    assert body_path_length(straight) == pytest.approx(0.15 + 0.3 * (straight.num_steps - 1))


def test_height_cost_penalises_uneven_footholds():
    heights = np.zeros((80, 40))
    heights[40:, :] = 0.05  # a 5 cm step in the floor at x = 1.0 (not an obstacle)
    grid = OccupancyGrid(np.zeros((80, 40), bool), heights=heights)
    chk = FootprintChecker(grid, footprint_masks(0.16, 0.10, 0.025))
    assert chk.height_range(1.0, 0.5, 0.0) == pytest.approx(0.05)  # straddles the edge
    assert chk.height_range(0.8, 0.5, 0.0) == 0.0 and chk.height_range(1.2, 0.5, 0.0) == 0.0
    t = nominal_action_table()
    start, goal = (0.40, 0.595, 0.0), (1.75, 0.5)
    flat = plan_footsteps(grid, start, "left", goal, t)
    w = 40.0
    careful = plan_footsteps(
        grid, start, "left", goal, t, PlannerOptions(height_cost_weight=w, time_limit=30)
    )
    assert careful.succeeded
    ranges = [chk.height_range(*p) for p in careful.poses[1:]]
    steps = sum(t.step_cost[t.index(a)] for a in careful.actions)
    assert careful.cost == pytest.approx(steps + w * sum(ranges))
    assert sum(chk.height_range(*p) for p in flat.poses[1:]) > 0  # ignores the edge
    assert sum(ranges) == 0.0  # no foot straddles the edge when it costs


def test_start_in_goal_and_turning_around():
    g = OccupancyGrid.empty((2.0, 2.0))
    t = nominal_action_table()
    here = plan_footsteps(g, (1.0, 1.0, 0.0), "left", (1.05, 1.0), t)
    assert here.status == PlanStatus.SUCCESS and here.num_steps == 0 and here.cost == 0.0
    # facing away from the goal: turning steps of 0.35 rad first, then walking
    back = plan_footsteps(g, (1.0, 1.0, 3.0), "left", (1.9, 1.0), t)
    assert back.succeeded
    turns = sum(a in ("turn_left", "turn_right") for a in back.actions)
    assert turns >= math.ceil((3.0 - 0.6) / 0.35)
    follows_table(back, t)


def test_receding_horizon_reaches_goal_with_small_budgets():
    from repertoire.planning.footstep.receding import plan_receding_horizon
    from repertoire.planning.footstep.scenes import random_static_scene

    sc = random_static_scene(5)
    t = nominal_action_table()
    problem = (sc.grid, sc.start, sc.start_foot, sc.goal, t)
    small = PlannerOptions(max_expansions=40)
    one_shot = plan_footsteps(*problem, small)
    assert one_shot.status == PlanStatus.NODE_LIMIT  # one small budget is not enough
    res = plan_receding_horizon(*problem, small, execute_steps=3)
    assert res.plan.status == PlanStatus.SUCCESS and res.rounds > 1
    assert res.statuses[-1] == "SUCCESS" and res.statuses[0] == "NODE_LIMIT"
    follows_table(res.plan, t)  # histories carried across rounds
    assert res.plan.cost_to_go == 0.0
    assert all(not foot_collides_reference(sc.grid, p, 0.16, 0.10) for p in res.plan.poses)
    capped = plan_receding_horizon(*problem, small, max_rounds=1)
    assert capped.plan.status == PlanStatus.NODE_LIMIT and capped.plan.num_steps == 4
    assert 0 < capped.plan.cost_to_go
    with pytest.raises(FootstepError, match="execute_steps"):
        plan_receding_horizon(*problem, PlannerOptions(), execute_steps=0)
