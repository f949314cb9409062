"""The biped's search space and successors: Chestnutt et al.'s table T as a step model.

A state (:class:`BipedState`) is the stance foot pose ``(x, y, yaw)``, which foot stands,
the last two commanded actions, the time and where the swing foot stands. Its successors
come from the displacement table ``T(a_prev2, a_prev1, stance foot, a)`` for the actions the
filter F allows; each costs ``step_cost(a) + location_cost(landing)`` and is dropped when
the landing foot rectangle (inflated by the margin) overlaps an occupied cell of E(t), is
not flat enough, steps up or down more than the limits (highest ground under each sole),
or its swing line crosses an obstacle taller than the swing clearance. In a dynamic world
a foot stands from its landing until the next step lands: a landing is checked over the
table's shortest step, and a step that lasts longer is taken only if the stance foot stays
free until that step lands.
States are merged on a lattice of ``xy_resolution`` x ``yaw_bins`` (x time bins in dynamic
worlds, x history classes) by :meth:`BipedStepModel.lattice_key`, the one place the key is
written; the poses themselves stay continuous.

:class:`BipedStepModel` satisfies :class:`repertoire.planning.footstep.search.StepModel`,
so the generic weighted A* runs it; for static grids it also exports its tables
(:meth:`BipedStepModel.compiled_tables`) for the compiled core
(:mod:`repertoire.planning.footstep.fastcore`).
"""

import collections
import dataclasses
import math
from collections.abc import Callable, Iterable, Iterator, Sequence
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from repertoire.planning.footstep.actions import (
    ASIMO_LIKE,
    BipedGeometry,
    apply_displacement,
    history_classes,
    swing_start_classes,
)
from repertoire.planning.footstep.environment import DynamicEnvironment, OccupancyGrid
from repertoire.planning.footstep.fastkernels import swing_crosses
from repertoire.planning.footstep.footprint import (
    FootprintChecker,
    FootprintMasks,
    footprint_masks,
)
from repertoire.planning.footstep.heuristic import LazyCostToGo, shared_cost_to_go
from repertoire.planning.footstep.reachability import goal_closed_reason, goal_foothold_error
from repertoire.planning.footstep.types import (
    ActionTable,
    Foot,
    FootstepError,
    parse_foot,
    wrap_angle,
)

from repertoire.checks import is_real
from repertoire.limits import require_memory

if TYPE_CHECKING:
    from repertoire.planning.footstep.planner import PlannerOptions

ActionFilter = Callable[[str, str, Foot], Sequence[str]]

# per map cell: the Dijkstra field, its indexed heap (4 arrays), the cost and depth fields,
# the edge distance and two padded footprint grids (occupancy, distance, free flag); a field
# computed whole at set-up has no heap but padded distance and cost copies, row distances
# and queue entries (~30 more)
PLANNING_BYTES_PER_CELL = 150
# maps up to this many cells get the whole Dijkstra field at set-up (a bucket queue, ~25-60
# ns per cell: at most a few tens of ms), larger ones settle it on demand
EAGER_CELLS = 1 << 20


class BipedState(NamedTuple):
    """One search state of the biped.

    Immutable: a named tuple, built 4-5x faster than a frozen dataclass (the search builds
    one per successor and per plan step).

    Attributes:
        x, y, yaw: stance foot pose (m, m, rad), continuous.
        foot: index of the stance foot (0 left, 1 right).
        a_prev2, a_prev1: indices of the two last actions (``a_prev1`` led here).
        t: time (s) at which this foot became the stance foot.
        swing_x, swing_y: where the swing foot stands (the previous stance foot).
        h: cost-to-go estimate of this state (the model's heuristic).
    """

    x: float
    y: float
    yaw: float
    foot: int
    a_prev2: int
    a_prev1: int
    t: float
    swing_x: float
    swing_y: float
    h: float


_TABLE_CACHE: dict[bytes, dict] = {}
_TABLE_SEEN: dict[int, tuple] = {}  # by object: (it, content, names and shapes, entry)


