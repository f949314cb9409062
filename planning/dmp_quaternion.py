"""Quaternion math of orientation DMPs: S^3 products, exp/log, the goal's sign, rollouts.

Quaternions are ``(w, x, y, z)`` (Drake's order). ``quat_exp(u)`` maps a 3-vector ``u``
to ``(cos|u|, sin|u| u/|u|)`` (a rotation by ``2|u|``), and ``quat_log`` is its inverse.
The position DMP math these build on is in :mod:`repertoire.planning.dmp_math`.
"""

import math

import numpy as np
from repertoire.planning.dmp_math import (
    canonical_phase,
    check_finite_vector,
    check_n_steps,
    check_positive,
    forcing_term,
)

from repertoire.errors import RepertoireError

FULL_TURN_MARGIN = 1e-3  # [rad] how close to a full turn a manifold DMP may be asked to turn


def check_turn(
    goal: np.ndarray, q: np.ndarray, *, what: str = "from the start to the goal"
) -> float:
    """Angle ``2 arccos(goal . q)`` the manifold DMP turns from ``q`` to ``goal`` (on S^3).

    Raises RepertoireError when it is within :data:`FULL_TURN_MARGIN` of a full turn
    (``goal`` near ``-q``), where ``2 log(goal q^*)`` has no defined axis.

    Args:
        goal: Goal orientation, shape (4,) (the sign counts).
        q: Orientation, shape (4,).
        what: Which turn, for the message.
    """
    c = float(np.clip(np.asarray(goal, float) @ np.asarray(q, float), -1.0, 1.0))
    angle = 2.0 * math.acos(c)
    if angle > 2.0 * math.pi - FULL_TURN_MARGIN:
        raise RepertoireError(
            f"the turn {what} is {math.degrees(angle):.4f} deg (goal . q = {c:.6g}), within "
            f"{FULL_TURN_MARGIN} rad of a full turn: the on-manifold quaternion DMP turns "
            "less than a full 360 deg turn; use mode='component' or split the movement"
        )
    return angle


#: Largest growth exponent (:func:`manifold_growth_exponent`) accepted when learning an
#: on-manifold quaternion DMP: sideways deviations grow at most e^6.9 = 1000-fold.
MAX_MANIFOLD_GROWTH = math.log(1000.0)


def manifold_growth_exponent(
    t: np.ndarray, q: np.ndarray, goal: np.ndarray, K: float, D: float
) -> float:
    """How much the on-manifold DMP amplifies sideways deviations along a demonstration.

    Past 180 deg from the goal the spring ``K e``, ``e = 2 log(g q^*)`` (angle ``psi``),
    pushes a sideways deviation outward: the linearised error dynamics perpendicular to
    ``e`` have stiffness ``-K kappa(psi)``, ``kappa = -(psi / 2) cot(psi / 2)`` (> 0 for
    ``psi`` in (pi, 2 pi), growing as ``2 pi / (2 pi - psi)`` near a full turn), so with
    ``tau^2 x'' + D tau x' = K kappa x`` a deviation grows at
    ``lambda = (-D + sqrt(D^2 + 4 K kappa)) / (2 tau)``. The exponent is
    ``E = int lambda dt`` over the demonstration (trapezoid rule; ``tau = t[-1] - t[0]``):
    a start or goal off the demonstration by ``delta`` leaves it by about
    ``delta e^(3 E / 4)`` (measured on yaw demonstrations: 300 deg E = 4.7, 330 deg 8.0,
    355 deg 17.5 with 1e-6 rad at the start 2.1 rad off).

    Args:
        t: Time stamps, shape (N,), increasing.
        q: Sign-continuous unit quaternions (w, x, y, z), shape (N, 4).
        goal: Goal quaternion (the sign counts), shape (4,).
        K: Spring constant (> 0).
        D: Damping (>= 0).

    Returns:
        ``E`` (0 for a demonstration that stays within 180 deg of the goal).
    """
    t = np.asarray(t, dtype=float)
    tau = float(t[-1] - t[0])
    psi = 2.0 * np.arccos(np.clip(np.asarray(q, float) @ np.asarray(goal, float), -1.0, 1.0))
    half = np.clip(psi / 2.0, 0.0, math.pi - 1e-12)
    kappa = np.zeros_like(psi)
    past = psi > math.pi
    kappa[past] = -half[past] * np.cos(half[past]) / np.sin(half[past])
    lam = (-D + np.sqrt(D * D + 4.0 * K * kappa)) / (2.0 * tau)
    return float(np.sum(0.5 * (lam[1:] + lam[:-1]) * np.diff(t)))


