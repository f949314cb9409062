"""Exact foot-rectangle collision checks against grid cells, made fast by precomputation.

For every discretised yaw (``yaw_bins``) and sub-cell offset of the foot centre
(``sub`` x ``sub`` bins per cell) two cell masks are precomputed: the *outer* mask holds
every cell the foot can overlap for any pose in the bin, the *inner* mask every cell it
overlaps for all poses in the bin. A pose is free if no outer cell is occupied, in
collision if an inner cell is; only occupied cells of the thin ring between the two are
tested exactly (separating axes) for the actual pose. Far from obstacles a distance
transform answers without any mask. The answer is always the exact one for the
rectangle: a cell blocks a foot only if they overlap with positive area.

The grid's rows are Python integers (one bit per cell) and each mask is a few
``(row offset, bit pattern)`` pairs, so a test is a handful of shifts and ANDs.
"""

import functools
import math

import numpy as np
from repertoire.planning.footstep.environment import OccupancyGrid, rect_overlaps_cells
from repertoire.planning.footstep.fastkernels import SAT_EPS, _occupancy_words, _sat_limits
from repertoire.planning.footstep.jitcache import njit


class FootprintMasks:
    """Precomputed outer/inner/ring cell masks of a foot rectangle.

    Args:
        foot_length: sole length (m).
        foot_width: sole width (m).
        resolution: grid cell side (m).
        yaw_bins: number of yaw bins over a full turn.
        sub: sub-cell bins per axis for the foot centre.
    """

    def __init__(
        self,
        foot_length: float,
        foot_width: float,
        resolution: float,
        yaw_bins: int = 72,
        sub: int = 4,
    ) -> None:
        self.half = (foot_length / 2.0, foot_width / 2.0)
        self.resolution = resolution
        self.yaw_bins = yaw_bins
        self.yaw_scale = yaw_bins / (2.0 * math.pi)
        self.sub = sub
        self.r_diag = math.hypot(*self.half)
        dyaw = 2.0 * math.pi / yaw_bins
        self.margin = resolution / sub * math.sqrt(2.0) / 2.0 + self.r_diag * dyaw / 2.0
        self.radius_cells = int(math.ceil((self.r_diag + self.margin) / resolution)) + 1
        R = self.radius_cells
        width = 2 * R + 1
        di, dj = np.meshgrid(np.arange(-R, R + 1), np.arange(-R, R + 1), indexing="ij")
        di, dj = di.ravel(), dj.ravel()
        centers = np.stack([(di + 0.5) * resolution, (dj + 0.5) * resolution], axis=1)
        hl, hw = self.half
        e = self.margin
        subs = np.array(
            [((qx + 0.5) / sub * resolution, (qy + 0.5) / sub * resolution)
             for qx in range(sub) for qy in range(sub)]
        )  # fmt: skip
        # masks (yaw bin, then sub-cell x, then y) over the (2R+1)^2 cells, row-major in di:
        # every sub-cell centre of a yaw bin in one call
        out_all = np.empty((yaw_bins, sub * sub, width * width), bool)
        inn_all = np.empty_like(out_all)
        half_cell = resolution / 2
        for yb in range(yaw_bins):
            yaw = yb * dyaw
            out_all[yb] = rect_overlaps_cells(subs, (hl + e, hw + e), yaw, centers, half_cell)
            inn_all[yb] = rect_overlaps_cells(
                subs, (max(hl - e, 0.0), max(hw - e, 0.0)), yaw, centers, half_cell
            )
        n = yaw_bins * sub * sub
        out_all, inn_all = out_all.reshape(n, -1), inn_all.reshape(n, -1)
        ring_all = out_all & ~inn_all
        #: per mask the cells as booleans, shape (masks, 2R+1, 2R+1) indexed [m, di+R, dj+R]
        self.outer_cells = out_all.reshape(n, width, width)
        self.inner_cells = inn_all.reshape(n, width, width)
        self.ring_cells = ring_all.reshape(n, width, width)
        self.outer = [(di[m], dj[m]) for m in out_all]
        self.inner = [(di[m], dj[m]) for m in inn_all]
        self.ring = [(di[m], dj[m]) for m in ring_all]

    # the same masks as (row offset, bit set of column offsets + R) per grid row, for the
    # Python checks; built on first use (the compiled core reads the cells as words instead)
    @functools.cached_property
    def outer_rows(self) -> list[tuple[tuple[int, int], ...]]:
        return _rows_of(self.outer_cells, self.radius_cells)

    @functools.cached_property
    def inner_rows(self) -> list[tuple[tuple[int, int], ...]]:
        return _rows_of(self.inner_cells, self.radius_cells)

    @functools.cached_property
    def ring_rows(self) -> list[tuple[tuple[int, int], ...]]:
        return _rows_of(self.ring_cells, self.radius_cells)

    def index(self, yaw: float, fx: float, fy: float) -> int:
        """Mask index for a yaw and the fractional position of the centre in its cell.

        Args:
            yaw: foot yaw (rad).
            fx: fractional x in [0, 1) within the cell.
            fy: fractional y in [0, 1) within the cell.
        """
        yb = int(yaw * self.yaw_scale + self.yaw_bins + 0.5) % self.yaw_bins
        qx = min(int(fx * self.sub), self.sub - 1)
        qy = min(int(fy * self.sub), self.sub - 1)
        return (yb * self.sub + qx) * self.sub + qy


