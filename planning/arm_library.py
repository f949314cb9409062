"""The arm's motion library: synthetic demonstrations and the DMPs learned from them.

Pastor et al. (2009), sec. III-B / IV-B: movements are demonstrated once (here synthesised,
minimum-jerk through via points, as an exoskeleton recording would give), learned as
10-D task-space DMPs (position, the paper's component quaternion DMP, three fingers) and
stored under semantic labels (grasp, place, release, pour, retreat). Also the grasp
geometry the demonstrations and the worlds share (grasp heights, the side-grasp and
pouring orientations, the home tcp pose) and the grasp approach direction of a DMP.
"""

import functools

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.plant import MultibodyPlant
from repertoire.models.arm7 import (
    HAND_GRASP_7CM,
    HAND_OPEN,
    TABLE_HEIGHT,
    TCP_FRAME,
    arm7_home_configuration,
    make_arm7_control_plant,
)
from repertoire.planning.dmp import TaskSpaceDmp
from repertoire.planning.dmp_demos import Demonstration, synthesize_demonstration
from repertoire.planning.dmp_learn import learn_task_space_dmp
from repertoire.planning.motion_library import MotionLibrary
from repertoire.planning.motion_library import approach_direction as motion_approach_direction

from repertoire.errors import RepertoireError

#: Height of the cup's and the bottle's grasp frame above their bottom [m].
CUP_GRASP_HEIGHT = 0.055
BOTTLE_GRASP_HEIGHT = 0.10
#: Bottle spout (tip) above the grasp point, along the bottle axis [m].
BOTTLE_TIP_ABOVE_GRASP = 0.15
COASTER_TOP = 0.006
PLACE_CLEARANCE = 0.004
#: Tilt of the bottle when pouring: rotation about the approach axis z_palm [rad].
POUR_TILT = -1.65
#: Height of the bottle tip above the cup rim when pouring [m].
POUR_TIP_ABOVE_RIM = 0.10
CUP_RIM = 0.10


def rotation_from_approach(approach_W: np.ndarray) -> RotationMatrix:
    """Side-grasp orientation of the palm for a horizontal approach direction (sec. IV-C).

    z_palm (approach) is the horizontal part of ``approach_W``, x_palm is up (the
    axis of an upright cylinder), y_palm = z_palm x x_palm closes across it.
    """
    a = np.array([approach_W[0], approach_W[1], 0.0])
    norm = np.linalg.norm(a)
    if norm < 1e-9:
        raise RepertoireError(
            f"the grasp approach direction {approach_W} has no horizontal part; a side grasp "
            "needs a horizontal approach"
        )
    z = a / norm
    x = np.array([0.0, 0.0, 1.0])
    y = np.cross(z, x)
    return RotationMatrix(np.column_stack([x, y, z]))


def quaternion_wxyz(R: RotationMatrix) -> np.ndarray:
    """The unit quaternion (w, x, y, z) of a rotation matrix."""
    return R.ToQuaternion().wxyz()


# ----------------------------------------------------------------------------- motion library
#: The canonical layout the demonstrations were "recorded" in.
DEMO_CUP_XY = (0.55, -0.25)
DEMO_COASTER_XY = (0.55, 0.10)
DEMO_BOTTLE_XY = (0.52, -0.28)
DEMO_POUR_CUP_XY = (0.66, 0.0)
R_SIDE = rotation_from_approach(np.array([1.0, 0.0, 0.0]))
R_POUR = R_SIDE @ RotationMatrix.MakeZRotation(POUR_TILT)


def home_tcp_pose() -> RigidTransform:
    """The tcp pose of arm7 in its home configuration (base at the world origin)."""
    plant = arm_control_plant()
    context = plant.CreateDefaultContext()
    plant.SetPositions(context, np.concatenate([arm7_home_configuration(), HAND_OPEN]))
    return plant.GetFrameByName(TCP_FRAME).CalcPoseInWorld(context)


@functools.lru_cache(maxsize=1)
def arm_control_plant() -> MultibodyPlant:
    """The arm7 control plant (arm and fingers, no world), built once."""
    return make_arm7_control_plant()


def pour_tcp_position(cup_xy, R_WE: RotationMatrix) -> np.ndarray:
    """Tcp position that puts the bottle tip above a cup's centre (bottle held upright in E)."""
    tip = np.array([cup_xy[0], cup_xy[1], TABLE_HEIGHT + CUP_RIM + POUR_TIP_ABOVE_RIM])
    return tip - BOTTLE_TIP_ABOVE_GRASP * R_WE.matrix()[:, 0]


