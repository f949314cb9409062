"""A plan's corridor: the grid with every cell farther than a radius from the plan blocked.

The anytime planner improves a plan by searching again inside its corridor (on a finer
lattice, at a lower weight): the corridor's lattice is a small part of the map's, so such
a search takes a fraction of a whole-map one, and any plan found there is a plan on the
whole map (the corridor only blocks cells), at the same cost (step costs do not depend on
the blocked cells). The plan itself lies in its corridor, so the search can keep it.
"""

from collections.abc import Sequence

import numpy as np
from repertoire.planning.footstep.environment import OccupancyGrid
from repertoire.planning.footstep.types import FootstepError
from scipy.spatial import cKDTree

from repertoire.limits import require_memory

# height given to the cells outside the corridor when the grid has heights: taller than
# any swing clearance, so no step swings across them (m)
OUTSIDE_HEIGHT = 1.0e3
# discs are stamped at the polyline's cells (fast for corridors narrower than the map), this
# many stamps at a time; a disc of more than 4 map's worth of cells is replaced by a query of
# each map cell's nearest polyline cell (a k-d tree: time and memory bounded by the map)
STAMP_CHUNK = 1 << 22


def corridor_grid(
    grid: OccupancyGrid, points: Sequence[Sequence[float]], radius: float
) -> OccupancyGrid:
    """The grid with every cell farther than ``radius`` from the polyline's cells blocked.

    The polyline's cells are those its points and segments pass through (sampled every
    half cell); a cell stays as it was when its centre is within ``radius`` of the centre
    of one of them, so every point within ``radius - 0.71 res`` of the polyline keeps its
    cell.

    Args:
        grid: the map.
        points: ``(x, y, ...)`` points of the polyline (the plan's foot positions in order).
        radius: corridor half-width (m), > 0.

    Returns:
        a new grid: ``occupied`` is the map's plus every cell outside the corridor; with
        heights, the cells outside are :data:`OUTSIDE_HEIGHT` tall (those inside keep
        theirs).

    Raises:
        FootstepError: a radius that is not a positive number, or no points.
    """
    if not (np.isfinite(radius) and radius > 0.0):
        raise FootstepError(f"corridor radius must be a positive number of metres, got {radius}")
    try:
        xy = np.asarray([(float(p[0]), float(p[1])) for p in points], dtype=float).reshape(-1, 2)
    except (TypeError, ValueError, IndexError):
        raise FootstepError(
            f"corridor points must be (x, y, ...) numbers, got {points!r}"
        ) from None
    if len(xy) == 0:
        raise FootstepError("a corridor needs at least one point")
    if not np.isfinite(xy).all():
        raise FootstepError(f"corridor points must be finite, got {xy[~np.isfinite(xy).all(1)][0]}")
    res = grid.resolution
    steps = np.maximum(1, np.ceil(np.hypot(*np.diff(xy, axis=0).T) / (0.5 * res)))
    require_memory(16.0 * steps.sum(), f"the samples of a {len(xy)}-point corridor polyline")
    dense = [xy[:1]]
    for a, b, k in zip(xy[:-1], xy[1:], steps.astype(np.int64), strict=True):
        dense.append(a + (b - a) * (np.arange(1, k + 1)[:, None] / k))
    pts = np.concatenate(dense)
    n = int(np.floor(radius / res))
    nx, ny = grid.shape
    cells = np.floor((pts - np.asarray(grid.origin)) / res).astype(np.int64)
    cells = cells[
        (cells[:, 0] >= -n) & (cells[:, 0] < nx + n) & (cells[:, 1] >= -n) & (cells[:, 1] < ny + n)
    ]
    cells = np.unique(cells, axis=0)
    if not len(cells):
        keep = np.zeros((nx, ny), dtype=bool)
    elif (2 * n + 1) ** 2 > 4 * nx * ny:
        keep = _keep_by_nearest(cells, nx, ny, res, radius)
    else:
        keep = _keep_by_discs(cells, nx, ny, n, res, radius)
    heights = None
    if grid.heights is not None:
        heights = np.where(keep, grid.heights, OUTSIDE_HEIGHT)
    return OccupancyGrid(grid.occupied | ~keep, res, grid.origin, heights)


def _keep_by_discs(
    cells: np.ndarray, nx: int, ny: int, n: int, res: float, radius: float
) -> np.ndarray:
    """The map cells within ``radius`` (m) of a polyline cell: a disc stamped at each one."""
    wy = ny + 4 * n  # padded by 2 n on every side: no clipping, no wrapping
    flat = np.unique((cells[:, 0] + 2 * n) * wy + (cells[:, 1] + 2 * n))
    di, dj = np.meshgrid(np.arange(-n, n + 1), np.arange(-n, n + 1), indexing="ij")
    disc = (di * di + dj * dj) * (res * res) <= radius * radius
    offsets = (di[disc] * wy + dj[disc]).astype(np.int64)
    keep = np.zeros((nx + 4 * n) * wy, dtype=bool)
    chunk = max(1, STAMP_CHUNK // len(offsets))
    for k in range(0, len(flat), chunk):
        keep[(flat[k : k + chunk, None] + offsets[None, :]).ravel()] = True
    return keep.reshape(nx + 4 * n, wy)[2 * n : 2 * n + nx, 2 * n : 2 * n + ny]


def _keep_by_nearest(cells: np.ndarray, nx: int, ny: int, res: float, radius: float) -> np.ndarray:
    """The same cells as :func:`_keep_by_discs`, by each map cell's nearest polyline cell.

    For discs wider than the map (many more disc cells than map cells): a k-d tree query
    per map cell, the nearest polyline cell then checked exactly as the discs do.
    """
    ii, jj = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    query = np.stack([ii.ravel(), jj.ravel()], axis=1)
    _, nearest = cKDTree(cells).query(query)
    d = query - cells[nearest]
    close = (d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]) * (res * res) <= radius * radius
    return close.reshape(nx, ny)
