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
    join_boards,
    replace_with_rocks,
    rock_coverage,
    rock_field,
    tile_boards,
)

from repertoire.cli import main
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


def _height_over_all_boxes(board: TerrainBoard, x, y) -> np.ndarray:
    """The height function's definition: the highest box holding each point, 0 outside."""
    x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
    z = np.zeros(x.shape)
    for box in board.boxes:
        z = np.where(box.contains_xy(x, y), np.maximum(z, box.top), z)
    return z


def test_height_skips_only_boxes_away_from_the_query():
    # height() tests only the boxes whose footprint's bounding rectangle meets the query
    # points' (a foothold or swing test in a rock field meets a few of ~200): the same
    # heights as testing every box, exactly, also on footprint edges and corners.
    rng = np.random.default_rng(3)
    yawed = TerrainBox([0.1, -0.05, 0.03], [0.06, 0.02, 0.06], yaw=0.7, label="rock")
    boards = [
        generate_board(TerrainParams(kind="rocks", rock_count=60), seed=2),
        generate_board(TerrainParams(kind="mixed"), seed=4),
        replace_with_rocks(generate_board(TerrainParams(kind="flat"), seed=0), 0.0, seed=5),
        TerrainBoard(params=TerrainParams(), seed=0, boxes=[yawed]),
    ]
    for board in boards:
        x0, x1, y0, y1 = board.bounds()
        queries = [rng.uniform([x0 - 0.05, y0 - 0.05], [x1 + 0.05, y1 + 0.05], (500, 2))]
        for _ in range(200):  # small windows, single points
            c = rng.uniform([x0, y0], [x1, y1])
            queries.append(c + rng.uniform(-0.02, 0.02, (int(rng.integers(1, 30)), 2)))
        for box in board.boxes:  # corners and edge midpoints of each footprint
            u = np.array([[1, 1], [1, -1], [-1, 1], [-1, -1], [1, 0], [0, 1]]) * 0.5
            local = u * box.size[:2]
            c, s = math.cos(box.yaw), math.sin(box.yaw)
            corners = box.center[:2] + local @ np.array([[c, s], [-s, c]])
            queries.extend(corners[[i]] for i in range(len(corners)))
        for q in queries:
            np.testing.assert_array_equal(
                board.height(q[:, 0], q[:, 1]), _height_over_all_boxes(board, q[:, 0], q[:, 1])
            )
        assert board.height(np.zeros(0), np.zeros(0)).shape == (0,)
    # a yawed box's corner is inside (closed set) though it is off its neighbours' rectangles
    corner = yawed.center[0] + 0.03 * math.cos(0.7) - 0.01 * math.sin(0.7)
    corner_y = yawed.center[1] + 0.03 * math.sin(0.7) + 0.01 * math.cos(0.7)
    assert boards[-1].height(corner, corner_y) == pytest.approx(0.06)


def test_height_of_many_points_is_the_height_over_every_box():
    # height() sorts the points by x and tests each box on its footprint's x range only:
    # on a rock field's profile batch (2-D, ties in x, points exactly at each footprint's
    # x bounds) the heights equal testing every box, bit for bit.
    board = replace_with_rocks(generate_board(TerrainParams(kind="rocks"), seed=1), 0.0, seed=3)
    rng = np.random.default_rng(7)
    x0, x1, y0, y1 = board.bounds()
    frames = rng.uniform([x0, y0, -1.0], [x1, y1, 1.0], (300, 3))
    u, v = np.meshgrid(np.arange(29) * 0.012 - 0.168, np.arange(16) * 0.012 - 0.09)
    c, s = np.cos(frames[:, 2:3]), np.sin(frames[:, 2:3])
    x = frames[:, 0:1] + c * u.ravel() - s * v.ravel()
    y = frames[:, 1:2] + s * u.ravel() + c * v.ravel()
    x[:, :40] = np.round(x[:, :40], 2)  # many equal x
    edges = np.array([[b.footprint_bounds()[k], b.center[1]] for b in board.boxes for k in (0, 1)])
    n = min(len(edges), x.shape[1])
    x[-1, :n], y[-1, :n] = edges[:n, 0], edges[:n, 1]
    np.testing.assert_array_equal(board.height(x, y), _height_over_all_boxes(board, x, y))
    np.testing.assert_array_equal(board.height(x.T, 0.1), _height_over_all_boxes(board, x.T, 0.1))


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
        # 15 sections of 0.04 m on the default 0.6 m board: a gap of up to 0.07 m cannot fit.
        (
            TerrainParams(kind="mixed", mixed_sections=15),
            r"mixed_sections=15 on size_x=0.6 m has sections of 0.04 m, too short for a gap of "
            r"up to gap_width max 0.07 m; expected gap_width max < 0.8\*size_x/mixed_sections "
            r"= 0.032 m",
        ),
        (TerrainParams(kind="mixed", size_x=0.2), "sections of 0.05 m, too short for a gap"),
        (
            TerrainParams(kind="mixed", mixed_sections=15, gap_width=[0.01, 0.032]),
            "too short for a gap",
        ),
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


