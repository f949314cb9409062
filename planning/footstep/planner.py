"""A* footstep planner over state-dependent actions (Chestnutt et al., Algorithm 1).

The search space and successors are the biped step model
(:class:`~repertoire.planning.footstep.biped_model.BipedStepModel`: the table T, F, the
footprint checks and the lattice key); the search loop is the generic weighted A*
(:func:`repertoire.planning.footstep.search.search`) or, for static grids, its compiled
twin (:mod:`repertoire.planning.footstep.fastcore`), which gives the same plans. The queue
is ordered by ``g + w h`` with ``h`` the expected cost-to-go. States are merged on a
lattice of ``xy_resolution`` x ``yaw_bins`` (x time bins in dynamic worlds) while the poses
themselves stay continuous, so a plan's poses are exactly what T predicts. When the time
limit runs out, or the open list is exhausted, the best partial plan (smallest cost-to-go)
is returned with its status.
"""

import dataclasses
import math
import time
from collections.abc import Collection, Iterator, Sequence

import numpy as np
from repertoire.planning.footstep.actions import ASIMO_LIKE, BipedGeometry
from repertoire.planning.footstep.biped_model import (
    ActionFilter,
    BipedState,
    BipedStepModel,
    history_classes,
    sole_masks,
)
from repertoire.planning.footstep.cores import _ara, _backend, _search_once
from repertoire.planning.footstep.environment import DynamicEnvironment, OccupancyGrid
from repertoire.planning.footstep.fastkernels import MASK_WORD_CELLS, _cached_mask_bits
from repertoire.planning.footstep.reachability import goal_cut_off
from repertoire.planning.footstep.search import SearchResult, anytime_weights
from repertoire.planning.footstep.types import (
    ActionTable,
    Foot,
    FootstepError,
    FootstepPlan,
    PlanStatus,
)

from repertoire.checks import is_real

__all__ = [
    "ActionFilter",
    "AnytimePlan",
    "PlannerOptions",
    "history_classes",
    "plan_footsteps",
    "plan_footsteps_anytime",
    "plan_state",
]

BACKENDS = ("auto", "compiled", "python")
# with corridor searches, the share of the time left after the first plan that ARA* may
# spend on the whole map before the best plan is improved in its corridor
ARA_SHARE = 0.25
HEURISTICS = ("dijkstra", "euclidean", "none")


