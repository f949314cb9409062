"""Compiled (numba) weighted A* for table-driven step models on static grids.

The same search as :func:`repertoire.planning.footstep.search.search` run on the biped
step model (:class:`~repertoire.planning.footstep.biped_model.BipedStepModel`), with
everything in arrays so that numba compiles it:

- the open list is a 4-ary heap of ``(f, h, tie, node)`` rows ordered by ``(f, h, tie)``
  exactly as the Python loop's ``heapq`` tuples (so both pop the same states), each node's
  four children on two whole cache lines (``fastkernels._heap_rows``); a row whose h is a
  lower bound carries ``-1 - node`` and keeps its g and lazy cell per tie beside it;
- that heap is kept small enough for the nearer caches: it holds only the rows whose f is
  below a threshold (the hot heap), and the others wait unordered in a cold array, appended
  as they come. When the hot heap grows past :data:`HOT_ROWS` rows (or twice its size after
  its last refill), the rows at or above a new threshold move to the cold array (about
  :data:`HOT_KEEP` stay); when it runs empty, the cold rows below a higher threshold (about
  a sixteenth of them, at least :data:`HOT_KEEP`) move back and are heapified
  (``fastkernels._spill``, ``_refill``; ``_open_push`` places a new row). Every hot row's f
  is below the threshold and every cold row's at or above it, so the pops come in the same
  order as from one heap; on a 12 m open floor the pops wait less on memory for the heap's
  lower levels (at 291k expansions, +15 % expansions per second on a quiet machine, +24 %
  with its other core loaded; geometric means of 8 alternating runs each);
- the Dijkstra cost-to-go is the model's
  :class:`~repertoire.planning.footstep.heuristic.LazyCostToGo` (values equal to the full
  field, settled on demand); a successor whose cell is not settled yet enters the open list
  with a lower bound of its value (the backward search's frontier key, the straight line
  to the goal) and gets its exact value when it reaches the top, then is reinserted with
  its own tie number, so states are expanded in exactly the Python loop's order;
- duplicate detection is an open-addressing table from lattice keys (the model's
  :meth:`~repertoire.planning.footstep.biped_model.BipedStepModel.lattice_key`, computed
  here by the same formula) to its g (16-byte rows) and its node (a column beside), so
  testing a successor reads one table row and no node's row (the node's search flags are
  read only when a successor improves its g); the keys of one map cell share cache lines,
  and the rows of a state's successors (and their node column) are prefetched before they are read
  (:mod:`~repertoire.planning.footstep.fastkernels`);
- nodes are rows of named fields (40 bytes of floats, 32 of integers), pre-sized from a
  finite expansion budget so that a search neither copies them nor touches rows it does
  not use;
- successor expansion reads the flattened table T (per history and stance foot); room for
  all successors of a state is made before its successor loop, so no array is reassigned
  inside it (numba would count references on every successor);
- a successor whose lattice state is already reached as cheaply is dropped before its
  checks (counted as merged, as :func:`~repertoire.planning.footstep.search.successor_function`
  says): on 12 m floors at 30 % clutter most are, and this saves ~13-15 % of a search;
- footprint checks use the model's precomputed checker: the surely-free shortcut (read
  in the loop), then an exact separating-axis test of the occupied cells of the pose's outer mask;
  flatness and height cost read the exact checker's outer mask over the height map, the
  step-up/down limits the highest ground under each sole (its exact cells:
  ``fastkernels._top_height``);
  swing lines are traversed exactly over the cells taller than the swing clearance.

Dynamic worlds and models that are not table-driven stay on the Python loop. The functions
are compiled with numba's cache, keyed by the contents of every compiled planner source
(:mod:`~repertoire.planning.footstep.jitcache`; the first call in a fresh environment or
after an edit compiles them, up to a minute; later processes load them from the cache in
about a second): :func:`warm_up`
does that once per process, before any plan's clock starts.
"""

import math
import time

