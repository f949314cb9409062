"""Footstep planning in dynamic worlds E(t): start checks, replanning, statuses."""

import math

import numpy as np
import pytest
from repertoire.planning.footstep import (
    DynamicEnvironment,
    FootstepError,
    FootstepPlan,
    GridError,
    MovingRectObstacle,
    OccupancyGrid,
    PlannerOptions,
    PlanStatus,
    RectObstacle,
    nominal_action_table,
    plan_footsteps,
)
from repertoire.planning.footstep.footprint import foot_collides_reference
from repertoire.planning.footstep.receding import plan_receding_horizon

FOOT = (0.16, 0.10)  # the nominal (ASIMO-like) sole


def _stands_free(env, plan, hold=0.8):
    """(k, t) of every grid in which pose k overlaps an obstacle while it stands."""
    bad = []
    n = len(plan.poses)
    for k in range(1, n):
        t0 = plan.times[k]
        t1 = plan.times[k + 1] if k + 1 < n else t0 + hold
        for grid, tg in zip(env.grids, env.times):
            if t0 - env.max_time_gap - 1e-9 <= tg <= t1 + env.max_time_gap + 1e-9:
                if foot_collides_reference(grid, plan.poses[k], *FOOT):
                    bad.append((k, float(tg)))
    return bad


def _sweeper(t_arrive: float) -> DynamicEnvironment:
    """A 0.2 m block moving +x at 0.5 m/s along y = 0.7 that reaches the right sole at
    (1.595, 0.7) (x from 1.545) at ``t_arrive``."""
    x0 = 1.545 - 0.1 - 0.5 * t_arrive
    block = MovingRectObstacle([x0, 0.7], [0.2, 0.2], [0.5, 0.0])
    return DynamicEnvironment.from_moving_obstacles((3.0, 3.0), moving=[block], t_end=40.0)


def test_initial_swing_foot_needs_only_be_free_when_it_lifts():
    # the swing foot lifts at the start time: a block arriving there 0.5 s later is no error
    env = _sweeper(0.5)
    assert not foot_collides_reference(env.at(0.0), (1.595, 0.7, math.pi / 2), *FOOT)
    assert foot_collides_reference(env.at(0.5), (1.595, 0.7, math.pi / 2), *FOOT)
    t = nominal_action_table()
    opts = PlannerOptions(heuristic="euclidean", max_expansions=3000, time_limit=10.0)
    plan = plan_footsteps(
        env, (1.405, 1.0, math.pi / 2), "left", (1.5, 2.6), t, opts,
        initial_swing_pose=(1.595, 0.7, math.pi / 2),
    )  # fmt: skip
    assert plan.status is PlanStatus.SUCCESS and _stands_free(env, plan) == []
    # occupied at the start time itself: still the clear error, naming the time
    with pytest.raises(FootstepError, match=r"initial swing foot at \(1.595, 0.700\).*t = 0.600"):
        plan_footsteps(
            env, (1.405, 1.0, math.pi / 2), "left", (1.5, 2.6), t, opts,
            initial_swing_pose=(1.595, 0.7, math.pi / 2), start_time=0.6,
        )  # fmt: skip


def test_receding_horizon_survives_a_block_crossing_behind_the_robot():
    # the block crosses y = 0.7 at t = 2.0 s, after the right foot that landed there at 0.8 s
    # lifted at 1.6 s; the round that starts at 1.6 s has that foot as its swing foot
    env = _sweeper(2.0)
    t = nominal_action_table()
    opts = PlannerOptions(heuristic="euclidean", max_expansions=3, time_limit=10.0)
    one = plan_footsteps(env, (1.405, 0.4, math.pi / 2), "left", (1.5, 2.6), t, opts)
    assert one.status is PlanStatus.NODE_LIMIT
    assert [round(p[1], 3) for p in one.poses] == [0.4, 0.7, 1.0]
    for steps in (1, 2):
        res = plan_receding_horizon(
            env, (1.405, 0.4, math.pi / 2), "left", (1.5, 2.6), t, opts, execute_steps=steps
        )
        assert res.plan.status is PlanStatus.SUCCESS and res.rounds > 1
        assert _stands_free(env, res.plan) == []


