"""Tests of systems/task_space.py: the RMRC math and the ResolvedMotionRateIK LeafSystem."""

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from pydrake.multibody.math import SpatialVelocity
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import BodyIndex, JacobianWrtVariable
from pydrake.systems.analysis import Simulator
from repertoire.planning.dmp_math import obstacle_coupling
from repertoire.systems.grasp import GraspWrench, grip_wrench
from repertoire.systems.obstacle_coupling import (
    MultiPointObstacleCoupling,
    multi_point_obstacle_coupling,
)
from repertoire.systems.task_space import (
    STATUS_OK,
    STATUS_TARGET_OUT_OF_REACH,
    STATUS_TRACKING_LOST,
    ResolvedMotionRateIK,
    check_reachable,
    damped_pseudoinverse,
    joint_limit_barrier_gradient,
    joint_limit_gradient,
    joint_limit_potential_gradient,
    joint_velocity_bounds,
    null_space_projector,
    pose_position_residual,
    quaternion_error,
    quaternion_multiply,
    reach_bound,
    rmrc_joint_velocity,
    speed_bounded_scale,
)

from repertoire.errors import RepertoireError

# A 7-DOF test arm written here so the tests need no other model: z-y-z shoulder,
# y elbow, z-y-z wrist; links of 0.3 m, 0.3 m and 0.1 m.
AXES = ["0 0 1", "0 1 0", "0 0 1", "0 1 0", "0 0 1", "0 1 0", "0 0 1"]
OFFSETS = [0.1, 0.0, 0.15, 0.15, 0.15, 0.15, 0.05]


def _arm_urdf() -> str:
    links = ['<link name="base"/>']
    joints = []
    for i in range(7):
        links.append(
            f'<link name="l{i + 1}"><inertial><mass value="1"/>'
            f'<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>'
        )
        parent = "base" if i == 0 else f"l{i}"
        joints.append(
            f'<joint name="j{i + 1}" type="revolute"><parent link="{parent}"/>'
            f'<child link="l{i + 1}"/><origin xyz="0 0 {OFFSETS[i]}"/><axis xyz="{AXES[i]}"/>'
            f'<limit lower="-2.9" upper="2.9" effort="100" velocity="3"/></joint>'
        )
    links.append('<link name="ee"/>')
    joints.append(
        '<joint name="ee_joint" type="fixed"><parent link="l7"/><child link="ee"/>'
        '<origin xyz="0 0 0.1"/></joint>'
    )
    return '<robot name="arm">' + "".join(links + joints) + "</robot>"


def _make_plant() -> MultibodyPlant:
    plant = MultibodyPlant(0.0)
    Parser(plant).AddModelsFromString(_arm_urdf(), "urdf")
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


def test_grip_wrench_closed_form():
    X_WH = RigidTransform(RollPitchYaw(0.0, 0.0, 0.5), [0.1, 0.2, 0.3])
    X_HO = RigidTransform([0.0, 0.0, 0.1])
    zero = SpatialVelocity(np.zeros(3), np.zeros(3))
    # Object exactly at the held pose and at rest: no wrench.
    torque, force = grip_wrench(
        X_WH, X_WH @ X_HO, X_HO, zero, zero, np.zeros(3), 1000.0, 10.0, 5.0, 0.1
    )
    assert np.allclose(torque, 0.0) and np.allclose(force, 0.0)
    # Displaced by 2 mm along -z and turned by 0.1 rad about x: F = k d, tau = k_r * 0.1 x.
    X_WO = RigidTransform(RotationMatrix.MakeXRotation(-0.1), [0, 0, -0.002]) @ (X_WH @ X_HO)
    X_WO = RigidTransform(X_WO.rotation(), (X_WH @ X_HO).translation() - [0, 0, 0.002])
    torque, force = grip_wrench(X_WH, X_WO, X_HO, zero, zero, np.zeros(3), 1000.0, 10.0, 5.0, 0.1)
    assert np.allclose(force, [0, 0, 2.0])
    assert np.allclose(torque, [0.5, 0, 0])
    # The hand translating at 1 m/s drags the object with c * 1 m/s.
    moving = SpatialVelocity(np.zeros(3), np.array([1.0, 0, 0]))
    torque, force = grip_wrench(
        X_WH, X_WH @ X_HO, X_HO, moving, zero, np.zeros(3), 1000.0, 10.0, 5.0, 0.1
    )
    assert np.allclose(force, [10.0, 0, 0]) and np.allclose(torque, 0.0)


