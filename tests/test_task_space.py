"""Tests of systems/task_space.py: the RMRC math and the ResolvedMotionRateIK LeafSystem."""

import numpy as np
import pytest
from pydrake.math import RollPitchYaw, RotationMatrix
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.systems.analysis import Simulator
from repertoire.systems.task_space import (
    STATUS_JOINT_LIMITS,
    STATUS_OK,
    STATUS_TARGET_OUT_OF_REACH,
    STATUS_TRACKING_LOST,
    ResolvedMotionRateIK,
    damped_pseudoinverse,
    joint_limit_barrier_gradient,
    joint_limit_gradient,
    joint_limit_potential_gradient,
    joint_velocity_bounds,
    joints_held_at_limits,
    null_space_projector,
    quaternion_error,
    quaternion_multiply,
    rmrc_joint_velocity,
    speed_bounded_scale,
)
from repertoire.systems.task_space_reach import (
    check_reachable,
    pose_position_residual,
    reach_bound,
)

from repertoire.errors import RepertoireError

# A 7-DOF test arm written here so the tests need no other model: z-y-z shoulder,
# y elbow, z-y-z wrist; links of 0.3 m, 0.3 m and 0.1 m.
AXES = ["0 0 1", "0 1 0", "0 0 1", "0 1 0", "0 0 1", "0 1 0", "0 0 1"]
OFFSETS = [0.1, 0.0, 0.15, 0.15, 0.15, 0.15, 0.05]


def _arm_urdf(limits: dict[int, tuple[float, float]] | None = None) -> str:
    """The test arm; ``limits`` replaces the +-2.9 rad limits of the joints it names (0-6)."""
    limits = limits or {}
    links = ['<link name="base"/>']
    joints = []
    for i in range(7):
        links.append(
            f'<link name="l{i + 1}"><inertial><mass value="1"/>'
            f'<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>'
        )
        parent = "base" if i == 0 else f"l{i}"
        low, up = limits.get(i, (-2.9, 2.9))
        joints.append(
            f'<joint name="j{i + 1}" type="revolute"><parent link="{parent}"/>'
            f'<child link="l{i + 1}"/><origin xyz="0 0 {OFFSETS[i]}"/><axis xyz="{AXES[i]}"/>'
            f'<limit lower="{low}" upper="{up}" effort="100" velocity="3"/></joint>'
        )
    links.append('<link name="ee"/>')
    joints.append(
        '<joint name="ee_joint" type="fixed"><parent link="l7"/><child link="ee"/>'
        '<origin xyz="0 0 0.1"/></joint>'
    )
    return '<robot name="arm">' + "".join(links + joints) + "</robot>"


def _make_plant(limits: dict[int, tuple[float, float]] | None = None) -> MultibodyPlant:
    plant = MultibodyPlant(0.0)
    Parser(plant).AddModelsFromString(_arm_urdf(limits), "urdf")
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("base"))
    plant.Finalize()
    return plant


ZERO3 = np.zeros(3)
Q0 = np.array([0.1, 0.5, -0.2, -1.2, 0.3, 0.6, 0.2])


def _pose(plant, q):
    ctx = plant.CreateDefaultContext()
    plant.SetPositions(ctx, q)
    return plant.GetFrameByName("ee").CalcPoseInWorld(ctx)


def _system(plant, **kwargs):
    return ResolvedMotionRateIK(plant, plant.GetFrameByName("ee"), list(range(7)), **kwargs)


def _fix(system, context, p_d, q_d, v_d=ZERO3, w_d=ZERO3, q_meas=Q0):
    system.GetInputPort("position_desired").FixValue(context, p_d)
    system.GetInputPort("velocity_desired").FixValue(context, v_d)
    system.GetInputPort("orientation_desired").FixValue(context, q_d)
    system.GetInputPort("angular_velocity_desired").FixValue(context, w_d)
    system.GetInputPort("arm_state_measured").FixValue(
        context, np.concatenate([q_meas, 0 * q_meas])
    )


def test_quaternion_error_closed_form():
    q = RotationMatrix(RollPitchYaw(0.2, -0.1, 0.4)).ToQuaternion().wxyz()
    assert np.allclose(quaternion_error(q, q), 0.0, atol=1e-15)
    assert np.allclose(quaternion_error(-q, q), 0.0, atol=1e-15)  # double cover
    # Desired = rotation of 0.3 rad about world z applied to q: e = sin(0.15) z.
    r = np.array([np.cos(0.15), 0, 0, np.sin(0.15)])
    e = quaternion_error(quaternion_multiply(r, q), q)
    assert np.allclose(e, [0, 0, np.sin(0.15)], atol=1e-15)
    e = quaternion_error(-quaternion_multiply(r, q), q)
    assert np.allclose(e, [0, 0, np.sin(0.15)], atol=1e-15)


