"""The repertoire biped: an ASIMO-like humanoid, its dimensions and its leg kinematics.

The model file is ``package://repertoire/biped/biped.urdf``: a floating ``pelvis``
with a fixed torso, head and arms, and two 6-DOF legs (hip yaw z, hip roll x,
hip pitch y, knee y, ankle pitch y, ankle roll x). The three hip axes meet at
the hip point, the two ankle axes at the ankle point, so each leg has the
closed-form inverse kinematics of Kajita et al. (Introduction to Humanoid
Robotics, 2014, sec. 2.5), implemented here as :func:`leg_ik` and checked
against the plant's forward kinematics in the tests.

Conventions: the pelvis frame P has x forward, y left, z up, origin at the
height of the hip points. A sole frame (``left_sole``/``right_sole``) sits at
the centre of the sole, ``ANKLE_HEIGHT`` below the ankle point, axes aligned
with the foot. With all joints at zero the legs are straight and vertical.
"""

import dataclasses
from pathlib import Path

import numpy as np

from repertoire.errors import RepertoireError

MODEL_URL = "package://repertoire/biped/biped.urdf"
MODEL_RELATIVE_PATH = "biped/biped.urdf"
#: The footstep table T learned on this biped in simulation (studies/footstep_table.py,
#: all 343 three-command sequences), used by the footstep planner for this robot.
LEARNED_TABLE_PATH = Path(__file__).resolve().parent / "learned_footstep_table.json"

HIP_Y = 0.075  # lateral offset of each hip point from the pelvis origin [m]
THIGH_LENGTH = 0.30  # hip point to knee axis [m]
SHANK_LENGTH = 0.30  # knee axis to ankle point [m]
ANKLE_HEIGHT = 0.07  # ankle point above the sole [m]
FOOT_LENGTH = 0.16  # sole size along x [m]
FOOT_WIDTH = 0.10  # sole size along y [m]
CONTACT_RADIUS = 0.01  # radius of the four sole-corner contact spheres [m]
TOTAL_MASS = 50.0  # [kg]

SIDES = ("left", "right")
LEG_JOINTS = ("hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch", "ankle_roll")
#: Actuated joint names in actuator order (left leg, then right leg).
JOINT_NAMES = tuple(f"{side}_{j}" for side in SIDES for j in LEG_JOINTS)
SOLE_FRAMES = {"left": "left_sole", "right": "right_sole"}
#: Joint position limits [rad] per leg joint, as in the URDF.
JOINT_LIMITS = {
    "hip_yaw": (-0.8, 0.8),
    "hip_roll": (-0.6, 0.6),
    "hip_pitch": (-1.9, 0.9),
    "knee": (0.0, 2.4),
    "ankle_pitch": (-1.2, 1.0),
    "ankle_roll": (-0.5, 0.5),
}
#: Effort limits [N m] per leg joint, as in the URDF.
EFFORT_LIMITS = {
    "hip_yaw": 120.0,
    "hip_roll": 200.0,
    "hip_pitch": 200.0,
    "knee": 250.0,
    "ankle_pitch": 150.0,
    "ankle_roll": 100.0,
}


@dataclasses.dataclass
class LegGains:
    """Joint PD gains used with the plant's desired-state input.

    Attributes:
        kp: proportional gain per leg joint [N m/rad], in ``LEG_JOINTS`` order.
        kd: derivative gain per leg joint [N m s/rad], in ``LEG_JOINTS`` order.
    """

    kp: list = dataclasses.field(
        default_factory=lambda: [800.0, 1500.0, 1500.0, 1500.0, 800.0, 800.0]
    )
    kd: list = dataclasses.field(default_factory=lambda: [20.0, 40.0, 40.0, 40.0, 20.0, 20.0])


