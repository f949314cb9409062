"""Terrain boards: the exact height function agrees with Drake's geometry of the boxes."""

import math

import numpy as np
import pytest
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.systems.framework import DiagramBuilder
from repertoire.models.terrain import (
    BOARD_KINDS,
    MAX_ROCK_COVERAGE,
    TerrainBoard,
    TerrainBox,
    TerrainParams,
    generate_board,
    rock_coverage,
    rock_field,
)

from repertoire.errors import RepertoireError

N_PROBES = 1000


def _query_object(board: TerrainBoard, *, sdf_path=None):
    """A SceneGraph QueryObject holding only the board (from the plant or from its SDF).

    Returns ``(diagram, context, query_object)``: the QueryObject refers to the
    context, so the caller must keep all three alive while querying.
    """
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, 0.001)
    if sdf_path is None:
        board.add_to_plant(plant)
    else:
        Parser(plant).AddModels(str(sdf_path))
    plant.Finalize()
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    query_object = scene_graph.get_query_output_port().Eval(
        scene_graph.GetMyContextFromRoot(context)
    )
    return diagram, context, query_object


def _ray_cast_heights(query_object, xy: np.ndarray, z_low=-0.05, z_high=0.3) -> np.ndarray:
    """Heights of the first surface hit by vertical rays cast down at each (x, y).

    Each column of the board is solid from the ground up to its surface, so the
    surface is where the minimum signed distance of the point (x, y, z) to all
    geometries changes sign; bisection on z finds it to 1e-10 m.
    """

    def inside(x, y, z):
        hits = query_object.ComputeSignedDistanceToPoint(np.array([x, y, z]), threshold=0.01)
        return any(h.distance <= 0.0 for h in hits)

    heights = np.empty(len(xy))
    for k, (x, y) in enumerate(xy):
        lo, hi = z_low, z_high
        assert inside(x, y, lo) and not inside(x, y, hi)
        while hi - lo > 1e-10:
            mid = 0.5 * (lo + hi)
            if inside(x, y, mid):
                lo = mid
            else:
                hi = mid
        heights[k] = 0.5 * (lo + hi)
    return heights


def _probe_points(board: TerrainBoard, seed: int) -> np.ndarray:
    """Seeded random points over the board and a 0.1 m margin of ground around it."""
    rng = np.random.default_rng(seed)
    half_x = 0.5 * board.params.size_x + 0.1
    half_y = 0.5 * board.params.size_y + 0.1
    return rng.uniform([-half_x, -half_y], [half_x, half_y], size=(N_PROBES, 2))


@pytest.mark.parametrize("kind", BOARD_KINDS)
def test_height_function_agrees_with_drake_geometry(kind, tmp_path):
    board = generate_board(TerrainParams(kind=kind), seed=11)
    xy = _probe_points(board, seed=100 + BOARD_KINDS.index(kind))
    expected = board.height(xy[:, 0], xy[:, 1])
    diagram, context, query_object = _query_object(board)
    measured = _ray_cast_heights(query_object, xy)
    np.testing.assert_allclose(measured, expected, atol=1e-8)
    # The SDF file describes the same terrain.
    sdf = board.write_sdf(tmp_path / f"{kind}.sdf")
    diagram_sdf, context_sdf, query_object_sdf = _query_object(board, sdf_path=sdf)
    measured_sdf = _ray_cast_heights(query_object_sdf, xy[:200])
    np.testing.assert_allclose(measured_sdf, expected[:200], atol=1e-8)
    # The probes saw the ground, the slab and (rocks, steps, mixed) higher tops.
    levels = np.unique(np.round(expected, 9))
    assert len(levels) >= (2 if kind in ("flat", "gaps") else 3)


def test_flat_board_closed_form():
    params = TerrainParams(kind="flat", size_x=0.6, size_y=0.4, base_thickness=0.05)
    board = generate_board(params, seed=0)
    assert len(board.boxes) == 1
    x, y = np.meshgrid(np.linspace(-0.505, 0.505, 101), np.linspace(-0.505, 0.505, 51))
    z = board.height(x, y)
    assert z.shape == (51, 101)
    on_board = (np.abs(x) <= 0.3) & (np.abs(y) <= 0.2)
    np.testing.assert_array_equal(z[on_board], 0.05)
    np.testing.assert_array_equal(z[~on_board], 0.0)
    assert board.height(0.0, 0.0) == 0.05
    assert board.max_height() == 0.05


