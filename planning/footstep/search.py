"""A generic best-first (weighted A*) search over a robot's step model.

The search knows nothing about feet: a :class:`StepModel` gives the start
state, the successors of a state with their step costs, a hashable lattice key
for duplicate detection, a goal test and an admissible heuristic. The
quadruped crawl model (:mod:`repertoire.planning.footstep.quadruped`) is one
such model, the biped's table T (:mod:`repertoire.planning.footstep.biped_model`) another;
:func:`repertoire.planning.footstep.plan_footsteps` runs the biped through this core (or
through its compiled twin :mod:`repertoire.planning.footstep.fastcore`).

Statuses are honest:

- ``SUCCESS``: a goal state was expanded; the plan's cost is at most ``weight``
  times the optimum over the model's lattice (admissible heuristic).
- ``UNREACHABLE``: the open list was exhausted, so no state of the lattice
  reachable from the start satisfies the goal test.
- ``NODE_LIMIT`` / ``TIME_LIMIT``: the budget ran out first; the path is the
  best partial one (the expanded state with the lowest heuristic). The clock is read
  every 64 expansions (in the compiled core every 1024 past the first 4096), after at
  least one expansion.

:func:`anytime_search` is ARA*: weighted A* with decreasing weights that reuses
the search between weights (OPEN plus the INCONS list) and reports each plan with
its suboptimality bound.
"""

import dataclasses
import heapq
import inspect
import itertools
import math
import time
from collections.abc import Callable, Hashable, Iterable, Sequence
from typing import Any, Protocol

from repertoire.planning.footstep.types import FootstepError, PlanStatus

from repertoire.checks import is_real


class StepModel(Protocol):
    """What :func:`search` needs from a robot's step model."""

    def start(self) -> Any:
        """The start state."""

    def successors(self, state: Any) -> Iterable[tuple[Any, float]]:
        """``(next_state, step_cost)`` pairs, costs > 0.

        A model may take a second argument, ``dominated`` (see :func:`successor_function`):
        the search's test ``dominated(key, step_cost)``, true when the successor's lattice
        state is already reached at no more than the state's cost plus ``step_cost``. Such
        a successor would be dropped anyway, so the model may ask before its costly checks
        (footprint, heights, swing) and skip it; the search counts it as merged.
        """

    def key(self, state: Any) -> Hashable:
        """Lattice key for duplicate detection (equal keys = the same state)."""

    def is_goal(self, state: Any) -> bool:
        """True when ``state`` satisfies the goal."""

    def heuristic(self, state: Any) -> float:
        """Admissible lower bound on the cost to the goal."""


@dataclasses.dataclass
class SearchResult:
    """The outcome of one search.

    Attributes:
        status: see the module docstring.
        path: states from the start to the last state (goal, or best partial).
        cost: summed step costs along ``path``.
        weight: heuristic weight used; with SUCCESS, ``cost <= weight * optimum``.
        expansions: states expanded.
        seconds: wall time of the search.
        generated: successors evaluated (returned by the model; with a model that asks the
            search's ``dominated`` test, see :func:`successor_function`, those not
            dominated before its checks).
        merged: successors dropped because their lattice state was already reached at
            no higher cost (0 means no plan was discarded by duplicate detection).
        cost_to_go: the heuristic at the path's last state.
        bound: suboptimality bound of a SUCCESS (ARA*'s ``min(weight, cost / min f)``;
            ``weight`` for a single search).
    """

    status: PlanStatus
    path: list[Any]
    cost: float
    weight: float
    expansions: int
    seconds: float
    generated: int = 0
    merged: int = 0
    cost_to_go: float = 0.0
    bound: float = math.nan

    def __post_init__(self) -> None:
        if math.isnan(self.bound):
            self.bound = self.weight


