"""Environments of the footstep planner: occupancy grids and time-indexed grids E(t).

A grid has square cells of side ``resolution`` (2.5 cm in the paper); cell ``(ix, iy)``
covers ``[x0 + ix r, x0 + (ix + 1) r) x [y0 + iy r, y0 + (iy + 1) r)``. ``occupied[ix, iy]``
is True where the robot may not step; heights are optional. A dynamic world is a list of
grids with times; ``E(t)`` is the grid of the nearest time, which stands for every time
within ``max_time_gap`` of its own (grids of moving obstacles mark what they sweep then).
"""

import dataclasses
import itertools
import math
from collections.abc import Sequence

import numpy as np
from repertoire.planning.footstep.types import GridError

from repertoire.checks import is_real
from repertoire.limits import require_memory


def rect_overlaps_cells(
    center: "Sequence[float] | np.ndarray",
    half_extents: Sequence[float],
    yaw: float,
    cell_centers: np.ndarray,
    half_cell: float,
) -> np.ndarray:
    """Exact overlap (positive area) of an oriented rectangle with axis-aligned squares.

    Separating-axis test on the two grid axes and the rectangle's two axes; touching
    boundaries do not count as overlap.

    Args:
        center: rectangle centre ``(x, y)``, or (k, 2) centres of k rectangles of the same
            size and yaw (each answered element for element as if alone).
        half_extents: half length along the rectangle's x axis and half width.
        yaw: rectangle orientation (rad).
        cell_centers: (m, 2) centres of the squares.
        half_cell: half side of the squares.

    Returns:
        (m,) bool array, or (k, m) for k centres.
    """
    c, s = math.cos(yaw), math.sin(yaw)
    hl, hw = float(half_extents[0]), float(half_extents[1])
    ctr = np.asarray(center, dtype=float)
    d = np.asarray(cell_centers, dtype=float) - ctr[..., None, :]  # (m, 2) or (k, m, 2)
    eps = 1e-12
    # grid axes
    ext_x = hl * abs(c) + hw * abs(s)
    ext_y = hl * abs(s) + hw * abs(c)
    sep = np.abs(d[..., 0]) >= ext_x + half_cell - eps
    sep |= np.abs(d[..., 1]) >= ext_y + half_cell - eps
    # rectangle axes u = (c, s), v = (-s, c)
    cell_u = half_cell * (abs(c) + abs(s))
    sep |= np.abs(d[..., 0] * c + d[..., 1] * s) >= hl + cell_u - eps
    sep |= np.abs(-d[..., 0] * s + d[..., 1] * c) >= hw + cell_u - eps
    return ~sep


def swept_rect_overlaps_cells(
    center_a: Sequence[float],
    center_b: Sequence[float],
    half_extents: Sequence[float],
    yaw: float,
    cell_centers: np.ndarray,
    half_cell: float,
) -> np.ndarray:
    """Exact overlap (positive area) of the region a translating rectangle sweeps with squares.

    The rectangle moves on the segment from ``center_a`` to ``center_b`` at a fixed yaw; the
    region it covers is the convex hull of its two end placements. Separating-axis test on
    the grid axes, the rectangle's axes and the normal of the motion (the hull's edge
    normals); touching boundaries do not count. With ``center_a == center_b`` the answer is
    :func:`rect_overlaps_cells`'s.

    Args:
        center_a: centre ``(x, y)`` at the start of the motion.
        center_b: centre ``(x, y)`` at its end.
        half_extents: half length along the rectangle's x axis and half width.
        yaw: rectangle orientation (rad).
        cell_centers: (m, 2) centres of the squares.
        half_cell: half side of the squares.

    Returns:
        (m,) bool array.
    """
    c, s = math.cos(yaw), math.sin(yaw)
    hl, hw = float(half_extents[0]), float(half_extents[1])
    a = np.asarray(center_a, dtype=float)
    b = np.asarray(center_b, dtype=float)
    p = np.asarray(cell_centers, dtype=float)
    axes = [(1.0, 0.0), (0.0, 1.0), (c, s), (-s, c)]
    d = b - a
    length = math.hypot(d[0], d[1])
    if length > 1e-12:
        axes.append((-d[1] / length, d[0] / length))
    eps = 1e-12
    hit = np.ones(len(p), dtype=bool)
    for ax, ay in axes:
        r_rect = hl * abs(c * ax + s * ay) + hw * abs(-s * ax + c * ay)
        pa, pb = a[0] * ax + a[1] * ay, b[0] * ax + b[1] * ay
        lo, hi = min(pa, pb) - r_rect, max(pa, pb) + r_rect
        pc = p[:, 0] * ax + p[:, 1] * ay
        r_cell = half_cell * (abs(ax) + abs(ay))
        hit &= (pc - r_cell < hi - eps) & (pc + r_cell > lo + eps)
    return hit