def test_damped_pseudoinverse_and_null_space():
    J = np.array([[1.0, 0.0, 2.0], [0.0, 1.0, 1.0]])
    assert np.allclose(J @ damped_pseudoinverse(J, 0.0), np.eye(2), atol=1e-14)
    assert np.allclose(damped_pseudoinverse(J, 0.0), np.linalg.pinv(J), atol=1e-14)
    closed_form = J.T @ np.linalg.inv(J @ J.T + 0.3**2 * np.eye(2))
    np.testing.assert_allclose(damped_pseudoinverse(J, 0.3), closed_form, rtol=1e-13)
    rank_one = np.array([[1.0, 2.0], [2.0, 4.0]])  # singular J J^T: still the pseudo-inverse
    np.testing.assert_allclose(damped_pseudoinverse(rank_one, 0.0), np.linalg.pinv(rank_one))
    lower, upper = -np.ones(3), 3 * np.ones(3)
    assert np.allclose(joint_limit_gradient(np.ones(3), lower, upper), 0.0)
    assert np.allclose(joint_limit_gradient(np.array([3.0, 1, 1]), lower, upper), [0.25, 0, 0])
    qd = rmrc_joint_velocity(
        J, np.array([1.0, -1.0]), np.array([2.5, 0, 1]), lower, upper, 0.0, 1.0
    )
    assert np.allclose(J @ qd, [1.0, -1.0], atol=1e-14)  # the null-space motion adds no task motion


def _barrier(q, lower, upper, band):
    """B(q) of joint_limit_barrier_gradient, written out per joint."""
    total = 0.0
    for qi, lo, up in zip(q, lower, upper, strict=True):
        d = band * (up - lo)
        if qi > up - d:
            total += ((qi - up + d) / d) ** 2
        elif qi < lo + d:
            total += ((lo + d - qi) / d) ** 2
    return total


def test_joint_limit_barrier_gradient_closed_form():
    lower, upper = -np.ones(4), 3 * np.ones(4)  # range 4; band 0.25: d = 1, active outside [0, 2]
    q = np.array([1.0, 2.0, 2.5, -0.5])
    # middle and band edge: 0; 0.5 into the upper band: 2 * 0.5 / 1; 0.5 into the lower: -1.
    assert np.array_equal(joint_limit_barrier_gradient(q, lower, upper, 0.25), [0, 0, 1.0, -1.0])
    at_limits = joint_limit_barrier_gradient(np.array([3.0, -1, 1, 1]), lower, upper, 0.25)
    assert np.array_equal(at_limits, [2.0, -2.0, 0, 0])  # 2 / d at the limit itself
    rng = np.random.default_rng(3)
    lower, upper = np.array([-0.9, -0.4, -1.6, 0.0]), np.array([2.8, 2.4, 1.6, 2.6])
    for _ in range(20):
        x = rng.uniform(lower, upper)
        grad = joint_limit_barrier_gradient(x, lower, upper, 0.15)
        eps = 1e-6
        fd = [
            (_barrier(x + eps * e, lower, upper, 0.15) - _barrier(x - eps * e, lower, upper, 0.15))
            / (2 * eps)
            for e in np.eye(4)
        ]
        np.testing.assert_allclose(grad, fd, atol=1e-6)
    for band in (0.0, 0.6, np.nan):
        with pytest.raises(RepertoireError, match=r"band must be in \(0, 0.5\]"):
            joint_limit_barrier_gradient(q, lower, upper, band)


def test_null_space_projector_is_the_exact_null_space():
    rng = np.random.default_rng(11)
    J = rng.normal(size=(6, 7))
    N = null_space_projector(J)
    np.testing.assert_allclose(N, np.eye(7) - np.linalg.pinv(J) @ J, atol=1e-12)
    np.testing.assert_allclose(N, N.T, atol=1e-14)
    np.testing.assert_allclose(N @ N, N, atol=1e-13)
    assert np.trace(N) == pytest.approx(1.0)  # rank 6 task, 7 joints: one redundant direction
    x = rng.normal(size=7)
    assert np.linalg.norm(J @ N @ x) < 1e-12 * np.linalg.norm(x)
    # A repeated task row: rank 5, two redundant directions.
    J2 = np.vstack([J[:5], J[4]])
    assert np.trace(null_space_projector(J2)) == pytest.approx(2.0)
    assert np.allclose(J2 @ null_space_projector(J2), 0.0, atol=1e-12)
    assert np.array_equal(null_space_projector(np.zeros((6, 7))), np.eye(7))


def test_speed_bounded_scale_closed_form():
    v = np.array([2.0, 2.0, 2.0])
    # Room per joint: (2 - 1) / 2 = 0.5, (2 + 1) / 2 = 1.5, (2 + 0) / 4 = 0.5.
    assert speed_bounded_scale([1.0, -1.0, 0.0], [2.0, 2.0, -4.0], v) == 0.5
    assert speed_bounded_scale([1.0, -1.0, 0.0], [0.5, 0.5, -0.5], v) == 1.0
    # The task alone past the limit: no more speed that way, any amount the other way.
    assert speed_bounded_scale([3.0], [1.0], [2.0]) == 0.0
    assert speed_bounded_scale([3.0], [-1.0], [2.0]) == 1.0
    assert speed_bounded_scale([0.0, 0.0], [0.0, 0.0], [1.0, 1.0]) == 1.0
    # A round-off component (-1e-17) at a joint the task drives past its bound decided
    # a = 0; below `negligible` it bounds nothing (the other joint: (2 - 0) / 1 > 1).
    assert speed_bounded_scale([-1.6, 0.0], [-1e-17, 1.0], [1.5, 2.0]) == 0.0
    assert speed_bounded_scale([-1.6, 0.0], [-1e-17, 1.0], [1.5, 2.0], negligible=1e-12) == 1.0
    assert speed_bounded_scale([-1.6, 0.0], [-0.1, 1.0], [1.5, 2.0], negligible=1e-12) == 0.0
    with pytest.raises(RepertoireError, match="negligible must be >= 0 rad/s, got nan"):
        speed_bounded_scale([0.0], [1.0], [1.0], negligible=np.nan)


