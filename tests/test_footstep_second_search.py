"""The anytime planner's second search in a thread beside it (planning/footstep/portfolio.py)."""

import dataclasses

import pytest
from repertoire.planning.footstep import (
    DynamicEnvironment,
    PlannerOptions,
    PlanStatus,
    nominal_action_table,
    plan_footsteps,
    plan_footsteps_anytime,
)
from repertoire.planning.footstep.planner import AnytimePlan
from repertoire.planning.footstep.portfolio import merge_second, second_options
from repertoire.planning.footstep.scenes import random_floor_scene
from repertoire.planning.footstep.types import FootstepError

TABLE = nominal_action_table()
BUDGET = PlannerOptions(max_expansions=20_000, time_limit=600.0)


def _run(seed: int, second: bool, opts: PlannerOptions = BUDGET) -> list[AnytimePlan]:
    sc = random_floor_scene(seed, size=4.0)
    return plan_footsteps_anytime(
        sc.grid, sc.start, sc.start_foot, sc.goal, TABLE, opts, second_search=second
    )


def _second(seed: int, opts: PlannerOptions = BUDGET):
    sc = random_floor_scene(seed, size=4.0)
    return plan_footsteps(sc.grid, sc.start, sc.start_foot, sc.goal, TABLE, second_options(opts))


def _key(p: AnytimePlan) -> tuple:
    plan = p.plan
    return (plan.status, plan.cost, plan.poses, plan.feet, plan.xy_resolution,
            plan.nodes_expanded, p.weight, p.bound)  # fmt: skip


def test_second_search_options_are_the_first_refinements_lattice_at_weight_1_5():
    o = second_options(PlannerOptions(xy_resolution=0.04, yaw_bins=30, max_expansions=7))
    assert (o.xy_resolution, o.yaw_bins, o.heuristic_weight, o.refinements) == (0.02, 60, 1.5, 0)
    assert (o.max_expansions, o.heuristic) == (7, "dijkstra")


@pytest.mark.parametrize("bad", ["yes", 1, None])
def test_second_search_must_be_a_bool(bad):
    with pytest.raises(FootstepError, match=f"second_search must be True or False, got {bad!r}"):
        _run(2, bad)


def test_second_search_needs_the_compiled_core():
    with pytest.raises(FootstepError, match="second_search runs on the compiled core only"):
        _run(2, True, dataclasses.replace(BUDGET, backend="python"))
    sc = random_floor_scene(2, size=4.0)
    env = DynamicEnvironment([0.0, 1.0], [sc.grid, sc.grid], 0.5)
    euclid = dataclasses.replace(BUDGET, heuristic="euclidean")
    with pytest.raises(FootstepError, match="static grids"):
        plan_footsteps_anytime(
            env, sc.start, sc.start_foot, sc.goal, TABLE, euclid, second_search=True
        )


def test_the_second_plan_replaces_a_pipeline_without_plan():
    # floor 2 (4 m): the pipeline's 20k expansions find no plan, the second search's do
    alone = _run(2, False)
    assert [p.plan.status for p in alone] == [PlanStatus.NODE_LIMIT]
    b = _second(2)
    assert b.status is PlanStatus.SUCCESS and b.cost == pytest.approx(18.3)
    for _ in range(2):  # deterministic: the same results on a repeated run
        (only,) = _run(2, True)
        assert only.plan.poses == b.poses and only.plan.feet == b.feet
        assert (only.plan.cost, only.weight, only.bound) == (b.cost, 1.5, 1.5)
        assert (only.plan.xy_resolution, only.plan.yaw_bins) == (0.025, 72)
        assert only.plan.planning_time_s == only.elapsed_s > 0.0