import numpy as np
from repertoire.planning.footstep.biped_model import BipedState, BipedStepModel
from repertoire.planning.footstep.fastkernels import (
    _borrowed,
    _cached_mask_bits,
    _cached_masks,
    _cell_height,
    _foot_free,
    _grow_heap,
    _grow_rows,
    _heap_pop,
    _heap_push,
    _heap_rows,
    _height_range,
    _lattice_yaw,
    _now,
    _occupancy_words,
    _open_push,
    _prefetch_row,
    _refill,
    _rehash,
    _slot,
    _spill,
    _top_height,
    _wrap,
    swing_crosses,
)
from repertoire.planning.footstep.heuristic import _rra_h, _rra_value
from repertoire.planning.footstep.jitcache import njit
from repertoire.planning.footstep.reachability import goal_cut_off
from repertoire.planning.footstep.search import SearchResult
from repertoire.planning.footstep.types import PlanStatus

_STATUS = (PlanStatus.SUCCESS, PlanStatus.UNREACHABLE, PlanStatus.NODE_LIMIT, PlanStatus.TIME_LIMIT)

# Node fields. Float rows (40 B): position, yaw, cost-to-go h (exact, or a lower bound while
# the lazy cell is set) and g. A node's swing start is its parent's position and its time the
# parent's time plus the step's duration: both are filled in for the path nodes only.
_X, _Y, _YAW, _H, _G = 0, 1, 2, 3, 4
# Integer rows (32 B): parent, the search it was expanded in (-1: none), lazy cell (-1: h
# exact), row in the lattice table (-1: none), stance foot, the two previous actions, and
# _OPEN or _INCONS (0: neither).
_PARENT, _EXPANDED, _LAZY, _ROW, _FOOT, _A2, _A1, _LIST = 0, 1, 2, 3, 4, 5, 6, 7
_OPEN, _INCONS = 1, 2
# Work arrays pre-sized from a finite expansion budget hold at most this many node rows
# (np.empty: only the rows written are ever faulted in; larger searches grow them).
_PRESIZE_ROWS = 2**21
HOT_ROWS = 1 << 13
"""The open list's hot heap is split when it holds more rows than this (see the module)."""
HOT_KEEP = 1 << 11
"""About this many rows stay in the hot heap when it is split."""


