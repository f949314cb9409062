"""Compiled (numba) weighted A* for table-driven step models on static grids.

The same search as :func:`repertoire.planning.footstep.search.search` run on the biped
step model (:class:`~repertoire.planning.footstep.biped_model.BipedStepModel`), with
everything in arrays so that numba compiles it:

- the open list is a 4-ary heap of ``(f, h, tie)`` rows of one array (the node, its g
  and a lazy cell kept per tie beside it), ordered exactly as the Python loop's ``heapq``
  tuples (so both pop the same states);
- the Dijkstra cost-to-go is the model's
  :class:`~repertoire.planning.footstep.heuristic.LazyCostToGo` (values equal to the full
  field, settled on demand); a successor whose cell is not settled yet enters the open list
  with a lower bound of its value (the backward search's frontier key, the straight line
  to the goal) and gets its exact value when it reaches the top, then is reinserted with
  its own tie number, so states are expanded in exactly the Python loop's order;
- duplicate detection is an open-addressing hash table from lattice keys (the model's
  :meth:`~repertoire.planning.footstep.biped_model.BipedStepModel.lattice_key`, computed
  here by the same formula) to node indices; nodes are named field arrays;
- successor expansion reads the flattened table T (per history and stance foot);
- footprint checks use the model's precomputed checker: the distance-transform shortcut,
  then an exact separating-axis test of the occupied cells of the pose's outer mask;
  flatness, height cost and step-up/down limits read the exact checker's outer mask over
  the height map;
  swing lines are sampled over the cells taller than the swing clearance.

Dynamic worlds and models that are not table-driven stay on the Python loop. The functions
are compiled with ``cache=True`` (the first call in a fresh environment compiles them, up
to a minute; later processes load them from the cache in about a second): :func:`warm_up`
does that once per process, before any plan's clock starts.
"""

import math
import time

import numba
import numpy as np
from repertoire.planning.footstep.biped_model import BipedState, BipedStepModel
from repertoire.planning.footstep.heuristic import _rra_h, _rra_value
from repertoire.planning.footstep.search import SearchResult
from repertoire.planning.footstep.types import PlanStatus

_STATUS = (PlanStatus.SUCCESS, PlanStatus.UNREACHABLE, PlanStatus.NODE_LIMIT, PlanStatus.TIME_LIMIT)


@numba.njit(cache=True, inline="always")
def _less(f1, h1, t1, f2, h2, t2):
    if f1 != f2:
        return f1 < f2
    if h1 != h2:
        return h1 < h2
    return t1 < t2


@numba.njit(cache=True)
def _heap_push(heap, size, f, h, tie):
    """Insert ``(f, h, tie)`` into a 4-ary heap of ``size`` rows ordered by the triple."""
    i = size
    while i > 0:
        p = (i - 1) >> 2
        if _less(f, h, tie, heap[p, 0], heap[p, 1], heap[p, 2]):
            heap[i, 0], heap[i, 1], heap[i, 2] = heap[p, 0], heap[p, 1], heap[p, 2]
            i = p
        else:
            break
    heap[i, 0], heap[i, 1], heap[i, 2] = f, h, tie


@numba.njit(cache=True)
def _heap_pop(heap, size):
    """Remove the root of a 4-ary heap of ``size`` rows (the caller read it first)."""
    size -= 1
    f, h, tie = heap[size, 0], heap[size, 1], heap[size, 2]
    i = 0
    while True:
        c = 4 * i + 1
        if c >= size:
            break
        best = c
        for c2 in range(c + 1, min(c + 4, size)):
            if _less(
                heap[c2, 0], heap[c2, 1], heap[c2, 2], heap[best, 0], heap[best, 1], heap[best, 2]
            ):
                best = c2
        if _less(heap[best, 0], heap[best, 1], heap[best, 2], f, h, tie):
            heap[i, 0], heap[i, 1], heap[i, 2] = heap[best, 0], heap[best, 1], heap[best, 2]
            i = best
        else:
            break
    heap[i, 0], heap[i, 1], heap[i, 2] = f, h, tie


