"""LittleDog step library: pose math, StepLibrary, segmentation, crawl, policy, executor,
integral controller (plain functions and LeafSystems with FixValue), physics smoke runs."""

import dataclasses
import json
import math

import numpy as np
import pytest
from pydrake.math import RollPitchYaw
from repertoire.models.littledog import FOOT_RADIUS, LEGS, leg_fk, leg_ik, standing_configuration
from repertoire.models.littledog.pose import (
    body_to_world,
    rotation_from_rpy,
    rpy_from_rotation,
    world_to_body,
)
from repertoire.models.terrain import TerrainParams, generate_board, join_boards
from repertoire.planning.littledog_crawl import (
    CRAWL_ORDER,
    CrawlError,
    CrawlParams,
    CrawlStep,
    choose_footholds,
    plan_crawl,
    plan_to_steps,
)
from repertoire.planning.step_library import (
    FORMAT_VERSION,
    LibraryStep,
    StepLibrary,
    StepLibraryError,
    segment_recording,
)
from repertoire.systems.integral_foot_controller import (
    IntegralFootController,
    body_feet,
    corrected_angles,
    integrator_update,
)
from repertoire.systems.library_policy import (
    LibraryPolicy,
    StepChoice,
    StepIndex,
    foot_distance_sums,
    front_progress,
)
from repertoire.systems.step_executor import (
    StepExecutor,
    blend_pose,
    cubic_blend,
    interpolate_step,
    spline_duration,
)

from repertoire.errors import RepertoireError

Q0 = standing_configuration(0.14)


def make_step(rng, *, foot=0, n=5, shift=0.0, **overrides) -> LibraryStep:
    feet = body_to_world([shift, 0, 0.14, 0, 0, 0], body_feet(Q0))
    fields = dict(
        start_feet=feet + rng.normal(0, 0.01, (4, 3)),
        start_pose=np.array([shift, 0.0, 0.14, 0.0, 0.0, 0.0]),
        times=np.arange(n) * 0.01,
        q=np.repeat(Q0[None], n, 0) + rng.normal(0, 0.01, (n, 12)),
        body_pose=np.tile([shift, 0.0, 0.14, 0.0, 0.0, 0.0], (n, 1)),
        stance=np.ones((n, 4), bool),
        foot=foot,
        terrain="t",
        direction=0.0,
    )
    fields.update(overrides)
    return LibraryStep(**fields)


@pytest.fixture
def library():
    rng = np.random.default_rng(0)
    return StepLibrary([make_step(rng, foot=i % 4, shift=0.01 * i) for i in range(6)])


# ---------------------------------------------------------------- pose math


def test_pose_functions_match_drake_and_invert():
    rpy = [0.1, -0.2, 2.5]
    assert np.allclose(rotation_from_rpy(rpy), RollPitchYaw(rpy).ToRotationMatrix().matrix())
    assert np.allclose(rpy_from_rotation(rotation_from_rpy(rpy)), rpy)
    pose = [0.3, -0.1, 0.2, *rpy]
    p = np.random.default_rng(1).normal(size=(4, 3))
    assert np.allclose(world_to_body(pose, body_to_world(pose, p)), p)


# ---------------------------------------------------------------- StepLibrary


def test_library_save_load_is_exact(library, tmp_path):
    npz, js = library.save(tmp_path / "lib")
    assert npz.is_file() and js.is_file()
    loaded = StepLibrary.load(tmp_path / "lib.json")
    assert len(loaded) == len(library)
    for a, b in zip(library, loaded):
        for f in dataclasses.fields(LibraryStep):
            va, vb = getattr(a, f.name), getattr(b, f.name)
            assert np.array_equal(va, vb), f.name
    assert np.array_equal(loaded.keys, library.keys)
    assert not list(tmp_path.glob("*.tmp"))


def test_library_transform_closed_form_and_inverse(library):
    moved = library.transformed(0.5, -0.2, math.pi / 2)
    s, m = library[0], moved[0]
    # A quarter turn maps (x, y) to (-y, x), then the shift.
    assert np.allclose(m.start_feet[:, 0], -s.start_feet[:, 1] + 0.5)
    assert np.allclose(m.start_feet[:, 1], s.start_feet[:, 0] - 0.2)
    assert np.allclose(m.start_feet[:, 2], s.start_feet[:, 2])
    assert np.isclose(m.start_pose[5], math.pi / 2)
    assert np.array_equal(m.q, s.q) and np.array_equal(m.times, s.times)
    back = moved.transformed(-0.5, 0.2, 0.0).transformed(0.0, 0.0, -math.pi / 2)
    assert np.allclose(back[0].start_feet, s.start_feet)
    assert np.allclose(back[0].body_pose, s.body_pose)