def test_time_bins_never_collide_with_other_states():
    # the time bin was added as k * 1e6 + bin: with 1e-7 s bins (one history class) the
    # other foot at t collided with this one 0.1 s later; bins now span the grids' times
    from repertoire.planning.footstep.biped_model import BipedStepModel

    block = MovingRectObstacle([0.5, 2.5], [0.2, 0.2], [0.1, 0.0])
    env = DynamicEnvironment.from_moving_obstacles((3.0, 3.0), moving=[block], t_end=20.0)
    shifted = DynamicEnvironment(env.times - 10.0, env.grids, env.max_time_gap)  # t in [-10, 10]
    t = nominal_action_table()
    for world, t0 in ((env, 3.0), (shifted, -7.0)):
        for tq in (0.1, 1e-7):
            opts = PlannerOptions(heuristic="euclidean", time_resolution=tq)
            model = BipedStepModel(world, (1.0, 1.0, 0.0), "left", (2.0, 1.0), t, opts)
            assert model.n_hist == 1

            def key(foot, time, model=model):
                return model.lattice_key(1.0, 1.0, 0.0, foot, 0, time)

            times = [t0 + k * 0.1 for k in range(-20, 21)] + [t0 + tq / 4]
            keys = {(f, round(x / tq)): key(f, x) for f in (0, 1) for x in times}
            assert len(set(keys.values())) == len(keys)  # one key per state and time bin
            assert key(0, t0 + tq / 4) == key(0, t0)  # within half a bin: the same state


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda g: DynamicEnvironment([0.0, 2.0, 1.0], [g] * 3, 0.5),
         r"strictly increasing, got 2.0 then 1.0 at indices 1, 2"),
        (lambda g: DynamicEnvironment([0.0, math.nan], [g] * 2, 0.5),
         r"finite, got nan at index 1"),
        (lambda g: DynamicEnvironment([[0.0, 1.0]], [g] * 2, 0.5), r"1-D .* shape \(1, 2\)"),
        (lambda g: DynamicEnvironment(["a", "b"], [g] * 2, 0.5), r"times must be numbers"),
        (lambda g: DynamicEnvironment([0.0, 1.0], [g, np.zeros((8, 8))], 0.5),
         r"grid 1 must be an OccupancyGrid, got ndarray"),
        (lambda g: DynamicEnvironment([0.0, 1.0], iter([g, g]), 0.5), r"grids must be a list"),
        (lambda g: DynamicEnvironment([0.0, 1.0], [g, g], "1"), r"max_time_gap .* got '1'"),
        (lambda g: DynamicEnvironment([0.0, 1.0], [g, _with_heights(g)], 0.5),
         r"grid 1 has heights but grid 0 has none"),
        (lambda g: DynamicEnvironment([0.0, 1.0], [_with_heights(g), g], 0.5),
         r"grid 1 has no heights but grid 0 has"),
        (lambda g: DynamicEnvironment([0.0], [g], 0.5).at("0"), r"time must be .* got '0'"),
        (lambda g: _from_moving(moving=[RectObstacle([0.5, 0.5], [0.2, 0.2])]),
         r"moving\[0\] must be a MovingRectObstacle, got RectObstacle"),
        (lambda g: _from_moving(static=[MovingRectObstacle([0.5, 0.5], [0.2, 0.2])]),
         r"static\[0\] must be a RectObstacle, got MovingRectObstacle"),
        (lambda g: _from_moving(moving=None), r"moving must be a list of MovingRectObstacle"),
        (lambda g: _from_moving(t_end="5"), r"t_end must be .* got '5'"),
        (lambda g: _from_moving(dt="0.1"), r"dt must be .* got '0.1'"),
        (lambda g: MovingRectObstacle([0, 0], [0.1, 0.1], waypoints=[["a", 0, 1]]),
         r"waypoints must be finite \[t, x, y\] rows"),
    ],
)  # fmt: skip
def test_dynamic_bad_inputs_are_named(make, message):
    with pytest.raises(GridError, match=message):
        make(OccupancyGrid.empty((1.0, 1.0)))


def _with_heights(g):
    return OccupancyGrid(g.occupied, g.resolution, g.origin, np.zeros(g.shape))


def _from_moving(**kw):
    args = {"moving": [], "t_end": 1.0, **kw}
    return DynamicEnvironment.from_moving_obstacles((1.0, 1.0), **args)


def test_obstacles_accept_numpy_numbers_and_generators():
    # numpy scalars (np.float32 too) are numbers; a generator of moving obstacles is read
    # once, not exhausted by the first grid
    yaw, height = np.float32(0.5), np.float32(0.1)
    m = MovingRectObstacle([0.2, 0.5], [0.2, 0.2], [0.5, 0.0], yaw=yaw, height=height)
    env = DynamicEnvironment.from_moving_obstacles(
        (1.0, 1.0), moving=(x for x in [m]), t_end=1.0, dt=0.5
    )
    assert [g.occupied.any() for g in env.grids] == [True, True, True]
    assert env.at(1.0).occupied[28, 20] and not env.at(0.0).occupied[28, 20]  # x 0.7 at 1 s


