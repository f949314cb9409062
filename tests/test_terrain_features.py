"""Terrain features, PCA matching and step transfer (Stolle et al., section V)."""

import math

import numpy as np
import pytest
from repertoire.models.terrain import (
    TerrainBoard,
    TerrainParams,
    generate_board,
    join_boards,
    replace_with_rocks,
    tile_boards,
)
from repertoire.planning.terrain_features import (
    PROFILE_NX,
    PROFILE_NY,
    PROFILE_SIZE,
    TransferConfig,
    TransferError,
    candidate_frames,
    fit_pca,
    match_steps,
    profile_offsets,
    stance_frame,
    stances_on_terrain,
    target_candidates,
    terrain_bounds,
    terrain_features,
    transfer_stance,
    transfer_steps,
    wrap_angle,
)

from repertoire.errors import RepertoireError


@pytest.fixture(scope="module")
def rough():
    return generate_board(TerrainParams(kind="rocks", rock_count=30), seed=5)


@pytest.fixture(scope="module")
def source():
    """A rough board followed by a flat part (the source terrain of Fig. 10)."""
    rocks = generate_board(TerrainParams(kind="rocks", rock_count=30), seed=5)
    flat = generate_board(TerrainParams(kind="flat", size_x=0.4), seed=0)
    return tile_boards([rocks, flat])


@pytest.fixture(scope="module")
def pca(source):
    f = terrain_features(source, candidate_frames(source, 0.03, 5))
    return fit_pca(f.values[f.on_terrain])