@numba.njit(cache=True, inline="always")
def _slot(table, key):
    """Row of ``key`` in an open-addressing table of (key, value) rows, or of its empty slot."""
    mask = table.shape[0] - 1
    i = ((key * 0x9E3779B97F4A7C15) >> 17) & mask
    while table[i, 0] != -1 and table[i, 0] != key:
        i = (i + 1) & mask
    return i


@numba.njit(cache=True)
def _rehash(table):
    new = np.full((table.shape[0] * 2, 2), -1, np.int64)
    for i in range(table.shape[0]):
        if table[i, 0] != -1:
            j = _slot(new, table[i, 0])
            new[j, 0] = table[i, 0]
            new[j, 1] = table[i, 1]
    return new


@numba.njit(cache=True)
def _grow_rows(a):
    b = np.empty((a.shape[0] * 2, a.shape[1]), a.dtype)
    b[: a.shape[0]] = a
    return b


@numba.njit(cache=True)
def _grow(a):
    b = np.empty(a.size * 2, a.dtype)
    b[: a.size] = a
    return b


@numba.njit(cache=True)
def _foot_free(x, y, th, grid, chk, occw, free, mbits, mrows):
    """The margin checker's answer: foot at (x, y, th) overlaps no occupied cell.

    As :meth:`~repertoire.planning.footstep.footprint.FootprintChecker.is_free`: the
    surely-free shortcut, then per mask row a 64-bit window of the padded occupancy against
    the row's inner cells (overlapped for sure) and ring cells (exact separating axes).
    """
    ox, oy, inv_res = grid[0], grid[1], grid[2]
    fx = (x - ox) * inv_res
    fy = (y - oy) * inv_res
    ix = int(fx)
    iy = int(fy)
    pad, nyp = int(chk[0]), int(chk[1])
    if free[(ix + pad) * nyp + iy + pad]:
        return True
    sub, nb, yaw_scale, hl, hw, big_r = (
        int(chk[2]),
        int(chk[3]),
        chk[4],
        chk[5],
        chk[6],
        int(chk[7]),
    )
    fx -= ix
    fy -= iy
    qx = int(fx * sub)
    qy = int(fy * sub)
    if qx >= sub:
        qx = sub - 1
    if qy >= sub:
        qy = sub - 1
    m = ((int(th * yaw_scale + nb + 0.5) % nb) * sub + qx) * sub + qy
    col = iy + pad - big_r  # bit of the mask's column offset -R
    q = col >> 6
    sh = np.uint64(col & 63)
    back = np.uint64(64 - (col & 63))
    one = np.uint64(1)
    exact = False
    c = s = ext_x = ext_y = lim_u = lim_v = 0.0
    for r in range(mrows[m, 0], mrows[m, 1]):
        row = ix + pad + r - big_r
        word = occw[row, q] >> sh
        if sh:
            word |= occw[row, q + 1] << back
        if word & mbits[m, r, 0]:  # an inner cell is occupied
            return False
        hit = word & mbits[m, r, 1]
        if hit:
            if not exact:
                exact = True
                c, s = math.cos(th), math.sin(th)
                ext_x = (hl * abs(c) + hw * abs(s)) * inv_res + 0.5
                ext_y = (hl * abs(s) + hw * abs(c)) * inv_res + 0.5
                cell_u = 0.5 * (abs(c) + abs(s))
                lim_u = hl * inv_res + cell_u
                lim_v = hw * inv_res + cell_u
            dx = r - big_r + 0.5 - fx
            for jj in range(2 * big_r + 1):
                if (hit >> np.uint64(jj)) & one:
                    dy = jj - big_r + 0.5 - fy
                    eps = 1e-9
                    if (
                        abs(dx) < ext_x - eps
                        and abs(dy) < ext_y - eps
                        and abs(dx * c + dy * s) < lim_u - eps
                        and abs(-dx * s + dy * c) < lim_v - eps
                    ):
                        return False
    return True