def sat_limits(
    yaw: float, half: "tuple[float, float]", inv_res: float
) -> tuple[float, float, float, float, float, float]:
    """The separating-axis test's limits for a sole at ``yaw``, in cells.

    A cell whose centre lies ``(dx, dy)`` cells from the sole's centre overlaps the sole
    (positive area) when ``|dx| < ext_x``, ``|dy| < ext_y``, ``|dx c + dy s| < lim_u`` and
    ``|-dx s + dy c| < lim_v``, each by more than ``SAT_EPS``. Both cores compute them
    with one compiled function, ``fastkernels._sat_limits``.

    Args:
        yaw: sole yaw (rad).
        half: the sole's half length and half width (m).
        inv_res: cells per metre.

    Returns:
        ``c, s, ext_x, ext_y, lim_u, lim_v``: cos and sin of the yaw, the rectangle's half
        extents along the grid axes plus half a cell, and its half sides plus a cell's half
        extent along the sole's axes.
    """
    return _sat_limits(yaw, half[0], half[1], inv_res)


def _rows_of(cells: np.ndarray, R: int) -> list[tuple[tuple[int, int], ...]]:
    """Every mask as ``(row offset, bits of column offset + R)`` pairs, rows ascending.

    Args:
        cells: the masks' booleans, shape (masks, 2R+1, 2R+1), indexed ``[m, di + R, dj + R]``.
        R: the masks' radius in cells.

    Columns are packed 62 at a time as int64, then joined as Python ints (wide masks of very
    fine grids need more than 64 bits).
    """
    n, width = cells.shape[0], 2 * R + 1
    chunks = []
    for k in range(0, width, 62):
        part = cells[:, :, k : k + 62].astype(np.int64)
        chunks.append((part << np.arange(part.shape[2], dtype=np.int64)).sum(axis=2))
    nonzero = np.zeros(chunks[0].shape, bool)
    for chunk in chunks:
        nonzero |= chunk != 0
    m_idx, i_idx = np.nonzero(nonzero)  # row-major: by mask, then row ascending
    vals = chunks[0][m_idx, i_idx].tolist()
    for j, chunk in enumerate(chunks[1:], 1):
        vals = [v | (w << (62 * j)) for v, w in zip(vals, chunk[m_idx, i_idx].tolist())]
    pairs = list(zip((i_idx - R).tolist(), vals))
    bounds = np.searchsorted(m_idx, np.arange(n + 1)).tolist()
    return [tuple(pairs[bounds[k] : bounds[k + 1]]) for k in range(n)]


@functools.lru_cache(maxsize=8)
def footprint_masks(
    foot_length: float, foot_width: float, resolution: float, yaw_bins: int = 72, sub: int = 4
) -> FootprintMasks:
    """Cached :class:`FootprintMasks` (built once per geometry and resolution).

    Args:
        foot_length: sole length (m).
        foot_width: sole width (m).
        resolution: grid cell side (m).
        yaw_bins: yaw bins per turn.
        sub: sub-cell bins per axis.
    """
    return FootprintMasks(foot_length, foot_width, resolution, yaw_bins, sub)