def _table_entry(table: ActionTable) -> dict:
    """Work that depends on the table's content only, remembered for a few tables.

    The table is validated the first time its content is seen; the entry then holds its
    history classes (``"hist"``, ``"n_hist"``), its longest duration, forward step,
    cheapest step cost and reach, and, once built, its successor rows without an action
    filter (``"succ"``).
    """
    content = table.displacement.tobytes() + table.duration.tobytes() + table.step_cost.tobytes()
    shapes = (table.displacement.shape, table.duration.shape, table.step_cost.shape)
    # the same table object again: its content compared with what it held (a memcmp and a
    # few small equalities), not hashed and printed again (~10 us per plan)
    seen = _TABLE_SEEN.get(id(table))
    if (
        seen is not None
        and seen[0] is table
        and seen[1] == content
        and seen[2] == (list(table.actions), table.rest_action, table.mirror, shapes)
    ):
        return seen[3]
    meta = repr((table.actions, table.rest_action, sorted(table.mirror.items())))
    key = content + (meta + repr(shapes)).encode()
    entry = _TABLE_CACHE.get(key)
    if entry is None:
        table.validate()
        if len(_TABLE_CACHE) >= 8:
            _TABLE_CACHE.clear()
        hist = history_classes(table)
        entry = _TABLE_CACHE[key] = {
            "hist": hist,
            "n_hist": int(hist.max()) + 1,
            "min_duration": float(table.duration.min()),
            "max_forward": float(np.max(table.displacement[..., 0])),
            "c_min": float(table.step_cost.min()),
            "max_reach": table.max_reach(),
        }
    if len(_TABLE_SEEN) >= 8:
        _TABLE_SEEN.clear()
    meta_now = (list(table.actions), table.rest_action, dict(table.mirror), shapes)  # copies
    _TABLE_SEEN[id(table)] = (table, content, meta_now, entry)
    return entry


def pose3(p: Sequence[float], name: str) -> tuple[float, float, float]:
    """``(x, y[, yaw])`` as three finite floats with the yaw wrapped; errors name ``p``."""
    try:
        vals = [float(v) for v in p]
    except (TypeError, ValueError):
        raise FootstepError(f"{name} must be a sequence of numbers, got {p!r}") from None
    if len(vals) == 2:
        vals.append(0.0)
    if len(vals) != 3 or not all(math.isfinite(v) for v in vals):
        raise FootstepError(f"{name} must be finite (x, y[, yaw]), got {p!r}")
    return vals[0], vals[1], wrap_angle(vals[2])


def sole_masks(geometry: BipedGeometry, margin: float, resolution: float) -> FootprintMasks:
    """The cached footprint masks of the sole inflated by ``margin`` (m) on every side."""
    return footprint_masks(
        geometry.foot_length + 2.0 * margin, geometry.foot_width + 2.0 * margin, resolution
    )


CACHE_BYTES = 256 * 2**20
"""Memory (bytes, estimated) each per-time cache of a dynamic world's model may hold (footprint
checkers, swing-blocking masks), least recently used out first (rebuilt when needed): an 8 m
map with a 60 s horizon held ~145 MB for a 37-step plan before; 12 m with heights ~2.6 MB/index."""


class _LruCache:
    """A dict of at most ``max_bytes`` (each value's size given on insertion), LRU out."""

    def __init__(self, max_bytes: int = CACHE_BYTES) -> None:
        self.max_bytes = max_bytes
        self.bytes = 0
        self._items: collections.OrderedDict = collections.OrderedDict()

    def __contains__(self, key) -> bool:
        return key in self._items

    def __len__(self) -> int:
        return len(self._items)

    def get(self, key, default=None):
        item = self._items.get(key)
        if item is None:
            return default
        self._items.move_to_end(key)
        return item[0]

    def put(self, key, value, nbytes: int) -> None:
        old = self._items.pop(key, None)
        if old is not None:
            self.bytes -= old[1]
        self._items[key] = (value, nbytes)
        self.bytes += nbytes
        while self.bytes > self.max_bytes and len(self._items) > 1:
            _, (_, n) = self._items.popitem(last=False)
            self.bytes -= n


