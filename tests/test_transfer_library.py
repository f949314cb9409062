"""Whole-StepLibrary transfer, the search over it and the final library (issue 12)."""

import math

import numpy as np
import pytest
from repertoire.diagrams.littledog_demos import crossing_start, flat_start, library_terrain
from repertoire.models.littledog import FOOT_RADIUS
from repertoire.models.terrain import (
    TerrainBoard,
    TerrainBox,
    TerrainParams,
    generate_board,
    replace_with_rocks,
    tile_boards,
)
from repertoire.planning.littledog_crawl import (
    CrawlParams,
    choose_footholds,
    plan_crawl,
    plan_to_steps,
)
from repertoire.planning.step_library import StepLibrary
from repertoire.planning.terrain_features import (
    TransferConfig,
    TransferError,
    candidate_frames,
    terrain_bounds,
    wrap_angle,
)
from repertoire.planning.transfer_library import (
    chain_frames,
    chain_successors,
    final_library,
    fit_board_pca,
    foot_path,
    library_stances,
    placing_steps,
    search_library,
    step_end_feet,
    step_supported,
    transfer_library,
)
from repertoire.planning.transfer_search import (
    GapFill,
    PathItem,
    PlannedStep,
    SearchResult,
    foot_distance,
)


@pytest.fixture(scope="module")
def source():
    t = library_terrain("terrain_a")
    return tile_boards([generate_board(t.board, s) for s in t.seeds])


@pytest.fixture(scope="module")
def library(source):
    """The scripted 0-degree crossing of terrain_a, cut into steps (kinematic, no physics)."""
    params = CrawlParams()
    off = flat_start(source, 0.0, 0.25, params)
    pose, feet, _ = crossing_start(source, 0.0, 0.25, params.standing_height, off)
    steps = choose_footholds(source, feet, 0.0, 0.23, params)
    plan = plan_crawl(feet, pose, steps, source, params)
    return StepLibrary(plan_to_steps(plan, terrain="terrain_a", direction=0.0, kind="recorded"))


@pytest.fixture(scope="module")
def pca(source):
    return fit_board_pca([source])


def test_end_stance_is_the_next_start_less_the_press(library):
    press = CrawlParams().press
    for k in range(len(library) - 1):
        end = step_end_feet(library[k])
        nxt = library[k + 1].start_feet
        f = library[k].foot
        others = [i for i in range(4) if i != f]
        np.testing.assert_allclose(end[others], library[k].start_feet[others])
        # The action's last angles command the foot ``press`` below its foothold.
        np.testing.assert_allclose(end[f], nxt[f] - [0.0, 0.0, press], atol=1e-9)
    starts, ends = library_stances(library)
    assert starts.shape == ends.shape == (len(library), 4, 3)
    assert library_stances(None)[0].shape == (0, 4, 3)


def test_library_matches_back_at_its_own_places(library, source, pca, tmp_path):
    r = transfer_library(library, {"terrain_a": source}, source, pca, target_name="back")
    assert r.library is not None
    # A step matched at its own place stands exactly as recorded: supported by construction.
    assert r.unsupported == [] and "support" not in r.message
    # Steps whose profile leaves the board (near its edge) are reported, never placed.
    assert r.off_source and not set(r.off_source) & set(r.source_index.tolist())
    assert len(r.library) + len(r.discarded) == len(library)
    for new, j in zip(r.library, r.source_index):
        old = library[int(j)]
        assert np.max(np.linalg.norm(new.start_feet - old.start_feet, axis=1)) < 0.02
        assert abs(math.degrees(wrap_angle(new.start_pose[5] - old.start_pose[5]))) < 5.0
        # The action is unchanged; the body path moves rigidly with the start.
        np.testing.assert_array_equal(new.q, old.q)
        np.testing.assert_array_equal(new.times, old.times)
        np.testing.assert_array_equal(new.stance, old.stance)
        assert (new.kind, new.foot, new.terrain) == (old.kind, old.foot, "back")
        rel_new = np.linalg.norm(new.body_pose[:, :2] - new.start_pose[:2], axis=1)
        rel_old = np.linalg.norm(old.body_pose[:, :2] - old.start_pose[:2], axis=1)
        np.testing.assert_allclose(rel_new, rel_old, atol=1e-9)
        np.testing.assert_allclose(
            new.body_pose[:, 2] - new.start_pose[2], old.body_pose[:, 2] - old.start_pose[2]
        )
    r.library.save(tmp_path / "back")
    loaded = StepLibrary.load(tmp_path / "back")
    np.testing.assert_array_equal(loaded.keys, r.library.keys)


