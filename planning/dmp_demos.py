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
)
from repertoire.planning.dmp_quaternion import (
    quat_conjugate,
    quat_exp,
    quat_log,
    quat_multiply,
)

from repertoire.checks import check_seed, is_real, is_whole
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


def noisy_sparse_minimum_jerk(
    seed: int, n: int = 101, duration: float = 2.0, noise: float = 2e-3
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A unit minimum-jerk move (0 to 1) sampled at random times, with Gaussian noise.

    The hard case for learning a DMP: the stamps are ``0``, ``duration`` and ``n - 2``
    sorted uniform draws between them (gaps and clusters), and the positions carry noise
    of standard deviation ``noise``.

    Args:
        seed: Random seed (the same seed gives the same demonstration).
        n: Number of samples, >= 3.
        duration: Duration [s], > 0.
        noise: Standard deviation of the position noise, >= 0.

    Returns:
        ``(t, x, xd, xdd)``: stamps (n,), noisy positions (n, 1), and the move's exact
        velocities and accelerations at the stamps (n, 1), without noise.
    """
    if not (is_whole(n) and n >= 3):
        raise RepertoireError(f"n must be an integer >= 3, got {n!r}")
    if not (is_real(duration) and np.isfinite(duration) and duration > 0):
        raise RepertoireError(f"duration must be a finite number > 0 s, got {duration!r}")
    if not (is_real(noise) and np.isfinite(noise) and noise >= 0):
        raise RepertoireError(f"noise must be a finite number >= 0, got {noise!r}")
    rng = np.random.default_rng(check_seed(seed))
    t = np.concatenate([[0.0], np.sort(rng.uniform(0.0, duration, n - 2)), [duration]])
    x, xd, xdd = minimum_jerk(np.zeros(1), np.ones(1), duration, t)
    return t, x + rng.normal(scale=noise, size=x.shape), xd, xdd


def sines_in_motion(
    seed: int, n_dims: int = 1, duration: float = 1.5, n: int = 751
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A demonstration that starts and ends in motion: a sum of three sines per DOF.

    Each DOF is ``sum_k a_k sin(w_k t + phi_k)`` with ``a_k`` uniform in [-1, 1],
    ``w_k`` in [1, 4] rad/s and ``phi_k`` in [0, 2 pi): unlike Pastor et al.'s
    rest-to-rest demonstrations, its velocity at ``t = 0`` is (almost surely) not zero.

    Args:
        seed: Random seed (the same seed gives the same demonstration).
        n_dims: Number of DOF, >= 1.
        duration: Duration [s], > 0.
        n: Number of evenly spaced samples, >= 3.

    Returns:
        ``(t, x, xd)``: stamps (n,), positions (n, n_dims) and their exact velocities
        (n, n_dims).
    """
    if not (is_whole(n_dims) and n_dims >= 1):
        raise RepertoireError(f"n_dims must be an integer >= 1, got {n_dims!r}")
    if not (is_whole(n) and n >= 3):
        raise RepertoireError(f"n must be an integer >= 3, got {n!r}")
    if not (is_real(duration) and np.isfinite(duration) and duration > 0):
        raise RepertoireError(f"duration must be a finite number > 0 s, got {duration!r}")
    rng = np.random.default_rng(check_seed(seed))
    a = rng.uniform(-1.0, 1.0, (n_dims, 3))
    w = rng.uniform(1.0, 4.0, (n_dims, 3))
    ph = rng.uniform(0.0, 2.0 * np.pi, (n_dims, 3))
    t = np.linspace(0.0, duration, n)
    arg = w[None] * t[:, None, None] + ph[None]
    x = np.sum(a[None] * np.sin(arg), axis=2)
    xd = np.sum((a * w)[None] * np.cos(arg), axis=2)
    return t, x, xd


def slerp_minimum_jerk(q_start: np.ndarray, q_end: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Shortest-arc interpolation with a minimum-jerk time law over ``[t[0], t[-1]]``.

    Args:
        q_start: Start quaternion (unit).
        q_end: End quaternion (unit).
        t: Sample times, shape (N,).
    """
    q_start, q_end = np.asarray(q_start, float), np.asarray(q_end, float)
    for name, q in (("q_start", q_start), ("q_end", q_end)):
        if q.shape != (4,) or not np.all(np.isfinite(q)) or not np.linalg.norm(q) > 0.0:
            raise RepertoireError(
                f"{name} must be a non-zero finite quaternion [w, x, y, z], got {q}"
            )
    q_start, q_end = q_start / np.linalg.norm(q_start), q_end / np.linalg.norm(q_end)
    d = quat_multiply(q_end, quat_conjugate(q_start))
    if d[0] < 0:
        d = -d
    u = quat_log(d)
    s, _, _ = minimum_jerk(np.zeros(1), np.ones(1), t[-1] - t[0], t - t[0])
    return quat_multiply(quat_exp(s * u), q_start)


def _slerp(q0: np.ndarray, q1: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Shortest-arc slerp from q0 to q1 at fractions s (N,)."""
    q1 = q1 if q0 @ q1 >= 0 else -q1
    dot = np.clip(q0 @ q1, -1.0, 1.0)
    angle = np.arccos(dot)
    if angle < 1e-9:
        return np.tile(q0, (len(s), 1))
    s = s[:, None]
    return (np.sin((1 - s) * angle) * q0 + np.sin(s * angle) * q1) / np.sin(angle)


def _min_jerk_profile(t: np.ndarray, t0: float, t1: float) -> np.ndarray:
    """0 -> 1 minimum-jerk profile between t0 and t1 (0 before, 1 after)."""
    s, _, _ = minimum_jerk(np.zeros(1), np.ones(1), t1 - t0, np.clip(t - t0, 0.0, t1 - t0))
    return s[:, 0]


def synthesize_demonstration(
    via_points: np.ndarray,
    move_window: tuple,
    q_start: np.ndarray,
    q_end: np.ndarray,
    turn_window: tuple,
    fingers: list,
    duration: float,
    n_samples: int = 600,
) -> Demonstration:
    """A synthetic demonstration: what an exoskeleton recording would give (sec. IV-B).

    Args:
        via_points: end-effector via points (m x 3), a minimum-jerk path through them
            during ``move_window`` (fractions of the duration), at rest outside it.
        move_window: (start, end) of the position movement, fractions of ``duration``.
        q_start: start orientation [w, x, y, z].
        q_end: end orientation; a minimum-jerk slerp during ``turn_window``.
        turn_window: (start, end) of the rotation, fractions of ``duration``.
        fingers: list of (start fraction, end fraction, from (3), to (3)) minimum-jerk
            finger movements; the hand holds between them.
        duration: seconds.
        n_samples: samples of the demonstration.

    Returns:
        The Demonstration (t, positions (N x 3), quaternions (N x 4), fingers (N x 3)).
    """
    via_points = np.asarray(via_points, float)
    if via_points.ndim != 2 or via_points.shape[1] != 3 or len(via_points) < 2:
        raise RepertoireError(f"via_points must have shape (m >= 2, 3), got {via_points.shape}")
    if not np.all(np.isfinite(via_points)):
        raise RepertoireError("via_points contain NaN or inf")
    if not (np.isfinite(duration) and duration > 0) or int(n_samples) < 3:
        raise RepertoireError(
            f"duration must be > 0 and n_samples >= 3, got {duration} and {n_samples}"
        )
    for what, (a, b) in (("move_window", move_window), ("turn_window", turn_window)):
        if not 0.0 <= a < b <= 1.0:
            raise RepertoireError(f"{what} must be fractions 0 <= start < end <= 1, got {(a, b)}")
    for what, q in (("q_start", q_start), ("q_end", q_end)):
        q = np.asarray(q, float)
        if q.shape != (4,) or not abs(np.linalg.norm(q) - 1.0) <= 1e-6:
            raise RepertoireError(f"{what} must be a unit quaternion [w, x, y, z], got {q}")
    if not fingers:
        raise RepertoireError("fingers needs at least one (start, end, from, to) movement")
    t = np.linspace(0.0, duration, n_samples)
    t0, t1 = move_window[0] * duration, move_window[1] * duration
    inside = (t >= t0) & (t <= t1)
    n_in = int(inside.sum())
    if n_in < 3:
        raise RepertoireError(
            f"move_window {tuple(move_window)} holds {n_in} of the {n_samples} samples; the "
            "minimum-jerk path needs at least 3: widen it or use more samples"
        )
    _, path = minimum_jerk_via_points(np.asarray(via_points, float), t1 - t0, n_in)
    p = np.empty((n_samples, 3))
    p[t < t0] = via_points[0]
    p[inside] = path
    p[t > t1] = via_points[-1]
    s = _min_jerk_profile(t, turn_window[0] * duration, turn_window[1] * duration)
    q = _slerp(np.asarray(q_start, float), np.asarray(q_end, float), s)
    f = np.tile(np.asarray(fingers[0][2], float), (n_samples, 1))
    for a, b, f_from, f_to in fingers:
        s = _min_jerk_profile(t, a * duration, b * duration)
        active = t >= a * duration
        f[active] = (np.asarray(f_from) + np.outer(s, np.asarray(f_to) - np.asarray(f_from)))[
            active
        ]
    return Demonstration(t, p, q, f)