def _validate_budget(weight: float, max_expansions: int, time_limit: float) -> None:
    for name, v in (("weight", weight), ("max_expansions", max_expansions)):
        if not is_real(v):
            raise FootstepError(f"search {name} must be a number, got {v!r}")
    if not is_real(time_limit):
        raise FootstepError(f"time_limit must be a number of seconds, got {time_limit!r}")
    if not (math.isfinite(weight) and weight >= 1.0):
        raise FootstepError(f"search weight must be a finite number >= 1, got {weight}")
    if int(max_expansions) != max_expansions or max_expansions < 1:
        raise FootstepError(f"max_expansions must be a positive integer, got {max_expansions}")
    if not (math.isfinite(time_limit) and time_limit > 0.0):
        raise FootstepError(f"time_limit must be a positive number of seconds, got {time_limit}")


def anytime_weights(weights: Sequence[float]) -> list[float]:
    """The weights of an anytime search as floats, checked.

    At least one weight, each finite and >= 1, none above the one before.

    Raises:
        FootstepError: a weight that is not such a number, or an empty or increasing list.
    """
    try:
        if isinstance(weights, (str, bytes)):  # its characters are no weights
            raise TypeError
        ws = [float(w) for w in weights]
    except (TypeError, ValueError):
        raise FootstepError(f"anytime weights must be numbers >= 1, got {weights!r}") from None
    if not ws or any(not (math.isfinite(w) and w >= 1.0) for w in ws):
        raise FootstepError(f"anytime weights must be numbers >= 1, got {list(weights)}")
    if any(b > a for a, b in itertools.pairwise(ws)):
        raise FootstepError(f"anytime weights must not increase, got {ws}")
    return ws


def successor_function(model: StepModel) -> Callable[[Any, Any], Iterable[tuple[Any, float]]]:
    """``successors(state, dominated)`` of ``model``; ``dominated`` dropped if it takes none.

    ``dominated(key, step_cost)`` is the search's duplicate test, asked before a
    successor's checks: true when that lattice state already has a cost no more than the
    expanded state's plus ``step_cost`` (the search counts the call as a merge). A model
    that asks it gives the same search for less work: plans, costs and expansions do not
    change; ``generated`` no longer counts the dominated successors, and ``merged``
    counts each of them whether or not it would have passed the checks (on 12 m floors at
    30 % clutter most successors are dominated; the compiled core skips their checks the
    same way).
    """
    try:
        takes = "dominated" in inspect.signature(model.successors).parameters
    except (TypeError, ValueError):
        takes = False
    if takes:
        return model.successors
    return lambda state, dominated: model.successors(state)


def _start_state(model: StepModel, require_successors: bool) -> Any:
    """``model.start()``, refused when it is no goal and has no successor (if required)."""
    start = model.start()
    if (
        require_successors
        and not model.is_goal(start)
        and not any(True for _ in model.successors(start))
    ):
        raise FootstepError(
            "the step model's successors of the start state are empty: no step is possible "
            "from the start (check the candidate set, reach and terrain around the start)"
        )
    return start