@pytest.mark.parametrize("speeds", [(0.18, 0.12), (-0.18, 0.12), (-0.4, -0.3), (0.0, 0.0)])
def test_strings_span_the_floor_whichever_way_the_rows_move(speeds):
    # with a row moving along -x the string covered half the floor and blocks were missing
    from repertoire.planning.footstep.scenes import strings_scene

    sc = strings_scene(11, speeds=speeds, t_end=15.0, dt=0.5)
    for g in sc.env.grids:
        for y in sc.rows_y:
            assert g.occupied[:, g.cell_of(1.5, y)[1]].all()  # the string, x = 0 .. 3 m
        # the blocks (2 cm tall, 20 cm deep) along row 1: 0.3 m of every 0.9 m, each grid
        # marking what a block sweeps over its 0.5 s (|v| 0.5 m more), with whole cells and
        # partial blocks at the floor's ends: about (0.3 + 0.5 |v|) / 0.9 of the row
        blocks = g.heights[:, g.cell_of(1.5, sc.rows_y[0] + 0.08)[1]] > 0.01
        share = (0.3 + 0.5 * abs(speeds[0])) / 0.9
        assert share - 0.06 <= blocks.mean() <= share + 0.1


@pytest.mark.parametrize(
    ("kw", "message"),
    [
        ({"spacings": (0.0, 1.2)}, r"spacings\[0\] must be a positive number .* got 0.0"),
        ({"speeds": (0.18, math.nan)}, r"speeds\[1\] must be a finite number .* got nan"),
        ({"speeds": (0.18,)}, r"one value per row, got 2, 1 and 2"),
    ],
)
def test_strings_scene_bad_rows_are_named(kw, message):
    from repertoire.planning.footstep.scenes import strings_scene

    with pytest.raises(GridError, match=message):
        strings_scene(0, t_end=2.0, **kw)


def _start_actions(env, clearance):
    from repertoire.planning.footstep.biped_model import BipedStepModel

    t = nominal_action_table()
    opts = PlannerOptions(heuristic="euclidean", swing_clearance=clearance)
    model = BipedStepModel(env, (1.405, 0.4, math.pi / 2), "left", (1.5, 2.6), t, opts)
    return sorted(t.actions[s.a_prev1] for s, _ in model.successors(model.start()))


@pytest.mark.parametrize(
    ("t_cross", "refused"),
    [(0.4, ["forward_long", "forward_medium"]), (1.2, [])],
)
def test_swing_line_is_checked_against_tall_cells_while_the_foot_swings(t_cross, refused):
    # a 30 cm tall bar along y = 0.55 (between the feet) moves +x at 1 m/s and crosses the
    # right foot's line x = 1.595 at t_cross; the first step swings that foot from y = 0.4
    # during [0, 0.8] s (forward_long / medium land at y = 0.7 / 0.6 and cross y = 0.55).
    # The swing was checked against the cells tall at the landing and the next 0.8 s
    # instead: a bar crossing mid-swing (0.4 s) was missed, one crossing after the landing
    # (1.2 s, both feet clear of it) refused the step.
    bar = MovingRectObstacle([1.595 - t_cross, 0.55], [0.1, 0.05], [1.0, 0.0], height=0.3)
    env = DynamicEnvironment.from_moving_obstacles(
        (3.0, 3.0), moving=[bar], t_end=20.0, with_heights=True
    )
    every = _start_actions(env, math.inf)  # no swing limit: the feet's own checks only
    assert "forward_long" in every and set(refused) <= set(every)
    assert _start_actions(env, 0.05) == sorted(set(every) - set(refused))


