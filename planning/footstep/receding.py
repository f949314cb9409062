"""Receding-horizon footstep planning: plan within a budget, walk a few steps, plan again.

This is how a time-limited planner is used on a robot (the paper's "limited-horizon search
that computes the best partial footstep path it can find in the time allowed"): each
round plans from the current state with the given options (time limit or node budget),
commits the first ``execute_steps`` steps of the (possibly partial) plan, and continues
from there with the right stance foot, swing foot, action history and time. A partial
plan may end where no step is possible any more (in a dynamic world, an obstacle about to
cover the feet); when the next round proves the end of the committed steps such a trap
(UNREACHABLE from there), a shorter prefix is committed instead, and the trap is a dead end
that no later round's search enters (:func:`~repertoire.planning.footstep.planner.plan_state`,
``dead_ends``). When even the first step ends in a proved trap, nothing is committed and the
round is planned again from the same state around the traps. A trap whose proof needs more
than a round's budget can still be committed: a round that then proves the state it starts
from cut off ends the plan UNREACHABLE, naming that state.
"""

import dataclasses
import math
from collections.abc import Callable, Sequence

from repertoire.planning.footstep.actions import ASIMO_LIKE, BipedGeometry
from repertoire.planning.footstep.environment import DynamicEnvironment, OccupancyGrid
from repertoire.planning.footstep.planner import (
    PlannerOptions,
    _options,
    plan_footsteps,
    plan_state,
)
from repertoire.planning.footstep.types import (
    ActionTable,
    Foot,
    FootstepError,
    FootstepPlan,
    PlanStatus,
)

from repertoire.checks import is_real

THINK_LONGER_DOUBLINGS = 6
"""How often a round that found no step is planned again with twice the budget (at most
64 times the round's budget in all)."""


@dataclasses.dataclass
class RecedingResult:
    """Outcome of :func:`plan_receding_horizon`.

    Attributes:
        plan: the committed steps of every round joined into one plan (status SUCCESS
            when it reaches the goal, else the last round's status); its cost is the sum
            of the committed actions' step costs, its planning time and node counts the
            sums over the rounds; its ``reason`` the last round's (an UNREACHABLE of a
            later round says from which committed state: the start itself was not proved
            cut off).
        rounds: planner calls made (also those of prefixes found to end in a trap and
            those planned again around a trap).
        statuses: status of every planner call, in order.
    """

    plan: FootstepPlan
    rounds: int
    statuses: list[str]