def search(
    model: StepModel,
    *,
    weight: float = 1.0,
    max_expansions: int = 200_000,
    time_limit: float = 10.0,
    require_successors: bool = True,
) -> SearchResult:
    """Weighted A* from ``model.start()`` to the first expanded goal state.

    Args:
        model: the step model.
        weight: heuristic inflation (1 = optimal A*).
        max_expansions: expansion budget (NODE_LIMIT when exhausted).
        time_limit: wall-time budget in s (TIME_LIMIT when exhausted).
        require_successors: refuse a start without successors (an empty step model); when
            False such a start gives UNREACHABLE (a robot boxed in by obstacles).

    Raises:
        FootstepError: bad budget, or a start state that is not a goal and has no
            successors (the step model offers no step at all).
    """
    _validate_budget(weight, max_expansions, time_limit)
    t0 = time.perf_counter()
    start = _start_state(model, require_successors)
    tie = itertools.count()
    start_key = model.key(start)
    g: dict[Hashable, float] = {start_key: 0.0}
    parent: dict[Hashable, Hashable | None] = {start_key: None}
    states: dict[Hashable, Any] = {start_key: start}
    closed: set[Hashable] = set()
    h0 = model.heuristic(start)
    open_list: list[tuple[float, float, int, Hashable]] = [(weight * h0, h0, next(tie), start_key)]
    best_key, best_h = start_key, h0
    expansions = generated = merged = 0
    status = PlanStatus.UNREACHABLE
    end_key = None
    successors = successor_function(model)
    g_state = 0.0
    # closed states reached again more cheaply (dropped all the same): the cost the
    # duplicate test compares with, as the compiled core's lattice table keeps it
    lowered: dict[Hashable, float] = {}

    def dominated(nkey: Hashable, step_cost: float) -> bool:
        nonlocal merged
        least = lowered.get(nkey)
        if g_state + step_cost >= (g.get(nkey, math.inf) if least is None else least):
            merged += 1
            return True
        return False

    while open_list:
        _, h, _, key = heapq.heappop(open_list)
        if key in closed:
            continue
        state = states[key]
        if model.is_goal(state):
            status, end_key = PlanStatus.SUCCESS, key
            break
        if expansions >= max_expansions:
            status = PlanStatus.NODE_LIMIT
            break
        if expansions and (expansions & 63) == 0 and time.perf_counter() - t0 > time_limit:
            status = PlanStatus.TIME_LIMIT
            break
        closed.add(key)
        expansions += 1
        g_state = g[key]
        if h < best_h or (h == best_h and g_state < g[best_key]):
            best_key, best_h = key, h
        for nxt, step_cost in successors(state, dominated):
            generated += 1
            nkey = model.key(nxt)
            g_new = g_state + step_cost
            if nkey in closed:
                merged += 1
                if g_new < lowered.get(nkey, g[nkey]):
                    lowered[nkey] = g_new
                continue
            if g_new >= g.get(nkey, math.inf):
                merged += 1
            else:
                g[nkey] = g_new
                parent[nkey] = key
                states[nkey] = nxt
                h_new = model.heuristic(nxt)
                heapq.heappush(open_list, (g_new + weight * h_new, h_new, next(tie), nkey))
    if end_key is None:
        end_key = best_key
    path_keys = []
    k: Hashable | None = end_key
    while k is not None:
        path_keys.append(k)
        k = parent[k]
    path_keys.reverse()
    return SearchResult(
        status=status,
        path=[states[k] for k in path_keys],
        cost=g[end_key],
        weight=weight,
        expansions=expansions,
        seconds=time.perf_counter() - t0,
        generated=generated,
        merged=merged,
        cost_to_go=model.heuristic(states[end_key]),
    )


