"""Footstep planner: the footprint checker (exact reference, surely-free table, margins)."""

import math

import numpy as np
import pytest
from repertoire.planning.footstep import (
    FootstepError,
    OccupancyGrid,
    PlannerOptions,
    RectObstacle,
    nominal_action_table,
    plan_footsteps,
)
from repertoire.planning.footstep.footprint import (
    FootprintChecker,
    foot_collides_reference,
    footprint_masks,
)


def test_footprint_checker_matches_exact_reference():
    rng = np.random.default_rng(3)
    rects = [
        RectObstacle(
            list(rng.uniform(0, 2, 2)), list(rng.uniform(0.02, 0.4, 2)), float(rng.uniform(-3, 3))
        )
        for _ in range(15)
    ]
    grid = OccupancyGrid.from_rectangles((2.0, 2.0), rects)
    chk = FootprintChecker(grid, footprint_masks(0.16, 0.10, 0.025))
    poses = np.column_stack(
        [rng.uniform(-0.05, 2.05, 1500), rng.uniform(-0.05, 2.05, 1500), rng.uniform(-4, 4, 1500)]
    )
    fast = [chk.is_free(*p) for p in poses]
    ref = [not foot_collides_reference(grid, p, 0.16, 0.10) for p in poses]
    assert fast == ref
    assert [chk.is_free(p[0], p[1], p[2] - 4 * math.pi) for p in poses[:300]] == ref[:300]
    assert 0.2 < np.mean(ref) < 0.9  # both outcomes are exercised
    # a foot exactly between two obstacles whose edges it touches is free (no circle test)
    g = OccupancyGrid.from_rectangles(
        (1.0, 1.0), [RectObstacle([0.5, 0.4], [0.4, 0.1]), RectObstacle([0.5, 0.6], [0.4, 0.1])]
    )
    chk2 = FootprintChecker(g, footprint_masks(0.16, 0.10, 0.025))
    assert chk2.is_free(0.5, 0.5, 0.0)  # sole spans y in [0.45, 0.55] exactly
    assert not chk2.is_free(0.5, 0.5, 0.05)  # a slight turn hits both
    assert not chk2.is_free(0.5, 0.5, math.pi / 2)


def _row_bits_reference(di, dj, big_r):
    """One mask's cells as (row offset, bits of column offset + R), one cell at a time."""
    rows = {}
    for i, j in zip(di.tolist(), dj.tolist(), strict=True):
        rows[i] = rows.get(i, 0) | (1 << (j + big_r))
    return tuple(sorted(rows.items()))


