"""Receding-horizon footstep planning: proved traps are never committed or entered again."""

import math

import pytest
from repertoire.planning.footstep import (
    DynamicEnvironment,
    FootstepError,
    MovingRectObstacle,
    PlannerOptions,
    PlanStatus,
    nominal_action_table,
    plan_footsteps,
)
from repertoire.planning.footstep.footprint import foot_collides_reference
from repertoire.planning.footstep.planner import plan_state
from repertoire.planning.footstep.receding import plan_receding_horizon
from repertoire.planning.footstep.scenes import random_static_scene


def _trap_after_one_step() -> tuple:
    """A 3 m floor where a 50-expansion round walks into a trap (two blocks of scene 204).

    The first round's partial plan turns right and walks forward_long three times; from its
    third step's end, (1.795, 0.881) at t = 2.4 s, the next round's partial plan is two
    forward_medium steps, and both their ends are traps (no step sequence escapes the block
    on waypoints).
    """
    moving = [
        MovingRectObstacle([1.587, 2.099], [0.155, 0.161], [-0.052, -0.324], yaw=-1.323),
        MovingRectObstacle(
            [0.0, 0.0], [0.408, 0.376], yaw=0.955,
            waypoints=[[0.0, 1.315, 2.391], [1.494, 0.693, 1.777], [5.527, 1.836, 1.289],
                       [10.29, 1.993, 1.998], [13.036, 1.722, 1.202]],
        ),
    ]  # fmt: skip
    env = DynamicEnvironment.from_moving_obstacles((3.0, 3.0), moving=moving, t_end=30.0)
    opts = PlannerOptions(heuristic="euclidean", max_expansions=50, time_limit=5.0)
    return env, (1.405, 0.3, math.pi / 2), "left", (1.5, 2.7), nominal_action_table(), opts


def _hits(env: DynamicEnvironment, plan, hold: float = 0.8) -> list:
    """(k, t) of every grid in which pose k overlaps an obstacle while it stands."""
    bad, n = [], len(plan.poses)
    for k in range(1, n):
        t0, t1 = plan.times[k], plan.times[k + 1] if k + 1 < n else plan.times[k] + hold
        for grid, tg in zip(env.grids, env.times):
            if t0 - env.max_time_gap - 1e-9 <= tg <= t1 + env.max_time_gap + 1e-9:
                if foot_collides_reference(grid, plan.poses[k], 0.16, 0.10):
                    bad.append((k, float(tg)))
    return bad


def test_plan_state_names_the_search_state_a_plan_stands_in():
    env, start, foot, goal, table, opts = _trap_after_one_step()
    plan = plan_footsteps(env, start, foot, goal, table, opts)
    assert plan.status is PlanStatus.NODE_LIMIT
    assert plan.actions == ["turn_right", "forward_long", "forward_long", "forward_long"]
    stop = table.index("stop")
    swing = plan.initial_swing_pose
    assert plan_state(plan, 0, table) == (*start, 0, stop, stop, 0.0, swing[0], swing[1])
    x, y, yaw = plan.poses[2]
    assert plan_state(plan, 2, table) == (
        x, y, yaw, 0, table.index("turn_right"), table.index("forward_long"), 1.6,
        plan.poses[1][0], plan.poses[1][1],
    )  # fmt: skip
    for bad in (-1, 5, 1.5, "1"):
        with pytest.raises(FootstepError, match=r"step index must be an integer in \[0, 4\]"):
            plan_state(plan, bad, table)


def test_plan_footsteps_never_enters_a_dead_end():
    args = _trap_after_one_step()
    table = args[4]
    first = plan_footsteps(*args)
    dead = plan_state(first, 1, table)  # the first step's end, turned right
    around = plan_footsteps(*args, dead_ends={dead})
    assert around.status is PlanStatus.NODE_LIMIT and around.nodes_expanded == 50
    assert dead not in {plan_state(around, i, table) for i in range(around.num_steps + 1)}
    assert around.actions[0] != "turn_right"
    # a dead end the search never meets changes nothing (on a static grid: the python core
    # instead of the compiled one, the same plan)
    sc = random_static_scene(3)
    problem = (sc.grid, sc.start, sc.start_foot, sc.goal, table, PlannerOptions())
    plain = plan_footsteps(*problem)
    far = plan_footsteps(*problem, dead_ends={(0.0,) * 9})
    assert plain.status is PlanStatus.SUCCESS and far.poses == plain.poses
    assert far.nodes_expanded == plain.nodes_expanded
    with pytest.raises(FootstepError, match="dead_ends must be a collection of states, got 'x'"):
        plan_footsteps(*problem, dead_ends="x")
    with pytest.raises(FootstepError, match=r"plan_state's form \(9 values\), got \(1.0, 2.0\)"):
        plan_footsteps(*problem, dead_ends=[(1.0, 2.0)])