def test_modified_terrain_keeps_matches_only_before_the_change(library, source, pca):
    x_from = 0.05
    modified = replace_with_rocks(source, x_from, seed=5)
    r = transfer_library(library, {"terrain_a": source}, modified, pca, target_name="mod")
    assert r.library is not None and len(r.library) >= 3
    for new, j in zip(r.library, r.source_index):
        assert np.max(np.linalg.norm(new.start_feet - library[int(j)].start_feet, axis=1)) < 0.02
        # Its whole profile (0.35 m long around the feet's centroid) lies before the change.
        assert new.start_feet[:, 0].mean() + 0.17 < x_from


def test_missing_source_terrain_is_named(library, source, pca):
    with pytest.raises(TransferError, match="terrain_a"):
        transfer_library(library, {"terrain_b": source}, source, pca)
    with pytest.raises(TransferError, match="StepLibrary"):
        transfer_library(library.steps, {"terrain_a": source}, source, pca)
    with pytest.raises(TransferError, match="target"):
        transfer_library(library, {"terrain_a": source}, None, pca)


class Straight:
    """A gap filler moving each foot straight to the target in one step per foot."""

    def __call__(self, start, target, time_limit):
        steps, cur = [], np.array(start, dtype=float)
        for f in (2, 0, 3, 1):
            nxt = cur.copy()
            nxt[f] = target[f]
            steps.append(PlannedStep(cur, nxt, f))
            cur = nxt
        return GapFill(steps, "reached")


def test_threshold_discarding_every_step_leaves_the_planner_alone(library, source, pca):
    cfg = TransferConfig(threshold=1e-9, coarse_factor=1.0, refine_levels=0)
    r = transfer_library(
        library, {"terrain_a": source}, generate_board(source.params, 99), pca, cfg
    )
    assert r.library is None and len(r.discarded) + len(r.off_source) >= len(library)
    assert "planner alone" in r.message
    start = library[0].start_feet
    goal = start + [0.1, 0.0, 0.0]
    result = search_library(None, start, goal, Straight())
    assert result.status == "reached" and result.recorded_count == 0
    assert result.planned_count == 4 and "planner alone" in result.message


def test_final_library_orders_recorded_and_planned_steps(library, source, tmp_path):
    a, b = library[3], library[4]
    gap_end = b.start_feet.copy()
    planned = Straight()(step_end_feet(a), gap_end, 1.0).steps
    result = SearchResult(
        "reached",
        [PathItem("recorded", step=3)] + [PathItem("planned", planned=p) for p in planned],
        0.0,
        1,
        4,
        1,
        2,
        "test",
    )
    final = final_library(result, library, source, "test")
    assert [s.kind for s in final] == ["recorded"] + ["planned"] * 4
    assert final[0] is a
    np.testing.assert_allclose(final[1].start_feet, planned[0].start_feet, atol=1e-9)
    assert [s.foot for s in final[1:]] == [2, 0, 3, 1]
    # The crawl starts from the recorded step's last body pose.
    np.testing.assert_allclose(final[1].start_pose, a.body_pose[-1], atol=1e-9)
    # Figs. 11-12: the final library (to the last step's end) over the height map.
    from repertoire.planning.transfer_plot import library_path_figure

    png = library_path_figure(source, library, final, tmp_path / "f.png", goal=0.2, links=[(3, 4)])
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    empty = SearchResult("unreachable", [], 0.0, 0, 0, 0, 0, "nothing")
    with pytest.raises(TransferError, match="no steps"):
        final_library(empty, library, source)
    bad = SearchResult("reached", [PathItem("recorded", step=999)], 1.0, 1, 0, 0, 1, "x")
    with pytest.raises(TransferError, match="999"):
        final_library(bad, library, source)


def test_placing_steps_place_the_fewest_feet_the_executor_cannot_take_up():
    target = np.zeros((4, 3))
    current = target.copy()
    current[:, 0] = [0.003, 0.006, 0.036, 0.008]  # lf, rf, lh, rh offsets (m), summed 5.3 cm
    # Every foot beyond 5 mm, in crawl order (lh, lf, rh, rf); lf (3 mm) stays.
    every = placing_steps(current, target)
    assert [p.foot for p in every] == [2, 3, 1]
    np.testing.assert_allclose(every[-1].end_feet[1:], 0.0)
    assert every[-1].end_feet[0, 0] == 0.003
    # Within 4 cm: placing lh (the largest) leaves 1.7 cm, under 4 cm and under half of
    # lh's 3.6 cm move (so the policy takes the target's step next, not that move again).
    few = placing_steps(current, target, within=0.04)
    assert [p.foot for p in few] == [2]
    np.testing.assert_allclose(few[0].end_feet[2], 0.0)
    np.testing.assert_allclose(few[0].end_feet[[0, 1, 3]], current[[0, 1, 3]])
    # No placing when the move that led here is long: 5.3 cm <= 6 cm and <= half of 12 cm.
    before = current.copy()
    before[2, 0] -= 0.12
    assert placing_steps(current, target, within=0.06, before=before) == []
    before[2, 0] += 0.04  # an 8 cm move: 5.3 cm > 4 cm, lh is placed
    assert [p.foot for p in placing_steps(current, target, within=0.06, before=before)] == [2]