def test_library_concatenate_and_counts(library):
    both = library + library.transformed(0.0, 0.0, math.pi)
    assert len(both) == 12
    assert both.counts() == {"t/0": 6, "t/180": 6}
    planned = make_step(np.random.default_rng(3), kind="planned")
    assert library.appended([planned])[6].kind == "planned"


def test_library_bad_input(library, tmp_path):
    rng = np.random.default_rng(2)
    with pytest.raises(StepLibraryError, match="at least one step"):
        StepLibrary([])
    with pytest.raises(StepLibraryError, match="stance labels are missing"):
        make_step(rng, stance=None)
    with pytest.raises(StepLibraryError, match="stance labels must be T x 4"):
        make_step(rng, stance=np.ones((5, 3), bool))
    with pytest.raises(StepLibraryError, match="start with all four feet down"):
        make_step(rng, stance=np.array([[1, 0, 1, 1]] * 5, bool))
    q = np.repeat(Q0[None], 5, 0)
    q[2, 4] = np.nan
    with pytest.raises(StepLibraryError, match="q contains NaN"):
        make_step(rng, q=q)
    q[2, 4] = 5.0
    with pytest.raises(StepLibraryError, match=r"joint angle 4 \(rf\) = 5.000 rad .* limits"):
        make_step(rng, q=q)
    library.save(tmp_path / "lib")
    meta = json.loads((tmp_path / "lib.json").read_text())
    meta["format_version"] = FORMAT_VERSION + 1
    (tmp_path / "lib.json").write_text(json.dumps(meta))
    with pytest.raises(StepLibraryError, match="format version 2; this code reads version 1"):
        StepLibrary.load(tmp_path / "lib")
    with pytest.raises(StepLibraryError, match="does not exist"):
        StepLibrary.load(tmp_path / "missing")


def test_segment_recording_by_stance():
    n = 100
    times = np.arange(n) * 0.01
    contact = np.ones((n, 4))
    contact[20:45, 2] = 0  # lh in flight
    contact[50:52, 1] = 0  # flicker, not a step
    contact[60:85, 0] = 0  # lf in flight
    feet = np.repeat(body_feet(Q0)[None], n, 0) + np.arange(n)[:, None, None] * 1e-4
    pose = np.zeros((n, 6))
    q = np.repeat(Q0[None], n, 0)
    steps = segment_recording(times, q, pose, feet, contact, terrain="t", direction=0.0, settle=5)
    assert [s.foot for s in steps] == [2, 0]
    # Touchdown at sample 45, settling until the flicker at 50 breaks "all four down".
    assert len(steps[0].times) == 50 and np.isclose(steps[0].times[-1], 0.49)
    assert np.array_equal(steps[1].start_feet, feet[49])
    assert len(steps[1].times) == 90 - 49 + 1
    assert steps[1].stance[:, 0].sum() == len(steps[1].times) - 25
    contact[30:40, 3] = 0
    contact[25:45, 1] = 0
    with pytest.raises(StepLibraryError, match="in flight together"):
        segment_recording(times, q, pose, feet, contact, terrain="t", direction=0.0)


# ---------------------------------------------------------------- policy


