"""Best-first search over transferred steps with planner-filled gaps (section V)."""

import dataclasses
import math
import re
import time

import numpy as np
import pytest
from repertoire.models.littledog import nominal_foot_positions
from repertoire.models.terrain import TerrainParams, generate_board
from repertoire.planning.transfer_search import (
    GapFill,
    PlannedStep,
    SearchConfig,
    TransferSearchError,
    foot_distance,
    gap_steps,
    search_transfer,
)

ORDER = (2, 0, 3, 1)  # lh, lf, rh, rf: the crawl gait's foot order
REACH = 0.04


def stance(x: float, y: float = 0.0) -> np.ndarray:
    feet = nominal_foot_positions()
    feet[:, 0] += x
    feet[:, 1] += y
    feet[:, 2] = 0.0
    return feet


def crawl(start: np.ndarray, count: int, first: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """``count`` crawl steps from ``start``: each moves one foot REACH along +x."""
    starts, ends = [], []
    cur = start.copy()
    for k in range(count):
        nxt = cur.copy()
        nxt[ORDER[(first + k) % 4], 0] += REACH
        starts.append(cur)
        ends.append(nxt)
        cur = nxt
    return np.array(starts), np.array(ends)


class StraightCrawl:
    """Stand-in gap filler: moves feet in crawl order straight to the target."""

    def __init__(self, status: str | None = None, delay: float = 0.0, busy: bool = True):
        self.calls = 0
        self.status = status
        self.delay = delay
        self.busy = busy

    def __call__(self, start, target, time_limit):
        self.calls += 1
        if self.delay and self.busy:  # burns CPU time
            t0 = time.process_time()
            while time.process_time() - t0 < min(self.delay, time_limit):
                pass
        elif self.delay:  # waits without CPU time (as under another process's load)
            time.sleep(self.delay)
        if self.status is not None:
            return GapFill([], self.status)
        steps, cur = [], start.copy()
        for _ in range(400):
            if foot_distance(cur, target) < 1e-9:
                return GapFill(steps, "reached")
            for i in ORDER:
                d = target[i] - cur[i]
                n = np.linalg.norm(d)
                if n < 1e-12:
                    continue
                nxt = cur.copy()
                nxt[i] = cur[i] + d * min(1.0, REACH / n)
                steps.append(PlannedStep(cur, nxt, i))
                cur = nxt
        return GapFill(steps, "failed")


def test_recorded_chain_is_followed_and_spurious_steps_left_out():
    start = stance(0.0)
    s_in, s_out = crawl(start, 16)
    goal = s_out[-1]
    # Spurious steps: a crawl far to the side, not towards the goal.
    side_in, side_out = crawl(stance(0.0, 0.5), 8)
    filler = StraightCrawl()
    result = search_transfer(
        start,
        goal,
        np.concatenate([s_in, side_in]),
        np.concatenate([s_out, side_out]),
        filler,
        SearchConfig(),
    )
    assert result.status == "reached"
    assert [p.step for p in result.path] == list(range(16))
    assert result.planned_count == 0 and result.recorded_count == 16
    assert result.cost == pytest.approx(16.0)
    assert filler.calls == 1  # the planner alone (start -> goal), planned first as the fallback


def test_gap_in_the_chain_is_filled_by_the_planner():
    start = stance(0.0)
    a_in, a_out = crawl(start, 8)
    # The second part starts 0.08 m further on: a gap of 8 planned steps.
    b_start = a_out[-1].copy()
    b_start[:, 0] += 0.08
    b_in, b_out = crawl(b_start, 8)
    goal = b_out[-1]
    filler = StraightCrawl()
    cfg = SearchConfig(step_reach=REACH)
    result = search_transfer(
        start, goal, np.concatenate([a_in, b_in]), np.concatenate([a_out, b_out]), filler, cfg
    )
    assert result.status == "reached"
    kinds = [p.kind for p in result.path]
    assert kinds == ["recorded"] * 8 + ["planned"] * 8 + ["recorded"] * 8
    assert result.cost == pytest.approx(16 * 1.0 + 8 * 3.0)
    # The planned steps join the two parts exactly.
    planned = [p.planned for p in result.path if p.kind == "planned"]
    np.testing.assert_allclose(planned[0].start_feet, a_out[-1])
    np.testing.assert_allclose(planned[-1].end_feet, b_in[0])
    # The gap estimate (feet x ceil(distance / reach)) is exact for this filler: one call
    # besides the planner alone.
    assert filler.calls == 2


def test_no_transferred_steps_plans_with_the_planner_alone():
    start, goal = stance(0.0), stance(0.12)
    result = search_transfer(start, goal, np.zeros((0, 4, 3)), np.zeros((0, 4, 3)), StraightCrawl())
    assert result.status == "reached"
    assert result.recorded_count == 0 and result.planned_count == 12
    assert "planner alone" in result.message


def test_failed_gaps_give_the_best_partial_path():
    start = stance(0.0)
    a_in, a_out = crawl(start, 8)
    goal = stance(0.3)
    result = search_transfer(start, goal, a_in, a_out, StraightCrawl(status="failed"))
    assert result.status == "unreachable"
    assert [p.step for p in result.path] == list(range(8))
    assert "from the goal" in result.message


def test_time_limit_returns_partial_path_and_says_so():
    start = stance(0.0)
    a_in, a_out = crawl(start, 8)
    goal = stance(0.3)
    cfg = SearchConfig(time_limit=0.05)
    calls = []
    slow = StraightCrawl(status="time_limit", delay=0.2)

    def filler(a, b, limit):
        calls.append(limit)
        if len(calls) == 1:
            return GapFill([], "failed")  # the planner alone (planned first) fails at once
        return slow(a, b, limit)  # the gap after the chain uses up the time

    result = search_transfer(start, goal, a_in, a_out, filler, cfg)
    assert result.status == "time_limit"
    assert result.planned_count == 0
    assert [p.step for p in result.path] == list(range(8))  # the best partial path
    assert "time_limit" in result.message and "CPU-time limit 0.05 s" in result.message
    assert 0.05 <= result.cpu_s < 1.0


def test_time_limit_after_the_planner_alone_returns_it():
    start = stance(0.0)
    a_in, a_out = crawl(start, 8)
    cfg = SearchConfig(time_limit=0.05, step_reach=REACH)
    result = search_transfer(start, stance(0.24), a_in, a_out, StraightCrawl(delay=0.2), cfg)
    assert result.status == "reached" and result.recorded_count == 0
    assert result.planned_count == 24 and result.cost == pytest.approx(72.0)
    assert "CPU-time limit 0.05 s reached: the planner alone" in result.message


def turned_chains(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Three recorded crawls of 4-11 steps at random places, each turned by up to 69 deg."""
    rng = np.random.default_rng(seed)
    ins, outs = [], []
    for _ in range(3):
        s0 = stance(rng.uniform(-0.05, 0.2), rng.uniform(-0.15, 0.15))
        a, b = crawl(s0, int(rng.integers(4, 12)))
        ang = rng.uniform(-1.2, 1.2)
        rot = np.array([[np.cos(ang), -np.sin(ang), 0], [np.sin(ang), np.cos(ang), 0], [0, 0, 1]])
        c0 = s0.mean(axis=0)
        ins.append((a - c0) @ rot.T + c0)
        outs.append((b - c0) @ rot.T + c0)
    return np.concatenate(ins), np.concatenate(outs)


@pytest.mark.parametrize("weight", [1.0, 2.0, 5.0])
def test_search_never_costs_more_than_the_planner_alone(weight):
    # A gap estimate above the planner's real cost (step_reach half the filler's reach) once
    # let goal paths through detours (e.g. seed 39: 9 recorded + 23 planned = 78) leave the
    # queue before the direct gap was planned (24 planned = 72).
    start, goal = stance(0.0), stance(0.24)
    cfg = SearchConfig(heuristic_weight=weight, step_reach=0.5 * REACH, max_gap=1.0)
    none = np.zeros((0, 4, 3))
    alone = search_transfer(start, goal, none, none, StraightCrawl(), cfg)
    assert alone.cost == pytest.approx(72.0)
    for seed in (36, 37, 38, 39):
        s_in, s_out = turned_chains(seed)
        result = search_transfer(start, goal, s_in, s_out, StraightCrawl(), cfg)
        assert result.status == "reached"
        assert result.cost <= alone.cost


def test_time_limit_counts_cpu_time_not_waiting():
    # A filler that waits (wall time, no CPU) longer than the limit does not cut the search.
    start = stance(0.0)
    a_in, a_out = crawl(start, 8)
    cfg = SearchConfig(time_limit=0.05, step_reach=REACH)
    filler = StraightCrawl(delay=0.1, busy=False)
    result = search_transfer(start, stance(0.36), a_in, a_out, filler, cfg)
    assert result.status == "reached" and filler.calls >= 1
    assert result.recorded_count == 8 and result.planned_count > 0


def test_bad_inputs_raise_clear_errors():
    start, goal = stance(0.0), stance(0.1)
    empty = np.zeros((0, 4, 3))
    board = generate_board(TerrainParams(kind="flat"), seed=0)
    with pytest.raises(TransferSearchError, match="off the terrain"):
        search_transfer(start, stance(2.0), empty, empty, StraightCrawl(), terrain=board)
    # the board's extent is where its boxes are: a board moved by 1 m along x holds x = 1.1
    # and not x = 0.1 (its params still say size_x around the origin)
    moved = board.translated(1.0, 0.0)
    with pytest.raises(TransferSearchError, match="off the terrain"):
        search_transfer(start, goal, empty, empty, StraightCrawl(), terrain=moved)
    result = search_transfer(stance(1.0), stance(1.1), empty, empty, StraightCrawl(), terrain=moved)
    assert result.status == "reached"
    with pytest.raises(TransferSearchError, match="planned_cost"):
        search_transfer(start, goal, empty, empty, StraightCrawl(), SearchConfig(planned_cost=0.5))
    with pytest.raises(TransferSearchError, match=r"\(4, 3\)"):
        search_transfer(np.zeros(3), goal, empty, empty, StraightCrawl())
    with pytest.raises(TransferSearchError, match="differ in count"):
        search_transfer(start, goal, np.zeros((2, 4, 3)), np.zeros((1, 4, 3)), StraightCrawl())
    with pytest.raises(TransferSearchError, match="callable"):
        search_transfer(start, goal, empty, empty, None)
    with pytest.raises(TransferSearchError, match="GapFill"):
        search_transfer(start, goal, empty, empty, lambda a, b, t: [])


def test_crawl_gap_filler_plans_a_gap_on_a_flat_board():
    # Needs the footstep planner's quadruped crawl model (issue 9), merged separately.
    pytest.importorskip(
        "repertoire.planning.footstep.quadruped",
        reason="repertoire.planning.footstep.quadruped (issue 9) is not on this branch",
    )
    from repertoire.planning.footstep.height_map import height_map_from_board
    from repertoire.planning.transfer_crawl_filler import CrawlGapFiller

    board = generate_board(TerrainParams(kind="flat"), seed=0)
    hmap = height_map_from_board(board, (-0.3, 0.3), (-0.3, 0.3), 0.01)
    start = stance(-0.1)
    start[:, 2] = board.params.base_thickness
    target = stance(0.0)
    answer = CrawlGapFiller(hmap)(start, target, 2.0)
    assert answer.status == "reached"
    assert len(answer.steps) >= 4
    end = answer.steps[-1].end_feet
    assert np.linalg.norm(end[:, :2].mean(0) - target[:, :2].mean(0)) <= 0.03 + 1e-9


def test_a_gap_that_misses_the_step_start_does_not_join_it():
    # The filler "reaches" the target's centroid but leaves every foot 3 cm to the side:
    # the recorded chain cannot be joined, so the search plans to the goal without it.
    start = stance(0.0)
    a_in, a_out = crawl(stance(0.12), 8)

    class SideCrawl(StraightCrawl):
        def __call__(self, start, target, time_limit):
            return super().__call__(start, target + np.array([0.0, 0.03, 0.0]), time_limit)

    cfg = SearchConfig(step_reach=REACH, join_tolerance=0.04)
    result = search_transfer(start, stance(0.4), a_in, a_out, SideCrawl(), cfg)
    assert result.status == "reached"
    assert result.recorded_count == 0 and result.planned_count > 0
    plain = search_transfer(start, stance(0.4), a_in, a_out, StraightCrawl(), cfg)
    assert plain.recorded_count > 0  # the same chain, joined exactly


def test_crawl_gap_filler_refuses_footholds_at_edges_its_map_misses():
    pytest.importorskip("repertoire.planning.footstep.quadruped")
    from repertoire.models.littledog import FOOT_RADIUS
    from repertoire.planning.footstep.height_map import height_map_from_board
    from repertoire.planning.littledog_crawl import foothold_ok
    from repertoire.planning.transfer_crawl_filler import CrawlGapFiller

    flat = generate_board(TerrainParams(kind="flat"), seed=0)
    base = flat.params.base_thickness

    class RidgeBoard:
        """A 3 cm ridge over 0.052 < x < 0.058: between the 1 cm map's cell centres."""

        params = flat.params

        def height(self, x, y):
            x = np.asarray(x, dtype=float)
            return np.where((x > 0.052) & (x < 0.058), base + 0.03, base) + 0.0 * np.asarray(y)

    board = RidgeBoard()
    hmap = height_map_from_board(board, (-0.3, 0.3), (-0.3, 0.3), 0.01)
    assert np.ptp(hmap.heights) == 0.0  # the map does not see the ridge
    filler = CrawlGapFiller(hmap, board=board)
    start = stance(-0.1)
    start[:, 2] = base + FOOT_RADIUS
    steps, cur = [], start
    for foot, x in ((2, cur[2, 0] + 0.04), (0, 0.062), (3, cur[3, 0] + 0.04)):
        nxt = cur.copy()
        nxt[foot, 0] = x  # lh forward, lf 4 mm past the ridge, rh forward
        steps.append(PlannedStep(cur, nxt, foot))
        cur = nxt
    assert filler.usable_prefix(steps) == 1
    assert CrawlGapFiller(hmap, board=flat).usable_prefix(steps) == 3
    # Planning across the ridge, every foothold kept is flat on the exact board.
    answer = filler(start, stance(0.1), 2.0)
    assert answer.steps
    rule = dataclasses.replace(filler.crawl, edge_radius=FOOT_RADIUS, flat_tolerance=0.006)
    landing = np.array([p.end_feet[p.foot, :2] for p in answer.steps])
    assert np.all(foothold_ok(board, landing, rule))


def flat_filler(**kwargs):
    """A crawl gap filler on a flat board (exact ground) and a start stance on it."""
    pytest.importorskip("repertoire.planning.footstep.quadruped")
    from repertoire.models.littledog import FOOT_RADIUS
    from repertoire.planning.footstep.height_map import height_map_from_board
    from repertoire.planning.transfer_crawl_filler import CrawlGapFiller

    board = generate_board(TerrainParams(kind="flat"), seed=0)
    hmap = height_map_from_board(board, (-0.3, 0.3), (-0.3, 0.3), 0.01)
    start = stance(-0.1)
    start[:, 2] = board.params.base_thickness + FOOT_RADIUS
    kwargs.setdefault("place_feet", True)
    return CrawlGapFiller(hmap, board=board, **kwargs), start


def test_crawl_gap_filler_refuses_non_finite_stances_naming_them():
    # A NaN target stance used to reach the exact board's height test ("terrain height
    # query needs finite x and y", naming neither stance) with place_feet, and a NaN start
    # came back as a failed gap; both are bad input.
    filler, start = flat_filler()
    for name in ("start", "target"):
        bad = {"start": start.copy(), "target": stance(0.0)}
        bad[name][2, 1] = math.nan
        with pytest.raises(TransferSearchError, match=f"needs finite stances, got {name} .*nan"):
            filler(bad["start"], bad["target"], 2.0)
        bad[name][2, 1] = math.inf
        with pytest.raises(TransferSearchError, match=f"needs finite stances, got {name} .*inf"):
            filler(bad["start"], bad["target"], 2.0)


def test_crawl_gap_filler_reaches_a_centroid_when_the_feet_cannot_be_placed():
    filler, start = flat_filler()
    wide = stance(0.0)
    wide[:, 1] *= 3.0  # flat footholds no leg reaches from the crawl's stance
    wide[:, 2] = start[0, 2]
    answer = filler(start, wide, 2.0)
    assert answer.status == "reached"  # enough for a goal; a step is joined only exactly
    end = answer.steps[-1].end_feet
    assert np.linalg.norm(end[:, :2].mean(0) - wide[:, :2].mean(0)) <= 0.03 + 1e-9
    assert foot_distance(end, wide) > 0.1


def test_crawl_gap_filler_places_only_the_feet_the_executor_cannot_take_up():
    filler, start = flat_filler()
    target = start.copy()
    target[2, 0] += 0.06  # lh 6 cm forward, lf 1.5 cm: the centroid within the goal radius
    target[0, 0] += 0.015
    every = filler(start, target, 2.0)
    few = flat_filler(place_within=0.04)[0](start, target, 2.0)
    assert every.status == few.status == "reached"
    # Every foot placed (within 5 mm) vs the fewest: lf's 1.5 cm is left to the executor.
    assert [p.foot for p in every.steps] == [2, 0]
    assert np.array_equal(every.steps[-1].end_feet, target)
    assert [p.foot for p in few.steps] == [2]
    end = few.steps[-1].end_feet
    assert float(foot_distance(end, target)) == pytest.approx(0.015)


def test_crawl_gap_filler_takes_the_fewest_steps_onto_a_recorded_start():
    # Every foot 11.3 cm from the target stance: one move each reaches it. The planner
    # aims at the centroid, not the footholds: its 4 steps and then placing moves made 8
    # steps (7 with place_within 0.04), about twice what the robot needs to spend.
    filler, start = flat_filler()
    target = stance(0.013, 0.007)  # off the planner's 2 cm lattice
    target[:, 2] = start[0, 2]
    for within in (0.0, 0.04):
        answer = flat_filler(place_within=within)[0](start, target, 2.0)
        assert answer.status == "reached"
        assert [p.foot for p in answer.steps] == [2, 0, 3, 1]
        assert np.array_equal(answer.steps[-1].end_feet, target)
    assert [p.foot for p in filler.shortest_placed(start, [], target)] == [2, 0, 3, 1]
    # Candidates the crawl cannot execute are passed over: with a support margin no swing
    # of these stances keeps, none is usable.
    strict = dataclasses.replace(
        filler, params=dataclasses.replace(filler.params, support_margin=0.2)
    )
    assert strict.shortest_placed(start, [], target) is None


def test_crawl_gap_filler_places_no_feet_onto_a_goal_target():
    # place=False (a goal reached by the planner's goal test): the planner's steps alone,
    # those of a filler that never places; a non-bool is refused, naming it.
    filler, start = flat_filler()
    target = stance(0.013, 0.007)  # off the planner's 2 cm lattice
    target[:, 2] = start[0, 2]
    goal = filler(start, target, 2.0, place=False)
    plain = flat_filler(place_feet=False)[0](start, target, 2.0)
    assert goal.status == plain.status == "reached"
    assert len(goal.steps) == len(plain.steps) == 4
    for a, b in zip(goal.steps, plain.steps):
        assert a.foot == b.foot and np.array_equal(a.end_feet, b.end_feet)
    end = goal.steps[-1].end_feet
    assert np.linalg.norm(end[:, :2].mean(0) - target[:, :2].mean(0)) <= 0.03 + 1e-9
    assert float(foot_distance(end, target)) > 0.04  # not placed onto the target
    with pytest.raises(TransferSearchError, match="place must be a bool, got 'no'"):
        filler(start, target, 2.0, place="no")


def test_crawl_gap_filler_says_why_a_gap_was_not_reached():
    # A planner out of expansions (or with no way) came back as "failed" with no reason,
    # so the search's error named none ("unreachable: 0 recorded and 0 planned steps").
    # Its expansions are its budget (session 37: they bind, not the wall time), and a gap
    # they cut leaves the target's reachability open: "time_limit", as a gap cut by wall
    # time (before: "partial" or "failed", and the search said "unreachable").
    filler, start = flat_filler(max_expansions=2)
    target = stance(0.2)
    target[:, 2] = start[0, 2]
    answer = filler(start, target, 2.0)
    assert answer.status == "time_limit" and len(answer.steps) == 1
    assert re.fullmatch(
        r"the crawl planner ended with NODE_LIMIT after 2 expansions \(\d+\.\d\d s\), "
        r"1 steps towards the target",
        answer.message,
    )
    answer = flat_filler(max_expansions=1)[0](start, target, 2.0)
    assert answer.status == "time_limit" and answer.steps == []
    assert answer.message.startswith("the crawl planner ended with NODE_LIMIT after 1 exp")
    result = search_transfer(start, target, np.zeros((0, 4, 3)), np.zeros((0, 4, 3)), filler)
    assert result.status == "time_limit"
    assert "gap filler: time_limit: the crawl planner ended with NODE_LIMIT" in result.message
    assert "(a gap filler's time limit reached)" in result.message


def test_crawl_gap_fillers_budget_is_its_expansions_under_a_longer_wall_limit(monkeypatch):
    # 50000 expansions under a 10 s wall limit: at 1.3-2.3 ms of CPU per expansion on
    # tall rocks the wall limit bound, so a gap's outcome depended on the machine's load.
    # The planner now gets 5000 expansions and a wall limit of at least 60 s.
    import repertoire.planning.transfer_crawl_filler as tcf

    calls = []
    real = tcf.plan_crawl
    monkeypatch.setattr(tcf, "plan_crawl", lambda *a, **k: calls.append(k) or real(*a, **k))
    filler, start = flat_filler()
    target = stance(0.1)
    target[:, 2] = start[0, 2]
    for remaining in (2.0, 75.0):
        assert filler(start, target, remaining).status == "reached"
    budgets = [(k["max_expansions"], k["time_limit"]) for k in calls]
    assert budgets == [(5000, 60.0), (5000, 75.0)]


@pytest.mark.parametrize("yaw_deg", [-40.0, 45.0])
def test_crawl_gap_filler_turns_onto_a_yawed_target_stance(yaw_deg):
    # A recorded step matched with a yaw at the edge of the candidate range: the crawl
    # turns the body, so the gap ends on the step's start stance (before: 0.31 / 0.43 m off).
    from repertoire.planning.littledog_crawl import heading_of
    from repertoire.planning.transfer_crawl_filler import executable_prefix

    filler, start = flat_filler()
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    target = stance(0.0) @ np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    target += [0.05, 0.02, start[0, 2]]
    answer = filler(start, target, 2.0)
    assert answer.status == "reached"
    end = answer.steps[-1].end_feet
    assert np.all(np.linalg.norm(end - target, axis=1) <= 0.005 + 1e-9)
    assert heading_of(end) == pytest.approx(math.radians(yaw_deg))
    assert executable_prefix(answer.steps, filler.crawl, filler.board) == len(answer.steps)


class Refusing:
    """Stand-in gap filler that never reaches, with a reason; records every gap it plans."""

    def __init__(self, message: str = "no way"):
        self.gaps: list[tuple[float, float]] = []
        self.message = message

    def __call__(self, start, target, time_limit):
        self.gaps.append(
            (round(float(start[:, 0].mean()), 4), round(float(target[:, 0].mean()), 4))
        )
        return GapFill([], "failed", self.message)


def test_a_failed_planner_alone_is_not_planned_again():
    none = np.zeros((0, 4, 3))
    filler = Refusing()
    result = search_transfer(stance(0.0), stance(0.5), none, none, filler)
    assert result.status == "unreachable"
    assert result.planner_calls == 1
    assert filler.gaps == [(0.0, 0.5)]
    assert result.path == [] and result.expanded == 0
    assert result.message == (
        "no transferred steps (every step discarded): planner alone; unreachable: "
        "0 recorded and 0 planned steps; best partial path ends 0.500 m from the goal; "
        "gap filler: failed: no way"
    )


def test_no_gap_is_planned_twice_when_every_gap_fails():
    starts, ends = crawl(stance(0.0), 8)
    starts[:, :, 0] += 0.1  # every step behind a gap from the start
    ends[:, :, 0] += 0.1
    filler = Refusing()
    config = SearchConfig(neighbours=4)
    result = search_transfer(stance(0.0), stance(0.5), starts, ends, filler, config)
    assert result.status == "unreachable"
    assert filler.gaps[0] == (0.0, 0.5)  # the planner alone first
    assert len(filler.gaps) == len(set(filler.gaps)) == result.planner_calls
    # Start -> goal and start -> its 4 nearest steps: each once; no step is ever entered.
    assert result.planner_calls == 5 and result.expanded == 0
    assert result.message.endswith("; gap filler: failed: no way")


def test_a_start_within_goal_tolerance_is_at_the_goal():
    none = np.zeros((0, 4, 3))
    filler = Refusing()
    config = SearchConfig(goal_tolerance=0.03)
    result = search_transfer(stance(0.0), stance(0.02), none, none, filler, config)
    assert result.status == "reached"
    assert result.path == [] and result.cost == 0.0
    assert result.planner_calls == 0 and filler.gaps == []
    assert result.message == (
        "no transferred steps (every step discarded): planner alone; reached: "
        "0 recorded and 0 planned steps"
    )
    # Just outside the tolerance the planner alone is tried (once) and fails.
    result = search_transfer(
        stance(0.0), stance(0.031), none, none, filler, SearchConfig(goal_tolerance=0.03)
    )
    assert result.status == "unreachable" and result.planner_calls == 1
    assert filler.gaps == [(0.0, 0.031)]


def test_crawl_gap_filler_names_the_planners_refusal():
    from repertoire.models.littledog import FOOT_RADIUS

    filler, _ = flat_filler()
    start = stance(-0.25)  # rear feet beyond the map's -0.3 m edge
    start[:, 2] = filler.board.params.base_thickness + FOOT_RADIUS
    answer = filler(start, stance(0.0), 2.0)
    assert answer.status == "failed" and answer.steps == []
    assert answer.message.startswith("the crawl planner refused: crawl start footholds [[")
    assert answer.message.endswith("leave the height map")
    none = np.zeros((0, 4, 3))
    result = search_transfer(start, stance(0.0), none, none, filler)
    assert result.status == "unreachable" and result.planner_calls == 1
    assert "; gap filler: failed: the crawl planner refused: crawl start footholds" in (
        result.message
    )
    assert result.message.endswith("leave the height map")


def test_result_reports_the_planner_alones_cost():
    """The cost every path through recorded steps had to beat: 16 planned steps (48) here."""
    start = stance(0.0)
    s_in, s_out = crawl(start, 16)
    result = search_transfer(start, s_out[-1], s_in, s_out, StraightCrawl(), SearchConfig())
    assert result.cost == pytest.approx(16.0)
    assert result.planner_alone_cost == pytest.approx(16 * 3.0)
    none = np.zeros((0, 4, 3))
    alone = search_transfer(start, stance(0.12), none, none, StraightCrawl())
    assert alone.planner_alone_cost == alone.cost == pytest.approx(12 * 3.0)
    failed = search_transfer(stance(0.0), stance(0.5), none, none, Refusing())
    assert math.isnan(failed.planner_alone_cost)


def test_goal_test_is_what_the_final_stance_must_also_satisfy():
    none = np.zeros((0, 4, 3))
    goal = stance(0.02)
    line = float(goal[:2, 0].min())  # the goal stance's front feet

    def past(feet):
        return bool(min(feet[0, 0], feet[1, 0]) >= line - 1e-12)

    config = SearchConfig(goal_tolerance=0.03)
    # The start is within goal_tolerance of the goal but its front feet are 2 cm short:
    # not at the goal; the planner alone (each foot 2 cm, one step each) gets there.
    filler = StraightCrawl()
    result = search_transfer(stance(0.0), goal, none, none, filler, config, goal_test=past)
    assert result.status == "reached" and filler.calls == 1
    assert result.planned_count == 4 and result.recorded_count == 0
    assert past(result.path[-1].planned.end_feet)
    # Without the test the start is at the goal with an empty path.
    assert search_transfer(stance(0.0), goal, none, none, filler, config).path == []
    # A gap to the goal ending on a stance that fails the test does not reach it.
    result = search_transfer(
        stance(0.0), goal, none, none, StraightCrawl(), config, goal_test=lambda f: False
    )
    assert result.status == "unreachable" and result.path == []
    assert "; gap filler: a gap to the goal ended on a stance failing the goal test: [[" in (
        result.message
    )
    # A start on the goal stance (joined within join_tolerance) is tested too.
    result = search_transfer(goal, goal, none, none, StraightCrawl(), goal_test=lambda f: False)
    assert result.status == "unreachable"
    with pytest.raises(TransferSearchError, match="goal_test must be callable.*got 3"):
        search_transfer(stance(0.0), goal, none, none, filler, config, goal_test=3)


def test_gap_steps_leave_out_the_feet_the_join_tolerance_takes_up():
    a = np.zeros((4, 3))
    b = np.zeros((4, 3))
    b[:, 0] = [0.01, 0.30, 0.02, 0.05]
    # 1 + 3 moves for the 5 and 30 cm feet; 1 and 2 cm (3 cm in sum) are within 4 cm.
    assert gap_steps(a, b, 0.13, 0.04) == 4
    assert gap_steps(a, b, 0.13, 0.0) == 6  # every foot moves: 1 + 3 + 1 + 1
    assert gap_steps(a, b, 0.13, 0.08) == 3  # 8 cm left over: only the 30 cm foot
    assert gap_steps(a, b, 0.13, 0.38) == 0
    assert gap_steps(a, a, 0.13, 0.0) == 0
    with pytest.raises(TransferSearchError, match="reach must be a positive length, got 0.0"):
        gap_steps(a, b, 0.0, 0.04)
    with pytest.raises(TransferSearchError, match="tolerance must be >= 0, got nan"):
        gap_steps(a, b, 0.13, math.nan)


def test_a_gap_estimate_counting_joined_feet_does_not_hide_the_cheaper_path():
    # The chain's first step starts 5 mm off on three feet and 6 cm on one: one move joins
    # it (3). Its estimate was 4 moves (12: every foot off by more than 0 counted), so
    # the search returned the planner alone (15) before planning that gap: 11 through
    # the chain. (Execution study start 5: a gap into the chain's second step closed it
    # first, 47 instead of 45.)
    start = stance(0.0)
    first = start.copy()
    first[:3, 0] += 0.005
    first[3, 0] += 0.06
    a_in, a_out = crawl(first, 8)

    class Placing(StraightCrawl):
        """Moves the feet the join tolerance cannot take up, largest first, 13 cm a move."""

        def __call__(self, start, target, time_limit):
            self.calls += 1
            steps, cur = [], start.copy()
            for f in np.argsort(-np.linalg.norm(cur - target, axis=1), kind="stable"):
                while foot_distance(cur, target) > 0.02 and np.linalg.norm(target[f] - cur[f]):
                    d = target[f] - cur[f]
                    nxt = cur.copy()
                    nxt[f] = cur[f] + d * min(1.0, 0.13 / np.linalg.norm(d))
                    steps.append(PlannedStep(cur, nxt, int(f)))
                    cur = nxt
            return GapFill(steps, "reached")

    cfg = SearchConfig(step_reach=0.13, join_tolerance=0.02)
    result = search_transfer(start, a_out[-1], a_in, a_out, Placing(), cfg)
    assert result.status == "reached"
    assert result.planner_alone_cost == pytest.approx(15.0)
    assert [p.kind for p in result.path] == ["planned"] + ["recorded"] * 8
    assert [p.step for p in result.path[1:]] == list(range(8))
    assert result.cost == pytest.approx(3.0 + 8.0)


def test_placing_moves_keep_the_planners_height_rules():
    # within_step_rules: a foot's height change at most max_step_height (9 cm), no cell of
    # the straight swing line more than swing_clearance (5 cm) above the higher foothold,
    # the rules the planner keeps for its own steps; placing moves are held to them too.
    pytest.importorskip("repertoire.planning.footstep.quadruped")
    from repertoire.models.littledog import FOOT_RADIUS
    from repertoire.planning.footstep.height_map import HeightMap
    from repertoire.planning.transfer_crawl_filler import CrawlGapFiller

    heights = np.zeros((60, 60))  # 1 cm cells, x and y in [-0.3, 0.29]
    heights[:, 30] = 0.06  # a 6 cm wall at x = 0
    heights[:, 40:] = 0.091  # a 9.1 cm plateau from x = 0.1
    filler = CrawlGapFiller(HeightMap((-0.3, -0.3), 0.01, heights))

    def move(x0, x1, z1=0.0, z0=0.0):
        a = np.zeros((4, 3)) + FOOT_RADIUS
        b = a.copy()
        a[0] = (x0, 0.0, z0 + FOOT_RADIUS)
        b[0] = (x1, 0.0, z1 + FOOT_RADIUS)
        return PlannedStep(a, b, 0)

    assert filler.within_step_rules(move(-0.2, -0.1))
    assert not filler.within_step_rules(move(-0.05, 0.05))  # over the 6 cm wall
    assert filler.within_step_rules(move(0.04, 0.08))  # beside it
    assert not filler.within_step_rules(move(0.05, 0.12, 0.091))  # a 9.1 cm rise
    assert filler.within_step_rules(move(0.05, 0.12, 0.089, 0.0))  # an 8.9 cm one
    assert filler.within_step_rules(move(0.12, 0.15, 0.091, 0.091))  # on the plateau


def test_a_gap_cut_by_its_planners_time_limit_is_not_called_unreachable():
    # The planner alone on a steps board (3.5 cm rises) ended TIME_LIMIT after 10 s of wall
    # time at 5.7 s of the search's 10 s CPU, and the search said "unreachable": nothing had
    # shown the goal unreachable. Failed gaps (no way) still give "unreachable".
    start, goal = stance(0.0), stance(0.3)
    none = np.zeros((0, 4, 3))
    result = search_transfer(start, goal, none, none, StraightCrawl(status="time_limit"))
    assert result.status == "time_limit" and result.path == []
    assert result.message == (
        "no transferred steps (every step discarded): planner alone; time_limit: 0 recorded "
        "and 0 planned steps; best partial path ends 0.300 m from the goal (a gap filler's "
        "time limit reached)"
    )
    a_in, a_out = crawl(start, 8)
    result = search_transfer(start, goal, a_in, a_out, StraightCrawl(status="time_limit"))
    assert result.status == "time_limit"
    assert [p.step for p in result.path] == list(range(8))
    result = search_transfer(start, goal, none, none, StraightCrawl(status="failed"))
    assert result.status == "unreachable"
