"""The comparison baseline: a 2-D mobile-robot planner with the robot's bounding circle.

The grid is inflated by the bounding-circle radius (a cell is blocked when a disc of that
radius centred on its centre overlaps an occupied cell's square or leaves the map) and an
8-connected
Dijkstra finds the shortest path between cell centres. Such a robot must go around every
obstacle, including the flat ones a biped steps over.
"""

import dataclasses
import math
import time

import numpy as np
from repertoire.planning.footstep.environment import OccupancyGrid
from repertoire.planning.footstep.heuristic import grid_graph
from repertoire.planning.footstep.types import FootstepError, PlanStatus
from scipy import signal
from scipy.sparse.csgraph import dijkstra

from repertoire.checks import is_real


@dataclasses.dataclass
class Mobile2DPlan:
    """Result of the 2-D planner.

    Attributes:
        status: SUCCESS or UNREACHABLE.
        path: list of ``[x, y]`` cell centres from start to goal (empty if unreachable).
        length: path length (m), inf if unreachable.
        planning_time_s: wall time (s).
        reason: why it failed ("" on success).
    """

    status: PlanStatus
    path: list[list[float]]
    length: float
    planning_time_s: float
    reason: str = ""


def inflate(grid: OccupancyGrid, radius: float) -> np.ndarray:
    """Cells a disc of ``radius`` centred there would overlap an obstacle or leave the map.

    Exact on the cell centres: the distance from a centre to the square of the cell
    ``(di, dj)`` cells away is ``r * hypot(max(|di| - 1/2, 0), max(|dj| - 1/2, 0))``; the
    disc overlaps that square when the distance is below ``radius`` (an occupied cell itself
    is always blocked). Outside the map counts as occupied.

    Args:
        grid: the grid.
        radius: bounding-circle radius (m).

    Returns:
        (nx, ny) bool, True where the robot's centre may not be.
    """
    if not (math.isfinite(radius) and radius >= 0):
        raise FootstepError(f"radius must be >= 0, got {radius}")
    r = grid.resolution
    m = int(math.ceil(radius / r + 0.5))  # squares farther than m cells are out of reach
    gap = np.maximum(np.abs(np.arange(-m, m + 1)) - 0.5, 0.0) * r
    kernel = gap[:, None] ** 2 + gap[None, :] ** 2 < radius * radius
    kernel[m, m] = True
    occ = np.pad(grid.occupied, m, constant_values=True)
    hits = signal.fftconvolve(occ.astype(float), kernel.astype(float), mode="valid")
    return hits > 0.5  # counts of occupied squares in reach (integers up to rounding)


def plan_mobile2d(
    grid: OccupancyGrid,
    start: "tuple[float, float]",
    goal: "tuple[float, float]",
    radius: float,
) -> Mobile2DPlan:
    """Shortest 8-connected path of the robot's centre on the inflated grid.

    Args:
        grid: the grid.
        start: start ``(x, y)`` (m), inside the map.
        goal: goal ``(x, y)`` (m), inside the map.
        radius: bounding-circle radius (m).
    """
    t0 = time.perf_counter()
    if not isinstance(grid, OccupancyGrid):
        raise FootstepError(f"grid must be an OccupancyGrid, got {type(grid).__name__}")
    if not is_real(radius):
        raise FootstepError(f"radius must be a number >= 0 (m), got {radius!r}")
    for name, p in (("start", start), ("goal", goal)):
        try:
            xy = np.asarray(p, dtype=float)
        except (TypeError, ValueError):
            xy = None
        if xy is None or xy.ndim != 1 or len(xy) < 2:
            raise FootstepError(f"{name} must be (x, y) numbers, got {p!r}")
        if not all(math.isfinite(v) for v in xy[:2]) or not grid.contains(xy[0], xy[1]):
            raise FootstepError(f"{name} {tuple(p[:2])} lies outside the map of size {grid.size}")
    blocked = inflate(grid, radius)
    s = grid.cell_of(*start[:2])
    g = grid.cell_of(*goal[:2])

    def fail(reason: str) -> Mobile2DPlan:
        return Mobile2DPlan(PlanStatus.UNREACHABLE, [], math.inf, time.perf_counter() - t0, reason)

    if blocked[s]:
        return fail("start is within the bounding radius of an obstacle")
    if blocked[g]:
        return fail("goal is within the bounding radius of an obstacle")
    cost = np.where(blocked, np.inf, 1.0)
    graph = grid_graph(cost, grid.resolution)
    ny = grid.shape[1]
    si, gi = s[0] * ny + s[1], g[0] * ny + g[1]
    dist, pred = dijkstra(graph, directed=True, indices=si, return_predecessors=True)
    if not np.isfinite(dist[gi]):
        return fail("no collision-free path for the bounding circle")
    cells = [gi]
    while cells[-1] != si:
        cells.append(int(pred[cells[-1]]))
    cells.reverse()
    r = grid.resolution
    x0, y0 = grid.origin
    path = [[x0 + (c // ny + 0.5) * r, y0 + (c % ny + 0.5) * r] for c in cells]
    return Mobile2DPlan(PlanStatus.SUCCESS, path, float(dist[gi]), time.perf_counter() - t0)