def test_step_index_is_exact_nearest_by_sum_of_distances(library):
    rng = np.random.default_rng(4)
    keys = rng.normal(size=(300, 12))
    feet = rng.normal(size=(50, 12))
    sums = np.array(
        [[np.linalg.norm((f - k).reshape(4, 3), axis=1).sum() for k in keys] for f in feet]
    )
    assert np.allclose(foot_distance_sums(keys, feet), sums)
    lib_steps = []
    for k in keys[:40]:
        lib_steps.append(dataclasses.replace(library[0], start_feet=k.reshape(4, 3)))
    lib = StepLibrary(lib_steps)
    for tree in (True, False):
        index = StepIndex(lib, brute_force_below=0 if tree else 10_000)
        for f, row in zip(feet, sums[:, :40]):
            i, d = index.query(f)
            assert i == int(np.argmin(row)) and np.isclose(d, row.min())
        ib, db = index.query_batch(feet)
        assert np.array_equal(ib, np.argmin(sums[:, :40], axis=1))
    with pytest.raises(RepertoireError, match="NaN"):
        index.query(np.full(12, np.nan))
    with pytest.raises(RepertoireError, match=r"B foot sets .* got \(2, 2, 12\)"):
        index.query_batch(np.zeros((2, 2, 12)))  # used to fail inside numpy broadcasting
    ib, db = index.query_batch(feet[:3].reshape(3, 4, 3))
    assert np.array_equal(ib, np.argmin(sums[:3, :40], axis=1))
    with pytest.raises(RepertoireError, match="feet must be numbers, got 'abc'"):
        index.query("abc")  # was numpy's "could not convert string to float"
    for bad in (-1, 2.5, True):
        with pytest.raises(RepertoireError, match=f"brute_force_below must be .* got {bad}"):
            StepIndex(lib, brute_force_below=bad)


def test_library_policy_chooses_only_with_four_feet_down(library):
    from pydrake.systems.analysis import Simulator

    policy = LibraryPolicy(library)
    context = policy.CreateDefaultContext()
    policy.feet_input.FixValue(context, library.keys[3])
    policy.contact_input.FixValue(context, [1, 1, 0, 1])
    simulator = Simulator(policy, context)
    simulator.AdvanceTo(0.505)
    assert policy.choice_output.Eval(context).index == -1
    policy.contact_input.FixValue(context, [1, 1, 1, 1])
    simulator.AdvanceTo(0.515)  # the update at t = 0.51 chooses
    choice = policy.choice_output.Eval(context)
    assert choice.index == 3 and choice.distance == 0.0 and np.isclose(choice.time, 0.51)
    policy.contact_input.FixValue(context, [1, 1, np.nan, 1])  # not "down": an error
    with pytest.raises(RepertoireError, match="contact flags must be finite"):
        simulator.AdvanceTo(0.525)


def test_library_policy_stops_choosing_past_its_goal_line(library):
    from pydrake.systems.analysis import Simulator

    feet = np.asarray(library.keys[3], dtype=float)
    front = min(feet[0], feet[3])  # x of lf and rf (heading 0: the x axis)
    policy = LibraryPolicy(library, goal_line=(0.0, front + 1e-3))
    context = policy.CreateDefaultContext()
    policy.feet_input.FixValue(context, feet)
    policy.contact_input.FixValue(context, [1, 1, 1, 1])
    simulator = Simulator(policy, context)
    simulator.AdvanceTo(0.005)  # before the line: the nearest step, as without a goal
    choice = policy.choice_output.Eval(context)
    assert choice.index == 3 and choice.distance == 0.0 and choice.time == 0.0
    assert not policy.past_goal(feet)
    moved = feet.copy()
    moved[[0, 3]] += 2e-3  # both front feet past the line, the hind ones not
    assert policy.past_goal(moved)
    policy.feet_input.FixValue(context, moved)
    simulator.AdvanceTo(0.505)
    assert policy.choice_output.Eval(context) == choice  # no new choice: the robot holds
    one = moved.copy()
    one[3] = front  # the right front foot back before the line: choosing again
    policy.feet_input.FixValue(context, one)
    simulator.AdvanceTo(0.515)
    assert np.isclose(policy.choice_output.Eval(context).time, 0.51)
    # heading pi / 2: the line runs along x, the feet's y decide
    turned = LibraryPolicy(library, goal_line=(np.pi / 2, min(feet[1], feet[4]) - 1e-3))
    assert turned.past_goal(feet)
    # the one crossing test, per row: the hinder front foot's progress along the heading
    rows = np.stack([feet, moved, one])
    assert front_progress(feet, 0.0) == front
    assert front_progress(feet.reshape(4, 3), np.pi / 2) == pytest.approx(min(feet[1], feet[4]))
    np.testing.assert_array_equal(front_progress(rows, 0.0), [front, front + 2e-3, front])
    for bad, msg in (((0.0,), "goal_line must be"), ((np.nan, 1.0), "must be finite"),
                     ("ab", "goal_line must be")):  # fmt: skip
        with pytest.raises(RepertoireError, match=msg):
            LibraryPolicy(library, goal_line=bad)


