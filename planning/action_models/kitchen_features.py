"""Kitchen features of Table 7 (Stulp & Beetz): goToPose and reach of the kitchen robot.

goToPose (start ``[x, y, phi, v]``, goal ``[x_g, y_g, phi_g, v_g]``), with
``angle_to_signed = norm(atan2(y_g - y, x_g - x) - phi)`` and ``norm`` wrapping
to [-pi, pi]:

- ``v_g``: the goal speed,
- ``dist``: ``sqrt((x - x_g)^2 + (y - y_g)^2)``,
- ``angle_to``: ``|angle_to_signed|``,
- ``angle_at``: ``sgn(angle_to_signed) * norm(phi_g - atan2(y_g - y, x_g - x))``
  (the soccer definitions of Table 7, which the kitchen row refers to),
- ``delta_angle``: ``|norm(phi_g - phi)|``.

reach (gripper start ``[x, y, z]`` and goal ``[x_g, y_g, z_g]``, both in the
chassis frame here):

- ``dist_xyz``, ``dist_xy``, ``dist_xz``, ``dist_yz``: Euclidean distances in
  3-D and in the three coordinate planes,
- ``angle_xy = atan2(y_g - y, x_g - x)``, ``angle_xz = atan2(z_g - z, x_g - x)``,
  ``angle_yz = atan2(z_g - z, y_g - y)``.

The paper's reach features are Cartesian; our arm is cylindrical (lift,
yaw about a column at ``COLUMN_X`` ahead of the axle, radial extension) and moves
on a straight joint-space line at limited joint speeds, so its duration is set
by the joint displacements, which the Cartesian features give only roughly (a
turn of the arm changes ``dist_xy`` little when the gripper is near the column).
:func:`kitchen_reach_arm_features` adds them, from the same start and goal:

- ``turn``: ``|norm(atan2(y_g, x_g - c) - atan2(y, x - c))|`` with ``c = COLUMN_X``,
  the arm's yaw displacement,
- ``d_radial``: ``|hypot(x_g - c, y_g) - hypot(x - c, y)|``, its extension,
- ``d_height``: ``|z_g - z|``, its lift.

All functions take one pair (1-D arrays) or ``n`` pairs (``(n, k)`` arrays) and
raise RepertoireError on NaN/inf or a wrong width.
"""

import numpy as np
from repertoire.planning.action_models.features import (
    goto_pose_features,
    state_goal_pairs,
    wrap_angle,
)

KITCHEN_GOTO_FEATURES = ("v_g", "dist", "angle_to", "angle_at", "delta_angle")
KITCHEN_REACH_FEATURES = (
    "dist_xyz",
    "dist_xy",
    "dist_xz",
    "dist_yz",
    "angle_xy",
    "angle_xz",
    "angle_yz",
)

KITCHEN_REACH_ARM_FEATURES = ("turn", "d_radial", "d_height")


def _pairs(name: str, start, goal, width: int) -> tuple[np.ndarray, np.ndarray, bool]:
    labels = "[x, y, phi, v]" if width == 4 else "[x, y, z]"
    return state_goal_pairs(name, start, goal, width, labels)


def kitchen_goto_features(state, goal) -> np.ndarray:
    """The five kitchen goToPose features (``KITCHEN_GOTO_FEATURES`` order).

    Args:
        state: ``[x, y, phi, v]`` or ``(n, 4)``.
        goal: ``[x_g, y_g, phi_g, v_g]`` or ``(n, 4)``.
    """
    s, g, single = _pairs("kitchen goToPose features", state, goal, 4)
    dist, angle_to, angle_at = goto_pose_features(s, g)[:, :3].T  # mirrored, as Table 7
    out = np.column_stack(
        [g[:, 3], dist, angle_to, angle_at, np.abs(wrap_angle(g[:, 2] - s[:, 2]))]
    )
    return out[0] if single else out


def kitchen_reach_features(start, goal) -> np.ndarray:
    """The seven kitchen reach features (``KITCHEN_REACH_FEATURES`` order).

    Args:
        start: gripper ``[x, y, z]`` or ``(n, 3)``.
        goal: gripper target ``[x_g, y_g, z_g]`` or ``(n, 3)``.
    """
    s, g, single = _pairs("kitchen reach features", start, goal, 3)
    dx, dy, dz = (g - s).T
    out = np.column_stack(
        [
            np.sqrt(dx**2 + dy**2 + dz**2),
            np.hypot(dx, dy),
            np.hypot(dx, dz),
            np.hypot(dy, dz),
            np.arctan2(dy, dx),
            np.arctan2(dz, dx),
            np.arctan2(dz, dy),
        ]
    )
    return out[0] if single else out


def kitchen_reach_arm_features(start, goal) -> np.ndarray:
    """The arm's joint displacements of a kitchen reach (``KITCHEN_REACH_ARM_FEATURES`` order).

    Args:
        start: gripper ``[x, y, z]`` in the chassis frame, or ``(n, 3)``.
        goal: gripper target ``[x_g, y_g, z_g]`` in the chassis frame, or ``(n, 3)``.
    """
    from repertoire.models.diffdrive.generate import COLUMN_X

    s, g, single = _pairs("kitchen reach arm features", start, goal, 3)
    out = np.column_stack(
        [
            np.abs(
                wrap_angle(
                    np.arctan2(g[:, 1], g[:, 0] - COLUMN_X)
                    - np.arctan2(s[:, 1], s[:, 0] - COLUMN_X)
                )
            ),
            np.abs(np.hypot(g[:, 0] - COLUMN_X, g[:, 1]) - np.hypot(s[:, 0] - COLUMN_X, s[:, 1])),
            np.abs(g[:, 2] - s[:, 2]),
        ]
    )
    return out[0] if single else out