def test_start_foot_hit_while_it_stands_is_unreachable_with_the_reason():
    # free at t = 0, reached by the block at 0.5 s, before the first step can land (0.8 s):
    # no plan from this start (was a FootstepError, as for a bad input); the grid of 0.5 s
    # is the first to mark the sole (x from 1.545), the block's front at 1.52 m at 0.45 s
    env = _sweeper(0.5)
    t = nominal_action_table()
    opts = PlannerOptions(heuristic="euclidean")
    start = (1.595, 0.7, math.pi / 2)
    plan = plan_footsteps(env, start, "right", (1.5, 2.6), t, opts)
    assert plan.status is PlanStatus.UNREACHABLE and plan.poses == [list(start)]
    assert plan.reason == (
        "the start foot at (1.595, 0.700, 1.571) stands until the first step lands and is hit "
        "by an obstacle at t = 0.500 s (the grid standing for [0.450, 0.550] s): steps landing "
        "later were dropped, and no earlier one lands free"
    )
    assert FootstepPlan.from_dict(plan.to_dict()).reason == plan.reason
    # steps of 0.4 s lift the foot before the block arrives: a plan, no reason given
    quick = nominal_action_table(step_duration=0.4)
    plan = plan_footsteps(env, start, "right", (1.5, 2.6), quick, opts)
    assert plan.status is PlanStatus.SUCCESS and plan.times[1] == 0.4 and plan.reason == ""
    assert _stands_free(env, plan, hold=0.4) == []
    # occupied at the start time itself: a bad input, the clear error naming the time
    with pytest.raises(
        FootstepError,
        match=r"start foot at \(1.595, 0.700, 1.571\) overlaps an obstacle .* at t = 0.500 s",
    ):
        plan_footsteps(env, start, "right", (1.5, 2.6), t, opts, start_time=0.5)


def test_receding_horizon_takes_default_options_when_the_goal_is_not_reached():
    # options=None (the defaults, as plan_footsteps takes) crashed in dataclasses.replace
    # when the goal was not reached (the cost-to-go estimate at the last committed pose)
    wall = OccupancyGrid.from_rectangles((3.0, 3.0), [RectObstacle([2.0, 1.5], [0.6, 3.0])])
    t = nominal_action_table()
    res = plan_receding_horizon(wall, (0.5, 1.5, 0.0), "left", (2.7, 1.5), t, None, max_rounds=1)
    assert res.statuses == ["UNREACHABLE"] and res.plan.status is PlanStatus.UNREACHABLE
    assert res.plan.cost_to_go > 0
    with pytest.raises(FootstepError, match="options must be PlannerOptions, got dict"):
        plan_receding_horizon(wall, (0.5, 1.5, 0.0), "left", (2.7, 1.5), t, {})


def test_mobile2d_inflation_is_exact_at_cell_corners():
    # one occupied cell (20, 20) of 2.5 cm; a 9 cm disc centred on cell (23, 23) reaches its
    # corner: distance 0.025 * hypot(2.5, 2.5) = 0.0884 m < 0.09. The inflation measured
    # centre to centre minus half a cell (0.025 * (hypot(3, 3) - 0.5) = 0.0936 m) and left
    # the cell free.
    from repertoire.planning.footstep.mobile2d import inflate

    occ = np.zeros((41, 41), bool)
    occ[20, 20] = True
    g = OccupancyGrid(occ, 0.025)
    b = inflate(g, 0.09)
    assert b[23, 23] and b[20, 24] and b[20, 16] and not b[20, 25] and not b[24, 23]
    assert not inflate(g, 0.088)[23, 23] and inflate(g, 0.0)[20, 20]
    assert inflate(g, 0.0).sum() == 1
    assert b[3, 20] and not b[4, 20]  # the border: 3.5 cells from cell 3's centre to x = 0


def test_per_time_caches_stay_within_their_memory_bound(monkeypatch):
    # Each time index of a dynamic world has its own footprint checker and swing masks;
    # kept without bound they grew ~145 MB on an 8 m map with a 60 s horizon. They are
    # least-recently-used caches of CACHE_BYTES: with a bound of three checkers the plan is
    # the same as with every checker kept, and the caches never hold more than the bound.
    import repertoire.planning.footstep.biped_model as bm

    env = _sweeper(2.0)
    t = nominal_action_table()
    opts = PlannerOptions(heuristic="euclidean", max_expansions=3000, time_limit=30.0)
    args = (env, (1.405, 1.0, math.pi / 2), "left", (1.5, 2.6), t, opts)
    kept = plan_footsteps(*args, initial_swing_pose=(1.595, 1.0, math.pi / 2))
    grid = env.reference
    masks = bm.sole_masks(bm.ASIMO_LIKE, opts.footprint_margin_m, grid.resolution)
    pad = masks.radius_cells + 1
    one = (grid.shape[0] + 2 * pad) * (grid.shape[1] + 2 * pad) * 3  # no heights here
    seen = []
    real_put = bm._LruCache.put

    def put(self, key, value, nbytes):
        real_put(self, key, value, nbytes)
        seen.append(self.bytes)
        assert self.bytes <= self.max_bytes

    monkeypatch.setattr(bm, "CACHE_BYTES", 3 * one)
    monkeypatch.setattr(bm._LruCache.__init__, "__defaults__", (3 * one,))
    monkeypatch.setattr(bm._LruCache, "put", put)
    bounded = plan_footsteps(*args, initial_swing_pose=(1.595, 1.0, math.pi / 2))
    assert bounded.poses == kept.poses and bounded.cost == kept.cost
    assert bounded.status is PlanStatus.SUCCESS
    assert len(seen) > 3 and max(seen) <= 3 * one  # more checkers were built than kept