def anytime_search(
    model: StepModel,
    *,
    weights: Sequence[float] = (3.0, 2.0, 1.5, 1.2, 1.0),
    max_expansions: int = 200_000,
    time_limit: float = 1.0,
    require_successors: bool = True,
) -> list[SearchResult]:
    """ARA* (Likhachev et al. 2003): weighted A* that reuses its search as the weight drops.

    The first search (the largest weight) is exactly :func:`search`. Each later one starts
    from the previous open list plus the INCONS list (states whose cost improved after they
    were expanded) with the new weight, and re-expands only states whose cost changed, so
    better plans come for a fraction of a fresh search. Each result reports its weight and
    ``bound = min(weight, cost / min over OPEN u INCONS of (g + h))``: with an admissible
    heuristic the plan costs at most ``bound`` times the optimum. A weight not below the
    last plan's bound is skipped (its search could only promise what that plan already
    has), so the time goes to the weights that can tighten it. States merged on the
    lattice keep their continuous poses: a state that improves after its expansion becomes
    a new node, so every path stays a chain of real successors.

    Args:
        model: the step model.
        weights: decreasing weights, each >= 1.
        max_expansions: expansion budget over all the searches.
        time_limit: total wall-time budget in s.
        require_successors: as in :func:`search`.

    Returns:
        one result per search that ran (skipped weights have none): SUCCESS ones carry
        improving plans; the last may end in TIME_LIMIT / NODE_LIMIT (best partial plan, or
        the previous plan's path when one exists) or UNREACHABLE.

    Raises:
        FootstepError: bad weights or budget, or an empty step model (see :func:`search`).
    """
    ws = anytime_weights(weights)
    _validate_budget(ws[0], max_expansions, time_limit)
    t0 = time.perf_counter()
    start = _start_state(model, require_successors)
    # nodes: parallel lists; a lattice key maps to its latest node
    states, g, h, parent = [start], [0.0], [model.heuristic(start)], [-1]
    expanded_in, in_open, in_incons = [-1], [True], [False]
    index: dict[Hashable, int] = {model.key(start): 0}
    best, best_h = 0, h[0]
    expansions = generated = merged = 0
    results: list[SearchResult] = []
    solution = -1
    met = math.inf  # the bound the last plan reported
    successors = successor_function(model)
    gi = 0.0

    def dominated(nkey: Hashable, step_cost: float) -> bool:
        nonlocal merged
        j = index.get(nkey)
        if j is not None and gi + step_cost >= g[j]:
            merged += 1
            return True
        return False

    for it, w in enumerate(ws):
        if w >= met:  # that plan already meets what this weight would promise: skipped
            continue
        t_it = time.perf_counter()
        heap = []
        for i in range(len(states)):
            if in_open[i] or in_incons[i]:
                heap.append((g[i] + w * h[i], h[i], len(heap), i))
                in_open[i], in_incons[i] = True, False
        heapq.heapify(heap)
        tie = len(heap)
        status, end, exp_it = PlanStatus.UNREACHABLE, -1, 0
        while heap:
            _, hh, _, i = heapq.heappop(heap)
            if expanded_in[i] == it:
                continue
            if model.is_goal(states[i]):
                status, end = PlanStatus.SUCCESS, i
                break
            if expansions >= max_expansions:
                status = PlanStatus.NODE_LIMIT
                break
            if expansions and (expansions & 63) == 0 and time.perf_counter() - t0 > time_limit:
                status = PlanStatus.TIME_LIMIT
                break
            in_open[i], expanded_in[i] = False, it
            expansions += 1
            exp_it += 1
            gi = g[i]
            if hh < best_h or (hh == best_h and gi < g[best]):
                best, best_h = i, hh
            for nxt, step_cost in successors(states[i], dominated):
                generated += 1
                nkey = model.key(nxt)
                g2 = gi + step_cost
                j = index.get(nkey)
                closed_now = False
                if j is not None:
                    closed_now = expanded_in[j] == it or in_incons[j]
                    if closed_now or g2 >= g[j]:
                        merged += 1
                    if g2 >= g[j]:
                        continue
                    if expanded_in[j] >= 0:  # has children: a new node keeps them consistent
                        j = None
                h2 = model.heuristic(nxt)
                if j is None:
                    j = len(states)
                    states.append(nxt)
                    g.append(g2)
                    h.append(h2)
                    parent.append(i)
                    expanded_in.append(-1)
                    in_open.append(not closed_now)
                    in_incons.append(closed_now)
                    index[nkey] = j
                else:
                    states[j], g[j], h[j], parent[j] = nxt, g2, h2, i
                if not in_incons[j]:
                    heapq.heappush(heap, (g2 + w * h2, h2, tie, j))
                    tie += 1
        bound = w
        if status is PlanStatus.SUCCESS:
            solution = end
            low = min(
                (g[k] + h[k] for k in range(len(states)) if in_open[k] or in_incons[k]),
                default=g[end],
            )
            # a plan of cost 0 (the start meets the goal) is optimal: bound 1
            bound = min(w, g[end] / low) if low > 0 else (1.0 if g[end] == 0.0 else w)
            met = bound
        last = end if end >= 0 else (solution if solution >= 0 else best)
        path = []
        k = last
        while k >= 0:
            path.append(states[k])
            k = parent[k]
        path.reverse()
        results.append(
            SearchResult(
                status=status,
                path=path,
                cost=g[last],
                weight=w,
                expansions=exp_it,
                seconds=time.perf_counter() - t_it,
                generated=generated,
                merged=merged,
                cost_to_go=h[last],
                bound=bound,
            )
        )
        if status is not PlanStatus.SUCCESS:
            break
    return results
