"""What LittleDog's controllers measure: feet in contact, body pose, joint angles, feet.

:class:`FootContactSensor`: only the foot spheres of LittleDog collide (one per lower
leg), so a foot is
down when a contact pair involving its lower-leg body pushes with at least
``min_force``. :class:`BodyStateSensor`: body pose ``[x, y, z, roll, pitch, yaw]``, the
12 joint angles (``JOINT_NAMES`` order) and the world foot centres (closed-form FK)
from the plant's state.
"""

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.multibody.plant import ContactResults, MultibodyPlant
from pydrake.multibody.tree import ModelInstanceIndex
from pydrake.systems.framework import BasicVector, Context, LeafSystem
from repertoire.models.littledog import JOINT_NAMES, LEGS, leg_fk
from repertoire.models.littledog.pose import body_to_world, rpy_from_rotation

from repertoire.errors import RepertoireError


def foot_contact_flags(
    contact_results: ContactResults, foot_bodies: list[int], min_force: float
) -> tuple[np.ndarray, np.ndarray]:
    """Contact flags and slip speeds of the four feet.

    Args:
        contact_results: the plant's contact results.
        foot_bodies: body indices (ints) of the four lower legs, ``LEGS`` order.
        min_force: smallest contact force magnitude counted as contact (N).

    Returns:
        ``(flags, slip)``: 1.0 for each foot with a contact pair pushing at least
        ``min_force`` (else 0.0), and the largest tangential sliding speed of its
        contact points (m/s; 0 in flight).
    """
    flags = np.zeros(len(foot_bodies))
    slip = np.zeros(len(foot_bodies))
    for i in range(contact_results.num_point_pair_contacts()):
        info = contact_results.point_pair_contact_info(i)
        if np.linalg.norm(info.contact_force()) < min_force:
            continue
        for body in (int(info.bodyA_index()), int(info.bodyB_index())):
            if body in foot_bodies:
                k = foot_bodies.index(body)
                flags[k] = 1.0
                slip[k] = max(slip[k], info.slip_speed())
    return flags, slip


class FootContactSensor(LeafSystem):
    """Contact state of LittleDog's four feet.

    Input ports:
        contact_results: the plant's ``ContactResults`` (abstract).

    Output ports:
        contact: 4 flags (1.0 foot down, 0.0 in flight), ``LEGS`` order.
        slip_speed: 4 tangential sliding speeds of the feet's contacts (m/s).
    """

    def __init__(
        self, plant: MultibodyPlant, instance: ModelInstanceIndex, min_force: float = 0.5
    ) -> None:
        """Creates the system.

        Args:
        plant: the finalized plant holding LittleDog.
        instance: LittleDog's model instance.
        min_force: smallest contact force counted as contact (N), > 0.
        """
        super().__init__()
        if not (np.isfinite(min_force) and min_force > 0.0):
            raise RepertoireError(f"min_force must be > 0 N, got {min_force}")
        self._bodies = [
            int(plant.GetBodyByName(f"{leg}_lower_leg", instance).index()) for leg in LEGS
        ]
        self._min_force = float(min_force)
        self.contact_results_input = self.DeclareAbstractInputPort(
            "contact_results", AbstractValue.Make(ContactResults())
        )
        self.contact_output = self.DeclareVectorOutputPort("contact", 4, self._calc)
        self.slip_speed_output = self.DeclareVectorOutputPort("slip_speed", 4, self._calc_slip)

    def _calc(self, context: Context, output: BasicVector) -> None:
        results = self.contact_results_input.Eval(context)
        output.SetFromVector(foot_contact_flags(results, self._bodies, self._min_force)[0])

    def _calc_slip(self, context: Context, output: BasicVector) -> None:
        results = self.contact_results_input.Eval(context)
        output.SetFromVector(foot_contact_flags(results, self._bodies, self._min_force)[1])


def body_pose_from_positions(q_plant) -> np.ndarray:
    """Body pose [x, y, z, roll, pitch, yaw] from plant positions (quaternion w, x, y, z, then xyz).

    LittleDog's floating base comes first in the plant's positions.
    """
    q = np.asarray(q_plant, dtype=float)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    n = np.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    R = np.empty(q.shape[:-1] + (3, 3))
    R[..., 0, 0] = 1 - 2 * (y * y + z * z)
    R[..., 0, 1] = 2 * (x * y - z * w)
    R[..., 0, 2] = 2 * (x * z + y * w)
    R[..., 1, 0] = 2 * (x * y + z * w)
    R[..., 1, 1] = 1 - 2 * (x * x + z * z)
    R[..., 1, 2] = 2 * (y * z - x * w)
    R[..., 2, 0] = 2 * (x * z - y * w)
    R[..., 2, 1] = 2 * (y * z + x * w)
    R[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return np.concatenate([q[..., 4:7], rpy_from_rotation(R)], axis=-1)


def feet_in_world(pose, q_joints) -> np.ndarray:
    """World foot centres (4 x 3) from a body pose and 12 joint angles (closed-form FK)."""
    q = np.asarray(q_joints, dtype=float)
    p_BF = np.stack([leg_fk(leg, q[3 * i : 3 * i + 3]) for i, leg in enumerate(LEGS)])
    return body_to_world(pose, p_BF)


class BodyStateSensor(LeafSystem):
    """LittleDog's body pose, joint angles and world foot positions from the plant state.

    Input ports:
        state: the plant's state output (positions then velocities).

    Output ports:
        body_pose: [x, y, z, roll, pitch, yaw] of the body.
        joint_angles: 12 joint angles, ``JOINT_NAMES`` order.
        feet: world foot centres, 12 values (``LEGS`` order, x y z each).
    """

    def __init__(self, plant: MultibodyPlant, instance: ModelInstanceIndex) -> None:
        """Creates the system.

        Args:
        plant: the finalized plant; LittleDog's floating base must be its first positions.
        instance: LittleDog's model instance.
        """
        super().__init__()
        body = plant.GetBodyByName("body", instance)
        if not body.is_floating_base_body() or body.floating_positions_start() != 0:
            raise RepertoireError("BodyStateSensor needs LittleDog's floating base first in q")
        self._joint_starts = [
            plant.GetJointByName(n, instance).position_start() for n in JOINT_NAMES
        ]
        self.state_input = self.DeclareVectorInputPort("state", plant.num_multibody_states())
        self.body_pose_output = self.DeclareVectorOutputPort("body_pose", 6, self._calc_pose)
        self.joint_angles_output = self.DeclareVectorOutputPort(
            "joint_angles", 12, self._calc_joints
        )
        self.feet_output = self.DeclareVectorOutputPort("feet", 12, self._calc_feet)

    def _calc_pose(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(body_pose_from_positions(self.state_input.Eval(context)[:7]))

    def _calc_joints(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self.state_input.Eval(context)[self._joint_starts])

    def _calc_feet(self, context: Context, output: BasicVector) -> None:
        pose = self.body_pose_output.Eval(context)
        q = self.joint_angles_output.Eval(context)
        output.SetFromVector(feet_in_world(pose, q).reshape(12))


__all__ = [
    "BodyStateSensor",
    "FootContactSensor",
    "body_pose_from_positions",
    "feet_in_world",
    "foot_contact_flags",
]