class Checkers:
    """Footprint checkers per window of time indices (dynamic) or one checker (static).

    In a dynamic world the checker of the window ``[k, k_end]`` sees every cell occupied in
    any of those grids, with the tallest height over them: a foot that stands from a time
    near ``times[k]`` to one near ``times[k_end]`` (each grid standing for the times within
    ``max_time_gap`` of its own) is free while it stands when that checker finds it free.
    The foot rectangle is inflated by ``margin`` (m) on every side.
    """

    def __init__(
        self,
        world: "OccupancyGrid | DynamicEnvironment",
        geometry: BipedGeometry,
        margin: float = 0.0,
    ) -> None:
        self.world = world
        grid0 = world if isinstance(world, OccupancyGrid) else world.reference
        self.masks = sole_masks(geometry, margin, grid0.resolution)
        self.static = isinstance(world, OccupancyGrid)
        if self.static:
            self._static = FootprintChecker(world, self.masks)
        else:  # per time index, bounded (CACHE_BYTES): the padded occupancy, free-cell
            # bytes and row bits, and with heights the grid's and the padded heights
            pad = self.masks.radius_cells + 1
            nx, ny = grid0.shape
            per_cell = 3 + (16 if grid0.heights is not None else 0)
            self._bytes = (nx + 2 * pad) * (ny + 2 * pad) * per_cell
            self._cache = _LruCache()

    def index(self, t: float) -> int:
        """Time index of ``t``, or -1 when no grid is near (always 0 in static worlds)."""
        if self.static:
            return 0
        env = self.world
        k = env.nearest_index_unchecked(t)
        return k if abs(env.times[k] - t) <= env.max_time_gap + 1e-9 else -1

    def end_index(self, t: float) -> int:
        """Time index of ``t``, the last grid's past the grids' times (0 in static worlds)."""
        return 0 if self.static else self.world.nearest_index_unchecked(t)

    def checker(self, k: int, k_end: int | None = None) -> FootprintChecker:
        """The checker of grids ``k .. k_end`` (both included; ``k`` alone by default)."""
        if self.static:
            return self._static
        key = (k, k if k_end is None else max(k, k_end))
        c = self._cache.get(key)
        if c is None:
            env = self.world
            window = slice(key[0], key[1] + 1)
            union = env.stack[window].any(axis=0)
            ref = env.reference
            heights = ref.heights
            if heights is not None:  # the tallest obstacle over the window
                heights = np.max([g.heights for g in env.grids[window]], axis=0)
            c = FootprintChecker(
                OccupancyGrid(union, ref.resolution, ref.origin, heights), self.masks
            )
            self._cache.put(key, c, self._bytes)
        return c


@dataclasses.dataclass(frozen=True)
class Successor:
    """One row of the successor table: action ``a`` with its displacement, duration, cost."""

    a: int
    dx: float
    dy: float
    dyaw: float
    duration: float
    cost: float