# Edge parameters that validate() accepts: each at or near one of its limits.
EDGE_PARAMS = [
    # A 0.10 m rock yawed by 45 degrees spans 0.14 m > 0.12 m: scaled across y.
    TerrainParams(kind="rocks", size_y=0.12),
    TerrainParams(kind="rocks", size_x=0.11, size_y=0.11, rock_count=30, gap_width=[0.0, 0.04]),
    # 15 sections of 0.04 m with gaps just under 0.8 * 0.04 m.
    TerrainParams(kind="mixed", mixed_sections=15, gap_width=[0.01, 0.0319]),
    TerrainParams(kind="mixed", size_x=0.2, gap_width=[0.0, 0.0399]),
    TerrainParams(kind="mixed", size_x=0.2, size_y=0.11, gap_width=[0.0, 0.0399]),
    TerrainParams(
        kind="mixed", mixed_sections=40, gap_width=[0.0, 0.0119], step_count=100, rock_count=80
    ),
    TerrainParams(kind="gaps", size_x=0.2, gap_count=2, gap_width=[0.07, 0.0799]),
    TerrainParams(kind="steps", size_x=0.2, size_y=0.05, step_count=30, rock_size=[0.01, 0.04]),
    TerrainParams(kind="flat", size_x=0.01, size_y=0.01, rock_size=[1e-3, 2e-3], gap_width=[0, 0]),
]


@pytest.mark.parametrize("index", range(len(EDGE_PARAMS)))
def test_valid_params_always_generate_positive_boxes_inside_the_board(index):
    params = EDGE_PARAMS[index]
    params.validate()
    hx, hy = 0.5 * params.size_x, 0.5 * params.size_y
    for seed in range(25):
        board = generate_board(params, seed)
        board.check_boxes()
        for box in board.boxes:
            assert min(box.size) > 0.0 and all(map(math.isfinite, [*box.center, *box.size]))
            x0, x1, y0, y1 = box.footprint_bounds()
            assert -hx - 1e-12 <= x0 < x1 <= hx + 1e-12
            assert -hy - 1e-12 <= y0 < y1 <= hy + 1e-12
        # The boxes cover the board: its extent is the closed form.
        np.testing.assert_allclose(board.bounds(), [-hx, hx, -hy, hy], rtol=0, atol=1e-12)
    # Drake takes every box (it aborts the process on a non-positive one).
    plant, _ = AddMultibodyPlantSceneGraph(DiagramBuilder(), 0.001)
    assert len(board.add_to_plant(plant)) == len(board.boxes) + 1


def test_rocks_wider_than_a_narrow_board_are_scaled_to_fit_across():
    params = TerrainParams(kind="rocks", size_y=0.12)
    scaled = 0
    for seed in range(20):
        rocks = [b for b in generate_board(params, seed).boxes if b.label == "rock"]
        assert len(rocks) == params.rock_count
        _assert_rocks_inside(rocks, params, -0.3, 0.3)
        for rock in rocks:
            _, _, y0, y1 = rock.footprint_bounds()
            if y1 - y0 == pytest.approx(0.95 * params.size_y, abs=1e-15):
                scaled += 1  # scaled to 95 % of the width, proportions kept
                assert max(rock.size[:2]) <= params.rock_size[1]
            else:  # as drawn
                assert y1 - y0 < params.size_y
                assert all(params.rock_size[0] <= v <= params.rock_size[1] for v in rock.size[:2])
    assert scaled >= 7  # the seeds that used to raise numpy's 'high - low < 0'


def test_flat_and_short_mixed_boards_accept_their_own_limits():
    # mixed_sections only matters for a mixed board; one section has no gap section.
    TerrainParams(kind="flat", mixed_sections=15).validate()
    TerrainParams(kind="rocks", mixed_sections=15).validate()
    board = generate_board(TerrainParams(kind="mixed", mixed_sections=1, size_x=0.2), seed=0)
    assert [b.label for b in board.boxes] == ["slab"]


def test_bad_boxes_are_refused_before_drake():
    board = generate_board(TerrainParams(), seed=0)
    bad = TerrainBox([0.0, 0.0, 0.02], [-0.0004, 0.6, 0.04], 0.0, "slab")
    broken = TerrainBoard(board.params, board.seed, [*board.boxes, bad])
    plant, _ = AddMultibodyPlantSceneGraph(DiagramBuilder(), 0.001)
    with pytest.raises(RepertoireError, match=r"terrain box 1 \(slab\) .* positive size"):
        broken.add_to_plant(plant)
    with pytest.raises(RepertoireError, match="positive size"):
        broken.sdf_text()
    nan = TerrainBox([np.nan, 0.0, 0.02], [0.1, 0.1, 0.04], 0.0, "rock")
    with pytest.raises(RepertoireError, match="finite centre"):
        TerrainBoard(board.params, board.seed, [nan]).check_boxes()


