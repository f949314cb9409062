"""Grids of moving obstacles mark what the obstacle sweeps over the interval a grid stands for."""

import math

import numpy as np
import pytest
from repertoire.planning.footstep import (
    DynamicEnvironment,
    GridError,
    MovingRectObstacle,
    OccupancyGrid,
    RectObstacle,
)
from repertoire.planning.footstep.environment import (
    rect_overlaps_cells,
    swept_rect_overlaps_cells,
)


def _cells(ix0: int, ix1: int, iy0: int, iy1: int, shape=(120, 120)) -> np.ndarray:
    occ = np.zeros(shape, bool)
    occ[ix0 : ix1 + 1, iy0 : iy1 + 1] = True
    return occ


def test_a_fast_obstacle_marks_the_cells_it_crosses_between_grid_times():
    # a 0.2 m block at 5 m/s: x spans [0.9 + 5t, 1.1 + 5t], y [0.6, 0.8]. Painted at the grid
    # times only (0, 0.1, 0.2 s) it covered [0.9, 1.1], [1.4, 1.6], [1.9, 2.1]: the cells of
    # [1.1, 1.4] (crossed during (0, 0.1) s) were in no grid, so a foot standing there was
    # free in every grid. Grid k stands for [0.1 k - 0.05, 0.1 k + 0.05] s and now marks
    # x in (0.65 + 0.5 k, 1.35 + 0.5 k): cells 26 + 20 k .. 53 + 20 k, rows 24 .. 31.
    block = MovingRectObstacle([1.0, 0.7], [0.2, 0.2], [5.0, 0.0])
    env = DynamicEnvironment.from_moving_obstacles((3.0, 3.0), moving=[block], t_end=0.2)
    assert env.max_time_gap == 0.05
    for k in range(3):
        np.testing.assert_array_equal(
            env.grids[k].occupied, _cells(26 + 20 * k, 53 + 20 * k, 24, 31)
        )
    cell = env.reference.cell_of(1.26, 0.71)  # crossed for t in (0.03, 0.075) s only
    assert cell == (50, 28) and [bool(g.occupied[cell]) for g in env.grids] == [True, True, False]


@pytest.mark.parametrize("yaw", [0.0, 0.3, math.pi / 2])
def test_a_slow_obstacle_grows_by_half_a_grid_interval_of_travel_on_either_side(yaw):
    # moving along its own x axis at v, the rectangle sweeps over [t - dt/2, t + dt/2]
    # exactly the rectangle v dt longer at the same centre: each grid is that static
    # rectangle's, the snapshot's cells plus those within |v| dt / 2 ahead and behind
    v, dt = 0.18, 0.1
    c, s = math.cos(yaw), math.sin(yaw)
    block = MovingRectObstacle([1.0, 1.0], [0.5, 0.2], [v * c, v * s], yaw=yaw, height=0.02)
    env = DynamicEnvironment.from_moving_obstacles(
        (3.0, 3.0), moving=[block], t_end=2.0, dt=dt, with_heights=True
    )
    grew = 0
    for t, g in zip(env.times, env.grids, strict=True):
        center = block.center_at(float(t))
        longer = RectObstacle(center, [0.5 + v * dt, 0.2], yaw, 0.02)
        want = OccupancyGrid.from_rectangles((3.0, 3.0), [longer], with_heights=True)
        snap = OccupancyGrid.from_rectangles((3.0, 3.0), [block.at(float(t))])
        np.testing.assert_array_equal(g.occupied, want.occupied)
        np.testing.assert_array_equal(g.heights, want.heights)
        assert not (snap.occupied & ~g.occupied).any()  # only grown
        grew += int(g.occupied.sum() - snap.occupied.sum())
    assert grew > 0


def test_waypoint_obstacles_sweep_their_polyline_and_still_ones_are_unchanged():
    # a corner at t = 1.0 s (0.6, 0.2) -> (0.6, 0.8) at 0.3 m/s; the grid of 1.0 s covers the
    # 1.5 cm before and after the corner: the union of the two legs' longer rectangles
    path = MovingRectObstacle(
        [0, 0], [0.1, 0.1], waypoints=[[0, 0.3, 0.2], [1, 0.6, 0.2], [3, 0.6, 0.8]]
    )
    still = MovingRectObstacle([2.0, 2.0], [0.3, 0.1], yaw=0.4)
    env = DynamicEnvironment.from_moving_obstacles(
        (3.0, 3.0), moving=[path, still], t_end=1.0, dt=0.1
    )
    legs = [RectObstacle([0.5925, 0.2], [0.115, 0.1]), RectObstacle([0.6, 0.2075], [0.1, 0.115])]
    fixed = RectObstacle([2.0, 2.0], [0.3, 0.1], 0.4)
    want = OccupancyGrid.from_rectangles((3.0, 3.0), [*legs, fixed])
    np.testing.assert_array_equal(env.grids[-1].occupied, want.occupied)
    # held before t = 0, then 1.5 cm along the first leg by 0.05 s
    first = RectObstacle([0.3075, 0.2], [0.115, 0.1])
    start = OccupancyGrid.from_rectangles((3.0, 3.0), [first, fixed])
    np.testing.assert_array_equal(env.grids[0].occupied, start.occupied)


def test_swept_overlap_is_the_hull_of_both_ends():
    # against a dense set of points: a square of side ~0 overlaps the hull iff the point is
    # strictly inside it; a zero-length sweep is the rectangle's own test
    rng = np.random.default_rng(3)
    pts = rng.uniform(-1.0, 2.0, size=(4000, 2))
    a, b, half, yaw = (0.1, 0.2), (1.1, 0.7), (0.3, 0.1), 0.5
    got = swept_rect_overlaps_cells(a, b, half, yaw, pts, 1e-9)
    # inside the hull: some placement along the segment contains the point
    ts = np.linspace(0.0, 1.0, 2001)
    centers = np.asarray(a) + ts[:, None] * (np.asarray(b) - np.asarray(a))
    inside = rect_overlaps_cells(centers, half, yaw, pts, 1e-9).any(axis=0)
    assert (got == inside).mean() > 0.997 and (inside & ~got).sum() == 0
    same = swept_rect_overlaps_cells(a, a, half, yaw, pts, 0.05)
    np.testing.assert_array_equal(same, rect_overlaps_cells(a, half, yaw, pts, 0.05))


def test_a_velocity_beside_waypoints_is_refused_not_ignored():
    # the waypoints set the centre; a velocity given as well was silently dropped
    with pytest.raises(GridError, match=r"velocity \[0.5, 0.0\] is not used with waypoints"):
        MovingRectObstacle([0, 0], [0.1, 0.1], [0.5, 0.0], waypoints=[[0, 0, 0], [1, 1, 0]])
    ok = MovingRectObstacle([0, 0], [0.1, 0.1], [0.0, 0.0], waypoints=[[0, 0, 0], [1, 1, 0]])
    assert ok.center_at(0.5) == [0.5, 0.0]
