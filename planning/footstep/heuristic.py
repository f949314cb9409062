"""Expected cost-to-go: a backward 2-D Dijkstra over the grid, or Euclidean distance.

The Dijkstra estimate is the paper's "standard mobile robot planner run backwards from
the goal": 8-connected moves between cell centres, each move costing its length times
the mean traversal cost of the two cells (1 on free cells, ``obstacle_cost`` on occupied
ones, which the biped may still step over). It is informed but not admissible. The
search runs compiled (:func:`grid_dijkstra`, numba); :func:`grid_graph` gives the same
graph to scipy's ``dijkstra`` for reference. The planner reads it through
:class:`LazyCostToGo`, which settles only the cells it is asked about (the same values),
or, on maps up to a size, every cell at once with a bucket queue (again the same values).
"""

import functools
import math

import numpy as np
from repertoire.planning.footstep.environment import OccupancyGrid
from repertoire.planning.footstep.footprint import distance_to_features
from repertoire.planning.footstep.jitcache import njit
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
    cost = _cell_costs(grid, obstacle_cost, impassable_depth, deep_cost)
    return grid_dijkstra(cost, grid.resolution, _goal_cells(grid, goal, goal_tolerance))


def _cell_costs(
    grid: OccupancyGrid, obstacle_cost: float, impassable_depth: float, deep_cost: float
) -> np.ndarray:
    """Traversal cost per metre of every cell (see :func:`dijkstra_cost_to_go`)."""
    cost = np.where(grid.occupied, obstacle_cost, 1.0)
    if math.isfinite(impassable_depth) and grid.occupied.any():
        depth = distance_to_features(~grid.occupied) * grid.resolution
        cost[depth > impassable_depth] = deep_cost
    return cost


def _goal_cells(grid: OccupancyGrid, goal: "tuple[float, float]", tol: float) -> np.ndarray:
    """Flat indices of the cells whose centre lies within the goal radius (the sources)."""
    nx, ny = grid.shape
    res, (x0, y0) = grid.resolution, grid.origin
    radius = max(tol, res * 0.75)
    i0 = min(max(int(math.floor((goal[0] - radius - x0) / res)) - 1, 0), nx)
    i1 = min(max(int(math.floor((goal[0] + radius - x0) / res)) + 2, 0), nx)
    j0 = min(max(int(math.floor((goal[1] - radius - y0) / res)) - 1, 0), ny)
    j1 = min(max(int(math.floor((goal[1] + radius - y0) / res)) + 2, 0), ny)
    near = _near_cells(i0, i1, j0, j1, ny, x0, y0, res, goal[0], goal[1], radius)
    if near.size:
        return near
    centers = grid.cell_centers()
    d_goal = np.hypot(centers[..., 0] - goal[0], centers[..., 1] - goal[1])
    return np.array([int(np.argmin(d_goal))])


@njit()
def _near_cells(i0, i1, j0, j1, ny, x0, y0, res, gx, gy, radius):
    """Flat indices of the cells of the box whose centre (as ``cell_centers``) is near."""
    out = np.empty((i1 - i0) * max(j1 - j0, 0), np.int64)
    k = 0
    for i in range(i0, i1):
        cx = x0 + (i + 0.5) * res
        for j in range(j0, j1):
            if math.hypot(cx - gx, y0 + (j + 0.5) * res - gy) <= radius:
                out[k] = i * ny + j
                k += 1
    return out[:k]


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


@njit()
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


@njit()
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