def test_the_portfolio_is_the_pipeline_merged_with_the_second_plan():
    # floor 0 (4 m): the second plan (21.6) is dearer than the pipeline's last (19.25);
    # whether it joins between the pipeline's plans depends on the clock, the rest not
    alone = [_key(p) for p in _run(0, False)]
    b = _second(0)
    assert b.cost == pytest.approx(21.6) and alone[-1][1] == pytest.approx(19.25)
    for _ in range(2):
        both = _run(0, True)
        costs = [p.plan.cost for p in both]
        assert costs == sorted(costs, reverse=True)
        mine = (b.status, b.cost, b.poses, b.feet, 0.025, b.nodes_expanded, 1.5, 1.5)
        rest = [_key(p) for p in both if _key(p) != mine]
        assert len(both) - len(rest) <= 1  # the second plan at most once
        it = iter(alone)
        assert all(k in it for k in rest)  # the pipeline's plans, in order
        assert rest[-1] == alone[-1]  # its best plan last


def _fake(plan, cost: float, at: float, weight: float = 3.0, status=PlanStatus.SUCCESS):
    p = dataclasses.replace(plan, cost=cost, status=status)
    return AnytimePlan(p, weight, weight, at, 0.0)


def test_merge_second_keeps_costs_non_increasing_and_drops_partial_plans():
    plan = _second(2)
    a, b, c = _fake(plan, 30.0, 0.1), _fake(plan, 25.0, 0.4, 2.0), _fake(plan, 20.0, 0.8, 1.0)
    x = _fake(plan, 22.0, 0.5, 1.5)
    assert merge_second([a, b, c], x) == [a, b, x, c]  # c is cheaper: kept after x
    assert merge_second([a, b, c], _fake(plan, 26.0, 0.5, 1.5)) == [a, b, c]  # not cheaper
    y = _fake(plan, 19.0, 0.5, 1.5)
    assert merge_second([a, b, c], y) == [a, b, y]  # c is dearer than y: dropped
    first = _fake(plan, 40.0, 0.05, 1.5)
    assert merge_second([a, b, c], first) == [first, a, b, c]  # before any plan
    same = _fake(plan, 20.0, 0.9, 1.0)  # as cheap, tighter bound (the admissible search)
    assert merge_second([a, same], _fake(plan, 20.0, 0.5, 1.5)) == [
        a,
        _fake(plan, 20.0, 0.5, 1.5),
        same,
    ]
    partial = _fake(plan, 3.0, 1.0, 3.0, PlanStatus.TIME_LIMIT)
    assert merge_second([partial], x) == [x]
    assert merge_second([a, partial], x) == [a, x]
    assert merge_second([a, partial], _fake(plan, 35.0, 0.5)) == [a, partial]


def test_the_second_search_has_its_own_field_and_work_arrays(monkeypatch):
    import time

    import numpy as np
    from repertoire.planning.footstep import biped_model, fastcore, heuristic
    from repertoire.planning.footstep.portfolio import SecondSearch

    sc = random_floor_scene(2, size=4.0)
    b = _second(2)
    for eager in (biped_model.EAGER_CELLS, 0):  # settled whole, or on demand (written to)
        monkeypatch.setattr(biped_model, "EAGER_CELLS", eager)
        monkeypatch.setattr(heuristic, "_SHARED", {})
        fastcore._WORK.clear()
        args = (sc.grid, sc.start, sc.start_foot, sc.goal, TABLE)
        second = SecondSearch(*args, BUDGET, {}, time.perf_counter())
        pipeline = plan_footsteps_anytime(*args, BUDGET)  # meanwhile, on the shared field
        (only,) = second.merge(pipeline)
        assert only.plan.poses == b.poses and only.plan.cost == b.cost
        shared = next(iter(heuristic._SHARED.values()))
        own = second.model.h_lazy
        assert own is not shared and not np.shares_memory(own.f, shared.f)
        assert not np.shares_memory(own.i, shared.i) and own.size is not shared.size
        assert not np.shares_memory(own.p, shared.p)  # a retarget writes p[6], p[7]
        # a work set per search running at once (two when they overlapped, one when the
        # clock let one finish first), never one set in two places
        kept = [w[0] for w in fastcore._WORK]
        assert 1 <= len(kept) <= 2 and len({id(a) for a in kept}) == len(kept)