def test_grasp_wrench_latches_and_releases():
    grip = GraspWrench(
        BodyIndex(1),
        [BodyIndex(2), BodyIndex(3)],
        num_fingers=3,
        closure_weights=np.array([1.0, 0.0, 0.0]),
        close_threshold=0.8,
        open_threshold=0.2,
        palm_point_H=np.array([0.0, 0.0, 0.1]),
        capture_radius=0.03,
        period=0.01,
    )
    context = grip.CreateDefaultContext()
    X_WH = RigidTransform([0.5, 0.0, 0.4])
    poses = [RigidTransform(), X_WH, RigidTransform([0.5, 0.01, 0.5]), RigidTransform([0, 0, 1])]
    zero = SpatialVelocity(np.zeros(3), np.zeros(3))
    grip.GetInputPort("body_poses").FixValue(context, poses)
    grip.GetInputPort("body_spatial_velocities").FixValue(context, [zero] * 4)
    fingers = grip.GetInputPort("finger_command").FixValue(context, np.array([0.5, 0, 0]))
    simulator = Simulator(grip, context)
    simulator.AdvanceTo(0.02)
    assert grip.GetOutputPort("held_object").Eval(context)[0] == -1  # not closed yet
    assert grip.GetOutputPort("spatial_forces").Eval(context) == []
    fingers.GetMutableData().set_value(np.array([0.9, 0, 0]))
    simulator.AdvanceTo(0.04)
    assert grip.GetOutputPort("held_object").Eval(context)[0] == 0  # body 2: 1 cm from palm point
    forces = grip.GetOutputPort("spatial_forces").Eval(context)
    assert [int(f.body_index) for f in forces] == [2, 1]
    assert np.allclose(forces[0].F_Bq_W.get_coeffs(), 0.0)  # held where it was caught
    fingers.GetMutableData().set_value(np.array([0.1, 0, 0]))
    simulator.AdvanceTo(0.06)
    assert grip.GetOutputPort("held_object").Eval(context)[0] == -1
    with pytest.raises(RepertoireError, match="open_threshold"):
        GraspWrench(
            BodyIndex(1),
            [BodyIndex(2)],
            num_fingers=1,
            closure_weights=np.ones(1),
            close_threshold=0.2,
            open_threshold=0.5,
            palm_point_H=np.zeros(3),
            capture_radius=0.03,
            period=0.01,
        )


# ----------------------------------------------------------------------------- obstacle coupling
def _eq10_closed_form(gamma: float, beta: float, phi: float, speed: float) -> float:
    return gamma * speed * phi * np.exp(-beta * phi)


def test_coupling_at_a_control_point_turns_it_away_from_the_ball():
    # The control point sits 0.1 m along y_E of a hand turned 90 deg about z (R_WE maps y_E
    # to -x_W), so 0.1 m behind the tcp along x. Moving along +y_W at 0.5 m/s with the ball
    # 1 m ahead and 0.05 m to the +x side: phi = atan(0.05 / 1), p points along -x (away).
    R_WE = RotationMatrix.MakeZRotation(np.pi / 2).matrix()
    x = np.array([0.3, 0.0, 0.9])
    c = x + R_WE @ [0.0, 0.1, 0.0]
    assert c == pytest.approx([0.2, 0.0, 0.9])
    v = np.array([0.0, 0.5, 0.0])
    ball = c + [0.05, 1.0, 0.0]
    p = multi_point_obstacle_coupling(x, v, R_WE, [[0.0, 0.1, 0.0]], ball, 1000.0, 20 / np.pi)
    phi = np.arctan2(0.05, 1.0)
    expected = _eq10_closed_form(1000.0, 20 / np.pi, phi, 0.5)
    np.testing.assert_allclose(p, [-expected, 0.0, 0.0], rtol=1e-12, atol=1e-15)
    # The ball on the other side: pushed the other way.
    mirrored = c + [-0.05, 1.0, 0.0]
    p2 = multi_point_obstacle_coupling(x, v, R_WE, [[0.0, 0.1, 0.0]], mirrored, 1000.0, 20 / np.pi)
    np.testing.assert_allclose(p2, [expected, 0.0, 0.0], rtol=1e-12, atol=1e-15)


