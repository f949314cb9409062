"""A proof that no footstep plan reaches the goal, at any lattice: a relaxed flood fill.

A search that runs out of states after merging some cannot say UNREACHABLE on its own: a
finer lattice keeps poses the coarse one merged away and may get through (the planner
then refines). But some goals are cut off for every lattice: behind a band wider than a
step, up a step taller than ``max_step_up``, in a pocket no step reaches. :func:`goal_cut_off`
tells those apart with a flood fill over map cells that over-approximates every plan:

- a foot centre ``p`` stands in the cell containing it; the sole covers its inscribed disc
  whatever the yaw, so it overlaps every cell whose centre is within
  ``min(length, width) / 2 - res / sqrt(2)`` of that cell's centre (the cell itself
  included), and may overlap only cells within ``half-diagonal + res sqrt(2)``; the cells
  it surely overlaps must be free;
- the highest ground under the sole (what the step limits compare) is then the height of
  a free cell it may overlap, at least the highest of the cells surely overlapped (``lo``)
  and at most the highest free cell it may overlap (``hi``); with a flatness limit also at
  most the lowest surely-overlapped cell plus the limit (and a cell whose surely-overlapped
  heights already differ by more is no foothold). The fill's states are (cell, level):
  each such height apart, up to :data:`LEVELS` of them, else the interval ``[lo, hi]``, so
  a stance below a step the limits forbid never reaches the states above it;
- a step moves the foot centre by at most the table's reach ``R``
  (:meth:`ActionTable.max_reach`), each foot landing relative to the other, so consecutive
  cells have centres at most ``R + res sqrt(2)`` apart, and the step-up limit holds only if
  the landing's lowest level minus the stance's highest is at most ``max_step_up``
  (step-down likewise);
- the goal is reached when the stance foot centre is within the tolerance, so a goal
  cell's centre is within ``tol + res / sqrt(2)`` of the goal point.

Footprint margins, headings and histories only remove steps, so they are left out, and so
is the swing clearance but for :func:`_swing_walled` (cells too tall for any swing that
wall the start off the goal, settled first): when the fill from the start cell meets no
goal cell, no sequence of table steps does, whatever the lattice (sound, not complete: a
goal it cannot rule out may still be unreachable). The connected components of the
footholds' reach discs (:func:`_discs_connect`, heights left out) then settle a goal no
chain of footholds reaches, in tens of milliseconds. The fill visits each reachable state
at most once (compiled, nearest the goal first), about ``pi (R / res + 2)^2`` neighbouring
cells per state. The planner runs the proof only after a search ran out of states, before refining,
with the plan's clock: a fill the time limit cuts short proves nothing (the planner then
reports TIME_LIMIT).
"""

import functools
import math
import time

import numpy as np
from repertoire.planning.footstep.fastkernels import _heap_pop, _heap_push, _now
from repertoire.planning.footstep.jitcache import njit
from scipy import ndimage

from repertoire.limits import memory_limit_bytes

_EPS = 1e-9  # rounding slack (m): the relaxation refuses a step only when surely refused
LEVELS = 8
"""Ground heights kept apart per cell (more become one interval)."""
STATE_BYTES = 73
"""Memory per (cell, level) state of the fill: its interval (with the table's growth slack),
cell index, seen flag and heap row; a map whose level table might need more than
:func:`~repertoire.limits.memory_limit_bytes` gets no proof (the planner carries on)."""