@dataclasses.dataclass
class PlannerOptions:
    """Options of :func:`plan_footsteps`.

    Attributes:
        time_limit: wall-time budget of the search (s), > 0.
        heuristic: ``"dijkstra"`` (backward 2-D Dijkstra, informed, inadmissible; static
            grids only), ``"euclidean"`` (straight-line distance, admissible) or ``"none"``
            (uniform-cost search).
        heuristic_weight: w in ``g + w h`` (>= 1: with the admissible ``"euclidean"``
            heuristic a plan costs at most w times the lattice's optimum).
        goal_tolerance: the goal is reached when the stance foot centre is within this
            distance of the goal point (m).
        obstacle_cost: Dijkstra traversal cost per metre over occupied cells (free = 1).
        step_over_depth: occupied cells deeper than this inside an obstacle (distance to
            the nearest free cell, m) cost ``10 obstacle_cost`` in the Dijkstra heuristic
            (too thick to step over); negative: derived from the table as half of (longest
            forward step - foot length) plus one cell; ``inf``: every obstacle may be
            crossed at ``obstacle_cost``.
        xy_resolution: lattice spacing used to merge states (m); poses stay continuous,
            states closer than this (same foot, yaw bin and history class) are one state.
        yaw_bins: yaw bins per turn used to merge states.
        time_resolution: time bins used to merge states in dynamic worlds (s).
        height_cost_weight: location cost per metre of height variation under a foot (max
            minus min height over the cells the sole may overlap, its outer mask).
        max_expansions: stop after this many expansions with status NODE_LIMIT (0 = no
            limit); a deterministic budget for reproducible studies.
        footprint_margin_m: clearance (m, >= 0) kept between a planned footprint and any
            occupied cell: the foot rectangle is inflated by this much on every side for the
            obstacle check of landings (0 keeps the exact check). The start feet are checked
            exactly (they already stand there).
        refinements: when the open list runs empty after states were merged (a successor
            dropped because its lattice cell was already reached), the search is repeated
            with half the ``xy_resolution`` and twice the ``yaw_bins`` (and, where a cell is
            taller than the swing clearance, keyed on the swing foot's start too: the step
            model's ``swing_start_states``), up to this many
            times within the time limit, so UNREACHABLE is reported only when the lattice
            reachable from the start is exhausted at the finest resolution tried (recorded
            in the plan). 0 keeps one search. The default, 3, ends at 0.625 cm / 288 bins
            from the default lattice: a 2 m stepping-stone field with 10 cm gaps was
            UNREACHABLE at 1.25 cm / 144 and has a plan at 0.625 cm / 288. A time limit that
            runs out before the finest lattice is exhausted gives TIME_LIMIT.
        swing_clearance: how high (m) the swing foot rises above the highest of the stance
            sole's and the landing sole's ground (each the highest of the grid's
            ``heights`` under the sole) and the ground of the cell it lifts from (down a
            stair, the trailing foot's tread): a step whose straight centre line from the swing
            foot's previous position to its landing passes through the interior of a cell
            higher than that, occupied or free ground, is refused (exact grid traversal: a
            line through a cell's corner point only, or along its edge, does not cross it);
            on ground level 0 that is every cell taller than this; on a 0.3 m platform a
            0.35 m kerb is 5 cm tall; in a dynamic world, a cell's highest height in any
            grid of E(t) from the step's start to its landing. ``inf`` (the default) or a
            grid without heights: every flat obstacle may be stepped over.
        max_height_range: a foot lands only where the height range under its sole (the
            grid's ``heights``) is at most this (m): flat enough ground. The start feet
            must satisfy it too. ``inf`` (the default): no flatness limit. Measured
            conservatively over every cell the sole may overlap (its outer mask, up to about
            a third of a cell beyond the sole), so a sole beside a step may be refused
            although the ground it overlaps is within the limit.
        max_step_up: a step may raise the foot by at most this (m): the highest ground
            under the landing sole minus the highest under the stance sole, each the max of
            the grid's ``heights`` over the cells the sole rectangle overlaps with positive
            area (the cells the collision check counts; touching an edge is not
            overlapping); ``inf`` (the default) or no heights: no limit.
        max_step_down: the same for lowering the foot (m).
        backend: ``"python"`` (the generic search loop), ``"compiled"`` (the numba core,
            static grids only, footprint masks up to 64 cells across; the same plans) or
            ``"auto"`` (compiled where it applies, else python: dynamic worlds, and grids so
            fine, or margins so wide, that a foot's mask spans more than 64 cells, e.g.
            cells of 3.7 mm or less for the nominal foot with the default margin).
    """

    time_limit: float = 1.0
    heuristic: str = "dijkstra"
    heuristic_weight: float = 1.5
    goal_tolerance: float = 0.15
    obstacle_cost: float = 3.0
    step_over_depth: float = -1.0
    xy_resolution: float = 0.05
    yaw_bins: int = 36
    time_resolution: float = 0.1
    height_cost_weight: float = 0.0
    max_expansions: int = 0
    footprint_margin_m: float = 0.01
    refinements: int = 3
    swing_clearance: float = math.inf
    max_height_range: float = math.inf
    max_step_up: float = math.inf
    max_step_down: float = math.inf
    backend: str = "auto"

    @classmethod
    def admissible(cls, **overrides: float) -> "PlannerOptions":
        """Options for optimal plans: Euclidean heuristic (admissible), weight 1, fine lattice.

        Optimal with respect to the state lattice: states closer than ``xy_resolution``
        and ``yaw_bins`` are merged (2.5 cm and 5 degrees here), exactly so when the table's
        displacements lie on that lattice. Otherwise a merged state keeps the pose of its
        cheapest arrival, and in dense clutter a route that needs another pose a few
        millimetres away is lost: on ``random_floor_scene(20)`` (12 m, 30 % occupied) this
        mode finds 107.2, 90.45 on 1.25 cm / 144 bins, where a plan of 73.85 exists.

        Args:
            **overrides: other fields to set.
        """
        base = {
            "heuristic": "euclidean",
            "heuristic_weight": 1.0,
            "xy_resolution": 0.025,
            "yaw_bins": 72,
        }
        return cls(**{**base, **overrides})

    def validate(self) -> None:
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if f.type in ("float", "int", float, int) and not is_real(v):
                raise FootstepError(f"{f.name} must be a number, got {v!r}")
        if not (is_real(self.time_limit) and math.isfinite(self.time_limit)):
            raise FootstepError(
                f"time_limit must be a finite number of seconds, got {self.time_limit}"
            )
        if self.time_limit <= 0:
            raise FootstepError(f"time_limit must be positive, got {self.time_limit} s")
        if self.heuristic not in HEURISTICS:
            raise FootstepError(
                f"unknown heuristic {self.heuristic!r}; expected one of {HEURISTICS}"
            )
        if not (math.isfinite(self.heuristic_weight) and self.heuristic_weight >= 1.0):
            raise FootstepError(
                f"heuristic_weight must be finite and >= 1 (the plan's bound), got "
                f"{self.heuristic_weight}"
            )
        if math.isnan(self.step_over_depth):
            raise FootstepError("step_over_depth must be a depth (m), inf or negative, got nan")
        for name in (
            "obstacle_cost",
            "height_cost_weight",
            "footprint_margin_m",
        ):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise FootstepError(f"{name} must be finite and >= 0, got {v}")
        for name in ("max_step_up", "max_step_down"):
            v = getattr(self, name)
            if math.isnan(v) or v < 0.0:
                raise FootstepError(f"{name} must be >= 0 m, got {v}")
        if math.isnan(self.max_height_range) or self.max_height_range < 0.0:
            raise FootstepError(f"max_height_range must be >= 0 m, got {self.max_height_range}")
        if math.isnan(self.swing_clearance) or self.swing_clearance <= 0.0:
            raise FootstepError(f"swing_clearance must be > 0 m, got {self.swing_clearance}")
        for name in ("goal_tolerance", "xy_resolution", "time_resolution"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise FootstepError(f"{name} must be finite and > 0, got {v}")
        if int(self.max_expansions) != self.max_expansions or self.max_expansions < 0:
            raise FootstepError(
                f"max_expansions must be an integer >= 0, got {self.max_expansions}"
            )
        if int(self.refinements) != self.refinements or not 0 <= self.refinements <= 4:
            raise FootstepError(f"refinements must be an integer in [0, 4], got {self.refinements}")
        if self.backend not in BACKENDS:
            raise FootstepError(f"unknown backend {self.backend!r}; expected one of {BACKENDS}")
        if int(self.yaw_bins) != self.yaw_bins or self.yaw_bins < 4:
            raise FootstepError(f"yaw_bins must be an integer >= 4, got {self.yaw_bins}")


def plan_footsteps(
    world: "OccupancyGrid | DynamicEnvironment",
    start: Sequence[float],
    start_foot: "Foot | int | str",
    goal: Sequence[float],
    table: ActionTable,
    options: PlannerOptions | None = None,
    *,
    dead_ends: Collection[tuple] = (),
    **kwargs,
) -> FootstepPlan:
    """Plan footsteps from a stance pose to a goal point (Algorithm 1 with a time limit).

    Runs one A* search at the options' lattice; when it reports UNREACHABLE after merging
    states, repeats it on a finer lattice (see :attr:`PlannerOptions.refinements`) with
    the time left. The plan records the lattice (``xy_resolution``, ``yaw_bins``) of the
    search that produced it.

    Args:
        world: a static :class:`OccupancyGrid` or a :class:`DynamicEnvironment` E(t).
        start: ``(x, y, yaw)`` of the stance foot at the start.
        start_foot: which foot stands at ``start`` (the other one moves first).
        goal: ``(x, y)`` of the goal point (a third value, yaw, is ignored).
        table: the displacement table T (with durations and step costs).
        options: planner options (defaults: :class:`PlannerOptions`).
        dead_ends: search states (:func:`plan_state`) known to have no plan to the goal: the
            search never enters them (a receding-horizon planner's proved traps). Not empty:
            the python core (the compiled one cannot skip states).
        **kwargs: keyword-only arguments of
            :class:`~repertoire.planning.footstep.biped_model.BipedStepModel`
            (``geometry``, ``initial_swing_pose``, ``start_time``, ``initial_history``,
            ``action_filter``).

    Raises:
        FootstepError: bad options or inputs (see the step model).
    """
    from repertoire.planning.footstep.fastcore import warm_up

    warm_up()  # one-time compilation / cache load, outside the time limit
    opts = _options(options)
    dead = _dead_ends(dead_ends)
    if dead:
        opts = dataclasses.replace(opts, backend="python")
    _build_footprint_masks(world, opts, kwargs)  # one-time per resolution, outside it too
    t_begin = time.perf_counter()
    kwargs = {**kwargs, "dead_ends": dead}
    plan, merged, model = _plan_once(world, start, start_foot, goal, table, opts, t_begin, kwargs)
    level = 0
    while plan.status is PlanStatus.UNREACHABLE and merged and level < opts.refinements:
        if level == 0 and goal_cut_off(model, t_begin + opts.time_limit):  # no lattice gets
            break  # through: nothing to refine (a proof cut short by the limit proves nothing)
        left = opts.time_limit - (time.perf_counter() - t_begin)
        if left <= 0.0:
            plan.status = PlanStatus.TIME_LIMIT
            break
        level += 1
        finer = _finer(opts, level, opts.time_limit)  # _plan_once counts from t_begin
        split = {**kwargs, "swing_start_states": True}  # the finer lattice keys swing starts
        plan, merged, _ = _plan_once(world, start, start_foot, goal, table, finer, t_begin, split)
    plan.planning_time_s = time.perf_counter() - t_begin
    return plan


def _plan_once(
    world: "OccupancyGrid | DynamicEnvironment",
    start: Sequence[float],
    start_foot: "Foot | int | str",
    goal: Sequence[float],
    table: ActionTable,
    opts: PlannerOptions,
    t_begin: float,
    kwargs: dict,
) -> tuple[FootstepPlan, int, BipedStepModel]:
    """One search at the options' lattice: the plan, the merged-successor count, the model."""
    t_once = time.perf_counter()
    dead = kwargs.get("dead_ends", frozenset())
    kwargs = {k: v for k, v in kwargs.items() if k != "dead_ends"}
    model = BipedStepModel(world, start, start_foot, goal, table, opts, **kwargs)
    left = max(opts.time_limit - (time.perf_counter() - t_begin), 1e-9)
    budget = int(opts.max_expansions) if opts.max_expansions > 0 else 2**62
    searched = _Avoiding(model, dead) if dead else model
    result = _search_once(searched, _backend(opts, model), opts.heuristic_weight, budget, left)
    plan = _to_plan(model, result, time.perf_counter() - t_once)
    return plan, result.merged, model


def plan_state(plan: FootstepPlan, i: int, table: ActionTable) -> tuple:
    """The search state ``plan`` stands in after its first ``i`` steps, as ``dead_ends`` names it.

    Every field of the step model's state but its estimate: stance pose, foot, the two last
    actions (table indices), time and where the swing foot stands.

    Args:
        plan: a plan.
        i: steps taken, 0..``plan.num_steps``.
        table: the table the plan was made with.
    """
    if not (is_real(i) and int(i) == i and 0 <= i <= plan.num_steps):
        raise FootstepError(f"step index must be an integer in [0, {plan.num_steps}], got {i!r}")
    i = int(i)
    names = list(plan.initial_history) + list(plan.actions)
    x, y, yaw = plan.poses[i]
    swing = plan.poses[i - 1] if i else plan.initial_swing_pose
    a2, a1 = (table.index(a) for a in names[i : i + 2])
    return (x, y, yaw, int(plan.feet[i]), a2, a1, plan.times[i], swing[0], swing[1])


def _dead_ends(dead_ends: Collection[tuple]) -> frozenset:
    """``dead_ends`` as a set, each a state of :func:`plan_state`'s form (checked)."""
    if isinstance(dead_ends, (str, bytes)) or not isinstance(dead_ends, Collection):
        raise FootstepError(f"dead_ends must be a collection of states, got {dead_ends!r}")
    for d in dead_ends:
        if not (isinstance(d, tuple) and len(d) == len(BipedState._fields) - 1):
            raise FootstepError(
                f"a dead end must be a state of plan_state's form (9 values), got {d!r}"
            )
    return frozenset(dead_ends)


class _Avoiding:
    """The step model whose successors skip known dead ends (its search never enters them)."""

    def __init__(self, model: BipedStepModel, dead: frozenset) -> None:
        self.model, self.dead, self.start, self.key = model, dead, model.start, model.key
        self.is_goal, self.heuristic = model.is_goal, model.heuristic

    def successors(self, s: BipedState, dominated=None) -> Iterator[tuple[BipedState, float]]:
        """The model's successors of ``s`` but the dead ends (``dominated`` passed on)."""
        for nxt, cost in self.model.successors(s, dominated):
            if nxt[:-1] not in self.dead:  # every field but the estimate h
                yield nxt, cost


def _to_plan(model: BipedStepModel, result: SearchResult, seconds: float) -> FootstepPlan:
    path: list[BipedState] = result.path
    names = model.table.actions
    a2, a1 = model.history0
    return FootstepPlan(
        poses=[[s.x, s.y, s.yaw] for s in path],
        feet=[s.foot for s in path],
        actions=[names[s.a_prev1] for s in path[1:]],
        times=[s.t for s in path],
        status=result.status,
        cost=result.cost,
        cost_to_go=path[-1].h,
        nodes_expanded=result.expansions,
        nodes_generated=result.generated,
        planning_time_s=seconds,
        initial_swing_pose=list(model.swing0),
        goal=list(model.goal),
        goal_tolerance=model.tol,
        initial_history=[names[a2], names[a1]],
        xy_resolution=model.opts.xy_resolution,
        yaw_bins=int(model.opts.yaw_bins),
        reason=model.unreachable_reason() if result.status is PlanStatus.UNREACHABLE else "",
    )


@dataclasses.dataclass
class AnytimePlan:
    """One plan of :func:`plan_footsteps_anytime`.

    Attributes:
        plan: the footstep plan (SUCCESS, or the final search's status).
        weight: heuristic weight of the search that produced it.
        bound: suboptimality bound of that search: with an admissible heuristic
            (``"euclidean"``), ``plan.cost <= bound * optimum``, the optimum over the
            search's lattice (``plan.xy_resolution``, ``plan.yaw_bins``) on the whole map,
            or, for a corridor plan (``corridor_m > 0``), only over the plans inside that
            corridor.
        elapsed_s: wall time from the call to this plan (s).
        corridor_m: 0 for a search of the whole map; else the half-width (m) of the
            corridor around the previous best plan that the search was confined to.
    """

    plan: FootstepPlan
    weight: float
    bound: float
    elapsed_s: float
    corridor_m: float = 0.0


def plan_footsteps_anytime(
    world: "OccupancyGrid | DynamicEnvironment",
    start: Sequence[float],
    start_foot: "Foot | int | str",
    goal: Sequence[float],
    table: ActionTable,
    options: PlannerOptions | None = None,
    *,
    weights: Sequence[float] = (3.0, 2.0, 1.5, 1.2, 1.0),
    restarts: bool = True,
    corridor: float = 0.0,
    second_search: bool = False,
    **kwargs,
) -> list[AnytimePlan]:
    """ARA* footstep planning: a first plan fast, better ones while time remains.

    The search is reused between weights (OPEN plus INCONS, see
    :func:`repertoire.planning.footstep.search.anytime_search`); each plan carries its
    bound, and weights not below the last plan's bound are skipped. Like
    :func:`plan_footsteps`, an UNREACHABLE after merged states repeats the search on finer
    lattices (``options.refinements``). ``options.heuristic_weight`` is ignored
    (``weights`` set it), the other options apply; ``time_limit`` and ``max_expansions``
    cover all searches.

    On static grids with ``corridor > 0`` (not the default), ARA* is split: after its first
    plan (the first weight alone), ARA* over all the weights runs on the whole map for at
    most a quarter of the time left (``ARA_SHARE``) plus the first search's time (it repeats
    that search: the compiled ARA* cannot be resumed); then the best plan so far is searched
    again inside its corridor (:func:`~repertoire.planning.footstep.corridor.corridor_grid`:
    the cells within ``corridor`` m of the plan's feet), on the next finer lattice (the first
    refinement's; ARA*'s own with ``refinements=0``), by a fresh weighted A* at each later
    weight, each around the best plan so far. A corridor holds a small part of the map's
    lattice, so such a search takes a fraction of a whole-map one, and its plan is a plan
    on the whole map at the same cost.

    When ARA* has run (or skipped) every weight and time remains, it starts again from
    scratch (restarting, Richter et al. 2010, "The Joy of Forgetting"), the cost-to-go field
    shared: first ARA* over every weight on the next finer lattice (the first refinement's;
    not with ``refinements=0``), its search reused between its weights, then fresh weighted
    A* at the weights after the first on ARA*'s own lattice. States merged on a lattice keep
    the continuous pose that reached them first, so a fresh search keeps other poses, and a
    finer lattice merges fewer, and either can find a cheaper plan where ARA*'s reuse cannot
    (one 12 m floor: 118.1 by ARA* at weight 1, 110.4 by a fresh search at 1.5 on the same
    lattice, 105.5 at 2 on the finer one). ARA* on the finer lattice rather than fresh
    searches there: on 92 12 m floors at 30 % with 1.0 M and 1.6 M expansions (about 1 s on
    the machines measured) 9 and 5 plans above 1.05 of the admissible mode's instead of 10
    and 6 (geometric means 1.0136 and 1.0046 instead of 1.0153 and 1.0078; single floors
    moved both ways). With the default ``heuristic="dijkstra"``, whatever time and budget the
    restarts leave go to the admissible search (the Euclidean heuristic at weight 1,
    :meth:`PlannerOptions.admissible`'s) on the restarts' finest lattice (with
    ``"euclidean"`` ARA*'s weights are that search's; with ``"none"`` every weight orders the
    queue alike, so no fresh search or corridor search repeats ARA*'s uniform-cost search,
    which is optimal on its lattice); when it ends in time, its plan is that lattice's optimum
    (bound 1 on it; by default the admissible mode's own plan). It finds plans the searches
    guided by the Dijkstra cost-to-go miss even when they end early (a 6 m maze: 39.1 after
    every weight on both lattices in 0.28 s, 36.95 from the admissible search at 0.55 s).
    After ARA*'s plans, a plan is added only when it is cheaper than every
    plan before it (the split ARA* of corridor searches also adds a plan as cheap with a
    tighter bound, and so does the admissible search when it ends: bound 1 on its lattice
    says the cost found is that lattice's optimum); its weight, bound, lattice and
    corridor are its own search's.

    Args:
        world, start, start_foot, goal, table, options, **kwargs: as in
            :func:`plan_footsteps`.
        weights: non-increasing weights, each >= 1.
        restarts: search again from scratch once ARA* is done: ARA* on the finer lattice,
            fresh weighted A* on ARA*'s, then the admissible search (see above).
        corridor: half-width (m) of the corridors the plans are improved in (0.5 is a
            reasonable value for bipeds: about twice the longest step); 0, the default: no
            corridor searches (ARA* alone, then the restarts). On 12 m floors with a 1 s
            limit, corridors help where ARA*'s lower weights come late (local detours of
            the first plan) and hurt where a different way round is cheaper (ARA* then has
            less time): on unseen floors neither choice was better on the whole
            (docs/results/footstep.md).
        second_search: also run one fresh weighted A* (weight 1.5, the first refinement's
            lattice) in a second thread, with its own time limit and budget, and merge its
            plan in where it is cheaper by then (:mod:`~repertoire.planning.footstep.portfolio`;
            for two free cores; compiled core only). False, the default: no second thread.

    Returns:
        the plans in order (costs non-increasing); the last may be a partial plan (status
        TIME_LIMIT / NODE_LIMIT / UNREACHABLE).

    Raises:
        FootstepError: bad options, weights or corridor, or bad inputs (see the step model).
    """
    from repertoire.planning.footstep.fastcore import warm_up

    warm_up()  # one-time compilation / cache load, outside the time limit
    opts = _options(options)
    weights = anytime_weights(weights)
    _build_footprint_masks(world, opts, kwargs)  # one-time per resolution, outside it too
    t_begin = time.perf_counter()
    if not (is_real(corridor) and math.isfinite(corridor) and corridor >= 0.0):
        raise FootstepError(f"corridor must be a half-width >= 0 m, got {corridor!r}")
    for name, flag in (("restarts", restarts), ("second_search", second_search)):
        if not isinstance(flag, (bool, np.bool_)):
            raise FootstepError(f"{name} must be True or False, got {flag!r}")
    if second_search:  # started first: it runs beside the pipeline for the whole limit
        from repertoire.planning.footstep.portfolio import SecondSearch

        second = SecondSearch(world, start, start_foot, goal, table, opts, kwargs, t_begin)
    found, t_done = _anytime_once(
        world, start, start_foot, goal, table, opts, weights, kwargs, restarts,
        opts.refinements > 0, corridor,
    )  # fmt: skip
    level = 0
    while (
        found[-1][1].status is PlanStatus.UNREACHABLE
        and found[-1][1].merged
        and level < opts.refinements
    ):
        if level == 0 and goal_cut_off(found[0][0], t_begin + opts.time_limit):
            break  # no lattice can get through (proved within the time limit)
        left = opts.time_limit - (time.perf_counter() - t_begin)
        if left <= 0.0:
            found[-1][1].status = PlanStatus.TIME_LIMIT
            break
        level += 1
        finer = _finer(opts, level, left)
        split = {**kwargs, "swing_start_states": True}  # as plan_footsteps' refinements
        found, t_done = _anytime_once(
            world, start, start_foot, goal, table, finer, weights, split, restarts,
            level < opts.refinements, corridor,
        )  # fmt: skip
    out = []
    # the results' seconds are contiguous and end when the last plan was found (searches
    # that found nothing cheaper after it are not part of any plan's time)
    elapsed = t_done - t_begin - sum(r.seconds for _, r, _ in found)
    for model, r, width in found:
        elapsed += r.seconds
        out.append(AnytimePlan(_to_plan(model, r, elapsed), r.weight, r.bound, elapsed, width))
    return second.merge(out) if second_search else out


def _options(options: "PlannerOptions | None") -> PlannerOptions:
    """The validated options (default: :class:`PlannerOptions`); errors name a wrong type."""
    if options is None:
        options = PlannerOptions()
    if not isinstance(options, PlannerOptions):
        raise FootstepError(f"options must be PlannerOptions, got {type(options).__name__}")
    options.validate()
    return options


def _build_footprint_masks(
    world: "OccupancyGrid | DynamicEnvironment", opts: PlannerOptions, kwargs: dict
) -> None:
    """Build the footprint masks the search will read, before a plan's clock starts.

    The masks of a grid resolution, foot and margin are cached per process; building them
    (with the Python core's row sets or the compiled core's bit rows) takes about 0.1-0.2 s
    at a new resolution, a one-time cost like the compilation (:func:`warm_up`), not part of
    any plan's time limit. Bad inputs are left to the step model, which names them.
    """
    geometry = kwargs.get("geometry", ASIMO_LIKE)
    if not isinstance(world, (OccupancyGrid, DynamicEnvironment)) or not isinstance(
        geometry, BipedGeometry
    ):
        return
    grid = world if isinstance(world, OccupancyGrid) else world.reference
    for margin in {opts.footprint_margin_m, 0.0}:  # the landing check's and the exact one
        masks = sole_masks(geometry, margin, grid.resolution)
        if opts.backend == "python" or isinstance(world, DynamicEnvironment):
            _ = masks.outer_rows, masks.inner_rows, masks.ring_rows
        elif 2 * masks.radius_cells + 1 <= MASK_WORD_CELLS:
            _cached_mask_bits(masks)


def _finer(opts: PlannerOptions, level: int, time_limit: float) -> PlannerOptions:
    """The options on the lattice of refinement ``level`` (cells / 2**level, bins * 2**level)."""
    return dataclasses.replace(
        opts,
        xy_resolution=opts.xy_resolution / 2**level,
        yaw_bins=int(opts.yaw_bins) * 2**level,
        time_limit=time_limit,
    )


def _anytime_once(
    world: "OccupancyGrid | DynamicEnvironment",
    start: Sequence[float],
    start_foot: "Foot | int | str",
    goal: Sequence[float],
    table: ActionTable,
    opts: PlannerOptions,
    weights: Sequence[float],
    kwargs: dict,
    restarts: bool = False,
    finer_restarts: bool = False,
    corridor: float = 0.0,
) -> tuple[list[tuple[BipedStepModel, SearchResult, float]], float]:
    """ARA* at the options' lattice, on the chosen backend, with corridor searches, restarts.

    The corridor searches, and the restarts' ARA* before its fresh searches on ``opts``'s
    lattice, run on the next finer lattice when ``finer_restarts``. Returns each result
    with the model (lattice) it was found on and its corridor half-width (0: whole map),
    and the clock (``time.perf_counter``) when the last result was found.
    """
    t0 = time.perf_counter()
    model = BipedStepModel(world, start, start_foot, goal, table, opts, **kwargs)
    left = max(opts.time_limit - (time.perf_counter() - t0), 1e-9)
    budget = int(opts.max_expansions) if opts.max_expansions > 0 else 2**62
    backend = _backend(opts, model)
    if model.dynamic:
        corridor = 0.0  # corridors are cut from a static grid
    # without a heuristic every weight orders the queue alike: one search is all of them
    later = list(weights)[1:] if opts.heuristic != "none" else []
    results = _ara(model, backend, list(weights)[:1] if corridor else weights, budget, left)
    run = _Improving(t0, opts.time_limit, budget, [(model, r, 0.0) for r in results])
    if results[-1].status is not PlanStatus.SUCCESS or run.best <= 0.0:
        return run.found, run.t_last  # no plan, or one of no step: optimal, nothing to do
    lattice = _finer(opts, 1, opts.time_limit) if finer_restarts else opts
    if corridor:
        # ARA* over all the weights on the whole map, for at most a share of the time left
        # plus the first search's time (it repeats the first plan's search: the compiled
        # ARA* cannot be resumed), then the best plan is improved in its corridor
        if len(weights) > 1 and run.left() > 0.0:
            t_ara = time.perf_counter()
            box = min(ARA_SHARE * run.left() + results[0].seconds, run.left())
            run.offer_ara(model, _ara(model, backend, weights, budget - run.used, box), t_ara)
        run.corridor(world, start, start_foot, goal, table, lattice, later, kwargs, backend,
                     corridor)  # fmt: skip
    if not (restarts and run.left() > 0.0):
        return run.found, run.t_last
    if finer_restarts:  # ARA* from scratch on the next finer lattice, over every weight
        fine = BipedStepModel(
            world, start, start_foot, goal, table, _finer(opts, 1, run.left()), **kwargs
        )
        t_ara = time.perf_counter()
        run.offer_ara(
            fine, _ara(fine, backend, weights, budget - run.used, run.left()), t_ara, tighter=False
        )
    for w in later:  # the first weight's plan is ARA*'s first plan already
        if run.left() <= 0.0 or run.used >= budget:
            break
        run.offer(model, _search_once(model, backend, float(w), budget - run.used, run.left()))
    if opts.heuristic == "dijkstra" and run.left() > 0.0:
        # what is left goes to the admissible search (Euclidean, weight 1) on the restarts'
        # finest lattice: if it ends, its plan is that lattice's optimum (bound 1); with the
        # Euclidean heuristic, ARA*'s weights are that search's own (weight 1 by default),
        # and without one, every search already was the uniform-cost search it refines
        exact = _finer(opts, 1, run.left()) if finer_restarts else opts
        exact = dataclasses.replace(exact, heuristic="euclidean", heuristic_weight=1.0)
        adm = BipedStepModel(world, start, start_foot, goal, table, exact, **kwargs)
        run.offer(adm, _search_once(adm, backend, 1.0, budget - run.used, run.left()), proof=True)
    return run.found, run.t_last


class _Improving:
    """The plans of one anytime call so far: only cheaper successful plans join them."""

    def __init__(self, t0: float, limit: float, budget: int, found: list) -> None:
        self.t0, self.limit, self.budget = t0, limit, budget
        self.found = found
        self.t_last = time.perf_counter()
        self.used = sum(r.expansions for _, r, _ in found)
        done = [r for _, r, _ in found if r.status is PlanStatus.SUCCESS]
        self.best = min((r.cost for r in done), default=math.inf)
        self.bound = min((r.bound for r in done), default=math.inf)  # ARA*'s bounds

    def left(self) -> float:
        """Wall time left (s); 0 once the expansion budget is spent."""
        if self.used >= self.budget:
            return 0.0
        return self.limit - (time.perf_counter() - self.t0)

    def offer(
        self, model: BipedStepModel, r: SearchResult, width: float = 0.0, at: float = 0.0,
        ara: bool = False, proof: bool = False,
    ) -> None:  # fmt: skip
        """Count the search; keep a successful plan that is cheaper (not rounding).

        ``ara``: a result of ARA* on the first plan's lattice, kept also when as cheap with
        a tighter bound than that ARA*'s plans so far. ``proof``: the admissible search's
        result, kept also when as cheap: its bound 1 shows the best plan so far optimal on
        its lattice. ``at``: the clock (``time.perf_counter``) when the plan was found
        (default: now).
        """
        self.used += r.expansions
        if r.status is not PlanStatus.SUCCESS:
            return
        as_cheap = r.cost <= self.best * (1.0 + 1e-9)
        tighter = (ara and r.bound < self.bound or proof) and as_cheap
        if r.cost < self.best * (1.0 - 1e-9) or tighter:
            self.best = min(self.best, r.cost)
            if ara:
                self.bound = min(self.bound, r.bound)
            now = at or time.perf_counter()
            r.seconds = now - self.t_last  # the fruitless searches since the last plan
            self.t_last = now
            self.found.append((model, r, width))

    def offer_ara(
        self, model: BipedStepModel, results: list[SearchResult], t_start: float,
        tighter: bool = True,
    ) -> None:  # fmt: skip
        """Offer the results of one ARA* call that started at ``t_start``, in order.

        The compiled ARA* returns all its results at its end: each plan's clock is rebuilt
        from the seconds of the searches before it. ``tighter``: keep a plan as cheap with
        a tighter bound too (``offer``'s ``ara``; ARA* on the first plan's lattice).
        """
        at = t_start
        for r in results:
            at += r.seconds
            self.offer(model, r, at=at, ara=tighter)

    def corridor(
        self,
        world: OccupancyGrid,
        start: Sequence[float],
        start_foot: "Foot | int | str",
        goal: Sequence[float],
        table: ActionTable,
        lattice: PlannerOptions,
        weights: Sequence[float],
        kwargs: dict,
        backend: str,
        width: float,
    ) -> None:
        """One weighted A* per weight in the corridor of the best plan so far.

        No search runs when the corridor leaves the start feet on blocked cells (a width
        below the feet's size): the step model refuses such a start.
        """
        from repertoire.planning.footstep.corridor import corridor_grid

        model, around = None, None
        for w in weights:
            if self.left() <= 0.0:
                return
            best = next(r for _, r, _ in reversed(self.found) if r.status is PlanStatus.SUCCESS)
            if best is not around:  # a new best plan: its own corridor
                m0 = self.found[0][0]
                feet = [m0.swing0, *((s.x, s.y) for s in best.path), m0.goal]
                grid = corridor_grid(world, feet, width)
                opts = dataclasses.replace(lattice, time_limit=max(self.left(), 1e-9))
                try:
                    model = BipedStepModel(grid, start, start_foot, goal, table, opts, **kwargs)
                except FootstepError:  # a corridor too narrow for the start feet: no pass
                    return
                around = best
            r = _search_once(model, backend, float(w), self.budget - self.used,
                             max(self.left(), 1e-9))  # fmt: skip
            self.offer(model, r, width)
