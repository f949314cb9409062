"""Tests of the grasp wrench (systems/grasp.py) and the multi-point obstacle coupling
(systems/obstacle_coupling.py), split out of tests/test_task_space.py."""

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from pydrake.multibody.math import SpatialVelocity
from pydrake.multibody.tree import BodyIndex
from pydrake.systems.analysis import Simulator
from repertoire.planning.dmp_math import obstacle_coupling
from repertoire.systems.grasp import GraspWrench, grip_wrench
from repertoire.systems.obstacle_coupling import (
    MultiPointObstacleCoupling,
    multi_point_obstacle_coupling,
    remaining_movement_gate,
)

from repertoire.errors import RepertoireError


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


def test_remaining_movement_gate_closed_form():
    assert remaining_movement_gate(0.05, 0.05, 0.03) == 1.0  # the ball as near as the goal
    assert remaining_movement_gate(0.0, 0.002, 0.03) == 1.0
    assert remaining_movement_gate(0.08, 0.05, 0.03) == 0.0  # one length scale beyond
    assert remaining_movement_gate(0.2, 0.0, 0.03) == 0.0
    assert remaining_movement_gate(0.065, 0.05, 0.03) == pytest.approx(0.5, abs=1e-15)
    # u = 1 / 3: 3 u^2 - 2 u^3 = 7 / 27
    assert remaining_movement_gate(0.07, 0.05, 0.03) == pytest.approx(7.0 / 27.0, rel=1e-12)


def _settle_point_dmp(goal_gate: bool, gamma: float, seconds: float = 2.0) -> np.ndarray:
    """A 3-D point DMP past its forcing term (the arm's K, D and carry tau) near its goal.

    The ball's surface is 10 cm from the goal; RK4 at 1 ms. Returns (k, 6) [x, dx/dt].
    """
    K, D, tau, g = 156.25, 25.0, 3.0, np.zeros(3)
    o = np.array([0.0, 0.16, 0.0])

    def rhs(z):
        x, v = z[:3], z[3:]
        p = multi_point_obstacle_coupling(
            x, v / tau, np.eye(3), [[0.0, 0.0, 0.0]], o, gamma, 4.0,
            obstacle_radius=0.06, length_scale=0.03, tau=tau, goal=g if goal_gate else None,
        )  # fmt: skip
        return np.concatenate([v / tau, (K * (g - x) - D * v + p) / tau])

    z, dt, out = np.array([0.005, -0.003, 0.0, 0.03, 0.0, 0.0]), 1e-3, []
    for _ in range(int(round(seconds / dt))):
        k1 = rhs(z)
        k2 = rhs(z + dt / 2 * k1)
        k3 = rhs(z + dt / 2 * k2)
        k4 = rhs(z + dt * k3)
        z = z + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        out.append(np.concatenate([z[:3], z[3:] / 3.0]))
    return np.array(out)


def test_coupled_dmp_comes_to_rest_at_its_goal():
    """Eq. 10 with the arm's gain must not keep a DMP circling its goal (session 37).

    The ball is behind the goal (10 cm from it): with the goal gate the term is 0 there,
    and the coupled DMP is the free one step for step, at rest on its goal after 2 s.
    Without the gate the exp fade leaves a turning rate above the damping and the
    slowest mode decays several times slower (the arm's place DMP circled its goal at
    2.6-4.2 mm/s).
    """
    from repertoire.diagrams.arm_dmp_scenarios import OBSTACLE_GAMMA

    free = _settle_point_dmp(True, 0.0)
    gated = _settle_point_dmp(True, OBSTACLE_GAMMA)
    np.testing.assert_array_equal(gated, free)
    assert np.linalg.norm(gated[-1, :3]) < 2e-5 and np.linalg.norm(gated[-1, 3:]) < 1e-4
    ungated = _settle_point_dmp(False, OBSTACLE_GAMMA)
    assert np.linalg.norm(ungated[-1, :3]) > 10 * np.linalg.norm(free[-1, :3])


def test_multi_point_coupling_system_goal_gate():
    points = [[0.0, 0.0, 0.0], [0.0, 0.0, -0.085]]
    system = MultiPointObstacleCoupling(
        points, gamma=2000.0, beta=4.0, obstacle_radius=0.06, length_scale=0.03
    )
    context = system.CreateDefaultContext()
    x, v, o = np.array([0.5, 0.0, 0.9]), np.array([0.0, 0.4, 0.05]), np.array([0.5, 0.17, 0.9])
    system.GetInputPort("position").FixValue(context, x)
    system.GetInputPort("velocity").FixValue(context, v)
    system.GetInputPort("orientation").FixValue(context, [1.0, 0.0, 0.0, 0.0])
    system.GetInputPort("obstacle").FixValue(context, o)
    free = system.GetOutputPort("coupling").Eval(context).copy()
    assert np.linalg.norm(free) > 0.0
    for goal in ([0.5, 0.3, 0.9], [0.5, 0.05, 0.9], [0.5, 0.09, 0.9]):
        system.GetInputPort("goal").FixValue(context, goal)
        expected = multi_point_obstacle_coupling(
            x, v, np.eye(3), points, o, 2000.0, 4.0,
            obstacle_radius=0.06, length_scale=0.03, goal=np.array(goal),
        )  # fmt: skip
        np.testing.assert_allclose(system.GetOutputPort("coupling").Eval(context), expected)
    # the goal farther than the ball: the plain term; the ball beyond the goal: 0
    system.GetInputPort("goal").FixValue(context, [0.5, 0.3, 0.9])
    np.testing.assert_array_equal(system.GetOutputPort("coupling").Eval(context), free)
    system.GetInputPort("goal").FixValue(context, [0.5, 0.005, 0.9])
    np.testing.assert_array_equal(system.GetOutputPort("coupling").Eval(context), np.zeros(3))
    with pytest.raises(RepertoireError, match="goal must be a finite 3-vector"):
        multi_point_obstacle_coupling(
            x, v, np.eye(3), points, o, 2000.0, 4.0, length_scale=0.03, goal=[0.0, np.nan, 1.0]
        )
