"""Robustness round 4: valid but unusual inputs and bad inputs on the public footstep API."""

import math
import time

import numpy as np
import pytest
from repertoire.planning.footstep import (
    ActionTable,
    ActionTableError,
    BipedGeometry,
    DynamicEnvironment,
    FootstepError,
    FootstepPlan,
    GridError,
    MovingRectObstacle,
    OccupancyGrid,
    PlannerOptions,
    PlanStatus,
    RectObstacle,
    nominal_action_table,
    plan_footsteps,
    plan_footsteps_anytime,
    plan_mobile2d,
    plan_receding_horizon,
)
from repertoire.planning.footstep.corridor import corridor_grid
from repertoire.planning.footstep.quadruped import CrawlParams, HeightMap, plan_crawl
from repertoire.planning.footstep.scenes import random_static_scene
from repertoire.planning.littledog_crawl import nominal_foot_positions

from repertoire.limits import ResourceLimitError


def _grid() -> OccupancyGrid:
    return OccupancyGrid.from_rectangles((2.0, 1.0), [RectObstacle([1.0, 0.5], [0.1, 0.4])])


@pytest.mark.parametrize("backend", ["python", "compiled"])
def test_numpy_integer_options_plan_as_python_integers(backend):
    grid, table = _grid(), nominal_action_table()
    ints = PlannerOptions(
        backend=backend, yaw_bins=np.int64(36), max_expansions=np.int64(100000),
        refinements=np.int32(2), time_limit=np.float32(5.0),
    )  # fmt: skip
    plain = PlannerOptions(backend=backend, max_expansions=100000, refinements=2, time_limit=5.0)
    a = plan_footsteps(grid, (0.3, 0.5, 0.0), "left", (1.6, 0.5), table, ints)
    b = plan_footsteps(grid, (0.3, 0.5, 0.0), "left", (1.6, 0.5), table, plain)
    assert a.status is PlanStatus.SUCCESS
    assert a.poses == b.poses and a.actions == b.actions and a.cost == b.cost


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"foot_length": -0.1}, "foot_length must be finite and > 0 m, got -0.1"),
        ({"foot_width": float("nan")}, "foot_width must be finite and > 0 m, got nan"),
        ({"foot_length": 0.0}, "foot_length must be finite and > 0 m, got 0.0"),
        ({"stance_width": -0.19}, "stance_width must be finite and >= 0 m, got -0.19"),
        ({"body_radius": "0.3"}, "body_radius must be finite and >= 0 m, got '0.3'"),
    ],
)
def test_bad_geometry_is_refused(kwargs, message):
    with pytest.raises(FootstepError, match=message):
        BipedGeometry(**kwargs)


def test_bad_step_model_arguments_name_the_value():
    grid, table = _grid(), nominal_action_table()
    args = (grid, (0.3, 0.5, 0.0), "left", (1.6, 0.5), table)
    with pytest.raises(FootstepError, match="geometry must be a BipedGeometry, got None"):
        plan_footsteps(*args, geometry=None)
    with pytest.raises(
        FootstepError, match="start_time must be a finite number of seconds, got '0'"
    ):
        plan_footsteps(*args, start_time="0")
    with pytest.raises(FootstepError, match="action_filter must return a sequence of action names"):
        plan_footsteps(*args, action_filter=lambda a2, a1, foot: None)
    with pytest.raises(FootstepError, match=r"unknown actions \[1, 'fly'\]"):
        plan_footsteps(*args, action_filter=lambda a2, a1, foot: ["stop", "fly", 1])


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"origin": (1.0,)}, r"origin must be 2 finite numbers \(x0, y0\), got \(1.0,\)"),
        ({"origin": (1.0, 2.0, 3.0)}, r"origin must be 2 finite numbers .*got \(1.0, 2.0, 3.0\)"),
        ({"origin": None}, "origin must be 2 finite numbers .*got None"),
        ({"resolution": "0.1"}, "resolution must be a positive number of metres, got '0.1'"),
        ({"resolution": True}, "resolution must be a positive number of metres, got True"),
        ({"heights": "abc"}, "heights must be an array of numbers, got 'abc'"),
        ({"occupied": np.full((5, 5), np.nan)}, "occupied must hold booleans or finite numbers"),
        ({"occupied": [[1, 0], [0, "x"]]}, "occupied must hold booleans or finite numbers"),
    ],
)
def test_bad_grid_is_refused(kwargs, message):
    args = {"occupied": np.zeros((5, 5), bool), "resolution": 0.1, **kwargs}
    with pytest.raises(GridError, match=message):
        OccupancyGrid(**args)