@functools.lru_cache(maxsize=1)
def synthetic_demonstrations() -> dict[str, Demonstration]:
    """The demonstrations of grasp, place, release, pour and retreat (sec. IV-B).

    Recorded in the canonical layout (``DEMO_*``): minimum-jerk paths through via
    points, minimum-jerk slerps, two minimum-jerk finger movements for the hand.

    Returns:
        label -> ``(t, positions, quaternions, fingers)``.
    """
    home = home_tcp_pose()
    p_home, q_home = home.translation(), quaternion_wxyz(home.rotation())
    q_side = quaternion_wxyz(R_SIDE)
    open_, grasp = np.array(HAND_OPEN), np.array(HAND_GRASP_7CM)
    demos = {}
    cup = np.array([*DEMO_CUP_XY, TABLE_HEIGHT + CUP_GRASP_HEIGHT])
    radial = np.array([cup[0], cup[1], 0.0]) / np.hypot(cup[0], cup[1])
    pre = cup - 0.10 * radial + np.array([0.0, 0.0, 0.03])
    demos["grasp"] = synthesize_demonstration(
        [p_home, (p_home + pre) / 2 + [0, 0, 0.02], pre, cup],
        (0.0, 0.8),
        q_home,
        q_side,
        (0.0, 0.6),
        [(0.0, 0.3, open_, open_), (0.82, 1.0, open_, grasp)],
        2.5,
    )
    coaster = np.array([*DEMO_COASTER_XY, TABLE_HEIGHT + COASTER_TOP + CUP_GRASP_HEIGHT])
    coaster = coaster + [0, 0, PLACE_CLEARANCE]
    lift = np.array([0, 0, 0.14])
    demos["place"] = synthesize_demonstration(
        [cup, cup + lift, (cup + coaster) / 2 + lift + [0, 0, 0.02], coaster + lift, coaster],
        (0.0, 0.85),
        q_side,
        q_side,
        (0.0, 1.0),
        [(0.0, 1.0, grasp, grasp)],
        3.0,
    )
    retreat = coaster + np.array([-0.12, 0.0, 0.08])
    demos["release"] = synthesize_demonstration(
        [coaster, coaster + [-0.02, 0, 0.03], retreat],
        (0.35, 1.0),
        q_side,
        q_side,
        (0.0, 1.0),
        [(0.0, 0.3, grasp, open_)],
        1.5,
    )
    bottle = np.array([*DEMO_BOTTLE_XY, TABLE_HEIGHT + BOTTLE_GRASP_HEIGHT])
    pour = pour_tcp_position(DEMO_POUR_CUP_XY, R_POUR)
    demos["pour"] = synthesize_demonstration(
        [bottle, bottle + [0, 0, 0.12], (bottle + pour) / 2 + [0, 0, 0.14], pour],
        (0.0, 0.8),
        q_side,
        quaternion_wxyz(R_POUR),
        (0.35, 0.95),
        [(0.0, 1.0, grasp, grasp)],
        2.2,
    )
    up = pour + np.array([0.0, 0.0, 0.06])
    demos["retreat"] = synthesize_demonstration(
        [pour, up],
        (0.2, 1.0),
        quaternion_wxyz(R_POUR),
        q_side,
        (0.0, 0.8),
        [(0.0, 1.0, grasp, grasp)],
        1.2,
    )
    return demos


@functools.lru_cache(maxsize=1)
def motion_library() -> dict[str, TaskSpaceDmp]:
    """Learns the labelled DMPs (grasp, place, release, pour, retreat) from the demos.

    Returns:
        label -> learned 10-D :class:`TaskSpaceDmp` (component quaternion DMP).
    """
    return {
        label: learn_task_space_dmp(t, p, q, f, orientation_mode="component", n_basis=30)
        for label, (t, p, q, f) in (
            (k, (d.t, d.position, d.orientation, d.fingers))
            for k, d in synthetic_demonstrations().items()
        )
    }


@functools.lru_cache(maxsize=1)
def arm_motion_library() -> MotionLibrary:
    """The learned DMPs as a labelled :class:`MotionLibrary` (sec. III-B).

    One primitive per label (``grasp``, ``place``, ``release``, ``pour``, ``retreat``),
    named ``<label>_arm7`` with context ``{"robot": "arm7"}``; the worlds recall
    their sequences from it (``compose("pick_and_place")`` is grasp -> place ->
    release).
    """
    lib = MotionLibrary()
    for label, dmp in motion_library().items():
        lib.add_dmp(f"{label}_arm7", label, dmp, {"robot": "arm7"})
    return lib


def approach_direction(dmp: TaskSpaceDmp, x_start: np.ndarray, goal: np.ndarray) -> np.ndarray:
    """Approach direction at the end of a movement (sec. IV-C).

    The position DMP rolled out from ``x_start`` to ``goal``, its velocity averaged over the
    last quarter of the part where it still moves
    (:func:`repertoire.planning.motion_library.approach_direction`).

    Args:
        dmp: the grasp DMP.
        x_start: start position (3).
        goal: goal position (3).

    Returns:
        Unit 3-vector.
    """
    return motion_approach_direction(dmp.position, goal, x_start, fraction=0.25, dt=0.005)
