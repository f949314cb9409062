"""Dynamic worlds: how long a landed foot stands, and why a plan is UNREACHABLE."""

import math

import numpy as np
import pytest
from repertoire.planning.footstep import (
    ActionTable,
    DynamicEnvironment,
    MovingRectObstacle,
    PlannerOptions,
    PlanStatus,
    nominal_action_table,
    plan_footsteps,
)
from repertoire.planning.footstep.biped_model import BipedStepModel
from repertoire.planning.footstep.footprint import foot_collides_reference
from repertoire.planning.footstep.types import FootstepError

FOOT = (0.16, 0.10)  # the nominal (ASIMO-like) sole
START = (1.405, 0.4, math.pi / 2)  # left foot, facing +y; the right one beside it at x 1.595
GOAL = (1.5, 2.6)


def _table(slow: tuple[str, ...], seconds: float = 1.6) -> ActionTable:
    """The nominal table (0.8 s steps) with the ``slow`` actions taking ``seconds``."""
    t = nominal_action_table()
    duration = t.duration.copy()
    duration[..., [t.index(a) for a in slow]] = seconds
    return ActionTable(t.actions, t.displacement, duration, t.step_cost, t.rest_action, t.mirror)


def _gate() -> DynamicEnvironment:
    """A 3 m x 0.3 m gate that slides across the floor into y in [0.55, 0.85] during
    [1.7, 1.75] s and stays: every grid from 1.7 s on blocks the band, none before."""
    gate = MovingRectObstacle([0, 0], [3.0, 0.3], waypoints=[[1.7, -2.0, 0.7], [1.75, 1.5, 0.7]])
    return DynamicEnvironment.from_moving_obstacles((3.0, 3.0), moving=[gate], t_end=20.0)


def _hits_while_standing(env: DynamicEnvironment, plan) -> list[tuple[int, float]]:
    """(k, grid time) of every grid standing for a time in [times[k], times[k + 1]] in
    which pose k overlaps an obstacle (the last pose: up to the grids' end)."""
    bad = []
    for k, pose in enumerate(plan.poses):
        t0 = plan.times[k]
        t1 = plan.times[k + 1] if k + 1 < len(plan.times) else env.times[-1]
        for grid, tg in zip(env.grids, env.times, strict=True):
            near = t0 - env.max_time_gap - 1e-9 <= tg <= t1 + env.max_time_gap + 1e-9
            if near and foot_collides_reference(grid, pose, *FOOT):
                bad.append((k, float(tg)))
    return bad


def test_a_landing_is_checked_for_as_long_as_the_foot_really_stands():
    # forward steps take 0.8 s, side steps and turns 1.6 s. The right foot's first landing,
    # (1.595, 0.7) at 0.8 s, stands until the next step lands: 1.6 s after a forward step,
    # before the gate closes on it (1.7 s). It was checked over the table's longest step
    # (0.8 + 1.6 = 2.4 s) and refused, like every landing in the band: UNREACHABLE.
    env = _gate()
    assert [bool(g.occupied.any()) for g in env.grids[15:19]] == [False, False, True, True]
    table = _table(("side_step", "turn_left", "turn_right"))
    opts = PlannerOptions(heuristic="euclidean", max_expansions=20000, time_limit=20.0)
    plan = plan_footsteps(env, START, "left", GOAL, table, opts)
    assert plan.status is PlanStatus.SUCCESS and plan.actions == ["forward_long"] * 7
    assert plan.times[:3] == [0.0, 0.8, 1.6] and plan.poses[1] == [1.595, 0.7, math.pi / 2]
    assert _hits_while_standing(env, plan) == []
    # from that landing only the 0.8 s step lifts the foot in time (and lands clear of the
    # band): the 1.6 s steps would keep it standing into the gate
    model = BipedStepModel(env, START, "left", GOAL, table, opts)
    first = next(s for s, _ in model.successors(model.start()) if s.y == 0.7 and s.x == 1.595)
    assert first.t == 0.8
    assert [table.actions[s.a_prev1] for s, _ in model.successors(first)] == ["forward_long"]
    # sound: when every step takes 1.6 s no foot leaves the band before the gate closes
    slow = _table(tuple(table.actions))
    stuck = plan_footsteps(env, START, "left", GOAL, slow, opts)
    assert stuck.status is PlanStatus.UNREACHABLE
    assert np.all(np.asarray(stuck.poses)[:, 1] < 0.5)