def test_gaps_go_down_to_the_ground():
    params = TerrainParams(kind="gaps", gap_count=3)
    board = generate_board(params, seed=5)
    slabs = sorted(board.boxes, key=lambda b: b.center[0])
    assert len(slabs) == 4
    for left, right in zip(slabs, slabs[1:]):
        gap_lo = left.center[0] + 0.5 * left.size[0]
        gap_hi = right.center[0] - 0.5 * right.size[0]
        assert params.gap_width[0] - 1e-12 <= gap_hi - gap_lo <= params.gap_width[1] + 1e-12
        xs = np.linspace(gap_lo + 1e-6, gap_hi - 1e-6, 20)
        np.testing.assert_array_equal(board.height(xs, 0.1), 0.0)
    assert slabs[0].center[0] - 0.5 * slabs[0].size[0] == pytest.approx(-0.3)
    assert slabs[-1].center[0] + 0.5 * slabs[-1].size[0] == pytest.approx(0.3)


def test_rocks_stay_on_the_board_and_stand_on_the_ground():
    params = TerrainParams(kind="rocks", rock_count=40)
    board = generate_board(params, seed=2)
    rocks = [b for b in board.boxes if b.label == "rock"]
    assert len(rocks) == 40
    _assert_rocks_inside(rocks, params, -0.3, 0.3)


def _assert_rocks_inside(rocks, params, x0, x1):
    """Every rock's footprint lies in [x0, x1] x the board's width; it stands on the ground."""
    half_y = 0.5 * params.size_y
    for rock in rocks:
        c, s = math.cos(rock.yaw), math.sin(rock.yaw)
        for u in (-0.5, 0.5):
            for v in (-0.5, 0.5):
                x = rock.center[0] + c * u * rock.size[0] - s * v * rock.size[1]
                y = rock.center[1] + s * u * rock.size[0] + c * v * rock.size[1]
                assert x0 - 1e-12 <= x <= x1 + 1e-12 and abs(y) <= half_y + 1e-12
        assert rock.center[2] - 0.5 * rock.size[2] == pytest.approx(0.0, abs=1e-15)
        height = rock.top - params.base_thickness
        assert params.rock_height[0] <= height <= params.rock_height[1]


@pytest.mark.parametrize("coverage", [0.3, 0.8])
def test_rock_field_reaches_its_coverage(coverage):
    params = TerrainParams(kind="rocks", size_x=0.8, size_y=0.8)
    x0, x1 = 0.05, 0.4
    boxes = rock_field(x0, x1, params, seed=4, coverage=coverage)
    slab = boxes[0]
    assert slab.label == "slab" and slab.yaw == 0.0
    np.testing.assert_allclose(slab.center + slab.size, [0.225, 0.0, 0.02, 0.35, 0.8, 0.04])
    rocks = boxes[1:]
    assert {b.label for b in rocks} == {"rock"}
    _assert_rocks_inside(rocks, params, x0, x1)
    # Coverage measured independently: the exact height above the slab on a 2 mm grid.
    board = TerrainBoard(params=params, seed=4, boxes=boxes)
    x, y = np.meshgrid(np.arange(x0 + 1e-3, x1, 2e-3), np.arange(-0.4 + 1e-3, 0.4, 2e-3))
    reached = float(np.mean(board.height(x, y) > params.base_thickness))
    # At least the target (up to the 5 mm measuring grid), at most one largest rock more.
    one_rock = params.rock_size[1] ** 2 / ((x1 - x0) * params.size_y)
    assert coverage - 0.01 <= reached <= coverage + one_rock + 0.01
    assert rock_coverage(rocks, x0, x1, params.size_y) == pytest.approx(reached, abs=0.01)
    # The last rock was needed: without it the field is below the target.
    assert rock_coverage(rocks[:-1], x0, x1, params.size_y) < coverage


def test_rock_field_is_deterministic_per_seed_and_bare_at_zero():
    params = TerrainParams(kind="rocks")
    a = rock_field(-0.3, 0.3, params, seed=8, coverage=0.5)
    assert a == rock_field(-0.3, 0.3, params, seed=8, coverage=0.5)
    assert a != rock_field(-0.3, 0.3, params, seed=9, coverage=0.5)
    assert rock_field(-0.3, 0.3, params, seed=8, coverage=0.0) == [a[0]]


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(coverage=-0.1), r"coverage must be a fraction in \[0, 0.9\], got -0.1"),
        (dict(coverage=MAX_ROCK_COVERAGE + 0.01), "got 0.91"),
        (dict(coverage=math.nan), "got nan"),
        (dict(x0=0.2, x1=0.1), r"x0 < x1, got \[0.2, 0.1\]"),
        (dict(seed=1.5), "seed must be an integer, got 1.5"),
    ],
)
def test_rock_field_bad_input(kwargs, match):
    args = dict(x0=-0.3, x1=0.3, p=TerrainParams(kind="rocks"), seed=0) | kwargs
    with pytest.raises(RepertoireError, match=match):
        rock_field(**args)


