"""Grasp physics for the arm worlds: a grip wrench that holds an object in the hand.

Pastor et al. (2009) grasp with a real hand; our simulated grip (``grasp_mode="grip"``)
adds the wrench of :func:`grip_wrench` between hand and object when the fingers close
(:class:`GraspWrench`). Split out of systems/task_space.py (one concept per module).
"""

import numpy as np
from pydrake.common.eigen_geometry import Quaternion
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.multibody.math import SpatialForce, SpatialVelocity
from pydrake.multibody.plant import ExternallyAppliedSpatialForce
from pydrake.multibody.tree import BodyIndex
from pydrake.systems.framework import BasicVector, Context, LeafSystem

from repertoire.errors import RepertoireError


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
