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
- the highest ground under the sole (what the step limits compare) is then at least the
  highest of the cells surely overlapped (``lo``) and at most the highest free cell it may
  overlap (``hi``); with a flatness limit it is also at most the lowest surely-overlapped
  cell plus the limit, and a cell whose surely-overlapped heights already differ by more
  is no foothold;
- a step moves the foot centre by at most the table's reach ``R``
  (:meth:`ActionTable.max_reach`), each foot landing relative to the other, so consecutive
  cells have centres at most ``R + res sqrt(2)`` apart, and the step-up limit holds only if
  ``lo(landing) - hi(stance) <= max_step_up`` (step-down likewise);
- the goal is reached when the stance foot centre is within the tolerance, so a goal
  cell's centre is within ``tol + res / sqrt(2)`` of the goal point.

Swing clearance, footprint margins, headings and histories only remove steps, so they are
left out: when the fill from the start cell meets no goal cell, no sequence of table steps
does, whatever the lattice (sound, not complete: a goal it cannot rule out may still be
unreachable). The fill visits each reachable cell once (compiled), about
``pi (R / res + 2)^2`` neighbours per cell; the planner runs it only after a search ran out
of states, before refining.
"""

import math

import numpy as np
from repertoire.planning.footstep.jitcache import njit
from scipy import ndimage

_EPS = 1e-9  # rounding slack (m): the relaxation refuses a step only when surely refused


def goal_cut_off(model) -> bool:
    """True when no plan of ``model`` (a biped step model on a static grid) reaches its goal.

    Always False in dynamic worlds (cells free at some time are not kept apart here).
    """
    if model.dynamic:
        return False
    grid = model.ref
    res = grid.resolution
    free = ~np.asarray(grid.occupied, bool)
    heights = np.zeros(free.shape) if grid.heights is None else np.asarray(grid.heights, float)
    up, down, flat = float(model.step_up), float(model.step_down), float(model.flat_limit)
    geo = model.geometry
    # cells every sole centred in a cell overlaps (its inscribed disc's), and may overlap
    sure = _disc(0.5 * min(geo.foot_length, geo.foot_width) / res - math.sqrt(0.5), strict=True)
    may = _disc(0.5 * math.hypot(geo.foot_length, geo.foot_width) / res + math.sqrt(2.0))
    valid = free & ndimage.minimum_filter(free, footprint=sure, mode="constant", cval=True)
    # (cells off the map count neither way)
    lo = ndimage.maximum_filter(heights, footprint=sure, mode="constant", cval=-np.inf)
    ground = np.where(free, heights, -np.inf)  # a sole overlaps free cells only
    hi = ndimage.maximum_filter(ground, footprint=may, mode="constant", cval=-np.inf)  # >= top
    if math.isfinite(flat):  # the top is within ``flat`` of the lowest ground under the sole
        bottom = ndimage.minimum_filter(heights, footprint=sure, mode="constant", cval=np.inf)
        valid &= lo - bottom <= flat + _EPS
        hi = np.minimum(hi, bottom + flat)
    reach = (model._table_entry["max_reach"] + res * math.sqrt(2.0)) / res
    (ox, oy), (gx, gy) = grid.origin, model.goal
    si = int((model.start_pose[0] - ox) / res)
    sj = int((model.start_pose[1] - oy) / res)
    goal_r = (model.tol + res / math.sqrt(2.0)) / res
    gi, gj = (gx - ox) / res - 0.5, (gy - oy) / res - 0.5  # the goal in cell-centre units
    return not _fill_reaches(valid, lo, hi, si, sj, gi, gj, goal_r, reach, up, down)


def _disc(radius: float, strict: bool = False) -> np.ndarray:
    """Cells whose centre lies within ``radius`` cells of the middle one (which is always in)."""
    k = max(int(math.floor(radius)), 0)
    di, dj = np.mgrid[-k : k + 1, -k : k + 1]
    d2 = di * di + dj * dj
    disc = d2 < radius * radius if strict else d2 <= radius * radius
    disc[k, k] = True
    return disc


@njit()
def _fill_reaches(valid, lo, hi, si, sj, gi, gj, goal_r, reach, up, down):
    """Breadth-first fill over the cells a foot may stand in; True when a goal cell is met.

    ``lo`` / ``hi``: bounds of the highest ground under a sole centred in each cell.
    """
    nx, ny = valid.shape
    if not (0 <= si < nx and 0 <= sj < ny):
        return True  # off the map: nothing to prove here (the step model refuses it)
    k = int(math.floor(reach))
    offs = []
    for di in range(-k, k + 1):
        for dj in range(-k, k + 1):
            if (di != 0 or dj != 0) and di * di + dj * dj <= reach * reach:
                offs.append((di, dj))
    seen = np.zeros((nx, ny), np.bool_)
    queue = np.empty(nx * ny, np.int64)
    seen[si, sj] = True
    queue[0] = si * ny + sj
    head, tail = 0, 1
    g2 = goal_r * goal_r
    while head < tail:
        c = queue[head]
        head += 1
        i, j = c // ny, c % ny
        if (i - gi) ** 2 + (j - gj) ** 2 <= g2:
            return True
        lo_a, hi_a = lo[i, j], hi[i, j]
        for di, dj in offs:
            i2, j2 = i + di, j + dj
            if i2 < 0 or i2 >= nx or j2 < 0 or j2 >= ny or seen[i2, j2] or not valid[i2, j2]:
                continue
            if lo[i2, j2] - hi_a > up + _EPS or lo_a - hi[i2, j2] > down + _EPS:
                continue
            seen[i2, j2] = True
            queue[tail] = i2 * ny + j2
            tail += 1
    return False


__all__ = ["goal_cut_off"]