# ---------------------------------------------------------------- executor


def test_executor_math():
    assert np.allclose(cubic_blend([0, 1], [2, 3], 0.0), [0, 1])
    assert np.allclose(cubic_blend([0, 1], [2, 3], 0.5), [1, 2])
    assert np.allclose(cubic_blend([0, 1], [2, 3], 1.0), [2, 3])
    d = spline_duration(
        [0.03, 0.04, 0, 0, 0, 0.2], [0, 0, 0, 0, 0, 0], min_time=0.1, speed=0.1, turn_rate=0.5
    )
    assert np.isclose(d, 0.1 + 0.05 / 0.1 + 0.2 / 0.5)
    step = make_step(np.random.default_rng(5))
    q, pose = interpolate_step(step, 0.015)
    assert np.allclose(q, 0.5 * (step.q[1] + step.q[2]))
    assert np.allclose(interpolate_step(step, 10.0)[0], step.q[-1])


def test_step_executor_blends_then_plays_back(library):
    executor = StepExecutor(library, Q0, min_time=0.1, speed=0.1, turn_rate=1.0)
    context = executor.CreateDefaultContext()
    step = library[2]
    body = step.start_pose + np.array([0.01, 0, 0, 0, 0, 0])
    executor.body_pose_input.FixValue(context, body)
    executor.choice_input.FixValue(context, StepChoice(2, 0.0, 1.0))
    context.SetTime(1.0)
    v = executor.EvalUniquePeriodicDiscreteUpdate(context).get_vector(0).value().copy()
    assert v[0] == 2 and v[1] == 1.0 and np.isclose(v[2], 0.1 + 0.01 / 0.1)
    assert np.array_equal(v[15:21], body)  # the pose the ideal pose blends from
    assert np.allclose(v[21:33], Q0)  # the blend starts at the last played angles
    assert np.allclose(v[33:39], body)  # ... and at the measured pose
    context.SetDiscreteState(v)
    # Half way through the 0.2 s blend; the body has moved on, the blend's origin has not.
    executor.body_pose_input.FixValue(context, body + 0.5)
    context.SetTime(1.0 + 0.1)
    v = executor.EvalUniquePeriodicDiscreteUpdate(context).get_vector(0).value().copy()
    assert np.allclose(v[21:33], 0.5 * (Q0 + step.q[0]))
    assert np.array_equal(v[15:21], body)
    context.SetDiscreteState(v)
    assert np.allclose(executor.q_playback_output.Eval(context), 0.5 * (Q0 + step.q[0]))
    half = step.start_pose + np.array([0.005, 0, 0, 0, 0, 0])
    assert np.allclose(executor.ideal_pose_output.Eval(context), half, atol=1e-12)
    assert executor.step_index_output.Eval(context)[0] == 2
    context.SetTime(1.0 + 0.2 + 0.015)  # playback: between samples 1 and 2
    v = executor.EvalUniquePeriodicDiscreteUpdate(context).get_vector(0).value().copy()
    assert np.allclose(v[21:33], 0.5 * (step.q[1] + step.q[2]))
    assert np.allclose(v[33:39], interpolate_step(step, 0.015)[1])


def test_step_executor_names_bad_inputs(library):
    # A NaN body pose used to end in "IndexError: index 5 is out of bounds" (a NaN blend
    # time), a choice beyond the library in "list index out of range".
    from pydrake.common.value import AbstractValue
    from pydrake.systems.analysis import Simulator

    for body, index, match in (
        (np.full(6, np.nan), 0, "body_pose must be finite"),
        ([0.0, 0.0, 0.14, 0.0, 0.0, np.inf], 0, "body_pose must be finite"),
        ([0.0, 0.0, 0.14, 0.0, 0.0, 0.0], len(library), "chose step 6 of a library of 6"),
    ):
        executor = StepExecutor(library, Q0)
        context = executor.CreateDefaultContext()
        executor.body_pose_input.FixValue(context, body)
        executor.choice_input.FixValue(context, AbstractValue.Make(StepChoice(index, 0.0, 0.0)))
        with pytest.raises(RepertoireError, match=match):
            Simulator(executor, context).AdvanceTo(0.05)


