"""Task-space control of an arm: resolved-motion-rate IK with quaternion feedback.

Pastor et al. (2009), section IV-D: the DMP's desired end-effector position,
velocity, orientation (unit quaternion) and angular velocity are turned into
reference joint velocities by a velocity-based inverse kinematics controller;
the reference joint positions and accelerations come from integrating and
differentiating those velocities; orientation is tracked with quaternion
feedback (Yuan 1988). An inverse-dynamics feed-forward plus PD torque
controller (Drake's ``InverseDynamicsController``) then tracks the references.

The math lives in plain functions (:func:`quaternion_error`,
:func:`damped_pseudoinverse`, :func:`joint_limit_gradient`,
:func:`rmrc_joint_velocity`, :func:`reach_bound`); :class:`ResolvedMotionRateIK`
only wraps them.

Quaternions are ``[w, x, y, z]`` (Drake's order), angular velocities and
Jacobians are expressed in the world frame W.
"""

import numpy as np
from pydrake.common.eigen_geometry import Quaternion
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.math import SpatialForce, SpatialVelocity
from pydrake.multibody.plant import ExternallyAppliedSpatialForce, MultibodyPlant
from pydrake.multibody.tree import BodyIndex, Frame, JacobianWrtVariable
from pydrake.systems.framework import BasicVector, Context, LeafSystem, ValueProducer
from repertoire.planning.dmp import DmpParameters, TaskSpaceDmp
from repertoire.planning.dmp_math import (
    angular_velocity,
    forcing_term,
    obstacle_coupling,
    transformation_derivatives,
)

from repertoire.errors import RepertoireError

#: Status codes of :class:`ResolvedMotionRateIK` (output port ``status``).
STATUS_OK = 0
#: The desired position lies outside the sphere the arm can reach at all.
STATUS_TARGET_OUT_OF_REACH = 1
#: The task-space error stayed above tolerance longer than the hold time
#: (target inside the sphere but not attainable: joint limits, base, singularity).
STATUS_TRACKING_LOST = 2

STATUS_NAMES = {
    STATUS_OK: "ok",
    STATUS_TARGET_OUT_OF_REACH: "target out of reach",
    STATUS_TRACKING_LOST: "task-space tracking lost",
}


def quaternion_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a * b`` of quaternions ``[w, x, y, z]``."""
    aw, av = a[0], np.asarray(a[1:])
    bw, bv = b[0], np.asarray(b[1:])
    return np.concatenate([[aw * bw - av @ bv], aw * bv + bw * av + np.cross(av, bv)])


def quaternion_error(q_desired: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Quaternion feedback error (Yuan 1988), the vector part of ``q_d * conj(q)``.

    ``e = eta * eps_d - eta_d * eps - eps_d x eps`` with ``q = [eta, eps]``. It is
    ``sin(theta / 2) * axis`` of the rotation ``R_d R^T`` taking the current to the
    desired orientation, expressed in the world frame; the sign is chosen for the
    shorter way round (``q`` and ``-q`` are the same rotation).

    Args:
        q_desired: desired unit quaternion ``[w, x, y, z]``.
        q: current unit quaternion ``[w, x, y, z]``.

    Returns:
        The 3-vector error; ``w_ref = w_d + K_o * e`` drives ``q`` to ``q_desired``.
    """
    q_desired = np.asarray(q_desired, dtype=float)
    q = np.asarray(q, dtype=float)
    eta_d, eps_d = q_desired[0], q_desired[1:]
    eta, eps = q[0], q[1:]
    scalar = eta_d * eta + eps_d @ eps
    e = eta * eps_d - eta_d * eps - np.cross(eps_d, eps)
    return -e if scalar < 0.0 else e


def damped_pseudoinverse(J: np.ndarray, damping: float) -> np.ndarray:
    """Damped least-squares inverse ``J^T (J J^T + damping^2 I)^-1``.

    Args:
        J: an ``m x n`` Jacobian.
        damping: the damping factor lambda (0 gives the right pseudo-inverse of a
            full-row-rank ``J``).
    """
    m = J.shape[0]
    return J.T @ np.linalg.solve(J @ J.T + damping**2 * np.eye(m), np.eye(m))