def test_round_off_at_a_joint_the_self_motion_cannot_move_does_not_stop_the_barrier():
    # The test arm's self-motion never changes the elbow (spherical shoulder and wrist),
    # so N's elbow entries are round-off of either sign. With the task driving the elbow
    # past its speed bound, a negative round-off entry set the barrier's motion to 0 on
    # some steps and not on others (arm7, seed 2000 of dmp_obstacle_arm: the reference
    # accelerations alternated +-280 rad/s^2 for 0.2 s). The secondary motion must be
    # the one the other joints' speed room allows, whatever the round-off's sign.
    rng = np.random.default_rng(21)
    plant = _make_plant()
    lower, upper = -2.9 * np.ones(7), 2.9 * np.ones(7)
    v_lim = 1.5 * np.ones(7)
    for _ in range(20):
        q = Q0 + rng.uniform(-0.2, 0.2, size=7)
        q[4] = 2.7  # in the barrier's band (0.1 of the range: above 2.32)
        J = _jacobian(plant, q)
        qd_task = np.zeros(7)
        qd_task[3] = rng.choice([-1.6, 1.6])  # the elbow past its bound of 1.5 rad/s
        args = (J, J @ qd_task, q, lower, upper, 0.0, 0.0)
        task_only = rmrc_joint_velocity(*args)
        qd = rmrc_joint_velocity(*args, limit_gain=3.0, limit_band=0.1, velocity_limits=v_lim)
        null = null_space_projector(J) @ (-3.0 * joint_limit_barrier_gradient(q, lower, upper, 0.1))
        assert abs(null[3]) < 1e-12 * np.max(np.abs(null))  # the elbow: round-off only
        others = np.arange(7) != 3
        a = speed_bounded_scale(task_only[others], null[others], v_lim[others])
        assert a > 0.05
        np.testing.assert_allclose(qd, task_only + a * null, rtol=1e-9, atol=1e-12)


def test_barrier_motion_adds_no_task_velocity_and_keeps_the_speed_bound():
    rng = np.random.default_rng(5)
    lower, upper = -2.9 * np.ones(7), 2.9 * np.ones(7)
    v_max = 1.5 * np.ones(7)
    for _ in range(10):
        J = rng.normal(size=(6, 7))
        xdot = 0.05 * rng.normal(size=6)  # task speeds well below v_max
        q = rng.uniform(-1.0, 1.0, size=7)
        args = (J, xdot, q, lower, upper, 0.02, 0.5)
        base = rmrc_joint_velocity(*args)
        # No joint within the band: the result is the one without the barrier, bit for bit.
        assert np.array_equal(rmrc_joint_velocity(*args, limit_gain=3.0), base)
        q[rng.integers(7)] = rng.choice([-2.8, 2.8])  # one joint 0.1 rad from a limit
        args = (J, xdot, q, lower, upper, 0.02, 0.5)
        base = rmrc_joint_velocity(*args)
        qd = rmrc_joint_velocity(*args, limit_gain=3.0, limit_band=0.1, velocity_limits=v_max)
        assert np.linalg.norm(qd - base) > 1e-3  # it moved
        assert np.linalg.norm(J @ (qd - base)) < 1e-12  # ... in the task's null space
        assert np.all(np.abs(qd) <= np.maximum(v_max, np.abs(base)) + 1e-12)
        # The barrier's motion lowers B to first order: grad B . (qd - base) < 0.
        assert joint_limit_barrier_gradient(q, lower, upper, 0.1) @ (qd - base) < 0.0


def test_joint_limit_potential_gradient_is_the_weighted_sum():
    lower, upper = -np.ones(4), 3 * np.ones(4)  # mid 1, range 4; band 0.25: active outside [0, 2]
    q = np.array([1.0, 2.0, 2.5, -0.5])
    # H' = 2 (q - 1) / 16 = [0, 1/8, 3/16, -3/16]; B' = [0, 0, 1, -1] (closed forms above)
    grad = joint_limit_potential_gradient(
        q, lower, upper, mid_gain=0.5, barrier_gain=3.0, band=0.25
    )
    np.testing.assert_allclose(grad, [0.0, 0.0625, 0.09375 + 3.0, -0.09375 - 3.0], rtol=1e-15)
    # Only the barrier: zero for every joint outside its band.
    only_barrier = joint_limit_potential_gradient(
        np.array([0.0, 1.0, 2.0, 1.7]), lower, upper, mid_gain=0.0, barrier_gain=3.0, band=0.25
    )
    assert np.array_equal(only_barrier, np.zeros(4))
    for kwargs, match in (
        ({"mid_gain": -1.0, "barrier_gain": 1.0}, "mid_gain must be finite and >= 0, got -1.0"),
        ({"mid_gain": 1.0, "barrier_gain": np.nan}, "barrier_gain must be finite and >= 0"),
    ):
        with pytest.raises(RepertoireError, match=match):
            joint_limit_potential_gradient(q, lower, upper, band=0.25, **kwargs)