def test_grid_accepts_numeric_occupancy_and_numpy_origin():
    grid = OccupancyGrid(np.array([[0, 255], [0.0, 1]]), np.float64(0.1), np.array([1, -2]))
    assert grid.occupied.tolist() == [[False, True], [False, True]]
    assert grid.origin == (1.0, -2.0) and isinstance(grid.origin[0], float)


def test_empty_grid_refuses_sizes_below_one_cell_and_bad_origins():
    with pytest.raises(GridError, match=r"size \(2, 1\) m holds no whole cell of 10.0 m"):
        OccupancyGrid.empty((2, 1), 10.0)
    with pytest.raises(GridError, match=r"origin must be 2 finite numbers .*got \(0,\)"):
        OccupancyGrid.empty((2, 1), 0.1, (0,))
    with pytest.raises(GridError, match="size must be two positive lengths, got None"):
        OccupancyGrid.empty(None, 0.1)
    with pytest.raises(GridError, match="resolution must be positive, got '0.1'"):
        OccupancyGrid.empty((2, 1), "0.1")


def test_dynamic_environment_checks_memory_before_making_times():
    mover = MovingRectObstacle(center=[1.0, 1.0], size=[0.2, 0.2])
    with pytest.raises(ResourceLimitError, match="about 1000000000001 grids of 120 x 80"):
        DynamicEnvironment.from_moving_obstacles((3.0, 2.0), moving=[mover], t_end=1e9, dt=1e-3)


def test_bad_table_arrays_and_mirror_are_named():
    n = 2
    good = {
        "actions": ["a", "b"],
        "displacement": np.zeros((n, n, 2, n, 3)),
        "duration": np.ones((n, n, 2, n)),
        "step_cost": np.ones(n),
        "rest_action": "a",
    }
    with pytest.raises(ActionTableError, match="displacement must be an array of numbers"):
        ActionTable(**{**good, "displacement": [[1, 2], [3]]})
    with pytest.raises(
        ActionTableError, match=r"duration must be an array of numbers \(ragged .*\), got .x."
    ):
        ActionTable(**{**good, "duration": "x"})
    with pytest.raises(ActionTableError, match=r"mirror must be a dict of name -> name, got \["):
        ActionTable(**good, mirror=[("a", "b")])
    with pytest.raises(ActionTableError, match="actions must be a list of names, got 'ab'"):
        ActionTable(**{**good, "actions": "ab"})
    data = nominal_action_table().to_dict()
    with pytest.raises(ActionTableError, match=r"mirror must be a dict of name -> name, got \[1"):
        ActionTable.from_dict({**data, "mirror": [1, 2]})
    with pytest.raises(ActionTableError, match="ragged or non-numeric"):
        ActionTable.from_dict({**data, "step_cost": "abc"})


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"execute_steps": float("nan")}, "execute_steps must be an integer >= 1, got nan"),
        ({"execute_steps": "2"}, "execute_steps must be an integer >= 1, got '2'"),
        ({"max_rounds": float("inf")}, "max_rounds must be an integer >= 1, got inf"),
        ({"max_rounds": True}, "max_rounds must be an integer >= 1, got True"),
    ],
)
def test_receding_bad_counts_are_named(kwargs, message):
    with pytest.raises(FootstepError, match=message):
        plan_receding_horizon(
            _grid(), (0.3, 0.5, 0.0), "left", (1.6, 0.5), nominal_action_table(),
            PlannerOptions(), **kwargs,
        )  # fmt: skip


def test_mobile2d_bad_inputs_are_named():
    grid = _grid()
    with pytest.raises(FootstepError, match=r"start must be \(x, y\) numbers, got \(0.4,\)"):
        plan_mobile2d(grid, (0.4,), (1.6, 0.5), 0.3)
    with pytest.raises(FootstepError, match=r"goal must be \(x, y\) numbers, got None"):
        plan_mobile2d(grid, (0.4, 0.5), None, 0.3)
    with pytest.raises(FootstepError, match="radius must be a number >= 0 .*got '0.3'"):
        plan_mobile2d(grid, (0.4, 0.5), (1.6, 0.5), "0.3")
    with pytest.raises(FootstepError, match="grid must be an OccupancyGrid, got NoneType"):
        plan_mobile2d(None, (0.4, 0.5), (1.6, 0.5), 0.3)
    plan = plan_mobile2d(grid, np.array([0.4, 0.5]), (1.6, 0.5), 0.0)
    assert plan.status is PlanStatus.SUCCESS


