"""A* footstep planner over state-dependent actions (Chestnutt et al., Algorithm 1).

A state is the stance foot pose ``(x, y, yaw)``, which foot stands, the last two commanded
actions and the time. Successors come from the action table T for the actions F allows;
each costs ``step_cost(a) + location_cost(landing)`` (infinite when the foot rectangle,
inflated by ``footprint_margin_m``, overlaps an occupied cell of E(t)); the queue is
ordered by ``g + w h`` with ``h`` the expected cost-to-go. States are merged on a lattice
of ``xy_resolution`` x ``yaw_bins`` (x time bins in dynamic worlds) while the poses
themselves stay continuous, so a plan's poses are exactly what T predicts. When the time
limit runs out, or the open list is exhausted, the best partial plan (smallest cost-to-go)
is returned with its status.
"""

import dataclasses
import heapq
import math
import time
from collections.abc import Callable, Sequence

import numpy as np
from repertoire.planning.footstep.actions import ASIMO_LIKE, BipedGeometry, apply_displacement
from repertoire.planning.footstep.environment import DynamicEnvironment, OccupancyGrid
from repertoire.planning.footstep.footprint import FootprintChecker, footprint_masks
from repertoire.planning.footstep.heuristic import dijkstra_cost_to_go
from repertoire.planning.footstep.types import (
    ActionTable,
    Foot,
    FootstepError,
    FootstepPlan,
    PlanStatus,
    parse_foot,
    wrap_angle,
)

HEURISTICS = ("dijkstra", "euclidean", "none")


@dataclasses.dataclass
class PlannerOptions:
    """Options of :func:`plan_footsteps`.

    Attributes:
        time_limit: wall-time budget of the search (s), > 0.
        heuristic: ``"dijkstra"`` (backward 2-D Dijkstra, informed, inadmissible; static
            grids only), ``"euclidean"`` (straight-line distance, admissible) or ``"none"``
            (uniform-cost search).
        heuristic_weight: w in ``g + w h`` (>= 0).
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
        height_cost_weight: location cost per metre of height variation under a foot.
        max_expansions: stop after this many expansions with status NODE_LIMIT (0 = no
            limit); a deterministic budget for reproducible studies.
        footprint_margin_m: clearance (m, >= 0) kept between a planned footprint and any
            occupied cell: the foot rectangle is inflated by this much on every side for the
            obstacle check of landings (0 keeps the exact check). The start feet are checked
            exactly (they already stand there).
        refinements: when the open list runs empty after states were merged (a successor
            dropped because its lattice cell was already reached), the search is repeated
            with half the ``xy_resolution`` and twice the ``yaw_bins``, up to this many
            times within the time limit, so UNREACHABLE is reported only when the lattice
            reachable from the start is exhausted at the finest resolution tried (recorded
            in the plan). 0 keeps one search.
        swing_clearance: obstacle cells taller than this (m, the grid's ``heights``) block
            the swing foot's path: a step whose straight centre line from the swing foot's
            previous position to its landing crosses such a cell is refused. ``inf`` (the
            default) or a grid without heights: every flat obstacle may be stepped over.
        max_height_range: a foot lands only where the height range under its sole (the
            grid's ``heights``) is at most this (m): flat enough ground. The start feet
            must satisfy it too. ``inf`` (the default): no flatness limit.
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
    refinements: int = 2
    swing_clearance: float = math.inf
    max_height_range: float = math.inf

    @classmethod
    def admissible(cls, **overrides: float) -> "PlannerOptions":
        """Options for optimal plans: Euclidean heuristic (admissible), weight 1, fine lattice.

        Optimal with respect to the state lattice: states closer than ``xy_resolution``
        and ``yaw_bins`` are merged (2.5 cm and 5 degrees here), exactly so when the table's
        displacements lie on that lattice.

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
        if not (isinstance(self.time_limit, (int, float)) and math.isfinite(self.time_limit)):
            raise FootstepError(
                f"time_limit must be a finite number of seconds, got {self.time_limit}"
            )
        if self.time_limit <= 0:
            raise FootstepError(f"time_limit must be positive, got {self.time_limit} s")
        if self.heuristic not in HEURISTICS:
            raise FootstepError(
                f"unknown heuristic {self.heuristic!r}; expected one of {HEURISTICS}"
            )
        for name in (
            "heuristic_weight",
            "obstacle_cost",
            "height_cost_weight",
            "footprint_margin_m",
        ):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise FootstepError(f"{name} must be finite and >= 0, got {v}")
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
        if int(self.yaw_bins) != self.yaw_bins or self.yaw_bins < 4:
            raise FootstepError(f"yaw_bins must be an integer >= 4, got {self.yaw_bins}")