def test_joint_velocity_bounds_closed_form():
    lower, upper = np.array([-1.0, -1.0, -1.0]), np.array([1.0, 1.0, 1.0])
    v_max = np.array([2.0, 2.0, 2.0])
    q = np.array([0.0, 0.99, -1.0])
    lo, hi = joint_velocity_bounds(q, lower, upper, v_max, 0.004, 8.0)
    # joint 0: 1 rad from both limits: the speed limit (sqrt(16) = 4 > 2, 1 / 0.004 > 2);
    # joint 1: 0.01 rad below the upper limit: sqrt(2 * 8 * 0.01) = 0.4 (0.01 / 0.004 = 2.5);
    # joint 2: at its lower limit: nothing below; 2 rad above: the speed limit.
    np.testing.assert_allclose(hi, [2.0, 0.4, 2.0], rtol=1e-15)
    np.testing.assert_allclose(lo, [-2.0, -2.0, 0.0], rtol=1e-15)
    # One period ahead bounds it when the period is long: 0.01 / 0.1 = 0.1.
    _, hi = joint_velocity_bounds(q, lower, upper, v_max, 0.1, 8.0)
    assert hi[1] == pytest.approx(0.1, rel=1e-15)
    # No braking term (deceleration inf): the speed and one-period bounds alone, also for
    # a joint on its limit (inf * 0 there must not make the box NaN)
    lo, hi = joint_velocity_bounds(q, lower, upper, v_max, 0.004, np.inf)
    np.testing.assert_array_equal(hi, [2.0, 2.0, 2.0])
    np.testing.assert_array_equal(lo, [-2.0, -2.0, 0.0])