def goal_cut_off(model, deadline: float = math.inf) -> bool:
    """True when no plan of ``model`` (a biped step model on a static grid) reaches its goal.

    Always False in dynamic worlds (cells free at some time are not kept apart here), and
    when the clock (``time.perf_counter``) passes ``deadline`` before the fill is done. On a
    12 m floor the components of :func:`_discs_connect` settle a walled-in goal in ~0.05 s;
    the fill then takes ~0.05 s where the goal can be reached, up to ~0.6 s where only step
    limits cut it off.
    """
    if model.dynamic or time.perf_counter() >= deadline:
        return False
    grid = model.ref
    res = grid.resolution
    free = ~np.asarray(grid.occupied, bool)
    heights = np.zeros(free.shape) if grid.heights is None else np.asarray(grid.heights, float)
    up, down, flat = float(model.step_up), float(model.step_down), float(model.flat_limit)
    geo = model.geometry
    _, valid, lo, bottom = _footholds(free, heights, geo, res, flat)
    # cells a sole centred in a cell may overlap
    may = _disc(0.5 * math.hypot(geo.foot_length, geo.foot_width) / res + math.sqrt(2.0))
    ground = np.where(free, heights, -np.inf)  # a sole overlaps free cells only
    hi = ndimage.maximum_filter(ground, footprint=may, mode="constant", cval=-np.inf)  # >= top
    if bottom is not None:  # the top is within ``flat`` of the lowest ground under the sole
        hi = np.minimum(hi, bottom + flat)
    reach = (model._table_entry["max_reach"] + res * math.sqrt(2.0)) / res
    (ox, oy), (gx, gy) = grid.origin, model.goal
    si = int((model.start_pose[0] - ox) / res)
    sj = int((model.start_pose[1] - oy) / res)
    goal_r = (model.tol + res / math.sqrt(2.0)) / res
    gi, gj = (gx - ox) / res - 0.5, (gy - oy) / res - 0.5  # the goal in cell-centre units
    if not (0 <= si < free.shape[0] and 0 <= sj < free.shape[1]):
        return False  # off the map: nothing to prove here (the step model refuses it)
    valid[si, sj] = True  # the start stands, whatever the relaxation says of its cell
    feet = [
        (int((x - ox) / res), int((y - oy) / res)) for x, y, _ in (model.start_pose, model.swing0)
    ]
    # the first swing starts at the initial swing foot, which may stand farther away
    apart = math.dist(model.start_pose[:2], model.swing0[:2]) / res + math.sqrt(2.0)
    if _swing_walled(model, heights, hi, valid, feet, max(reach, apart), gi, gj, goal_r):
        return True  # a wall too tall for any swing: proved at once
    if not _discs_connect(valid, si, sj, gi, gj, goal_r, reach):
        return True  # no chain of footholds at all, whatever the heights: proved at once
    if math.isfinite(up) or math.isfinite(down):
        if (LEVELS * STATE_BYTES * int(valid.sum()) + 8 * valid.size) > memory_limit_bytes():
            return False  # a level table that might not fit in memory: no proof (not a crash)
        ptr, zlo, zhi = _levels(
            valid, ground, lo, hi, np.argwhere(may) - (may.shape[0] // 2), deadline
        )
        if ptr.size == 0:  # out of time
            return False
    else:  # no step limits: levels do not matter, one state per foothold cell
        flat_valid = valid.ravel()
        ptr = np.concatenate([[0], np.cumsum(flat_valid, dtype=np.int64)])
        zlo, zhi = lo.ravel()[flat_valid], hi.ravel()[flat_valid]
    ny = free.shape[1]
    return _fill_reaches(ptr, zlo, zhi, ny, si, sj, gi, gj, goal_r, reach, up, down, deadline) == 0


def _footholds(free, heights, geo, res: float, flat: float):
    """The relaxation's footholds: cells where a sole centred in the cell may stand.

    ``free`` and ``heights`` are (nx, ny) arrays, or (K, nx, ny) stacks judged grid by grid.

    A sole centred anywhere in a cell overlaps, whatever its yaw, every cell within its
    inscribed disc (``sure``, in cells); those must be free (cells off the array count as
    free), and with a flatness limit their heights may differ by at most ``flat`` (the
    range under the sole is at least theirs). Every real foothold's cell is one.

    Returns:
        ``(fits, valid, lo, bottom)``: the cells whose ``sure`` disc is free, those also
        flat enough, the highest and (with a finite ``flat``, else None) the lowest height
        over each cell's ``sure`` disc.
    """
    sure = _sure_disc(min(geo.foot_length, geo.foot_width), res)
    sure = sure.reshape((1,) * (free.ndim - 2) + sure.shape)  # (K, nx, ny): K grids at once
    fits = free & ndimage.minimum_filter(free, footprint=sure, mode="constant", cval=True)
    lo = ndimage.maximum_filter(heights, footprint=sure, mode="constant", cval=-np.inf)
    if not math.isfinite(flat):
        return fits, fits, lo, None
    bottom = ndimage.minimum_filter(heights, footprint=sure, mode="constant", cval=np.inf)
    return fits, fits & (lo - bottom <= flat + _EPS), lo, bottom


def _foothold_at(occupied, heights, geo, res: float, i: int, j: int, flat: float) -> np.ndarray:
    """:func:`_footholds`' verdict on the one cell ``(i, j)`` of each of K grids (microseconds).

    ``occupied`` (K, nx, ny), ``heights`` likewise or None; returns (K,) bools.
    """
    k = _sure_disc(min(geo.foot_length, geo.foot_width), res)
    r = k.shape[0] // 2
    nx, ny = occupied.shape[1:]
    i0, i1, j0, j1 = max(i - r, 0), min(i + r + 1, nx), max(j - r, 0), min(j + r + 1, ny)
    sure = k[i0 - i + r : i1 - i + r, j0 - j + r : j1 - j + r]  # cells off the map: left out
    ok = ~occupied[:, i0:i1, j0:j1][:, sure].any(axis=1)
    if heights is None or not math.isfinite(flat):
        return ok
    z = heights[:, i0:i1, j0:j1][:, sure]
    return ok & (z.max(axis=1) - z.min(axis=1) <= flat + _EPS)


def goal_foothold_error(model) -> str:
    """Why no sole can stand within the goal tolerance of the goal ("" if one may).

    Judged by :func:`_footholds` on the cells around the goal (a few hundred, so every step
    model pays it): a goal cell's centre lies within ``tol + res / sqrt(2)`` of the goal
    point, and every sole that meets the goal test stands on one that is a foothold there.
    So a message here means no plan can end at the goal, on any lattice: a goal in a pocket
    too small for a sole, or on ground too steep for ``max_height_range``; in a dynamic
    world, so in every grid of E(t). "" when the start already meets the goal.
    """
    fits, valid, steep = _goal_footholds(model, None)
    if valid is None or valid.any():
        return ""
    geo, tol, (gx, gy) = model.geometry, model.opts.goal_tolerance, model.goal
    where = f"goal ({gx:.3f}, {gy:.3f})"
    when = " in any grid of E(t)" if model.dynamic else ""
    if not fits.any():
        return (
            f"{where}: no foot fits within goal_tolerance {tol} m of it{when} (every sole "
            f"{geo.foot_length} x {geo.foot_width} m centred there overlaps an obstacle)"
        )
    return (
        f"{where} lies on ground too steep{when}: every sole within goal_tolerance {tol} m of "
        f"it stands on a height range of at least {float(np.min(steep)):.3f} m > "
        f"max_height_range {model.flat_limit} m"
    )


def goal_closed_reason(model) -> str:
    """Why no plan of a dynamic world's model can arrive at its goal in time ("" if one may).

    Each step moves the stance foot by at most the table's reach ``R``
    (:meth:`ActionTable.max_reach`) and lasts at least its shortest duration, so the stance
    foot comes within the goal tolerance after ``n >= (distance - tol) / R`` steps, not
    before ``start_time + n`` shortest steps; a landing then is checked in a grid whose time
    is within ``max_time_gap`` of it. When no sole fits within the tolerance of the goal
    (:func:`goal_foothold_error`'s test) in any of those grids, e.g. an obstacle that moves
    onto the goal before the robot can get there, no plan exists. "" in static worlds,
    when the start meets the goal, when some such grid holds a sole, and when there is no
    such grid (an arrival past the last grid: the search's reason says so).
    """
    if not model.dynamic:
        return ""
    entry, tol = model._table_entry, model.opts.goal_tolerance
    reach, shortest = entry["max_reach"], entry["min_duration"]
    env, (gx, gy) = model.world, model.goal
    n = math.ceil((math.dist(model.start_pose[:2], model.goal) - tol) / reach - _EPS)
    if reach <= 0.0 or n <= 0:
        return ""
    arrive = model.start_time + n * shortest
    late = env.times >= arrive - env.max_time_gap - _EPS
    if not late.any():  # an arrival past the last grid: the search's reason says so
        return ""
    _, valid, _ = _goal_footholds(model, late)
    if valid.any():
        return ""
    last = f"{env.times[-1]:.3f} s"
    return (
        f"goal ({gx:.3f}, {gy:.3f}): the stance foot cannot come within goal_tolerance {tol} m "
        f"of it before t = {arrive:.3f} s ({n} steps of at least {shortest} s, each at most "
        f"{reach:.3f} m), and no foot fits there in any grid of E(t) from then on (up to "
        f"{last}): an obstacle covers it"
    )


def _goal_footholds(model, which):
    """Per grid (one in a static world), whether a sole fits near the goal, and flat enough.

    Args:
        model: the biped step model (its grids, goal, tolerance, geometry, flatness limit).
        which: (K,) bools, the grids of a dynamic world to judge; None: all.

    Returns:
        ``(fits, valid, steep)``: bools per judged grid and the least height range under
        the fitting soles (for the message; inf without one); all None when the start meets
        the goal. When the goal's own cell holds a sole in a judged grid (the usual case,
        microseconds), ``fits`` and ``valid`` are that cell's verdicts alone.
    """
    grid, tol = model.ref, model.opts.goal_tolerance  # (before the heuristic's set-up)
    (ox, oy), (gx, gy), (sx, sy, _) = grid.origin, model.goal, model.start_pose
    if (sx - gx) ** 2 + (sy - gy) ** 2 <= tol * tol:
        return None, None, None
    res, geo, (nx, ny) = grid.resolution, model.geometry, grid.shape
    goal_r = (tol + res / math.sqrt(2.0)) / res
    gi, gj = (gx - ox) / res - 0.5, (gy - oy) / res - 0.5  # the goal in cell-centre units
    flat = float(model.flat_limit)
    r = int(math.ceil(goal_r + 0.5 * min(geo.foot_length, geo.foot_width) / res)) + 2
    i0, i1 = max(int(gi) - r, 0), min(int(gi) + r + 2, nx)
    j0, j1 = max(int(gj) - r, 0), min(int(gj) + r + 2, ny)
    window = np.s_[i0:i1, j0:j1]
    if model.dynamic:  # the window of every judged grid
        ks = range(len(model.world.grids)) if which is None else np.flatnonzero(which)
        occupied = model.world.stack[(slice(None), *window)][list(ks)]
        grids = [model.world.grids[k] for k in ks]
    else:
        occupied, grids = grid.occupied[window][None], [grid]
    if grid.heights is None or not math.isfinite(flat):  # heights matter to flatness only
        heights = None
    else:
        heights = np.stack([g.heights[window] for g in grids])
    ci, cj = int(gi + 0.5) - i0, int(gj + 0.5) - j0  # the goal's own cell in the window
    own = _foothold_at(occupied, heights, geo, res, ci, cj, flat)
    if own.any():
        return own, own, np.zeros(1)
    ii, jj = np.mgrid[i0:i1, j0:j1]
    near = (ii - gi) ** 2 + (jj - gj) ** 2 <= goal_r * goal_r
    free = ~np.asarray(occupied, bool)
    z = np.zeros(free.shape) if heights is None else heights
    f, v, lo, bottom = _footholds(free, z, geo, res, flat)
    f, v = f & near, v & near
    steep = np.array([math.inf]) if bottom is None or not f.any() else (lo - bottom)[f]
    return f.any(axis=(1, 2)), v.any(axis=(1, 2)), steep


def _discs_connect(valid, si, sj, gi, gj, goal_r, reach) -> bool:
    """False only when no chain of footholds joins the start cell to a goal cell.

    A chain's cells are each within ``reach`` of the last (all in cells); True may be
    either. Two cells at most ``reach`` apart have discs of radius ``reach / 2`` that meet at the
    midpoint, and the cell holding the midpoint lies within ``reach / 2 + sqrt(1/2)`` of
    both centres; along the segment such cells are 8-connected. So the cells within that
    radius of a foothold centre (a distance transform), labelled 8-connected, put a chain's
    two ends in one component: a start and goal in different components have no chain.
    About 20 ms on a 12 m map, against ~0.6 s for the fill over a whole walled-in component;
    the fill (exact steps between cells) still decides where this says True.
    """
    near = ndimage.distance_transform_edt(~valid) <= 0.5 * reach + math.sqrt(0.5)
    labels, _ = ndimage.label(near, structure=np.ones((3, 3), bool))
    return _meets_goal(labels, labels[si, sj], valid, gi, gj, goal_r)


def _swing_walled(model, heights, hi, valid, starts, reach, gi, gj, goal_r) -> bool:
    """True when cells no swing line crosses wall both start feet off every goal cell.

    A swing's highest point is ``swing_clearance`` over the higher ground of two soles, the
    stance foot's and the landing's, each at most ``hi`` of its foothold cell (a ``valid``
    one, or a start foot's). The swing line runs within ``reach`` (cells, a step's reach or
    the start feet's distance, with the cells' slack) of the stance foot, and the landing
    lies within twice that of any point of the line: so a cell higher than the highest such
    ground within a square of half-side ``2 reach + 1`` cells around it, plus the clearance,
    blocks every swing (one with no foothold that near: no swing passes it). Each foot's
    centre moves on swing lines that enter no such cell's interior (nor run between two of
    them), so it stays in the closure of its start cell's 8-connected component of the other
    cells (landings keep the sole on the map, so no line runs along the map's edge); a goal
    cell outside both feet's components is out of reach. A thin wall too tall to swing over
    is thus settled at once.
    """
    nx, ny = valid.shape
    if not model.swing_limit or not all(0 <= i < nx and 0 <= j < ny for i, j in starts):
        return False  # (a start off the map: nothing to prove here)
    grounds = np.where(valid, hi, -np.inf)
    for i, j in starts:
        grounds[i, j] = hi[i, j]
    size = 2 * (int(math.ceil(2.0 * reach)) + 1) + 1
    near = ndimage.maximum_filter(grounds, size=size, mode="constant", cval=-np.inf)
    crossable = heights <= near + model.opts.swing_clearance + _EPS
    labels, _ = ndimage.label(crossable, structure=np.ones((3, 3), bool))
    for i, j in starts:
        if labels[i, j] == 0:
            return False
        if _meets_goal(labels, labels[i, j], crossable, gi, gj, goal_r):
            return False
    return True


def _meets_goal(labels, start, valid, gi, gj, goal_r) -> bool:
    """Whether a ``valid`` cell labelled ``start`` lies within ``goal_r`` of the goal.

    All in cells: the cell centres' distance to the goal ``(gi, gj)`` in cell-centre units.
    """
    nx, ny = valid.shape
    r = int(math.ceil(goal_r)) + 1
    i0, i1 = max(int(gi) - r, 0), min(int(gi) + r + 2, nx)
    j0, j1 = max(int(gj) - r, 0), min(int(gj) + r + 2, ny)
    if i0 >= i1 or j0 >= j1:
        return False
    ii, jj = np.mgrid[i0:i1, j0:j1]
    goal = valid[i0:i1, j0:j1] & ((ii - gi) ** 2 + (jj - gj) ** 2 <= goal_r * goal_r)
    return bool(np.any(labels[i0:i1, j0:j1][goal] == start))


@functools.lru_cache(maxsize=16)
def _sure_disc(breadth: float, res: float) -> np.ndarray:
    """The cells a sole ``breadth`` m across at its narrowest surely overlaps (read only).

    Centred anywhere in the middle cell, at any yaw: the cells of its inscribed disc.
    """
    disc = _disc(0.5 * breadth / res - math.sqrt(0.5), strict=True)
    disc.flags.writeable = False
    return disc


def _disc(radius: float, strict: bool = False) -> np.ndarray:
    """Cells whose centre lies within ``radius`` cells of the middle one (which is always in)."""
    k = max(int(math.floor(radius)), 0)
    di, dj = np.mgrid[-k : k + 1, -k : k + 1]
    d2 = di * di + dj * dj
    disc = d2 < radius * radius if strict else d2 <= radius * radius
    disc[k, k] = True
    return disc


@njit()
def _levels(valid, ground, lo, hi, may, deadline):
    """Per cell, the intervals the highest ground under a sole centred there can lie in.

    That ground is the height of a free cell the sole may overlap, within ``[lo, hi]``: up to
    :data:`LEVELS` such heights are kept apart (a state each, an exact height), more are one
    interval ``[lo, hi]``. Returns CSR rows ``ptr`` (per flat cell) and ``zlo``, ``zhi``;
    empty arrays when the clock passes ``deadline`` first (read every 4096 cells).
    """
    nx, ny = valid.shape
    ptr = np.zeros(nx * ny + 1, np.int64)
    zlo = np.empty(16, np.float64)
    zhi = np.empty(16, np.float64)
    vals = np.empty(may.shape[0], np.float64)
    n = 0
    for c in range(nx * ny):
        if (c & 4095) == 4095 and _now() >= deadline:
            return np.zeros(0, np.int64), zlo[:0], zhi[:0]
        i, j = c // ny, c % ny
        ptr[c] = n
        if not valid[i, j]:
            continue
        m = 0
        for k in range(may.shape[0]):
            i2, j2 = i + may[k, 0], j + may[k, 1]
            if 0 <= i2 < nx and 0 <= j2 < ny:
                z = ground[i2, j2]
                if lo[i, j] <= z <= hi[i, j]:
                    vals[m] = z
                    m += 1
        levels = np.unique(vals[:m])
        if n + LEVELS + 1 > zlo.shape[0]:
            zlo = np.concatenate((zlo, np.empty_like(zlo)))
            zhi = np.concatenate((zhi, np.empty_like(zhi)))
        if 0 < levels.size <= LEVELS:
            for z in levels:
                zlo[n], zhi[n] = z, z
                n += 1
        else:  # many heights (or none, with rounding): the whole interval
            zlo[n], zhi[n] = lo[i, j], max(hi[i, j], lo[i, j])
            n += 1
    ptr[nx * ny] = n
    return ptr, zlo[:n], zhi[:n]


@njit()
def _fill_reaches(ptr, zlo, zhi, ny, si, sj, gi, gj, goal_r, reach, up, down, deadline):
    """Best-first fill over (cell, ground level) states: 1 when a goal cell is met.

    A step joins two states whose cells' centres are within ``reach`` cells and whose
    levels may differ by at most the step-up and step-down limits. The state nearest the
    goal is taken first, so a goal that can be reached is usually met after a small part
    of the map (the planner asks only after a search ran out of states: on a 12 m floor
    where a finer lattice gets through, ~0.6 s breadth-first); a goal cut off needs every
    state reachable from the start either way. 0 when the fill ends without a goal cell,
    -1 when the clock passes ``deadline`` first (read every 256 states).
    """
    nx = (ptr.shape[0] - 1) // ny
    k = int(math.floor(reach))
    offs = []
    for di in range(-k, k + 1):
        for dj in range(-k, k + 1):
            if (di != 0 or dj != 0) and di * di + dj * dj <= reach * reach:
                offs.append((di, dj))
    n = zlo.shape[0]
    seen = np.zeros(n, np.bool_)
    cell = np.empty(n, np.int64)
    for c in range(nx * ny):
        cell[ptr[c] : ptr[c + 1]] = c
    # the search core's 4-ary heap: rows (squared cell distance to the goal, 0, state, state)
    heap = np.empty((n, 4))
    size = 0
    for s in range(ptr[si * ny + sj], ptr[si * ny + sj + 1]):
        seen[s] = True
        _heap_push(heap, size, (si - gi) ** 2 + (sj - gj) ** 2, 0.0, s, s)
        size += 1
    g2 = goal_r * goal_r
    done = 0
    while size > 0:
        if (done & 255) == 255 and _now() >= deadline:
            return -1
        done += 1
        s = int(heap[0, 3])
        _heap_pop(heap, size)
        size -= 1
        i, j = cell[s] // ny, cell[s] % ny
        if (i - gi) ** 2 + (j - gj) ** 2 <= g2:
            return 1
        lo_a, hi_a = zlo[s], zhi[s]
        for di, dj in offs:
            i2, j2 = i + di, j + dj
            if i2 < 0 or i2 >= nx or j2 < 0 or j2 >= ny:
                continue
            c2 = i2 * ny + j2
            for s2 in range(ptr[c2], ptr[c2 + 1]):
                if seen[s2] or zlo[s2] - hi_a > up + _EPS or lo_a - zhi[s2] > down + _EPS:
                    continue
                seen[s2] = True
                _heap_push(heap, size, (i2 - gi) ** 2 + (j2 - gj) ** 2, 0.0, s2, s2)
                size += 1
    return 0


__all__ = ["goal_closed_reason", "goal_cut_off", "goal_foothold_error"]
