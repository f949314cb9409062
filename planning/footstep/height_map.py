"""A 2.5-D height map of a terrain (ground height per square cell) for footstep planning.

:class:`HeightMap` holds the heights and answers cell look-ups and roughness;
:func:`height_map_from_board` samples a terrain board's exact height at cell centres.
The quadruped crawl step model (:mod:`repertoire.planning.footstep.quadruped`) plans on it.
"""

import dataclasses
import math

import numpy as np
from repertoire.planning.footstep.types import GridError
from scipy import ndimage

from repertoire.checks import is_real
from repertoire.limits import require_memory

# Bytes per height-map cell: the heights and the roughness array (float64 each).
_BYTES_PER_CELL = 16


@dataclasses.dataclass(frozen=True)
class HeightMap:
    """A 2.5-D map: ground height per square cell.

    Attributes:
        origin: world (x, y) of cell (0, 0)'s centre (m).
        resolution: cell side (m).
        heights: ground heights (m), shape (n_y, n_x), finite and >= 0.
    """

    origin: tuple[float, float]
    resolution: float
    heights: np.ndarray

    def __post_init__(self) -> None:
        if not (is_real(res := self.resolution) and math.isfinite(res) and res > 0.0):
            raise GridError(f"height map resolution must be positive, got {self.resolution!r}")
        if not _numbers(self.origin, 2):
            raise GridError(f"height map origin must be a finite (x, y), got {self.origin!r}")
        raw = np.asarray(self.heights)
        if raw.dtype.kind not in "biuf":  # complex (its imaginary part dropped), strings, objects
            raise GridError(
                f"height map heights must be real numbers (m), got dtype {raw.dtype} with values "
                f"such as {raw.ravel()[:3].tolist()}"
            )
        h = np.asarray(raw, dtype=float)
        if h.ndim != 2 or min(h.shape) < 1:
            raise GridError(f"height map heights must be a 2-D array, got shape {h.shape}")
        if not np.all(np.isfinite(h)):
            bad = np.argwhere(~np.isfinite(h))[0]
            raise GridError(
                f"height map height at cell (row {bad[0]}, col {bad[1]}) is "
                f"{h[tuple(bad)]}; heights must be finite"
            )
        if np.any(h < 0.0):
            bad = np.argwhere(h < 0.0)[0]
            raise GridError(
                f"height map height at cell (row {bad[0]}, col {bad[1]}) is "
                f"{h[tuple(bad)]} m; heights must be >= 0 (ground level 0)"
            )
        object.__setattr__(self, "heights", h)

    @property
    def shape(self) -> tuple[int, int]:
        return self.heights.shape

    def cell(self, x, y) -> tuple[np.ndarray, np.ndarray]:
        """(row, col) indices of the cells holding world points (x, y).

        A point off the map gets an index off it (-1 or the map's size at the farthest, so
        far points do not overflow the integers).
        """
        col = np.rint((np.asarray(x, dtype=float) - self.origin[0]) / self.resolution)
        row = np.rint((np.asarray(y, dtype=float) - self.origin[1]) / self.resolution)
        n_y, n_x = self.shape
        return np.clip(row, -1, n_y).astype(int), np.clip(col, -1, n_x).astype(int)

    def inside(self, row, col) -> np.ndarray:
        """True where (row, col) is a cell of the map."""
        row, col = np.asarray(row), np.asarray(col)
        return (row >= 0) & (row < self.shape[0]) & (col >= 0) & (col < self.shape[1])

    def center(self, row, col) -> tuple[np.ndarray, np.ndarray]:
        """World (x, y) of cell centres."""
        return (
            self.origin[0] + np.asarray(col) * self.resolution,
            self.origin[1] + np.asarray(row) * self.resolution,
        )

    def height(self, x, y) -> np.ndarray:
        """Heights of the cells holding world points (x, y); 0 off the map (like a board)."""
        row, col = self.cell(*np.broadcast_arrays(x, y))
        r = np.clip(row, 0, self.shape[0] - 1)
        c = np.clip(col, 0, self.shape[1] - 1)
        return np.where(self.inside(row, col), self.heights[r, c], 0.0)

    def roughness(self, radius: float) -> np.ndarray:
        """Height range (max - min) within ``radius`` of each cell, shape like heights."""
        r = max(int(math.ceil(radius / self.resolution - 1e-9)), 0)
        # a disk reaching across the whole map from every cell: the map's range everywhere
        if radius**2 >= self.resolution**2 * sum((n - 1) ** 2 for n in self.shape):
            return np.full(self.shape, np.ptp(self.heights))
        ii, jj = np.mgrid[-r : r + 1, -r : r + 1]
        disk = (ii**2 + jj**2) * self.resolution**2 <= radius**2 + 1e-12
        hi = ndimage.maximum_filter(self.heights, footprint=disk, mode="nearest")
        lo = ndimage.minimum_filter(self.heights, footprint=disk, mode="nearest")
        return hi - lo


def _numbers(values, n: int) -> bool:
    """True when ``values`` holds exactly ``n`` finite real numbers."""
    try:
        return len(values) == n and all(is_real(v) and math.isfinite(v) for v in values)
    except TypeError:  # no length: a single number, None
        return False


def height_map_from_board(
    board,
    x_range: tuple[float, float],
    y_range: tuple[float, float],
    resolution: float = 0.01,
) -> HeightMap:
    """Samples a terrain board's exact height at cell centres.

    Args:
        board: a :class:`repertoire.models.terrain.TerrainBoard` (anything with a
            vectorised ``height(x, y)``).
        x_range: [x_min, x_max] of the map (m).
        y_range: [y_min, y_max] of the map (m).
        resolution: cell side (m).

    Raises:
        GridError: empty or non-finite ranges, bad resolution.
        ResourceLimitError: the map would need more memory than allowed (the figure
            is in the message), checked before allocating.
    """
    if not (_numbers(x_range, 2) and _numbers(y_range, 2) and _numbers([resolution], 1)):
        raise GridError(
            f"height map ranges must be finite [min, max] and the resolution a finite number, "
            f"got x_range={x_range!r}, y_range={y_range!r}, resolution={resolution!r}"
        )
    if not callable(getattr(board, "height", None)):
        raise GridError(f"height map board must have a height(x, y) method, got {board!r:.80}")
    if resolution <= 0.0:
        raise GridError(f"height map resolution must be positive, got {resolution}")
    if x_range[1] <= x_range[0] or y_range[1] <= y_range[0]:
        raise GridError(f"height map ranges must be [min, max] with min < max: {x_range} {y_range}")
    n_x = int(math.floor((x_range[1] - x_range[0]) / resolution + 1e-9)) + 1
    n_y = int(math.floor((y_range[1] - y_range[0]) / resolution + 1e-9)) + 1
    require_memory(
        float(n_x) * n_y * _BYTES_PER_CELL,
        f"a {n_x} x {n_y} height map at {resolution} m",
    )
    xs = x_range[0] + np.arange(n_x) * resolution
    ys = y_range[0] + np.arange(n_y) * resolution
    X, Y = np.meshgrid(xs, ys)
    return HeightMap(
        origin=(float(x_range[0]), float(y_range[0])),
        resolution=float(resolution),
        heights=np.asarray(board.height(X, Y), dtype=float),
    )


__all__ = ["HeightMap", "height_map_from_board"]