@dataclasses.dataclass
class RectObstacle:
    """A flat rectangular obstacle.

    Attributes:
        center: ``[x, y]`` (m).
        size: ``[length, width]`` along the obstacle's own x and y axes (m).
        yaw: orientation (rad).
        height: height (m), stored in the grid's heights.
    """

    center: list[float]
    size: list[float]
    yaw: float = 0.0
    height: float = 0.02

    def __post_init__(self) -> None:
        _check_rectangle(self)


def _check_rectangle(ob: "RectObstacle | MovingRectObstacle") -> None:
    """Refuses a rectangle that would paint nothing or fail in numpy (naming the field).

    Raises:
        GridError: ``center`` (and ``velocity``) not 2 finite values, ``size`` not 2
            finite values > 0, ``yaw`` not finite, ``height`` not finite and >= 0.
    """
    kind = type(ob).__name__
    for name in ("center", "size", "velocity"):
        if not hasattr(ob, name):
            continue
        value = getattr(ob, name)
        try:
            v = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise GridError(f"{kind} {name} must be 2 numbers, got {value!r}") from None
        if v.shape != (2,) or not np.isfinite(v).all():
            raise GridError(f"{kind} {name} must be 2 finite numbers, got {value!r}")
        if name == "size" and not (v > 0.0).all():
            raise GridError(f"{kind} size must be > 0 m on both axes, got {value!r}")
    for name in ("yaw", "height"):
        value = getattr(ob, name)
        if not is_real(value):  # Python or numpy ints and floats (np.float32 too)
            raise GridError(f"{kind} {name} must be a number, got {value!r}")
        if not math.isfinite(value) or (name == "height" and value < 0.0):
            what = "finite" if name == "yaw" else "finite and >= 0 m"
            raise GridError(f"{kind} {name} must be {what}, got {value}")


@dataclasses.dataclass
class MovingRectObstacle:
    """A rectangle moving on a known trajectory.

    Without waypoints it translates at constant velocity: ``center(t) = center + velocity t``.
    With waypoints ``[[t0, x0, y0], [t1, x1, y1], ...]`` (increasing times) its centre is
    interpolated linearly between them and held before the first and after the last.

    Attributes:
        center: ``[x, y]`` at t = 0 (m); unused with waypoints.
        size: ``[length, width]`` (m).
        velocity: ``[vx, vy]`` (m/s); must stay zero with waypoints.
        yaw: orientation (rad).
        height: height (m).
        waypoints: optional ``[t, x, y]`` rows of a piecewise-linear trajectory.
    """

    center: list[float]
    size: list[float]
    velocity: list[float] = dataclasses.field(default_factory=lambda: [0.0, 0.0])
    yaw: float = 0.0
    height: float = 0.02
    waypoints: list[list[float]] = dataclasses.field(default_factory=list)

    def __post_init__(self) -> None:
        _check_rectangle(self)
        if self.waypoints:
            try:
                w = np.asarray(self.waypoints, dtype=float)
            except (TypeError, ValueError):
                raise GridError(
                    f"waypoints must be finite [t, x, y] rows, got {self.waypoints!r}"
                ) from None
            if w.ndim != 2 or w.shape[1] != 3 or not np.all(np.isfinite(w)):
                raise GridError(f"waypoints must be finite [t, x, y] rows, got {self.waypoints}")
            if np.any(np.diff(w[:, 0]) <= 0):
                raise GridError("waypoint times must increase strictly")
            if np.any(np.asarray(self.velocity, dtype=float) != 0.0):
                raise GridError(
                    f"MovingRectObstacle velocity {self.velocity} is not used with waypoints "
                    "(the centre follows them): give a velocity or waypoints, not both"
                )

    def center_at(self, t: float) -> list[float]:
        """Centre ``[x, y]`` at time ``t``.

        Args:
            t: time (s).
        """
        if self.waypoints:
            w = np.asarray(self.waypoints, dtype=float)
            return [float(np.interp(t, w[:, 0], w[:, 1])), float(np.interp(t, w[:, 0], w[:, 2]))]
        return [self.center[0] + self.velocity[0] * t, self.center[1] + self.velocity[1] * t]

    def path_between(self, t_a: float, t_b: float) -> list[list[float]]:
        """The centre's polyline over ``[t_a, t_b]``: its ends and the waypoints between.

        Args:
            t_a: start time (s).
            t_b: end time (s), >= ``t_a``.
        """
        inner = [w[0] for w in self.waypoints if t_a < w[0] < t_b]
        return [self.center_at(t) for t in (t_a, *inner, t_b)]

    def at(self, t: float) -> RectObstacle:
        """The obstacle at time ``t``.

        Args:
            t: time (s).
        """
        return RectObstacle(
            center=self.center_at(t), size=list(self.size), yaw=self.yaw, height=self.height
        )