def test_steps_bands_cover_the_board():
    board = generate_board(TerrainParams(kind="steps", step_count=5), seed=9)
    assert len(board.boxes) == 6
    assert board.boxes[0].top == pytest.approx(0.04)
    tops = [b.top for b in board.boxes]
    assert min(tops) >= 0.04 - 1e-15
    rises = np.abs(np.diff(tops))
    assert np.all((rises >= 0.015 - 1e-12) | (rises < 1e-15))
    np.testing.assert_allclose(sum(b.size[0] for b in board.boxes), 0.6)


def test_mixed_board_starts_flat():
    board = generate_board(TerrainParams(kind="mixed", mixed_sections=4), seed=1)
    xs = np.linspace(-0.3, -0.15, 30)
    np.testing.assert_array_equal(board.height(xs, 0.0), 0.04)
    labels = {b.label for b in board.boxes}
    assert "slab" in labels


def test_same_seed_same_board_other_seed_other_board():
    params = TerrainParams(kind="mixed")
    a, b = generate_board(params, seed=3), generate_board(params, seed=3)
    assert a.boxes == b.boxes
    c = generate_board(TerrainParams(kind="rocks"), seed=4)
    d = generate_board(TerrainParams(kind="rocks"), seed=5)
    assert c.boxes != d.boxes


def test_yawed_box_height_closed_form():
    box = TerrainBox([0.0, 0.0, 0.05], [0.2, 0.02, 0.1], yaw=math.pi / 4, label="rock")
    board = TerrainBoard(params=TerrainParams(), seed=0, boxes=[box])
    d = 0.09 / math.sqrt(2.0)
    assert board.height(d, d) == pytest.approx(0.1)  # along the box's long axis
    assert board.height(d, -d) == 0.0  # across it


@pytest.mark.parametrize(
    "params, match",
    [
        (TerrainParams(kind="lava"), "unknown terrain board kind 'lava'"),
        (TerrainParams(size_x=-0.6), "size_x must be a positive length"),
        (TerrainParams(base_thickness=0.0), "base_thickness must be a positive length"),
        (TerrainParams(rock_count=-1), "rock_count must be a non-negative integer"),
        (TerrainParams(rock_height=[0.05, 0.01]), r"rock_height must be a range \[min, max\]"),
        (TerrainParams(gap_width=[0.1]), "gap_width must be a range"),
        (TerrainParams(kind="gaps", gap_count=6, gap_width=[0.05, 0.09]), "too little board"),
        (TerrainParams(rock_size=[0.1, 0.7]), "smaller than the board"),
        (TerrainParams(mixed_sections=0), "mixed_sections must be >= 1"),
    ],
)
def test_bad_parameters(params, match):
    with pytest.raises(RepertoireError, match=match):
        generate_board(params, seed=0)


def test_bad_calls():
    with pytest.raises(RepertoireError, match="TerrainParams"):
        generate_board({"kind": "flat"}, seed=0)
    with pytest.raises(RepertoireError, match="seed must be an integer"):
        generate_board(TerrainParams(), seed=0.5)
    board = generate_board(TerrainParams(), seed=0)
    with pytest.raises(RepertoireError, match="finite"):
        board.height(np.nan, 0.0)


def test_height_grid_is_the_papers_464_point_profile():
    board = generate_board(TerrainParams(kind="flat"), seed=0)
    p_W, z = board.height_grid([0.0, 0.0])
    assert z.shape == (16, 29) and z.size == 464
    assert p_W.shape == (16, 29, 2)
    np.testing.assert_allclose(np.diff(p_W[0, :, 0]), 0.012)
    np.testing.assert_allclose(p_W.mean(axis=(0, 1)), [0.0, 0.0], atol=1e-15)
    np.testing.assert_array_equal(z, 0.04)


def test_height_grid_rotated_closed_form():
    # A step: everything with x >= 0 is 0.05 m high, the rest is ground.
    step = TerrainBox([0.5, 0.0, 0.025], [1.0, 2.0, 0.05], 0.0, "step")
    board = TerrainBoard(params=TerrainParams(), seed=0, boxes=[step])
    p_W, z = board.height_grid([0.0, 0.0], yaw=math.pi / 2, length=0.1, width=0.1, resolution=0.02)
    # Rotated by 90 degrees, the grid's y axis points along -x of the world.
    assert z.shape == (5, 5)
    np.testing.assert_allclose(p_W[:, 0, 0], [0.04, 0.02, 0.0, -0.02, -0.04], atol=1e-15)
    np.testing.assert_array_equal(z[:3], 0.05)
    np.testing.assert_array_equal(z[3:], 0.0)
    with pytest.raises(RepertoireError, match="resolution > 0"):
        board.height_grid([0.0, 0.0], resolution=0.0)
    with pytest.raises(RepertoireError, match="finite origin"):
        board.height_grid([0.0, np.nan])