def test_crawl_flatness_radius_wider_than_the_map_is_the_map_range():
    heights = np.zeros((61, 101))
    heights[0, 0] = 0.01
    hm = HeightMap(origin=(-0.3, -0.3), resolution=0.01, heights=heights)
    assert np.array_equal(hm.roughness(1e9), np.full((61, 101), 0.01))
    small = HeightMap(origin=(0.0, 0.0), resolution=0.01, heights=heights[:7, :12])
    near = small.roughness(math.hypot(0.06, 0.11) - 1e-6)  # just short of the diagonal
    assert near[0, 0] == 0.01 and near[-1, -1] == 0.0
    assert np.array_equal(small.roughness(math.hypot(0.06, 0.11)), np.full((7, 12), 0.01))
    start = nominal_foot_positions()[:, :2]
    with pytest.raises(FootstepError, match="on ground too steep"):
        plan_crawl(hm, start, (0.2, 0.0), CrawlParams(flat_radius=1e9, max_roughness=0.005))


def test_corridor_wider_than_the_map_keeps_the_map_quickly():
    grid = OccupancyGrid.from_rectangles((3.0, 2.0), [RectObstacle([1.5, 1.0], [0.3, 1.0])])
    wide = corridor_grid(grid, [(0.4, 1.0), (2.6, 1.0)], 1e3)  # was a 47.7 GiB MemoryError
    assert np.array_equal(wide.occupied, grid.occupied)
    far = corridor_grid(grid, [(50.01, 1.01)], 47.45)  # one point off the map: cell (2000, 40)
    di, dj = np.meshgrid(np.arange(120) - 2000, np.arange(80) - 40, indexing="ij")
    keep = (di * di + dj * dj) * 0.025**2 <= 47.45**2
    assert 0 < keep.sum() < keep.size
    assert np.array_equal(far.occupied, grid.occupied | ~keep)
    t0 = time.perf_counter()
    plans = plan_footsteps_anytime(
        grid,
        (0.4, 1.0, 0.0),
        "left",
        (2.6, 1.0),
        nominal_action_table(),
        PlannerOptions(time_limit=0.5),
        corridor=50.0,
    )  # fmt: skip (was 87 s with a 0.5 s limit)
    assert time.perf_counter() - t0 < 2.0
    assert plans[0].plan.status is PlanStatus.SUCCESS


def test_corridor_bad_points_are_named():
    grid = OccupancyGrid.empty((1.0, 1.0))
    with pytest.raises(FootstepError, match=r"corridor points must be \(x, y, \.\.\.\) numbers"):
        corridor_grid(grid, [(0.4,)], 0.3)
    with pytest.raises(FootstepError, match=r"corridor points must be finite, got \[inf"):
        corridor_grid(grid, [(0.4, 0.5), (math.inf, 0.5)], 0.3)
    with pytest.raises(ResourceLimitError, match="samples of a 2-point corridor polyline"):
        corridor_grid(grid, [(0.4, 0.5), (1e12, 0.5)], 0.3)


@pytest.mark.parametrize("seed", [-1, 1.5, None, "x", True])
def test_scene_seeds_must_be_integers(seed):
    with pytest.raises(FootstepError, match=f"a scene seed must be an integer >= 0, got {seed!r}"):
        random_static_scene(seed)
    assert random_static_scene(np.int64(3)).start == random_static_scene(3).start


def test_table_and_plan_files_that_are_not_json_name_the_file(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(ActionTableError, match=r"bad.json is not valid JSON"):
        ActionTable.load(bad)
    with pytest.raises(FootstepError, match=r"bad.json is not valid JSON"):
        FootstepPlan.load(bad)
    with pytest.raises(FootstepError, match=r"nope.json does not exist"):
        FootstepPlan.load(tmp_path / "nope.json")
    (tmp_path / "list.json").write_text("[1, 2]")
    with pytest.raises(FootstepError, match=r"list.json must hold a JSON object, got list"):
        FootstepPlan.load(tmp_path / "list.json")
    plan = plan_footsteps(_grid(), (0.3, 0.5, 0.0), "left", (0.3, 0.5), nominal_action_table())
    with pytest.raises(FootstepError, match=r"plan status 'DONE' is not one of \['SUCCESS'"):
        FootstepPlan.from_dict({**plan.to_dict(), "status": "DONE"})
    assert FootstepPlan.from_dict(plan.to_dict()) == plan


def test_options_of_another_type_are_named():
    args = (_grid(), (0.3, 0.5, 0.0), "left", (1.6, 0.5), nominal_action_table())
    with pytest.raises(FootstepError, match="options must be PlannerOptions, got dict"):
        plan_footsteps(*args, {"time_limit": 1.0})
    with pytest.raises(FootstepError, match="options must be PlannerOptions, got dict"):
        plan_footsteps_anytime(*args, {"time_limit": 1.0})