@dataclasses.dataclass
class OccupancyGrid:
    """An obstacle bitmap on square cells, with optional heights.

    Attributes:
        occupied: (nx, ny) bool, True where the robot may not step.
        resolution: cell side (m).
        origin: ``(x0, y0)`` of the corner of cell (0, 0) (m).
        heights: optional (nx, ny) heights (m).
    """

    occupied: np.ndarray
    resolution: float = 0.025
    origin: tuple[float, float] = (0.0, 0.0)
    heights: np.ndarray | None = None

    def __post_init__(self) -> None:
        occupied = np.asarray(self.occupied)
        if occupied.dtype.kind not in "biuf" or (
            occupied.dtype.kind == "f" and not np.isfinite(occupied).all()
        ):
            raise GridError(
                f"occupied must hold booleans or finite numbers (nonzero: occupied), got dtype "
                f"{occupied.dtype} with values such as {occupied.ravel()[:3].tolist()}"
            )
        self.occupied = occupied if occupied.dtype == bool else occupied.astype(bool)
        if self.occupied.ndim != 2 or min(self.occupied.shape) == 0:
            raise GridError(f"occupied must be a non-empty 2-D array, got {self.occupied.shape}")
        if not (
            is_real(self.resolution) and math.isfinite(self.resolution) and self.resolution > 0
        ):
            raise GridError(
                f"resolution must be a positive number of metres, got {self.resolution!r}"
            )
        try:
            origin = np.asarray(self.origin, dtype=float)
        except (TypeError, ValueError):
            origin = None
        if origin is None or origin.shape != (2,) or not np.isfinite(origin).all():
            raise GridError(f"origin must be 2 finite numbers (x0, y0), got {self.origin!r}")
        self.origin = (float(origin[0]), float(origin[1]))
        if self.heights is not None:
            try:
                self.heights = np.asarray(self.heights, dtype=float)
            except (TypeError, ValueError):
                raise GridError(
                    f"heights must be an array of numbers, got {self.heights!r}"
                ) from None
            if self.heights.shape != self.occupied.shape:
                raise GridError(
                    f"heights shape {self.heights.shape} differs from occupied "
                    f"{self.occupied.shape}"
                )
            if not np.all(np.isfinite(self.heights)):
                bad = np.argwhere(~np.isfinite(self.heights))[0]
                raise GridError(
                    f"heights must be finite; cell ({bad[0]}, {bad[1]}) is "
                    f"{self.heights[tuple(bad)]}"
                )
            if np.any(self.heights < 0.0):
                bad = np.argwhere(self.heights < 0.0)[0]
                raise GridError(
                    f"heights must be >= 0 m (ground level 0); cell ({bad[0]}, {bad[1]}) is "
                    f"{self.heights[tuple(bad)]} m"
                )

    @property
    def shape(self) -> tuple[int, int]:
        return self.occupied.shape  # type: ignore[return-value]

    @property
    def size(self) -> tuple[float, float]:
        return self.shape[0] * self.resolution, self.shape[1] * self.resolution

    def contains(self, x: float, y: float) -> bool:
        """Whether the point is inside the mapped area.

        Args:
            x: world x (m).
            y: world y (m).
        """
        sx, sy = self.size
        return (
            self.origin[0] <= x < self.origin[0] + sx and self.origin[1] <= y < self.origin[1] + sy
        )

    def cell_of(self, x: float, y: float) -> tuple[int, int]:
        """Cell indices containing a point (may lie outside the grid).

        Args:
            x: world x (m).
            y: world y (m).
        """
        return (
            int(math.floor((x - self.origin[0]) / self.resolution)),
            int(math.floor((y - self.origin[1]) / self.resolution)),
        )

    def cell_centers(self) -> np.ndarray:
        """(nx, ny, 2) cell centres."""
        ix = self.origin[0] + (np.arange(self.shape[0]) + 0.5) * self.resolution
        iy = self.origin[1] + (np.arange(self.shape[1]) + 0.5) * self.resolution
        return np.stack(np.meshgrid(ix, iy, indexing="ij"), axis=-1)

    def same_geometry(self, other: "OccupancyGrid") -> bool:
        return (
            self.shape == other.shape
            and abs(self.resolution - other.resolution) < 1e-12
            and np.allclose(self.origin, other.origin)
        )

    @classmethod
    def empty(
        cls, size: Sequence[float], resolution: float = 0.025, origin: Sequence[float] = (0.0, 0.0)
    ) -> "OccupancyGrid":
        """A free grid covering ``size`` metres.

        Args:
            size: ``(width_x, width_y)`` (m).
            resolution: cell side (m).
            origin: corner of cell (0, 0).

        Raises:
            GridError: a bad size or resolution.
            ResourceLimitError: a grid too large for memory (estimated before allocating).
        """
        if not (is_real(resolution) and math.isfinite(resolution) and resolution > 0):
            raise GridError(f"resolution must be positive, got {resolution!r}")
        if not (
            isinstance(size, Sequence | np.ndarray)
            and len(size) == 2
            and all(is_real(s) and math.isfinite(s) and s > 0 for s in size)
        ):
            raise GridError(f"size must be two positive lengths, got {size!r}")
        nx = int(round(size[0] / resolution))
        ny = int(round(size[1] / resolution))
        if min(nx, ny) == 0:
            raise GridError(
                f"size {tuple(size)} m holds no whole cell of {resolution} m on one axis: "
                "a map needs at least one cell each way"
            )
        # the grid, its cell centres and heights (from_rectangles): 1 + 16 + 8 bytes a cell
        require_memory(
            25.0 * nx * ny,
            f"a {nx} x {ny} occupancy grid for size {tuple(size)} m at {resolution} m",
        )
        return cls(np.zeros((nx, ny), bool), resolution, origin)

    @classmethod
    def from_rectangles(
        cls,
        size: Sequence[float],
        rectangles: Sequence[RectObstacle],
        resolution: float = 0.025,
        origin: Sequence[float] = (0.0, 0.0),
        with_heights: bool = False,
    ) -> "OccupancyGrid":
        """Rasterise rectangles: a cell is occupied if it overlaps one with positive area.

        Args:
            size: ``(width_x, width_y)`` (m).
            rectangles: the obstacles.
            resolution: cell side (m).
            origin: corner of cell (0, 0).
            with_heights: also fill a heights array from the obstacles' heights.
        """
        grid = cls.empty(size, resolution, origin)
        heights = np.zeros(grid.shape) if with_heights else None
        centers = grid.cell_centers()
        for rect in rectangles:
            grid._paint(rect, centers, heights)
        grid.heights = heights
        return grid

    def _paint(
        self,
        rect: RectObstacle,
        centers: np.ndarray,
        heights: np.ndarray | None,
        to: Sequence[float] | None = None,
    ) -> None:
        """Mark the cells ``rect`` overlaps, or with ``to`` those it sweeps moving there.

        Only the cells within the rectangle's axis-aligned extent (and the sweep's) are
        tested: a long thin obstacle (a string across the floor) tests a band of rows, not
        the square of its circumradius.
        """
        hl, hw = rect.size[0] / 2.0, rect.size[1] / 2.0
        c, s = abs(math.cos(rect.yaw)), abs(math.sin(rect.yaw))
        r = self.resolution
        ext_x, ext_y = hl * c + hw * s + r, hl * s + hw * c + r
        x0, y0 = self.origin
        end = rect.center if to is None else to
        xs, ys = (rect.center[0], end[0]), (rect.center[1], end[1])
        i0 = max(0, int(math.floor((min(xs) - ext_x - x0) / r)))
        i1 = min(self.shape[0], int(math.ceil((max(xs) + ext_x - x0) / r)) + 1)
        j0 = max(0, int(math.floor((min(ys) - ext_y - y0) / r)))
        j1 = min(self.shape[1], int(math.ceil((max(ys) + ext_y - y0) / r)) + 1)
        if i0 >= i1 or j0 >= j1:
            return
        sub = centers[i0:i1, j0:j1].reshape(-1, 2)
        if to is None:
            hit = rect_overlaps_cells(rect.center, (hl, hw), rect.yaw, sub, r / 2.0)
        else:
            hit = swept_rect_overlaps_cells(rect.center, end, (hl, hw), rect.yaw, sub, r / 2.0)
        hit = hit.reshape(i1 - i0, j1 - j0)
        self.occupied[i0:i1, j0:j1] |= hit
        if heights is not None:
            block = heights[i0:i1, j0:j1]
            block[hit] = np.maximum(block[hit], rect.height)