ActionFilter = Callable[[str, str, Foot], Sequence[str]]


def history_classes(table: ActionTable) -> np.ndarray:
    """Merge histories ``(a_prev2, a_prev1)`` whose futures are identical under T.

    Two histories are equivalent when they give the same displacements and durations for
    every foot and action, and the histories they lead to after any action are equivalent
    again (partition refinement, as in DFA minimisation). States that differ only by
    equivalent histories are merged by the search without changing any plan's cost.

    Args:
        table: the action table.

    Returns:
        (n, n) int array: class id of each history.
    """
    n = table.n
    sig: dict[bytes, int] = {}
    cls = np.zeros((n, n), dtype=int)
    for i2 in range(n):
        for i1 in range(n):
            b = table.displacement[i2, i1].tobytes() + table.duration[i2, i1].tobytes()
            cls[i2, i1] = sig.setdefault(b, len(sig))
    while True:
        sig2: dict[tuple, int] = {}
        new = np.zeros_like(cls)
        for i2 in range(n):
            for i1 in range(n):
                key = (int(cls[i2, i1]), *(int(cls[i1, a]) for a in range(n)))
                new[i2, i1] = sig2.setdefault(key, len(sig2))
        if len(sig2) == len(np.unique(cls)):
            return new
        cls = new


def _pose3(p: Sequence[float], name: str) -> tuple[float, float, float]:
    try:
        vals = [float(v) for v in p]
    except (TypeError, ValueError):
        raise FootstepError(f"{name} must be a sequence of numbers, got {p!r}") from None
    if len(vals) == 2:
        vals.append(0.0)
    if len(vals) != 3 or not all(math.isfinite(v) for v in vals):
        raise FootstepError(f"{name} must be finite (x, y[, yaw]), got {p!r}")
    return vals[0], vals[1], wrap_angle(vals[2])


class _Checkers:
    """Footprint checkers per time index (dynamic) or one checker (static).

    The foot rectangle is inflated by ``margin`` (m) on every side.
    """

    def __init__(
        self,
        world: "OccupancyGrid | DynamicEnvironment",
        geometry: BipedGeometry,
        hold: float,
        margin: float = 0.0,
    ) -> None:
        self.world = world
        grid0 = world if isinstance(world, OccupancyGrid) else world.reference
        self.masks = footprint_masks(
            geometry.foot_length + 2.0 * margin,
            geometry.foot_width + 2.0 * margin,
            grid0.resolution,
        )
        self.hold = hold
        self._cache: dict[int, FootprintChecker] = {}
        self.static = isinstance(world, OccupancyGrid)
        if self.static:
            self._cache[0] = FootprintChecker(world, self.masks)

    def index(self, t: float) -> int:
        """Time index of ``t``, or -1 when no grid is near (always 0 in static worlds)."""
        if self.static:
            return 0
        env = self.world
        k = env.nearest_index_unchecked(t)
        return k if abs(env.times[k] - t) <= env.max_time_gap + 1e-9 else -1

    def checker(self, k: int) -> FootprintChecker:
        c = self._cache.get(k)
        if c is None:
            env = self.world
            t_hold = env.times[k] + self.hold
            k2 = int(np.searchsorted(env.times, t_hold + env.max_time_gap + 1e-9))
            union = env.stack[k : max(k2, k + 1)].any(axis=0)
            ref = env.reference
            c = FootprintChecker(
                OccupancyGrid(union, ref.resolution, ref.origin, ref.heights), self.masks
            )
            self._cache[k] = c
        return c