def test_chain_successors_follow_each_demonstration(library):
    nxt = chain_successors(library)
    np.testing.assert_array_equal(nxt, list(range(1, len(library))) + [-1])
    # Two crossings back to back: the first one's last step does not continue into the second.
    twice = chain_successors(StepLibrary(library.steps + library.steps))
    n = len(library)
    assert twice[n - 1] == -1 and twice[n] == n + 1 and twice[-1] == -1
    with pytest.raises(TransferError, match="chain_join"):
        chain_successors(library, 0.0)


def test_chain_frame_is_the_matched_transform_of_the_neighbour():
    # Own frame at the origin matched at (1, 2) turned by 90 degrees: a neighbour 0.1 m
    # ahead (yaw 0.2) lands 0.1 m along the new heading, yaw 0.2 + 90 degrees.
    out = chain_frames([[0.0, 0.0, 0.0]], [[0.1, 0.0, 0.2]], [[1.0, 2.0, math.pi / 2]])
    np.testing.assert_allclose(out, [[1.0, 2.1, 0.2 + math.pi / 2]], atol=1e-12)
    # The identity match leaves the neighbour's own frame.
    a, b = np.array([[0.3, -0.1, 0.4]]), np.array([[0.35, -0.05, 0.5]])
    np.testing.assert_allclose(chain_frames(a, b, a), b, atol=1e-12)


@pytest.fixture(scope="module")
def flat_library():
    """A scripted crossing of a flat board: every profile is flat and matches anywhere."""
    flat = generate_board(TerrainParams(kind="flat"), 0)
    params = CrawlParams()
    pose, feet, _ = crossing_start(flat, 0.0, 0.25, params.standing_height, [0.0, 0.0])
    plan = plan_crawl(feet, pose, choose_footholds(flat, feet, 0.0, 0.23, params), flat, params)
    return flat, StepLibrary(plan_to_steps(plan, terrain="flat", direction=0.0, kind="recorded"))


def joined_pairs(r) -> list[tuple[int, int]]:
    """Placements (a, b) where b is the next step of a's demonstration and starts on a's end."""
    starts, ends = library_stances(r.library)
    idx = r.source_index
    return [
        (a, b)
        for a in range(len(idx))
        for b in range(len(idx))
        if idx[b] == idx[a] + 1 and foot_distance(ends[a], starts[b]) <= 0.04
    ]


def test_multiple_matches_transfer_recorded_chains_as_chains(flat_library, pca):
    flat, library = flat_library
    sources = {"flat": flat}
    single = transfer_library(library, sources, flat, pca)
    lone = transfer_library(
        library, sources, flat, pca, TransferConfig(multiple=True, chains=False)
    )
    cfg = TransferConfig(multiple=True)
    chained = transfer_library(library, sources, flat, pca, cfg)
    # Independent matches of flat profiles land anywhere: no two consecutive steps join.
    assert joined_pairs(single) == [] and joined_pairs(lone) == []
    assert single.chained == lone.chained == 0
    pairs = joined_pairs(chained)
    assert sorted(chained.links) == sorted(pairs) and single.links == lone.links == []
    matched = sorted(set(chained.source_index.tolist()))
    assert chained.chained > 0 and "recorded chains" in chained.message
    # At least one whole chain: every matched step joined to its successor somewhere.
    assert {int(chained.source_index[a]) for a, _ in pairs} == set(matched[:-1])
    press = CrawlParams().press
    for a, b in pairs:
        # A chain is moved rigidly: the recorded gap (the press) is kept exactly.
        gap = foot_distance(step_end_feet(chained.library[a]), chained.library[b].start_feet)
        assert gap == pytest.approx(press, abs=1e-9)
    # Minimum spacing and the cap per step still hold.
    for j in matched:
        rows = np.flatnonzero(chained.source_index == j)
        assert len(rows) <= cfg.max_matches
        c = np.array([chained.library[int(q)].start_feet[:, :2].mean(axis=0) for q in rows])
        d = np.linalg.norm(c[:, None] - c[None], axis=2) + np.eye(len(rows))
        assert d.min() >= cfg.min_spacing - 0.02  # frames >= min_spacing; centroids within 2 cm
    with pytest.raises(TransferError, match="chain_join"):
        transfer_library(
            library, sources, flat, pca, TransferConfig(multiple=True, chain_join=-1.0)
        )


