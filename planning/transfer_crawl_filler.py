"""Gap filler for the transfer search from the footstep planner's quadruped crawl model.

Adapts :func:`repertoire.planning.footstep.quadruped.plan_crawl` (the
second-generation footstep planner, issue 9) to the :class:`GapFiller` protocol of
:mod:`repertoire.planning.transfer_search`: one planner, not a second copy.

The crawl planner's goal is a point for the feet's centroid (within its
``goal_radius``) and a heading (within its ``heading_tolerance``), not a whole
stance: a filled gap ends with the feet's centroid near the target stance's
centroid and their heading near the target's (:func:`heading_of`: the crawl turns
the body, so a recorded step matched with a yaw can be joined); the remaining foot
offsets (up to the goal radius plus the lattice's offsets) are placed
(``place_feet``) or left to the executor that starts the next recorded step.
Planned footholds (ground points) are raised by the foot radius to foot centres,
like library stances. The planner's statuses map to the protocol's:
SUCCESS -> reached, TIME_LIMIT and NODE_LIMIT -> time_limit (its budget ran out:
whether the target can be reached is open), anything else -> failed.

The search's time limit is CPU time; the crawl planner measures wall time, which
under load runs ahead of CPU time. Its budget per gap is therefore its expansion count
(``max_expansions``, the same on any machine) with a wall-time safety limit of at least
``planner_wall_limit``, and the search checks its CPU budget between gaps. The expansion
budget must be the one that binds: a gap cut by wall time depends on the machine's load.
Until session 37 it was 50000 expansions under a 10 s wall limit, at 1.3-2.3 ms of CPU
per expansion on boards of 5-6 cm rocks (65-115 s of CPU), so the wall limit decided
every long gap: under load such gaps got 1.6-6.5 s of CPU and ended TIME_LIMIT
(the planner alone on pair 946/947: 2752 expansions in 10.2 s of wall time at 3.5 s of
CPU; alone it plans in 4896 expansions, 6.8 s of CPU). Now 5000 expansions, about the
search's default 10 s of CPU at 2 ms each, under a 60 s wall limit (a load of 6 still
leaves the expansions to bind). On the matching study (seeds 2-7) every gap call
succeeded within 78 expansions, and a half turn on the modified terrain takes 285, so
the budget decides only on hard terrain; the search's CPU budget can be overrun by one
gap's budget.
"""

import dataclasses

import numpy as np
from repertoire.models.littledog import FOOT_RADIUS
from repertoire.planning.footstep.quadruped import (
    CrawlParams,
    HeightMap,
    clear_of_faces,
    flat_on_ground,
    plan_crawl,
    swing_line_cells,
    swing_support_margin,
)
from repertoire.planning.footstep.types import FootstepError, PlanStatus
from repertoire.planning.littledog_crawl import CrawlError, CrawlStep, heading_of
from repertoire.planning.littledog_crawl import CrawlParams as ExecParams
from repertoire.planning.littledog_crawl import plan_crawl as execute_crawl
from repertoire.planning.transfer_search import GapFill, PlannedStep, TransferSearchError


def executable_prefix(steps: list[PlannedStep], params: ExecParams, board) -> int:
    """How many of ``steps`` the scripted crawl can execute from a level start (leg IK)."""
    from repertoire.planning.transfer_library import stance_pose

    if not steps:
        return 0
    feet0 = np.asarray(steps[0].start_feet, dtype=float)
    pose0 = stance_pose(feet0, params.standing_height)
    crawl = [CrawlStep(p.foot, np.asarray(p.end_feet, float)[p.foot]) for p in steps]
    try:
        execute_crawl(feet0, pose0, crawl, board, params, hold_time=params.dt)
    except CrawlError as e:
        k = _failed_step(str(e))
        return k if k is not None else 0
    return len(steps)


def _failed_step(message: str) -> int | None:
    import re

    m = re.search(r"step (\d+) \(moving foot", message)
    return int(m.group(1)) if m else None