def _swing_crosses(
    tall: np.ndarray, x0: float, y0: float, x1: float, y1: float, ox: float, oy: float, inv: float
) -> bool:
    """Whether the segment (x0, y0) -> (x1, y1) passes over a True cell of ``tall``."""
    n = int(math.hypot(x1 - x0, y1 - y0) * inv * 2.0) + 2
    nx, ny = tall.shape
    for k in range(n + 1):
        u = k / n
        i = int(((x0 + u * (x1 - x0)) - ox) * inv)
        j = int(((y0 + u * (y1 - y0)) - oy) * inv)
        if 0 <= i < nx and 0 <= j < ny and tall[i, j]:
            return True
    return False


def plan_footsteps(
    world: "OccupancyGrid | DynamicEnvironment",
    start: Sequence[float],
    start_foot: "Foot | int | str",
    goal: Sequence[float],
    table: ActionTable,
    options: PlannerOptions | None = None,
    **kwargs,
) -> FootstepPlan:
    """Plan footsteps from a stance pose to a goal point (Algorithm 1 with a time limit).

    Runs one A* search at the options' lattice; when it reports UNREACHABLE after merging
    states, repeats it on a finer lattice (see :attr:`PlannerOptions.refinements`) with
    the time left. The plan records the lattice (``xy_resolution``, ``yaw_bins``) of the
    search that produced it.

    Args:
        world, start, start_foot, goal, table, options, **kwargs: as in
            :func:`_plan_once` (keyword-only ``geometry``, ``initial_swing_pose``,
            ``start_time``, ``initial_history``, ``action_filter``).
    """
    t_begin = time.perf_counter()
    opts = options if options is not None else PlannerOptions()
    opts.validate()
    plan, merged = _plan_once(world, start, start_foot, goal, table, opts, **kwargs)
    level = 0
    while plan.status is PlanStatus.UNREACHABLE and merged and level < opts.refinements:
        left = opts.time_limit - (time.perf_counter() - t_begin)
        if left <= 0.0:
            plan.status = PlanStatus.TIME_LIMIT
            break
        level += 1
        finer = dataclasses.replace(
            opts,
            xy_resolution=opts.xy_resolution / 2**level,
            yaw_bins=int(opts.yaw_bins) * 2**level,
            time_limit=left,
        )
        plan, merged = _plan_once(world, start, start_foot, goal, table, finer, **kwargs)
    plan.planning_time_s = time.perf_counter() - t_begin
    return plan