def check_manifold_growth(t: np.ndarray, q: np.ndarray, goal: np.ndarray, K: float, D: float):
    """Raise RepertoireError when :func:`manifold_growth_exponent` exceeds the bound.

    Args:
        t: Time stamps, shape (N,).
        q: Sign-continuous unit quaternions, shape (N, 4).
        goal: Goal quaternion, shape (4,).
        K: Spring constant.
        D: Damping.
    """
    E = manifold_growth_exponent(t, q, goal, K, D)
    if E > MAX_MANIFOLD_GROWTH:
        turn = math.degrees(
            2.0 * math.acos(float(np.clip(np.asarray(q, float) @ goal, -1, 1).min()))
        )
        raise RepertoireError(
            f"the on-manifold quaternion DMP is unstable along this demonstration: it turns "
            f"up to {turn:.1f} deg from the goal, and past 180 deg the spring pushes sideways "
            f"deviations outward, which grow by e^{E:.1f} = {math.exp(min(E, 700.0)):.3g} "
            f"along it (at most e^{MAX_MANIFOLD_GROWTH:.1f} = 1000 accepted; a demonstration "
            "with a sideways detour is then reproduced up to 180 deg off); use "
            "mode='component' or split the movement"
        )


def quat_multiply(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product ``p * q`` of (w, x, y, z) quaternions, broadcasting over leading axes.

    Args:
        p: Shape (..., 4).
        q: Shape (..., 4).
    """
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    pw, pv = p[..., :1], p[..., 1:]
    qw, qv = q[..., :1], q[..., 1:]
    w = pw * qw - np.sum(pv * qv, axis=-1, keepdims=True)
    v = pw * qv + qw * pv + np.cross(pv, qv)
    return np.concatenate([w, v], axis=-1)


def quat_conjugate(q: np.ndarray) -> np.ndarray:
    """Conjugate ``(w, -x, -y, -z)``.

    Args:
        q: Shape (..., 4).
    """
    q = np.asarray(q, dtype=float)
    return np.concatenate([q[..., :1], -q[..., 1:]], axis=-1)


def quat_exp(u: np.ndarray) -> np.ndarray:
    """Exponential map ``u -> (cos|u|, sin|u| u/|u|)`` (unit quaternion; rotation by 2|u|).

    Args:
        u: Shape (..., 3).
    """
    u = np.asarray(u, dtype=float)
    a = np.linalg.norm(u, axis=-1, keepdims=True)
    small = a < 1e-8
    safe = np.where(small, 1.0, a)
    s = np.where(small, 1.0 - a * a / 6.0, np.sin(safe) / safe)
    q = np.concatenate([np.cos(a), s * u], axis=-1)
    return q


def quat_log(q: np.ndarray) -> np.ndarray:
    """Logarithm of a unit quaternion, the inverse of :func:`quat_exp` (|result| <= pi).

    Args:
        q: Shape (..., 4), unit norm.
    """
    q = np.asarray(q, dtype=float)
    w = q[..., :1]
    v = q[..., 1:]
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    angle = np.arctan2(n, w)
    small = n < 1e-12
    safe = np.where(small, 1.0, n)
    scale = np.where(small, 1.0 / np.where(np.abs(w) > 0, w, 1.0), angle / safe)
    return scale * v


def quat_error(goal: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Rotation vector ``2 log(goal * conj(q))`` along the shortest arc (world frame).

    Args:
        goal: Shape (..., 4).
        q: Shape (..., 4).
    """
    d = quat_multiply(goal, quat_conjugate(q))
    d = np.where(d[..., :1] < 0.0, -d, d)
    return 2.0 * quat_log(d)


def quat_log_error(goal: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Rotation vector ``2 log(goal * conj(q))`` on the unit sphere S^3 (no hemisphere flip).

    Unlike :func:`quat_error` the sign of the quaternions counts: ``goal`` and ``-goal``
    give the two ways round (angles ``phi`` and ``2 pi - phi`` about opposite axes), and
    the result (angle in [0, 2 pi]) is continuous in ``q`` except at ``q = -goal`` (a full
    turn). This is the error of Ude et al. (2014)'s quaternion DMP; along a sign-continuous
    path it does not jump when the rotation left to the goal passes 180 deg.

    Args:
        goal: Shape (..., 4).
        q: Shape (..., 4).
    """
    return 2.0 * quat_log(quat_multiply(goal, quat_conjugate(q)))


def learned_side(q: np.ndarray, learned_start: np.ndarray) -> float:
    """+1 or -1: the sign that puts ``q`` on the learned start's side (``q . q0 >= 0``).

    ``q`` and ``-q`` are one orientation but not one state of the component form (R^4),
    whose forcing term was learned from ``learned_start``: a component quaternion DMP runs
    from ``sign * q`` (its velocity and acceleration multiplied alike).
    """
    return 1.0 if float(np.asarray(q, dtype=float) @ learned_start) >= 0.0 else -1.0


def lift_quaternion_goal(
    goal: np.ndarray, start: np.ndarray, learned_goal: np.ndarray, learned_start: np.ndarray
) -> np.ndarray:
    """``goal`` or ``-goal``: the sign that turns from ``start`` the way the DMP learned.

    A quaternion DMP integrates on S^3 (the component form in R^4), where ``g`` and ``-g``
    are different targets: one is reached by turning less than 180 deg, the other by
    turning the other way round. The learned rotation ``learned_goal * conj(learned_start)``
    is carried to the new start, ``ref = learned_goal * conj(learned_start) * start``, and
    the sign of ``goal`` nearer to ``ref`` on S^3 is returned (``goal . ref >= 0``). With the
    learned start and goal this is the learned goal itself, so a demonstration that turns
    past 180 deg is reproduced; for a small goal change it is the sign nearest the learned
    goal (continuous in the goal). The choice jumps only for goals 180 deg from ``ref``.

    Args:
        goal: Goal orientation (w, x, y, z), shape (4,).
        start: Start orientation, shape (4,) (need not be unit: the component form's state).
        learned_goal: The DMP's learned goal, shape (4,).
        learned_start: The DMP's learned start, shape (4,).
    """
    goal = np.asarray(goal, dtype=float)
    ref = quat_multiply(quat_multiply(learned_goal, quat_conjugate(learned_start)), start)
    return goal if float(goal @ ref) >= 0.0 else -goal


def angular_velocity(q: np.ndarray, qd: np.ndarray) -> np.ndarray:
    """World-frame angular velocity ``omega = 2 vec(qd * conj(q))``.

    Args:
        q: Quaternions, shape (..., 4).
        qd: Their time derivatives, shape (..., 4).
    """
    return 2.0 * quat_multiply(qd, quat_conjugate(q))[..., 1:]


def post_normalised(raw: np.ndarray, raw_dot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The paper's post-normalisation of a component quaternion DMP (sec. IV-B).

    ``n = q / |q|`` and its time derivative ``n' = (q' - n (n . q')) / |q|`` of the R^4
    state ``q`` and its rate ``q'``; the angular velocity is then
    ``angular_velocity(n, n')``. (Written once for every system that normalises.)

    Args:
        raw: The un-normalised state, shape (4,).
        raw_dot: Its time derivative, shape (4,).

    Raises:
        RepertoireError: ``|q| = 0`` (no orientation) or a NaN or inf state.
    """
    norm = float(np.linalg.norm(raw))
    if not 0.0 < norm < math.inf:
        raise RepertoireError(
            f"the component quaternion DMP's state {raw} has |q| = {norm}: cannot normalise"
        )
    q = raw / norm
    return q, (raw_dot - q * (q @ raw_dot)) / norm


def quaternion_rate(omega: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Time derivative ``qd = (0, omega) * q / 2`` of a unit quaternion turning at ``omega``.

    The inverse of :func:`angular_velocity` for unit ``q`` (``qd . q = 0``).

    Args:
        omega: World-frame angular velocity, shape (..., 3).
        q: Unit quaternions (w, x, y, z), shape (..., 4).
    """
    omega = np.asarray(omega, dtype=float)
    pure = np.concatenate([np.zeros(omega.shape[:-1] + (1,)), omega], axis=-1)
    return 0.5 * quat_multiply(pure, np.asarray(q, dtype=float))


def manifold_step(
    q: np.ndarray,
    eta: np.ndarray,
    a: np.ndarray,
    goal: np.ndarray,
    e0: np.ndarray,
    theta_next: float,
    f_next: np.ndarray,
    K: float,
    D: float,
    tau: float,
    dt: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One step of the on-manifold quaternion DMP: velocity Verlet on the unit sphere.

    With ``a(q, k) = (K e(g,q) - K e0 theta_k + K f_k) / tau`` (the state-independent part
    of eta', ``e = 2 log(g q^*)`` by :func:`quat_log_error`, so the sign of ``goal`` picks
    which way round it is reached): half a velocity step
    ``eta' = eta + dt/2 (a - D eta / tau)``, the rotation
    ``q+ = exp(dt eta' / (2 tau)) * q`` (a product of unit quaternions, so |q| stays 1 to
    rounding), then the second half with the damping implicit,
    ``eta+ = (eta' + dt/2 a(q+, k+1)) / (1 + dt D / (2 tau))``. Second order: about 70x
    smaller reproduction error than semi-implicit Euler at 1 ms.

    Args:
        q: Orientation, shape (4,).
        eta: Scaled angular velocity tau omega, shape (3,).
        a: ``a(q, k)`` from the previous step (or the start), shape (3,).
        goal: Goal orientation.
        e0: ``2 log(g q0^*)`` (:func:`quat_log_error`).
        theta_next: Phase at the end of the step.
        f_next: Forcing term at the end of the step, shape (3,).
        K: Spring constant.
        D: Damping constant.
        tau: Temporal scaling.
        dt: Time step.

    Returns:
        ``(eta+, q+, a(q+, k+1))``.
    """
    half = eta + 0.5 * dt * (a - D * eta / tau)
    q_next = quat_multiply(quat_exp(0.5 * dt * half / tau), q)
    a_next = (K * quat_log_error(goal, q_next) - K * e0 * theta_next + K * np.asarray(f_next)) / tau
    eta_next = (half + 0.5 * dt * a_next) / (1.0 + 0.5 * dt * D / tau)
    return eta_next, q_next, a_next


def quaternion_rollout(
    weights: np.ndarray,
    centres: np.ndarray,
    widths: np.ndarray,
    K: float,
    D: float,
    alpha: float,
    tau: float,
    q0: np.ndarray,
    goal: np.ndarray,
    *,
    dt: float = 1e-3,
    n_steps: int | None = None,
    omega0: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """On-manifold rollout with :func:`manifold_step` (second order, exact unit norm).

    The sign of ``goal`` counts (see :func:`quat_log_error`): from ``q0`` the DMP turns by
    the angle ``2 arccos(goal . q0)`` in [0, 2 pi], so ``-goal`` is the same orientation
    reached the other way round; :func:`lift_quaternion_goal` picks the learned way.

    Args:
        weights: Shape (3, n_basis).
        centres: Shape (n_basis,).
        widths: Shape (n_basis,).
        K: Spring constant.
        D: Damping constant.
        alpha: Canonical-system constant.
        tau: Temporal scaling [s].
        q0: Start orientation (unit), shape (4,).
        goal: Goal orientation (unit), shape (4,).
        dt: Time step [s], > 0.
        n_steps: Number of steps, an integer >= 1; default ``round(tau / dt)``.
        omega0: Initial angular velocity (world frame) [rad/s], shape (3,); default zero.

    Returns:
        ``(t, q, omega)`` with shapes (N,), (N, 4), (N, 3).
    """
    tau = check_positive("tau", tau)
    dt = check_positive("dt", dt)
    N = check_n_steps(n_steps, tau, dt) + 1
    t = np.arange(N) * dt
    theta = canonical_phase(t, tau, alpha)
    f = forcing_term(theta, weights, centres, widths)
    q0 = np.asarray(q0, dtype=float)
    goal = np.asarray(goal, dtype=float)
    check_turn(goal, q0)
    e0 = quat_log_error(goal, q0)
    Q = np.empty((N, 4))
    E = np.empty((N, 3))
    q = q0.copy()
    eta = np.zeros(3) if omega0 is None else tau * check_finite_vector("omega0", omega0, 3)
    Q[0], E[0] = q, eta
    a = (K * quat_log_error(goal, q) - K * e0 * theta[0] + K * f[0]) / tau
    for k in range(N - 1):
        eta, q, a = manifold_step(q, eta, a, goal, e0, theta[k + 1], f[k + 1], K, D, tau, dt)
        Q[k + 1], E[k + 1] = q, eta
    return t, Q, E / tau