@dataclasses.dataclass
class CrawlGapFiller:
    """A :class:`GapFiller` planning crawl steps on a height map.

    Attributes:
        height_map: the terrain (``height_map_from_board`` of the new terrain).
        params: crawl model parameters.
        weight: heuristic weight of the planner's search.
        max_expansions: expansion budget per planner call (the budget that binds; see
            the module docstring).
        crawl: parameters of the crawl that executes planned steps: the planner checks
            every step with its reach (:func:`~repertoire.planning.littledog_crawl.step_reachable`
            at the crawl's own body pose), and the whole gap is executed by it once more
            (:func:`executable_prefix`) before use.
        board: the terrain's exact height function (default: the map's cell heights; the
            executing crawl reads the board, so pass it when known). With a board the
            planner's swings clear it and every planned foot lands on flat exact ground
            clear of faces (:func:`~repertoire.planning.footstep.quadruped.flat_on_ground`,
            :func:`~repertoire.planning.footstep.quadruped.clear_of_faces`): the map
            samples heights at cell centres and misses edges between them, and a foot
            landing on an edge slides off (seen in physics).
        place_feet: with ``board``, end a reached gap with one-foot moves onto the target
            stance when its footholds are flat (a recorded step's start; not a goal, see
            ``place`` of ``__call__``), checked executable like the rest; the planner's
            steps are cut where fewer steps in all reach the stance
            (:meth:`shortest_placed`).
        place_within: summed foot offset (m) from the target stance left to the executor
            (:func:`~repertoire.planning.transfer_library.placing_steps`: the fewest feet
            are placed); 0 places every foot farther than 5 mm. Set it to the search's
            ``join_tolerance``, the offset it accepts between recorded steps.
        planner_wall_limit: the planner's wall-time limit per call is the larger of this
            and the search's remaining CPU budget (s): a safety limit, not the budget
            (long enough that ``max_expansions`` binds first even under load).
    """

    height_map: HeightMap
    params: CrawlParams = dataclasses.field(default_factory=CrawlParams)
    weight: float = 3.0
    max_expansions: int = 5_000
    crawl: ExecParams = dataclasses.field(default_factory=ExecParams)
    board: object = None
    place_feet: bool = False
    place_within: float = 0.0
    planner_wall_limit: float = 60.0

    def _plan(
        self, start: np.ndarray, goal_xy: np.ndarray, time_limit: float, heading=None,
        front_line=None,
    ):  # fmt: skip
        """Planned steps (foot centres) from ``start``, the planner's status and its refusal.

        ``heading``: the goal heading of the stance (rad), or None. ``front_line``: the
        planner's goal line for the front feet (see ``plan_crawl``), or None.

        A start or goal the planner refuses (e.g. on a rock's edge, or off its map) gives
        no steps, status None and the planner's message; a plan that does not reach the
        goal names its status and work (else the message is empty).
        """
        try:
            plan = plan_crawl(
                self.height_map,
                start - np.array([0.0, 0.0, FOOT_RADIUS]),  # ground contact points
                goal_xy,
                self.params,
                time_limit=max(float(time_limit), self.planner_wall_limit),
                max_expansions=self.max_expansions,
                weight=self.weight,
                crawl=self.crawl,
                ground=self.board,
                goal_heading=heading,
                front_line=front_line,
            )
        except FootstepError as e:
            return [], None, f"the crawl planner refused: {e}"
        steps: list[PlannedStep] = []
        cur = start.copy()
        for s in plan.steps:
            # The planner's footholds are ground contact points; stances here are foot centres.
            nxt = np.asarray(s.stance, dtype=float) + np.array([0.0, 0.0, FOOT_RADIUS])
            steps.append(PlannedStep(cur, nxt, int(s.foot)))
            cur = nxt
        why = ""
        if plan.status is not PlanStatus.SUCCESS:
            why = (
                f"the crawl planner ended with {plan.status.value} after {plan.expansions} "
                f"expansions ({plan.seconds:.2f} s), {len(steps)} steps towards the target"
            )
        return steps, plan.status, why

    def within_step_rules(self, step: PlannedStep) -> bool:
        """Whether ``step`` keeps the planner's height rules on its height map.

        The foot's height change at most ``max_step_height``, and no cell along the straight
        swing line higher than ``swing_clearance`` above the higher foothold: the checks
        the planner makes of its own steps (so they hold for them by construction), made of
        the placing moves too.
        """
        m, p = self.height_map, self.params
        f = int(step.foot)
        a = np.asarray(step.start_feet, dtype=float)[f] - np.array([0.0, 0.0, FOOT_RADIUS])
        b = np.asarray(step.end_feet, dtype=float)[f] - np.array([0.0, 0.0, FOOT_RADIUS])
        if abs(b[2] - a[2]) > p.max_step_height + 1e-12:
            return False
        (r0, r1), (c0, c1) = m.cell([a[0], b[0]], [a[1], b[1]])
        rows, cols = swing_line_cells(int(r0), int(c0), int(r1), int(c1))
        ok = m.inside(rows, cols)
        line = m.heights[rows[ok], cols[ok]]
        return bool(ok.all() and line.max() <= max(a[2], b[2]) + p.swing_clearance + 1e-12)

    def usable_prefix(self, steps: list[PlannedStep]) -> int:
        """How many of ``steps`` the executing crawl can do (stable, flat footholds, leg IK).

        The planner's steps meet its rules by construction; moves added after it (placing
        the feet on a recorded step's start) are held to the same ones: static stability
        (:func:`~repertoire.planning.footstep.quadruped.swing_support_margin`, a
        placing move off the support triangle tipped the robot over in physics), its
        height rules (:meth:`within_step_rules`), flat
        footholds clear of faces
        (:func:`~repertoire.planning.footstep.quadruped.clear_of_faces`) and the crawl's
        leg IK.
        """
        board = self.height_map if self.board is None else self.board
        stable = [
            swing_support_margin(p.start_feet, p.foot, self.params) >= self.params.support_margin
            and self.within_step_rules(p)
            for p in steps
        ]
        n = stable.index(False) if not all(stable) else len(steps)
        if self.board is not None and steps:
            landing = np.array([p.end_feet[p.foot, :2] for p in steps])
            flat = flat_on_ground(self.board, landing, self.params)
            flat &= clear_of_faces(self.board, landing, self.params)
            n = min(n, int(np.argmin(flat))) if not flat.all() else n
        return executable_prefix(steps[:n], self.crawl, board) if n else 0

    def shortest_placed(
        self, start: np.ndarray, steps: list[PlannedStep], target: np.ndarray
    ) -> list[PlannedStep] | None:
        """The fewest steps onto ``target``: a prefix of ``steps`` and placing moves, or None.

        The planner aims at the target's centroid and knows nothing of its footholds, so
        its last steps may move feet to places the placing moves then move them away from
        (execution study start 1007: 6 planned steps to the centroid, the feet still 20.8
        cm in sum from the recorded step's start, 3 placing moves after them, 9 steps for
        10 cm of body travel). Each prefix ``steps[:k]`` (k = 0 .. len) followed by
        :func:`~repertoire.planning.transfer_library.placing_steps` onto ``target`` is a
        candidate; the shortest one the crawl can execute (:meth:`usable_prefix`: the
        placing moves held to the planner's rules) is returned, the longer prefix on a tie
        (the whole plan and its placing moves unless fewer steps do). Every step costs the
        robot one crawl cycle whatever its length, so fewer steps is what the search's
        cost of a gap should count. None when no candidate is executable.
        """
        from repertoire.planning.transfer_library import placing_steps

        candidates = []
        for k in range(len(steps) + 1):
            end, before = (steps[k - 1].end_feet, steps[k - 1].start_feet) if k else (start, None)
            moves = placing_steps(end, target, within=self.place_within, before=before)
            candidates.append((k + len(moves), -k, steps[:k] + moves))
        for _, _, candidate in sorted(candidates, key=lambda c: c[:2]):
            if self.usable_prefix(candidate) == len(candidate):
                return candidate
        return None

    def __call__(
        self,
        start: np.ndarray,
        target: np.ndarray,
        time_limit: float,
        front_line=None,
        place: bool = True,
    ) -> GapFill:
        """Plans crawl steps from ``start`` (4, 3) towards ``target``'s centroid and heading.

        ``front_line``: ``(nx, ny, d)``, the gap must also end with both front feet at
        ``n . p >= d`` (a task's goal line; the planner's goal test, see ``plan_crawl``).
        ``place``: False for a target reached by the planner's goal test alone (a goal
        stance checked by its centroid and a line, not a recorded step's start): no feet
        are placed onto it whatever ``place_feet`` says. Placing feet onto a made-up goal
        stance added up to four planned steps to a gap (rock seed 8: 12 instead of 8 from
        the recorded run's end, so the search kept 5 recorded steps instead of 11) and,
        where its footholds lay on a rock, put feet 4 cm into it (rock seed 31).
        """
        start = np.asarray(start, dtype=float)
        target = np.asarray(target, dtype=float)
        if start.shape != (4, 3) or target.shape != (4, 3):
            raise TransferSearchError(
                f"crawl gap filler needs (4, 3) stances, got {start.shape} and {target.shape}"
            )
        for name, stance in (("start", start), ("target", target)):
            if not np.all(np.isfinite(stance)):
                raise TransferSearchError(
                    f"crawl gap filler needs finite stances, got {name} {stance.tolist()}"
                )
        if not isinstance(place, bool | np.bool_):
            raise TransferSearchError(f"crawl gap filler: place must be a bool, got {place!r}")
        goal_xy = target[:, :2].mean(axis=0)
        if place and self.place_feet and self.board is not None:
            from repertoire.planning.littledog_crawl import foothold_ok

            # A recorded step's start (flat footholds): the gap ends on its exact stance,
            # so the nearest-step policy picks it next; unreachable placing = gap unusable.
            place = bool(np.all(foothold_ok(self.board, target[:, :2], self.crawl)))
        else:
            place = False
        new, status, refusal = self._plan(
            start, goal_xy, time_limit, heading_of(target), front_line
        )
        if status is PlanStatus.SUCCESS and place:
            shortest = self.shortest_placed(start, new, target)
            if shortest is not None:
                return GapFill(shortest, "reached", refusal)
        planned = len(new)
        if status is PlanStatus.SUCCESS and place:
            from repertoire.planning.transfer_library import placing_steps

            end, before = (new[-1].end_feet, new[-1].start_feet) if new else (start, None)
            new += placing_steps(end, target, within=self.place_within, before=before)
        usable = self.usable_prefix(new)
        if usable == len(new):
            return GapFill(new, _status(status), refusal)
        if usable >= planned and status is PlanStatus.SUCCESS:
            # The planner's steps reach the target's centroid but the legs cannot place
            # every foot on the target stance: enough for a goal (the search joins a
            # recorded step only on its exact start, so it will not join one this way).
            return GapFill(new[:planned], "reached")
        # The planner checks each step with the crawl's own reach and flat-foothold rules;
        # what it does not check (the body shift between two steps' poses) ends the gap.
        return GapFill(
            new[:usable],
            "partial" if usable else "failed",
            refusal or f"the crawl cannot execute planned step {usable} of {len(new)}",
        )


def _status(status) -> str:
    if status is PlanStatus.SUCCESS:
        return "reached"
    if status in (PlanStatus.TIME_LIMIT, PlanStatus.NODE_LIMIT):
        return "time_limit"
    return "failed"