def _plan_once(
    world: "OccupancyGrid | DynamicEnvironment",
    start: Sequence[float],
    start_foot: "Foot | int | str",
    goal: Sequence[float],
    table: ActionTable,
    options: PlannerOptions | None = None,
    *,
    geometry: BipedGeometry = ASIMO_LIKE,
    initial_swing_pose: Sequence[float] | None = None,
    start_time: float = 0.0,
    initial_history: Sequence[str] | None = None,
    action_filter: ActionFilter | None = None,
) -> tuple[FootstepPlan, int]:
    """One A* search (Algorithm 1 with a time limit) at the options' lattice resolution.

    Args:
        world: a static :class:`OccupancyGrid` or a :class:`DynamicEnvironment` E(t).
        start: ``(x, y, yaw)`` of the stance foot at the start.
        start_foot: which foot stands at ``start`` (the other one moves first).
        goal: ``(x, y)`` of the goal point (a third value, yaw, is ignored).
        table: the displacement table T (with durations and step costs).
        options: planner options (defaults: :class:`PlannerOptions`).
        geometry: foot size and stance width.
        initial_swing_pose: the other foot at the start; default: beside the stance foot
            at the nominal stance width.
        start_time: time of the start state (s); dynamic worlds need a grid near it.
        initial_history: ``(a_prev2, a_prev1)`` before the first action; default
            ``(rest_action, rest_action)`` (standing still).
        action_filter: F: ``(a_prev2, a_prev1, stance_foot) -> allowed action names``;
            default all actions.

    Returns:
        the plan (its status says whether it reaches the goal) and the number of
        successors dropped because their lattice state was already reached.
    """
    t_begin = time.perf_counter()
    opts = options if options is not None else PlannerOptions()
    opts.validate()
    if not isinstance(table, ActionTable):
        raise FootstepError(f"table must be an ActionTable, got {type(table).__name__}")
    table.validate()
    if not isinstance(world, (OccupancyGrid, DynamicEnvironment)):
        raise FootstepError(
            f"world must be an OccupancyGrid or DynamicEnvironment, got {type(world).__name__}"
        )
    dynamic = isinstance(world, DynamicEnvironment)
    if dynamic and opts.heuristic == "dijkstra":
        raise FootstepError(
            "the 'dijkstra' heuristic needs a static grid; use 'euclidean' in dynamic worlds"
        )
    if not math.isfinite(start_time):
        raise FootstepError(f"start_time must be finite, got {start_time}")
    foot0 = parse_foot(start_foot)
    sx, sy, sth = _pose3(start, "start")
    gx, gy, _ = _pose3(goal, "goal")
    ref = world if not dynamic else world.reference
    if dynamic:
        world.index_at(start_time)  # raises GridError when no grid is near the start time
    for name, (px, py) in (("start", (sx, sy)), ("goal", (gx, gy))):
        if not ref.contains(px, py):
            x0, y0 = ref.origin
            w, h = ref.size
            raise FootstepError(
                f"{name} ({px:.3f}, {py:.3f}) lies outside the map "
                f"[{x0}, {x0 + w}] x [{y0}, {y0 + h}]"
            )
    history = list(initial_history) if initial_history is not None else [table.rest_action] * 2
    if len(history) != 2:
        raise FootstepError(f"initial_history must hold two actions, got {history}")
    h2, h1 = table.index(history[0]), table.index(history[1])

    hold = float(table.duration.max())
    checkers = _Checkers(world, geometry, hold, opts.footprint_margin_m)
    k0 = checkers.index(start_time)
    # the start feet already stand: checked with the exact footprint, without the margin;
    # the height cost is also measured under the exact footprint (heights are the same at all t)
    exact = _Checkers(world, geometry, hold) if opts.footprint_margin_m > 0 else checkers
    chk_start = exact.checker(k0)
    if not chk_start.is_free(sx, sy, sth):
        raise FootstepError(
            f"start foot at ({sx:.3f}, {sy:.3f}, {sth:.3f}) overlaps an obstacle or the map edge"
        )
    if initial_swing_pose is None:
        side = 1.0 if foot0 == Foot.RIGHT else -1.0
        swing0 = apply_displacement((sx, sy, sth), (0.0, side * geometry.stance_width, 0.0))
    else:
        swing0 = _pose3(initial_swing_pose, "initial_swing_pose")
    if not chk_start.is_free(*swing0):
        raise FootstepError(
            f"initial swing foot at ({swing0[0]:.3f}, {swing0[1]:.3f}) overlaps an obstacle "
            "or the map edge"
        )
    chk0 = checkers.checker(k0)
    gcell = ref.cell_of(gx, gy)
    goal_blocked = (
        world.stack[:, gcell[0], gcell[1]].all() if dynamic else bool(ref.occupied[gcell])
    )
    if goal_blocked:
        raise FootstepError(f"goal ({gx:.3f}, {gy:.3f}) lies inside an obstacle")

    # ---------------------------------------------------------------- heuristic
    tol = opts.goal_tolerance
    max_forward = float(np.max(table.displacement[..., 0]))
    c_min = float(table.step_cost.min())
    nxg, nyg = ref.shape
    if opts.heuristic == "dijkstra":
        cost_per_m = c_min / max(max_forward, 1e-3)
        depth = opts.step_over_depth
        if depth < 0:
            depth = 0.5 * max(max_forward - geometry.foot_length, 0.0) + ref.resolution
        dist = dijkstra_cost_to_go(
            ref,
            (gx, gy),
            tol,
            obstacle_cost=opts.obstacle_cost,
            impassable_depth=depth,
            deep_cost=10.0 * opts.obstacle_cost,
        )
        h_cells = (dist * cost_per_m).ravel().tolist()
    else:
        cost_per_m = c_min / max(table.max_reach(), 1e-3) if opts.heuristic == "euclidean" else 0.0
        h_cells = None
    w_h = opts.heuristic_weight
    inv_res = 1.0 / ref.resolution
    ox, oy = ref.origin

    def cost_to_go(x: float, y: float) -> float:
        if h_cells is not None:
            return h_cells[int((x - ox) * inv_res) * nyg + int((y - oy) * inv_res)]
        return max(0.0, math.hypot(x - gx, y - gy) - tol) * cost_per_m

    # ---------------------------------------------------------------- successors (T, F)
    n = table.n
    names = table.actions
    succ: list[list[list[list[tuple]]]] = [
        [[[] for _ in range(2)] for _ in range(n)] for _ in range(n)
    ]
    for i2 in range(n):
        for i1 in range(n):
            for f in (0, 1):
                allowed = (
                    set(action_filter(names[i2], names[i1], Foot(f)))
                    if action_filter is not None
                    else set(names)
                )
                unknown = allowed - set(names)
                if unknown:
                    raise FootstepError(f"action_filter returned unknown actions {sorted(unknown)}")
                for a in range(n):
                    if names[a] in allowed:
                        dx, dy, dth = table.displacement[i2, i1, f, a]
                        succ[i2][i1][f].append(
                            (
                                a,
                                float(dx),
                                float(dy),
                                float(dth),
                                float(table.duration[i2, i1, f, a]),
                                float(table.step_cost[a]),
                            )
                        )

    # ---------------------------------------------------------------- search
    inv_q = 1.0 / opts.xy_resolution
    yaw_scale = opts.yaw_bins / (2.0 * math.pi)
    nyaw = int(opts.yaw_bins)
    KY = int(math.ceil(ref.size[1] * inv_q)) + 3
    inv_tq = 1.0 / opts.time_resolution
    height_w = opts.height_cost_weight
    use_heights = height_w > 0 and ref.heights is not None
    flat_limit = opts.max_height_range if ref.heights is not None else math.inf
    if math.isfinite(flat_limit):
        for name, pose in (("start", (sx, sy, sth)), ("initial swing foot", swing0)):
            rng_h = chk_start.height_range(*pose)
            if rng_h > flat_limit:
                raise FootstepError(
                    f"{name} at ({pose[0]:.3f}, {pose[1]:.3f}) stands on ground too steep: "
                    f"height range {rng_h:.3f} m under the sole > max_height_range {flat_limit} m"
                )
    tall = None
    if ref.heights is not None and math.isfinite(opts.swing_clearance):
        tall = ref.occupied & (ref.heights > opts.swing_clearance)
        if not tall.any():
            tall = None

    hist = history_classes(table).tolist()
    n_hist = max(max(row) for row in hist) + 1
    yaw_off = nyaw + 0.5  # th * yaw_scale + yaw_off > 0: int() rounds to the nearest bin
    pad, nyp = chk0.pad, chk0.nyp
    inf = math.inf

    def make_key(x: float, y: float, th: float, f: int, a2: int, a1: int, t: float) -> int:
        k = (int((x - ox) * inv_q + 0.5) * KY + int((y - oy) * inv_q + 0.5)) * nyaw + int(
            th * yaw_scale + yaw_off
        ) % nyaw
        k = (k * 2 + f) * n_hist + hist[a2][a1]
        if dynamic:
            k = k * 1_000_000 + int(t * inv_tq + 0.5)
        return k

    # a node is a tuple (key, x, y, yaw, foot, a_prev2, a_prev1, t, g, h, parent node)
    key0 = make_key(sx, sy, sth, int(foot0), h2, h1, start_time)
    root = (key0, sx, sy, sth, int(foot0), h2, h1, float(start_time), 0.0, cost_to_go(sx, sy), None)
    best_g = {key0: 0.0}
    closed: set[int] = set()
    heap = [(w_h * root[9], 0.0, 0, root)]
    best_node = root
    best_h, best_gg = root[9], 0.0
    counter = 1
    deadline = t_begin + opts.time_limit
    tol2 = tol * tol
    expanded = 0
    max_exp = int(opts.max_expansions) if opts.max_expansions > 0 else -1
    generated = 0
    merged = 0
    goal_node = None
    status = PlanStatus.UNREACHABLE
    perf = time.perf_counter
    heappush, heappop = heapq.heappush, heapq.heappop
    cos, sin, pi, two_pi = math.cos, math.sin, math.pi, 2.0 * math.pi

    while heap:
        if expanded and perf() > deadline:  # at least one expansion: a partial plan moves
            status = PlanStatus.TIME_LIMIT
            break
        node = heappop(heap)[3]
        key, x, y, th, f, a2_, a1_, t, g, _, _ = node
        if key in closed:
            continue
        if expanded == max_exp:
            status = PlanStatus.NODE_LIMIT
            break
        closed.add(key)
        expanded += 1
        if (x - gx) * (x - gx) + (y - gy) * (y - gy) <= tol2:
            goal_node = node
            status = PlanStatus.SUCCESS
            break
        nf = 1 - f
        c, s = cos(th), sin(th)
        hist_row = hist[a1_]
        for a, dx, dy, dth, dur, sc in succ[a2_][a1_][f]:
            x2 = x + c * dx - s * dy
            y2 = y + s * dx + c * dy
            th2 = (th + dth + pi) % two_pi - pi
            t2 = t + dur
            generated += 1
            k2 = (
                (
                    (int((x2 - ox) * inv_q + 0.5) * KY + int((y2 - oy) * inv_q + 0.5)) * nyaw
                    + int(th2 * yaw_scale + yaw_off) % nyaw
                )
                * 2
                + nf
            ) * n_hist + hist_row[a]
            if dynamic:
                k2 = k2 * 1_000_000 + int(t2 * inv_tq + 0.5)
            if k2 in closed:
                merged += 1
                continue
            g2 = g + sc
            old = best_g.get(k2)
            if old is not None and old <= g2:
                merged += 1
                continue
            # location cost: infinite if the foot overlaps an occupied cell of E(t2)
            fx = (x2 - ox) * inv_res
            fy = (y2 - oy) * inv_res
            if not (0.0 <= fx < nxg and 0.0 <= fy < nyg):
                continue
            ix = int(fx)
            iy = int(fy)
            if dynamic:
                kt = checkers.index(t2)
                if kt < 0:
                    continue
                chk = checkers.checker(kt)
            else:
                chk = chk0
            if not chk.free_bytes[(ix + pad) * nyp + iy + pad] and not chk._check_masks(
                0, ix, iy, fx - ix, fy - iy, th2
            ):
                continue
            if flat_limit < inf and chk_start.height_range(x2, y2, th2) > flat_limit:
                continue
            if tall is not None:
                par = node[10]
                px, py = (par[1], par[2]) if par is not None else (swing0[0], swing0[1])
                if _swing_crosses(tall, px, py, x2, y2, ox, oy, inv_res):
                    continue
            if use_heights:
                g2 += height_w * chk_start.height_range(x2, y2, th2)
                if old is not None and old <= g2:
                    continue
            best_g[k2] = g2
            h = h_cells[ix * nyg + iy] if h_cells is not None else cost_to_go(x2, y2)
            if h == inf:
                continue
            child = (k2, x2, y2, th2, nf, a1_, a, t2, g2, h, node)
            if h < best_h or (h == best_h and g2 < best_gg):
                best_node, best_h, best_gg = child, h, g2
            heappush(heap, (g2 + w_h * h, -g2, counter, child))
            counter += 1

    end = goal_node if goal_node is not None else best_node
    chain = []
    nd = end
    while nd is not None:
        chain.append(nd)
        nd = nd[10]
    chain.reverse()
    return FootstepPlan(
        poses=[[nd[1], nd[2], nd[3]] for nd in chain],
        feet=[nd[4] for nd in chain],
        actions=[names[nd[6]] for nd in chain[1:]],
        times=[nd[7] for nd in chain],
        status=status,
        cost=end[8],
        cost_to_go=end[9],
        nodes_expanded=expanded,
        nodes_generated=generated,
        planning_time_s=time.perf_counter() - t_begin,
        initial_swing_pose=list(swing0),
        goal=[gx, gy],
        goal_tolerance=tol,
        initial_history=[names[h2], names[h1]],
        xy_resolution=opts.xy_resolution,
        yaw_bins=int(opts.yaw_bins),
    ), merged
