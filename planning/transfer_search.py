"""Best-first search over transferred steps with planner-filled gaps (Stolle et al., section V).

The topological graph has a start node (the robot's stance), a goal node (a goal
stance) and one node per transferred step. From a node's outgoing stance (the
start stance, or a step's end stance) edges lead to the ``neighbours`` steps whose
start stances are nearest by the foot-location metric (the sum over the four feet
of the distance between corresponding feet), and to the goal. An edge whose
stances differ by more than ``join_tolerance`` is a gap, filled by a footstep
planner given as a callable (:class:`GapFiller`); planned steps cost more than
recorded ones; a filled gap joins a step only if it ends on the step's start stance
(within ``join_tolerance``). Gaps are planned lazily: an edge enters the queue with an estimated
cost and the planner runs only when that edge is popped (then it is re-queued with
its real cost), so most gaps are never planned. Steps that do not lead towards the
goal are never on the path and so are left out of the final sequence.

Every node has an edge to the goal (the direct start -> goal edge included), so
with no transferred steps (a match threshold that discarded all of them) the search
plans with the planner alone and says so. That direct edge, the planner alone, is
planned first and queued at its real cost: goal entries leave the queue in order of
their real cost, so the search never returns a path costlier than the planner alone,
whatever the heuristic weight (which trades planner calls for path cost among the
paths through recorded steps), and keeps it if the CPU-time limit cuts the search.

The search's time limit is CPU time (``time.process_time``: the search and its
planner calls), so the path found does not depend on how loaded the machine is;
when the limit is reached the best partial path is returned with status
``time_limit``.
"""

import dataclasses
import heapq
import math
import time
from collections.abc import Callable
from typing import Protocol

import numpy as np
from repertoire.models.terrain import TerrainBoard

from repertoire.checks import is_whole
from repertoire.errors import RepertoireError

GAP_STATUSES = ("reached", "partial", "failed", "time_limit")
"""Statuses a gap filler may return; only ``reached`` makes an edge usable."""


class TransferSearchError(RepertoireError):
    """Bad input to the transfer search."""


@dataclasses.dataclass
class PlannedStep:
    """One step from the gap-filling planner.

    Attributes:
        start_feet: foot centres before the step (4, 3).
        end_feet: foot centres after the step (4, 3).
        foot: index of the moving foot (``LEGS`` order).
    """

    start_feet: np.ndarray
    end_feet: np.ndarray
    foot: int


@dataclasses.dataclass
class GapFill:
    """A gap filler's answer.

    Attributes:
        steps: planned steps from the start stance towards the target stance.
        status: one of :data:`GAP_STATUSES`.
        message: why a gap was not reached, in words (e.g. the planner's refusal of a
            start off its map); the search names the first one when it fails.
    """

    steps: list[PlannedStep]
    status: str
    message: str = ""


class GapFiller(Protocol):
    """Plans steps from one stance to another (the footstep planner's quadruped model)."""

    def __call__(self, start: np.ndarray, target: np.ndarray, time_limit: float) -> GapFill:
        """Plans from ``start`` (4, 3) to ``target`` (4, 3) within ``time_limit`` seconds."""
        ...