def test_blend_pose_closed_form_and_shorter_way():
    a = np.array([0.0, 0.0, 0.1, 0.0, 0.0, 3.0])
    b = np.array([0.2, -0.1, 0.1, 0.0, 0.2, -3.0])  # yaw: 0.283 rad the short way round
    assert np.array_equal(blend_pose(a, b, 0.0), a)
    end = blend_pose(a, b, 1.0)
    assert np.allclose(end[:5], b[:5]) and np.isclose(end[5], 2 * np.pi - 3.0)
    h = 0.25 * 0.25 * (3 - 2 * 0.25)  # the cubic at s = 0.25: 0.15625
    mid = blend_pose(a, b, 0.25)
    assert np.allclose(mid, a + h * np.array([0.2, -0.1, 0.0, 0.0, 0.2, 2 * np.pi - 6.0]))
    assert np.array_equal(blend_pose(a, b, 2.0), blend_pose(a, b, 1.0))  # s clipped


# ---------------------------------------------------------------- integral controller


def test_integrator_update_closed_form():
    I0 = np.zeros((4, 3))
    ideal = np.array([0.0, 0.0, 0.14, 0.0, 0.0, 0.0])
    body = ideal + np.array([0.02, -0.01, 0.0, 0, 0, 0])
    new = integrator_update(I0, Q0, body, ideal, [1, 1, 1, 0], gain=0.1, decay=0.5, limit=1.0)
    assert np.allclose(new[:3], [[0.002, -0.001, 0.0]] * 3)
    assert np.allclose(new[3], 0.0)
    flying = integrator_update(
        np.ones((4, 3)) * 0.01, Q0, ideal, ideal, [0, 0, 0, 0], gain=0.1, decay=0.5, limit=1.0
    )
    assert np.allclose(flying, 0.005)
    sat = integrator_update(I0, Q0, body, ideal, [1, 1, 1, 1], gain=1.0, decay=0.5, limit=0.01)
    assert np.allclose(np.linalg.norm(sat, axis=1), 0.01)


def test_corrected_angles_move_the_feet_by_the_integrators():
    q, fallbacks = corrected_angles(Q0, np.zeros((4, 3)))
    assert np.allclose(q, Q0) and fallbacks == 0
    offsets = np.array([[0.01, 0.0, 0.0], [0.0, 0.01, 0.0], [0.0, 0.0, 0.01], [0.0, 0.0, 0.0]])
    q, _ = corrected_angles(Q0, offsets)
    for i, leg in enumerate(LEGS):
        assert np.allclose(leg_fk(leg, q[3 * i : 3 * i + 3]), body_feet(Q0)[i] + offsets[i])


def test_corrected_angles_saturate_at_the_leg_workspace():
    # Standing at 0.17 m every foot hangs 0.1597 m below its hip pitch axis, 17.4 mm
    # short of the straight leg (0.1771 m): a 40 mm downward correction is cut there,
    # not dropped (it used to fall back to the played-back angles on all four legs).
    from repertoire.models.littledog.kinematics import LOWER_LEG_LENGTH, UPPER_LEG_LENGTH

    q0 = standing_configuration(0.17)
    down = np.tile([0.0, 0.0, -0.04], (4, 1))
    q, saturated = corrected_angles(q0, down)
    assert saturated == 4
    feet = body_feet(q)
    assert np.allclose(feet[:, :2], body_feet(q0)[:, :2], atol=1e-12)
    straight = -(UPPER_LEG_LENGTH + LOWER_LEG_LENGTH)
    assert np.all(feet[:, 2] >= straight - 1e-12)
    assert np.all(feet[:, 2] <= straight + 0.04 / 64**2)
    q, saturated = corrected_angles(q0, 0.25 * down)  # 10 mm: within reach
    assert saturated == 0 and np.allclose(body_feet(q), body_feet(q0) + 0.25 * down)