@pytest.mark.parametrize(
    "geometry",
    [
        (0.16, 0.10, 0.025, 72, 4),
        (0.16, 0.12, 0.05, 36, 4),
        (0.10, 0.06, 0.02, 16, 2),
        (0.26, 0.10, 0.004, 8, 2),  # 77 cells wide: rows need more than one 62-bit chunk
    ],
)
def test_footprint_masks_equal_the_per_mask_separating_axis_test(geometry):
    """The masks, built for all sub-cell centres of a yaw in one call, are exactly the ones
    ``rect_overlaps_cells`` gives for each centre alone, and their row bits and 64-bit words the
    ones packed cell by cell."""
    from repertoire.planning.footstep.environment import rect_overlaps_cells
    from repertoire.planning.footstep.fastkernels import _cached_mask_bits

    length, width, res, bins, sub = geometry
    masks = footprint_masks(length, width, res, bins, sub)
    big_r = masks.radius_cells
    di, dj = (a.ravel() for a in np.meshgrid(*[np.arange(-big_r, big_r + 1)] * 2, indexing="ij"))
    centers = np.stack([(di + 0.5) * res, (dj + 0.5) * res], axis=1)
    hl, hw, e = length / 2, width / 2, masks.margin
    for m in range(0, bins * sub * sub, 7):
        yb, q = divmod(m, sub * sub)
        c = ((q // sub + 0.5) / sub * res, (q % sub + 0.5) / sub * res)
        yaw = yb * 2.0 * math.pi / bins
        out = rect_overlaps_cells(c, (hl + e, hw + e), yaw, centers, res / 2)
        inn = rect_overlaps_cells(c, (max(hl - e, 0), max(hw - e, 0)), yaw, centers, res / 2)
        for got, want, rows in (
            (masks.outer[m], out, masks.outer_rows[m]),
            (masks.inner[m], inn, masks.inner_rows[m]),
            (masks.ring[m], out & ~inn, masks.ring_rows[m]),
        ):
            np.testing.assert_array_equal(got[0], di[want])
            np.testing.assert_array_equal(got[1], dj[want])
            assert rows == _row_bits_reference(di[want], dj[want], big_r)
    if 2 * big_r + 1 > 64:  # the columns past the first chunk are used, and joined right
        assert any(b >= 1 << 62 for rows in masks.outer_rows for _, b in rows)
    else:
        bits, spans = _cached_mask_bits(masks)
        for m in range(0, len(masks.inner), 5):
            for k, part in ((0, masks.inner[m]), (1, masks.ring[m])):
                want = np.zeros(2 * big_r + 1, np.uint64)
                for i, j in zip(part[0].tolist(), part[1].tolist(), strict=True):
                    want[i + big_r] |= np.uint64(1) << np.uint64(j + big_r)
                np.testing.assert_array_equal(bits[m, :, k], want)
            used = np.flatnonzero(bits[m].any(axis=1))
            assert tuple(spans[m]) == ((used[0], used[-1] + 1) if used.size else (0, 0))


def test_surely_free_cells_equal_a_brute_force_window_count():
    from repertoire.planning.footstep.footprint import surely_free_words

    rng = np.random.default_rng(11)
    for trial in range(40):
        nx, ny = (int(v) for v in rng.integers(1, 150, 2))  # rows of 1 to 3 words
        res = float(rng.choice([0.01, 0.025, 0.05]))
        grid = OccupancyGrid(rng.random((nx, ny)) < rng.choice([0.0, 0.02, 0.2]), res)
        chk = FootprintChecker(grid, footprint_masks(0.16, 0.10, res))
        occ, m = chk._occ, chk._free_m
        assert m < chk.pad  # the occupied border is wider than the window
        want = np.zeros(occ.shape, np.uint8)
        windows = np.lib.stride_tricks.sliding_window_view(occ, (2 * m + 1, 2 * m + 1))
        want[m : occ.shape[0] - m, m : occ.shape[1] - m] = ~windows.any(axis=(2, 3))
        got = np.frombuffer(chk.free_bytes, np.uint8).reshape(occ.shape)
        np.testing.assert_array_equal(got, want, err_msg=f"trial {trial}")
    # one occupied cell in a free 3-word row: exactly its (2m + 1)^2 window is not free
    words = np.zeros((9, 3), np.uint64)
    words[4, 1] = np.uint64(1) << np.uint64(1)  # cell (4, 65)
    free = np.unpackbits(surely_free_words(words, 2).view(np.uint8), axis=1, bitorder="little")
    blocked = np.argwhere(free == 0)
    assert blocked[:, 0].min() == 2 and blocked[:, 0].max() == 6
    assert blocked[:, 1].min() == 63 and blocked[:, 1].max() == 67 and len(blocked) == 25
    # a window wider than a word (dilated in passes of at most 63 cells)
    words = np.zeros((3, 4), np.uint64)
    words[1, 2] = np.uint64(1) << np.uint64(10)  # cell (1, 138)
    free = np.unpackbits(surely_free_words(words, 100).view(np.uint8), axis=1, bitorder="little")
    assert (free[:, 38:239] == 0).all() and free[:, :38].all() and free[:, 239:].all()


def _foot_to_cells_distance(grid: OccupancyGrid, pose, foot_length: float, foot_width: float):
    """Euclidean distance (m) from the foot rectangle to the nearest occupied cell square."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    hl, hw = foot_length / 2, foot_width / 2
    foot = [
        (pose[0] + c * u - s * v, pose[1] + s * u + c * v)
        for u, v in ((-hl, -hw), (hl, -hw), (hl, hw), (-hl, hw))
    ]
    h = grid.resolution / 2

    def point_segment(p, a, b):
        ab = np.subtract(b, a)
        t = np.clip(np.dot(np.subtract(p, a), ab) / np.dot(ab, ab), 0.0, 1.0)
        return float(np.hypot(*(np.subtract(p, a) - t * ab)))

    best = math.inf
    for cx, cy in grid.cell_centers()[grid.occupied]:
        if math.hypot(cx - pose[0], cy - pose[1]) > math.hypot(hl, hw) + 2 * grid.resolution:
            continue
        cell = [(cx - h, cy - h), (cx + h, cy - h), (cx + h, cy + h), (cx - h, cy + h)]
        # separated convex polygons: the distance is attained at a vertex of one of them
        for p_set, q_set in ((foot, cell), (cell, foot)):
            for p in p_set:
                for i in range(4):
                    best = min(best, point_segment(p, q_set[i], q_set[(i + 1) % 4]))
    return best


@pytest.mark.parametrize("margin", [0.0, 0.01, 0.03])
def test_footprint_margin_keeps_clearance_from_obstacles(margin):
    from repertoire.planning.footstep.scenes import random_static_scene

    sc = random_static_scene(3)
    opts = PlannerOptions(footprint_margin_m=margin, time_limit=30)
    plan = plan_footsteps(sc.grid, sc.start, sc.start_foot, sc.goal, nominal_action_table(), opts)
    assert plan.succeeded
    assert all(not foot_collides_reference(sc.grid, p, 0.16, 0.10) for p in plan.poses[1:])
    closest = min(_foot_to_cells_distance(sc.grid, p, 0.16, 0.10) for p in plan.poses[1:])
    if margin > 0.0:
        assert closest >= margin - 1e-9
    else:  # the exact check: a landing passes within millimetres of an obstacle (3.5 mm here)
        assert closest < 0.01
    assert PlannerOptions().footprint_margin_m == 0.01  # the default keeps 1 cm
    with pytest.raises(FootstepError, match="footprint_margin_m must be finite and >= 0"):
        PlannerOptions(footprint_margin_m=-0.01).validate()
