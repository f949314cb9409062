"""Robustness round 4: unusual valid inputs and bad inputs of the LittleDog library."""

import json

import numpy as np
import pytest
from repertoire.models.littledog.kinematics import leg_fk, leg_ik, standing_configuration
from repertoire.models.littledog.pose import body_to_world
from repertoire.models.terrain import TerrainParams, generate_board, rock_field, tile_boards
from repertoire.planning.step_library import LibraryStep, StepLibrary, StepLibraryError
from repertoire.planning.transfer_search import (
    GapFill,
    SearchConfig,
    TransferSearchError,
    search_transfer,
)
from repertoire.systems.integral_foot_controller import (
    body_feet,
    corrected_angles,
    integrator_update,
)
from repertoire.systems.library_policy import StepIndex

from repertoire.errors import RepertoireError

Q0 = standing_configuration(0.14)


def _step(shift: float = 0.0, **overrides) -> LibraryStep:
    n = 3
    fields = dict(
        start_feet=body_to_world([shift, 0, 0.14, 0, 0, 0], body_feet(Q0)),
        start_pose=np.array([shift, 0.0, 0.14, 0.0, 0.0, 0.0]),
        times=np.arange(n) * 0.01,
        q=np.repeat(Q0[None], n, 0),
        body_pose=np.tile([shift, 0.0, 0.14, 0.0, 0.0, 0.0], (n, 1)),
        stance=np.ones((n, 4), bool),
        foot=0,
        terrain="t",
        direction=0.0,
    )
    fields.update(overrides)
    return LibraryStep(**fields)


@pytest.mark.parametrize(
    "leg, q",
    [
        ("lf", [-0.28714275, -2.01178104, -3.02040266]),
        ("rf", [0.16820404, -2.66406446, -2.76112512]),
        ("lh", [-0.17663979, 1.97614494, 3.03327496]),
    ],
)
def test_leg_ik_inverts_fk_for_a_pitch_beyond_pi_within_the_limits(leg, q):
    # The foot is below the hip and every angle within the limits: IK(FK(q)) == q
    # (the pitch used to come back 2 pi away, outside the limits, and was refused).
    np.testing.assert_allclose(leg_ik(leg, leg_fk(leg, q)), q, rtol=0, atol=1e-9)


def test_step_index_tree_breaks_ties_like_the_brute_force_search():
    steps = [_step(0.01 * i) for i in range(4)]
    lib = StepLibrary(steps + steps)  # every step twice: exact ties
    for i in range(4):
        feet = lib.keys[i] + 0.003
        assert StepIndex(lib, brute_force_below=1).query(feet)[0] == i
        assert StepIndex(lib).query(feet)[0] == i
        assert StepIndex(lib).query_batch(feet)[0][0] == i


def test_integral_foot_math_refuses_nan_and_wrong_shapes():
    zero = np.zeros((4, 3))
    pose = [0.0, 0.0, 0.14, 0.0, 0.0, 0.0]
    kw = dict(gain=0.5, decay=0.9, limit=0.04)
    with pytest.raises(RepertoireError, match="integrators must be a finite 4 x 3"):
        integrator_update(np.full((4, 3), np.nan), Q0, pose, pose, [1, 1, 1, 1], **kw)
    with pytest.raises(RepertoireError, match="contact must be 4 finite flags"):
        integrator_update(zero, Q0, pose, pose, [1, 1, 1], **kw)
    with pytest.raises(RepertoireError, match="gain must be in"):
        integrator_update(zero, Q0, pose, pose, [1, 1, 1, 1], gain=np.nan, decay=0.9, limit=0.04)
    with pytest.raises(RepertoireError, match="limit must be > 0 m, got 0"):
        integrator_update(zero, Q0, pose, pose, [1, 1, 1, 1], gain=0.5, decay=0.9, limit=0.0)
    with pytest.raises(RepertoireError, match="12-vector"):
        integrator_update(zero, Q0[:11], pose, pose, [1, 1, 1, 1], **kw)
    with pytest.raises(RepertoireError, match="integrators must be a finite 4 x 3"):
        corrected_angles(Q0, np.full((4, 3), np.nan))  # used to fall back silently
    with pytest.raises(RepertoireError, match=r"got shape \(12,\)"):
        corrected_angles(Q0, np.zeros(12))
    q, fallbacks = corrected_angles(Q0, zero)
    assert fallbacks == 0
    np.testing.assert_allclose(q, Q0, rtol=0, atol=1e-12)


def test_tile_boards_places_moved_and_joined_boards_by_their_boxes():
    a = generate_board(TerrainParams(kind="rocks"), 1)
    b = generate_board(TerrainParams(kind="flat"), 2)
    tiled = tile_boards([a.translated(1.0, 0.5), b])
    np.testing.assert_allclose(tiled.bounds(), [-0.6, 0.6, -0.3, 0.3], rtol=0, atol=1e-12)
    x, y = np.meshgrid(np.linspace(-0.29, 0.29, 30), np.linspace(-0.29, 0.29, 30))
    np.testing.assert_array_equal(tiled.height(x - 0.3, y), a.height(x, y))
    np.testing.assert_array_equal(tiled.height(x + 0.3, y), b.height(x, y))
    assert tiled.params.size_x == pytest.approx(1.2, abs=1e-12)