def plan_receding_horizon(
    world: "OccupancyGrid | DynamicEnvironment",
    start: Sequence[float],
    start_foot: "Foot | int | str",
    goal: Sequence[float],
    table: ActionTable,
    options: "PlannerOptions | None",
    *,
    execute_steps: int = 4,
    max_rounds: int = 30,
    geometry: BipedGeometry = ASIMO_LIKE,
    start_time: float = 0.0,
) -> RecedingResult:
    """Plan, commit ``execute_steps`` steps, replan from there, until the goal is reached.

    Args:
        world: the grid or time-indexed grids.
        start: ``(x, y, yaw)`` of the starting stance foot.
        start_foot: which foot stands at ``start``.
        goal: ``(x, y)``.
        table: the action table.
        options: planner options of every round (its time limit is the per-round budget);
            None: the defaults, as in :func:`plan_footsteps`.
        execute_steps: steps committed per round (a successful plan is committed whole;
            fewer when the next round proves their end a trap, down to none: then the
            round is planned again around the proved traps). A round whose budget found
            no step at all (its best partial plan is its start) is planned again with
            twice the budget and time limit, doubling until it finds one (at most
            ``THINK_LONGER_DOUBLINGS`` times).
        max_rounds: give up after this many rounds.
        geometry: robot geometry.
        start_time: time of the start state (s).
    """
    for name, value in (("execute_steps", execute_steps), ("max_rounds", max_rounds)):
        if not is_real(value) or not math.isfinite(value) or int(value) != value or value < 1:
            raise FootstepError(f"{name} must be an integer >= 1, got {value!r}")
    options = _options(options)  # None: the defaults (validated once, named if wrong)
    plan = plan_footsteps(
        world, start, start_foot, goal, table, options, geometry=geometry, start_time=start_time
    )
    calls = [plan]  # every planner call (its nodes and time count, committed or not)
    poses, feet, times = [plan.poses[0]], [plan.feet[0]], [plan.times[0]]
    actions: list[str] = []
    swing0, history0 = plan.initial_swing_pose, plan.initial_history
    first = True  # the plan in hand is from the caller's start
    dead: set[tuple] = set()  # states proved to have no plan: no round's search enters them

    def again(j: int) -> FootstepPlan:  # the round after the first j steps of ``plan``
        calls.append(_next_round(plan, j, world, goal, table, options, geometry, dead))
        return calls[-1]

    def think_longer(p: FootstepPlan, grown: PlannerOptions) -> FootstepPlan:  # p's round
        return _next_round(p, 0, world, goal, table, grown, geometry, dead)

    while True:
        plan = _think_longer(plan, options, think_longer, calls, max_rounds)
        k = plan.num_steps if plan.succeeded else min(execute_steps, plan.num_steps)
        if plan.status is PlanStatus.UNREACHABLE:
            k = 0  # no step from here reaches the goal: nothing more is committed
        nxt = None
        if not (plan.succeeded or k == 0 or len(calls) >= max_rounds):
            # commit the longest prefix (up to k steps) whose end the next round does not
            # prove a trap: a partial plan may end where no step is possible any more (an
            # obstacle about to cover the feet), and committing it walks the robot in there.
            # A proved trap is never entered again (every later round plans around it)
            for j in range(k, 0, -1):
                nxt = again(j)
                if nxt.status is not PlanStatus.UNREACHABLE or len(calls) >= max_rounds:
                    break
                dead.add(plan_state(plan, j, table))
            else:  # even the first step ends in a proved trap: this round again, from the
                j, nxt = 0, again(0)  # same state, around the traps (nothing committed)
            k = j
        poses += plan.poses[1 : k + 1]
        feet += plan.feet[1 : k + 1]
        times += plan.times[1 : k + 1]
        actions += plan.actions[:k]
        if nxt is None:
            break
        plan, first = nxt, first and k == 0
    rounds, statuses = len(calls), [c.status.value for c in calls]
    if plan.status is PlanStatus.UNREACHABLE and not first:
        # the last round's start is where earlier rounds' partial plans led, not the
        # caller's start: say so (the caller's start was not proved cut off)
        at = plan.poses[0]
        plan.reason = (
            f"from the state the committed steps reached at ({at[0]:.3f}, {at[1]:.3f}, "
            f"{at[2]:.3f}) t = {plan.times[0]:.3f} s (round {rounds}) no step sequence reaches "
            "the goal; the earlier rounds ended at their limits with partial plans, so the "
            "start was not proved cut off" + (f": {plan.reason}" if plan.reason else "")
        )
    if plan.succeeded:
        ctg = 0.0
    else:  # the estimate at the last committed pose: a planner call that expands only it
        ctg = plan_footsteps(
            world,
            poses[-1],
            feet[-1],
            goal,
            table,
            dataclasses.replace(options, max_expansions=1),
            geometry=geometry,
            initial_swing_pose=poses[-2] if len(poses) > 1 else swing0,
            start_time=times[-1],
            initial_history=(list(history0) + actions)[-2:],
        ).cost_to_go
    joined = FootstepPlan(
        poses=[list(p) for p in poses],
        feet=list(feet),
        actions=actions,
        times=list(times),
        status=PlanStatus.SUCCESS if plan.succeeded else plan.status,
        cost=float(sum(table.step_cost[table.index(a)] for a in actions)),
        cost_to_go=ctg,
        nodes_expanded=sum(c.nodes_expanded for c in calls),
        nodes_generated=sum(c.nodes_generated for c in calls),
        planning_time_s=sum(c.planning_time_s for c in calls),
        initial_swing_pose=list(swing0),
        goal=list(plan.goal),
        goal_tolerance=plan.goal_tolerance,
        initial_history=list(history0),
        reason="" if plan.succeeded else plan.reason,
    )
    return RecedingResult(joined, rounds, statuses)


def _think_longer(
    plan: FootstepPlan,
    options: PlannerOptions,
    replan: "Callable[[FootstepPlan, PlannerOptions], FootstepPlan]",
    calls: list[FootstepPlan],
    max_rounds: int,
) -> FootstepPlan:
    """A round that found no step, planned again from its start with twice the budget.

    ``replan(plan, options)`` plans ``plan``'s round again from its start. Node budget and
    time limit double until the round finds a step, ends otherwise, the
    rounds run out or the budget has doubled ``THINK_LONGER_DOUBLINGS`` times; each call is
    appended to ``calls``.

    Without this a round whose best partial plan is its own start (every state its budget
    reached lies farther from the goal: a row of blocks in front) committed nothing and
    ended the whole run, although a little more search finds a way on (waiting, a side
    step). The next round starts from the base budget again.
    """
    grown = options
    for _ in range(THINK_LONGER_DOUBLINGS):
        if not (
            plan.num_steps == 0
            and plan.status in (PlanStatus.NODE_LIMIT, PlanStatus.TIME_LIMIT)
            and len(calls) < max_rounds
        ):
            break
        grown = dataclasses.replace(
            grown,
            time_limit=2.0 * grown.time_limit,
            max_expansions=2 * grown.max_expansions,  # 0 (no node budget) stays 0
        )
        calls.append(replan(plan, grown))
        plan = calls[-1]
    return plan


def _next_round(
    plan: FootstepPlan,
    k: int,
    world: "OccupancyGrid | DynamicEnvironment",
    goal: Sequence[float],
    table: ActionTable,
    options: PlannerOptions,
    geometry: BipedGeometry,
    dead: set[tuple],
) -> FootstepPlan:
    """The round that starts after committing ``plan``'s first ``k`` steps, around ``dead``."""
    return plan_footsteps(
        world,
        plan.poses[k],
        plan.feet[k],
        goal,
        table,
        options,
        dead_ends=dead,
        geometry=geometry,
        initial_swing_pose=plan.poses[k - 1] if k else plan.initial_swing_pose,
        start_time=plan.times[k],
        initial_history=(list(plan.initial_history) + plan.actions)[k : k + 2],
    )