def test_lru_cache_evicts_the_least_recently_used_first():
    from repertoire.planning.footstep.biped_model import _LruCache

    c = _LruCache(max_bytes=30)
    for k in range(3):
        c.put(k, f"v{k}", 10)
    assert c.get(0) == "v0"  # 0 is now the most recently used
    c.put(3, "v3", 10)  # over 30 bytes: 1 goes, the least recently used
    assert 1 not in c and [k in c for k in (0, 2, 3)] == [True, True, True]
    assert c.bytes == 30 and len(c) == 3
    c.put(4, None, 25)  # a stored None is a value, not a miss
    assert 4 in c and c.get(4) is None and c.bytes <= 30
    big = _LruCache(max_bytes=5)
    big.put("a", 1, 100)  # a single entry over the bound is still kept (one at least)
    assert big.get("a") == 1


def _trap_after_two_steps() -> tuple:
    """A 3 m floor where a 300-expansion plan walks 2 steps into a trap (seed-202 scene).

    The partial plan ends at (1.405, 0.9) at t = 1.6 s; a block on waypoints sweeps across
    there at 3.2-4.3 s, and from that state no step sequence escapes it.
    """
    moving = [
        MovingRectObstacle([0.978, 1.668], [0.572, 0.383], [0.181, -0.127], yaw=-0.983),
        MovingRectObstacle(
            [0.0, 0.0], [0.415, 0.137], yaw=-0.954,
            waypoints=[[0.0, 0.892, 2.375], [3.211, 0.404, 0.802], [4.29, 1.508, 0.943],
                       [5.43, 0.532, 1.639], [8.961, 0.817, 2.264]],
        ),
    ]  # fmt: skip
    env = DynamicEnvironment.from_moving_obstacles((3.0, 3.0), moving=moving, t_end=30.0)
    opts = PlannerOptions(heuristic="euclidean", max_expansions=300, time_limit=5.0)
    return env, (1.405, 0.3, math.pi / 2), "left", (1.5, 2.7), nominal_action_table(), opts


def test_receding_horizon_does_not_commit_a_partial_plan_into_a_trap():
    # Before: both steps of the first round's partial plan were committed, the next round
    # found no step from there (UNREACHABLE, no reason), and the joined plan said
    # UNREACHABLE although the goal is reachable from the start (12 steps with a larger
    # budget). Now the proved trap is not committed: the robot takes one step, waits in
    # place (stop) while the block passes, and walks on.
    args = _trap_after_two_steps()
    first = plan_footsteps(*args)
    assert first.status is PlanStatus.NODE_LIMIT and first.actions == ["forward_long"] * 2
    assert [round(p[1], 3) for p in first.poses] == [0.3, 0.6, 0.9]
    res = plan_receding_horizon(*args, execute_steps=3)
    assert res.statuses == ["NODE_LIMIT", "UNREACHABLE", "SUCCESS"] and res.rounds == 3
    plan = res.plan
    assert plan.status is PlanStatus.SUCCESS and plan.reason == ""
    assert plan.num_steps == 13 and plan.actions[:6] == ["forward_long"] + ["stop"] * 4 + [
        "forward_medium"
    ]
    assert _stands_free(args[0], plan) == []
    # the cost is that of the committed actions, the counts every round's (the trap's too)
    table = args[4]
    assert plan.cost == pytest.approx(sum(table.step_cost[table.index(a)] for a in plan.actions))


def test_receding_horizon_says_when_its_own_steps_led_into_a_trap():
    # with no round left to try a shorter prefix the trap is committed; the joined plan's
    # UNREACHABLE then names where the rounds led, not the start (before: reason "")
    res = plan_receding_horizon(*_trap_after_two_steps(), execute_steps=3, max_rounds=2)
    assert res.statuses == ["NODE_LIMIT", "UNREACHABLE"]
    assert res.plan.status is PlanStatus.UNREACHABLE and res.plan.num_steps == 2
    assert res.plan.reason == (
        "from the state the committed steps reached at (1.405, 0.900, 1.571) t = 1.600 s "
        "(round 2) no step sequence reaches the goal; the earlier rounds ended at their "
        "limits with partial plans, so the start was not proved cut off"
    )