class BipedStepModel:
    """The biped's step model over a static grid or a dynamic environment.

    Args:
        world: a static :class:`OccupancyGrid` or a :class:`DynamicEnvironment` E(t).
        start: ``(x, y, yaw)`` of the stance foot at the start.
        start_foot: which foot stands at ``start`` (the other one moves first).
        goal: ``(x, y)`` of the goal point (a third value, yaw, is ignored).
        table: the displacement table T (with durations and step costs).
        opts: validated planner options (lattice, heuristic, margins, limits).
        geometry: foot size and stance width.
        initial_swing_pose: the other foot at the start; default: beside the stance foot.
        start_time: time of the start state (s).
        initial_history: ``(a_prev2, a_prev1)`` before the first action; default rest twice.
        action_filter: F: ``(a_prev2, a_prev1, stance_foot) -> allowed action names``.
        swing_start_states: where some cell is taller than the swing clearance, key the
            lattice on where the swing foot lifts from too (:func:`~repertoire.planning.
            footstep.actions.swing_start_classes`), so no state's swings are judged from
            another's swing start: no plan lost by that merge, up to 7x the states for the
            nominal table. ``plan_footsteps`` turns it on for its refinements.

    Raises:
        FootstepError: a bad world, table, pose, history or filter (also one that allows no
            action at all); a start or goal off the map, a start foot on an obstacle or on
            ground too steep, a goal in an obstacle or where no sole fits or stands flat
            enough within the goal tolerance.
        ResourceLimitError: a map whose planning fields would not fit in memory.
    """

    def __init__(
        self,
        world: "OccupancyGrid | DynamicEnvironment",
        start: Sequence[float],
        start_foot: "Foot | int | str",
        goal: Sequence[float],
        table: ActionTable,
        opts: "PlannerOptions",
        *,
        geometry: BipedGeometry = ASIMO_LIKE,
        initial_swing_pose: Sequence[float] | None = None,
        start_time: float = 0.0,
        initial_history: Sequence[str] | None = None,
        action_filter: ActionFilter | None = None,
        swing_start_states: bool = False,
    ) -> None:
        if not isinstance(table, ActionTable):
            raise FootstepError(f"table must be an ActionTable, got {type(table).__name__}")
        self._table_entry = _table_entry(table)  # validates a table not seen before
        if not isinstance(world, (OccupancyGrid, DynamicEnvironment)):
            raise FootstepError(
                f"world must be an OccupancyGrid or DynamicEnvironment, got {type(world).__name__}"
            )
        self.dynamic = dynamic = isinstance(world, DynamicEnvironment)
        if dynamic and opts.heuristic == "dijkstra":
            raise FootstepError(
                "the 'dijkstra' heuristic needs a static grid; use 'euclidean' in dynamic worlds"
            )
        if not isinstance(geometry, BipedGeometry):
            raise FootstepError(f"geometry must be a BipedGeometry, got {geometry!r}")
        if not (is_real(start_time) and math.isfinite(start_time)):
            raise FootstepError(
                f"start_time must be a finite number of seconds, got {start_time!r}"
            )
        self.world, self.table, self.opts, self.geometry = world, table, opts, geometry
        self.foot0 = parse_foot(start_foot)
        self.start_pose = sx, sy, sth = pose3(start, "start")
        gx, gy, _ = pose3(goal, "goal")
        self.goal = (gx, gy)
        self.ref = ref = world if not dynamic else world.reference
        nx, ny = ref.shape
        require_memory(
            PLANNING_BYTES_PER_CELL * nx * ny,
            f"planning fields (cost-to-go, distances, padded footprint grids) of a {nx} x {ny} "
            f"map at {ref.resolution} m",
        )
        if dynamic:
            world.index_at(start_time)  # raises GridError when no grid is near the start time
        for name, (px, py) in (("start", (sx, sy)), ("goal", (gx, gy))):
            if not ref.contains(px, py):
                x0, y0 = ref.origin
                w, h = ref.size
                raise FootstepError(
                    f"{name} ({px:.3f}, {py:.3f}) lies outside the map "
                    f"[{x0}, {x0 + w}) x [{y0}, {y0 + h}) (its far edges are outside)"
                )
        history = list(initial_history) if initial_history is not None else [table.rest_action] * 2
        if len(history) != 2:
            raise FootstepError(f"initial_history must hold two actions, got {history}")
        self.history0 = (table.index(history[0]), table.index(history[1]))
        self.start_time = float(start_time)

        # a landed foot stands until the next step lands: at least the table's shortest step
        self.min_hold = self._table_entry["min_duration"]
        self.checkers = Checkers(world, geometry, opts.footprint_margin_m)
        self.k0 = self.checkers.index(start_time)
        # the start feet already stand: checked exactly, without the margin; the height
        # cost is also measured under the exact footprint (heights are the same at all t)
        exact = Checkers(world, geometry, 0.0) if opts.footprint_margin_m > 0 else self.checkers
        self.exact_checkers = exact
        self._swing_tall_cache = _LruCache()  # per (swing start, landing) index pair
        # occupied at the start time: a bad input. Hit later, while it stands until the first
        # step lands: no error, the first steps that land too late are dropped (successors)
        self.exact = exact.checker(self.k0)
        self.start_hit: float | None = None  # grid time when the start foot is first hit
        self.start_successors = 0  # successors the start state yielded
        self.past_grids = 0  # landings dropped: their time is past the last grid's
        self.between_grids = 0  # ... or between two grids, near neither (max_time_gap)
        # dynamic: goal landings whose trailing foot is hit while the robot stands after them
        # (for the table's shortest step, as every landing foot): not goals
        self.rest_blocked: set[BipedState] = set()
        if not self.exact.is_free(sx, sy, sth, shortcut=False):
            when = f" at t = {start_time:.3f} s" if dynamic else ""
            raise FootstepError(
                f"start foot at ({sx:.3f}, {sy:.3f}, {sth:.3f}) overlaps an obstacle "
                f"or the map edge{when}"
            )
        if initial_swing_pose is None:
            side = 1.0 if self.foot0 == Foot.RIGHT else -1.0
            swing0 = apply_displacement((sx, sy, sth), (0.0, side * geometry.stance_width, 0.0))
        else:
            swing0 = pose3(initial_swing_pose, "initial_swing_pose")
        self.swing0 = swing0
        # the swing foot lifts at the start time (the first step moves it): in a dynamic
        # world it must be free in E(start_time) only, not over the stance foot's hold window
        # (an obstacle may pass over the spot it leaves, as in receding-horizon replanning)
        if not self.exact.is_free(*swing0, shortcut=False):
            when = f" at t = {self.start_time:.3f} s" if dynamic else ""
            raise FootstepError(
                f"initial swing foot at ({swing0[0]:.3f}, {swing0[1]:.3f}) overlaps an obstacle "
                f"or the map edge{when}"
            )
        self.chk0 = self.checkers.checker(self.k0)
        gcell = ref.cell_of(gx, gy)
        if (world.stack if dynamic else ref.occupied[None])[:, gcell[0], gcell[1]].all():
            raise FootstepError(f"goal ({gx:.3f}, {gy:.3f}) lies inside an obstacle")
        self._setup_terrain_limits()
        if why := goal_foothold_error(self):  # no sole fits near the goal, or too steep there
            raise FootstepError(why)
        self.goal_closed = goal_closed_reason(self)  # covered before the robot can get there
        self._setup_heuristic()
        if not isinstance(swing_start_states, (bool, np.bool_)):
            raise FootstepError(
                f"swing_start_states must be True or False, got {swing_start_states!r}"
            )
        self._setup_successors(action_filter, bool(swing_start_states))
        self._setup_lattice()

    # ------------------------------------------------------------------ setup
    def _setup_terrain_limits(self) -> None:
        opts, ref = self.opts, self.ref
        self.height_w = opts.height_cost_weight if ref.heights is not None else 0.0
        self.flat_limit = opts.max_height_range if ref.heights is not None else math.inf
        has_h = ref.heights is not None
        self.step_up = opts.max_step_up if has_h else math.inf
        self.step_down = opts.max_step_down if has_h else math.inf
        self.step_limits = math.isfinite(self.step_up) or math.isfinite(self.step_down)
        self.swing_limit = has_h and math.isfinite(opts.swing_clearance)  # see _tall_in
        free_h = ref.heights[~ref.occupied] if self.swing_limit and not self.dynamic else []
        self.ground_level = float(free_h[0]) if len(free_h) and np.ptp(free_h) == 0 else None
        self.uses_heights = self.step_limits or self.swing_limit or has_h and (
            math.isfinite(opts.max_height_range) or opts.height_cost_weight > 0.0)  # fmt: skip
        if math.isfinite(self.flat_limit):
            for name, pose in (("start", self.start_pose), ("initial swing foot", self.swing0)):
                rng_h = self.exact.height_range(*pose)
                if rng_h > self.flat_limit:
                    raise FootstepError(
                        f"{name} at ({pose[0]:.3f}, {pose[1]:.3f}) stands on ground too steep: "
                        f"height range {rng_h:.3f} m under the sole > max_height_range "
                        f"{self.flat_limit} m"
                    )
        self.tall = self.tall_at(self.k0) if not self.dynamic else None

    def _setup_heuristic(self) -> None:
        opts, ref = self.opts, self.ref
        self.tol = tol = opts.goal_tolerance
        entry = self._table_entry
        max_forward, c_min = entry["max_forward"], entry["c_min"]
        self.h_lazy: LazyCostToGo | None = None
        if opts.heuristic == "dijkstra":
            self.cost_per_m = c_min / max(max_forward, 1e-3)
            depth = opts.step_over_depth
            if depth < 0:
                depth = 0.5 * max(max_forward - self.geometry.foot_length, 0.0) + ref.resolution
            self.h_lazy = shared_cost_to_go(
                ref,
                self.goal,
                tol,
                self.start_pose[:2],
                obstacle_cost=opts.obstacle_cost,
                impassable_depth=depth,
                deep_cost=10.0 * opts.obstacle_cost,
                eager_cells=EAGER_CELLS,
            )
        elif opts.heuristic == "euclidean":
            self.cost_per_m = c_min / max(entry["max_reach"], 1e-3)
        else:
            self.cost_per_m = 0.0

    def _setup_successors(self, action_filter: ActionFilter | None, swing_starts: bool) -> None:
        entry = self._table_entry
        if action_filter is None and "succ" in entry:
            self.succ_ptr, self.succ_a, self.succ_f = entry["succ"]
        else:
            self._build_successors(action_filter)
            if action_filter is None:
                entry["succ"] = (self.succ_ptr, self.succ_a, self.succ_f)
        self._succ_rows: list[tuple[Successor, ...]] | None = None
        self.hist, self.n_hist = entry["hist"], entry["n_hist"]
        grids = self.world.grids if self.dynamic else [self.ref]
        if swing_starts and self._tall_in(grids) is not None:  # swings checked: a state's too
            self.hist = swing_start_classes(self.table, self.hist)
            self.n_hist = int(self.hist.max()) + 1
        self._hist_rows = self.hist.tolist()

    def _build_successors(self, action_filter: ActionFilter | None) -> None:
        table = self.table
        n, names = table.n, table.actions
        allowed = np.ones((n, n, 2, n), dtype=bool)
        if action_filter is not None:
            index = {name: a for a, name in enumerate(names)}
            for i2 in range(n):
                for i1 in range(n):
                    for f in (0, 1):
                        got = action_filter(names[i2], names[i1], Foot(f))
                        if isinstance(got, str) or not isinstance(got, Iterable):
                            raise FootstepError(
                                "action_filter must return a sequence of action names, got "
                                f"{got!r} for ({names[i2]}, {names[i1]}, {Foot(f).name})"
                            )
                        ok = set(got)
                        unknown = ok - set(names)
                        if unknown:
                            raise FootstepError(
                                f"action_filter returned unknown actions {sorted(unknown, key=str)}"
                            )
                        allowed[i2, i1, f] = False
                        allowed[i2, i1, f, [index[a] for a in ok]] = True
        # rows in (a_prev2, a_prev1, foot, a) order; succ_ptr[(a2 * n + a1) * 2 + f] starts a block
        if not allowed.any():
            raise FootstepError(
                "the step model's successors are empty: the action_filter allows no action "
                "after any history"
            )
        counts = allowed.reshape(-1, n).sum(axis=1)
        self.succ_ptr = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        self.succ_a = np.nonzero(allowed)[3].astype(np.int64)
        cost = np.broadcast_to(np.asarray(table.step_cost, float), allowed.shape)
        self.succ_f = np.column_stack(
            [
                table.displacement[allowed],
                table.duration[allowed],
                cost[allowed],
            ]
        ).astype(float)

    def successor_rows(self, a_prev2: int, a_prev1: int, foot: int) -> tuple[Successor, ...]:
        """The actions F allows after ``(a_prev2, a_prev1)`` on ``foot``, with T's values."""
        if self._succ_rows is None:
            rows = [
                Successor(a, *vals)
                for a, vals in zip(self.succ_a.tolist(), self.succ_f.tolist(), strict=True)
            ]
            ptr = self.succ_ptr.tolist()
            self._succ_rows = [tuple(rows[ptr[k] : ptr[k + 1]]) for k in range(len(ptr) - 1)]
        return self._succ_rows[(a_prev2 * self.table.n + a_prev1) * 2 + foot]

    def _setup_lattice(self) -> None:
        opts, ref = self.opts, self.ref
        self.inv_q = 1.0 / opts.xy_resolution
        self.nyaw = int(opts.yaw_bins)
        self.yaw_scale = self.nyaw / (2.0 * math.pi)
        # the yaw bins are centred on the start's yaw (see lattice_key)
        u = self.start_pose[2] * self.yaw_scale
        self.yaw_shift = self.nyaw + 0.5 - (u - round(u))
        self.ky = int(math.ceil(ref.size[1] * self.inv_q)) + 3
        self.inv_tq = 1.0 / opts.time_resolution
        if self.dynamic:  # time bins over the grids' span: every reachable state's time
            env = self.world
            self.tb0 = math.floor((env.times[0] - env.max_time_gap) * self.inv_tq + 0.5) - 1
            tb1 = math.floor((env.times[-1] + env.max_time_gap) * self.inv_tq + 0.5) + 1
            self.n_tbins = tb1 - self.tb0 + 1
        self.inv_res = 1.0 / ref.resolution
        self.origin = ref.origin

    def _tall_in(self, grids: Iterable[OccupancyGrid]) -> np.ndarray | None:
        """Each cell's highest height over ``grids``; None when none exceeds the clearance.

        A cell, occupied or free, blocks a swing line when higher than ``swing_clearance``
        over the higher ground of the stance and landing soles (0.35 m on a 0.3 m platform
        is 5 cm tall); grounds are >= 0, so None: nothing blocks.
        """
        if not self.swing_limit:
            return None
        tops = np.max([g.heights for g in grids], axis=0)
        return tops if float(tops.max()) > self.opts.swing_clearance else None

    def tall_at(self, k: int) -> np.ndarray | None:
        """Cell heights the swing is checked against at time index ``k`` (None: no limit)."""
        return self._tall_in([self.checkers.checker(k).grid])

    def tall_during(self, ka: int, kb: int) -> np.ndarray | None:
        """Each cell's highest height over grids ``ka`` to ``kb`` (both in; :meth:`_tall_in`).

        Args:
            ka: time index of the swing's start.
            kb: time index of the landing.
        """
        key = (ka, kb)
        if key in self._swing_tall_cache:
            return self._swing_tall_cache.get(key)
        tall = self._tall_in(self.world.grids[ka : kb + 1])
        self._swing_tall_cache.put(key, tall, 64 if tall is None else tall.nbytes)
        return tall

    # ------------------------------------------------------------------ lattice
    def lattice_key(self, x: float, y: float, yaw: float, foot: int, hist: int, t: float) -> int:
        """The lattice cell of a state: equal keys are the same search state.

        Position rounded to ``xy_resolution``, yaw (in ``[-pi, pi)``) to ``yaw_bins``, the
        foot, the history class and, in dynamic worlds, the time rounded to
        ``time_resolution`` (bins counted over the span of the grids' times, so any
        resolution and any times, negative ones too, give distinct keys).
        :mod:`~repertoire.planning.footstep.fastcore` computes the same integer (static).

        The yaw bins are centred on the start's yaw. The yaws a plan reaches are the start's
        plus whole turns; the nominal turn, 0.35 rad, is 2.005 bins of 36 and 4.011 of 72,
        so there each such yaw lies within a fifth of a bin of a centre, and yaws that
        differ by rounding alone or by a whole turn's remainder (18 turns come back 0.017
        rad off) share a bin. With bins placed on the map's axes instead, 37 % of start yaws
        (20,000 drawn) put at least one such pair on either side of a boundary at 72 bins:
        one 12 m floor's admissible search expanded 5.2 M states where 36 bins needed 2.7
        M, for the same cost.
        """
        ox, oy = self.origin
        inv_q = self.inv_q
        k = (int((x - ox) * inv_q + 0.5) * self.ky + int((y - oy) * inv_q + 0.5)) * self.nyaw + int(
            yaw * self.yaw_scale + self.yaw_shift
        ) % self.nyaw
        k = (k * 2 + foot) * self.n_hist + hist
        if self.dynamic:  # one key per (state, time bin) however many bins: no collisions
            k = k * self.n_tbins + math.floor(t * self.inv_tq + 0.5) - self.tb0
        return k

    def cost_to_go(self, x: float, y: float) -> float:
        """Heuristic at a point of the map (inf where the Dijkstra field says unreachable)."""
        if self.h_lazy is not None:
            ox, oy = self.origin
            ny = self.ref.shape[1]
            cell = int((x - ox) * self.inv_res) * ny + int((y - oy) * self.inv_res)
            return self.h_lazy.value(cell) * self.cost_per_m
        gx, gy = self.goal
        dx, dy = x - gx, y - gy  # sqrt, not hypot: the compiled core's formula, bit for bit
        return max(0.0, math.sqrt(dx * dx + dy * dy) - self.tol) * self.cost_per_m

    # ------------------------------------------------------------------ StepModel
    def start(self) -> BipedState:
        sx, sy, sth = self.start_pose
        a2, a1 = self.history0
        return BipedState(
            sx,
            sy,
            sth,
            int(self.foot0),
            a2,
            a1,
            self.start_time,
            self.swing0[0],
            self.swing0[1],
            self.cost_to_go(sx, sy),
        )

    def key(self, s: BipedState) -> int:
        return self.lattice_key(s.x, s.y, s.yaw, s.foot, self._hist_rows[s.a_prev2][s.a_prev1], s.t)

    def is_goal(self, s: BipedState) -> bool:
        """Within the goal tolerance, and (dynamic) both feet free to stand after it."""
        dx, dy = s.x - self.goal[0], s.y - self.goal[1]
        return dx * dx + dy * dy <= self.tol * self.tol and s not in self.rest_blocked

    def heuristic(self, s: BipedState) -> float:
        return s.h

    def successors(
        self, s: BipedState, dominated: "Callable[[int, float], bool] | None" = None
    ) -> Iterator[tuple[BipedState, float]]:
        """The landings T allows from ``s`` that are free, flat and reachable by the swing.

        With the search's ``dominated(key, step_cost)`` test
        (:func:`~repertoire.planning.footstep.search.successor_function`), a landing whose
        lattice state is already reached as cheaply is skipped before its checks (when its
        cost is the table's: no height cost), as the compiled core does.
        """
        if self.goal_closed:  # no plan (the start's successors: the search ends at once)
            return
        (ox, oy), inv_res, (nx, ny) = self.origin, self.inv_res, self.ref.shape
        c, sn = math.cos(s.yaw), math.sin(s.yaw)
        nf = 1 - s.foot
        ex1 = self.exact
        k_swing = self.checkers.index(s.t) if self.dynamic else 0  # the swing starts at s.t
        is_start = s.t == self.start_time  # every other state's time is later
        if self.dynamic:  # the stance foot stands until the step lands: checked up to the
            # table's shortest step when it landed (the start: at the start time only),
            # here up to each longer step's landing (once per landing index)
            stance_checked = self.k0 if is_start else self.checkers.end_index(s.t + self.min_hold)
            stance_free: dict[int, bool] = {}
            stance_checkers = self.exact_checkers if is_start else self.checkers
        z_ground = self.step_limits or self.swing_limit and self.ground_level is None
        if self.dynamic and z_ground:
            ex1 = self.exact_checkers.checker(k_swing)
        z0 = self.ground_level or 0.0
        z1 = ex1.top_height(s.x, s.y, s.yaw) if z_ground else z0
        z1s = max(z1, ex1.cell_height(s.swing_x, s.swing_y)) if z_ground else z0  # + lift-off
        if self.height_w > 0.0:
            dominated = None  # a landing's cost is known only after its height check
        hist1 = self._hist_rows[s.a_prev1]
        (gx, gy), tol2 = self.goal, self.tol * self.tol
        for m in self.successor_rows(s.a_prev2, s.a_prev1, s.foot):
            x2 = s.x + c * m.dx - sn * m.dy
            y2 = s.y + sn * m.dx + c * m.dy
            th2 = (s.yaw + m.dyaw + math.pi) % (2.0 * math.pi) - math.pi
            t2 = s.t + m.duration
            fx = (x2 - ox) * inv_res
            fy = (y2 - oy) * inv_res
            if not (0.0 <= fx < nx and 0.0 <= fy < ny):
                continue
            kt = self.checkers.index(t2) if self.dynamic else 0
            if kt < 0:  # no grid near its time: no state (nor a lattice key) there
                if t2 > self.world.times[-1]:
                    self.past_grids += 1
                else:
                    self.between_grids += 1
                continue
            if dominated is not None and dominated(
                self.lattice_key(x2, y2, th2, nf, hist1[m.a], t2), m.cost
            ):
                continue
            if self.dynamic:
                if kt > stance_checked:
                    free = stance_free.get(kt)
                    if free is None:
                        free = stance_free[kt] = stance_checkers.checker(k_swing, kt).is_free(
                            s.x, s.y, s.yaw, shortcut=False
                        )
                    if not free:
                        if is_start:
                            self._note_start_hit(kt)
                        continue
                k_hold = self.checkers.end_index(t2 + self.min_hold)  # it stands at least so
                chk = self.checkers.checker(kt, k_hold)
                ex = self.exact_checkers.checker(kt, k_hold) if self.uses_heights else self.exact
                tall = self.tall_during(k_swing, kt)
            else:
                chk, ex, tall = self.chk0, self.exact, self.tall
            ix, iy = int(fx), int(fy)
            if not chk.free_bytes[(ix + chk.pad) * chk.nyp + iy + chk.pad] and not (
                chk._check_masks(0, ix, iy, fx - ix, fy - iy, th2)
            ):
                continue
            if self.flat_limit < math.inf and ex.height_range(x2, y2, th2) > self.flat_limit:
                continue
            z2 = ex.top_height(x2, y2, th2) if z_ground else z0  # highest ground under it
            if self.step_limits and (z2 - z1 > self.step_up or z1 - z2 > self.step_down):
                continue
            top = max(z1s, z2) + self.opts.swing_clearance  # over stance, lift-off, landing
            if tall is not None and swing_crosses(
                tall, top, s.swing_x, s.swing_y, x2, y2, ox, oy, inv_res
            ):
                continue
            h = self.cost_to_go(x2, y2)
            if h == math.inf:
                continue
            cost = m.cost
            if self.height_w > 0.0:
                cost += self.height_w * ex.height_range(x2, y2, th2)
            if is_start:
                self.start_successors += 1
            nxt = BipedState(x2, y2, th2, nf, s.a_prev1, m.a, t2, s.x, s.y, h)
            if self.dynamic and (x2 - gx) ** 2 + (y2 - gy) ** 2 <= tol2:  # a last step
                if not stance_checkers.checker(kt, k_hold).is_free(s.x, s.y, s.yaw, shortcut=False):
                    self.rest_blocked.add(nxt)
            yield nxt, cost

    def _note_start_hit(self, k_end: int) -> None:
        """Record the first grid time (after the start's) at which the start foot is hit."""
        if self.start_hit is None:  # else found already: every window begins at k0
            sx, sy, sth = self.start_pose
            for k in range(self.k0 + 1, k_end + 1):
                if not self.exact_checkers.checker(k).is_free(sx, sy, sth, shortcut=False):
                    self.start_hit = float(self.world.times[k])
                    return

    def unreachable_reason(self) -> str:
        """Why the search may have run out of states, as far as the model knows ("" if not).

        In dynamic worlds: the goal covered from before the robot can get there on
        (:func:`goal_closed_reason`), the start foot hit by an obstacle before a first step lands,
        landings dropped because no grid is near their time (past the environment's last
        grid, or between two grids further apart than twice ``max_time_gap``).
        """
        if not self.dynamic:
            return ""
        env, gap = self.world, self.world.max_time_gap
        parts = [self.goal_closed] if self.goal_closed else []
        if self.start_hit is not None:
            (sx, sy, sth), hit = self.start_pose, self.start_hit
            parts.append(
                f"the start foot at ({sx:.3f}, {sy:.3f}, {sth:.3f}) stands until the first "
                f"step lands and is hit by an obstacle at t = {hit:.3f} s (the grid standing "
                f"for [{hit - gap:.3f}, {hit + gap:.3f}] s): steps landing later were dropped"
                + (", and no earlier one lands free" if self.start_successors == 0 else "")
            )
        end = f"t = {env.times[-1]:.3f} s, standing for times up to {env.times[-1] + gap:.3f} s"
        for n, where, fix in (
            (self.past_grids, f"past the environment's last grid ({end})", "extend t_end (the "
             "planning horizon) to plan further"),
            (self.between_grids, f"between grid times, more than max_time_gap = {gap:.3f} s "
             "from every grid,", "add grids there or widen max_time_gap"),
        ):  # fmt: skip
            if n:
                parts.append(f"{n} landing{'s' * (n != 1)} {where} dropped: {fix}")
        return "; ".join(parts)