@numba.njit(cache=True)
def _height_bounds(x, y, th, grid, ex, heights, ex_off, ex_ptr):
    """Min and max height over the exact footprint's outer mask (as FootprintChecker)."""
    ox, oy, inv_res = grid[0], grid[1], grid[2]
    pad, nyp, sub, nb, yaw_scale = int(ex[0]), int(ex[1]), int(ex[2]), int(ex[3]), ex[4]
    fx = (x - ox) * inv_res
    fy = (y - oy) * inv_res
    ix = int(math.floor(fx))
    iy = int(math.floor(fy))
    base = (ix + pad) * nyp + iy + pad
    qx = min(int((fx - ix) * sub), sub - 1)
    qy = min(int((fy - iy) * sub), sub - 1)
    m = ((int(th * yaw_scale + nb + 0.5) % nb) * sub + qx) * sub + qy
    lo, hi = np.inf, -np.inf
    for k in range(ex_ptr[m, 0], ex_ptr[m, 2]):
        v = heights[base + ex_off[k]]
        lo = min(lo, v)
        hi = max(hi, v)
    return lo, hi


@numba.njit(cache=True)
def _height_range(x, y, th, grid, ex, heights, ex_off, ex_ptr):
    lo, hi = _height_bounds(x, y, th, grid, ex, heights, ex_off, ex_ptr)
    return hi - lo


@numba.njit(cache=True)
def _swing_crosses(tall, x0, y0, x1, y1, ox, oy, inv):
    n = int(math.hypot(x1 - x0, y1 - y0) * inv * 2.0) + 2
    nx, ny = tall.shape
    for k in range(n + 1):
        u = k / n
        i = int(((x0 + u * (x1 - x0)) - ox) * inv)
        j = int(((y0 + u * (y1 - y0)) - oy) * inv)
        if 0 <= i < nx and 0 <= j < ny and tall[i, j]:
            return True
    return False


@numba.njit(cache=True)
def _now():
    with numba.objmode(t="float64"):
        t = time.perf_counter()
    return t