def test_corrected_angles_keep_the_played_back_knee_branch():
    # A front knee bent backwards (+0.3 rad, within its limits [-3.1, 1.0]) used to be
    # flipped to the -0.3 rad branch by the IK, even with zero integrators.
    q0 = standing_configuration(0.14)
    q0[0:3] = [0.0, -0.3, 0.3]
    q0[6:9] = [0.0, 0.3, -0.3]  # a hind knee bent forwards
    q, saturated = corrected_angles(q0, np.zeros((4, 3)))
    assert saturated == 0 and np.array_equal(q, q0)
    offsets = np.full((4, 3), 0.001)
    q, saturated = corrected_angles(q0, offsets)
    assert saturated == 0
    assert np.allclose(body_feet(q), body_feet(q0) + offsets)
    assert q[2] > 0.0 and q[8] < 0.0  # the played-back branches (else -0.35, +0.37)


def test_corrected_angles_keep_the_played_back_roll_branch():
    # An lf leg with its foot 7 mm above its hip pitch axis (knee bent by 2.1 rad): the
    # same foot is also reached with the foot below it, roll +0.2959 rad, both within the
    # limits. The IK's own choice (below) flipped the roll by 0.58 rad for a 1 mm correction.
    from repertoire.models.littledog.kinematics import foot_above_pitch_axis

    folded = np.array([-0.28, -0.34, -2.1])
    assert foot_above_pitch_axis(folded)
    p = leg_fk("lf", folded)
    np.testing.assert_allclose(leg_ik("lf", p), [0.2959, -0.1839, -2.1], atol=1e-4)
    np.testing.assert_allclose(leg_ik("lf", p, foot_above=True), folded, atol=1e-12)
    q0 = standing_configuration(0.14)
    q0[0:3] = folded
    offsets = np.zeros((4, 3))
    offsets[0] = [0.0, 0.0, 0.001]
    q, saturated = corrected_angles(q0, offsets)
    assert saturated == 0
    np.testing.assert_allclose(body_feet(q), body_feet(q0) + offsets, atol=1e-12)
    assert np.abs(q[0:3] - folded).max() < 0.05 and np.array_equal(q[3:], q0[3:])
    with pytest.raises(RepertoireError, match="foot_above must be True, False or None, got 1"):
        leg_ik("lf", p, foot_above=1)


def test_integral_controller_system_with_fixed_inputs():
    ctrl = IntegralFootController(gain=0.1, decay=0.5, limit=1.0)
    context = ctrl.CreateDefaultContext()
    ideal = np.array([0.0, 0.0, 0.14, 0.0, 0.0, 0.0])
    body = ideal + np.array([0.02, 0, 0, 0, 0, 0])
    ctrl.q_playback_input.FixValue(context, Q0)
    ctrl.ideal_pose_input.FixValue(context, ideal)
    ctrl.body_pose_input.FixValue(context, body)
    ctrl.joint_angles_input.FixValue(context, Q0)
    ctrl.contact_input.FixValue(context, [1, 1, 1, 1])
    assert np.allclose(ctrl.q_desired_output.Eval(context), Q0)
    x = ctrl.EvalUniquePeriodicDiscreteUpdate(context).get_vector(0).value().copy()
    expected = integrator_update(
        np.zeros((4, 3)), Q0, body, ideal, [1] * 4, gain=0.1, decay=0.5, limit=1.0
    )
    assert np.allclose(x, expected.ravel())
    context.SetDiscreteState(x)
    assert np.allclose(ctrl.q_desired_output.Eval(context), corrected_angles(Q0, expected)[0])
    ctrl.set_gains(context, 0.0, 0.5)  # the ablation: no correction
    x2 = ctrl.EvalUniquePeriodicDiscreteUpdate(context).get_vector(0).value()
    assert np.allclose(x2, expected.ravel())
    with pytest.raises(RepertoireError, match="gain must be in"):
        IntegralFootController(gain=2.0)


# ---------------------------------------------------------------- crawl


def _flat_start():
    board = generate_board(TerrainParams(kind="flat"))
    feet = body_to_world([0, 0, 0.18, 0, 0, 0], body_feet(standing_configuration(0.14)))
    return board, feet, np.array([0, 0, 0.18, 0, 0, 0.0])