@pytest.mark.parametrize("count", [np.nan, np.inf, "3"])
def test_terrain_counts_that_are_not_integers_get_a_clear_error(count):
    with pytest.raises(RepertoireError, match="rock_count must be a non-negative integer"):
        generate_board(TerrainParams(kind="rocks", rock_count=count))


@pytest.mark.parametrize("seed", [-1, np.nan, None])
def test_terrain_seeds_must_be_non_negative_integers(seed):
    with pytest.raises(RepertoireError, match="terrain seed must be an integer"):
        generate_board(TerrainParams(kind="rocks"), seed)
    with pytest.raises(RepertoireError, match="rock field seed must be an integer"):
        rock_field(0.0, 0.2, TerrainParams(), seed)


@pytest.mark.parametrize(
    "field, value, message",
    [
        ("foot", np.nan, "foot must be 0..3"),
        ("foot", "a", "foot must be 0..3"),
        ("direction", None, "direction must be a finite number"),
        ("direction", "x", "direction must be a finite number"),
        ("times", np.array(["a", "b", "c"]), "times must hold numbers"),
    ],
)
def test_library_step_bad_fields_raise_step_library_errors(field, value, message):
    with pytest.raises(StepLibraryError, match=message):
        _step(**{field: value})


def _corrupt(tmp_path, meta=None, arrays=None):
    StepLibrary([_step(0.0), _step(0.01, foot=2)]).save(tmp_path / "lib")
    if meta:
        m = json.loads((tmp_path / "lib.json").read_text())
        m.update(meta)
        (tmp_path / "lib.json").write_text(json.dumps(m))
    if arrays:
        with np.load(tmp_path / "lib.npz") as data:
            a = {k: data[k] for k in data.files}
        a.update({k: f(a[k]) for k, f in arrays.items()})
        np.savez(tmp_path / "lib.npz", **a)
    return tmp_path / "lib"


@pytest.mark.parametrize(
    "meta, arrays",
    [
        (dict(num_steps="x"), None),
        (dict(num_steps=None), None),
        (dict(terrain=None), None),
        (dict(kind=3), None),
        (None, dict(start_feet=lambda v: v[:1])),
        (None, dict(direction=lambda v: v[:1])),
        (None, dict(foot=lambda v: v + 0.5)),  # used to be truncated to an int silently
    ],
)
def test_corrupt_library_files_raise_step_library_errors(tmp_path, meta, arrays):
    with pytest.raises(StepLibraryError, match="inconsistent step counts"):
        StepLibrary.load(_corrupt(tmp_path, meta, arrays))


def test_library_file_with_text_arrays_is_refused(tmp_path):
    path = _corrupt(tmp_path, arrays=dict(times=lambda v: v.astype(str)))
    with pytest.raises(StepLibraryError, match=r"\['times'\] must hold floating-point"):
        StepLibrary.load(path)


def _stance(cx: float) -> np.ndarray:
    return np.array(
        [[cx + 0.1, 0.06, 0], [cx + 0.1, -0.06, 0], [cx - 0.1, 0.06, 0], [cx - 0.1, -0.06, 0]]
    )


def _no_gap(start, target, time_limit):
    return GapFill([], "failed", "no planner")


def test_search_transfer_bad_inputs_raise_transfer_search_errors():
    ins = np.stack([_stance(0.03 * i) for i in range(3)])
    args = (_stance(0.0), _stance(0.1))
    with pytest.raises(TransferSearchError, match=r"step_start_feet must be a finite \(M, 4, 3\)"):
        search_transfer(*args, np.zeros((5, 4, 2)), np.zeros((5, 4, 2)), _no_gap)
    with pytest.raises(TransferSearchError, match="step_start_feet must be a finite array"):
        search_transfer(*args, "x", ins, _no_gap)
    with pytest.raises(TransferSearchError, match="terrain must be a TerrainBoard, got str"):
        search_transfer(*args, ins, ins, _no_gap, terrain="x")
    with pytest.raises(TransferSearchError, match="config must be a SearchConfig, got dict"):
        search_transfer(*args, ins, ins, _no_gap, config={"neighbours": 2})
    with pytest.raises(TransferSearchError, match="neighbours must be a positive integer"):
        search_transfer(*args, ins, ins, _no_gap, config=SearchConfig(neighbours=np.nan))
    with pytest.raises(TransferSearchError, match="a list of steps"):
        search_transfer(*args, ins, ins, lambda s, t, tl: GapFill(None, "reached"))
    # (M, 12) stacks are still accepted, and an unreachable goal is reported.
    result = search_transfer(*args, ins.reshape(3, 12), ins.reshape(3, 12), _no_gap)
    assert result.status == "unreachable"


def test_height_grid_too_large_for_memory_is_refused_with_the_figure():
    from repertoire.limits import ResourceLimitError

    board = generate_board(TerrainParams())
    with pytest.raises(ResourceLimitError, match=r"height grid of 35000 x 20000 points .* GiB"):
        board.height_grid([0.0, 0.0], resolution=1e-5)
    assert board.height_grid([0.0, 0.0])[1].shape == (16, 29)