def test_receding_horizon_plans_around_a_first_step_that_ends_in_a_trap():
    # Before: the round from (1.795, 0.881) at 2.4 s found both ends of its partial plan
    # proved traps, committed its first step all the same, and the joined plan ended
    # UNREACHABLE after 4 steps (statuses NODE_LIMIT, NODE_LIMIT, UNREACHABLE) although the
    # start has a plan. Now that round is planned again around the proved traps: the robot
    # steps in place while the block passes and walks on to the goal.
    args = _trap_after_one_step()
    res = plan_receding_horizon(*args, execute_steps=3)
    assert res.statuses == [
        "NODE_LIMIT", "NODE_LIMIT", "UNREACHABLE", "NODE_LIMIT", "UNREACHABLE", "UNREACHABLE",
        "NODE_LIMIT", "UNREACHABLE", "UNREACHABLE", "NODE_LIMIT", "NODE_LIMIT", "SUCCESS",
    ]  # fmt: skip
    plan = res.plan
    assert plan.status is PlanStatus.SUCCESS and plan.reason == "" and plan.num_steps == 15
    assert plan.actions[:7] == ["turn_right"] + ["forward_long"] * 2 + [
        "stop", "stop", "side_step", "stop",
    ]  # fmt: skip
    assert _hits(args[0], plan) == []
    table = args[4]
    assert plan.cost == pytest.approx(sum(table.step_cost[table.index(a)] for a in plan.actions))
    # every round's nodes count, those of the prefixes found to end in traps too
    assert plan.nodes_expanded > 50 * res.statuses.count("NODE_LIMIT")


def test_a_round_that_finds_no_step_thinks_longer():
    # the dynamic study's scene 5 at 100 expansions a round: from the fourth step's end the
    # second round's budget reaches no state nearer the goal (a row of blocks in front), so
    # its best partial plan is its own start; the run committed nothing more and ended
    # there (NODE_LIMIT after 2 calls, 4 steps). That round is now planned again with 200,
    # 400, ... expansions until it has a step, and the run reaches the goal.
    from repertoire.planning.footstep.scenes import strings_scene

    scene = strings_scene(
        5, speeds=(0.18, 0.12), spacings=(0.9, 1.0), block_size=(0.5, 0.2), t_end=40.0, dt=0.1
    )
    opts = PlannerOptions(heuristic="euclidean", heuristic_weight=1.5, max_expansions=100,
                          time_limit=60.0, swing_clearance=0.10)  # fmt: skip
    args = (scene.env, scene.start, scene.start_foot, scene.goal, nominal_action_table(), opts)
    stuck = plan_receding_horizon(*args, max_rounds=2)
    assert stuck.statuses == ["NODE_LIMIT", "NODE_LIMIT"] and stuck.plan.num_steps == 4
    res = plan_receding_horizon(*args, max_rounds=60)
    assert res.plan.status is PlanStatus.SUCCESS and res.plan.num_steps == 22
    assert res.statuses == ["NODE_LIMIT"] * 5 + ["SUCCESS"]
    # the second call found no step; the third (200 expansions) found ten, four committed
    second = plan_footsteps(
        scene.env, res.plan.poses[4], res.plan.feet[4], scene.goal, nominal_action_table(),
        opts, initial_swing_pose=res.plan.poses[3], start_time=res.plan.times[4],
        initial_history=res.plan.actions[2:4],
    )  # fmt: skip
    assert second.status is PlanStatus.NODE_LIMIT and second.num_steps == 0
    assert res.plan.actions[4:8] == ["side_step", "turn_left", "side_step", "turn_left"]
    assert _hits(scene.env, res.plan) == []
