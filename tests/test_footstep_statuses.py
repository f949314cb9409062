"""UNREACHABLE only when the lattice is exhausted: refinement against a fine-lattice search."""

import numpy as np
import pytest
from repertoire.planning.footstep import (
    OccupancyGrid,
    PlannerOptions,
    PlanStatus,
    nominal_action_table,
    plan_footsteps,
)
from repertoire.planning.footstep.scenes import stepping_stones_grid
from repertoire.planning.footstep.types import FootstepError

START, GOAL = (0.2, 0.45, 0.0), (1.8, 0.4)


@pytest.mark.parametrize(("seed", "gap"), [(0, 0.10), (4, 0.10), (1, 0.08), (2, 0.06)])
def test_no_unreachable_where_a_fine_lattice_finds_a_plan(seed, gap):
    grid = stepping_stones_grid(seed, gap)
    table = nominal_action_table()
    fine = plan_footsteps(
        grid, START, "left", GOAL, table,
        PlannerOptions(time_limit=20.0, xy_resolution=0.01, yaw_bins=144, refinements=0),
    )  # fmt: skip
    plan = plan_footsteps(grid, START, "left", GOAL, table, PlannerOptions(time_limit=20.0))
    assert fine.status is PlanStatus.SUCCESS
    assert plan.status is PlanStatus.SUCCESS
    coarse = plan_footsteps(
        grid, START, "left", GOAL, table, PlannerOptions(time_limit=20.0, refinements=0)
    )
    assert coarse.xy_resolution == 0.05 and coarse.yaw_bins == 36
    if coarse.status is PlanStatus.UNREACHABLE:  # seeds 0 and 4: the 5 cm lattice merged
        assert (seed, plan.xy_resolution, plan.yaw_bins) in ((0, 0.025, 72), (4, 0.025, 72))
    else:
        assert plan.xy_resolution == 0.05


def test_unreachable_reported_at_the_finest_lattice_tried():
    occ = np.zeros((120, 60), dtype=bool)
    occ[50:90, :] = True  # a 40 cm band across the room: no step crosses it
    grid = OccupancyGrid(occ, 0.01)
    plan = plan_footsteps(
        grid, (0.2, 0.3, 0.0), "left", (1.1, 0.3), nominal_action_table(),
        PlannerOptions(time_limit=20.0, refinements=1),
    )  # fmt: skip
    assert plan.status is PlanStatus.UNREACHABLE
    assert (plan.xy_resolution, plan.yaw_bins) == (0.025, 72)
    assert max(p[0] for p in plan.poses) < 0.5
    with pytest.raises(FootstepError, match="gap must be >= 0 m, got -0.1"):
        stepping_stones_grid(0, -0.1)
    with pytest.raises(FootstepError, match="refinements must be an integer in"):
        PlannerOptions(refinements=7).validate()


def test_maze_grid_is_seeded_and_connected():
    from repertoire.planning.footstep.scenes import maze_grid
    from scipy import ndimage

    a, b = maze_grid(3), maze_grid(3)
    np.testing.assert_array_equal(a.occupied, b.occupied)
    assert not np.array_equal(a.occupied, maze_grid(4).occupied)
    labels, count = ndimage.label(~a.occupied)
    assert count == 1  # every room reachable through 0.5 m doorways
    assert a.shape == (240, 240)
    assert a.occupied[:, 0].all() and a.occupied[0, :].all()  # walled boundary
    with pytest.raises(FootstepError, match="do not fit"):
        maze_grid(0, door=1.2)


def test_swing_clearance_blocks_tall_walls_only():
    from repertoire.planning.footstep import RectObstacle

    wall = OccupancyGrid.from_rectangles((2.0, 1.0), [RectObstacle([1.0, 0.5], [0.05, 1.0])])
    table = nominal_action_table()
    args = ((0.4, 0.595, 0.0), "left", (1.6, 0.5), table)
    opts = PlannerOptions(time_limit=20.0, swing_clearance=0.1, refinements=1)
    for height, status in ((0.5, PlanStatus.UNREACHABLE), (0.05, PlanStatus.SUCCESS)):
        grid = OccupancyGrid(wall.occupied, wall.resolution, wall.origin, height * wall.occupied)
        plan = plan_footsteps(grid, *args, opts)
        assert plan.status is status, height
        if status is PlanStatus.UNREACHABLE:
            assert max(p[0] for p in plan.poses) < 1.0  # never past the wall
    # without a clearance (the default) the 5 cm thick wall of any height is stepped over
    tall = OccupancyGrid(wall.occupied, wall.resolution, wall.origin, 0.5 * wall.occupied)
    assert plan_footsteps(tall, *args, PlannerOptions(time_limit=20.0)).succeeded
    with pytest.raises(FootstepError, match=r"cell \(0, 0\) is -0.2 m"):
        OccupancyGrid(wall.occupied, wall.resolution, wall.origin, -0.2 * np.ones(wall.shape))
    with pytest.raises(FootstepError, match=r"cell \(0, 0\) is nan"):
        OccupancyGrid(wall.occupied, wall.resolution, wall.origin, np.full(wall.shape, np.nan))
    with pytest.raises(FootstepError, match="swing_clearance must be > 0 m, got -1"):
        PlannerOptions(swing_clearance=-1.0).validate()


def test_landing_only_on_flat_enough_ground():
    occ = np.zeros((80, 40), dtype=bool)
    heights = np.zeros((80, 40))
    heights[30:50, :] = np.linspace(0.0, 0.3, 40)[None, :]  # a steep ramp band across y
    occ_grid = OccupancyGrid(occ, 0.025, (0.0, 0.0), heights)
    table = nominal_action_table()
    opts = PlannerOptions(time_limit=20.0, max_height_range=0.01, refinements=0)
    plan = plan_footsteps(occ_grid, (0.2, 0.5, 0.0), "left", (1.8, 0.5), table, opts)
    assert plan.status is PlanStatus.UNREACHABLE  # the 0.5 m band is too wide to step over
    xs = [p[0] for p in plan.poses]
    assert max(xs) < 0.75 + 0.08 + 0.025  # no sole centre on the ramp band x in [0.75, 1.25]
    flat = PlannerOptions(time_limit=20.0)
    assert plan_footsteps(occ_grid, (0.2, 0.5, 0.0), "left", (1.8, 0.5), table, flat).succeeded
    with pytest.raises(FootstepError, match="start at \\(1.000, 0.500\\) stands on ground too"):
        plan_footsteps(occ_grid, (1.0, 0.5, 0.0), "left", (1.8, 0.5), table, opts)