@numba.njit(cache=True)
def _arastar(
    start,  # x, y, yaw, foot, a2, a1, t, swing_x, swing_y, h
    succ_ptr,
    succ_a,
    succ_f,  # rows: dx, dy, dyaw, duration, cost
    hist,
    lat,  # ox, oy, inv_q, ky, nyaw, yaw_scale, n_hist
    grid,  # ox, oy, inv_res, nx, ny, gx, gy, tol, cost_per_m, flat_limit, height_w, up, down
    hf,  # the LazyCostToGo's arrays (f, i, occ, p, size), or empty for Euclidean
    hi,
    hocc,
    hp,
    hcount,
    chk,  # pad, nyp, sub, yaw_bins, yaw_scale, hl, hw
    occw,
    free,
    mbits,
    mrows,
    ex,  # exact checker: pad, nyp, sub, yaw_bins, yaw_scale
    heights,
    ex_off,
    ex_ptr,
    tall,
    use_tall,
    weights,
    max_expansions,
    time_limit,
):
    """ARA* over the biped lattice, step for step as ``search.anytime_search``.

    One weight is plain weighted A* (``search.search``). Returns per search: status code,
    end node, cost, bound, expansions, seconds, generated, merged; then the node arrays.
    """
    t0 = _now()
    n = hist.shape[0]
    ox, oy, inv_q, ky, nyaw, yaw_scale, n_hist = (
        lat[0],
        lat[1],
        lat[2],
        int(lat[3]),
        int(lat[4]),
        lat[5],
        int(lat[6]),
    )
    inv_res, nx, ny = grid[2], int(grid[3]), int(grid[4])
    gx, gy, tol, cost_per_m, flat_limit, height_w = (
        grid[5],
        grid[6],
        grid[7],
        grid[8],
        grid[9],
        grid[10],
    )
    step_up, step_down = grid[11], grid[12]
    step_limits = step_up < np.inf or step_down < np.inf
    use_cells = hp.size > 0
    res = 1.0 / inv_res
    h_radius = max(tol, res * 0.75) + 1e-9
    h_cmin = hp[8] / res if use_cells else 0.0  # cheapest cost per metre, shrunk by 1e-6
    tol2 = tol * tol
    two_pi = 2.0 * math.pi
    cap = 1024
    fnode = np.empty((cap, 8))  # x, y, yaw, t, swing_x, swing_y, h, g
    # foot, a_prev2, a_prev1, parent, expanded in, open, incons, lazy cell (-1: h exact)
    inode = np.zeros((cap, 8), np.int32)
    table = np.full((4096, 2), -1, np.int64)
    heap = np.empty((1024, 3))  # open list rows (f, h, tie)
    ent = np.empty((1024, 3))  # per tie: node, g at the push, lazy cell (-1: h exact)

    sx, sy, sth = start[0], start[1], start[2]
    f0, a20, a10 = int(start[3]), int(start[4]), int(start[5])
    key0 = (int((sx - ox) * inv_q + 0.5) * ky + int((sy - oy) * inv_q + 0.5)) * nyaw + int(
        sth * yaw_scale + nyaw + 0.5
    ) % nyaw
    key0 = (key0 * 2 + f0) * n_hist + hist[a20, a10]
    for q, v in enumerate((sx, sy, sth, start[6], start[7], start[8], start[9], 0.0)):
        fnode[0, q] = v
    for q, v in enumerate((f0, a20, a10, -1, -1, 1, 0)):
        inode[0, q] = v
    inode[0, 7] = -1
    count = 1
    j = _slot(table, key0)
    table[j, 0] = key0
    table[j, 1] = 0
    used = 1
    best, best_h = 0, start[9]
    expansions = generated = merged = 0
    nw = weights.size
    out_i = np.zeros((nw, 5), np.int64)  # status, end, expansions, generated, merged
    out_f = np.zeros((nw, 3))  # cost, bound, seconds
    solution = -1
    runs = 0
    for it in range(nw):
        w = weights[it]
        t_it = _now()
        hsize = 0
        for k in range(count):
            if inode[k, 5] or inode[k, 6]:
                if hsize == heap.shape[0]:
                    heap = _grow_rows(heap)
                if hsize == ent.shape[0]:
                    ent = _grow_rows(ent)
                ent[hsize, 0], ent[hsize, 1], ent[hsize, 2] = k, fnode[k, 7], inode[k, 7]
                _heap_push(heap, hsize, fnode[k, 7] + w * fnode[k, 6], fnode[k, 6], hsize)
                hsize += 1
                inode[k, 5], inode[k, 6] = 1, 0
        tie = hsize
        status, end, exp_it = 1, -1, 0  # UNREACHABLE
        while hsize > 0:
            h = heap[0, 1]
            tp = heap[0, 2]
            e = int(tp)
            node = int(ent[e, 0])
            lazy = int(ent[e, 2])
            if lazy >= 0 and inode[node, 4] != it:  # a lower bound: the exact key, same tie
                h = _rra_value(lazy, hf, hi, hocc, hp, hcount) * cost_per_m
                gp = ent[e, 1]
                _heap_pop(heap, hsize)
                if inode[node, 7] == lazy:
                    fnode[node, 6], inode[node, 7] = h, -1
                if h < np.inf:
                    ent[e, 2] = -1
                    _heap_push(heap, hsize - 1, gp + w * h, h, tp)
                else:
                    hsize -= 1
                continue
            _heap_pop(heap, hsize)
            hsize -= 1
            if inode[node, 4] == it:
                continue
            if inode[node, 7] >= 0:  # the node moved since this entry: its own h, exact
                fnode[node, 6] = _rra_value(inode[node, 7], hf, hi, hocc, hp, hcount) * cost_per_m
                inode[node, 7] = -1
            x, y, th, foot = fnode[node, 0], fnode[node, 1], fnode[node, 2], inode[node, 0]
            if (x - gx) * (x - gx) + (y - gy) * (y - gy) <= tol2:
                status, end = 0, node
                break
            if expansions >= max_expansions:
                status = 2
                break
            if expansions and (expansions & 1023) == 0 and _now() - t0 > time_limit:
                status = 3
                break
            inode[node, 5], inode[node, 4] = 0, it
            expansions += 1
            exp_it += 1
            g = fnode[node, 7]
            if h < best_h or (h == best_h and g < fnode[best, 7]):
                best, best_h = node, h
            a2, a1 = inode[node, 1], inode[node, 2]
            c, s = math.cos(th), math.sin(th)
            nf = 1 - foot
            row = (a2 * n + a1) * 2 + foot
            z1 = 0.0
            if step_limits:
                z1 = _height_bounds(x, y, th, grid, ex, heights, ex_off, ex_ptr)[1]
            for r in range(succ_ptr[row], succ_ptr[row + 1]):
                dx, dy = succ_f[r, 0], succ_f[r, 1]
                x2 = x + c * dx - s * dy
                y2 = y + s * dx + c * dy
                th2 = (th + succ_f[r, 2] + math.pi) % two_pi - math.pi
                fx = (x2 - ox) * inv_res
                fy = (y2 - oy) * inv_res
                if not (0.0 <= fx < nx and 0.0 <= fy < ny):
                    continue
                if not _foot_free(x2, y2, th2, grid, chk, occw, free, mbits, mrows):
                    continue
                if flat_limit < np.inf and (
                    _height_range(x2, y2, th2, grid, ex, heights, ex_off, ex_ptr) > flat_limit
                ):
                    continue
                if step_limits:
                    dz = _height_bounds(x2, y2, th2, grid, ex, heights, ex_off, ex_ptr)[1] - z1
                    if dz > step_up or -dz > step_down:
                        continue
                if use_tall and _swing_crosses(
                    tall, fnode[node, 4], fnode[node, 5], x2, y2, ox, oy, inv_res
                ):
                    continue
                lazy = -1
                if use_cells:
                    cell = int(fx) * ny + int(fy)
                    if hf[cell, 2] == -2.0 or hcount[0] == 0:  # settled (or unreachable)
                        h2 = _rra_value(cell, hf, hi, hocc, hp, hcount) * cost_per_m
                    else:  # a lower bound now, the exact value when popped
                        f_min = hi[0, 0]
                        lb = f_min - _rra_h(cell, hp) - 1e-9 * (1.0 + abs(f_min))
                        # every path to the goal region is at least as long as the straight line
                        cx = ox + ((cell // ny) + 0.5) * res
                        cy = oy + ((cell % ny) + 0.5) * res
                        lb2 = (math.hypot(cx - gx, cy - gy) - h_radius) * h_cmin
                        h2 = max(lb, lb2, 0.0) * cost_per_m
                        lazy = cell
                else:
                    h2 = max(0.0, math.hypot(x2 - gx, y2 - gy) - tol) * cost_per_m
                if h2 == np.inf:
                    continue
                cost = succ_f[r, 4]
                if height_w > 0.0:
                    cost += height_w * _height_range(x2, y2, th2, grid, ex, heights, ex_off, ex_ptr)
                generated += 1
                a = succ_a[r]
                g2 = g + cost
                k2 = (
                    int((x2 - ox) * inv_q + 0.5) * ky + int((y2 - oy) * inv_q + 0.5)
                ) * nyaw + int(th2 * yaw_scale + nyaw + 0.5) % nyaw
                k2 = (k2 * 2 + nf) * n_hist + hist[a1, a]
                j = _slot(table, k2)
                idx = -1
                closed_now = False
                if table[j, 0] == k2:
                    idx = table[j, 1]
                    closed_now = inode[idx, 4] == it or inode[idx, 6] == 1
                    if closed_now or g2 >= fnode[idx, 7]:
                        merged += 1
                    if g2 >= fnode[idx, 7]:
                        continue
                    if inode[idx, 4] >= 0:  # has children: a new node keeps them consistent
                        idx = -1
                if idx < 0:
                    if count == fnode.shape[0]:
                        fnode, inode = _grow_rows(fnode), _grow_rows(inode)
                    idx = count
                    count += 1
                    inode[idx, 4] = -1
                    inode[idx, 5] = 0 if closed_now else 1
                    inode[idx, 6] = 1 if closed_now else 0
                    if table[j, 0] != k2:
                        table[j, 0] = k2
                        used += 1
                    table[j, 1] = idx
                    if 2 * used > table.shape[0]:
                        table = _rehash(table)
                fnode[idx, 0], fnode[idx, 1], fnode[idx, 2], fnode[idx, 3] = (
                    x2,
                    y2,
                    th2,
                    fnode[node, 3] + succ_f[r, 3],
                )
                fnode[idx, 4], fnode[idx, 5], fnode[idx, 6], fnode[idx, 7] = x, y, h2, g2
                inode[idx, 0], inode[idx, 1], inode[idx, 2], inode[idx, 3] = nf, a1, a, node
                inode[idx, 7] = lazy
                if inode[idx, 6] == 0:
                    if hsize == heap.shape[0]:
                        heap = _grow_rows(heap)
                    if tie == ent.shape[0]:
                        ent = _grow_rows(ent)
                    ent[tie, 0], ent[tie, 1], ent[tie, 2] = idx, g2, lazy
                    _heap_push(heap, hsize, g2 + w * h2, h2, tie)
                    hsize += 1
                    tie += 1
        bound = w
        if status == 0:
            solution = end
            low = np.inf
            for k in range(count):  # a lower bound above ``low`` needs no exact value
                if (inode[k, 5] or inode[k, 6]) and fnode[k, 7] + fnode[k, 6] < low:
                    if inode[k, 7] >= 0:
                        fnode[k, 6] = _rra_value(inode[k, 7], hf, hi, hocc, hp, hcount) * cost_per_m
                        inode[k, 7] = -1
                    if fnode[k, 7] + fnode[k, 6] < low:
                        low = fnode[k, 7] + fnode[k, 6]
            if low == np.inf:
                low = fnode[end, 7]
            bound = min(w, fnode[end, 7] / low) if low > 0 else w
        last = end if end >= 0 else (solution if solution >= 0 else best)
        out_i[it, 0], out_i[it, 1], out_i[it, 2] = status, last, exp_it
        out_i[it, 3], out_i[it, 4] = generated, merged
        out_f[it, 0], out_f[it, 1], out_f[it, 2] = fnode[last, 7], bound, _now() - t_it
        runs += 1
        if status != 0:
            break
    nodes = np.empty((count, 10))  # x, y, yaw, t, swing_x, swing_y, h, foot, a2, a1
    parents = inode[:count, 3]
    for it in range(runs):  # only the nodes on the paths are filled
        k = out_i[it, 1]
        while k >= 0:
            nodes[k, 0], nodes[k, 1], nodes[k, 2], nodes[k, 3] = (
                fnode[k, 0],
                fnode[k, 1],
                fnode[k, 2],
                fnode[k, 3],
            )
            nodes[k, 4], nodes[k, 5], nodes[k, 6] = fnode[k, 4], fnode[k, 5], fnode[k, 6]
            nodes[k, 7], nodes[k, 8], nodes[k, 9] = inode[k, 0], inode[k, 1], inode[k, 2]
            k = inode[k, 3]
    return out_i[:runs], out_f[:runs], nodes, parents


def _mask_arrays(masks, nyp: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Outer masks, inner cells first then ring cells.

    Returns offsets ``di * nyp + dj``, ``di``, ``dj`` and per mask ``(start, ring start, end)``.
    """
    di_parts, dj_parts, ptr = [], [], np.zeros((len(masks.outer), 3), np.int64)
    at = 0
    for m, ((ia, ib), (ra, rb)) in enumerate(zip(masks.inner, masks.ring, strict=True)):
        di_parts += [np.asarray(ia, np.int64), np.asarray(ra, np.int64)]
        dj_parts += [np.asarray(ib, np.int64), np.asarray(rb, np.int64)]
        ptr[m] = (at, at + len(ia), at + len(ia) + len(ra))
        at = int(ptr[m, 2])
    di_all = np.concatenate(di_parts) if di_parts else np.zeros(0, np.int64)
    dj_all = np.concatenate(dj_parts) if dj_parts else np.zeros(0, np.int64)
    return di_all * nyp + dj_all, di_all, dj_all, ptr


def _occupancy_words(chk) -> np.ndarray:
    """The padded occupancy, bit j of row i at bit ``j % 64`` of word ``j // 64``.

    One spare word per row lets a 64-bit window start at any bit.
    """
    nxp, nyp = chk._occ.shape
    packed = np.packbits(chk._occ, axis=1, bitorder="little")
    words = np.zeros((nxp, (nyp + 63) // 64 + 1), np.uint64)
    words.view(np.uint8)[:, : packed.shape[1]] = packed
    return words


_BITS_CACHE: dict[int, tuple] = {}


def _cached_mask_bits(masks) -> tuple[np.ndarray, np.ndarray]:
    """Per mask and row ``di + R``: the inner and ring cells as bits ``dj + R``; row ranges."""
    hit = _BITS_CACHE.get(id(masks))
    if hit is not None and hit[0] is masks:
        return hit[1], hit[2]
    big_r = masks.radius_cells
    if 2 * big_r + 1 > 64:
        raise ValueError(f"footprint masks {2 * big_r + 1} cells wide exceed a 64-bit window")
    n = len(masks.inner)
    bits = np.zeros((n, 2 * big_r + 1, 2), np.uint64)
    rows = np.zeros((n, 2), np.int64)
    for m in range(n):
        for k, part in ((0, masks.inner[m]), (1, masks.ring[m])):
            di, dj = part
            np.bitwise_or.at(
                bits[m, :, k],
                np.asarray(di, np.int64) + big_r,
                np.left_shift(np.uint64(1), (np.asarray(dj, np.int64) + big_r).astype(np.uint64)),
            )
        used = np.flatnonzero(bits[m].any(axis=1))
        rows[m] = (used[0], used[-1] + 1) if used.size else (0, 0)
    if len(_BITS_CACHE) > 16:
        _BITS_CACHE.clear()
    _BITS_CACHE[id(masks)] = (masks, bits, rows)
    return bits, rows


def _masks_key(chk) -> tuple:
    return (id(chk.masks), chk.nyp)


_MASK_CACHE: dict[tuple, tuple] = {}


def _cached_masks(chk) -> tuple:
    key = _masks_key(chk)
    arrays = _MASK_CACHE.get(key)
    if arrays is None:
        if len(_MASK_CACHE) > 16:
            _MASK_CACHE.clear()
        arrays = _MASK_CACHE[key] = (chk.masks, *_mask_arrays(chk.masks, chk.nyp))
    return arrays[1:]


def _lazy_arrays(lazy) -> dict:
    if lazy is None:
        return {"hf": np.zeros((0, 3)), "hi": np.zeros((0, 2)), "hocc": np.zeros(0, np.uint8),
                "hp": np.zeros(0), "hcount": np.zeros(1, np.int64)}  # fmt: skip
    return {"hf": lazy.f, "hi": lazy.i, "hocc": lazy.occ, "hp": lazy.p, "hcount": lazy.size}


def compiled_tables(model: BipedStepModel) -> dict:
    """The model's search space as the arrays :func:`_astar` reads (static grids only)."""
    if model.dynamic:
        raise ValueError("the compiled core plans on static grids only")
    chk, exact, ref = model.chk0, model.exact, model.ref
    ox, oy = model.origin
    nx, ny = ref.shape
    gx, gy = model.goal
    mbits, mrows = _cached_mask_bits(chk.masks)
    ex_off, _, _, ex_ptr = _cached_masks(exact)
    mk, emk = chk.masks, exact.masks
    heights = exact.heights_flat if exact.heights_flat is not None else np.zeros(1)
    tall = model.tall if model.tall is not None else np.zeros((1, 1), bool)
    return {
        "succ_ptr": model.succ_ptr,
        "succ_a": model.succ_a,
        "succ_f": np.ascontiguousarray(model.succ_f),
        "hist": np.asarray(model.hist, np.int64),
        "lat": np.array(
            [ox, oy, model.inv_q, model.ky, model.nyaw, model.yaw_scale, model.n_hist], float
        ),
        "grid": np.array(
            [
                ox,
                oy,
                model.inv_res,
                nx,
                ny,
                gx,
                gy,
                model.tol,
                model.cost_per_m,
                model.flat_limit,
                model.height_w,
                model.step_up,
                model.step_down,
            ],
            float,
        ),
        **_lazy_arrays(model.h_lazy),
        "chk": np.array(
            [
                chk.pad,
                chk.nyp,
                mk.sub,
                mk.yaw_bins,
                mk.yaw_scale,
                mk.half[0],
                mk.half[1],
                mk.radius_cells,
            ],
            float,
        ),
        "occw": _occupancy_words(chk),
        "free": np.frombuffer(chk.free_bytes, np.uint8),
        "mbits": mbits,
        "mrows": mrows,
        "ex": np.array([exact.pad, exact.nyp, emk.sub, emk.yaw_bins, emk.yaw_scale], float),
        "heights": np.asarray(heights, float),
        "ex_off": ex_off,
        "ex_ptr": ex_ptr,
        "tall": np.ascontiguousarray(tall, bool),
        "use_tall": model.tall is not None,
    }


def compiled_search(
    model: BipedStepModel, weight: float, max_expansions: int, time_limit: float
) -> SearchResult:
    """Weighted A* on the compiled core; the same result as ``search.search(model, ...)``.

    Args:
        model: a biped step model on a static grid.
        weight: heuristic inflation (>= 1 for the bound; any >= 0 runs).
        max_expansions: expansion budget (NODE_LIMIT when exhausted).
        time_limit: wall-time budget in s (TIME_LIMIT when exhausted).
    """
    return compiled_anytime(model, [weight], max_expansions, time_limit)[0]


def compiled_anytime(
    model: BipedStepModel, weights, max_expansions: int, time_limit: float
) -> list[SearchResult]:
    """ARA* on the compiled core; the same results as ``search.anytime_search(model, ...)``.

    Args:
        model: a biped step model on a static grid.
        weights: non-increasing heuristic weights.
        max_expansions: expansion budget over all searches.
        time_limit: wall-time budget in s over all searches.
    """
    t0 = time.perf_counter()
    tab = compiled_tables(model)
    s0 = model.start()
    start = np.array(
        [s0.x, s0.y, s0.yaw, s0.foot, s0.a_prev2, s0.a_prev1, s0.t, s0.swing_x, s0.swing_y, s0.h]
    )
    left = time_limit - (time.perf_counter() - t0)
    ws = np.asarray(weights, dtype=float)
    out_i, out_f, nodes, parents = _arastar(
        start, *tab.values(), ws, int(max_expansions), float(max(left, 1e-9))
    )

    def state(k: int) -> BipedState:
        x, y, yaw, t, sx, sy, h, f, a2, a1 = nodes[k].tolist()
        return BipedState(x, y, yaw, int(f), int(a2), int(a1), t, sx, sy, h)

    results = []
    for (status, last, exp, gen, mer), (cost, bound, secs), w in zip(
        out_i.tolist(), out_f.tolist(), ws.tolist(), strict=False
    ):
        chain = []
        k = last
        while k >= 0:
            chain.append(k)
            k = int(parents[k])
        path = [state(k) for k in reversed(chain)]
        results.append(
            SearchResult(
                status=_STATUS[status],
                path=path,
                cost=cost,
                weight=w,
                expansions=exp,
                seconds=secs,
                generated=gen,
                merged=mer,
                cost_to_go=path[-1].h,
                bound=bound,
            )
        )
    return results


_WARM = False


def warm_up() -> None:
    """Compile (or load from numba's cache) every compiled function once per process.

    :func:`repertoire.planning.footstep.plan_footsteps` calls it before starting its clock,
    so the one-time compilation (tens of seconds cold, about a second from the cache) never
    eats a plan's time limit.
    """
    global _WARM
    if _WARM:
        return
    _WARM = True
    from repertoire.planning.footstep.actions import nominal_action_table
    from repertoire.planning.footstep.environment import OccupancyGrid
    from repertoire.planning.footstep.planner import PlannerOptions

    occ = np.zeros((24, 24), dtype=bool)
    occ[12, :6] = True
    heights = 0.01 * occ
    grid = OccupancyGrid(occ, 0.025, (0.0, 0.0), heights)
    opts = PlannerOptions(
        max_expansions=3, max_height_range=1.0, max_step_up=1.0, swing_clearance=0.5,
        height_cost_weight=0.1, backend="compiled",
    )  # fmt: skip
    model = BipedStepModel(
        grid, (0.15, 0.35, 0.0), "left", (0.45, 0.45), nominal_action_table(), opts
    )
    compiled_anytime(model, [2.0, 1.0], 3, 60.0)