def test_cli_refuses_a_mixed_board_too_short_for_its_gaps(tmp_path, capsys):
    scenario = tmp_path / "mixed15.yaml"
    scenario.write_text("terrain: {kind: mixed, mixed_sections: 15}\n")
    argv = ["simulate", "littledog_stand", "--scenario", str(scenario), "--out", str(tmp_path)]
    assert main(argv) == 2
    assert "mixed_sections=15" in capsys.readouterr().err


def _kept_exactly(board: TerrainBoard, x_from: float, x, y) -> np.ndarray:
    """Where ``replace_with_rocks(board, x_from)`` keeps the heights: before ``x_from`` and
    outside every yawed rock that reaches past it (such a rock is dropped whole)."""
    keep = x < x_from
    for box in board.boxes:
        lo, hi, _, _ = box.footprint_bounds()
        if box.yaw != 0.0 and lo < x_from <= hi:
            keep &= ~box.contains_xy(x, y)
    return keep


def _two_boards():
    p = TerrainParams(kind="rocks", size_x=0.4, size_y=0.8, rock_count=12)
    return generate_board(p, 11), generate_board(p, 12)


def test_bounds_follow_the_boxes_of_moved_and_joined_boards():
    a, b = _two_boards()
    assert a.bounds() == (-0.2, 0.2, -0.4, 0.4)
    np.testing.assert_allclose(
        a.translated(0.3, -0.1).bounds(), [0.1, 0.5, -0.5, 0.3], rtol=0, atol=1e-15
    )
    joined = join_boards([a, b], [[-0.2, 0.0], [0.2, 0.0]])
    assert joined.params.size_x == 0.4  # the first board's parameters ...
    assert joined.bounds() == (-0.4, 0.4, -0.4, 0.4)  # ... but both boards' extent
    assert tile_boards([a, b]).bounds() == joined.bounds()
    apart = join_boards([a, b], [[0.0, 0.0], [0.5, 0.3]])
    np.testing.assert_allclose(apart.bounds(), [-0.2, 0.7, -0.4, 0.7], rtol=0, atol=1e-15)
    with pytest.raises(RepertoireError, match="no boxes"):
        TerrainBoard(a.params, 0, []).bounds()


def test_replace_with_rocks_on_a_joined_board_keeps_the_second_board():
    a, b = _two_boards()
    joined = join_boards([a, b], [[-0.2, 0.0], [0.2, 0.0]])
    tiled = tile_boards([a, b])
    modified = replace_with_rocks(joined, 0.05, seed=0)
    # Same boxes as on the tiled board (the same terrain), so the same new rocks.
    assert modified.boxes == replace_with_rocks(tiled, 0.05, seed=0).boxes
    assert modified.bounds() == joined.bounds()
    x, y = np.meshgrid(np.linspace(-0.45, 0.45, 91), np.linspace(-0.45, 0.45, 91))
    before = x < 0.05
    # The second board's part before x_from (0 <= x < 0.05) is kept exactly.
    keep = _kept_exactly(joined, 0.05, x, y)
    assert np.count_nonzero(before & ~keep) == 6  # under the one yawed rock dropped
    np.testing.assert_array_equal(modified.height(x, y)[keep], joined.height(x, y)[keep])
    second = keep & (x > 0.0) & (np.abs(y) <= 0.4)
    assert np.count_nonzero(second) == np.count_nonzero(before & (x > 0) & (np.abs(y) <= 0.4)) - 6
    assert np.all(modified.height(x, y)[second] >= a.params.base_thickness)
    # The rest of the extent is the rock field: slab or rock everywhere on it, ground outside.
    on = ~before & (np.abs(x) <= 0.4) & (np.abs(y) <= 0.4)
    assert np.all(modified.height(x, y)[on] >= a.params.base_thickness)
    np.testing.assert_array_equal(modified.height(x, y)[np.abs(x) > 0.4], 0.0)


def test_replace_with_rocks_on_a_moved_board_covers_its_own_extent():
    a, _ = _two_boards()
    moved = a.translated(0.3, 0.25)  # x in [0.1, 0.5], y in [-0.15, 0.65]
    modified = replace_with_rocks(moved, 0.3, seed=3)
    np.testing.assert_allclose(modified.bounds(), moved.bounds(), rtol=0, atol=1e-15)
    x, y = np.meshgrid(np.linspace(0.0, 0.6, 61), np.linspace(-0.3, 0.8, 111))
    before = x < 0.3
    keep = _kept_exactly(moved, 0.3, x, y)
    np.testing.assert_array_equal(modified.height(x, y)[keep], moved.height(x, y)[keep])
    x0, x1, y0, y1 = moved.bounds()
    on = ~before & (x <= x1) & (y >= y0) & (y <= y1)
    assert np.all(modified.height(x, y)[on] >= a.params.base_thickness)
    off = (y < y0 - 1e-9) | (y > y1 + 1e-9) | (x > x1 + 1e-9)
    np.testing.assert_array_equal(modified.height(x, y)[off], 0.0)
    with pytest.raises(RepertoireError, match=r"x_from=0.05 must lie strictly inside"):
        replace_with_rocks(moved, 0.05)
