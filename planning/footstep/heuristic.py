"""Expected cost-to-go: a backward 2-D Dijkstra over the grid, or Euclidean distance.

The Dijkstra estimate is the paper's "standard mobile robot planner run backwards from
the goal": 8-connected moves between cell centres, each move costing its length times
the mean traversal cost of the two cells (1 on free cells, ``obstacle_cost`` on occupied
ones, which the biped may still step over). It is informed but not admissible.
"""

import functools
import math

import numpy as np
from repertoire.planning.footstep.environment import OccupancyGrid
from scipy import ndimage
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

_NEIGHBOURS = ((1, 0), (0, 1), (1, 1), (1, -1))


@functools.lru_cache(maxsize=8)
def _grid_structure(nx: int, ny: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Both directions of every 8-connected edge, sorted by source: (src, dst, length, indptr)."""
    idx = np.arange(nx * ny).reshape(nx, ny)
    src, dst, length = [], [], []
    for di, dj in _NEIGHBOURS:
        i0, i1 = max(0, -di), nx - max(0, di)
        j0, j1 = max(0, -dj), ny - max(0, dj)
        a = idx[i0:i1, j0:j1].ravel()
        b = idx[i0 + di : i1 + di, j0 + dj : j1 + dj].ravel()
        d = np.full(a.shape, math.hypot(di, dj))
        src += [a, b]
        dst += [b, a]
        length += [d, d]
    s, t, L = np.concatenate(src), np.concatenate(dst), np.concatenate(length)
    order = np.argsort(s, kind="stable")
    s, t, L = s[order], t[order], L[order]
    indptr = np.concatenate([[0], np.cumsum(np.bincount(s, minlength=nx * ny))])
    return s, t, L, indptr


def grid_graph(cell_cost: np.ndarray, resolution: float) -> csr_matrix:
    """8-connected graph over the cells; an edge costs its length times the mean cell cost.

    Args:
        cell_cost: (nx, ny) traversal cost per metre of each cell (inf = no passage).
        resolution: cell side (m).

    Returns:
        a sparse (nx ny) x (nx ny) matrix with both directions of every finite edge (use
        ``directed=True``).
    """
    nx, ny = cell_cost.shape
    s, t, L, indptr = _grid_structure(nx, ny)
    flat = np.asarray(cell_cost, dtype=float).ravel()
    w = 0.5 * (flat[s] + flat[t]) * (L * resolution)
    ok = np.isfinite(w)
    if ok.all():
        return csr_matrix((w, t, indptr), shape=(nx * ny, nx * ny))
    ptr = np.concatenate([[0], np.cumsum(np.bincount(s[ok], minlength=nx * ny))])
    return csr_matrix((w[ok], t[ok], ptr), shape=(nx * ny, nx * ny))


def dijkstra_cost_to_go(
    grid: OccupancyGrid,
    goal: "tuple[float, float]",
    goal_tolerance: float,
    *,
    obstacle_cost: float = 3.0,
    impassable_depth: float = math.inf,
    deep_cost: float = 30.0,
) -> np.ndarray:
    """Backward Dijkstra distance (m, weighted) from every cell to the goal region.

    Args:
        grid: the grid.
        goal: goal ``(x, y)``.
        goal_tolerance: cells whose centre lies within this radius of the goal are sources.
        obstacle_cost: traversal cost per metre of an occupied cell (free cells cost 1).
        impassable_depth: occupied cells farther than this from every free cell lie inside
            an obstacle too thick to step over (m); they cost ``deep_cost`` per metre.
        deep_cost: traversal cost per metre of those cells; finite, so that every cell
            keeps an ordered estimate and the best partial plan of an unreachable goal
            still ends as close to it as the robot can get.

    Returns:
        (nx, ny) array of distances, inf where the goal cannot be reached.
    """
    cost = np.where(grid.occupied, obstacle_cost, 1.0)
    if math.isfinite(impassable_depth) and grid.occupied.any():
        depth = ndimage.distance_transform_edt(grid.occupied) * grid.resolution
        cost[depth > impassable_depth] = deep_cost
    centers = grid.cell_centers()
    d_goal = np.hypot(centers[..., 0] - goal[0], centers[..., 1] - goal[1])
    sources = np.flatnonzero(d_goal <= max(goal_tolerance, grid.resolution * 0.75))
    if len(sources) == 0:
        sources = np.array([int(np.argmin(d_goal))])
    g = grid_graph(cost, grid.resolution)
    dist = dijkstra(g, directed=True, indices=sources, min_only=True)
    return np.asarray(dist).reshape(grid.shape)