def test_saturated_joint_leaves_its_share_to_the_others():
    rng = np.random.default_rng(8)
    lower, upper = -2.9 * np.ones(7), 2.9 * np.ones(7)
    for _ in range(10):
        J = rng.normal(size=(6, 7))
        xdot = rng.normal(size=6)
        q = rng.uniform(-1.0, 1.0, size=7)
        free = rmrc_joint_velocity(J, xdot, q, lower, upper, 0.0, 0.0)
        j = int(np.argmax(np.abs(free)))
        # A box the free solution fits in: the same solution, bit for bit.
        wide = (-np.abs(free) - 1.0, np.abs(free) + 1.0)
        qd = rmrc_joint_velocity(J, xdot, q, lower, upper, 0.0, 0.0, velocity_bounds=wide)
        assert np.array_equal(qd, free)
        # Joint j may move only half as fast as it would: it is saturated at that bound and
        # the other six joints do the whole task, exactly (closed form over their columns).
        lo, hi = -np.inf * np.ones(7), np.inf * np.ones(7)
        bound = 0.5 * free[j]
        (hi if bound > 0 else lo)[j] = bound
        (lo if bound > 0 else hi)[j] = 0.0
        qd = rmrc_joint_velocity(J, xdot, q, lower, upper, 0.0, 0.0, velocity_bounds=(lo, hi))
        others = np.arange(7) != j
        expected = np.linalg.solve(J[:, others], xdot - J[:, j] * bound)
        assert qd[j] == bound
        np.testing.assert_allclose(qd[others], expected, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(J @ qd, xdot, atol=1e-10)
        # The secondary objective then moves in the null space of the six free columns:
        # that is only the zero vector (rank 6), so it adds nothing.
        with_null = rmrc_joint_velocity(
            J, xdot, q + 1.5, lower, upper, 0.0, 1.0, limit_gain=2.0, velocity_bounds=(lo, hi)
        )
        np.testing.assert_allclose(J @ with_null, xdot, atol=1e-10)


def test_too_few_joints_give_the_least_squares_compromise():
    # A planar 3-joint task (2 rows) with joint 0 locked at 0: the two others cannot do
    # a 2-d task whose columns they lack; the result is the least-squares solution.
    J = np.array([[1.0, 0.0, 0.0], [1.0, 1.0, 1.0]])
    xdot = np.array([1.0, 0.0])
    lower, upper = -np.ones(3), np.ones(3)
    box = (np.array([0.0, -5.0, -5.0]), np.array([0.0, 5.0, 5.0]))
    qd = rmrc_joint_velocity(J, xdot, np.zeros(3), lower, upper, 0.0, 0.0, velocity_bounds=box)
    # min |J qd - xdot| with qd_0 = 0: row 0 cannot be helped; row 1 is met with the
    # minimum-norm split qd_1 = qd_2 = 0.
    np.testing.assert_allclose(qd, [0.0, 0.0, 0.0], atol=1e-15)
    # All joints outside a box that is empty of motion: every one saturated at 0.
    zero = (np.zeros(3), np.zeros(3))
    qd = rmrc_joint_velocity(J, xdot, np.zeros(3), lower, upper, 0.0, 0.0, velocity_bounds=zero)
    assert np.array_equal(qd, np.zeros(3))


def test_reach_bound_and_check():
    assert reach_bound(np.array([[0, 0, 0], [0, 0, 1], [0, 1, 1]])) == pytest.approx(2.0)
    check_reachable(np.array([0, 0, 1.9]), np.zeros(3), 2.0, what="goal")
    with pytest.raises(RepertoireError, match="IK target out of reach: grasp goal .* by 0.500 m"):
        check_reachable(np.array([0, 0, 2.5]), np.zeros(3), 2.0, what="grasp goal")
    with pytest.raises(RepertoireError, match="finite 3-vector"):
        check_reachable(np.array([0, np.nan, 1.0]), np.zeros(3), 2.0, what="goal")


def test_pose_position_residual_is_the_exact_gap_to_an_attainable_pose():
    plant = _make_plant()
    ee = plant.GetFrameByName("ee")
    X = _pose(plant, Q0)
    # A pose of the arm, found from another seed: attained.
    residual = pose_position_residual(
        plant, ee, X.translation(), X.rotation(), [0.5 * Q0], orientation_tolerance=0.01
    )
    assert residual < 1e-5
    # Straight up, 1.0 m high with the base orientation: the stretched arm's tip is at
    # 0.85 m (offsets 0.1 + 0.6 + 0.05 + 0.1), the closest it can come, 0.15 m short.
    residual = pose_position_residual(
        plant, ee, np.array([0.0, 0.0, 1.0]), RotationMatrix(), [Q0], orientation_tolerance=0.01
    )
    assert residual == pytest.approx(0.15, abs=1e-5)
    with pytest.raises(RepertoireError, match="one or more seeds"):
        pose_position_residual(plant, ee, ZERO3, RotationMatrix(), [], orientation_tolerance=0.1)
    with pytest.raises(RepertoireError, match="finite 3-vector"):
        pose_position_residual(
            plant, ee, np.array([0, np.nan, 1.0]), RotationMatrix(), [Q0], orientation_tolerance=0.1
        )
    with pytest.raises(RepertoireError, match="each seed must be 7 finite joint positions"):
        pose_position_residual(
            plant, ee, ZERO3, RotationMatrix(), [Q0[:3]], orientation_tolerance=0.1
        )


def test_zero_error_keeps_reference_at_measured():
    plant = _make_plant()
    system = _system(plant)
    context = system.CreateDefaultContext()
    # Joint-limit avoidance moves in the null space; with null gain 0 nothing may move.
    context.get_mutable_numeric_parameter(system.gains_parameter_index).SetAtIndex(3, 0.0)
    X = _pose(plant, Q0)
    _fix(system, context, X.translation(), X.rotation().ToQuaternion().wxyz())
    simulator = Simulator(system, context)
    simulator.AdvanceTo(0.012)  # initialisation (q_r <- measured), then 4 updates
    state = system.GetOutputPort("arm_reference_state").Eval(context)
    assert np.array_equal(state[:7], Q0)
    assert np.array_equal(state[7:], np.zeros(7))
    assert np.array_equal(
        system.GetOutputPort("arm_reference_acceleration").Eval(context), np.zeros(7)
    )
    assert system.GetOutputPort("status").Eval(context)[0] == STATUS_OK
    assert np.allclose(system.GetOutputPort("task_error").Eval(context), 0.0, atol=1e-12)


def test_null_space_motion_keeps_the_pose():
    plant = _make_plant()
    system = _system(
        plant, null_gain=2.0, position_gain=0.0, orientation_gain=0.0, damping=0.0, period=1e-3
    )
    context = system.CreateDefaultContext()
    X = _pose(plant, Q0)
    _fix(system, context, X.translation(), X.rotation().ToQuaternion().wxyz())
    simulator = Simulator(system, context)
    simulator.AdvanceTo(0.001)
    q1 = system.GetOutputPort("arm_reference_state").Eval(context)[:7]
    assert np.linalg.norm(q1 - Q0) > 5e-6  # it moved toward the middle of the ranges
    assert np.linalg.norm(_pose(plant, q1).translation() - X.translation()) < 1e-9


def _jacobian(plant, q):
    ctx = plant.CreateDefaultContext()
    plant.SetPositions(ctx, q)
    return plant.CalcJacobianSpatialVelocity(
        ctx,
        JacobianWrtVariable.kV,
        plant.GetFrameByName("ee"),
        ZERO3,
        plant.world_frame(),
        plant.world_frame(),
    )


def test_barrier_step_of_the_system_is_the_projected_speed_bounded_gradient():
    plant = _make_plant()
    period, gain = 1e-3, 2.0
    # Only the barrier moves: no task feedback, no quadratic cost, no damping.
    system = _system(
        plant,
        period=period,
        position_gain=0.0,
        orientation_gain=0.0,
        damping=0.0,
        null_gain=0.0,
        limit_gain=gain,
        limit_band=0.1,
        limit_speed_fraction=0.5,
    )
    q0 = Q0.copy()
    # Band 0.1 of 5.8 rad: active above 2.32, 0.28 rad into it. (Not the elbow: with a
    # spherical shoulder and wrist the self-motion never changes the elbow angle.)
    q0[4] = 2.6
    context = system.CreateDefaultContext()
    X = _pose(plant, q0)
    _fix(system, context, X.translation(), X.rotation().ToQuaternion().wxyz(), q_meas=q0)
    Simulator(system, context).AdvanceTo(period)
    state = system.GetOutputPort("arm_reference_state").Eval(context)
    lower, upper = -2.9 * np.ones(7), 2.9 * np.ones(7)
    grad = joint_limit_barrier_gradient(q0, lower, upper, 0.1)
    assert np.array_equal(grad != 0.0, np.arange(7) == 4)
    assert grad[4] == pytest.approx(2.0 * 0.28 / 0.58**2)
    step = null_space_projector(_jacobian(plant, q0)) @ (-gain * grad)
    step *= speed_bounded_scale(np.zeros(7), step, 0.5 * 3.0 * np.ones(7))
    np.testing.assert_allclose(state[7:], step, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(state[:7], q0 + period * step, rtol=0, atol=1e-15)
    assert state[7 + 4] < 0.0  # the wrist joint turns away from its upper limit
    assert state[7 + 3] == pytest.approx(0.0, abs=1e-12)  # the elbow does not move
    assert np.max(np.abs(state[7:])) <= 1.5 + 1e-12
    # The pose moves only to second order in the step (an arm under 1 m long).
    dq = np.linalg.norm(state[:7] - q0)
    assert dq > 1e-3
    assert np.linalg.norm(_pose(plant, state[:7]).translation() - X.translation()) < dq**2


def test_joint_at_its_limit_stays_there_and_the_others_do_the_task():
    plant = _make_plant()
    period = 1e-3
    # No feedback, no secondary objective, no damping: xdot_ref = [w_d; v_d] exactly.
    system = _system(
        plant,
        period=period,
        position_gain=0.0,
        orientation_gain=0.0,
        damping=0.0,
        null_gain=0.0,
    )
    q0 = Q0.copy()
    q0[4] = 2.9  # the wrist's z joint at its upper limit
    J = _jacobian(plant, q0)
    xdot = J @ np.array([0.1, -0.2, 0.1, 0.2, 0.5, 0.1, -0.1])  # joint 4 would go up
    context = system.CreateDefaultContext()
    X = _pose(plant, q0)
    _fix(
        system,
        context,
        X.translation(),
        X.rotation().ToQuaternion().wxyz(),
        xdot[3:],
        xdot[:3],
        q_meas=q0,
    )
    Simulator(system, context).AdvanceTo(period)
    state = system.GetOutputPort("arm_reference_state").Eval(context)
    lower, upper = -2.9 * np.ones(7), 2.9 * np.ones(7)
    weights = np.repeat([1.0, 0.3 / 0.03], 3)  # orientation rows, position rows
    bounds = joint_velocity_bounds(q0, lower, upper, 3.0 * np.ones(7), period, 10.0)
    assert bounds[1][4] == 0.0
    expected = rmrc_joint_velocity(
        weights[:, None] * J,
        weights * xdot,
        q0,
        lower,
        upper,
        0.0,
        0.0,
        velocity_limits=0.5 * 3.0 * np.ones(7),
        velocity_bounds=bounds,
    )
    np.testing.assert_allclose(state[7:], expected, rtol=1e-12, atol=1e-13)
    np.testing.assert_allclose(state[:7], q0 + period * expected, rtol=0, atol=1e-15)
    assert state[7 + 4] == 0.0 and state[4] == 2.9  # the saturated joint stays at its limit
    np.testing.assert_allclose(J @ state[7:], xdot, atol=1e-9)  # the others do the whole task
    others = np.arange(7) != 4
    np.testing.assert_allclose(
        state[7:][others], np.linalg.solve(J[:, others], xdot), rtol=1e-8, atol=1e-10
    )


def test_barrier_off_the_band_leaves_the_system_unchanged():
    plant = _make_plant()
    X = _pose(plant, Q0)
    target = X.translation() + np.array([0.05, -0.03, 0.04])
    states = []
    for limit_gain in (0.0, 5.0):
        system = _system(plant, limit_gain=limit_gain)
        context = system.CreateDefaultContext()
        _fix(system, context, target, X.rotation().ToQuaternion().wxyz())
        Simulator(system, context).AdvanceTo(0.1)
        states.append(system.GetOutputPort("arm_reference_state").Eval(context).copy())
    assert np.max(np.abs(states[0][:7])) < 2.32  # no joint came into the band
    assert np.array_equal(states[0], states[1])


def test_velocity_step_matches_finite_difference():
    plant = _make_plant()
    period = 1e-4
    system = _system(plant, period=period, damping=0.0, null_gain=0.0)
    context = system.CreateDefaultContext()
    X = _pose(plant, Q0)
    v_d = np.array([0.1, -0.05, 0.08])
    w_d = np.array([0.2, 0.1, -0.3])
    _fix(system, context, X.translation(), X.rotation().ToQuaternion().wxyz(), v_d, w_d)
    simulator = Simulator(system, context)
    simulator.AdvanceTo(period)
    q1 = system.GetOutputPort("arm_reference_state").Eval(context)[:7]
    X1 = _pose(plant, q1)
    # One step of h along qdot = J^+ [w_d; v_d]: the pose moves by h [w_d; v_d] to first order.
    assert np.allclose((X1.translation() - X.translation()) / period, v_d, atol=1e-4)
    dR = (X1.rotation() @ X.rotation().inverse()).ToAngleAxis()
    assert np.allclose(dR.axis() * dR.angle() / period, w_d, atol=1e-4)


def test_position_error_converges_to_target():
    plant = _make_plant()
    system = _system(plant)
    context = system.CreateDefaultContext()
    X = _pose(plant, Q0)
    target = X.translation() + np.array([0.05, -0.03, 0.04])
    _fix(system, context, target, X.rotation().ToQuaternion().wxyz())
    simulator = Simulator(system, context)
    simulator.AdvanceTo(0.6)  # K_p = 20 1/s: 12 time constants
    q = system.GetOutputPort("arm_reference_state").Eval(context)[:7]
    X1 = _pose(plant, q)
    assert np.linalg.norm(X1.translation() - target) < 1e-5
    assert system.GetOutputPort("status").Eval(context)[0] == STATUS_OK


def _run_towards_far_target(plant, system, t_end: float):
    """Simulates ``system`` to ``t_end`` with a target 1.5 m out; returns its context."""
    context = system.CreateDefaultContext()
    X = _pose(plant, Q0)
    _fix(system, context, np.array([1.5, 0.0, 0.1]), X.rotation().ToQuaternion().wxyz())
    Simulator(system, context).AdvanceTo(t_end)
    return context


def test_unreachable_target_is_reported():
    plant = _make_plant()
    system = _system(plant, reach_center=np.array([0, 0, 0.1]), max_reach=0.8)
    context = _run_towards_far_target(plant, system, 0.008)
    assert system.GetOutputPort("status").Eval(context)[0] == STATUS_TARGET_OUT_OF_REACH


def test_tracking_lost_inside_the_sphere_is_reported():
    plant = _make_plant()
    # No reach sphere: a target 1.5 m away can only show up as lost tracking.
    system = _system(plant, error_hold_time=0.2)
    context = _run_towards_far_target(plant, system, 0.3)
    assert system.GetOutputPort("status").Eval(context)[0] == STATUS_TRACKING_LOST
    q = system.GetOutputPort("arm_reference_state").Eval(context)[:7]
    assert np.all(np.abs(q) <= 2.9)  # references stay inside the joint limits
    # The stretched arm is short of the target, not stopped by a limit: no joint held.
    assert np.array_equal(system.GetOutputPort("joints_at_limits").Eval(context), np.zeros(7))


def test_joints_held_at_limits_closed_form():
    v_max = np.array([2.0, 2.0, 2.0, 2.0, 2.0])
    # joint 0: hi from the position limit (0.4 < 2), qdot at it: held at the upper limit;
    # joint 1: lo from the position limit, qdot at it: held at the lower limit;
    # joint 2: at the speed limit 2.0: a speed bound, not a limit; joint 3: inside the box;
    # joint 4: on its upper limit (hi = 0) and held there.
    lo = np.array([-2.0, -0.3, -2.0, -2.0, -2.0])
    hi = np.array([0.4, 2.0, 2.0, 1.0, 0.0])
    qdot = np.array([0.4, -0.3, 2.0, 0.5, 0.0])
    held = joints_held_at_limits(qdot, (lo, hi), v_max)
    assert np.array_equal(held, [1.0, -1.0, 0.0, 0.0, 1.0])
    # The same box from joint_velocity_bounds: a joint 0.008 rad below its upper limit
    # (braking: sqrt(2 * 10 * 0.008) = 0.4) that the solve saturates is held there.
    lower, upper = -np.ones(3), np.ones(3)
    box = joint_velocity_bounds(np.array([0.992, 0.0, 0.0]), lower, upper, v_max[:3], 0.004, 10.0)
    assert box[1][0] == pytest.approx(0.4, rel=1e-12)
    qdot = rmrc_joint_velocity(
        np.array([[1.0, 0.0, 0.0]]),
        np.array([1.0]),
        np.zeros(3),
        lower,
        upper,
        0.0,
        0.0,
        velocity_bounds=box,
    )
    assert np.array_equal(joints_held_at_limits(qdot, box, v_max[:3]), [1.0, 0.0, 0.0])


def test_a_joint_driven_into_its_limit_brakes_at_the_set_deceleration_and_stops_on_it():
    # The task (feed-forward only) moves the tcp toward the shoulder at 0.3 m/s with the
    # orientation kept: only the elbow can do that (see the test below), at about 1.6 rad/s,
    # toward a lower limit 0.3 rad away. The box of joint_velocity_bounds must brake it at
    # a_max = 10 rad/s^2: while it is held at the braking bound, v_k = -sqrt(2 a d_k), so
    # the step's deceleration (|v_k| - |v_k+1|) / h = (v - sqrt(v^2 - 2 a h v)) / h lies
    # in [a, 2 a] (2 a on the last step, when v = 2 a h); then it rests on the limit.
    a_max, period = 10.0, 0.004
    lower = Q0[3] - 0.3
    plant = _make_plant({3: (lower, 0.0)})
    system = _system(
        plant,
        period=period,
        position_gain=0.0,
        orientation_gain=0.0,
        null_gain=0.0,
        limit_deceleration=a_max,
        error_hold_time=10.0,
    )
    context = system.CreateDefaultContext()
    X = _pose(plant, Q0)
    wrist, shoulder = X.translation() - 0.15 * X.rotation().col(2), np.array([0.0, 0.0, 0.1])
    toward = (shoulder - wrist) / np.linalg.norm(shoulder - wrist)
    _fix(system, context, X.translation(), X.rotation().ToQuaternion().wxyz(), 0.3 * toward)
    simulator = Simulator(system, context)
    q, v, held = [], [], []
    for k in range(1, 121):
        simulator.AdvanceTo(k * period)
        state = system.GetOutputPort("arm_reference_state").Eval(context)
        q.append(state[3])
        v.append(state[7 + 3])
        held.append(system.GetOutputPort("joints_at_limits").Eval(context)[3])
    q, v, held = np.array(q), np.array(v), np.array(held)
    assert v[0] < -1.5  # it starts fast (braking distance v^2 / (2 a) > 0.11 rad) ...
    assert np.all(q >= lower)  # ... never passes the limit ...
    assert q[-1] == lower and v[-1] == 0.0  # ... and ends on it, at rest
    assert held[-1] == -1.0
    d = q - lower
    assert np.all(np.abs(v[1:]) <= np.sqrt(2.0 * a_max * d[:-1]) + 1e-12)
    braking = (held[:-1] == -1.0) & (held[1:] == -1.0) & (v[1:] < 0.0)
    assert np.sum(braking) >= 20
    decel = (np.abs(v[:-1]) - np.abs(v[1:]))[braking] / period
    assert np.all(decel >= a_max * (1 - 1e-9)) and np.all(decel <= 2 * a_max * (1 + 1e-9))


def test_tracking_lost_at_a_joint_limit_is_reported_as_such():
    # The elbow (j4) may move only 0.01 rad. With the hand's orientation kept, the
    # shoulder-to-wrist distance depends on the elbow alone (spherical shoulder, the
    # wrist centre 0.15 m behind the tcp along its axis), so a tcp 5 cm nearer the
    # shoulder along that line needs the elbow bent further than its lower limit.
    elbow = (Q0[3] - 0.01, Q0[3] + 0.01)
    plant = _make_plant({3: elbow})
    system = _system(plant, error_hold_time=0.1)
    context = system.CreateDefaultContext()
    X = _pose(plant, Q0)
    shoulder = np.array([0.0, 0.0, 0.1])
    wrist = X.translation() - 0.15 * X.rotation().col(2)
    toward = (shoulder - wrist) / np.linalg.norm(shoulder - wrist)
    _fix(system, context, X.translation() + 0.05 * toward, X.rotation().ToQuaternion().wxyz())
    simulator = Simulator(system, context)
    simulator.AdvanceTo(0.05)
    assert system.GetOutputPort("status").Eval(context)[0] == STATUS_OK
    q = system.GetOutputPort("arm_reference_state").Eval(context)[:7]
    assert q[3] == elbow[0]  # bent to its lower limit and held there
    assert np.array_equal(
        system.GetOutputPort("joints_at_limits").Eval(context), [0, 0, 0, -1.0, 0, 0, 0]
    )
    simulator.AdvanceTo(0.2)
    assert system.GetOutputPort("status").Eval(context)[0] == STATUS_JOINT_LIMITS
    assert system.GetOutputPort("task_error").Eval(context)[0] > 0.03


@pytest.mark.parametrize("angle, lost", [(0.5, True), (0.2, False)])
def test_orientation_error_alone_is_reported_as_lost_tracking(angle, lost):
    # K_o = 0 and no null-space motion: the reference stands still (qdot = J# 0 = 0), the
    # position error is 0 and the orientation error stays the goal's angle exactly.
    plant = _make_plant()
    system = _system(plant, orientation_gain=0.0, null_gain=0.0, error_hold_time=0.1)
    context = system.CreateDefaultContext()
    X = _pose(plant, Q0)
    R_d = RotationMatrix.MakeXRotation(angle) @ X.rotation()
    _fix(system, context, X.translation(), R_d.ToQuaternion().wxyz())
    simulator = Simulator(system, context)
    simulator.AdvanceTo(0.08)
    assert system.GetOutputPort("status").Eval(context)[0] == STATUS_OK
    simulator.AdvanceTo(0.2)
    assert np.allclose(system.GetOutputPort("task_error").Eval(context), [0.0, angle], atol=1e-12)
    assert np.array_equal(system.GetOutputPort("arm_reference_state").Eval(context)[:7], Q0)
    expected = STATUS_TRACKING_LOST if lost else STATUS_OK
    assert system.GetOutputPort("status").Eval(context)[0] == expected


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"error_tolerance": 0.0}, "error_tolerance must be finite and > 0, got 0.0"),
        ({"orientation_tolerance": np.nan}, "orientation_tolerance must be finite and > 0"),
        ({"error_hold_time": -1.0}, "error_hold_time must be finite and > 0, got -1.0"),
        ({"max_reach": 0.0}, r"max_reach must be > 0 m \(inf disables it\), got 0.0"),
        ({"reach_center": [0.0, 1.0]}, r"reach_center must be a finite 3-vector, got \[0.0, 1.0\]"),
        ({"limit_gain": -1.0}, "limit_gain must be finite and >= 0, got -1.0"),
        ({"limit_band": 0.6}, r"limit_band must be in \(0, 0.5\], got 0.6"),
        ({"limit_speed_fraction": 0.0}, "limit_speed_fraction must be finite and > 0, got 0.0"),
        ({"limit_deceleration": 0.0}, r"limit_deceleration must be > 0 rad/s\^2 .*got 0.0"),
        ({"limit_deceleration": np.nan}, r"limit_deceleration must be > 0 rad/s\^2 .*got nan"),
    ],
)
def test_bad_tolerances_and_reach_sphere_are_refused(kwargs, match):
    with pytest.raises(RepertoireError, match=match):
        _system(_make_plant(), **kwargs)


def test_bad_construction_and_input():
    plant = _make_plant()
    with pytest.raises(RepertoireError, match="period must be > 0"):
        _system(plant, period=0.0)
    with pytest.raises(RepertoireError, match="arm_velocity_indices"):
        ResolvedMotionRateIK(plant, plant.GetFrameByName("ee"), [0, 1, 9])
    with pytest.raises(RepertoireError, match="damping must be finite"):
        _system(plant, damping=-1.0)
    unfinalized = MultibodyPlant(0.0)
    with pytest.raises(RepertoireError, match="finalized"):
        ResolvedMotionRateIK(unfinalized, unfinalized.world_frame(), [0])
    system = _system(plant)
    context = system.CreateDefaultContext()
    X = _pose(plant, Q0)
    _fix(system, context, X.translation(), np.array([1.0, 0.5, 0.0, 0.0]))
    simulator = Simulator(system, context)
    with pytest.raises(RepertoireError, match="unit quaternion"):
        simulator.AdvanceTo(0.01)