def joint_limit_gradient(q: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """Gradient of ``H(q) = sum(((q - q_mid) / (upper - lower))^2)``.

    ``H`` grows toward the joint limits; following ``-grad H`` in the null space
    of the task keeps the joints near the middle of their ranges.

    Args:
        q: joint positions.
        lower: lower joint limits (finite).
        upper: upper joint limits (finite).
    """
    span = upper - lower
    return 2.0 * (q - 0.5 * (lower + upper)) / span**2


def rmrc_joint_velocity(
    J: np.ndarray,
    xdot_ref: np.ndarray,
    q: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    damping: float,
    null_gain: float,
) -> np.ndarray:
    """Resolved-motion-rate joint velocity with joint-limit avoidance in the null space.

    ``qdot = J# xdot_ref + (I - J# J) (-null_gain * grad H(q))`` with the damped
    least-squares inverse ``J#``.

    Args:
        J: ``6 x n`` spatial-velocity Jacobian ``[angular; translational]``.
        xdot_ref: reference spatial velocity ``[w_ref; v_ref]`` (6).
        q: joint positions (n).
        lower: lower joint limits (n).
        upper: upper joint limits (n).
        damping: damped least-squares factor.
        null_gain: gain of the joint-limit avoidance in the null space.
    """
    J_pinv = damped_pseudoinverse(J, damping)
    n = J.shape[1]
    qdot_null = -null_gain * joint_limit_gradient(q, lower, upper)
    return J_pinv @ xdot_ref + (np.eye(n) - J_pinv @ J) @ qdot_null


def reach_bound(points: np.ndarray) -> float:
    """Upper bound on the reach of a serial chain: the length of its joint polyline.

    Args:
        points: ``k x 3`` world positions of the shoulder (first row), every joint
            origin down the chain, and the end-effector point (last row).

    Returns:
        The summed segment lengths; no configuration puts the end-effector
        farther than this from the first point (triangle inequality).
    """
    points = np.asarray(points, dtype=float)
    return float(np.sum(np.linalg.norm(np.diff(points, axis=0), axis=1)))


def check_reachable(p_W: np.ndarray, center_W: np.ndarray, reach: float, *, what: str) -> None:
    """Raises a clear error if ``p_W`` is outside the sphere ``center_W``, ``reach``.

    Args:
        p_W: target point in the world frame.
        center_W: shoulder point in the world frame.
        reach: reach radius (see :func:`reach_bound`).
        what: what the target is, for the message (e.g. ``"grasp goal"``).

    Raises:
        RepertoireError: the target is out of reach (says by how much).
    """
    p_W = np.asarray(p_W, dtype=float)
    if p_W.shape != (3,) or not np.all(np.isfinite(p_W)):
        raise RepertoireError(f"{what} must be a finite 3-vector, got {p_W!r}")
    distance = float(np.linalg.norm(p_W - center_W))
    if distance > reach:
        raise RepertoireError(
            f"IK target out of reach: {what} {np.round(p_W, 4).tolist()} is {distance:.3f} m "
            f"from the shoulder {np.round(center_W, 4).tolist()}, beyond the arm's reach of "
            f"{reach:.3f} m by {distance - reach:.3f} m; move the target closer"
        )


class ResolvedMotionRateIK(LeafSystem):
    """Resolved-motion-rate IK with quaternion feedback (Pastor et al. 2009, IV-D).

    Every ``period`` seconds the reference joint positions ``q_r`` (discrete
    state) are advanced by ``period * qdot_r`` with

    ``qdot_r = J# [w_d + K_o e_o; v_d + K_p (p_d - p(q_r))] + (I - J# J)(-k_n grad H)``

    where ``J`` is the end-effector Jacobian at ``q_r`` (evaluated in a plant
    Context held in a cache entry), ``J#`` its damped least-squares inverse and
    ``e_o`` the quaternion error. ``qdd_r`` is the backward difference of
    ``qdot_r``. ``q_r`` starts at the measured joint positions (initialisation
    event) and is kept inside the joint limits. The kinematic loop is closed on
    ``q_r`` (as in the paper's Fig. 11); the torque controller closes the loop on
    the measured state.

    Target monitoring: ``status`` is :data:`STATUS_TARGET_OUT_OF_REACH` as soon as
    the desired position is farther than ``max_reach`` from ``reach_center``, and
    :data:`STATUS_TRACKING_LOST` when the position error stayed above
    ``error_tolerance`` for longer than ``error_hold_time``. The status latches.

    Input ports:
        position_desired: p_d, 3.
        velocity_desired: v_d, 3.
        orientation_desired: q_d, unit quaternion [w, x, y, z], 4.
        angular_velocity_desired: w_d in W, 3.
        arm_state_measured: [q; v] of the n arm joints, 2n.

    Output ports:
        arm_reference_state: [q_r; qdot_r], 2n.
        arm_reference_acceleration: qdd_r, n.
        status: [status code], 1 (see ``STATUS_NAMES``).
        task_error: [|p_d - p(q_r)| in m, orientation error angle in rad], 2.

    Numeric parameter (index ``gains_parameter_index``): ``[K_p, K_o, damping,
    null_gain]``.
    """

    def __init__(
        self,
        plant: MultibodyPlant,
        frame_E: Frame,
        arm_velocity_indices: list[int],
        *,
        period: float = 0.004,
        position_gain: float = 20.0,
        orientation_gain: float = 20.0,
        damping: float = 0.02,
        null_gain: float = 0.5,
        reach_center: np.ndarray | None = None,
        max_reach: float = np.inf,
        error_tolerance: float = 0.03,
        error_hold_time: float = 0.5,
    ):
        """Builds the IK system for a finalized control plant.

        Args:
            plant: finalized control plant (positions equal velocities for the arm
                joints). Positions not in ``arm_velocity_indices`` stay at defaults.
            frame_E: end-effector frame of ``plant``; its origin is the controlled point.
            arm_velocity_indices: indices of the n arm joints in the plant's
                position (= velocity) vector, in the order of ``arm_state_measured``.
            period: update period of the discrete reference in seconds.
            position_gain: K_p in 1/s.
            orientation_gain: K_o in 1/s.
            damping: damped least-squares factor.
            null_gain: joint-limit avoidance gain.
            reach_center: shoulder point in W for the reach check.
            max_reach: reach radius in m (see :func:`reach_bound`); inf disables.
            error_tolerance: position error in m above which tracking counts as lost.
            error_hold_time: seconds the error may stay above tolerance.

        Raises:
            RepertoireError: bad period, gains, indices or unfinalized plant.
        """
        super().__init__()
        if not plant.is_finalized():
            raise RepertoireError("ResolvedMotionRateIK needs a finalized control plant")
        if not period > 0.0:
            raise RepertoireError(f"period must be > 0 s, got {period}")
        for name, value in (
            ("position_gain", position_gain),
            ("orientation_gain", orientation_gain),
            ("damping", damping),
            ("null_gain", null_gain),
        ):
            if not (np.isfinite(value) and value >= 0.0):
                raise RepertoireError(f"{name} must be finite and >= 0, got {value}")
        idx = np.asarray(arm_velocity_indices, dtype=int)
        if (
            idx.ndim != 1
            or len(idx) == 0
            or len(set(idx.tolist())) != len(idx)
            or idx.min() < 0
            or idx.max() >= plant.num_velocities()
        ):
            raise RepertoireError(
                f"arm_velocity_indices must be distinct indices below {plant.num_velocities()}, "
                f"got {arm_velocity_indices}"
            )
        if plant.num_positions() != plant.num_velocities():
            raise RepertoireError("the control plant must have as many positions as velocities")
        self._plant = plant
        self._frame_E = frame_E
        self._idx = idx
        n = len(idx)
        self._n = n
        self._period = float(period)
        lower = plant.GetPositionLowerLimits()[idx]
        upper = plant.GetPositionUpperLimits()[idx]
        if not (np.all(np.isfinite(lower)) and np.all(np.isfinite(upper))):
            raise RepertoireError("every arm joint needs finite position limits")
        self._lower, self._upper = lower, upper
        self._center = (
            np.zeros(3) if reach_center is None else np.asarray(reach_center, dtype=float)
        )
        self._max_reach = float(max_reach)
        self._tol = float(error_tolerance)
        self._hold = float(error_hold_time)

        self._p_d = self.DeclareVectorInputPort("position_desired", 3)
        self._v_d = self.DeclareVectorInputPort("velocity_desired", 3)
        self._q_d = self.DeclareVectorInputPort("orientation_desired", 4)
        self._w_d = self.DeclareVectorInputPort("angular_velocity_desired", 3)
        self._x_meas = self.DeclareVectorInputPort("arm_state_measured", 2 * n)

        self.gains_parameter_index = self.DeclareNumericParameter(
            BasicVector([position_gain, orientation_gain, damping, null_gain])
        )
        # Group 0: [q_r, qdot_r, qdd_r]; group 1: [status, seconds above tolerance,
        # position error, orientation error].
        self._ref_group = self.DeclareDiscreteState(3 * n)
        self._monitor_group = self.DeclareDiscreteState(4)
        self.DeclarePeriodicDiscreteUpdateEvent(self._period, 0.0, self._update)
        self.DeclareInitializationDiscreteUpdateEvent(self._initialize)

        self._plant_context = self.DeclareCacheEntry(
            "control plant context at q_r",
            ValueProducer(
                allocate=lambda: AbstractValue.Make(plant.CreateDefaultContext()),
                calc=self._calc_plant_context,
            ),
            prerequisites_of_calc={self.discrete_state_ticket(self._ref_group)},
        )

        self.DeclareVectorOutputPort(
            "arm_reference_state",
            2 * n,
            lambda c, o: o.SetFromVector(c.get_discrete_state(self._ref_group).value()[: 2 * n]),
            prerequisites_of_calc={self.discrete_state_ticket(self._ref_group)},
        )
        self.DeclareVectorOutputPort(
            "arm_reference_acceleration",
            n,
            lambda c, o: o.SetFromVector(c.get_discrete_state(self._ref_group).value()[2 * n :]),
            prerequisites_of_calc={self.discrete_state_ticket(self._ref_group)},
        )
        self.DeclareVectorOutputPort(
            "status",
            1,
            lambda c, o: o.SetFromVector(c.get_discrete_state(self._monitor_group).value()[:1]),
            prerequisites_of_calc={self.discrete_state_ticket(self._monitor_group)},
        )
        self.DeclareVectorOutputPort(
            "task_error",
            2,
            lambda c, o: o.SetFromVector(c.get_discrete_state(self._monitor_group).value()[2:]),
            prerequisites_of_calc={self.discrete_state_ticket(self._monitor_group)},
        )

    @property
    def num_arm_joints(self) -> int:
        return self._n

    def _calc_plant_context(self, context: Context, value: AbstractValue) -> None:
        plant_context = value.get_mutable_value()
        q = self._plant.GetPositions(plant_context).copy()
        q[self._idx] = context.get_discrete_state(self._ref_group).value()[: self._n]
        self._plant.SetPositions(plant_context, q)

    def end_effector_pose(self, context: Context) -> tuple[np.ndarray, RotationMatrix]:
        """Position and rotation of the end-effector at the reference ``q_r``."""
        plant_context = self._plant_context.Eval(context)
        X_WE = self._frame_E.CalcPoseInWorld(plant_context)
        return X_WE.translation(), X_WE.rotation()

    def _initialize(self, context: Context, discrete_state) -> None:
        n = self._n
        q_meas = self._x_meas.Eval(context)[:n]
        x = np.zeros(3 * n)
        x[:n] = np.clip(q_meas, self._lower, self._upper)
        discrete_state.get_mutable_vector(self._ref_group).SetFromVector(x)
        discrete_state.get_mutable_vector(self._monitor_group).SetFromVector(np.zeros(4))

    def _update(self, context: Context, discrete_state) -> None:
        n = self._n
        h = self._period
        kp, ko, damping, null_gain = context.get_numeric_parameter(
            self.gains_parameter_index
        ).value()
        ref = context.get_discrete_state(self._ref_group).value()
        q_r, qd_prev = ref[:n], ref[n : 2 * n]
        plant_context = self._plant_context.Eval(context)
        X_WE = self._frame_E.CalcPoseInWorld(plant_context)
        J = self._plant.CalcJacobianSpatialVelocity(
            plant_context,
            JacobianWrtVariable.kV,
            self._frame_E,
            np.zeros(3),
            self._plant.world_frame(),
            self._plant.world_frame(),
        )[:, self._idx]
        p_d = self._p_d.Eval(context)
        q_d = np.asarray(self._q_d.Eval(context), dtype=float)
        norm = np.linalg.norm(q_d)
        if not (np.isfinite(norm) and abs(norm - 1.0) < 1e-3):
            raise RepertoireError(
                f"orientation_desired must be a unit quaternion [w, x, y, z], got {q_d} "
                f"(norm {norm})"
            )
        e_p = p_d - X_WE.translation()
        e_o = quaternion_error(q_d / norm, X_WE.rotation().ToQuaternion().wxyz())
        xdot_ref = np.concatenate(
            [self._w_d.Eval(context) + ko * e_o, self._v_d.Eval(context) + kp * e_p]
        )
        qd = rmrc_joint_velocity(J, xdot_ref, q_r, self._lower, self._upper, damping, null_gain)
        q_new = np.clip(q_r + h * qd, self._lower, self._upper)
        qd = (q_new - q_r) / h
        discrete_state.get_mutable_vector(self._ref_group).SetFromVector(
            np.concatenate([q_new, qd, (qd - qd_prev) / h])
        )

        monitor = context.get_discrete_state(self._monitor_group).value()
        status, above = int(monitor[0]), monitor[1]
        pos_err = float(np.linalg.norm(e_p))
        ori_err = float(2.0 * np.arcsin(min(1.0, np.linalg.norm(e_o))))
        above = above + h if pos_err > self._tol else 0.0
        if status == STATUS_OK:
            if np.linalg.norm(p_d - self._center) > self._max_reach:
                status = STATUS_TARGET_OUT_OF_REACH
            elif above > self._hold:
                status = STATUS_TRACKING_LOST
        discrete_state.get_mutable_vector(self._monitor_group).SetFromVector(
            [status, above, pos_err, ori_err]
        )


def grip_wrench(
    X_WH: RigidTransform,
    X_WO: RigidTransform,
    X_HO_held: RigidTransform,
    V_WH: SpatialVelocity,
    V_WO: SpatialVelocity,
    p_OQ: np.ndarray,
    stiffness: float,
    damping: float,
    rotational_stiffness: float,
    rotational_damping: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Spring-damper wrench that holds an object at ``X_HO_held`` in the hand.

    The force acts at the object's point Q (its centre of mass) and pulls Q toward
    where it would be with the object at ``X_WH * X_HO_held``; the damping term
    pulls Q's velocity toward that of the hand's material point at Q.

    Args:
        X_WH: hand pose in W.
        X_WO: object pose in W.
        X_HO_held: the object pose in the hand frame captured when the grip closed.
        V_WH: hand spatial velocity in W (about the hand origin).
        V_WO: object spatial velocity in W (about the object origin).
        p_OQ: the point Q where the wrench acts, in the object frame.
        stiffness: translational stiffness in N/m.
        damping: translational damping in N s/m.
        rotational_stiffness: in N m/rad.
        rotational_damping: in N m s/rad.

    Returns:
        ``(torque_W, force_W)`` on the object at Q; the hand gets the opposite at Q.
    """
    X_WT = X_WH @ X_HO_held
    p_WQ = X_WO @ p_OQ
    w_WH, w_WO = V_WH.rotational(), V_WO.rotational()
    v_WHq = V_WH.translational() + np.cross(w_WH, p_WQ - X_WH.translation())
    v_WQ = V_WO.translational() + np.cross(w_WO, p_WQ - X_WO.translation())
    force = stiffness * (X_WT @ p_OQ - p_WQ) + damping * (v_WHq - v_WQ)
    aa = (X_WT.rotation() @ X_WO.rotation().inverse()).ToAngleAxis()
    torque = rotational_stiffness * aa.angle() * aa.axis() + rotational_damping * (w_WH - w_WO)
    return torque, force


class GraspWrench(LeafSystem):
    """The hand's grip on a grasped object, as a stiff spring-damper wrench.

    Physically motivated stand-in for frictional finger contact (documented
    choice): when the commanded finger closure exceeds ``close_threshold`` and a
    graspable object's origin is within ``capture_radius`` of the palm point, the
    object is latched and its pose in the hand frame is recorded; from then on a
    6-D spring-damper (the grip) holds it at that pose, with the reaction on the
    hand, until the closure drops below ``open_threshold`` (release). The object
    is then free and falls or rests under contact as usual. The latch and the
    recorded pose are discrete state updated every ``period``.

    Input ports:
        body_poses: the plant's ``body_poses`` (abstract list of RigidTransform).
        body_spatial_velocities: the plant's ``body_spatial_velocities``.
        finger_command: commanded finger positions, ``num_fingers``.

    Output ports:
        spatial_forces: abstract list of ExternallyAppliedSpatialForce for the
            plant's ``applied_spatial_force`` input (empty while nothing is held).
        held_object: [index into ``object_bodies`` of the held object, or -1], 1.

    Numeric parameter (index ``grip_parameter_index``): ``[stiffness, damping,
    rotational_stiffness, rotational_damping]``.
    """

    def __init__(
        self,
        hand_body_index: BodyIndex,
        object_body_indices: list[BodyIndex],
        *,
        num_fingers: int,
        closure_weights: np.ndarray,
        close_threshold: float,
        open_threshold: float,
        palm_point_H: np.ndarray,
        capture_radius: float,
        period: float,
        object_com_offsets: list[np.ndarray] | None = None,
        stiffness: float = 3000.0,
        damping: float = 40.0,
        rotational_stiffness: float = 5.0,
        rotational_damping: float = 0.05,
    ):
        """Builds the grip.

        Args:
            hand_body_index: the hand (palm) body in the simulation plant.
            object_body_indices: graspable bodies in the simulation plant.
            num_fingers: size of ``finger_command``.
            closure_weights: closure = ``closure_weights @ finger_command``.
            close_threshold: closure at or above which the grip latches.
            open_threshold: closure below which a held object is released.
            palm_point_H: point in the hand frame where objects are captured.
            capture_radius: largest distance (m) from the palm point to an object's
                origin at which closing the hand grips it.
            period: update period of the latch in s (use the plant's time step).
            object_com_offsets: centre of mass of each object in its body frame, where
                the grip acts (default: the body origins). With the plant's explicit
                time step h keep ``sqrt(k/m) h`` and ``c h / m`` (and the rotational
                counterparts with the object's inertia) well below 1.
            stiffness: translational grip stiffness, N/m.
            damping: translational grip damping, N s/m.
            rotational_stiffness: N m/rad.
            rotational_damping: N m s/rad.

        Raises:
            RepertoireError: inconsistent thresholds, sizes, or non-positive values.
        """
        super().__init__()
        closure_weights = np.asarray(closure_weights, dtype=float)
        if closure_weights.shape != (num_fingers,):
            raise RepertoireError(
                f"closure_weights must have {num_fingers} entries, got {closure_weights.shape}"
            )
        if not open_threshold < close_threshold:
            raise RepertoireError(
                f"open_threshold ({open_threshold}) must be below close_threshold "
                f"({close_threshold})"
            )
        if not (capture_radius > 0.0 and period > 0.0):
            raise RepertoireError("capture_radius and period must be > 0")
        if len(object_body_indices) == 0:
            raise RepertoireError("GraspWrench needs at least one graspable object body")
        self._hand = hand_body_index
        self._objects = list(object_body_indices)
        self._weights = closure_weights
        self._close = float(close_threshold)
        self._open = float(open_threshold)
        self._palm = np.asarray(palm_point_H, dtype=float)
        self._radius = float(capture_radius)
        if object_com_offsets is None:
            object_com_offsets = [np.zeros(3)] * len(self._objects)
        if len(object_com_offsets) != len(self._objects):
            raise RepertoireError("need one centre-of-mass offset per graspable object")
        self._coms = [np.asarray(p, dtype=float) for p in object_com_offsets]

        self._poses = self.DeclareAbstractInputPort(
            "body_poses", AbstractValue.Make([RigidTransform()])
        )
        self._velocities = self.DeclareAbstractInputPort(
            "body_spatial_velocities", AbstractValue.Make([SpatialVelocity()])
        )
        self._fingers = self.DeclareVectorInputPort("finger_command", num_fingers)
        self.grip_parameter_index = self.DeclareNumericParameter(
            BasicVector([stiffness, damping, rotational_stiffness, rotational_damping])
        )
        # [held object (-1 none), p_HO (3), quaternion_HO (4)]
        self._latch = self.DeclareDiscreteState(np.array([-1.0, 0, 0, 0, 1, 0, 0, 0]))
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        self.DeclareAbstractOutputPort(
            "spatial_forces",
            lambda: AbstractValue.Make([ExternallyAppliedSpatialForce()]),
            self._calc_forces,
        )
        self.DeclareVectorOutputPort(
            "held_object",
            1,
            lambda c, o: o.SetFromVector(c.get_discrete_state(self._latch).value()[:1]),
            prerequisites_of_calc={self.discrete_state_ticket(self._latch)},
        )

    def _update(self, context: Context, discrete_state) -> None:
        latch = context.get_discrete_state(self._latch).value().copy()
        closure = float(self._weights @ self._fingers.Eval(context))
        held = int(latch[0])
        if held >= 0 and closure < self._open:
            latch[0] = -1.0
        elif held < 0 and closure >= self._close:
            poses = self._poses.Eval(context)
            X_WH = poses[int(self._hand)]
            p_WP = X_WH @ self._palm
            distances = [np.linalg.norm(poses[int(b)].translation() - p_WP) for b in self._objects]
            best = int(np.argmin(distances))
            if distances[best] <= self._radius:
                X_HO = X_WH.inverse() @ poses[int(self._objects[best])]
                latch = np.concatenate(
                    [[best], X_HO.translation(), X_HO.rotation().ToQuaternion().wxyz()]
                )
        discrete_state.get_mutable_vector(self._latch).SetFromVector(latch)

    def _calc_forces(self, context: Context, output: AbstractValue) -> None:
        latch = context.get_discrete_state(self._latch).value()
        held = int(latch[0])
        if held < 0:
            output.set_value([])
            return
        k, c, kr, cr = context.get_numeric_parameter(self.grip_parameter_index).value()
        poses = self._poses.Eval(context)
        velocities = self._velocities.Eval(context)
        body_O = self._objects[held]
        X_HO = RigidTransform(Quaternion(latch[4:8] / np.linalg.norm(latch[4:8])), latch[1:4])
        X_WH, X_WO = poses[int(self._hand)], poses[int(body_O)]
        p_OQ = self._coms[held]
        torque, force = grip_wrench(
            X_WH,
            X_WO,
            X_HO,
            velocities[int(self._hand)],
            velocities[int(body_O)],
            p_OQ,
            k,
            c,
            kr,
            cr,
        )
        on_object = ExternallyAppliedSpatialForce()
        on_object.body_index = body_O
        on_object.p_BoBq_B = p_OQ
        on_object.F_Bq_W = SpatialForce(torque, force)
        on_hand = ExternallyAppliedSpatialForce()
        on_hand.body_index = self._hand
        on_hand.p_BoBq_B = X_WH.inverse() @ (X_WO @ p_OQ)
        on_hand.F_Bq_W = SpatialForce(-torque, -force)
        output.set_value([on_object, on_hand])


def stack_task_space_dmp(dmp: TaskSpaceDmp) -> DmpParameters:
    """The paper's 10-D DMP (Fig. 7) as one DmpParameters: [x y z, qw qx qy qz, fingers].

    Args:
        dmp: a TaskSpaceDmp whose orientation is in ``mode="component"`` (one
            transformation system per quaternion component, the paper's approach)
            and that has finger DOF.

    Raises:
        RepertoireError: manifold orientation, no fingers, or mismatched bases.
    """
    if dmp.orientation.mode != "component":
        raise RepertoireError(
            "the task-space chain runs the paper's component quaternion DMP; learn the "
            "orientation with orientation_mode='component'"
        )
    if dmp.fingers is None:
        raise RepertoireError("the task-space chain needs a DMP with finger DOF")
    parts = [dmp.position, dmp.orientation.component_parameters(), dmp.fingers]
    for part in parts[1:]:
        if part.n_basis != parts[0].n_basis or not np.array_equal(part.centres, parts[0].centres):
            raise RepertoireError("position, orientation and finger DMPs must share their basis")
    return DmpParameters(
        np.vstack([p.weights for p in parts]),
        parts[0].centres,
        parts[0].widths,
        np.concatenate([p.K for p in parts]),
        np.concatenate([p.D for p in parts]),
        parts[0].alpha,
        parts[0].tau,
        np.concatenate([p.x0 for p in parts]),
        np.concatenate([p.goal for p in parts]),
        parts[0].formulation,
    )


class TaskSpaceDmpChain(LeafSystem):
    """A sequence of 10-D task-space DMPs (Fig. 7) run one after another in one system.

    Each segment is the paper's 10-D DMP: end-effector position (3), orientation
    as four quaternion components with post-normalisation (4) and finger DOF
    (n_fingers), all sharing one phase, in the new formulation (eq. 6-7, 9; the
    math is :func:`repertoire.planning.dmp_math.transformation_derivatives`).
    Segment ``k`` starts at ``start_times[k]``: the phase is reset to 1, the new
    segment's start ``x0`` is the current position and the velocity is handed
    over (``x_pred -> x_succ``, ``v_pred -> v_succ``, section III-C), so the
    references stay continuous. The goal is an input, read every step, so it
    may change during the movement (section II-B); the world supplies the
    active segment's goal from the ``segment`` output. (``DmpSequencer`` of
    ``repertoire.systems.dmp_compose`` chains plain n-D DMPs with one goal; the arm
    worlds need a goal per segment read from the scene, the post-normalised
    orientation and the world angular velocity for the IK, hence this system.)

    Continuous state: [theta, x (10), v (10)] with ``v = tau dx/dt``. Discrete
    state: [segment index, x0 (10)], switched by a periodic unrestricted update.

    Input ports:
        goal: the active segment's goal [p (3), q (4), fingers (n_fingers)].
        coupling: position coupling term p of eq. 9-10 (3), e.g. ObstacleCoupling.

    Output ports:
        position: p_d (3).
        velocity: v_d (3).
        orientation: post-normalised q_d [w, x, y, z] (4).
        angular_velocity: w_d in W (3).
        finger_position, finger_velocity, finger_acceleration: n_fingers each.
        segment: [index of the active segment] (1).
        phase: [theta] (1).
    """

    def __init__(
        self,
        segments: list[TaskSpaceDmp],
        start_times: list[float],
        x_start: np.ndarray,
        *,
        switch_period: float = 0.004,
    ):
        """Builds the chain.

        Args:
            segments: the task-space DMPs in execution order (component orientation,
                same number of finger DOF).
            start_times: onset of each segment in s; the first is 0, increasing.
            x_start: the chain's start [p, q, fingers] (the robot's current state).
            switch_period: how often the switch times are checked, in s.

        Raises:
            RepertoireError: empty chain, bad times, or mismatched segments.
        """
        super().__init__()
        if len(segments) == 0:
            raise RepertoireError("a DMP chain needs at least one segment")
        if len(start_times) != len(segments):
            raise RepertoireError(
                f"need one start time per segment: {len(segments)} segments, "
                f"{len(start_times)} start times"
            )
        times = np.asarray(start_times, dtype=float)
        if times[0] != 0.0 or np.any(np.diff(times) <= 0.0):
            raise RepertoireError(
                f"start_times must start at 0 and increase, got {list(start_times)}"
            )
        self._params = [stack_task_space_dmp(s) for s in segments]
        n = self._params[0].n_dims
        if any(p.n_dims != n for p in self._params):
            raise RepertoireError("every segment must have the same number of finger DOF")
        x_start = np.asarray(x_start, dtype=float)
        if x_start.shape != (n,):
            raise RepertoireError(f"x_start must have {n} entries, got shape {x_start.shape}")
        self._n = n
        self._m = n - 7
        self._times = times
        self._goal = self.DeclareVectorInputPort("goal", n)
        self._coupling = self.DeclareVectorInputPort("coupling", 3)
        self.DeclareContinuousState(BasicVector(np.concatenate([[1.0], x_start, np.zeros(n)])))
        self._switch = self.DeclareDiscreteState(np.concatenate([[0.0], x_start]))
        self.DeclarePeriodicUnrestrictedUpdateEvent(switch_period, 0.0, self._maybe_switch)
        xc = {self.xc_ticket(), self.discrete_state_ticket(self._switch)}
        m = self._m
        self.DeclareVectorOutputPort(
            "position", 3, lambda c, o: o.SetFromVector(self._x(c)[:3]), prerequisites_of_calc=xc
        )
        self.DeclareVectorOutputPort(
            "velocity",
            3,
            lambda c, o: o.SetFromVector(self._xd(c)[:3]),
            prerequisites_of_calc=xc,
        )
        self.DeclareVectorOutputPort(
            "orientation", 4, lambda c, o: o.SetFromVector(self._q(c)[0]), prerequisites_of_calc=xc
        )
        self.DeclareVectorOutputPort(
            "angular_velocity",
            3,
            lambda c, o: o.SetFromVector(angular_velocity(*self._q(c))),
            prerequisites_of_calc=xc,
        )
        self.DeclareVectorOutputPort(
            "finger_position",
            m,
            lambda c, o: o.SetFromVector(self._x(c)[7:]),
            prerequisites_of_calc=xc,
        )
        self.DeclareVectorOutputPort(
            "finger_velocity",
            m,
            lambda c, o: o.SetFromVector(self._xd(c)[7:]),
            prerequisites_of_calc=xc,
        )
        self.DeclareVectorOutputPort(
            "finger_acceleration", m, lambda c, o: o.SetFromVector(self._derivatives(c)[2][7:])
        )
        self.DeclareVectorOutputPort(
            "segment",
            1,
            lambda c, o: o.SetFromVector([self._segment(c)]),
            prerequisites_of_calc={self.discrete_state_ticket(self._switch)},
        )
        self.DeclareVectorOutputPort(
            "phase", 1, lambda c, o: o.SetFromVector([self._theta(c)]), prerequisites_of_calc=xc
        )

    @property
    def segment_parameters(self) -> list[DmpParameters]:
        """The 10-D parameters of every segment."""
        return self._params

    def _segment(self, context: Context) -> int:
        return int(context.get_discrete_state(self._switch).GetAtIndex(0))

    def _theta(self, context: Context) -> float:
        return context.get_continuous_state_vector().GetAtIndex(0)

    def _x(self, context: Context) -> np.ndarray:
        return context.get_continuous_state_vector().CopyToVector()[1 : 1 + self._n]

    def _xd(self, context: Context) -> np.ndarray:
        z = context.get_continuous_state_vector().CopyToVector()
        return z[1 + self._n :] / self._params[self._segment(context)].tau

    def _q(self, context: Context) -> tuple[np.ndarray, np.ndarray]:
        """Normalised quaternion and its time derivative."""
        raw = self._x(context)[3:7]
        raw_dot = self._xd(context)[3:7]
        norm = np.linalg.norm(raw)
        q = raw / norm
        return q, (raw_dot - q * (q @ raw_dot)) / norm

    def _derivatives(self, context: Context) -> tuple[float, np.ndarray, np.ndarray]:
        """(theta', x', physical acceleration) of the active segment."""
        p = self._params[self._segment(context)]
        z = context.get_continuous_state_vector().CopyToVector()
        n = self._n
        theta, x, v = z[0], z[1 : 1 + n], z[1 + n :]
        x0 = context.get_discrete_state(self._switch).value()[1:]
        goal = np.array(self._goal.Eval(context), dtype=float)
        if not np.all(np.isfinite(goal)):
            raise RepertoireError(f"the DMP goal must be finite, got {goal}")
        if goal[3:7] @ x0[3:7] < 0.0:  # same hemisphere as the start: shortest rotation
            goal[3:7] = -goal[3:7]
        coupling = np.zeros(n)
        coupling[:3] = self._coupling.Eval(context)
        f = forcing_term(theta, p.weights, p.centres, p.widths)
        xd, vd = transformation_derivatives(
            x, v, theta, goal, x0, f, p.K, p.D, p.tau, p.formulation, coupling
        )
        return -p.alpha * theta / p.tau, xd, vd / p.tau

    def DoCalcTimeDerivatives(self, context: Context, derivatives) -> None:
        theta_dot, xd, acc = self._derivatives(context)
        tau = self._params[self._segment(context)].tau
        derivatives.get_mutable_vector().SetFromVector(np.concatenate([[theta_dot], xd, tau * acc]))

    def _maybe_switch(self, context: Context, state) -> None:
        k = self._segment(context)
        if k + 1 >= len(self._times) or context.get_time() < self._times[k + 1] - 1e-9:
            return
        n = self._n
        z = context.get_continuous_state_vector().CopyToVector()
        x, v = z[1 : 1 + n], z[1 + n :]
        # Hand over position and physical velocity: v_succ = tau_succ * v_pred / tau_pred.
        v_new = v * self._params[k + 1].tau / self._params[k].tau
        state.get_mutable_continuous_state().get_mutable_vector().SetFromVector(
            np.concatenate([[1.0], x, v_new])
        )
        state.get_mutable_discrete_state(self._switch).SetFromVector(np.concatenate([[k + 1], x]))


# ----------------------------------------------------------------------------- obstacle coupling
def multi_point_obstacle_coupling(
    x: np.ndarray,
    xd: np.ndarray,
    R_WE: np.ndarray,
    points_E: np.ndarray,
    obstacle: np.ndarray,
    gamma: float,
    beta: float,
    *,
    obstacle_radius: float = 0.0,
    length_scale: float = 0.0,
) -> np.ndarray:
    """Eq. 10 applied at several control points of the hand and its load, summed.

    Control point ``i`` sits at ``c_i = x + R_WE @ points_E[i]`` (``x`` is the
    end-effector's position, ``R_WE`` its orientation); it moves with the
    end-effector's linear velocity ``xd`` (the rotation's contribution is left out:
    the orientation DMPs turn slowly while carrying). Each point gets the paper's
    term ``p_i = gamma R_i v phi_i exp(-beta phi_i)``
    (:func:`repertoire.planning.dmp_math.obstacle_coupling`, same axis sign) and
    the sum drives the end-effector's position DMP::

        p = sum_i s(d_i) p_i,   s(d) = exp(-max(d - obstacle_radius, 0) / length_scale)

    with ``d_i = |c_i - o|``. ``length_scale = 0`` gives ``s = 1``: the paper's
    eq. 10 exactly, summed over the points (with the single point ``[0, 0, 0]`` it
    *is* eq. 10 on the end-effector). ``length_scale > 0`` is our extension: eq. 10
    depends on the angle only, so a gain strong enough to clear a cup-sized load
    (which needs a smaller ``beta``, acting over a wider angle) would also bend the
    movement far from the obstacle and keep it from its goal; the distance factor
    fades the term out beyond a few ``length_scale`` from the ball's surface.

    Args:
        x: End-effector position in W, shape (3,).
        xd: End-effector velocity dx/dt in W, shape (3,).
        R_WE: End-effector orientation (3 x 3 rotation matrix).
        points_E: Control points in the end-effector frame E, shape (k, 3), k >= 1.
        obstacle: Obstacle centre o in W, shape (3,).
        gamma: Gain of eq. 10 (>= 0).
        beta: Angular decay of eq. 10 (the paper's c, >= 0).
        obstacle_radius: Radius of the obstacle [m] (>= 0), where ``s`` is 1.
        length_scale: Decay length of ``s`` [m] (>= 0; 0 switches the factor off).

    Returns:
        The summed coupling term, shape (3,).

    Raises:
        RepertoireError: a negative gain, radius or length, or badly shaped points.
    """
    if gamma < 0 or beta < 0 or obstacle_radius < 0 or length_scale < 0:
        raise RepertoireError(
            "gamma, beta, obstacle_radius and length_scale must be >= 0, got "
            f"{gamma}, {beta}, {obstacle_radius}, {length_scale}"
        )
    pts = np.asarray(points_E, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 3 or pts.shape[0] == 0 or not np.all(np.isfinite(pts)):
        raise RepertoireError(
            f"control points must be a non-empty k x 3 array of finite numbers, got shape "
            f"{pts.shape}"
        )
    x = np.asarray(x, dtype=float).reshape(3)
    o = np.asarray(obstacle, dtype=float).reshape(3)
    R = np.asarray(R_WE, dtype=float).reshape(3, 3)
    total = np.zeros(3)
    for c in x + pts @ R.T:
        scale = 1.0
        if length_scale > 0.0:
            gap = max(float(np.linalg.norm(c - o)) - obstacle_radius, 0.0)
            scale = float(np.exp(-gap / length_scale))
            if scale < 1e-12:
                continue
        total += scale * obstacle_coupling(c, xd, o, gamma, beta)
    return total


class MultiPointObstacleCoupling(LeafSystem):
    """Eq. 10 at several control points (tcp, the carried cup, the fingers), summed.

    Wraps :func:`multi_point_obstacle_coupling`; with the single control point
    ``[0, 0, 0]`` and ``length_scale = 0`` it outputs the paper's eq. 10 on the
    end-effector (as ``repertoire.systems.dmp.ObstacleCoupling``).

    Input ports:
        position: end-effector position x in W (3).
        velocity: end-effector velocity dx/dt in W (3).
        orientation: end-effector orientation [w, x, y, z] (4; normalised here).
        obstacle: obstacle centre o in W (3).

    Output ports:
        coupling: the summed coupling term p (3), for the DMP chain's ``coupling`` input.

    Numeric parameters: [gamma, beta, obstacle_radius, length_scale].
    """

    def __init__(
        self,
        points_E: np.ndarray,
        *,
        gamma: float = 1000.0,
        beta: float = 20.0 / np.pi,
        obstacle_radius: float = 0.0,
        length_scale: float = 0.0,
    ) -> None:
        """Builds the coupling.

        Args:
            points_E: control points in the end-effector frame, shape (k, 3).
            gamma: gain of eq. 10.
            beta: angular decay of eq. 10.
            obstacle_radius: obstacle radius [m] for the distance factor.
            length_scale: decay length of the distance factor [m] (0: off, exact eq. 10).

        Raises:
            RepertoireError: negative gains or badly shaped control points.
        """
        super().__init__()
        # Validates everything once (a zero velocity gives a zero term).
        multi_point_obstacle_coupling(
            np.zeros(3),
            np.zeros(3),
            np.eye(3),
            points_E,
            np.ones(3),
            gamma,
            beta,
            obstacle_radius=obstacle_radius,
            length_scale=length_scale,
        )
        self._points = np.array(points_E, dtype=float)
        self._params = self.DeclareNumericParameter(
            BasicVector([float(gamma), float(beta), float(obstacle_radius), float(length_scale)])
        )
        self._x = self.DeclareVectorInputPort("position", 3)
        self._v = self.DeclareVectorInputPort("velocity", 3)
        self._q = self.DeclareVectorInputPort("orientation", 4)
        self._o = self.DeclareVectorInputPort("obstacle", 3)
        self.DeclareVectorOutputPort("coupling", 3, self._calc)

    @property
    def points_E(self) -> np.ndarray:
        """The control points in the end-effector frame (k x 3)."""
        return self._points.copy()

    def _calc(self, context: Context, output: BasicVector) -> None:
        gamma, beta, radius, length = context.get_numeric_parameter(self._params).value()
        q = np.asarray(self._q.Eval(context), dtype=float)
        norm = float(np.linalg.norm(q))
        if not np.isfinite(norm) or norm < 1e-9:
            raise RepertoireError(f"orientation must be a non-zero quaternion, got {q}")
        R = RotationMatrix(Quaternion(q / norm)).matrix()
        output.SetFromVector(
            multi_point_obstacle_coupling(
                self._x.Eval(context),
                self._v.Eval(context),
                R,
                self._points,
                self._o.Eval(context),
                gamma,
                beta,
                obstacle_radius=radius,
                length_scale=length,
            )
        )