def test_profile_is_29_by_16_at_12mm():
    assert (PROFILE_NX, PROFILE_NY, PROFILE_SIZE) == (29, 16, 464)
    off = profile_offsets()
    assert off.shape == (464, 2)
    np.testing.assert_allclose(np.unique(np.round(np.diff(np.unique(off[:, 0])), 12)), [0.012])
    np.testing.assert_allclose(off.mean(axis=0), [0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(np.ptp(off, axis=0), [28 * 0.012, 15 * 0.012])


def test_features_equal_height_grid_minus_mean(rough):
    frames = np.array([[0.02, -0.03, 0.3], [-0.1, 0.05, -0.7], [0.0, 0.0, 0.0]])
    f = terrain_features(rough, frames)
    for i, (x, y, yaw) in enumerate(frames):
        _, z = rough.height_grid([x, y], yaw)
        np.testing.assert_allclose(f.values[i], z.ravel() - z.mean(), atol=1e-15)
        assert f.mean_height[i] == pytest.approx(z.mean())
    assert f.on_terrain.all()


def test_repeated_and_reordered_frames_give_the_same_profiles_exactly(rough):
    # terrain_features computes each distinct frame once (in x order): a frame's row is the
    # same, bit for bit, alone, repeated, or among others in any order; off-board rows NaN.
    rng = np.random.default_rng(2)
    frames = rng.uniform([-0.15, -0.1, -0.8], [0.15, 0.1, 0.8], (40, 3))
    frames = np.vstack([frames, frames[::3], [[1.0, 1.0, 0.0]], frames[:1]])
    f = terrain_features(rough, frames)
    perm = rng.permutation(len(frames))
    g = terrain_features(rough, frames[perm])
    np.testing.assert_array_equal(g.values, f.values[perm])
    np.testing.assert_array_equal(g.mean_height, f.mean_height[perm])
    for i in (0, 5, 39, 40, len(frames) - 2):
        one = terrain_features(rough, frames[i])
        np.testing.assert_array_equal(one.values[0], f.values[i])
        assert one.on_terrain[0] == f.on_terrain[i]
    assert not f.on_terrain[-2] and np.isnan(f.values[-2]).all() and f.on_terrain.sum() > 30
    assert np.isfinite(f.values[f.on_terrain]).all() and np.isnan(f.values[~f.on_terrain]).all()


def test_flat_board_features_are_zero_and_off_board_reported():
    flat = generate_board(TerrainParams(kind="flat"), seed=0)
    f = terrain_features(flat, [[0.0, 0.0, 0.2], [0.29, 0.0, 0.0], [1.0, 1.0, 0.0]])
    np.testing.assert_allclose(f.values[0], 0.0, atol=1e-15)
    assert f.mean_height[0] == pytest.approx(flat.params.base_thickness)
    assert f.on_terrain.tolist() == [True, False, False]
    assert f.off_terrain_count == 2


def test_stance_frame_centroid_and_heading(rough):
    yaw = 0.4
    feet, body = stances_on_terrain(rough, [[0.05, -0.02, yaw]])
    frame = stance_frame(feet[0])
    np.testing.assert_allclose(frame, [0.05, -0.02, yaw], atol=1e-12)
    np.testing.assert_allclose(
        feet[0, :, 2], rough.height(feet[0, :, 0], feet[0, :, 1]) + 0.0103, atol=1e-12
    )
    assert body[0, 5] == yaw


def test_candidate_frames_grid_and_yaws(rough):
    c = candidate_frames(rough, spacing=0.1, yaw_count=3, margin=0.1)
    # x and y in [-0.2, 0.2] at 0.1: 5 x 5 positions, yaws -pi/4, 0, pi/4.
    assert c.shape == (75, 3)
    np.testing.assert_allclose(np.unique(c[:, 2]), [-math.pi / 4, 0.0, math.pi / 4])
    np.testing.assert_allclose(np.unique(c[:, 0]), [-0.2, -0.1, 0.0, 0.1, 0.2], atol=1e-12)


def test_pca_keeps_95_percent_and_projects_orthonormally(rough):
    f = terrain_features(rough, candidate_frames(rough, 0.04, 5))
    p = fit_pca(f.values[f.on_terrain])
    assert p.explained.sum() >= 0.95
    assert p.explained[:-1].sum() < 0.95
    np.testing.assert_allclose(p.components @ p.components.T, np.eye(p.size), atol=1e-10)
    # Projections of the fitting set have zero mean.
    np.testing.assert_allclose(p.project(f.values[f.on_terrain]).mean(0), 0.0, atol=1e-10)


def test_steps_match_back_at_their_own_places(rough):
    rng = np.random.default_rng(0)
    poses = np.column_stack(
        [rng.uniform(-0.1, 0.1, 12), rng.uniform(-0.1, 0.1, 12), rng.uniform(-0.5, 0.5, 12)]
    )
    feet, body = stances_on_terrain(rough, poses)
    f = terrain_features(rough, candidate_frames(rough, 0.03, 5))
    pca = fit_pca(f.values[f.on_terrain])
    result = transfer_steps(rough, feet, body, rough, pca, TransferConfig())
    assert result.matches.discarded == []
    assert len(result.steps) == 12
    for t in result.steps:
        own = result.source_frames[t.step]
        assert np.hypot(*(t.match.frame[:2] - own[:2])) < 0.02
        assert abs(math.degrees(wrap_angle(t.match.frame[2] - own[2]))) < 5.0
        np.testing.assert_allclose(t.feet, feet[t.step], atol=0.02)
        assert abs(t.body_pose[5] - body[t.step, 5]) < math.radians(5.0)


def test_candidate_features_computed_once_give_the_same_transfer(rough):
    feet, body = stances_on_terrain(rough, [[0.02, -0.03, 0.2], [-0.05, 0.04, -0.3]])
    f = terrain_features(rough, candidate_frames(rough, 0.03, 5))
    pca = fit_pca(f.values[f.on_terrain])
    cfg = TransferConfig(refine_levels=1)
    feats, times = target_candidates(rough, cfg)
    np.testing.assert_array_equal(
        feats.frames, candidate_frames(rough, cfg.spacing, cfg.yaw_count, cfg.yaw_range)
    )
    assert set(times) == {"candidates", "features"}
    once = transfer_steps(rough, feet, body, rough, pca, cfg, feats)
    fresh = transfer_steps(rough, feet, body, rough, pca, cfg)
    assert once.timings["features"] == 0.0 and fresh.timings["features"] > 0.0
    assert [t.step for t in once.steps] == [t.step for t in fresh.steps]
    for a, b in zip(once.steps, fresh.steps):
        np.testing.assert_array_equal(a.match.frame, b.match.frame)
        np.testing.assert_array_equal(a.feet, b.feet)
    np.testing.assert_array_equal(
        once.step_values, terrain_features(rough, once.source_frames).values
    )


def test_flat_ground_matches_many_places(source, pca):
    # A stance on the flat part matches all over the flat part: spurious matches.
    feet, body = stances_on_terrain(source, [[0.3, 0.0, 0.0]])
    cfg = TransferConfig(multiple=True, min_spacing=0.05, max_matches=50, refine_levels=0)
    result = transfer_steps(source, feet, body, source, pca, cfg)
    assert len(result.steps) >= 5
    frames = np.array([t.match.frame for t in result.steps])
    flat = terrain_features(source, frames)
    np.testing.assert_allclose(flat.values, 0.0, atol=1e-12)
    spacing = np.hypot(*(frames[:, None, :2] - frames[None, :, :2]).transpose(2, 0, 1))
    assert spacing[~np.eye(len(frames), dtype=bool)].min() >= 0.05 - 1e-12


def test_modified_terrain_matches_where_unchanged_and_not_on_rocks(source, pca):
    x_from = 0.1
    modified = replace_with_rocks(source, x_from, seed=7)
    # The unchanged part keeps its heights exactly.
    x, y = np.meshgrid(np.linspace(-0.5, x_from - 1e-6, 60), np.linspace(-0.3, 0.3, 40))
    np.testing.assert_array_equal(source.height(x, y), modified.height(x, y))
    xs = np.arange(-0.25, 0.26, 0.02)
    poses = np.column_stack([xs, 0.03 * np.sin(7 * xs), 0.2 * np.sin(5 * xs)])
    feet, body = stances_on_terrain(source, poses)
    result = transfer_steps(source, feet, body, modified, pca, TransferConfig())
    reach = np.abs(profile_offsets()).max(axis=0)
    unchanged = [i for i in range(len(xs)) if xs[i] + np.hypot(*reach) < x_from]
    placed = {t.step: t for t in result.steps}
    for i in unchanged:
        own = result.source_frames[i]
        assert i in placed
        assert np.hypot(*(placed[i].match.frame[:2] - own[:2])) < 0.02
    # No step is placed on the changed part.
    assert all(t.match.frame[0] < x_from for t in result.steps)
    # The flat-part steps (their terrain is now rocks) are discarded.
    assert {i for i in range(len(xs)) if xs[i] > x_from} <= set(result.matches.discarded)


def test_multiple_matches_respect_min_spacing(rough):
    f = terrain_features(rough, candidate_frames(rough, 0.04, 3))
    pca = fit_pca(f.values[f.on_terrain])
    feet, _ = stances_on_terrain(rough, [[0.0, 0.0, 0.0]])
    own = terrain_features(rough, stance_frame(feet))
    single = match_steps(own.values, f, pca, 10.0)
    many = match_steps(own.values, f, pca, 10.0, multiple=True, min_spacing=0.1, max_matches=6)
    assert len(single.matches) == 1 and len(many.matches) == 6
    assert many.matches[0].cost == single.matches[0].cost
    xy = np.array([m.frame[:2] for m in many.matches])
    d = np.hypot(*(xy[:, None] - xy[None]).transpose(2, 0, 1))
    assert d[~np.eye(6, dtype=bool)].min() >= 0.1
    assert [m.cost for m in many.matches] == sorted(m.cost for m in many.matches)


def test_transfer_stance_is_a_planar_rigid_motion():
    feet = np.array(
        [[0.1, 0.06, 0.05], [0.1, -0.06, 0.05], [-0.1, 0.06, 0.06], [-0.1, -0.06, 0.05]]
    )
    pose = np.array([0.0, 0.0, 0.2, 0.05, -0.02, 0.1])
    new_feet, new_pose = transfer_stance(
        feet, pose, [0.0, 0.0, 0.1], 0.04, [1.0, 2.0, 0.1 + math.pi / 2], 0.10
    )
    np.testing.assert_allclose(new_feet[0], [1.0 - 0.06, 2.0 + 0.1, 0.11], atol=1e-12)
    np.testing.assert_allclose(new_pose, [1.0, 2.0, 0.26, 0.05, -0.02, 0.1 + math.pi / 2])
    # Distances between feet are kept.
    d = np.linalg.norm(feet[:, None] - feet[None], axis=-1)
    np.testing.assert_allclose(np.linalg.norm(new_feet[:, None] - new_feet[None], axis=-1), d)


def test_tile_boards_places_boards_side_by_side():
    a = generate_board(TerrainParams(kind="rocks"), seed=1)
    b = generate_board(TerrainParams(kind="steps"), seed=2)
    t = tile_boards([a, b])
    assert t.params.size_x == pytest.approx(1.2)
    x, y = np.meshgrid(np.linspace(-0.29, 0.29, 30), np.linspace(-0.29, 0.29, 30))
    np.testing.assert_array_equal(t.height(x - 0.3, y), a.height(x, y))
    np.testing.assert_array_equal(t.height(x + 0.3, y), b.height(x, y))


def test_bad_inputs_raise_clear_errors(rough, pca):
    with pytest.raises(TransferError, match="TerrainBoard"):
        terrain_features(None, [[0.0, 0.0, 0.0]])
    with pytest.raises(TransferError, match=r"\(N, 3\)"):
        terrain_features(rough, [[0.0, 0.0]])
    with pytest.raises(TransferError, match="spacing"):
        candidate_frames(rough, spacing=0.0)
    with pytest.raises(TransferError, match="yaw_count"):
        candidate_frames(rough, yaw_count=0)
    with pytest.raises(TransferError, match="margin"):
        candidate_frames(rough, margin=0.4)
    with pytest.raises(TransferError, match="coincide"):
        stance_frame(np.zeros((4, 3)))
    with pytest.raises(TransferError, match="variance"):
        fit_pca(np.ones((3, 464)) * np.arange(3)[:, None], variance=0.0)
    with pytest.raises(TransferError, match="no variance"):
        fit_pca(np.ones((3, 464)))
    feet, body = stances_on_terrain(rough, [[0.0, 0.0, 0.0]])
    with pytest.raises(TransferError, match="source terrain"):
        transfer_steps(None, feet, body, rough, pca)
    with pytest.raises(TransferError, match="threshold"):
        match_steps(np.zeros((1, 464)), terrain_features(rough, [[0.0, 0.0, 0.0]]), pca, 0.0)
    off = terrain_features(rough, [[5.0, 5.0, 0.0]])
    with pytest.raises(TransferError, match="no candidate frame"):
        match_steps(np.zeros((1, 464)), off, pca, 1.0)
    with pytest.raises(RepertoireError, match="x_from"):
        replace_with_rocks(rough, 0.5)
    with pytest.raises(RepertoireError, match="equal size_y"):
        tile_boards([rough, generate_board(TerrainParams(size_y=0.4))])


def test_source_steps_off_their_terrain_are_reported(rough, pca):
    feet, body = stances_on_terrain(rough, [[0.0, 0.0, 0.0], [0.28, 0.0, 0.0]])
    result = transfer_steps(rough, feet, body, rough, pca, TransferConfig(refine_levels=1))
    assert result.off_source == [1]
    assert 1 in result.matches.discarded
    assert [t.step for t in result.steps] == [0]


def test_matched_steps_figure_writes_a_png(tmp_path, rough, pca):
    from repertoire.planning.transfer_plot import matched_steps_figure

    feet, body = stances_on_terrain(rough, [[0.0, 0.0, 0.1], [0.05, 0.02, -0.2]])
    result = transfer_steps(rough, feet, body, rough, pca, TransferConfig(refine_levels=1))
    out = matched_steps_figure(rough, result, tmp_path / "m.png", changed_from=0.1)
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(TransferError, match="TransferResult"):
        matched_steps_figure(rough, None, tmp_path / "x.png")


def _library_like_boards():
    p = TerrainParams(kind="rocks", size_x=0.4, size_y=0.8, rock_count=12)
    return generate_board(p, 11), generate_board(p, 12)


def test_joined_board_has_the_bounds_frames_and_features_of_the_tiled_one():
    a, b = _library_like_boards()
    tiled = tile_boards([a, b])
    joined = join_boards([a, b], [[-0.2, 0.0], [0.2, 0.0]])  # LibraryTerrain.build()
    assert terrain_bounds(joined) == terrain_bounds(tiled) == (-0.4, 0.4, -0.4, 0.4)
    frames = candidate_frames(joined)
    # 0.8 m less twice the 0.096 m margin at 0.02 m: 31 positions per axis, 13 yaws.
    assert frames.shape == (31 * 31 * 13, 3)  # 12,493; the first board's extent gave 4,433
    np.testing.assert_array_equal(frames, candidate_frames(tiled))
    fj, ft = terrain_features(joined, frames), terrain_features(tiled, frames)
    np.testing.assert_array_equal(fj.on_terrain, ft.on_terrain)
    np.testing.assert_array_equal(fj.values, ft.values)


def test_translated_board_bounds_and_on_terrain_follow_its_boxes():
    a, b = _library_like_boards()
    tiled = tile_boards([a, b])
    moved = tiled.translated(0.3, 0.0)  # x in [-0.1, 0.7]
    np.testing.assert_allclose(terrain_bounds(moved), [-0.1, 0.7, -0.4, 0.4], rtol=0, atol=1e-15)
    f = terrain_features(moved, [[-0.2, 0.0, 0.0], [0.5, 0.0, 0.0]])
    assert not f.on_terrain[0]  # the profile reaches x = -0.368: off the board
    assert f.on_terrain[1]  # the profile spans x in [0.332, 0.668]: on it
    frames = candidate_frames(moved)
    np.testing.assert_allclose(frames, candidate_frames(tiled) + [0.3, 0.0, 0.0], atol=1e-15)
    fm, ft = terrain_features(moved, frames), terrain_features(tiled, candidate_frames(tiled))
    np.testing.assert_array_equal(fm.on_terrain, ft.on_terrain)
    np.testing.assert_allclose(fm.mean_height, ft.mean_height, rtol=0, atol=1e-15)
    with pytest.raises(TransferError, match="no boxes"):
        terrain_bounds(TerrainBoard(a.params, 0, []))


def test_refined_matches_keep_the_candidate_yaw_range():
    # The paper limits the placed frames to yaws in [-pi/4, pi/4]. Refinement used to
    # step past the grid's edge yaws (0.851 rad here), and with a single candidate yaw
    # (yaw_count=1: yaw 0) it used a yaw step of pi/2 and placed frames at 0.29 rad.
    from repertoire.planning.transfer_library import fit_board_pca

    src = generate_board(TerrainParams(kind="rocks", size_x=0.8, size_y=0.8), 3)
    tgt = generate_board(TerrainParams(kind="rocks", size_x=0.8, size_y=0.8), 4)
    pca = fit_board_pca([src])
    rng = np.random.default_rng(0)
    poses = np.column_stack([rng.uniform(-0.15, 0.15, (40, 2)), rng.uniform(-0.3, 0.3, 40)])
    feet, body = stances_on_terrain(src, poses)
    for count, half in ((13, math.pi / 4), (5, 0.2), (1, math.pi / 4)):
        config = TransferConfig(yaw_count=count, yaw_range=half, threshold=0.5)
        result = transfer_steps(src, feet, body, tgt, pca, config)
        yaws = np.array([m.frame[2] for m in result.matches.matches])
        assert len(yaws) == 40
        limit = half if count > 1 else 0.0
        assert np.all(np.abs(yaws) <= limit + 1e-12)
    assert TransferConfig(yaw_count=1).yaw_step == 0.0
    assert TransferConfig(yaw_count=13).yaw_step == math.pi / 24
