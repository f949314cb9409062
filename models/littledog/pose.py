"""Body poses of LittleDog as 6-vectors and foot positions between world and body frames.

A body pose is ``[x, y, z, roll, pitch, yaw]``: the body origin in the world
frame W (m) and the body's orientation as roll-pitch-yaw angles (rad),
``R_WB = Rz(yaw) Ry(pitch) Rx(roll)`` (Drake's RollPitchYaw convention). The
functions are vectorised over leading axes and written with numpy only, so the
100 Hz controllers can call them without building Drake objects.
"""

import numpy as np

from repertoire.errors import RepertoireError


def _as_pose(pose, name: str = "pose") -> np.ndarray:
    pose = np.asarray(pose, dtype=float)
    if pose.shape[-1:] != (6,):
        raise RepertoireError(
            f"{name} must have shape (..., 6) [x, y, z, roll, pitch, yaw], got {pose.shape}"
        )
    if not np.all(np.isfinite(pose)):
        raise RepertoireError(f"{name} contains NaN or infinite values")
    return pose


def rotation_from_rpy(rpy) -> np.ndarray:
    """Rotation matrices ``Rz(yaw) Ry(pitch) Rx(roll)``, shape ``(..., 3, 3)``."""
    rpy = np.asarray(rpy, dtype=float)
    r, p, y = rpy[..., 0], rpy[..., 1], rpy[..., 2]
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    R = np.empty(rpy.shape[:-1] + (3, 3))
    R[..., 0, 0] = cy * cp
    R[..., 0, 1] = cy * sp * sr - sy * cr
    R[..., 0, 2] = cy * sp * cr + sy * sr
    R[..., 1, 0] = sy * cp
    R[..., 1, 1] = sy * sp * sr + cy * cr
    R[..., 1, 2] = sy * sp * cr - cy * sr
    R[..., 2, 0] = -sp
    R[..., 2, 1] = cp * sr
    R[..., 2, 2] = cp * cr
    return R


def rpy_from_rotation(R) -> np.ndarray:
    """Roll-pitch-yaw angles of rotation matrices (inverse of :func:`rotation_from_rpy`)."""
    R = np.asarray(R, dtype=float)
    pitch = np.arcsin(np.clip(-R[..., 2, 0], -1.0, 1.0))
    roll = np.arctan2(R[..., 2, 1], R[..., 2, 2])
    yaw = np.arctan2(R[..., 1, 0], R[..., 0, 0])
    return np.stack([roll, pitch, yaw], axis=-1)


def body_to_world(pose, p_BF) -> np.ndarray:
    """World positions ``p_WF`` of body-frame points ``p_BF`` (shape ``(..., 4, 3)`` or ``(3,)``).

    Args:
        pose: body pose ``[x, y, z, roll, pitch, yaw]``.
        p_BF: points in the body frame; the last axis is (x, y, z).
    """
    pose = _as_pose(pose)
    R = rotation_from_rpy(pose[3:])
    return np.asarray(p_BF, dtype=float) @ R.T + pose[:3]


def world_to_body(pose, p_WF) -> np.ndarray:
    """Body-frame positions ``p_BF`` of world points ``p_WF`` (inverse of :func:`body_to_world`)."""
    pose = _as_pose(pose)
    R = rotation_from_rpy(pose[3:])
    return (np.asarray(p_WF, dtype=float) - pose[:3]) @ R


def wrap_angle(a):
    """Angles wrapped into ``[-pi, pi)``."""
    return (np.asarray(a, dtype=float) + np.pi) % (2.0 * np.pi) - np.pi


def pose_error(pose, pose_ref) -> tuple[float, float]:
    """Position error (m) and yaw-roll-pitch angle error (rad, largest |wrapped difference|)."""
    a, b = _as_pose(pose), _as_pose(pose_ref, "pose_ref")
    return float(np.linalg.norm(a[:3] - b[:3])), float(np.max(np.abs(wrap_angle(a[3:] - b[3:]))))
