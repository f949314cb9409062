"""Synthesised demonstrations: minimum-jerk movements through via points.

Positions, quaternions and fingers stand in for the paper's recorded exoskeleton data
(sec. IV-B).

Finger trajectories follow the paper: composed of minimum-jerk segments (e.g. open, then
close). Orientations follow a minimum-jerk time law along the shortest arc (slerp) between
key orientations.
"""

from dataclasses import dataclass

import numpy as np
from repertoire.planning.dmp_math import (
    minimum_jerk,
    minimum_jerk_via_points,
    quat_conjugate,
    quat_exp,
    quat_log,
    quat_multiply,
)

from repertoire.errors import RepertoireError


@dataclass
class Demonstration:
    """A synthesised task-space demonstration.

    Attributes:
        t: Time stamps [s], shape (N,).
        position: End-effector positions p_WE [m], shape (N, 3).
        orientation: Unit quaternions (w, x, y, z), shape (N, 4).
        fingers: Finger positions, shape (N, k) (k may be 0).
    """

    t: np.ndarray
    position: np.ndarray
    orientation: np.ndarray
    fingers: np.ndarray


def _min_jerk_keyframes(keys: np.ndarray, key_times: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Rest-to-rest minimum-jerk segments between keyframes held at given times."""
    out = np.empty((t.size, keys.shape[1]))
    out[:] = keys[0]
    for i in range(len(keys) - 1):
        t0, t1 = key_times[i], key_times[i + 1]
        sel = t >= t0
        x, _, _ = minimum_jerk(keys[i], keys[i + 1], t1 - t0, t[sel] - t0)
        out[sel] = x
    return out


def slerp_minimum_jerk(q_start: np.ndarray, q_end: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Shortest-arc interpolation with a minimum-jerk time law over ``[t[0], t[-1]]``.

    Args:
        q_start: Start quaternion (unit).
        q_end: End quaternion (unit).
        t: Sample times, shape (N,).
    """
    q_start = np.asarray(q_start, float) / np.linalg.norm(q_start)
    q_end = np.asarray(q_end, float) / np.linalg.norm(q_end)
    d = quat_multiply(q_end, quat_conjugate(q_start))
    if d[0] < 0:
        d = -d
    u = quat_log(d)
    s, _, _ = minimum_jerk(np.zeros(1), np.ones(1), t[-1] - t[0], t - t[0])
    return quat_multiply(quat_exp(s * u), q_start)


def synthesize_demonstration(
    via_points: np.ndarray,
    orientations: np.ndarray,
    finger_keys: np.ndarray | None = None,
    finger_times: np.ndarray | None = None,
    *,
    duration: float = 2.0,
    n_samples: int = 481,
) -> Demonstration:
    """A minimum-jerk demonstration through via points.

    Args:
        via_points: Positions incl. start and end, shape (m, 3).
        orientations: Start and end orientation (w, x, y, z), shape (2, 4).
        finger_keys: Finger key positions, shape (r, k); None for no fingers.
        finger_times: Fractions of the duration (in [0, 1], increasing, first 0, last 1) at
            which the finger keys are reached.
        duration: Duration [s].
        n_samples: Number of samples (the paper recorded at 480 Hz).
    """
    t, pos = minimum_jerk_via_points(via_points, duration, n_samples)
    orientations = np.asarray(orientations, float)
    if orientations.shape != (2, 4):
        raise RepertoireError(f"orientations must have shape (2, 4), got {orientations.shape}")
    quat = slerp_minimum_jerk(orientations[0], orientations[1], t)
    if finger_keys is None:
        fingers = np.zeros((t.size, 0))
    else:
        keys = np.atleast_2d(np.asarray(finger_keys, float))
        times = np.linspace(0, 1, len(keys)) if finger_times is None else np.asarray(finger_times)
        if times.shape != (len(keys),) or times[0] != 0 or times[-1] != 1:
            raise RepertoireError("finger_times must start at 0, end at 1, one per finger key")
        if np.any(np.diff(times) <= 0):
            raise RepertoireError("finger_times must be increasing")
        fingers = _min_jerk_keyframes(keys, times * duration, t)
    return Demonstration(t, pos, quat, fingers)