def test_unreachable_past_the_grids_says_the_horizon_is_too_short():
    # 1.8 m straight ahead by forward_long steps only: 6 steps of 0.8 s (4.8 s); the grids
    # end at 2.0 s, so the third step (landing at 2.4 s) is dropped, the only one
    env = DynamicEnvironment.from_moving_obstacles((3.0, 3.0), moving=[], t_end=2.0)
    table = nominal_action_table()
    opts = PlannerOptions(heuristic="euclidean", max_expansions=3000)
    only_long = {"action_filter": lambda a2, a1, foot: ["forward_long"]}
    args = (env, (0.5, 1.5, 0.0), "left", (2.3, 1.5), table, opts)
    plan = plan_footsteps(*args, **only_long)
    assert plan.status is PlanStatus.UNREACHABLE and plan.times == [0.0, 0.8, 1.6]
    assert [p[0] for p in plan.poses] == pytest.approx([0.5, 0.8, 1.1])
    assert plan.reason == (
        "1 landing past the environment's last grid (t = 2.000 s, standing for times up to "
        "2.050 s) dropped: extend t_end (the planning horizon) to plan further"
    )
    # every action: each of the 7 x 7 = 49 states of 1.6 s drops its 7 landings (2.4 s)
    model = BipedStepModel(*args)
    seconds = [s for f, _ in model.successors(model.start()) for s, _ in model.successors(f)]
    assert len(seconds) == 49 and {s.t for s in seconds} == {1.6}
    assert all(list(model.successors(s)) == [] for s in seconds) and model.past_grids == 343
    longer = DynamicEnvironment.from_moving_obstacles((3.0, 3.0), moving=[], t_end=8.0)
    done = plan_footsteps(longer, *args[1:], **only_long)
    assert done.status is PlanStatus.SUCCESS and done.reason == "" and done.num_steps == 6


def test_unreachable_between_grids_says_no_grid_stands_for_the_landing_times():
    # grids every 0.8 s standing for 0.05 s either side: 0.4 s steps land between them
    grid = DynamicEnvironment.from_moving_obstacles((3.0, 3.0), moving=[], t_end=0.0).grids[0]
    env = DynamicEnvironment(np.arange(5) * 0.8, [grid] * 5, max_time_gap=0.05)
    quick = nominal_action_table(step_duration=0.4)
    opts = PlannerOptions(heuristic="euclidean", max_expansions=3000)
    only_long = {"action_filter": lambda a2, a1, foot: ["forward_long"]}
    plan = plan_footsteps(env, (0.5, 1.5, 0.0), "left", (2.3, 1.5), quick, opts, **only_long)
    assert plan.status is PlanStatus.UNREACHABLE and plan.num_steps == 0
    assert plan.reason == (
        "1 landing between grid times, more than max_time_gap = 0.050 s from every grid, "
        "dropped: add grids there or widen max_time_gap"
    )


def test_receding_horizon_passes_the_last_rounds_reason_on():
    from repertoire.planning.footstep.receding import plan_receding_horizon

    env = DynamicEnvironment.from_moving_obstacles((3.0, 3.0), moving=[], t_end=2.0)
    table = nominal_action_table()
    opts = PlannerOptions(heuristic="euclidean", max_expansions=3000, refinements=0)
    args = (env, (0.5, 1.5, 0.0), "left", (2.3, 1.5), table, opts)
    alone = plan_footsteps(*args)
    assert alone.status is PlanStatus.UNREACHABLE and "past the environment's" in alone.reason
    res = plan_receding_horizon(*args, max_rounds=1)
    assert res.statuses == ["UNREACHABLE"] and res.plan.reason == alone.reason


def _parked_on_the_goal(t_park: float) -> DynamicEnvironment:
    """A 0.4 m block that slides onto (3.0, 1.5) by ``t_park`` and stays there."""
    block = MovingRectObstacle([0, 0], [0.4, 0.4], waypoints=[[0, 3.0, -1.0], [t_park, 3.0, 1.5]])
    return DynamicEnvironment.from_moving_obstacles((4.0, 3.0), moving=[block], t_end=20.0)