def _rot_x(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _rot_y(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rot_z(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rotation_rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Rotation matrix R = Rz(yaw) Ry(pitch) Rx(roll) (Drake's RollPitchYaw convention)."""
    return _rot_z(yaw) @ _rot_y(pitch) @ _rot_x(roll)


def _side_sign(side: str) -> float:
    if side not in SIDES:
        raise RepertoireError(f"leg side must be one of {SIDES}, got {side!r}")
    return 1.0 if side == "left" else -1.0


def leg_fk(q_leg: np.ndarray, side: str) -> tuple[np.ndarray, np.ndarray]:
    """Pose of a sole frame in the pelvis frame from the six leg joint angles.

    Args:
        q_leg: (6,) joint angles in ``LEG_JOINTS`` order [rad].
        side: ``"left"`` or ``"right"``.

    Returns:
        ``(p_PS, R_PS)``: sole position (3,) and rotation (3, 3) in the pelvis frame.
    """
    q = np.asarray(q_leg, dtype=float)
    if q.shape != (6,):
        raise RepertoireError(f"leg_fk needs 6 joint angles, got shape {q.shape}")
    p = np.array([0.0, _side_sign(side) * HIP_Y, 0.0])
    R = _rot_z(q[0]) @ _rot_x(q[1]) @ _rot_y(q[2])
    p = p + R @ np.array([0.0, 0.0, -THIGH_LENGTH])
    R = R @ _rot_y(q[3])
    p = p + R @ np.array([0.0, 0.0, -SHANK_LENGTH])
    R = R @ _rot_y(q[4]) @ _rot_x(q[5])
    p = p + R @ np.array([0.0, 0.0, -ANKLE_HEIGHT])
    return p, R


def leg_ik(p_PS: np.ndarray, R_PS: np.ndarray, side: str, *, strict: bool = True) -> np.ndarray:
    """Closed-form inverse kinematics of one leg (Kajita's solution, knee bent forward).

    Args:
        p_PS: (3,) desired sole position in the pelvis frame [m].
        R_PS: (3, 3) desired sole orientation in the pelvis frame.
        side: ``"left"`` or ``"right"``.
        strict: if True, an out-of-reach target or a solution outside the joint
            limits raises; if False the knee is stretched to the reach limit and
            the angles are returned unclipped (for controllers that must not stop).

    Returns:
        (6,) joint angles in ``LEG_JOINTS`` order [rad].

    Raises:
        RepertoireError: non-finite input, target out of reach or outside the joint limits
            (when ``strict``).
    """
    p_PS = np.asarray(p_PS, dtype=float)
    R_PS = np.asarray(R_PS, dtype=float)
    if p_PS.shape != (3,) or R_PS.shape != (3, 3):
        raise RepertoireError(f"leg_ik needs p (3,) and R (3, 3), got {p_PS.shape}, {R_PS.shape}")
    if not (np.all(np.isfinite(p_PS)) and np.all(np.isfinite(R_PS))):
        raise RepertoireError("leg_ik target contains NaN or inf")
    hip = np.array([0.0, _side_sign(side) * HIP_Y, 0.0])
    ankle = p_PS + R_PS @ np.array([0.0, 0.0, ANKLE_HEIGHT])
    # Hip point relative to the ankle, in the foot frame.
    r = R_PS.T @ (hip - ankle)
    A, B = THIGH_LENGTH, SHANK_LENGTH
    C = float(np.linalg.norm(r))
    c_knee = (C * C - A * A - B * B) / (2.0 * A * B)
    if c_knee >= 1.0:
        if strict and c_knee > 1.0 + 1e-9:
            raise RepertoireError(
                f"leg_ik: {side} sole target out of reach (hip-ankle distance {C:.4f} m > "
                f"{A + B:.3f} m)"
            )
        knee = 0.0
    elif c_knee <= -1.0:
        raise RepertoireError(f"leg_ik: {side} sole target too close to the hip ({C:.4f} m)")
    else:
        knee = float(np.arccos(c_knee))
    ankle_pitch_a = float(np.arcsin(np.clip(A / C * np.sin(np.pi - knee), -1.0, 1.0)))
    ankle_roll = float(np.arctan2(r[1], r[2]))
    if ankle_roll > np.pi / 2:
        ankle_roll -= np.pi
    elif ankle_roll < -np.pi / 2:
        ankle_roll += np.pi
    ankle_pitch = float(-np.arctan2(r[0], np.sign(r[2]) * np.hypot(r[1], r[2])) - ankle_pitch_a)
    R = R_PS @ _rot_x(-ankle_roll) @ _rot_y(-ankle_pitch - knee)
    hip_yaw = float(np.arctan2(-R[0, 1], R[1, 1]))
    cz, sz = np.cos(hip_yaw), np.sin(hip_yaw)
    hip_roll = float(np.arctan2(R[2, 1], -R[0, 1] * sz + R[1, 1] * cz))
    hip_pitch = float(np.arctan2(-R[2, 0], R[2, 2]))
    q = np.array([hip_yaw, hip_roll, hip_pitch, knee, ankle_pitch, ankle_roll])
    if strict:
        for name, value in zip(LEG_JOINTS, q):
            lo, hi = JOINT_LIMITS[name]
            if not lo - 1e-9 <= value <= hi + 1e-9:
                raise RepertoireError(
                    f"leg_ik: {side}_{name} = {value:.3f} rad outside its limits [{lo}, {hi}]"
                )
    return q


def standing_joint_angles(
    pelvis_height: float = 0.62, stance_width: float = 2 * HIP_Y
) -> np.ndarray:
    """Joint angles (12,) in ``JOINT_NAMES`` order for a symmetric stand on flat ground.

    Args:
        pelvis_height: height of the pelvis origin (hip points) above the soles [m].
        stance_width: lateral distance between the sole centres [m].
    """
    q = []
    for side in SIDES:
        s = _side_sign(side)
        q.append(leg_ik(np.array([0.0, s * stance_width / 2, -pelvis_height]), np.eye(3), side))
    return np.concatenate(q)


def add_biped(plant, parser, *, gains: LegGains | None = None, name: str | None = None):
    """Adds the biped to an unfinalized plant and sets actuator PD gains.

    The gains make the plant's ``desired_state`` input a joint PD controller
    (requires a discrete plant with the ``lagged`` or ``sap`` contact approximation).

    Args:
        plant: an unfinalized ``MultibodyPlant``.
        parser: a ``Parser`` on that plant (``ConfigureParser`` is applied here).
        gains: joint PD gains (default :class:`LegGains`).
        name: optional model instance name.

    Returns:
        The biped's ModelInstanceIndex.
    """
    from pydrake.multibody.tree import PdControllerGains
    from repertoire.models import ConfigureParser

    ConfigureParser(parser)
    if name is not None:
        parser.SetAutoRenaming(True)
    (instance,) = parser.AddModels(url=MODEL_URL)
    if name is not None:
        plant.RenameModelInstance(instance, name)
    gains = gains or LegGains()
    if len(gains.kp) != 6 or len(gains.kd) != 6:
        raise RepertoireError(
            f"LegGains needs 6 kp and 6 kd values, got {len(gains.kp)}, {len(gains.kd)}"
        )
    for side in SIDES:
        for k, joint in enumerate(LEG_JOINTS):
            actuator = plant.GetJointActuatorByName(f"{side}_{joint}_motor", instance)
            actuator.set_controller_gains(PdControllerGains(p=gains.kp[k], d=gains.kd[k]))
    return instance


#: (mass [kg], CoM [m] in the pelvis frame) of the bodies fixed to the pelvis, as in the URDF:
#: pelvis, torso, head, left arm, right arm (arms hang from the shoulders rolled out by 0.06 rad).
UPPER_BODY_MASSES = (
    (9.0, (0.0, 0.0, 0.02)),
    (17.0, (-0.01, 0.0, 0.23)),
    (3.0, (0.0, 0.0, 0.48)),
    (3.0, (0.0, 0.195 + 0.22 * np.sin(0.06), 0.34 - 0.22 * np.cos(0.06))),
    (3.0, (0.0, -0.195 - 0.22 * np.sin(0.06), 0.34 - 0.22 * np.cos(0.06))),
)
_UPPER_BODY_MOMENT = sum(m * np.asarray(c) for m, c in UPPER_BODY_MASSES)
#: Leg link masses [kg]: hip yaw link, hip roll link, thigh, shank, ankle link, foot.
LEG_LINK_MASSES = (0.5, 0.5, 3.5, 2.0, 0.2, 0.8)


def _leg_com_moment(q_leg: np.ndarray, side: str) -> np.ndarray:
    """Sum of mass times CoM position (pelvis frame) over the six links of one leg."""
    q = np.asarray(q_leg, dtype=float)
    m_yaw, m_roll, m_thigh, m_shank, m_ankle, m_foot = LEG_LINK_MASSES
    hip = np.array([0.0, _side_sign(side) * HIP_Y, 0.0])
    R = _rot_z(q[0]) @ _rot_x(q[1]) @ _rot_y(q[2])
    thigh_com = hip + R @ np.array([0.0, 0.0, -THIGH_LENGTH / 2])
    knee = hip + R @ np.array([0.0, 0.0, -THIGH_LENGTH])
    R = R @ _rot_y(q[3])
    shank_com = knee + R @ np.array([0.0, 0.0, -SHANK_LENGTH / 2])
    ankle = knee + R @ np.array([0.0, 0.0, -SHANK_LENGTH])
    R = R @ _rot_y(q[4]) @ _rot_x(q[5])
    foot_com = ankle + R @ np.array([0.0, 0.0, -ANKLE_HEIGHT + 0.015])
    return (
        (m_yaw + m_roll) * hip
        + m_thigh * thigh_com
        + m_shank * shank_com
        + m_ankle * ankle
        + m_foot * foot_com
    )


def com_in_pelvis(q_joints: np.ndarray) -> np.ndarray:
    """Whole-body centre of mass in the pelvis frame.

    Args:
        q_joints: (12,) joint angles in ``JOINT_NAMES`` order.

    Returns:
        (3,) CoM position in the pelvis frame [m].
    """
    q = np.asarray(q_joints, dtype=float)
    if q.shape != (12,):
        raise RepertoireError(f"com_in_pelvis needs 12 joint angles, got shape {q.shape}")
    moment = _UPPER_BODY_MOMENT + _leg_com_moment(q[:6], "left") + _leg_com_moment(q[6:], "right")
    return moment / TOTAL_MASS