def with_box(board: TerrainBoard, center_xy, size_xy, rise: float) -> TerrainBoard:
    """``board`` plus a box whose top is ``rise`` above the board's top at ``center_xy``."""
    top = float(board.height(*center_xy))
    box = TerrainBox([center_xy[0], center_xy[1], top], [size_xy[0], size_xy[1], 2 * rise])
    return TerrainBoard(board.params, board.seed, [*board.boxes, box])


def test_support_needs_the_feet_on_flat_ground_at_their_recorded_height(flat_library):
    flat, library = flat_library
    step = library[1]
    f = step.foot
    path = foot_path(step)
    land = path[-1, :2]
    stance = step.start_feet[(f + 1) % 4, :2]
    tol = TransferConfig().support_tolerance

    def ok(board, tolerance=tol):
        return step_supported(flat, board, step, step, tolerance)

    # Its own board, or a box 0.5 m away: supported.
    assert ok(flat) and ok(flat, 0.0)
    assert ok(with_box(flat, land + [0.5, 0.0], [0.04, 0.04], 0.02))
    # The landing foot on top of a 2 cm box: 2 cm above its recorded height.
    assert not ok(with_box(flat, land, [0.04, 0.04], 0.02))
    # A stance foot's centre on the slab, a 1 cm box edge 5 mm from it: not flat.
    edge = with_box(flat, stance + [0.005 + 0.02, 0.0], [0.04, 0.04], 0.01)
    assert float(edge.height(*stance)) == float(flat.height(*stance))
    assert not ok(edge)
    # A 3 mm plate under a stance foot: 3 mm off, within 5 mm but not within 2 mm.
    plate = with_box(flat, stance, [0.04, 0.04], 0.003)
    assert ok(plate) and not ok(plate, 0.002)
    # A 10 cm post (1 cm wide) under the middle of the swing, clear of every foot's disc.
    swing = path[~step.stance[:, f]]
    mid = swing[len(swing) // 2, :2]
    feet = np.vstack([step.start_feet[:, :2], land])
    assert np.linalg.norm(feet - mid, axis=1).min() > 0.005 * math.sqrt(2) + FOOT_RADIUS
    assert not ok(with_box(flat, mid, [0.01, 0.01], 0.1))
    with pytest.raises(TransferError, match="-0.001"):
        ok(flat, -0.001)


def test_transfer_drops_steps_the_new_board_does_not_support(flat_library, pca):
    flat, library = flat_library
    sources = {"flat": flat}
    cfg = TransferConfig(refine_levels=0)
    plain = transfer_library(library, sources, flat, pca, cfg)
    assert plain.library is not None and plain.unsupported == []
    # A post (6 mm wide, 4 cm tall, between the profile samples: the matches stay where
    # they were) under the first placement's landing foot: exactly the placements with a
    # foot there are dropped; the others, whose feet keep the post out of their radius, stay.
    post = foot_path(plain.library[0])[-1, :2]
    board = with_box(flat, post, [0.006, 0.006], 0.04)
    r = transfer_library(library, sources, board, pca, cfg)

    def feet_xy(s):
        return np.vstack([s.start_feet[:, :2], foot_path(s)[-1:, :2]])

    dist = np.array([np.linalg.norm(feet_xy(s) - post, axis=1).min() for s in plain.library])
    on_post = plain.source_index[dist < 1e-9].tolist()
    clear = dist[dist >= 1e-9]
    assert 0 < len(on_post) < len(plain.library)
    assert np.all(clear > FOOT_RADIUS + 0.003 * math.sqrt(2))
    assert r.unsupported == on_post
    assert f"{len(on_post)} matches dropped: the terrain does not support them" in r.message
    kept = [j for j in plain.source_index.tolist() if j not in on_post]
    assert r.source_index.tolist() == kept and r.discarded == plain.discarded
    where = {int(j): s.start_feet for s, j in zip(plain.library, plain.source_index)}
    for s, j in zip(r.library, r.source_index):
        np.testing.assert_array_equal(s.start_feet, where[int(j)])  # kept at the same place
    with pytest.raises(TransferError, match="-1.0"):
        transfer_library(library, sources, flat, pca, TransferConfig(support_tolerance=-1.0))


@pytest.mark.parametrize("name", ["terrain_a", "terrain_b"])
def test_library_terrain_as_recorded_has_the_extent_of_both_boards(name):
    # littledog_library records on LibraryTerrain.build() (join_boards); the transfer
    # works on the same boards tiled. Same boxes, so the same extent and frames.
    t = library_terrain(name)
    built = t.build()
    tiled = tile_boards([generate_board(t.board, s) for s in t.seeds])
    assert built.boxes == tiled.boxes
    assert terrain_bounds(built) == terrain_bounds(tiled) == (-0.4, 0.4, -0.4, 0.4)
    assert len(candidate_frames(built)) == 31 * 31 * 13
    assert replace_with_rocks(built, 0.1, seed=2).boxes == replace_with_rocks(tiled, 0.1, 2).boxes