@dataclasses.dataclass
class SearchConfig:
    """Settings of the transfer search (YAML-loadable).

    Attributes:
        neighbours: edges from each node to this many nearest steps.
        join_tolerance: foot-location distance (sum over feet, m) under which two
            stances join without planned steps.
        recorded_cost: cost of one recorded step.
        planned_cost: cost of one planned step (> recorded_cost).
        step_reach: farthest one foot moves in one planned step (m); a gap's cost is
            estimated as ``planned_cost`` times :func:`gap_steps` (the sum over the feet
            the join tolerance does not take up of ``ceil(distance / step_reach)``) until
            the planner has filled it.
        goal_tolerance: distance (m) of a stance's centroid from the goal centroid that
            counts as at the goal; 0 means the goal stance itself must be joined (within
            ``join_tolerance``, or by planned steps).
        max_gap: gaps between steps whose centroids are farther apart than this (m) are
            not tried; gaps to the goal always are (lazily, so only when they may win).
        time_limit: CPU-time limit of the whole search with its planner calls (s,
            ``time.process_time``); checked before each gap is planned, and the remaining
            budget is passed to the gap filler.
        heuristic_weight: weight of the distance-to-goal heuristic (recorded steps
            needed at ``step_reach / 4`` of body progress each); 1 is A*, larger is
            greedier best-first with fewer planner calls. Either way no path costlier
            than the planner alone is returned (it is planned first).
    """

    neighbours: int = 8
    join_tolerance: float = 0.02
    recorded_cost: float = 1.0
    planned_cost: float = 3.0
    step_reach: float = 0.08
    goal_tolerance: float = 0.0
    max_gap: float = 0.3
    time_limit: float = 2.0
    heuristic_weight: float = 2.0

    def validate(self) -> None:
        """Raises TransferSearchError naming a bad field."""
        if (
            not (
                is_whole(self.neighbours)
                or (isinstance(self.neighbours, float) and self.neighbours.is_integer())
            )
            or self.neighbours < 1
        ):
            raise TransferSearchError(
                f"neighbours must be a positive integer, got {self.neighbours}"
            )
        for name in ("join_tolerance", "goal_tolerance"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0.0):
                raise TransferSearchError(f"{name} must be a non-negative length, got {v}")
        for name in ("recorded_cost", "step_reach", "max_gap", "time_limit", "heuristic_weight"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise TransferSearchError(f"{name} must be positive, got {v}")
        if not (math.isfinite(self.planned_cost) and self.planned_cost > self.recorded_cost):
            raise TransferSearchError(
                f"planned_cost ({self.planned_cost}) must exceed recorded_cost "
                f"({self.recorded_cost}): planned steps cost more than recorded ones"
            )


@dataclasses.dataclass
class PathItem:
    """One entry of the found sequence.

    Attributes:
        kind: ``recorded`` (a transferred library step) or ``planned``.
        step: index of the transferred step (``recorded``), else -1.
        planned: the planned step (``planned``), else None.
    """

    kind: str
    step: int = -1
    planned: PlannedStep | None = None


@dataclasses.dataclass
class SearchResult:
    """Outcome of :func:`search_transfer`.

    Attributes:
        status: ``reached``, ``time_limit`` (best partial path; the search's CPU-time
            limit, or a gap filler's own time limit cut a gap it needed) or ``unreachable``
            (best partial path; no gap was cut by a time limit).
        path: the sequence of recorded and planned steps from the start.
        cost: total cost of ``path``.
        recorded_count: recorded steps on the path.
        planned_count: planned steps on the path.
        planner_calls: gap-filler calls made.
        expanded: nodes expanded.
        message: what happened, in words (e.g. planner-only because no step matched).
        cpu_s: CPU time of the search with its planner calls (s).
        planner_alone_cost: cost of the planner alone from the start to the goal, the
            path every path through recorded steps must beat (NaN when it was not
            planned or did not reach the goal).
    """

    status: str
    path: list[PathItem]
    cost: float
    recorded_count: int
    planned_count: int
    planner_calls: int
    expanded: int
    message: str
    cpu_s: float = 0.0
    planner_alone_cost: float = math.nan


def foot_distance(a, b) -> np.ndarray:
    """The foot-location metric: sum over the four feet of ||a_i - b_i|| (broadcasts)."""
    return np.linalg.norm(np.asarray(a, float) - np.asarray(b, float), axis=-1).sum(axis=-1)


def gap_steps(a, b, reach: float, tolerance: float) -> int:
    """Fewest one-foot moves of at most ``reach`` (m) from stance ``a`` to within ``tolerance``.

    The feet farthest from ``b`` move first, until the other feet's summed offset is at
    most ``tolerance`` (what the search joins without planned steps); each moved foot
    needs ``ceil(offset / reach)`` moves. Feet inside the tolerance are not counted: a
    gap whose feet already stand on the target but one (joined by one placing move) was
    estimated at four moves, above its planned cost, so a cheaper path through it was
    passed over for one its estimate ranked first (execution study start 5).

    Args:
        a: the stance the gap starts from (4, 3).
        b: the target stance (4, 3).
        reach: farthest one foot moves in one step (m, > 0).
        tolerance: summed foot offset left over (m, >= 0).

    Raises:
        TransferSearchError: a reach that is not positive, a negative tolerance.
    """
    if not (math.isfinite(reach) and reach > 0.0):
        raise TransferSearchError(f"gap_steps: reach must be a positive length, got {reach}")
    if not (math.isfinite(tolerance) and tolerance >= 0.0):
        raise TransferSearchError(f"gap_steps: tolerance must be >= 0, got {tolerance}")
    d = np.sort(np.linalg.norm(np.asarray(a, float) - np.asarray(b, float), axis=-1))
    moved = len(d)
    while moved and d[: len(d) - moved + 1].sum() <= tolerance:
        moved -= 1
    return int(np.ceil(d[len(d) - moved :] / reach - 1e-9).sum())


def _check_stances(name: str, value, batch: bool) -> np.ndarray:
    try:
        a = np.asarray(value, dtype=float)
        if batch and a.size % 12 == 0:
            a = a.reshape(-1, 4, 3)
    except (TypeError, ValueError) as e:
        raise TransferSearchError(f"{name} must be a finite array of stances: {e}") from e
    shape_ok = (a.ndim == 3 and a.shape[1:] == (4, 3)) if batch else a.shape == (4, 3)
    if not shape_ok or not np.all(np.isfinite(a)):
        want = "(M, 4, 3)" if batch else "(4, 3)"
        raise TransferSearchError(f"{name} must be a finite {want} array, got {a.shape}")
    return a


def search_transfer(
    start,
    goal,
    step_start_feet,
    step_end_feet,
    gap_filler: GapFiller,
    config: SearchConfig | None = None,
    terrain: TerrainBoard | None = None,
    goal_test: Callable[[np.ndarray], bool] | None = None,
) -> SearchResult:
    """Best-first (lazy A*) search from ``start`` to ``goal`` over transferred steps.

    Args:
        start: the robot's start stance (4, 3).
        goal: the goal stance (4, 3).
        step_start_feet: start stances of the transferred steps (M, 4, 3), M may be 0.
        step_end_feet: end stances of the transferred steps (M, 4, 3).
        gap_filler: the planner filling gaps (see :class:`GapFiller`).
        config: search settings.
        terrain: if given, the goal must lie on it.
        goal_test: if given, what a path's final stance (4, 3) must also satisfy to
            count as at the goal (e.g. front feet past a goal line): a stance within
            ``goal_tolerance`` of the goal, or a gap to the goal ending on a stance, that
            fails it does not reach the goal (the goal stance and tolerances are the
            search's target; this is the task's criterion, which they need not imply).

    Raises:
        TransferSearchError: malformed stances, a goal off the terrain, bad settings.
    """
    config = SearchConfig() if config is None else config
    if not isinstance(config, SearchConfig):
        raise TransferSearchError(f"config must be a SearchConfig, got {type(config).__name__}")
    if terrain is not None and not isinstance(terrain, TerrainBoard):
        raise TransferSearchError(f"terrain must be a TerrainBoard, got {type(terrain).__name__}")
    config.validate()
    start = _check_stances("start", start, False)
    goal = _check_stances("goal", goal, False)
    s_in = _check_stances("step_start_feet", step_start_feet, True)
    s_out = _check_stances("step_end_feet", step_end_feet, True)
    if s_in.shape != s_out.shape:
        raise TransferSearchError(
            f"step start and end stances differ in count: {s_in.shape} vs {s_out.shape}"
        )
    if not callable(gap_filler):
        raise TransferSearchError("gap_filler must be callable (start, target, time_limit)")
    if goal_test is not None and not callable(goal_test):
        raise TransferSearchError(f"goal_test must be callable (stance) or None, got {goal_test!r}")

    def final_ok(stance: np.ndarray) -> bool:
        return goal_test is None or bool(goal_test(np.array(stance, dtype=float)))

    if terrain is not None:
        x0, x1, y0, y1 = terrain.bounds()  # the boxes' extent (a moved or joined board too)
        gx, gy = goal[:, 0], goal[:, 1]
        if np.any((gx < x0) | (gx > x1)) or np.any((gy < y0) | (gy > y1)):
            raise TransferSearchError(
                f"goal stance lies off the terrain ([{x0:.4g}, {x1:.4g}] x [{y0:.4g}, {y1:.4g}]"
                f" m): {goal[:, :2]}"
            )
    m = s_in.shape[0]
    goal_node = m + 1
    goal_c = goal[:, :2].mean(axis=0)
    out_stance = [start] + list(s_out)
    out_c = np.array([s[:, :2].mean(axis=0) for s in out_stance])
    in_c = s_in[:, :, :2].mean(axis=1) if m else np.zeros((0, 2))
    reach = config.step_reach

    def h_dist(node: int) -> float:
        return float(np.linalg.norm(out_c[node] - goal_c))

    def h(node: int) -> float:
        return config.heuristic_weight * config.recorded_cost * 4.0 * h_dist(node) / reach

    def gap_estimate(a: np.ndarray, b: np.ndarray) -> float:
        return config.planned_cost * gap_steps(a, b, reach, config.join_tolerance)

    clock = time.process_time  # CPU time: the same budget whatever the machine's load
    t0 = clock()
    counter = 0
    queue: list = []
    g_best = {0: 0.0}
    parent: dict[int, tuple[int, list[PlannedStep]]] = {}
    closed: set[int] = set()
    planner_calls = 0
    expanded = 0
    reached = False
    timed_out = False
    refusal = ""  # the first gap filler's reason for an unusable gap
    gap_cut = False  # a gap filler stopped by its own time limit: unreachability not shown

    def push_edges(u: int, skip_goal: bool = False) -> None:
        nonlocal counter
        a = out_stance[u]
        targets: list[int] = []
        if m:
            d = foot_distance(a, s_in)
            near = np.argsort(d, kind="stable")
            near = [int(j) for j in near if j + 1 != u and j + 1 not in closed]
            targets = [j + 1 for j in near[: config.neighbours]]
        if not skip_goal:
            targets.append(goal_node)
        for v in targets:
            b = goal if v == goal_node else s_in[v - 1]
            gap = float(foot_distance(a, b))
            step_cost = 0.0 if v == goal_node else config.recorded_cost
            if gap <= config.join_tolerance and (v != goal_node or final_ok(a)):
                est, evaluated = step_cost, True
            else:
                cu = out_c[u]
                cv = goal_c if v == goal_node else in_c[v - 1]
                if v != goal_node and np.linalg.norm(cu - cv) > config.max_gap:
                    continue
                est, evaluated = step_cost + gap_estimate(a, b), False
            g = g_best[u] + est
            f = g + (0.0 if v == goal_node else h(v))
            counter += 1
            heapq.heappush(queue, (f, not evaluated, -g, counter, u, v, g, evaluated, []))

    def fill_gap(u: int, v: int) -> tuple | None:
        """Plans the gap of edge u -> v: its queue entry at the real cost, or None (unusable)."""
        nonlocal counter, planner_calls, refusal, gap_cut
        b = goal if v == goal_node else s_in[v - 1]
        remaining = config.time_limit - (clock() - t0)
        planner_calls += 1
        answer = gap_filler(out_stance[u].copy(), b.copy(), remaining)
        if (
            not isinstance(answer, GapFill)
            or answer.status not in GAP_STATUSES
            or not isinstance(answer.steps, list)
        ):
            raise TransferSearchError(
                f"gap_filler must return GapFill with a list of steps and status in "
                f"{GAP_STATUSES}, got {answer!r}"
            )
        if answer.status != "reached":
            gap_cut = gap_cut or answer.status == "time_limit"
            if answer.message and not refusal:
                refusal = f"{answer.status}: {answer.message}"
            return None
        end = answer.steps[-1].end_feet if answer.steps else out_stance[u]
        if v != goal_node and float(foot_distance(end, b)) > config.join_tolerance:
            # The planner aims at a centroid: a gap that does not end on the step's
            # start stance would leave the nearest-step policy repeating the last step.
            return None
        if v == goal_node and not final_ok(end):
            if not refusal:
                refusal = f"a gap to the goal ended on a stance failing the goal test: {end[:, :2]}"
            return None
        step_cost = 0.0 if v == goal_node else config.recorded_cost
        g = g_best[u] + step_cost + config.planned_cost * len(answer.steps)
        counter += 1
        f = g + (0.0 if v == goal_node else h(v))
        return (f, False, -g, counter, u, v, g, True, list(answer.steps))

    # The planner alone (start -> goal) is planned first: the fallback every path must
    # beat. It enters the queue at its real cost, and goal entries leave the queue in
    # order of their real cost, so no path costlier than the planner alone is returned
    # (with any heuristic weight), and it is kept if the CPU-time limit cuts the search.
    # A start already within goal_tolerance of the goal is reached with an empty path.
    fallback = None
    closed.add(0)
    if config.goal_tolerance > 0.0 and h_dist(0) <= config.goal_tolerance and final_ok(start):
        parent[goal_node] = (0, [])
        reached = True
    elif (
        float(foot_distance(start, goal)) > config.join_tolerance
        and config.time_limit > clock() - t0
    ):
        # Planned once: a failed attempt is not queued (and planned) again.
        fallback = fill_gap(0, goal_node)
        push_edges(0, skip_goal=True)
    else:
        push_edges(0)
    if fallback is not None:
        heapq.heappush(queue, fallback)
    while queue and not reached:
        if clock() - t0 > config.time_limit:
            timed_out = True
            break
        entry = heapq.heappop(queue)
        f, _, _, _, u, v, g, evaluated, fill = entry
        if v in closed:
            continue
        if not evaluated:
            if config.time_limit - (clock() - t0) <= 0.0:
                timed_out = True
                break
            entry = fill_gap(u, v)
            if entry is not None:
                heapq.heappush(queue, entry)
            continue
        closed.add(v)
        g_best[v] = g
        parent[v] = (u, fill)
        expanded += 1
        if v == goal_node:
            reached = True
            break
        if (
            config.goal_tolerance > 0.0
            and h_dist(v) <= config.goal_tolerance
            and final_ok(out_stance[v])
        ):
            # At the goal already: join it directly.
            g_best[goal_node] = g
            parent[goal_node] = (v, [])
            reached = True
            break
        push_edges(v)

    if timed_out and fallback is not None:
        # Cut short: the planner alone reached the goal, better than any partial path.
        parent[goal_node] = (0, fallback[-1])
        reached = True
    if reached:
        end = goal_node
        status = "reached"
    else:
        end = min((n for n in closed if n != goal_node), key=h)
        # A gap its planner's time limit cut leaves the goal's reachability open: the
        # search ran out of time there too (a steps board's one gap, the planner alone,
        # ended TIME_LIMIT after 10 s of wall time at 5.7 s of the search's CPU, and the
        # search said "unreachable").
        status = "time_limit" if timed_out or gap_cut else "unreachable"
    path: list[PathItem] = []
    node = end
    while node != 0:
        u, fill = parent[node]
        items = [PathItem("planned", planned=p) for p in fill]
        if node != goal_node:
            items.append(PathItem("recorded", step=node - 1))
        path = items + path
        node = u
    recorded = sum(1 for p in path if p.kind == "recorded")
    planned = len(path) - recorded
    cost = recorded * config.recorded_cost + planned * config.planned_cost
    if m == 0:
        message = "no transferred steps (every step discarded): planner alone"
    else:
        message = f"{m} transferred steps"
    message += f"; {status}: {recorded} recorded and {planned} planned steps"
    if reached and timed_out:
        message += f" (CPU-time limit {config.time_limit} s reached: the planner alone)"
    if not reached:
        left = h_dist(end)
        message += f"; best partial path ends {left:.3f} m from the goal"
        if timed_out:
            message += f" (CPU-time limit {config.time_limit} s reached)"
        elif gap_cut:
            message += " (a gap filler's time limit reached)"
        if refusal:
            message += f"; gap filler: {refusal}"
    alone = fallback[6] if fallback is not None else math.nan
    return SearchResult(
        status, path, cost, recorded, planned, planner_calls, expanded, message, clock() - t0,
        alone,
    )  # fmt: skip