def _obstacle_list(name: str, obs: object, kind: type) -> list:
    """``obs`` as a list of ``kind`` (a generator read once), or a GridError naming it."""
    if isinstance(obs, str) or not hasattr(obs, "__iter__"):
        raise GridError(f"{name} must be a list of {kind.__name__}, got {obs!r}")
    obs = list(obs)  # type: ignore[call-overload]
    for k, ob in enumerate(obs):
        if not isinstance(ob, kind):
            raise GridError(f"{name}[{k}] must be a {kind.__name__}, got {type(ob).__name__}")
    return obs


@dataclasses.dataclass
class DynamicEnvironment:
    """Time-indexed grids: ``E(t)`` is the grid whose time is nearest to ``t``.

    Attributes:
        times: increasing grid times (s).
        grids: one grid per time, all with the same shape, resolution and origin.
        max_time_gap: a request further than this from every grid time is an error (s).
    """

    times: np.ndarray
    grids: list[OccupancyGrid]
    max_time_gap: float

    def __post_init__(self) -> None:
        try:
            times = np.asarray(self.times, dtype=float)
        except (TypeError, ValueError):
            raise GridError(f"grid times must be numbers (s), got {self.times!r}") from None
        if times.ndim != 1:
            raise GridError(f"grid times must be a 1-D sequence, got shape {times.shape}")
        self.times = times
        if len(self.times) == 0:
            raise GridError("a dynamic environment needs at least one grid time")
        if not isinstance(self.grids, Sequence):
            raise GridError(f"grids must be a list of OccupancyGrid, got {type(self.grids)}")
        if len(self.grids) != len(self.times):
            raise GridError(f"{len(self.times)} times but {len(self.grids)} grids")
        if not np.all(np.isfinite(self.times)):
            k = int(np.argmin(np.isfinite(self.times)))
            raise GridError(f"grid times must be finite, got {self.times[k]} at index {k}")
        if np.any(np.diff(self.times) <= 0):
            k = int(np.argmax(np.diff(self.times) <= 0))
            raise GridError(
                f"grid times must be strictly increasing, got {self.times[k]} then "
                f"{self.times[k + 1]} at indices {k}, {k + 1}"
            )
        if not (
            is_real(self.max_time_gap)
            and math.isfinite(self.max_time_gap)
            and self.max_time_gap >= 0
        ):
            raise GridError(f"max_time_gap must be a number >= 0 (s), got {self.max_time_gap!r}")
        for k, g in enumerate(self.grids):
            if not isinstance(g, OccupancyGrid):
                raise GridError(f"grid {k} must be an OccupancyGrid, got {type(g).__name__}")
        g0 = self.grids[0]
        for k, g in enumerate(self.grids):
            if (g.heights is None) != (g0.heights is None):
                raise GridError(
                    f"grid {k} {'has no' if g.heights is None else 'has'} heights but grid 0 "
                    f"{'has' if g.heights is None else 'has none'}: either every grid of a "
                    "dynamic environment carries heights or none does"
                )
            if not g0.same_geometry(g):
                raise GridError(
                    f"grid {k} has shape {g.shape}, resolution {g.resolution}, origin {g.origin}; "
                    f"grid 0 has {g0.shape}, {g0.resolution}, {g0.origin}: all grids of a dynamic "
                    "environment must share shape, resolution and origin"
                )
        self._stack: np.ndarray | None = None

    @property
    def resolution(self) -> float:
        return self.grids[0].resolution

    @property
    def reference(self) -> OccupancyGrid:
        return self.grids[0]

    @property
    def stack(self) -> np.ndarray:
        """(K, nx, ny) occupancy of every grid."""
        if self._stack is None:
            self._stack = np.stack([g.occupied for g in self.grids])
        return self._stack

    def covers(self, t: float) -> bool:
        """Whether a grid lies within ``max_time_gap`` of ``t``.

        Args:
            t: time (s).
        """
        k = self.nearest_index_unchecked(t)
        return abs(self.times[k] - t) <= self.max_time_gap + 1e-9

    def nearest_index_unchecked(self, t: float) -> int:
        k = int(np.searchsorted(self.times, t))
        if k == 0:
            return 0
        if k >= len(self.times):
            return len(self.times) - 1
        return k if self.times[k] - t < t - self.times[k - 1] else k - 1

    def index_at(self, t: float) -> int:
        """Index of the grid nearest ``t``; :class:`GridError` if none is near.

        Args:
            t: time (s).
        """
        if not (is_real(t) and math.isfinite(t)):
            raise GridError(f"time must be a finite number (s), got {t!r}")
        k = self.nearest_index_unchecked(t)
        if abs(self.times[k] - t) > self.max_time_gap + 1e-9:
            raise GridError(
                f"no grid near t = {t:.3f} s: grids cover [{self.times[0]:.3f}, "
                f"{self.times[-1]:.3f}] s with max_time_gap {self.max_time_gap:.3f} s"
            )
        return k

    def at(self, t: float) -> OccupancyGrid:
        """E(t): the grid nearest ``t``.

        Args:
            t: time (s).
        """
        return self.grids[self.index_at(t)]

    @classmethod
    def from_moving_obstacles(
        cls,
        size: Sequence[float],
        *,
        moving: Sequence[MovingRectObstacle],
        static: Sequence[RectObstacle] = (),
        t_end: float,
        dt: float = 0.1,
        resolution: float = 0.025,
        origin: Sequence[float] = (0.0, 0.0),
        with_heights: bool = False,
    ) -> "DynamicEnvironment":
        """Grids every ``dt`` seconds over ``[0, t_end]`` of obstacles on known trajectories.

        The grid of time ``t`` stands for every time within ``max_time_gap = dt / 2`` of it,
        so it marks every cell a moving obstacle overlaps at any time of
        ``[t - dt/2, t + dt/2]``: the region the rectangle sweeps (the convex hull of its
        placements at the interval's ends, per segment of a waypoint trajectory). An
        obstacle that crosses a cell between two grid times is in one of the grids, however
        fast it moves; a slow one grows by ``|v| dt / 2`` along its motion on either side.

        Args:
            size: ``(width_x, width_y)`` (m).
            moving: obstacles moving at constant velocity or along waypoints.
            static: obstacles that stay.
            t_end: last grid time (s).
            dt: spacing of the grid times (s); also ``2 max_time_gap``.
            resolution: cell side (m).
            origin: corner of cell (0, 0).
            with_heights: every grid also carries its obstacles' heights (a 2.5-D E(t)).
        """
        if not (is_real(dt) and math.isfinite(dt) and dt > 0):
            raise GridError(f"dt must be a positive number of seconds, got {dt!r}")
        if not (is_real(t_end) and math.isfinite(t_end) and t_end >= 0):
            raise GridError(f"t_end must be a number of seconds >= 0, got {t_end!r}")
        moving = _obstacle_list("moving", moving, MovingRectObstacle)  # used once per grid
        static = _obstacle_list("static", static, RectObstacle)
        base = OccupancyGrid.from_rectangles(
            size, static, resolution, origin, with_heights=with_heights
        )
        centers = base.cell_centers()
        nx, ny = base.shape
        per_grid = nx * ny * (9.0 if with_heights else 1.0)
        count = math.floor(t_end / dt + 0.5) + 1  # the times below, counted before making them
        require_memory(per_grid * count, f"about {count} grids of {nx} x {ny} cells (dt {dt} s)")
        times = np.arange(0.0, t_end + 0.5 * dt, dt)
        grids = []
        half = dt / 2.0
        for t in times:
            heights = base.heights.copy() if with_heights else None
            g = OccupancyGrid(base.occupied.copy(), resolution, origin)
            for m in moving:  # every place it takes over [t - dt/2, t + dt/2]
                path = m.path_between(float(t) - half, float(t) + half)
                for p, q in itertools.pairwise(path):
                    rect = RectObstacle(p, list(m.size), m.yaw, m.height)
                    g._paint(rect, centers, heights, to=q)
            g.heights = heights
            grids.append(g)
        return cls(times, grids, max_time_gap=dt / 2.0)
