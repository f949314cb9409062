"""Compiled kernels of the footstep search core: open list, lattice table, footprint checks.

The parts of :mod:`repertoire.planning.footstep.fastcore` that are not the search loop:

- the open list, a 4-ary heap of ``(f, h, tie)`` rows ordered exactly as Python's
  ``heapq`` orders those tuples, split by a threshold on f into a hot heap and unordered
  cold rows (``_open_push``, ``_spill``, ``_refill``; the reachability proof's fill uses the
  heap too);
- the lattice table (open addressing, keys grouped per map cell so that the states of one
  cell share cache lines) holding each lattice state's node, g and search flags;
- the footprint checks on the model's precomputed masks (64-bit occupancy words, exact
  separating axes on the ring cells), the height bounds of a sole's outer mask, the
  highest ground under a sole (exact cells) and the swing line (exact grid traversal);
- the arrays the checks read, built once per mask set and map.
"""

import math
import time

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic
from repertoire.planning.footstep.jitcache import njit


@njit(inline="always")
def _less(f1, h1, t1, f2, h2, t2):
    if f1 != f2:
        return f1 < f2
    if h1 != h2:
        return h1 < h2
    return t1 < t2


@njit(inline="always")
def _heap_push(heap, size, f, h, tie, node):
    """Insert the row ``(f, h, tie, node)`` into a 4-ary heap of ``size`` rows.

    Rows are ordered by ``(f, h, tie)`` (``tie`` unique); ``node`` rides along.
    """
    i = size
    while i > 0:
        p = (i - 1) >> 2
        if _less(f, h, tie, heap[p, 0], heap[p, 1], heap[p, 2]):
            for q in range(4):
                heap[i, q] = heap[p, q]
            i = p
        else:
            break
    heap[i, 0], heap[i, 1], heap[i, 2], heap[i, 3] = f, h, tie, node