def test_crawl_on_flat_board_follows_the_gait_and_reaches_the_goal():
    board, feet, pose = _flat_start()
    params = CrawlParams()
    steps = choose_footholds(board, feet, 0.0, 0.15, params)
    assert [s.foot for s in steps[:4]] == CRAWL_ORDER
    plan = plan_crawl(feet, pose, steps, board, params)
    assert np.all(plan.feet[-1][:2, 0] >= 0.15) and np.any(plan.feet[-2][:2, 0] < 0.15)
    assert plan.q.shape == (len(plan.times), 12) and np.all(np.isfinite(plan.q))
    # A flying foot is planned off the ground for exactly its swing samples.
    swing = round(params.swing_time / params.dt)
    assert np.sum(~plan.stance[:, CRAWL_ORDER[0]]) == swing * (
        sum(s.foot == CRAWL_ORDER[0] for s in steps)
    )
    assert np.allclose(plan.feet[-1][[s.foot for s in steps[-4:]]], [s.p_WF for s in steps[-4:]])


def test_scripted_operator_chooses_only_footholds_the_crawl_can_reach():
    # On these rocks, crossed towards -y, the nearest safe foothold of step 2 used to
    # need hip_roll = -0.604 rad (limit 0.6) at the crawl's swing pose: plan_crawl failed
    # after the operator had chosen it. The operator now skips footholds out of reach.
    from repertoire.diagrams.littledog_demos import crossing_start, flat_start
    from repertoire.models.terrain import tile_boards
    from repertoire.planning.littledog_crawl import step_reachable

    board = tile_boards(
        [generate_board(TerrainParams(kind="rocks", size_x=0.4, size_y=0.8), s) for s in (12, 13)]
    )
    params, heading = CrawlParams(), -0.5 * math.pi
    off = flat_start(board, heading, 0.25, params)
    pose, feet, _ = crossing_start(board, heading, 0.25, params.standing_height, off)
    steps = choose_footholds(board, feet, heading, 0.23, params)
    plan = plan_crawl(feet, pose, steps, board, params)
    for k, step in enumerate(steps):
        assert step_reachable(plan.feet[k], step.foot, step.p_WF[None], params, board)[0]


def test_plan_to_steps_gives_planned_library_steps():
    board, feet, pose = _flat_start()
    steps = choose_footholds(board, feet, 0.0, 0.13)
    plan = plan_crawl(feet, pose, steps, board)
    lib = StepLibrary(plan_to_steps(plan, terrain="flat", direction=0.0))
    assert len(lib) == len(steps) and {s.kind for s in lib} == {"planned"}
    assert [s.foot for s in lib] == [s.foot for s in steps]
    assert np.allclose(lib[0].start_feet, feet)
    for k in range(1, len(lib)):
        assert np.allclose(lib[k].start_feet, plan.feet[k])  # footholds after step k - 1


def test_crawl_bad_input():
    board, feet, pose = _flat_start()
    with pytest.raises(CrawlError, match="foot must be 0..3"):
        CrawlStep(4, [0, 0, 0])
    with pytest.raises(CrawlError, match="at least one CrawlStep"):
        plan_crawl(feet, pose, [], board)
    too_high = pose + np.array([0, 0, 0.1, 0, 0, 0])
    with pytest.raises(
        CrawlError,
        match=r"start pose cannot be reached: leg lf: foot target "
        r"out of reach \(hip-to-foot distance in the leg plane 0.2327 m.* missed by 0.0556 m\)",
    ):
        plan_crawl(feet, too_high, [CrawlStep(0, feet[0])], board)
    with pytest.raises(CrawlError, match="time limit"):
        choose_footholds(board, feet, 0.0, 5.0, time_limit=0.0)
    # A foothold off the ground: a foot commanded into the terrain (a placing move onto a
    # goal stance with the start's heights put feet 4 cm into rocks) or into the air.
    ground = board.params.base_thickness + FOOT_RADIUS
    steps = choose_footholds(board, feet, 0.0, 0.15)
    assert steps[1].p_WF[2] == pytest.approx(ground)
    for dz, side in ((-0.04, "below"), (0.0051, "above")):
        bad = CrawlStep(steps[1].foot, steps[1].p_WF + [0.0, 0.0, dz])
        with pytest.raises(
            CrawlError,
            match=rf"step 1 \(moving foot {LEGS[bad.foot]}\) foothold centre .* lies "
            rf"{abs(dz):.4f} m {side} the ground plus the foot radius \(at most 0.005 m\)",
        ):
            plan_crawl(feet, pose, [steps[0], bad, *steps[2:]], board)
    ok = CrawlStep(steps[1].foot, steps[1].p_WF + [0.0, 0.0, 0.0049])  # within the tolerance
    plan_crawl(feet, pose, [steps[0], ok], board)
    with pytest.raises(CrawlError, match="ground_tolerance must be in"):
        plan_crawl(feet, pose, steps, board, CrawlParams(ground_tolerance=-0.001))

    class Jagged:  # every spot is an edge
        def height(self, x, y):
            return 0.01 * ((np.floor(np.asarray(x) / 0.004) + np.floor(np.asarray(y) / 0.004)) % 2)

    with pytest.raises(CrawlError, match="no safe foothold for foot lh .* no crossable path"):
        choose_footholds(Jagged(), feet, 0.0, 0.3)