def distance_to_features(features: np.ndarray) -> np.ndarray:
    """Exact Euclidean distance (in cells) from each cell centre to the nearest feature cell.

    The same values as ``scipy.ndimage.distance_transform_edt(~features)`` (inf where there
    is no feature), by Felzenszwalb and Huttenlocher's two-pass lower envelope of parabolas,
    compiled.

    Args:
        features: (nx, ny) bool array.
    """
    return np.sqrt(_edt_sq(np.ascontiguousarray(features, dtype=np.bool_)))


@njit()
def _edt_sq(features):
    nx, ny = features.shape
    big = 1e20
    col = np.empty((nx, ny))
    for j in range(ny):  # pass 1: squared distance along x
        last = -1
        for i in range(nx):
            if features[i, j]:
                last = i
            col[i, j] = big if last < 0 else float((i - last) * (i - last))
        last = -1
        for i in range(nx - 1, -1, -1):
            if features[i, j]:
                last = i
            if last >= 0:
                d = float((last - i) * (last - i))
                if d < col[i, j]:
                    col[i, j] = d
    out = np.empty((nx, ny))
    v = np.empty(ny, np.int64)
    z = np.empty(ny + 1)
    for i in range(nx):  # pass 2: lower envelope of parabolas along y
        f = col[i]
        k = -1
        for q in range(ny):
            if f[q] >= big:
                continue
            while k >= 0:
                p = v[k]
                s = ((f[q] + q * q) - (f[p] + p * p)) / (2.0 * (q - p))
                if s <= z[k]:
                    k -= 1
                else:
                    break
            k += 1
            v[k] = q
            z[k] = (
                -np.inf
                if k == 0
                else ((f[q] + q * q) - (f[v[k - 1]] + v[k - 1] ** 2)) / (2.0 * (q - v[k - 1]))
            )
            z[k + 1] = np.inf
        if k < 0:
            for q in range(ny):
                out[i, q] = np.inf
            continue
        m = 0
        for q in range(ny):
            while z[m + 1] < q:
                m += 1
            p = v[m]
            out[i, q] = (q - p) * (q - p) + f[p]
    return out


@njit()
def surely_free_words(words, half_width):
    """Cells with no occupied cell within ``half_width`` cells (Chebyshev), as bits.

    Bit-parallel: each row (bit j of word j // 64) is dilated by ``half_width`` along the
    row by shifts, then the dilated rows within ``half_width`` are OR-ed; a cell is surely
    free where the result is 0. Rows beyond the grid's first and last count as free, so
    only cells whose square window lies in the grid are meaningful: with an occupied
    border wider than ``half_width`` (a :class:`FootprintChecker`'s padding) every other
    cell is occupied itself, hence never free.

    Args:
        words: (NX, W) uint64 occupancy bits, bit ``j % 64`` of word ``j // 64`` for cell
            ``(i, j)``; bits past the last cell 0.
        half_width: half side of the square window, in cells (>= 0).

    Returns:
        (NX, W) uint64, bit set where surely free.
    """
    nxp, nw = words.shape
    rowd = words.copy()
    left = half_width
    while left > 0:  # dilations add up: passes of at most 63 (a shift stays below 64)
        step = min(left, 63)
        left -= step
        prev = rowd.copy()
        for i in range(nxp):
            for w in range(nw):
                x = prev[i, w]
                lo = prev[i, w - 1] if w > 0 else np.uint64(0)
                hi = prev[i, w + 1] if w + 1 < nw else np.uint64(0)
                acc = x
                for s in range(1, step + 1):
                    sh, back = np.uint64(s), np.uint64(64 - s)
                    acc |= (x << sh) | (lo >> back) | (x >> sh) | (hi << back)
                rowd[i, w] = acc
    free = np.empty_like(words)
    for i in range(nxp):
        a, b = max(i - half_width, 0), min(i + half_width + 1, nxp)
        for w in range(nw):
            acc = np.uint64(0)
            for k in range(a, b):
                acc |= rowd[k, w]
            free[i, w] = ~acc
    return free