@njit()
def _heap_rows(heap):
    """The rows of ``heap`` from the one that puts every 4-ary node's children on two lines.

    Rows are 32 bytes and the children of row ``i`` are rows ``4 i + 1 .. 4 i + 4``: with row
    1 on a 128-byte boundary each child group is two whole cache lines (else three).
    """
    return heap[((-(heap.ctypes.data + 32)) % 128) // 32 :]


@njit()
def _grow_heap(heap, rows, size):
    """A heap base twice as large; its first ``size`` rows (of :func:`_heap_rows`) = ``rows``'."""
    new = np.empty((heap.shape[0] * 2, heap.shape[1]), heap.dtype)
    _heap_rows(new)[:size] = rows[:size]
    return new


@njit(inline="always")
def _heap_pop(heap, size):
    """Remove the root of a 4-ary heap of ``size`` rows (the caller read it first)."""
    size -= 1
    for q in range(4):
        heap[0, q] = heap[size, q]
    _sift_down(heap, size, 0, True)


@njit(inline="always")
def _sift_down(heap, size, i, prefetch):
    """Move row ``i`` of a 4-ary heap of ``size`` rows down to its place.

    ``prefetch``: load the grandchildren's rows while a level is compared (a pop from a heap
    too large for the caches; not while heapifying, which walks the rows in order).
    """
    f, h, tie, node = heap[i, 0], heap[i, 1], heap[i, 2], heap[i, 3]
    while True:
        c = 4 * i + 1
        if c >= size:
            break
        g = 4 * c + 1
        if prefetch and g < size:
            for k in range(g, min(g + 16, size), 2):
                _prefetch_row(heap, k)
        best = c
        for c2 in range(c + 1, min(c + 4, size)):
            if _less(
                heap[c2, 0], heap[c2, 1], heap[c2, 2], heap[best, 0], heap[best, 1], heap[best, 2]
            ):
                best = c2
        if _less(heap[best, 0], heap[best, 1], heap[best, 2], f, h, tie):
            for q in range(4):
                heap[i, q] = heap[best, q]
            i = best
        else:
            break
    heap[i, 0], heap[i, 1], heap[i, 2], heap[i, 3] = f, h, tie, node


@njit(inline="always")
def _open_push(hot, hsize, cold, csize, thr, f, h, tie, node):
    """Add a row to the open list: the hot heap when ``f`` is below ``thr``, else the cold rows.

    Returns the new ``(hsize, csize)``.
    """
    if f < thr:
        _heap_push(hot, hsize, f, h, tie, node)
        return hsize + 1, csize
    cold[csize, 0], cold[csize, 1], cold[csize, 2], cold[csize, 3] = f, h, tie, node
    return hsize, csize + 1


@njit()
def _f_quantile(rows, size, keep):
    """About the ``keep``-th smallest ``f`` (column 0) of ``rows[:size]``.

    Read from 255 evenly spaced rows (or all of them), so it costs nothing next to a move.
    """
    m = min(size, 255)
    sample = np.empty(m)
    for k in range(m):
        sample[k] = rows[(k * size) // m, 0]
    sample.sort()
    return sample[min(m - 1, (keep * m) // size)]


@njit()
def _spill(hot, hsize, cold, csize, keep):
    """Move the hot heap's rows at or above a new threshold to ``cold``; about ``keep`` stay.

    Returns ``(hsize, csize, threshold)``: every row left in the (re-heapified) hot heap has
    ``f`` below the threshold and every row moved has ``f`` at or above it. The smallest
    ``f`` always stays hot.
    """
    thr = _f_quantile(hot, hsize, keep)
    if thr <= hot[0, 0]:  # the root holds the smallest f
        thr = np.nextafter(hot[0, 0], np.inf)
    k = 0
    for i in range(hsize):
        if hot[i, 0] < thr:
            for q in range(4):
                hot[k, q] = hot[i, q]
            k += 1
        else:
            for q in range(4):
                cold[csize, q] = hot[i, q]
            csize += 1
    for i in range((k - 2) // 4, -1, -1):
        _sift_down(hot, k, i, False)
    return k, csize, thr


@njit()
def _refill(hot, cold, csize, keep):
    """Fill the empty hot heap with the rows of ``cold`` below a new threshold.

    About ``keep`` rows move (every row when ``csize <= keep``), at least one; the last cold
    row fills each one's place, so a refill writes only the rows that move (the cold rows'
    order is free: the threshold alone splits the open list). Returns
    ``(hsize, csize, threshold)`` with the invariant of :func:`_spill`.
    """
    thr = np.inf if csize <= keep else _f_quantile(cold, csize, keep)
    k = 0
    while k == 0:
        low = np.inf
        i = 0
        while i < csize:
            f = cold[i, 0]
            if f < thr:
                csize -= 1
                for q in range(4):
                    hot[k, q] = cold[i, q]
                    cold[i, q] = cold[csize, q]
                k += 1
            else:
                low = min(low, f)
                i += 1
        if k == 0:  # the sample's quantile was the smallest f: take every row that has it
            thr = np.nextafter(low, np.inf)
    for i in range((k - 2) // 4, -1, -1):
        _sift_down(hot, k, i, False)
    return k, csize, thr


@njit(inline="always")
def _slot(table, key, cell, local):
    """Row of ``key = cell * S + local`` in the lattice table, or of its empty slot.

    Rows are ``(key, g bits)`` (``-1`` key: empty; the node is in a column beside the
    table). The keys of one map cell
    (``cell``; ``local`` = yaw bin, foot and history class) start at the cell's hashed row
    and run on consecutive rows, so the states of a cell share cache lines: the successors
    of nearby states mostly read lines already loaded. Linear probing resolves collisions.
    """
    mask = table.shape[0] - 1
    i = (((cell * 0x9E3779B97F4A7C15) >> 17) + local) & mask
    while table[i, 0] != -1 and table[i, 0] != key:
        i = (i + 1) & mask
    return i


@njit()
def _rehash(table, tnode, new, new_node, s, inode, col):
    """Move the keys (``cell * s + local``) into the empty table ``new``.

    ``new`` has more rows than ``table`` and is filled with -1; each key's node (``tnode``,
    to ``new_node``) and ``inode[node, col]`` follow its row.
    """
    for i in range(table.shape[0]):
        key = table[i, 0]
        if key != -1:
            j = _slot(new, key, key // s, key % s)
            new[j, 0], new[j, 1] = key, table[i, 1]
            new_node[j] = tnode[i]
            inode[tnode[i], col] = j


@intrinsic
def _prefetch_row(typingctx, arr, row):
    """Hint the CPU to load row ``row`` of the 1-D or 2-D array ``arr`` into the cache.

    The search computes the lattice-table rows of all successors of a state first and
    prefetches them, so their cache misses overlap instead of stalling one after another.
    No effect on any value.
    """
    sig = types.void(arr, row)

    def codegen(context, builder, signature, args):
        aryty = signature.args[0]
        ary = context.make_array(aryty)(context, builder, args[0])
        r = context.cast(builder, args[1], signature.args[1], types.intp)
        zero = context.get_constant(types.intp, 0)
        idx = [r, zero] if aryty.ndim == 2 else [r]
        ptr = cgutils.get_item_pointer(context, builder, aryty, ary, idx)
        i8p, i32 = ir.IntType(8).as_pointer(), ir.IntType(32)
        fnty = ir.FunctionType(ir.VoidType(), [i8p, i32, i32, i32])
        fn = cgutils.get_or_insert_function(builder.module, fnty, "llvm.prefetch.p0")
        builder.call(fn, [builder.bitcast(ptr, i8p), i32(0), i32(3), i32(1)])
        return context.get_dummy_value()

    return sig, codegen


@intrinsic
def _borrowed(typingctx, arr):
    """``arr`` itself without its reference count (a NULL meminfo): same data, shape, strides.

    numba counts references (an atomic ``lock`` add and subtract) on the arrays an inlined
    kernel takes whenever it cannot prove them unneeded, e.g. around a loop with early
    exits (``_foot_free``: three per call; ``_open_push``: four per push); on a borrowed
    array those calls do nothing.
    The caller keeps ``arr`` alive while the borrowed one is used.
    """
    sig = arr(arr)

    def codegen(context, builder, signature, args):
        out = context.make_array(signature.args[0])(context, builder, value=args[0])
        out.meminfo = cgutils.get_null_value(out.meminfo.type)
        return out._getvalue()

    return sig, codegen


@njit(inline="always")
def _wrap(t):
    """``(t + pi) % (2 pi) - pi`` bit for bit (Python's float modulo), without the modulo.

    In the common ranges the modulo is one exact subtraction (Sterbenz) or Python's own
    ``x + 2 pi`` for negative ``x``; elsewhere the modulo itself.
    """
    two_pi = 2.0 * math.pi
    x = t + math.pi
    if 0.0 <= x < two_pi:
        pass
    elif two_pi <= x < 2.0 * two_pi:
        x = x - two_pi
    elif -two_pi < x < 0.0:
        x = x + two_pi
    else:
        x = x % two_pi
    return x - math.pi


@njit(inline="always")
def _yaw_bin(th, yaw_scale, nb):
    """``int(th * yaw_scale + nb + 0.5) % nb``; one subtraction for a wrapped yaw."""
    return _wrap_bin(int(th * yaw_scale + nb + 0.5), nb)


@njit(inline="always")
def _lattice_yaw(th, yaw_scale, shift, nb):
    """The lattice's yaw bin, ``int(th * yaw_scale + shift) % nb``.

    ``shift`` in [nb, nb + 1] centres the bins on the start's yaw (see
    ``BipedStepModel.lattice_key``).
    """
    return _wrap_bin(int(th * yaw_scale + shift), nb)


@njit(inline="always")
def _wrap_bin(v, nb):
    """``v % nb`` for ``v >= 0``; one subtraction for a wrapped yaw."""
    if 0 <= v < nb:
        return v
    if nb <= v < 2 * nb:
        return v - nb
    return v % nb


@njit()
def _grow_rows(a):
    b = np.empty((a.shape[0] * 2, a.shape[1]), a.dtype)
    b[: a.shape[0]] = a
    return b


@njit(inline="always")
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
    m = (_yaw_bin(th, yaw_scale, nb) * sub + qx) * sub + qy
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
                c, s, ext_x, ext_y, lim_u, lim_v = _sat_limits(th, hl, hw, inv_res)
            dx = r - big_r + 0.5 - fx
            for jj in range(2 * big_r + 1):
                if (hit >> np.uint64(jj)) & one:
                    dy = jj - big_r + 0.5 - fy
                    if _sat_overlaps(dx, dy, c, s, ext_x, ext_y, lim_u, lim_v):
                        return False
    return True


@njit()
def _sat_limits(th, hl, hw, inv_res):
    """The separating-axis test's limits for a sole at yaw ``th``, in cells.

    The one definition, for both cores (the Python checks call it through
    :func:`repertoire.planning.footstep.footprint.sat_limits`).
    ``hl``, ``hw``: the sole's half sides (m). Returns ``cos th, sin th``, the rectangle's
    half extents along the grid axes plus half a cell, and its half sides plus a cell's half
    extent along the sole's axes.
    """
    c, s = math.cos(th), math.sin(th)
    cell_u = 0.5 * (abs(c) + abs(s))
    return (
        c,
        s,
        (hl * abs(c) + hw * abs(s)) * inv_res + 0.5,
        (hl * abs(s) + hw * abs(c)) * inv_res + 0.5,
        hl * inv_res + cell_u,
        hw * inv_res + cell_u,
    )


# tolerance (cells) of the separating-axis test: a cell overlaps the sole only by more
SAT_EPS = 1e-9


@njit()
def _sat_overlaps(dx, dy, c, s, ext_x, ext_y, lim_u, lim_v):
    """True when a cell overlaps the sole with positive area (no separating axis).

    ``(dx, dy)``: the cell's centre minus the sole's, in cells; a :data:`SAT_EPS` tolerance.
    """
    eps = SAT_EPS
    return (
        abs(dx) < ext_x - eps
        and abs(dy) < ext_y - eps
        and abs(dx * c + dy * s) < lim_u - eps
        and abs(-dx * s + dy * c) < lim_v - eps
    )


@njit()
def _height_bounds(x, y, th, grid, ex, heights, ex_off, ex_ptr):
    """Min and max height over the exact footprint's outer mask (as FootprintChecker).

    The outer mask holds every cell the sole *may* overlap (up to about a mask margin
    beyond it): the range ``max - min`` over it is at least the range under the sole
    (a conservative flatness test), but its max is not the highest ground under the
    sole; the step limits use :func:`_top_height`.
    """
    ox, oy, inv_res = grid[0], grid[1], grid[2]
    pad, nyp, sub, nb, yaw_scale = int(ex[0]), int(ex[1]), int(ex[2]), int(ex[3]), ex[4]
    fx = (x - ox) * inv_res
    fy = (y - oy) * inv_res
    ix = int(math.floor(fx))
    iy = int(math.floor(fy))
    base = (ix + pad) * nyp + iy + pad
    qx = min(int((fx - ix) * sub), sub - 1)
    qy = min(int((fy - iy) * sub), sub - 1)
    m = (_yaw_bin(th, yaw_scale, nb) * sub + qx) * sub + qy
    lo, hi = np.inf, -np.inf
    for k in range(ex_ptr[m, 0], ex_ptr[m, 2]):
        v = heights[base + ex_off[k]]
        lo = min(lo, v)
        hi = max(hi, v)
    return lo, hi


@njit()
def _height_range(x, y, th, grid, ex, heights, ex_off, ex_ptr):
    lo, hi = _height_bounds(x, y, th, grid, ex, heights, ex_off, ex_ptr)
    return hi - lo


@njit()
def _cell_height(x, y, grid, ex, heights):
    """The height of the cell holding ``(x, y)`` (padded ``heights``, 0 off the grid).

    ``FootprintChecker.cell_height``'s twin: the ground a swing foot lifts from.
    """
    pad, nyp = int(ex[0]), int(ex[1])
    ix = int(math.floor((x - grid[0]) * grid[2]))
    iy = int(math.floor((y - grid[1]) * grid[2]))
    return heights[(ix + pad) * nyp + iy + pad]


@njit()
def _top_height(x, y, th, grid, ex, heights, ex_off, ex_ptr):
    """Highest ground under the sole at ``(x, y, th)``: the max height over the cells it overlaps.

    The cells are those the rectangle overlaps with positive area, as the collision check
    decides it: every cell of the pose's inner mask, and each ring cell that the exact
    separating-axis test of :func:`_foot_free` (same formula, same tolerance) finds
    overlapped; a ring cell is tested only when it would raise the max. The same value,
    bit for bit, as
    :meth:`~repertoire.planning.footstep.footprint.FootprintChecker.top_height`.
    ``ex``: pad, nyp, sub, yaw bins, yaw scale, half length, half width, mask radius R.
    """
    ox, oy, inv_res = grid[0], grid[1], grid[2]
    pad, nyp, sub, nb, yaw_scale = int(ex[0]), int(ex[1]), int(ex[2]), int(ex[3]), ex[4]
    hl, hw, big_r = ex[5], ex[6], int(ex[7])
    th = _wrap(th)  # as FootprintChecker (a no-op bit for bit except at a few ulps of +-pi)
    fx = (x - ox) * inv_res
    fy = (y - oy) * inv_res
    ix = int(math.floor(fx))
    iy = int(math.floor(fy))
    base = (ix + pad) * nyp + iy + pad
    fx -= ix
    fy -= iy
    qx = min(int(fx * sub), sub - 1)
    qy = min(int(fy * sub), sub - 1)
    m = (_yaw_bin(th, yaw_scale, nb) * sub + qx) * sub + qy
    top = -np.inf
    for k in range(ex_ptr[m, 0], ex_ptr[m, 1]):  # inner cells: overlapped for sure
        v = heights[base + ex_off[k]]
        if v > top:
            top = v
    exact = False
    c = s = ext_x = ext_y = lim_u = lim_v = 0.0
    for k in range(ex_ptr[m, 1], ex_ptr[m, 2]):  # ring cells: only if overlapped
        v = heights[base + ex_off[k]]
        if not v > top:
            continue
        if not exact:
            exact = True
            c, s, ext_x, ext_y, lim_u, lim_v = _sat_limits(th, hl, hw, inv_res)
        off = ex_off[k]  # di * nyp + dj with |dj| <= R < nyp / 2
        di = (off + big_r) // nyp
        dj = off - di * nyp
        if _sat_overlaps(di + 0.5 - fx, dj + 0.5 - fy, c, s, ext_x, ext_y, lim_u, lim_v):
            top = v
    return top


@njit()
def _along_grid_line(tops, top, k, a, b, along_u):
    """Whether a segment on a grid line runs through the interior of the tall region.

    The line is ``v = k`` (``along_u``; else ``u = k``), the segment from coordinate ``a``
    to ``b`` on it: inside where the cells on both sides of it are above ``top`` (one tall
    side only is touched, not crossed). Cells outside ``tops`` count as not tall.
    """
    nx, ny = tops.shape
    lo, hi = min(a, b), max(a, b)
    for c in range(math.floor(lo), math.ceil(hi)):
        if along_u:
            if 0 <= c < nx and 1 <= k < ny and tops[c, k - 1] > top and tops[c, k] > top:
                return True
        elif 0 <= c < ny and 1 <= k < nx and tops[k - 1, c] > top and tops[k, c] > top:
            return True
    return False


@njit()
def swing_crosses(tops, top, x0, y0, x1, y1, ox, oy, inv):
    """Whether the segment (x0, y0) -> (x1, y1) crosses a cell higher than ``top``.

    ``tops`` holds the cells' heights, ``top`` is the swing foot's highest point.
    Both search cores call this one function (the swing line of a step). Exact grid
    traversal (Amanatides and Woo): every cell whose open interior the closed segment
    meets is visited, in order, with the crossing parameters ``t`` of the next x and y
    cell boundaries recomputed from the endpoints at each step (no accumulated error).
    Touching is not crossing: a segment through a cell's corner point only (the x and y
    boundaries crossed at the same ``t``: it moves on diagonally), one running along a cell
    edge, or one ending on a cell's boundary, does not enter that cell; but a segment
    running along the edge between two tall cells is inside the tall region and crosses it
    (before, a straight walk on a grid line, e.g. at y = 0.5 m on 2.5 cm cells, swung
    through walls of any height). Exact in the segment's cell coordinates
    ``(x - ox) * inv`` up to the rounding of the ``t`` values (a pass within ~1e-15 cells
    of a corner may count either way). Cells outside ``tops`` count as not tall.
    """
    nx, ny = tops.shape
    u0 = (x0 - ox) * inv
    v0 = (y0 - oy) * inv
    du = (x1 - ox) * inv - u0
    dv = (y1 - oy) * inv - v0
    i = math.floor(u0)
    j = math.floor(v0)
    if i == u0 and du == 0.0:  # along the grid line u = i (or a point on it)
        return _along_grid_line(tops, top, i, v0, v0 + dv, False)
    if j == v0 and dv == 0.0:
        return _along_grid_line(tops, top, j, u0, u0 + du, True)
    if i == u0 and du < 0.0:  # starts on an x boundary: the cell it moves into
        i -= 1
    if j == v0 and dv < 0.0:
        j -= 1
    si = 1 if du > 0.0 else -1
    sj = 1 if dv > 0.0 else -1
    while True:
        if 0 <= i < nx and 0 <= j < ny and tops[i, j] > top:
            return True
        tx = ((i + 1 if si > 0 else i) - u0) / du if du != 0.0 else np.inf
        ty = ((j + 1 if sj > 0 else j) - v0) / dv if dv != 0.0 else np.inf
        if tx < ty:
            if not tx < 1.0:
                return False
            i += si
        elif ty < tx:
            if not ty < 1.0:
                return False
            j += sj
        else:  # through a corner point: the two side cells are only touched
            if not tx < 1.0:  # (also ends a point, and a NaN input)
                return False
            i += si
            j += sj


@njit()
def _now():
    with numba.objmode(t="float64"):
        t = time.perf_counter()
    return t


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


# the compiled checks read a footprint mask's rows as 64-bit words: masks up to 64 cells
# across (wider masks, of very fine grids or wide margins, plan on the Python core)
MASK_WORD_CELLS = 64
_BITS_CACHE: dict[int, tuple] = {}


def _cached_mask_bits(masks) -> tuple[np.ndarray, np.ndarray]:
    """Per mask and row ``di + R``: the inner and ring cells as bits ``dj + R``; row ranges."""
    hit = _BITS_CACHE.get(id(masks))
    if hit is not None and hit[0] is masks:
        return hit[1], hit[2]
    big_r = masks.radius_cells
    if 2 * big_r + 1 > MASK_WORD_CELLS:
        raise ValueError(f"footprint masks {2 * big_r + 1} cells wide exceed a 64-bit window")
    n, width = len(masks.inner), 2 * big_r + 1
    shifts = np.arange(width, dtype=np.uint64)
    bits = np.zeros((n, width, 2), np.uint64)
    for k, cells in ((0, masks.inner_cells), (1, masks.ring_cells)):
        bits[:, :, k] = (cells.astype(np.uint64) << shifts).sum(axis=2, dtype=np.uint64)
    used = bits.any(axis=2)  # (masks, rows)
    any_row = used.any(axis=1)
    first = np.where(any_row, used.argmax(axis=1), 0)
    last = np.where(any_row, width - used[:, ::-1].argmax(axis=1), 0)
    rows = np.stack([first, last], axis=1).astype(np.int64)
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