def test_join_boards_height_is_each_board_shifted():
    p = TerrainParams(kind="rocks", size_x=0.4, size_y=0.8, rock_count=5)
    a, b = generate_board(p, 1), generate_board(p, 2)
    joined = join_boards([a, b], [[-0.2, 0.0], [0.2, 0.0]])
    assert np.isclose(joined.height(-0.25, 0.1), a.height(-0.05, 0.1))
    assert np.isclose(joined.height(0.1, -0.3), b.height(-0.1, -0.3))
    with pytest.raises(RepertoireError, match="one finite"):
        join_boards([a], [[0.0, 0.0], [1.0, 0.0]])


def test_default_library_is_recorded_crossing_by_crossing_and_resumes(tmp_path, monkeypatch):
    import types

    import repertoire.diagrams.littledog_library as ll
    from repertoire.diagrams.littledog_demos import library_crossings, library_terrain

    monkeypatch.chdir(tmp_path)  # the default library lives under ./out
    jobs = library_crossings()
    assert len(jobs) == 7  # the two library terrains, 7 crossings in all
    rng = np.random.default_rng(3)
    steps = {job: [make_step(rng, foot=k % 4, shift=0.01 * k)] for k, job in enumerate(jobs)}
    recorded = []

    def fake_crossing(terrain, direction):
        job = next(j for j in jobs if library_terrain(j[0]) == terrain and j[1] == direction)
        recorded.append(job)
        if len(recorded) == 3:
            raise KeyboardInterrupt  # the user stops the third crossing
        return types.SimpleNamespace(steps=steps[job])

    monkeypatch.setattr(ll, "record_crossing", fake_crossing)
    with pytest.raises(KeyboardInterrupt):
        ll.load_library("")
    assert not ll.DEFAULT_LIBRARY.with_suffix(".json").exists()
    assert len(list(ll._CROSSINGS.glob("*.json"))) == 2  # the two finished crossings kept
    library = ll.load_library("")  # resumes: the two kept crossings are not recorded again
    assert recorded == jobs[:3] + jobs[2:]
    want = [s for job in jobs for s in steps[job]]
    assert len(library) == len(want)
    assert all(np.array_equal(a.q, b.q) for a, b in zip(library.steps, want, strict=True))
    assert len(list(ll._CROSSINGS.glob("*.json"))) == len(jobs)  # one library per crossing
    assert ll.load_library("") is not None and len(recorded) == len(jobs) + 1  # cached now


def test_default_library_is_recorded_once_by_processes_asking_at_once(tmp_path, monkeypatch):
    import threading
    import types

    import repertoire.diagrams.littledog_library as ll

    monkeypatch.chdir(tmp_path)  # the default library lives under ./out
    rng = np.random.default_rng(4)
    step = make_step(rng, foot=1)
    calls, started, release = [], threading.Event(), threading.Event()

    def slow_crossing(terrain, direction):
        calls.append(direction)
        started.set()
        release.wait(10.0)  # the second caller arrives while this one is recording
        return types.SimpleNamespace(steps=[step])

    monkeypatch.setattr(ll, "record_crossing", slow_crossing)
    libraries = []
    first = threading.Thread(target=lambda: libraries.append(ll.load_library("")))
    second = threading.Thread(target=lambda: libraries.append(ll.load_library("")))
    first.start()
    assert started.wait(10.0)
    second.start()  # opens the lock file itself: blocked until the first has saved
    second.join(0.3)
    assert second.is_alive()
    release.set()
    first.join(10.0)
    second.join(10.0)
    assert len(calls) == 7  # each crossing recorded once, by the first caller
    assert [len(lib) for lib in libraries] == [7, 7]