class FootprintChecker:
    """Collision checks of foot poses against one occupancy grid.

    Args:
        grid: the grid (outside the grid counts as occupied).
        masks: precomputed masks for the grid's resolution.
    """

    def __init__(self, grid: OccupancyGrid, masks: FootprintMasks) -> None:
        if abs(masks.resolution - grid.resolution) > 1e-12:
            raise ValueError(
                f"footprint masks were built for resolution {masks.resolution}, "
                f"the grid has {grid.resolution}"
            )
        self.grid = grid
        self.masks = masks
        pad = masks.radius_cells + 1
        self.pad = pad
        nx, ny = grid.shape
        self.nx, self.ny = nx, ny
        occ = np.ones((nx + 2 * pad, ny + 2 * pad), dtype=bool)
        occ[pad : pad + nx, pad : pad + ny] = grid.occupied
        self.nyp = ny + 2 * pad
        self.occ_flat = occ.ravel()
        # a foot centred in a cell whose centre is farther than r_diag + one cell diagonal
        # from every occupied (or outside) cell centre is free; no occupied cell within
        # m cells (Chebyshev, which is <= Euclidean) guarantees a distance > m cells
        reach = masks.r_diag + grid.resolution * math.sqrt(2.0)
        self._free_m = int(reach / grid.resolution + 1e-9)
        self._free_bytes: bytes | None = None
        self.inv_res = 1.0 / grid.resolution
        self.x0, self.y0 = grid.origin
        self._occ = occ
        self._rows: list[int] | None = None
        self._outer: list[np.ndarray] | None = None
        self._heights_flat: np.ndarray | None = None
        self._exact_cells: list | None = None

    @property
    def heights_flat(self) -> np.ndarray | None:
        """The grid's heights padded like the occupancy (0 outside), flat; None without.

        Built on first use: a plan without height limits or height cost never reads it.
        """
        if self._heights_flat is None and self.grid.heights is not None:
            pad, nx, ny = self.pad, self.nx, self.ny
            h = np.zeros(self._occ.shape)
            h[pad : pad + nx, pad : pad + ny] = self.grid.heights
            self._heights_flat = h.ravel()
        return self._heights_flat

    @property
    def free_bytes(self) -> bytes:
        """Per padded cell, 1 when a foot centred anywhere in it is surely free (computed once).

        Built on first use: a checker that only tests a few poses (the start feet) never
        needs it.
        """
        if self._free_bytes is None:
            free = surely_free_words(_occupancy_words(self), self._free_m)
            bits = np.unpackbits(free.view(np.uint8), axis=1, bitorder="little")
            self._free_bytes = bits[:, : self.nyp].tobytes()
        return self._free_bytes

    @property
    def rows(self) -> list[int]:
        """Each padded grid row as a Python int: bit j set when cell (i, j) is occupied."""
        if self._rows is None:
            packed = np.packbits(self._occ, axis=1, bitorder="little")
            self._rows = [int.from_bytes(r.tobytes(), "little") for r in packed]
        return self._rows

    @property
    def outer(self) -> list[np.ndarray]:
        """Flat offsets (``di * nyp + dj``) of the outer masks, for the height queries."""
        if self._outer is None:
            self._outer = [di * self.nyp + dj for di, dj in self.masks.outer]
        return self._outer

    def is_free(self, x: float, y: float, yaw: float, *, shortcut: bool = True) -> bool:
        """Whether a foot at ``(x, y, yaw)`` overlaps no occupied cell and lies in the map.

        Args:
            x: sole centre x (m).
            y: sole centre y (m).
            yaw: foot yaw (rad).
            shortcut: use (and build, the first time) the surely-free cells; False tests
                the masks only (the same answer; cheaper for a checker that tests a few
                poses).
        """
        fx = (x - self.x0) * self.inv_res
        fy = (y - self.y0) * self.inv_res
        if not (0.0 <= fx < self.nx and 0.0 <= fy < self.ny):
            return False
        yaw = (yaw + math.pi) % (2.0 * math.pi) - math.pi
        ix, iy = int(fx), int(fy)
        base = (ix + self.pad) * self.nyp + iy + self.pad
        if shortcut and self.free_bytes[base]:
            return True
        if not shortcut:  # the masks read only the (2r + 1)^2 cells around the centre cell
            r, px, py = self.masks.radius_cells, ix + self.pad, iy + self.pad
            if not self._occ[px - r : px + r + 1, py - r : py + r + 1].any():
                return True  # none occupied: the masks' answer, without building rows
        rows = None if shortcut or self._rows is not None else self._rows_near(ix + self.pad)
        return self._check_masks(base, ix, iy, fx - ix, fy - iy, yaw, rows)

    def _rows_near(self, px: int) -> dict[int, int]:
        """Rows ``px - R .. px + R`` (R the masks' radius) as :attr:`rows` gives them.

        A checker that tests a few poses builds only these, not every row.
        """
        r = self.masks.radius_cells
        lo, hi = max(px - r, 0), min(px + r + 1, self._occ.shape[0])
        packed = np.packbits(self._occ[lo:hi], axis=1, bitorder="little")
        return {lo + k: int.from_bytes(row.tobytes(), "little") for k, row in enumerate(packed)}

    def _check_masks(
        self, base: int, ix: int, iy: int, fx: float, fy: float, yaw: float, rows=None
    ) -> bool:
        """Mask test of a foot centred at fraction (fx, fy) of cell (ix, iy); yaw in [-pi, pi).

        ``rows``: the occupancy rows the masks read (default: :attr:`rows`).
        """
        masks = self.masks
        sub = masks.sub
        nb = masks.yaw_bins
        qx = int(fx * sub)
        qy = int(fy * sub)
        m = (
            ((int(yaw * masks.yaw_scale + nb + 0.5) % nb) * sub + (qx if qx < sub else sub - 1))
            * sub
        ) + (qy if qy < sub else sub - 1)
        rows = self.rows if rows is None else rows
        px = ix + self.pad
        shift = iy + self.pad - masks.radius_cells
        for di, bits in masks.outer_rows[m]:
            if (rows[px + di] >> shift) & bits:
                break
        else:
            return True
        for di, bits in masks.inner_rows[m]:
            if (rows[px + di] >> shift) & bits:
                return False
        # occupied cells of the ring: exact separating-axis test for this pose
        R = masks.radius_cells
        c, s, ext_x, ext_y, lim_u, lim_v = sat_limits(yaw, masks.half, self.inv_res)
        eps = SAT_EPS
        for di, bits in masks.ring_rows[m]:
            hit = (rows[px + di] >> shift) & bits
            while hit:
                low = hit & -hit
                hit ^= low
                dj = low.bit_length() - 1 - R
                # cell centre minus foot centre, in cells
                dx = di + 0.5 - fx
                dy = dj + 0.5 - fy
                if (
                    abs(dx) < ext_x - eps
                    and abs(dy) < ext_y - eps
                    and abs(dx * c + dy * s) < lim_u - eps
                    and abs(-dx * s + dy * c) < lim_v - eps
                ):
                    return False
        return True

    def height_range(self, x: float, y: float, yaw: float) -> float:
        """Max minus min height over the cells a foot may overlap (outer mask), 0 without heights.

        The outer mask holds every cell the sole overlaps and may hold a few it only comes
        within about :attr:`FootprintMasks.margin` of, so this is at least the range under
        the sole: a flatness limit on it never accepts a sole whose exact range exceeds the
        limit (and may refuse one at the edge of a step whose exact range is within it).

        Args:
            x: sole centre x (m).
            y: sole centre y (m).
            yaw: foot yaw (rad).
        """
        lo, hi = self.height_bounds(x, y, yaw)
        return hi - lo

    def height_bounds(self, x: float, y: float, yaw: float) -> tuple[float, float]:
        """Min and max height over the cells a foot may overlap (outer mask); 0, 0 without.

        Bounds, not the exact values: the min may be lower and the max higher than under the
        sole itself (see :meth:`height_range`). The highest ground under the sole is
        :meth:`top_height`.

        Args:
            x: sole centre x (m).
            y: sole centre y (m).
            yaw: foot yaw (rad).
        """
        if self.heights_flat is None:
            return 0.0, 0.0
        yaw = (yaw + math.pi) % (2.0 * math.pi) - math.pi
        fx = (x - self.x0) * self.inv_res
        fy = (y - self.y0) * self.inv_res
        ix, iy = int(math.floor(fx)), int(math.floor(fy))
        base = (ix + self.pad) * self.nyp + iy + self.pad
        h = self.heights_flat[base + self.outer[self.masks.index(yaw, fx - ix, fy - iy)]]
        return float(h.min()), float(h.max())

    @property
    def exact_cells(self) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
        """Per mask: flat offsets of the inner cells; flat offsets, ``di``, ``dj`` of the ring.

        Built on first use, for :meth:`top_height`.
        """
        if self._exact_cells is None:
            nyp = self.nyp
            self._exact_cells = [
                (
                    np.asarray(ia, np.int64) * nyp + np.asarray(ib, np.int64),
                    np.asarray(ra, np.int64) * nyp + np.asarray(rb, np.int64),
                    np.asarray(ra, np.int64),
                    np.asarray(rb, np.int64),
                )
                for (ia, ib), (ra, rb) in zip(self.masks.inner, self.masks.ring, strict=True)
            ]
        return self._exact_cells

    def cell_height(self, x: float, y: float) -> float:
        """The height of the grid cell holding the point; 0 without heights (or off the grid).

        The swing line's clearance counts the ground the swing foot lifts from by this value
        at its sole's centre (the compiled twin is ``fastkernels._cell_height``).

        Args:
            x: world x (m).
            y: world y (m).
        """
        if self.heights_flat is None:
            return 0.0
        ix = int(math.floor((x - self.x0) * self.inv_res))
        iy = int(math.floor((y - self.y0) * self.inv_res))
        return float(self.heights_flat[(ix + self.pad) * self.nyp + iy + self.pad])

    def top_height(self, x: float, y: float, yaw: float) -> float:
        """Highest ground under the sole: max height over the cells it overlaps; 0 without.

        The cells are exactly those the sole rectangle overlaps with positive area, decided
        as the collision check decides it: the pose's inner mask, plus each ring cell the
        exact separating-axis test finds overlapped (the same formula and tolerance as
        :meth:`is_free`). The step limits compare this value between two soles (an upper
        bound such as :meth:`height_bounds`' max is not sound for a difference). The
        compiled twin is ``fastkernels._top_height`` (the same value, bit for bit).

        Args:
            x: sole centre x (m).
            y: sole centre y (m).
            yaw: foot yaw (rad).
        """
        if self.heights_flat is None:
            return 0.0
        yaw = (yaw + math.pi) % (2.0 * math.pi) - math.pi
        fx = (x - self.x0) * self.inv_res
        fy = (y - self.y0) * self.inv_res
        ix, iy = int(math.floor(fx)), int(math.floor(fy))
        fx -= ix
        fy -= iy
        base = (ix + self.pad) * self.nyp + iy + self.pad
        inner, ring, ring_di, ring_dj = self.exact_cells[self.masks.index(yaw, fx, fy)]
        hf = self.heights_flat
        top = float(hf[base + inner].max()) if inner.size else -math.inf
        h_ring = hf[base + ring]
        cand = h_ring > top  # only ring cells that would raise the max need the exact test
        if cand.any():
            c, s, ext_x, ext_y, lim_u, lim_v = sat_limits(yaw, self.masks.half, self.inv_res)
            eps = SAT_EPS
            dx = ring_di[cand] + 0.5 - fx  # cell centre minus foot centre, in cells
            dy = ring_dj[cand] + 0.5 - fy
            hit = (
                (np.abs(dx) < ext_x - eps)
                & (np.abs(dy) < ext_y - eps)
                & (np.abs(dx * c + dy * s) < lim_u - eps)
                & (np.abs(-dx * s + dy * c) < lim_v - eps)
            )
            if hit.any():
                top = max(top, float(h_ring[cand][hit].max()))
        return top


def foot_collides_reference(
    grid: OccupancyGrid, pose: "tuple[float, float, float]", foot_length: float, foot_width: float
) -> bool:
    """Slow exact reference: does the foot overlap an occupied cell or leave the map?

    Args:
        grid: the grid.
        pose: ``(x, y, yaw)`` of the sole centre.
        foot_length: sole length (m).
        foot_width: sole width (m).
    """
    if not grid.contains(pose[0], pose[1]):
        return True
    c, s = math.cos(pose[2]), math.sin(pose[2])
    hl, hw = foot_length / 2, foot_width / 2
    corners = [
        (pose[0] + c * u - s * v, pose[1] + s * u + c * v) for u in (-hl, hl) for v in (-hw, hw)
    ]
    sx, sy = grid.size
    x0, y0 = grid.origin
    if any(not (x0 <= px <= x0 + sx and y0 <= py <= y0 + sy) for px, py in corners):
        return True
    centers = grid.cell_centers()[grid.occupied]
    if len(centers) == 0:
        return False
    return bool(
        rect_overlaps_cells(pose[:2], (hl, hw), pose[2], centers, grid.resolution / 2).any()
    )