def test_single_tcp_point_without_fade_is_eq10():
    rng = np.random.default_rng(4)
    for _ in range(5):
        x, v, o = rng.normal(size=3), rng.normal(size=3), rng.normal(size=3)
        R = RotationMatrix(RollPitchYaw(rng.normal(size=3))).matrix()
        p = multi_point_obstacle_coupling(x, v, R, [[0.0, 0.0, 0.0]], o, 700.0, 3.0)
        np.testing.assert_array_equal(p, obstacle_coupling(x, v, o, 700.0, 3.0))


def test_multi_point_sum_with_distance_fade():
    x = np.array([0.5, 0.0, 1.0])
    v = np.array([0.0, 0.3, 0.0])
    o = np.array([0.52, 0.2, 0.95])
    points = np.array([[0.0, 0.0, 0.0], [-0.045, 0.0, 0.0], [0.0, 0.06, 0.0]])
    R = RotationMatrix(RollPitchYaw(0.1, -0.2, 0.3)).matrix()
    total = multi_point_obstacle_coupling(
        x, v, R, points, o, 5000.0, 4.0, obstacle_radius=0.06, length_scale=0.03
    )
    expected = np.zeros(3)
    for r in points:
        c = x + R @ r
        fade = np.exp(-max(np.linalg.norm(c - o) - 0.06, 0.0) / 0.03)
        expected += fade * obstacle_coupling(c, v, o, 5000.0, 4.0)
    np.testing.assert_allclose(total, expected, rtol=1e-12)
    # Inside the ball's radius the fade is 1: the plain term.
    near = o + [0.0, -0.05, 0.0]
    p = multi_point_obstacle_coupling(
        near, v, np.eye(3), [[0, 0, 0]], o, 5000.0, 4.0, obstacle_radius=0.06, length_scale=0.03
    )
    np.testing.assert_allclose(p, obstacle_coupling(near, v, o, 5000.0, 4.0), rtol=1e-12)


def test_multi_point_coupling_system_wraps_the_function():
    points = [[0.0, 0.0, 0.0], [0.0, 0.0, -0.085]]
    system = MultiPointObstacleCoupling(
        points, gamma=2000.0, beta=4.0, obstacle_radius=0.06, length_scale=0.03
    )
    context = system.CreateDefaultContext()
    q = RollPitchYaw(0.0, np.pi / 2, 0.0).ToQuaternion()
    x, v, o = np.array([0.5, 0.0, 0.9]), np.array([0.0, 0.4, 0.05]), np.array([0.45, 0.1, 0.9])
    system.GetInputPort("position").FixValue(context, x)
    system.GetInputPort("velocity").FixValue(context, v)
    system.GetInputPort("orientation").FixValue(context, 2.0 * q.wxyz())  # normalised inside
    system.GetInputPort("obstacle").FixValue(context, o)
    out = system.GetOutputPort("coupling").Eval(context)
    R = RotationMatrix(q).matrix()
    expected = multi_point_obstacle_coupling(
        x, v, R, points, o, 2000.0, 4.0, obstacle_radius=0.06, length_scale=0.03
    )
    np.testing.assert_allclose(out, expected, rtol=1e-12)
    assert np.linalg.norm(out) > 0.0
    system.GetInputPort("orientation").FixValue(context, np.zeros(4))
    with pytest.raises(RepertoireError, match="non-zero quaternion"):
        system.GetOutputPort("coupling").Eval(context)


def test_multi_point_coupling_bad_input():
    with pytest.raises(RepertoireError, match="must be >= 0"):
        multi_point_obstacle_coupling(
            np.zeros(3), np.ones(3), np.eye(3), [[0, 0, 0]], np.ones(3), -1.0, 1.0
        )
    with pytest.raises(RepertoireError, match="non-empty k x 3 array"):
        MultiPointObstacleCoupling([[0.0, 0.0]])
    with pytest.raises(RepertoireError, match="non-empty k x 3 array"):
        MultiPointObstacleCoupling(np.zeros((0, 3)))