@njit(nogil=True)  # other threads run while it searches (the clock takes the GIL briefly)
def _arastar(
    start,  # x, y, yaw, foot, a2, a1, t, swing_x, swing_y, h
    succ_ptr,
    succ_a,
    succ_f,  # rows: dx, dy, dyaw, duration, cost
    hist,
    lat,  # ox, oy, inv_q, ky, nyaw, yaw_scale, n_hist, yaw_shift
    grid,  # ox, oy, inv_res, nx, ny, gx, gy, tol, cost_per_m, flat_limit, height_w, up, down,
    # swing clearance, ground level (NaN: uneven)
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
    ex,  # exact checker: pad, nyp, sub, yaw_bins, yaw_scale, hl, hw, R
    heights,
    ex_off,
    ex_ptr,
    tall,
    use_tall,
    weights,
    max_expansions,
    time_limit,
    hot_rows,
    hot_keep,
    fnode,  # work arrays of any rows, contents ignored (grown as needed, returned)
    inode,
    heap,
    ent,
    tb0,
    tb1,
    tn0,
    tn1,
    cold,
):
    """ARA* over the biped lattice, step for step as ``search.anytime_search``.

    One weight is plain weighted A* (``search.search``); a weight not below the last plan's
    bound is skipped. Returns per search that ran: status code, end node, expansions,
    generated, merged; cost, bound, seconds, weight; the path nodes; then
    the work arrays (the caller may pass them to the next search: no fresh memory).
    """
    t0 = _now()
    n = hist.shape[0]
    ox, oy, inv_q, ky, nyaw, yaw_scale, n_hist, yaw_shift = (
        lat[0],
        lat[1],
        lat[2],
        int(lat[3]),
        int(lat[4]),
        lat[5],
        int(lat[6]),
        lat[7],
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
    step_up, step_down, clearance, z_flat = grid[11], grid[12], grid[13], grid[14]
    step_limits = step_up < np.inf or step_down < np.inf
    # the ground under a sole: its highest cell, or one level for all (NaN: no such level)
    need_z = step_limits or (use_tall and np.isnan(z_flat))
    z_level = 0.0 if np.isnan(z_flat) else z_flat
    use_cells = hp.size > 0
    pad, nyp = int(chk[0]), int(chk[1])
    res = 1.0 / inv_res
    h_radius = max(tol, res * 0.75) + 1e-9
    h_cmin = hp[8] / res if use_cells else 0.0  # cheapest cost per metre, shrunk by 1e-6
    tol2 = tol * tol
    # the margin check's arrays without reference counts (see fastkernels._borrowed)
    bgrid, bchk, boccw = _borrowed(grid), _borrowed(chk), _borrowed(occw)
    bfree, bmbits, bmrows = _borrowed(free), _borrowed(mbits), _borrowed(mrows)
    # Lattice table rows: key, g (float bits); the successor test reads only this row (no
    # node row of another state unless it improves that state's g). The rows live in the
    # first rows of tb0, their nodes in tn0 (tb1, tn1: the spares a rehash fills).
    # Open list rows (f, h, tie, node), node -1 - node when h is a lower bound (lazy);
    # ent: per tie of a lazy row, g at the push and the lazy cell.
    if tb0.shape[0] < 4096 or tn0.shape[0] < tb0.shape[0]:
        tb0, tn0 = np.empty((4096, 2), np.int64), np.empty(4096, np.int32)
    table, tnode = tb0[:4096], tn0[:4096]
    table[:] = -1
    tg = table.view(np.float64)
    n_local = nyaw * 2 * n_hist  # keys per map cell: key = cell * n_local + local
    most = np.max(succ_ptr[1:] - succ_ptr[:-1])  # successors of one state, at most
    sp = np.empty((most, 3))  # one state's successors: pose; lattice key and table row
    sk = np.empty((most, 2), np.int64)
    if max_expansions < 2**62:  # a finite budget: room for every node it can create, capped
        rows = _PRESIZE_ROWS
        if max_expansions < _PRESIZE_ROWS:
            rows = min(1 + max_expansions * most, rows)
        if fnode.shape[0] < rows:
            fnode, inode = np.empty((rows, 5)), np.empty((rows, 8), np.int32)
        if heap.shape[0] < rows + 3:  # + 3: the rows _heap_rows may skip
            heap = np.empty((rows + 3, 4))
        if use_cells and ent.shape[0] < rows:
            ent = np.empty((rows, 2))

    sx, sy, sth = start[0], start[1], start[2]
    f0, a20, a10 = int(start[3]), int(start[4]), int(start[5])
    cell0 = int((sx - ox) * inv_q + 0.5) * ky + int((sy - oy) * inv_q + 0.5)
    local0 = (_lattice_yaw(sth, yaw_scale, yaw_shift, nyaw) * 2 + f0) * n_hist + hist[a20, a10]
    key0 = cell0 * n_local + local0
    fnode[0, _X], fnode[0, _Y], fnode[0, _YAW], fnode[0, _H], fnode[0, _G] = (
        sx,
        sy,
        sth,
        start[9],
        0.0,
    )
    inode[0, _PARENT], inode[0, _EXPANDED], inode[0, _LAZY], inode[0, _LIST] = -1, -1, -1, _OPEN
    inode[0, _FOOT], inode[0, _A2], inode[0, _A1] = f0, a20, a10
    count = 1
    j = _slot(table, key0, cell0, local0)
    table[j, 0], tnode[j] = key0, 0
    tg[j, 1] = 0.0
    inode[0, _ROW] = j
    used = 1
    best, best_h = 0, start[9]
    expansions = generated = merged = 0
    nw = weights.size
    out_i = np.zeros((nw, 5), np.int64)  # status, end, expansions, generated, merged
    out_f = np.zeros((nw, 4))  # cost, bound, seconds, weight
    solution = -1
    runs = 0
    # each run's path, start first, copied when the run ends (a later weight may give a node
    # on it a cheaper parent and the pose reached from it: an earlier plan must not change):
    # x, y, yaw, t, swing_x, swing_y, h, foot, a2, a1; only the path nodes' t and swing are
    # ever computed
    paths = np.empty((256, 10))
    pptr = np.zeros(nw + 1, np.int64)
    met = np.inf  # the bound the last plan reported: weights not below it are skipped
    for it in range(nw):
        w = weights[it]
        if w >= met:
            continue
        t_it = _now()
        hsize = 0
        while count > _heap_rows(heap).shape[0]:  # room for every node (no array is reassigned
            heap = _grow_rows(heap)  # inside a loop: numba would count references on each pass)
        hv = _heap_rows(heap)  # the open list's rows (child groups on whole cache lines)
        while use_cells and count > ent.shape[0]:
            ent = _grow_rows(ent)
        for k in range(count):
            if inode[k, _LIST]:
                code = k
                if inode[k, _LAZY] >= 0:
                    ent[hsize, 0], ent[hsize, 1], code = fnode[k, _G], inode[k, _LAZY], -1 - k
                _heap_push(hv, hsize, fnode[k, _G] + w * fnode[k, _H], fnode[k, _H], hsize, code)
                hsize += 1
                inode[k, _LIST] = _OPEN
        tie = hsize
        csize, thr, spill_at = 0, np.inf, hot_rows
        status, end, exp_it = 1, -1, 0  # UNREACHABLE
        while True:  # make room, then search until done or a node needs more room
            while count + most > fnode.shape[0]:
                fnode, inode = _grow_rows(fnode), _grow_rows(inode)
            while hsize + csize + most > hv.shape[0]:
                heap = _grow_heap(heap, hv, hsize)
                hv = _heap_rows(heap)
            while hsize + csize + most > cold.shape[0]:
                cold = _grow_rows(cold)
            while use_cells and tie + most > ent.shape[0]:
                ent = _grow_rows(ent)
            while 2 * (used + most) > table.shape[0]:
                rows = 2 * table.shape[0]
                if tb1.shape[0] < rows or tn1.shape[0] < rows:
                    tb1, tn1 = np.empty((rows, 2), np.int64), np.empty(rows, np.int32)
                new, new_node = tb1[:rows], tn1[:rows]
                new[:] = -1
                _rehash(table, tnode, new, new_node, n_local, inode, _ROW)
                tb0, tb1, table, tn0, tn1, tnode = tb1, tb0, new, tn1, tn0, new_node
                tg = table.view(np.float64)
            # The search loop reassigns no array (numba would count references on each
            # pass): it leaves when the next expansion might not fit.
            # the open list's arrays without reference counts (see fastkernels._borrowed),
            # made anew whenever the arrays above were grown
            ohv, ocold = _borrowed(hv), _borrowed(cold)
            room = True
            while hsize > 0 or csize > 0:
                if (
                    count + most > fnode.shape[0]
                    or hsize + csize + most > hv.shape[0]
                    or hsize + csize + most > cold.shape[0]
                    or (use_cells and tie + most > ent.shape[0])
                    or 2 * (used + most) > table.shape[0]
                ):
                    room = False
                    break
                if hsize == 0:
                    hsize, csize, thr = _refill(hv, cold, csize, max(hot_keep, csize >> 4))
                    spill_at = max(hot_rows, 2 * hsize)
                elif hsize > spill_at:
                    hsize, csize, thr = _spill(hv, hsize, cold, csize, hot_keep)
                    spill_at = max(hot_rows, 2 * hsize)
                h = hv[0, 1]
                tp = hv[0, 2]
                code = int(hv[0, 3])
                node = code if code >= 0 else -1 - code
                if (
                    code < 0 and inode[node, _EXPANDED] != it
                ):  # a lower bound: the exact key, same tie
                    e = int(tp)
                    lazy = int(ent[e, 1])
                    h = _rra_value(lazy, hf, hi, hocc, hp, hcount) * cost_per_m
                    gp = ent[e, 0]
                    _heap_pop(hv, hsize)
                    hsize -= 1
                    if inode[node, _LAZY] == lazy:
                        fnode[node, _H], inode[node, _LAZY] = h, -1
                    if h < np.inf:
                        hsize, csize = _open_push(
                            ohv, hsize, ocold, csize, thr, gp + w * h, h, tp, node
                        )
                    continue
                _heap_pop(hv, hsize)
                hsize -= 1
                if hsize > 0:  # the next candidate's node rows load while this one expands
                    nxt = int(hv[0, 3])
                    nxt = nxt if nxt >= 0 else -1 - nxt
                    _prefetch_row(inode, nxt)
                    _prefetch_row(fnode, nxt)
                if inode[node, _EXPANDED] == it:
                    continue
                if inode[node, _LAZY] >= 0:  # the node moved since this entry: its own h, exact
                    fnode[node, _H] = (
                        _rra_value(inode[node, _LAZY], hf, hi, hocc, hp, hcount) * cost_per_m
                    )
                    inode[node, _LAZY] = -1
                x, y, th, foot = (
                    fnode[node, _X],
                    fnode[node, _Y],
                    fnode[node, _YAW],
                    inode[node, _FOOT],
                )
                if (x - gx) * (x - gx) + (y - gy) * (y - gy) <= tol2:
                    status, end = 0, node
                    break
                if expansions >= max_expansions:
                    status = 2
                    break
                if (  # the clock every 64 expansions, every 1024 past the first 4096
                    expansions
                    and (expansions & (1023 if expansions >= 4096 else 63)) == 0
                    and _now() - t0 > time_limit
                ):
                    status = 3
                    break
                inode[node, _LIST], inode[node, _EXPANDED] = 0, it
                expansions += 1
                exp_it += 1
                g = fnode[node, _G]
                if h < best_h or (h == best_h and g < fnode[best, _G]):
                    best, best_h = node, h
                a2, a1 = inode[node, _A2], inode[node, _A1]
                c, s = math.cos(th), math.sin(th)
                nf = 1 - foot
                row = (a2 * n + a1) * 2 + foot
                z1 = z_level
                if need_z:
                    z1 = _top_height(x, y, th, grid, ex, heights, ex_off, ex_ptr)
                sw_x, sw_y = start[7], start[8]  # the swing starts where this foot stood before
                if use_tall and inode[node, _PARENT] >= 0:
                    sw_x, sw_y = fnode[inode[node, _PARENT], _X], fnode[inode[node, _PARENT], _Y]
                z1s = z1  # the higher of the stance's and the swing start's ground
                if use_tall and np.isnan(z_flat):
                    z1s = max(z1, _cell_height(sw_x, sw_y, grid, ex, heights))
                r0, r1 = succ_ptr[row], succ_ptr[row + 1]
                mask = table.shape[0] - 1
                for r in range(r0, r1):  # poses and table rows, the rows prefetched
                    dx, dy = succ_f[r, 0], succ_f[r, 1]
                    x2 = x + c * dx - s * dy
                    y2 = y + s * dx + c * dy
                    th2 = _wrap(th + succ_f[r, 2])
                    cell2 = int((x2 - ox) * inv_q + 0.5) * ky + int((y2 - oy) * inv_q + 0.5)
                    local = _lattice_yaw(th2, yaw_scale, yaw_shift, nyaw) * 2 + nf
                    local = local * n_hist + hist[a1, succ_a[r]]
                    j = (((cell2 * 0x9E3779B97F4A7C15) >> 17) + local) & mask
                    _prefetch_row(table, j)
                    _prefetch_row(tnode, j)  # read when the successor improves a state's g
                    q = r - r0
                    sp[q, 0], sp[q, 1], sp[q, 2] = x2, y2, th2
                    sk[q, 0], sk[q, 1] = cell2 * n_local + local, j
                for r in range(r0, r1):
                    q = r - r0
                    x2, y2, th2 = sp[q, 0], sp[q, 1], sp[q, 2]
                    fx = (x2 - ox) * inv_res
                    fy = (y2 - oy) * inv_res
                    if not (0.0 <= fx < nx and 0.0 <= fy < ny):
                        continue
                    # the lattice-table row of this successor (_slot written out here: an
                    # inlined call costs two atomic reference counts); nothing is inserted
                    # before this successor's own insert, so the row found stays valid
                    k2, j = sk[q, 0], sk[q, 1]
                    while table[j, 0] != -1 and table[j, 0] != k2:
                        j = (j + 1) & mask
                    if height_w == 0.0:  # a state already reached as cheaply: no checks
                        if table[j, 0] == k2 and g + succ_f[r, 4] >= tg[j, 1]:
                            merged += 1
                            continue
                    if not free[(int(fx) + pad) * nyp + int(fy) + pad] and not _foot_free(
                        x2, y2, th2, bgrid, bchk, boccw, bfree, bmbits, bmrows
                    ):  # the surely-free shortcut first (inline), then the masks
                        continue
                    if flat_limit < np.inf and (
                        _height_range(x2, y2, th2, grid, ex, heights, ex_off, ex_ptr) > flat_limit
                    ):
                        continue
                    z2 = z_level
                    if need_z:
                        z2 = _top_height(x2, y2, th2, grid, ex, heights, ex_off, ex_ptr)
                    if step_limits:
                        dz = z2 - z1
                        if dz > step_up or -dz > step_down:
                            continue
                    if use_tall and swing_crosses(
                        tall, max(z1s, z2) + clearance, sw_x, sw_y, x2, y2, ox, oy, inv_res
                    ):
                        continue
                    lazy = -1
                    if use_cells:
                        cell = int(fx) * ny + int(fy)
                        if hf[cell, 2] == -2.0:  # settled
                            h2 = hf[cell, 0] * cost_per_m
                        elif hcount[0] == 0:  # the backward search is over: unreachable
                            h2 = _rra_value(cell, hf, hi, hocc, hp, hcount) * cost_per_m
                        else:  # a lower bound now, the exact value when popped
                            f_min = hi[0, 0]
                            lb = f_min - _rra_h(cell, hp) - 1e-9 * (1.0 + abs(f_min))
                            # every path to the goal region is at least as long as the straight line
                            cx = ox + ((cell // ny) + 0.5) * res
                            cy = oy + ((cell % ny) + 0.5) * res
                            lb2 = (math.sqrt((cx - gx) ** 2 + (cy - gy) ** 2) - h_radius) * h_cmin
                            h2 = max(lb, lb2, 0.0) * cost_per_m
                            lazy = cell
                    else:
                        ddx, ddy = x2 - gx, y2 - gy
                        h2 = max(0.0, math.sqrt(ddx * ddx + ddy * ddy) - tol) * cost_per_m
                    if h2 == np.inf:
                        continue
                    cost = succ_f[r, 4]
                    if height_w > 0.0:
                        cost += height_w * _height_range(
                            x2, y2, th2, grid, ex, heights, ex_off, ex_ptr
                        )
                    generated += 1
                    a = succ_a[r]
                    g2 = g + cost
                    idx = -1
                    closed_now = False
                    if table[j, 0] == k2:
                        if g2 >= tg[j, 1]:
                            merged += 1
                            continue
                        idx = tnode[j]
                        closed_now = inode[idx, _EXPANDED] == it or inode[idx, _LIST] == _INCONS
                        if closed_now:
                            merged += 1
                        if inode[idx, _EXPANDED] >= 0:  # has children: a new node keeps them
                            inode[idx, _ROW] = -1  # no longer in the table
                            idx = -1
                    if idx < 0:
                        idx = count
                        count += 1
                        inode[idx, _EXPANDED] = -1
                        inode[idx, _LIST] = _INCONS if closed_now else _OPEN
                        inode[idx, _ROW] = j
                        if table[j, 0] != k2:
                            table[j, 0] = k2
                            used += 1
                        tnode[j] = idx
                    tg[j, 1] = g2
                    fnode[idx, _X], fnode[idx, _Y], fnode[idx, _YAW] = x2, y2, th2
                    fnode[idx, _H], fnode[idx, _G] = h2, g2
                    inode[idx, _FOOT], inode[idx, _A2], inode[idx, _A1] = nf, a1, a
                    inode[idx, _PARENT], inode[idx, _LAZY] = node, lazy
                    if inode[idx, _LIST] == _OPEN:
                        code = idx
                        if lazy >= 0:
                            ent[tie, 0], ent[tie, 1], code = g2, lazy, -1 - idx
                        hsize, csize = _open_push(
                            ohv, hsize, ocold, csize, thr, g2 + w * h2, h2, tie, code
                        )
                        tie += 1
            if room:
                break
        bound = w
        if status == 0:
            solution = end
            low = np.inf
            for k in range(count):  # a lower bound above ``low`` needs no exact value
                if inode[k, _LIST] and fnode[k, _G] + fnode[k, _H] < low:
                    if inode[k, _LAZY] >= 0:
                        fnode[k, _H] = (
                            _rra_value(inode[k, _LAZY], hf, hi, hocc, hp, hcount) * cost_per_m
                        )
                        inode[k, _LAZY] = -1
                    if fnode[k, _G] + fnode[k, _H] < low:
                        low = fnode[k, _G] + fnode[k, _H]
            if low == np.inf:
                low = fnode[end, _G]
            # a plan of cost 0 (the start meets the goal) is optimal: bound 1
            if low > 0:
                bound = min(w, fnode[end, _G] / low)
            elif fnode[end, _G] == 0.0:
                bound = 1.0
            met = bound
        last = end if end >= 0 else (solution if solution >= 0 else best)
        out_i[runs, 0], out_i[runs, 1], out_i[runs, 2] = status, last, exp_it
        out_i[runs, 3], out_i[runs, 4] = generated, merged
        out_f[runs, 0], out_f[runs, 1], out_f[runs, 2] = fnode[last, _G], bound, _now() - t_it
        out_f[runs, 3] = w
        m, k = 0, last
        while k >= 0:
            m += 1
            k = inode[k, _PARENT]
        while pptr[runs] + m > paths.shape[0]:
            paths = _grow_rows(paths)
        pptr[runs + 1] = q = pptr[runs] + m
        k = last
        while k >= 0:  # the path's nodes, from the end back
            q -= 1
            paths[q, 0], paths[q, 1], paths[q, 2] = fnode[k, _X], fnode[k, _Y], fnode[k, _YAW]
            paths[q, 6], paths[q, 7] = fnode[k, _H], inode[k, _FOOT]
            paths[q, 8], paths[q, 9] = inode[k, _A2], inode[k, _A1]
            k = inode[k, _PARENT]
        paths[q, 3], paths[q, 4], paths[q, 5] = start[6], start[7], start[8]
        for q in range(pptr[runs] + 1, pptr[runs + 1]):  # the parent's time plus the step's
            a2, a1, foot = int(paths[q - 1, 8]), int(paths[q - 1, 9]), int(paths[q - 1, 7])
            r = succ_ptr[(a2 * n + a1) * 2 + foot]  # duration (T's row for the history)
            while succ_a[r] != int(paths[q, 9]):
                r += 1
            paths[q, 3] = paths[q - 1, 3] + succ_f[r, 3]
            paths[q, 4], paths[q, 5] = paths[q - 1, 0], paths[q - 1, 1]
        runs += 1
        if status != 0:
            break
    work = (fnode, inode, heap, ent, tb0, tb1, tn0, tn1, cold)
    return out_i[:runs], out_f[:runs], paths[: pptr[runs]], pptr[: runs + 1], work


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
    # the core reads heights only for the limits or the height cost (model.uses_heights)
    heights = exact.heights_flat if model.uses_heights else None
    heights = heights if heights is not None else np.zeros(1)
    tall = model.tall if model.tall is not None else np.zeros((1, 1))
    return {
        "succ_ptr": model.succ_ptr,
        "succ_a": model.succ_a,
        "succ_f": np.ascontiguousarray(model.succ_f),
        "hist": np.asarray(model.hist, np.int64),
        "lat": np.array(
            [
                ox,
                oy,
                model.inv_q,
                model.ky,
                model.nyaw,
                model.yaw_scale,
                model.n_hist,
                model.yaw_shift,
            ],
            float,
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
                model.opts.swing_clearance,
                math.nan if model.ground_level is None else model.ground_level,
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
        "ex": np.array(
            [exact.pad, exact.nyp, emk.sub, emk.yaw_bins, emk.yaw_scale]
            + [*emk.half, emk.radius_cells],
            float,
        ),
        "heights": np.asarray(heights, float),
        "ex_off": ex_off,
        "ex_ptr": ex_ptr,
        "tall": np.ascontiguousarray(tall, float),
        "use_tall": model.tall is not None,
    }


# The search's work arrays, kept from one search to the next while under this size: a
# repeated search writes into memory it already has instead of faulting in fresh pages
# (about 35,000 page faults in a 291k-expansion search). A search pops a set (or makes a
# fresh one) and puts it back after, so searches in two threads at once (the anytime
# planner's ``second_search``) each have their own; at most _WORK_SETS sets are kept.
_WORK_KEEP_BYTES = 512 * 2**20
_WORK_SETS = 2
_WORK: list[tuple] = []


def _fresh_work() -> tuple:
    """Small work arrays for :func:`_arastar` (it grows them)."""
    return (
        np.empty((1024, 5)),
        np.empty((1024, 8), np.int32),
        np.empty((1024, 4)),
        np.empty((1024, 2)),
        np.empty((4096, 2), np.int64),
        np.empty((0, 2), np.int64),
        np.empty(4096, np.int32),
        np.empty(0, np.int32),
        np.empty((1024, 4)),
    )


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
    try:  # pop: one search per work set (a test-then-pop could race another thread)
        work = _WORK.pop()
    except IndexError:
        work = _fresh_work()
    out_i, out_f, paths, pptr, work = _arastar(
        start, *tab.values(), ws, int(max_expansions), float(max(left, 1e-9)),
        int(HOT_ROWS), int(HOT_KEEP), *work,
    )  # fmt: skip
    if sum(a.nbytes for a in work) <= _WORK_KEEP_BYTES and len(_WORK) < _WORK_SETS:
        _WORK.append(work)

    def state(row: list) -> BipedState:
        x, y, yaw, t, sx, sy, h, f, a2, a1 = row
        return BipedState(x, y, yaw, int(f), int(a2), int(a1), t, sx, sy, h)

    results = []
    for it, ((status, _, exp, gen, mer), (cost, bound, secs, w)) in enumerate(
        zip(out_i.tolist(), out_f.tolist(), strict=True)
    ):
        path = [state(row) for row in paths[pptr[it] : pptr[it + 1]].tolist()]
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
    eats a plan's time limit: the search core's and the reachability proof's kernels
    (:func:`~repertoire.planning.footstep.reachability.goal_cut_off`, which a plan runs
    inside its limit when a search ends UNREACHABLE).
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
    goal_cut_off(model)  # with step limits: the levels and the fill
