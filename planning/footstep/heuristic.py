"""Expected cost-to-go: a backward 2-D Dijkstra over the grid, or Euclidean distance.

The Dijkstra estimate is the paper's "standard mobile robot planner run backwards from
the goal": 8-connected moves between cell centres, each move costing its length times
the mean traversal cost of the two cells (1 on free cells, ``obstacle_cost`` on occupied
ones, which the biped may still step over). It is informed but not admissible. The
search runs compiled (:func:`grid_dijkstra`, numba); :func:`grid_graph` gives the same
graph to scipy's ``dijkstra`` for reference.
"""

import functools
import math

import numba
import numpy as np
from repertoire.planning.footstep.environment import OccupancyGrid
from repertoire.planning.footstep.footprint import distance_to_features
from scipy.sparse import csr_matrix

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
        depth = distance_to_features(~grid.occupied) * grid.resolution
        cost[depth > impassable_depth] = deep_cost
    centers = grid.cell_centers()
    d_goal = np.hypot(centers[..., 0] - goal[0], centers[..., 1] - goal[1])
    sources = np.flatnonzero(d_goal <= max(goal_tolerance, grid.resolution * 0.75))
    if len(sources) == 0:
        sources = np.array([int(np.argmin(d_goal))])
    return grid_dijkstra(cost, grid.resolution, sources)


def grid_dijkstra(cell_cost: np.ndarray, resolution: float, sources: np.ndarray) -> np.ndarray:
    """Multi-source Dijkstra over :func:`grid_graph`'s graph, compiled.

    Args:
        cell_cost: (nx, ny) traversal cost per metre of each cell (inf = no passage).
        resolution: cell side (m).
        sources: flat indices of the source cells (distance 0).

    Returns:
        (nx, ny) distances (inf where no source is reachable).
    """
    cost = np.ascontiguousarray(cell_cost, dtype=float)
    src = np.asarray(sources, dtype=np.int64).ravel()
    return _dijkstra8(cost, float(resolution), src)


@numba.njit(cache=True)
def _sift_up(hd, hc, pos, k, d, c):
    while k > 0:
        p = (k - 1) >> 1
        if hd[p] <= d:
            break
        hd[k], hc[k] = hd[p], hc[p]
        pos[hc[k]] = k
        k = p
    hd[k], hc[k] = d, c
    pos[c] = k


@numba.njit(cache=True)
def _dijkstra8(cost, res, sources):
    """Indexed binary heap with decrease-key: each cell enters the heap at most once."""
    nx, ny = cost.shape
    flat = cost.ravel()
    dist = np.full(nx * ny, np.inf)
    pos = np.full(nx * ny, -1, np.int64)  # heap position; -2 once settled
    hd = np.empty(nx * ny)
    hc = np.empty(nx * ny, np.int64)
    size = 0
    for s in sources:
        if pos[s] == -1:
            dist[s] = 0.0
            _sift_up(hd, hc, pos, size, 0.0, s)
            size += 1
    diag = math.sqrt(2.0) * res
    while size > 0:
        d, c = hd[0], hc[0]
        pos[c] = -2
        size -= 1
        if size > 0:
            ld, lc = hd[size], hc[size]
            k = 0
            while True:
                ch = 2 * k + 1
                if ch >= size:
                    break
                if ch + 1 < size and hd[ch + 1] < hd[ch]:
                    ch += 1
                if hd[ch] < ld:
                    hd[k], hc[k] = hd[ch], hc[ch]
                    pos[hc[k]] = k
                    k = ch
                else:
                    break
            hd[k], hc[k] = ld, lc
            pos[lc] = k
        i, j = c // ny, c % ny
        ci = flat[c]
        for di in range(-1, 2):
            a = i + di
            if a < 0 or a >= nx:
                continue
            for dj in range(-1, 2):
                b = j + dj
                if b < 0 or b >= ny or (di == 0 and dj == 0):
                    continue
                nb = a * ny + b
                if pos[nb] == -2:
                    continue
                step = diag if di != 0 and dj != 0 else res
                nd = d + 0.5 * (ci + flat[nb]) * step
                if nd < dist[nb]:
                    dist[nb] = nd
                    if pos[nb] == -1:
                        _sift_up(hd, hc, pos, size, nd, nb)
                        size += 1
                    else:
                        _sift_up(hd, hc, pos, pos[nb], nd, nb)
    return dist.reshape(nx, ny)