def test_a_goal_covered_before_the_robot_can_get_there_is_unreachable_at_once():
    # From (0.5, 1.405) the goal is 2.5018 m away: the stance foot moves at most 0.3551 m a
    # step (the nominal table's reach) and comes within 0.15 m after ceil(6.62) = 7 steps of
    # 0.8 s, at 5.6 s; the block covers every sole within 0.15 m of the goal from 3 s on.
    # Before: no plan and no proof, TIME_LIMIT after the whole limit (331k expansions in 60 s).
    table = nominal_action_table()
    opts = PlannerOptions(heuristic="euclidean", time_limit=2.0)
    args = ((0.5, 1.405, 0.0), "right", (3.0, 1.5), table, opts)
    plan = plan_footsteps(_parked_on_the_goal(3.0), *args)
    assert plan.status is PlanStatus.UNREACHABLE
    assert plan.nodes_expanded == 1 and plan.num_steps == 0
    assert plan.reason == (
        "goal (3.000, 1.500): the stance foot cannot come within goal_tolerance 0.15 m of it "
        "before t = 5.600 s (7 steps of at least 0.8 s, each at most 0.355 m), and no foot fits "
        "there in any grid of E(t) from then on (up to 20.000 s): an obstacle covers it"
    )
    # parked later than the robot can arrive: planned, landing on the goal before the block
    late = plan_footsteps(_parked_on_the_goal(12.0), *args)
    assert late.status is PlanStatus.SUCCESS and late.reason == "" and late.times[-1] < 11.0
    # the receding planner stops at once too
    from repertoire.planning.footstep.receding import plan_receding_horizon

    res = plan_receding_horizon(_parked_on_the_goal(3.0), *args)
    assert res.statuses == ["UNREACHABLE"] and res.plan.reason == plan.reason


def test_a_goal_no_sole_fits_at_any_time_is_refused_by_name():
    # the goal's cell is a free slit one cell (2.5 cm) wide between two blocks that stay;
    # before, dynamic worlds skipped this test of the goal and the search ran to its limit
    walls = [
        MovingRectObstacle([2.9, 1.5], [0.2, 0.6]),
        MovingRectObstacle([3.125, 1.5], [0.2, 0.6]),
    ]
    env = DynamicEnvironment.from_moving_obstacles((4.0, 3.0), moving=walls, t_end=20.0)
    opts = PlannerOptions(heuristic="euclidean", time_limit=2.0, goal_tolerance=0.05)
    table = nominal_action_table()
    assert not env.grids[0].occupied[env.reference.cell_of(3.0125, 1.5)]
    with pytest.raises(FootstepError, match=r"goal \(3.013, 1.500\): no foot fits within "
                       r"goal_tolerance 0.05 m of it in any grid of E\(t\)"):  # fmt: skip
        plan_footsteps(env, (0.5, 1.405, 0.0), "right", (3.0125, 1.5), table, opts)


def test_the_robot_stands_free_on_both_feet_after_the_last_step():
    # Without obstacles the plan is 4 long steps, the last at 3.2 s onto (1.405, 1.6); the
    # right foot stays at (1.595, 1.3). A 0.2 m block moving +x along y = 1.3 reaches it at
    # 3.5 s. Before, only the landing foot was checked after the last step (the trailing
    # one until that landing): the plan ended there and the block ran into the standing
    # robot 0.3 s after it arrived. Now both feet stand free as long as any landing is held
    # (the table's shortest step, 0.8 s): one more step lifts the right foot clear.
    table = nominal_action_table()
    opts = PlannerOptions(heuristic="euclidean", max_expansions=20000, time_limit=10.0)
    args = ((1.405, 0.4, math.pi / 2), "left", (1.5, 1.6), table, opts)
    free = DynamicEnvironment.from_moving_obstacles((3.0, 3.0), moving=[], t_end=20.0)
    alone = plan_footsteps(free, *args)
    assert alone.actions == ["forward_long"] * 4 and alone.times[-1] == pytest.approx(3.2)
    block = MovingRectObstacle([1.595 - 0.18 - 0.5 * 3.5, 1.3], [0.2, 0.2], [0.5, 0.0])
    env = DynamicEnvironment.from_moving_obstacles((3.0, 3.0), moving=[block], t_end=20.0)
    assert foot_collides_reference(env.at(3.5), (1.595, 1.3, math.pi / 2), *FOOT)
    plan = plan_footsteps(env, *args)
    assert plan.status is PlanStatus.SUCCESS
    assert plan.actions == ["forward_long"] * 4 + ["forward_short"]
    assert [round(v, 3) for v in plan.poses[-1][:2]] == [1.595, 1.7]
    assert plan.times[-1] == pytest.approx(4.0)
    for pose in plan.poses[-2:]:  # both feet free while the robot stands after arriving
        for grid, tg in zip(env.grids, env.times):
            if plan.times[-1] - 0.05 <= tg <= plan.times[-1] + 0.8 + 0.05:
                assert not foot_collides_reference(grid, pose, *FOOT), (pose, tg)