class LazyCostToGo:
    """:func:`dijkstra_cost_to_go`, computed only where it is asked for.

    Reverse resumable A* (Silver, "Cooperative pathfinding", 2005): the backward search from
    the goal region is an A* towards the ``toward`` point (the planner's start) with the
    octile distance times the cheapest cell cost, shrunk by 1e-6 so that it stays consistent
    beyond rounding; a query for a cell not yet closed resumes the search until that cell is
    closed. A closed cell's value is final and equal, bit for bit, to the full Dijkstra's
    (both are the minimum over paths of the left-to-right floating-point sums of the same
    edge weights), so a planner reading it expands the same states; only the cells whose
    values it needs (and the A* ellipse around them) are ever settled. Cell costs, the
    deep-obstacle test included, are also computed on demand (the exact distance-transform
    test, by scanning the cells within ``impassable_depth``).

    A map of at most ``eager_cells`` cells is settled whole at construction instead
    (:func:`_eager_field`, a bucket-queue Dijkstra at a few tens of ns per cell, the same
    values): on the maps measured (3 m study maps, 6 m mazes, 12 m floors) that is cheaper
    than settling on demand, whose heap and retargets cost ~150 ns per settled cell and
    which settles 40 % of a study map; on demand pays off only where a plan needs a small
    part of a very large map.

    Args:
        grid, goal, goal_tolerance, obstacle_cost, impassable_depth, deep_cost: as in
            :func:`dijkstra_cost_to_go`.
        toward: ``(x, y)`` the search heads for (where most queries will be).
        retarget_cells, retarget_ratio: when a query far from the target re-heads the
            backward search (see :func:`_rra_value`).
        eager_cells: settle every cell at construction when the map has at most this
            many cells (0: always on demand).
    """

    def __init__(
        self,
        grid: OccupancyGrid,
        goal: "tuple[float, float]",
        goal_tolerance: float,
        toward: "tuple[float, float]",
        *,
        obstacle_cost: float = 3.0,
        impassable_depth: float = math.inf,
        deep_cost: float = 30.0,
        retarget_cells: int | None = 4,
        retarget_ratio: float = 1.0,
        eager_cells: int = 0,
    ) -> None:
        nx, ny = grid.shape
        n = nx * ny
        res = grid.resolution
        self.occ = np.ascontiguousarray(grid.occupied, dtype=np.uint8).ravel()
        # per cell: distance, cost, heap position (-1 not reached, -2 closed), as floats so
        # one cell's fields share a cache line; the heap rows are (key, cell)
        eager = n <= eager_cells
        self.f = np.empty((n, 3))
        if not eager:  # (an eager field writes them all)
            self.f[:, 0] = np.inf
            self.f[:, 2] = -1.0
        radius = -1  # no deep-obstacle test
        if math.isfinite(impassable_depth) and grid.occupied.any():
            radius = int(impassable_depth / res) + 1
        given = not (0 <= impassable_depth and radius <= 8)
        if given:  # a wide scan per cell would cost more than the distance transform
            self.f[:, 1] = _cell_costs(grid, obstacle_cost, impassable_depth, deep_cost).ravel()
            radius = -1
        elif not eager:  # (an eager field writes them all)
            self.f[:, 1] = np.nan  # computed on demand
        self.i = np.empty((1 if eager else n, 2))  # the heap: (f = distance + octile, cell)
        self.size = np.zeros(2, np.int64)  # heap size, cells closed since the last retarget
        ti = min(max(int((toward[0] - grid.origin[0]) / res), 0), nx - 1)
        tj = min(max(int((toward[1] - grid.origin[1]) / res), 0), ny - 1)
        c_min = min(1.0, obstacle_cost, deep_cost)
        retarget = nx * ny if retarget_cells is None else retarget_cells
        # the cell offsets within impassable_depth, nearest first (the deep-obstacle scan)
        offsets = _scan_offsets(radius, res, impassable_depth) if radius >= 0 else ()
        # nx, ny, res, obstacle_cost, depth, deep_cost, target i, j, heuristic scale,
        # scan radius (-1: none), retarget distance, rebuild ratio, offset count, offsets
        self.p = np.concatenate(
            [
                [nx, ny, res, obstacle_cost, impassable_depth, deep_cost, ti, tj,
                 c_min * res * (1.0 - 1e-6), radius, retarget, retarget_ratio,
                 len(offsets) // 2],
                offsets,
            ]
        ).astype(float)  # fmt: skip
        sources = _goal_cells(grid, goal, goal_tolerance)
        if eager:  # every cell settled now (bucket Dijkstra); the heap stays empty
            work = _eager_work(nx, ny, sources.size)
            _eager_field(sources, self.f, self.occ, self.p, given, *work)
        else:
            _rra_start(sources, self.f, self.i, self.p, self.size)

    def value(self, cell: int) -> float:
        """The cost-to-go (m, weighted) of flat cell index ``cell`` (inf: unreachable)."""
        return _rra_value(cell, self.f, self.i, self.occ, self.p, self.size)

    @property
    def settled(self) -> int:
        """How many cells have been closed so far."""
        return int(np.count_nonzero(self.f[:, 2] == -2.0))


_SHARED: dict[tuple, LazyCostToGo] = {}


def shared_cost_to_go(
    grid: OccupancyGrid,
    goal: "tuple[float, float]",
    goal_tolerance: float,
    toward: "tuple[float, float]",
    *,
    obstacle_cost: float = 3.0,
    impassable_depth: float = math.inf,
    deep_cost: float = 30.0,
    eager_cells: int = 0,
) -> LazyCostToGo:
    """A :class:`LazyCostToGo`, reused while the map content, goal and costs stay the same.

    ``eager_cells`` is passed to a new field (a kept field is returned as it is).

    Its values do not depend on ``toward`` (only the order in which cells settle does), so
    plans on the same map towards the same goal (finer lattices after UNREACHABLE, ARA*
    levels, receding-horizon rounds) share the cells already settled. The last 4 fields
    are kept; the key holds the occupancy bits, so an edited grid gets a fresh field.
    """
    key = (
        np.packbits(grid.occupied).tobytes(),  # with the shape: the content, 8x cheaper to hash
        grid.shape,
        grid.resolution,
        grid.origin,
        (float(goal[0]), float(goal[1])),
        float(goal_tolerance),
        float(obstacle_cost),
        float(impassable_depth),
        float(deep_cost),
    )
    field = _SHARED.get(key)
    if field is None:
        field = LazyCostToGo(
            grid,
            goal,
            goal_tolerance,
            toward,
            obstacle_cost=obstacle_cost,
            impassable_depth=impassable_depth,
            deep_cost=deep_cost,
            eager_cells=eager_cells,
        )
        if len(_SHARED) >= 4:
            _SHARED.pop(next(iter(_SHARED)))
        _SHARED[key] = field
    return field


@functools.lru_cache(maxsize=16)
def _scan_offsets(radius: int, res: float, depth: float) -> tuple[float, ...]:
    """Cell offsets ``(di, dj)`` (flattened) whose centre lies within ``depth``, nearest first."""
    di, dj = np.mgrid[-radius : radius + 1, -radius : radius + 1]
    di, dj = di.ravel(), dj.ravel()
    within = np.sqrt((di * di + dj * dj).astype(float)) * res <= depth
    order = np.argsort((di * di + dj * dj)[within], kind="stable")
    return tuple(np.column_stack([di[within][order], dj[within][order]]).ravel().tolist())


@njit()
def _rra_h(c, p):
    ny = int(p[1])
    dx = abs(c // ny - int(p[6]))
    dy = abs(c % ny - int(p[7]))
    return ((max(dx, dy) - min(dx, dy)) + math.sqrt(2.0) * min(dx, dy)) * p[8]


@njit()
def _rra_cost(c, f, occ, p):
    v = f[c, 1]
    if v != v:  # not computed yet
        if not occ[c]:
            v = 1.0
        else:
            v = p[3]
            radius = int(p[9])
            if radius >= 0:  # deep unless a free cell lies within impassable_depth
                nx, ny = int(p[0]), int(p[1])
                i, j = c // ny, c % ny
                deep = True
                for k in range(int(p[12])):  # nearest first: stops at the first free cell
                    a = i + int(p[13 + 2 * k])
                    b = j + int(p[14 + 2 * k])
                    if 0 <= a < nx and 0 <= b < ny and not occ[a * ny + b]:
                        deep = False
                        break
                if deep:
                    v = p[5]
        f[c, 1] = v
    return v


@njit()
def _rra_sift_up(f, heap, k, key, c):
    while k > 0:
        up = (k - 1) >> 1
        if heap[up, 0] <= key:
            break
        heap[k, 0], heap[k, 1] = heap[up, 0], heap[up, 1]
        f[int(heap[k, 1]), 2] = k
        k = up
    heap[k, 0], heap[k, 1] = key, c
    f[c, 2] = k


@njit()
def _rra_sift_down(f, heap, k, n, key, c):
    while True:
        ch = 2 * k + 1
        if ch >= n:
            break
        if ch + 1 < n and heap[ch + 1, 0] < heap[ch, 0]:
            ch += 1
        if heap[ch, 0] < key:
            heap[k, 0], heap[k, 1] = heap[ch, 0], heap[ch, 1]
            f[int(heap[k, 1]), 2] = k
            k = ch
        else:
            break
    heap[k, 0], heap[k, 1] = key, c
    f[c, 2] = k


@njit()
def _rra_retarget(ti, tj, f, heap, p, n):
    """Head the search for cell (ti, tj): new keys for the open cells, heap rebuilt.

    Closed cells stay final (they were closed under a consistent heuristic), so any target
    gives the same values; the nearest one closes the fewest cells.
    """
    p[6], p[7] = ti, tj
    for k in range(n):
        c = int(heap[k, 1])
        heap[k, 0] = f[c, 0] + _rra_h(c, p)
    for k in range(n // 2 - 1, -1, -1):
        _rra_sift_down(f, heap, k, n, heap[k, 0], int(heap[k, 1]))


@njit()
def _rra_start(sources, f, heap, p, size):
    for s in sources:
        if f[s, 2] == -1.0:
            f[s, 0] = 0.0
            _rra_sift_up(f, heap, size[0], _rra_h(s, p), s)
            size[0] += 1


@njit()
def _rra_value(c, f, heap, occ, p, size):
    """Resume the backward A* until cell ``c`` is closed; its distance (inf: unreachable)."""
    if f[c, 2] == -2.0:
        return f[c, 0]
    nx, ny, res = int(p[0]), int(p[1]), p[2]
    diag = math.sqrt(2.0) * res
    n = size[0]
    ti, tj = c // ny, c % ny
    # retarget when the query is far from the target and the heap rebuild is small or
    # costs no more than the cells closed since the last one (rebuilds stay a fraction of
    # the work on large maps)
    far = max(abs(ti - int(p[6])), abs(tj - int(p[7]))) > int(p[10])
    if n > 0 and far and (n <= 2048 or n <= p[11] * size[1]):
        _rra_retarget(ti, tj, f, heap, p, n)
        size[1] = 0
    ti, tj = int(p[6]), int(p[7])
    scale = p[8]
    sqrt2 = math.sqrt(2.0)
    closed = 0
    while n > 0:
        u = int(heap[0, 1])
        f[u, 2] = -2.0
        n -= 1
        closed += 1
        if n > 0:
            _rra_sift_down(f, heap, 0, n, heap[n, 0], int(heap[n, 1]))
        d = f[u, 0]
        iu, ju = u // ny, u % ny
        cu = f[u, 1]
        if cu != cu:
            cu = _rra_cost(u, f, occ, p)
        for di in range(-1, 2):
            a = iu + di
            if a < 0 or a >= nx:
                continue
            hx = abs(a - ti)
            for dj in range(-1, 2):
                b = ju + dj
                if b < 0 or b >= ny or (di == 0 and dj == 0):
                    continue
                nb = a * ny + b
                where = f[nb, 2]
                if where == -2.0:
                    continue
                cn = f[nb, 1]
                if cn != cn:
                    cn = _rra_cost(nb, f, occ, p)
                step = diag if di != 0 and dj != 0 else res
                nd = d + 0.5 * (cu + cn) * step
                if nd < f[nb, 0]:
                    f[nb, 0] = nd
                    hy = abs(b - tj)
                    key = nd + ((max(hx, hy) - min(hx, hy)) + sqrt2 * min(hx, hy)) * scale
                    if where == -1.0:
                        _rra_sift_up(f, heap, n, key, nb)
                        n += 1
                    else:
                        _rra_sift_up(f, heap, int(where), key, nb)
        if u == c:
            break
    size[0] = n
    size[1] += closed
    return f[c, 0]


@njit()
def _cost_classes(f, occ, p, given, state, run):
    """Every cell's cost class into the padded ``state`` (0 free, 1 obstacle, 2 deep).

    The costs are those of :func:`_rra_cost` (``given``: read from ``f[:, 1]``, which then
    holds :func:`_cell_costs`' values): free 1, occupied ``p[3]``, deep ``p[5]``. The
    deep-obstacle scan (a free cell among the offsets within ``impassable_depth``)
    becomes, per row offset ``di``, one look-up of the distance along row ``i + di`` to
    its nearest free cell: within the depth, the offsets of one row are ``|dj| <= m(di)``.
    Returns which classes occur (a bit per class).
    """
    nx, ny = int(p[0]), int(p[1])
    nyp = ny + 2
    seen = 0
    if given:
        for i in range(nx):
            for j in range(ny):
                v = f[i * ny + j, 1]
                k = 0 if v == 1.0 else (1 if v == p[3] else 2)
                state[(i + 1) * nyp + j + 1] = k
                seen |= 1 << k
        return seen
    radius = int(p[9])
    reach = np.full(max(2 * radius + 1, 0), -1, np.int64)  # m(di), -1: no offset in that row
    for k in range(int(p[12])):
        di, dj = int(p[13 + 2 * k]), abs(int(p[14 + 2 * k]))
        reach[di + radius] = max(reach[di + radius], dj)
    far = nx + ny + 1
    # run (nx * ny): distance along the row to the nearest free cell
    if radius >= 0:
        for i in range(nx):
            last = -far
            for j in range(ny):
                if not occ[i * ny + j]:
                    last = j
                run[i * ny + j] = j - last
            last = 2 * far
            for j in range(ny - 1, -1, -1):
                if not occ[i * ny + j]:
                    last = j
                run[i * ny + j] = min(run[i * ny + j], last - j)
    for i in range(nx):
        for j in range(ny):
            k = 0
            if occ[i * ny + j]:
                k = 1
                if radius >= 0:
                    k = 2
                    for di in range(-radius, radius + 1):
                        a = i + di
                        if (
                            0 <= a < nx
                            and reach[di + radius] >= 0
                            and run[a * ny + j] <= reach[di + radius]
                        ):
                            k = 1
                            break
            state[(i + 1) * nyp + j + 1] = k
            seen |= 1 << k
    return seen


_EAGER_KEEP_BYTES = 128 * 2**20
_EAGER_WORK: list[np.ndarray] = []


def _eager_work(nx: int, ny: int, n_sources: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Work arrays of :func:`_eager_field` for an nx x ny map, kept between fields.

    Memory written before (up to ``_EAGER_KEEP_BYTES``) takes no page faults: fresh
    arrays cost a study map's plan ~0.1-0.2 ms in faults.
    """
    m, n = (nx + 2) * (ny + 2), nx * ny
    need = (m, m, 2 * (8 * n + n_sources + 1) + n)
    work = _EAGER_WORK.pop() if _EAGER_WORK else None
    if work is None or any(a.size < k for a, k in zip(work, need, strict=True)):
        if work is not None:  # grown to cover both maps
            need = tuple(max(a.size, k) for a, k in zip(work, need, strict=True))
        work = (np.empty(need[0]), np.empty(need[1], np.uint8), np.empty(need[2], np.int32))
    if sum(a.nbytes for a in work) <= _EAGER_KEEP_BYTES:
        _EAGER_WORK.append(work)
    return work


@njit()
def _eager_field(sources, f, occ, p, given, fbuf, ubuf, ibuf):
    """Settle every cell at once: the values of :func:`_rra_value`, bit for bit.

    Dijkstra with a bucket queue (Dial's): buckets of width ``0.45 * res * c_lo`` (c_lo the
    cheapest cell cost), less than half of the cheapest edge, so a cell taken from the
    current bucket cannot be improved by any other cell of that bucket (each of them adds
    at least two bucket widths): the cells of a bucket are closed in any order and every
    value is the minimum over paths of the same left-to-right sums as the heap's. A grid
    padded by one closed cell needs no bounds tests. A cell costs one of three values
    (free, obstacle, deep: :func:`_cost_classes`), so the search reads one byte per cell,
    its class with a closed flag, and each edge weight ``0.5 (c_u + c_v) step`` from a
    table (the same products): a small working set. With a zero-cost cell, the heap
    Dijkstra (:func:`_dijkstra8`) gives the values. ``given``: ``f[:, 1]`` holds the costs
    already. Writes distance, cost and closed (-2) into ``f``. ``fbuf``, ``ubuf``,
    ``ibuf``: work arrays of at least :func:`_eager_work`'s sizes (contents ignored).
    """
    nx, ny, res = int(p[0]), int(p[1]), p[2]
    n = nx * ny
    nyp = ny + 2
    m = (nx + 2) * nyp
    n_ent = 8 * n + sources.size + 1
    ent_c, ent_n = ibuf[:n_ent], ibuf[n_ent : 2 * n_ent]
    dist, state = fbuf[:m], ubuf[:m]
    # state: cost class (0 free, 1 obstacle, 2 deep, 3 border) + 4 once closed
    seen = _cost_classes(f, occ, p, given, state, ibuf[2 * n_ent : 2 * n_ent + n])
    val = np.array([1.0, p[3], p[5], np.inf])
    for q in range(m):
        dist[q] = np.inf
    for q in range(nyp):  # the border: closed, never entered
        state[q], state[m - 1 - q] = 7, 7
    for i in range(nx):
        state[(i + 1) * nyp], state[(i + 1) * nyp + ny + 1] = 7, 7
    c_lo, c_hi = np.inf, 0.0
    for k in range(3):
        if seen & (1 << k):
            c_lo = min(c_lo, val[k])
            if val[k] < np.inf:
                c_hi = max(c_hi, val[k])
    if not c_lo > 0.0:
        for c in range(n):
            f[c, 1] = val[state[(c // ny + 1) * nyp + c % ny + 1]]
        full = _dijkstra8(f[:, 1].copy().reshape(nx, ny), res, sources).ravel()
        for c in range(n):
            f[c, 0], f[c, 2] = full[c], -2.0
        return
    inv = 1.0 / (0.45 * res * c_lo)
    diag = math.sqrt(2.0) * res
    nb = int(diag * c_hi * inv) + 3  # buckets in the ring: a push lands < nb ahead
    head = np.full(nb, -1, np.int64)
    offs = (-nyp - 1, -nyp, -nyp + 1, -1, 1, nyp - 1, nyp, nyp + 1)
    steps = (diag, res, diag, res, res, diag, res, diag)
    # edge weight from a cell of class a in direction k to a cell of class b:
    # w[a * 32 + k * 4 + b] = 0.5 (c_a + c_b) step_k
    w = np.empty(4 * 32)
    for a in range(4):
        for k in range(8):
            for b in range(4):
                w[a * 32 + k * 4 + b] = 0.5 * (val[a] + val[b]) * steps[k]
    # entries ent_c, ent_n (cell, next entry): one per improvement, at most 8 per cell plus
    # the sources; a taken entry is chained for reuse, so only the pending ones use memory
    top, spare, pending = 0, -1, 0
    for s in sources:
        q = (s // ny + 1) * nyp + s % ny + 1
        if dist[q] != 0.0:
            dist[q] = 0.0
            ent_c[top], ent_n[top], head[0] = q, head[0], top
            top += 1
            pending += 1
    cur = 0
    while pending > 0:
        slot = cur % nb
        e = head[slot]
        head[slot] = -1
        while e >= 0:
            u, nxt = ent_c[e], ent_n[e]
            ent_n[e], spare = spare, e  # the entry is free again
            e = nxt
            pending -= 1
            su = state[u]
            if su & 4:
                continue
            state[u] = su | 4
            d = dist[u]
            row = su * 32  # su: the class (a cell is taken open, the border never)
            for k in range(8):
                v = u + offs[k]
                sv = state[v]
                if sv & 4:  # closed (or the border): its dist <= nd already
                    continue
                nd = d + w[row + 4 * k + sv]
                if nd < dist[v]:
                    dist[v] = nd
                    b = slot + int(nd * inv) - cur  # 2 to nb - 1 buckets ahead
                    if b >= nb:
                        b -= nb
                    if spare >= 0:
                        x, spare = spare, ent_n[spare]
                    else:
                        x, top = top, top + 1
                    ent_c[x], ent_n[x], head[b] = v, head[b], x
                    pending += 1
        cur += 1
    for i in range(nx):
        for j in range(ny):
            c, q = i * ny + j, (i + 1) * nyp + j + 1
            f[c, 0], f[c, 1], f[c, 2] = dist[q], val[state[q] & 3], -2.0
