"""Pure, vectorised math of dynamic movement primitives (Pastor et al. 2009, eq. 1-10).

Everything here is plain NumPy so it can be tested against closed forms; the
LeafSystems in :mod:`repertoire.systems.dmp` and the learning code in
:mod:`repertoire.planning.dmp` only wrap these functions.

Conventions (the paper's):

* phase ``theta`` obeys ``tau * theta' = -alpha * theta`` with ``theta(0) = 1``, so
  ``theta(t) = exp(-alpha * t / tau)``;
* the transformation system state is ``(x, v)`` with ``tau * x' = v``; ``v`` is the
  *scaled* velocity ``tau * dx/dt``. Physical velocity and acceleration are
  ``v / tau`` and ``v' / tau``;
* ``formulation="new"`` is eq. 6-7:
  ``tau v' = K (g - x) - D v - K (g - x0) theta + K f(theta) + p``;
  ``formulation="old"`` is eq. 1-2: ``tau v' = K (g - x) - D v + (g - x0) f(theta) + p``;
* ``f(theta) = sum_i w_i psi_i(theta) theta / sum_i psi_i(theta)`` with
  ``psi_i = exp(-h_i (theta - c_i)^2)`` (eq. 3).

Orientation (quaternion) DMPs are in :mod:`repertoire.planning.dmp_quaternion`.
"""

import math
from dataclasses import dataclass

import numpy as np
from repertoire.planning.dmp_obstacle import obstacle_coupling  # noqa: F401 (re-exported)
from scipy.linalg import expm

from repertoire.checks import is_whole
from repertoire.errors import RepertoireError
from repertoire.limits import require_memory

FORMULATIONS = ("new", "old")


def check_formulation(formulation: str) -> None:
    """Raises RepertoireError unless ``formulation`` is one of :data:`FORMULATIONS`.

    Args:
        formulation: ``"new"`` (eq. 6-8) or ``"old"`` (eq. 1-5).
    """
    if formulation not in FORMULATIONS:
        raise RepertoireError(f"formulation must be one of {FORMULATIONS}, got {formulation!r}")


# --------------------------------------------------------------------------- canonical system
def canonical_phase(t: np.ndarray | float, tau: float, alpha: float) -> np.ndarray:
    """Closed-form phase ``theta(t) = exp(-alpha t / tau)`` of eq. 4.

    Args:
        t: Time(s) since movement onset [s].
        tau: Temporal scaling (movement duration) [s], > 0.
        alpha: Canonical-system constant, > 0.
    """
    check_positive("tau", tau)
    check_positive("alpha", alpha)
    return np.exp(-alpha * np.asarray(t, dtype=float) / tau)


def canonical_derivative(theta: np.ndarray | float, tau: float, alpha: float) -> np.ndarray:
    """Time derivative ``theta' = -alpha theta / tau`` of eq. 4.

    Args:
        theta: Phase value(s).
        tau: Temporal scaling [s], > 0.
        alpha: Canonical-system constant, > 0.
    """
    return -alpha * np.asarray(theta, dtype=float) / tau


def alpha_for_final_phase(final_phase: float = 0.01) -> float:
    """Canonical constant alpha such that ``theta(tau) = final_phase``.

    Args:
        final_phase: Phase value reached at ``t = tau``, in (0, 1).
    """
    if not 0.0 < final_phase < 1.0:
        raise RepertoireError(f"final_phase must be in (0, 1), got {final_phase}")
    return float(-np.log(final_phase))


# --------------------------------------------------------------------------- basis functions
def basis_centres(n_basis: int, alpha: float) -> np.ndarray:
    """Centres ``c_i`` in phase, spaced equally in time over ``[0, tau]``.

    ``c_i = exp(-alpha * i / (n_basis - 1))``; independent of tau.

    Args:
        n_basis: Number of Gaussian basis functions, >= 1.
        alpha: Canonical-system constant, > 0.
    """
    n_basis = check_n_basis(n_basis)
    check_positive("alpha", alpha)
    if n_basis == 1:
        return np.array([1.0])
    s = np.linspace(0.0, 1.0, n_basis)
    return np.exp(-alpha * s)


def basis_widths(centres: np.ndarray, alpha: float, overlap: float = 0.5) -> np.ndarray:
    """Widths ``h_i`` so that ``psi_i(c_{i+1}) = overlap`` (neighbouring centres).

    The last width repeats the previous one. With a single centre the width spans the
    whole phase range ``[exp(-alpha), 1]``.

    Args:
        centres: Basis centres in phase, decreasing.
        alpha: Canonical-system constant (used with a single centre).
        overlap: Value of a Gaussian at its neighbour's centre, in (0, 1).
    """
    centres = np.asarray(centres, dtype=float)
    if not 0.0 < overlap < 1.0:
        raise RepertoireError(f"overlap must be in (0, 1), got {overlap}")
    if centres.size == 0:
        raise RepertoireError("need at least one basis function, got 0 centres")
    log_overlap = -np.log(overlap)
    if centres.size == 1:
        span = 1.0 - np.exp(-alpha)
        return np.array([log_overlap / span**2])
    diff = np.diff(centres)
    if np.any(diff == 0.0):
        raise RepertoireError("basis centres must be distinct")
    with np.errstate(divide="ignore", over="ignore"):
        h = log_overlap / diff**2
    if not np.all(np.isfinite(h)):
        raise RepertoireError(
            f"the {centres.size} basis centres are too close in phase for finite widths "
            f"(alpha = {alpha}: centres down to {centres.min():.3g}); use a smaller alpha or "
            "fewer basis functions"
        )
    return np.append(h, h[-1])


def basis_activations(theta: np.ndarray, centres: np.ndarray, widths: np.ndarray) -> np.ndarray:
    """Gaussian activations ``psi_i(theta)``, shape ``theta.shape + (n_basis,)``.

    Args:
        theta: Phase value(s).
        centres: Basis centres, shape (n_basis,).
        widths: Basis widths, shape (n_basis,).
    """
    theta = np.asarray(theta, dtype=float)[..., None]
    return np.exp(-widths * (theta - centres) ** 2)


def forcing_features(theta: np.ndarray, centres: np.ndarray, widths: np.ndarray) -> np.ndarray:
    """Normalised, phase-gated features ``psi_i theta / sum_j psi_j`` (the regressors of eq. 3).

    Returns shape ``theta.shape + (n_basis,)``; ``f = features @ w``.

    Args:
        theta: Phase value(s).
        centres: Basis centres, shape (n_basis,).
        widths: Basis widths, shape (n_basis,).
    """
    psi = basis_activations(theta, centres, widths)
    total = psi.sum(axis=-1, keepdims=True)
    total = np.where(total > 1e-300, total, 1e-300)
    return psi * np.asarray(theta, dtype=float)[..., None] / total


def forcing_term(
    theta: np.ndarray, weights: np.ndarray, centres: np.ndarray, widths: np.ndarray
) -> np.ndarray:
    """Forcing term ``f(theta)`` of eq. 3 for every DOF.

    Args:
        theta: Phase value(s), any shape S.
        weights: Weights, shape (n_dims, n_basis).
        centres: Basis centres, shape (n_basis,).
        widths: Basis widths, shape (n_basis,).

    Returns:
        Array of shape S + (n_dims,).
    """
    return forcing_features(theta, centres, widths) @ np.asarray(weights).T


# --------------------------------------------------------------------------- transformation
def transformation_derivatives(
    x: np.ndarray,
    v: np.ndarray,
    theta: np.ndarray | float,
    goal: np.ndarray,
    x0: np.ndarray,
    f: np.ndarray,
    K: np.ndarray | float,
    D: np.ndarray | float,
    tau: float,
    formulation: str = "new",
    coupling: np.ndarray | float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Right-hand side ``(x', v')`` of the transformation system (eq. 1-2 or 6-7, 9).

    Args:
        x: Position(s), shape (..., n).
        v: Scaled velocity ``tau dx/dt``, shape (..., n).
        theta: Phase, broadcastable against x[..., 0].
        goal: Goal(s), shape (..., n).
        x0: Start position, shape (n,).
        f: Forcing term value(s), shape (..., n).
        K: Spring constant(s), scalar or (n,).
        D: Damping constant(s), scalar or (n,).
        tau: Temporal scaling [s].
        formulation: ``"new"`` (eq. 6) or ``"old"`` (eq. 1).
        coupling: Coupling term ``p`` added to ``tau v'`` (eq. 9).
    """
    theta = np.asarray(theta, dtype=float)
    if theta.ndim and theta.shape != np.shape(x)[:-1]:
        theta = theta.reshape(np.shape(x)[:-1])
    th = theta[..., None] if theta.ndim else theta
    check_formulation(formulation)
    if formulation == "new":
        tau_vd = K * (goal - x) - D * v - K * (goal - x0) * th + K * f + coupling
    else:
        tau_vd = K * (goal - x) - D * v + (goal - x0) * f + coupling
    return v / tau, tau_vd / tau


def forcing_target(
    x: np.ndarray,
    xd: np.ndarray,
    xdd: np.ndarray,
    theta: np.ndarray,
    goal: np.ndarray,
    x0: np.ndarray,
    K: np.ndarray | float,
    D: np.ndarray | float,
    tau: float,
    formulation: str = "new",
) -> np.ndarray:
    """Target forcing values from a demonstration (eq. 8 for "new", eq. 5 for "old").

    Uses physical derivatives: ``v = tau xd`` and ``tau v' = tau^2 xdd``. Note that eq. 8 as
    printed has ``- D y'``; solving eq. 6 for f gives ``+ D v`` (the sign used here and by
    every implementation that reproduces the demonstration).

    Args:
        x: Demonstrated positions, shape (N, n).
        xd: Their time derivatives, shape (N, n).
        xdd: Their second time derivatives, shape (N, n).
        theta: Phase at each sample, shape (N,).
        goal: Goal (last sample), shape (n,).
        x0: Start (first sample), shape (n,).
        K: Spring constant(s).
        D: Damping constant(s).
        tau: Temporal scaling [s].
        formulation: ``"new"`` or ``"old"``.
    """
    v = tau * xd
    tau_vd = tau * tau * xdd
    th = np.asarray(theta)[:, None]
    check_formulation(formulation)
    if formulation == "new":
        return (tau_vd + D * v) / K - (goal - x) + (goal - x0) * th
    return (tau_vd + D * v - K * (goal - x)) / (goal - x0)


@dataclass
class Rollout:
    """A DMP trajectory sampled at times ``t``.

    Attributes:
        t: Times [s], shape (N,).
        theta: Phase, shape (N,).
        x: Positions, shape (N, n).
        xd: Physical velocities, shape (N, n).
        xdd: Physical accelerations, shape (N, n).
    """

    t: np.ndarray
    theta: np.ndarray
    x: np.ndarray
    xd: np.ndarray
    xdd: np.ndarray


def foh_matrices(K: np.ndarray, D: np.ndarray, tau: float, dt: float) -> tuple:
    """Exact first-order-hold discretisation of ``x' = v/tau, v' = (-K x - D v + u)/tau``.

    Returns per-DOF arrays Phi (n, 2, 2), Gu (n, 2), Gd (n, 2) such that
    ``z_{k+1} = Phi z_k + Gu u_k + Gd (u_{k+1} - u_k)`` for input linear in time.
    """
    n = K.shape[0]
    Phi = np.empty((n, 2, 2))
    Gu = np.empty((n, 2))
    Gd = np.empty((n, 2))
    cache: dict = {}
    for i in range(n):
        key = (float(K[i]), float(D[i]))
        if key not in cache:
            M = np.zeros((4, 4))
            M[0, 1] = 1.0 / tau
            M[1, 0] = -K[i] / tau
            M[1, 1] = -D[i] / tau
            M[1, 2] = 1.0 / tau
            M[2, 3] = 1.0 / dt
            E = expm(M * dt)
            cache[key] = (E[:2, :2], E[:2, 2], E[:2, 3])
        Phi[i], Gu[i], Gd[i] = cache[key]
    return Phi, Gu, Gd


def _linear_recurrence(Phi: np.ndarray, C: np.ndarray, z0: np.ndarray) -> np.ndarray:
    """Solve ``z_{k+1} = Phi_i z_k + c_k`` for every DOF i at once with ``lfilter`` (in C).

    By Cayley-Hamilton each state component obeys the scalar recurrence
    ``z_{k+2} - tr z_{k+1} + det z_k = c_{k+1} + (Phi - tr I) c_k``, a second-order IIR
    filter; initial conditions enter as the first two input samples.

    Args:
        Phi: Per-DOF transition matrices, shape (n, 2, 2).
        C: Inputs, shape (N-1, 2, n).
        z0: Initial states, shape (2, n).

    Returns:
        States, shape (N, 2, n).
    """
    from scipy.signal import lfilter

    n = Phi.shape[0]
    N = C.shape[0] + 1
    Z = np.empty((N, 2, n))
    keys = {}
    for i in range(n):
        keys.setdefault(Phi[i].tobytes(), []).append(i)
    for idx in keys.values():
        P = Phi[idx[0]]
        tr = P[0, 0] + P[1, 1]
        det = P[0, 0] * P[1, 1] - P[0, 1] * P[1, 0]
        c = C[:, :, idx]
        z0i = z0[:, idx]
        z1 = np.einsum("ab,bj->aj", P, z0i) + c[0]
        W = np.empty((N, 2, len(idx)))
        W[0] = z0i
        W[1] = z1 - tr * z0i
        if N > 2:
            W[2:] = c[1:] + np.einsum("ab,kbj->kaj", P - tr * np.eye(2), c[:-1])
        Z[:, :, idx] = lfilter([1.0], [1.0, -tr, det], W, axis=0)
    return Z


def rollout(
    weights: np.ndarray,
    centres: np.ndarray,
    widths: np.ndarray,
    K: np.ndarray | float,
    D: np.ndarray | float,
    alpha: float,
    tau: float,
    x0: np.ndarray,
    goal: np.ndarray,
    *,
    dt: float = 1e-3,
    n_steps: int | None = None,
    formulation: str = "new",
    v0: np.ndarray | None = None,
    method: str = "exact",
    coupling=None,
    x_init: np.ndarray | None = None,
) -> Rollout:
    """Vectorised NumPy rollout of an n-DOF DMP from ``t = 0`` for ``n_steps`` steps of ``dt``.

    The canonical system has a closed form, so phase and forcing values are precomputed in
    one vectorised call; only the 2n-dimensional linear recurrence remains.

    ``method="exact"`` integrates the linear spring-damper exactly, with the input (goal,
    phase and forcing terms) linear between samples (first-order hold): the only error is
    that interpolation. ``method="euler"`` is semi-implicit Euler (v first, then x) and
    accepts a state-dependent ``coupling(x, xd) -> p`` callable (e.g. eq. 10).

    Args:
        weights: Shape (n, n_basis).
        centres: Shape (n_basis,).
        widths: Shape (n_basis,).
        K: Spring constant(s), scalar or (n,).
        D: Damping constant(s), scalar or (n,).
        alpha: Canonical-system constant.
        tau: Temporal scaling [s].
        x0: Start position, shape (n,) (also the x0 of the equations).
        goal: Goal, shape (n,), or one goal per sample, shape (n_steps + 1, n).
        dt: Time step [s].
        n_steps: Number of steps, an integer >= 1; default ``round(tau / dt)``.
        formulation: ``"new"`` or ``"old"``.
        v0: Initial physical velocity, shape (n,); default zero.
        method: ``"exact"`` or ``"euler"``.
        coupling: Optional callable ``(x, xd) -> p`` (shape (n,)), euler only; ``p`` is added
            to ``tau v'`` (eq. 9). For eq. 10 pass this rollout's tau,
            ``obstacle_coupling(x, xd, o, gamma, beta, tau=tau)`` (the paper's ``v`` is
            ``tau xd``; the path is then the same at any tau).
        x_init: Initial position if it differs from the equations' x0 (chaining with
            acceleration handoff); default x0.

    Returns:
        A :class:`Rollout` with ``n_steps + 1`` samples.
    """
    tau = check_positive("tau", tau)  # a float, also from a one-entry array
    dt = check_positive("dt", dt)
    weights = np.atleast_2d(np.asarray(weights, dtype=float))
    n = weights.shape[0]
    x0 = check_finite_vector("x0", x0, n)
    N = check_n_steps(n_steps, tau, dt) + 1
    # the basis activations (N x basis) and about a dozen (N x n) arrays, before any is made
    require_memory(
        8.0 * N * (weights.shape[1] + 12 * n),
        f"a DMP rollout of {N - 1} steps ({n} DOF, {weights.shape[1]} basis functions)",
    )
    goal = np.asarray(goal, dtype=float)
    if goal.ndim == 1:
        if goal.shape != (n,):
            raise RepertoireError(f"goal has {goal.size} entries but weights have {n} DOF")
        G = np.broadcast_to(goal, (N, n))
    elif goal.shape == (N, n):
        G = goal
    else:
        raise RepertoireError(f"goal must have shape ({n},) or ({N}, {n}), got {goal.shape}")
    if not np.all(np.isfinite(G)):
        raise RepertoireError(f"goal contains NaN or inf: {goal}")
    Kv = np.broadcast_to(np.asarray(K, dtype=float), (n,))
    Dv = np.broadcast_to(np.asarray(D, dtype=float), (n,))
    t = np.arange(N) * dt
    theta = canonical_phase(t, tau, alpha)
    f = forcing_term(theta, weights, centres, widths)
    v_init = np.zeros(n) if v0 is None else tau * check_finite_vector("v0", v0, n)
    X = np.empty((N, n))
    V = np.empty((N, n))
    x_init = x0 if x_init is None else check_finite_vector("x_init", x_init, n)
    # The equations see positions only through g - x, g - x0 and x - x0: integrate the
    # displacement from x0, so a movement far from the origin keeps its digits (a 0.3 mm
    # movement 1000 units out was off by 1.6e-4 of its range at 0.1 ms steps).
    shift, x0 = x0, np.zeros(n)
    G = G - shift
    x_init = x_init - shift
    X[0], V[0] = x_init, v_init
    if method == "exact":
        if coupling is not None:
            raise RepertoireError("coupling needs method='euler' (it depends on the state)")
        # Input u = tau v' + K x + D v (everything not depending on the state).
        check_formulation(formulation)
        if formulation == "new":
            U = Kv * G - Kv * (G - x0) * theta[:, None] + Kv * f
        else:
            U = Kv * G + (G - x0) * f
        Phi, Gu, Gd = foh_matrices(Kv, Dv, tau, dt)
        dU = np.diff(U, axis=0)
        # Per-step input contribution c_k (shape (N-1, 2, n)) of z_{k+1} = Phi z_k + c_k.
        C = Gu.T[None] * U[:-1, None, :] + Gd.T[None] * dU[:, None, :]
        Z = _linear_recurrence(Phi, C, np.stack([x_init, v_init]))
        X, V = Z[:, 0, :], Z[:, 1, :]
        P = 0.0
    elif method == "euler":
        P = np.zeros((N, n))
        x, v = X[0].copy(), V[0].copy()
        for k in range(N - 1):
            p = 0.0
            if coupling is not None:
                p = np.asarray(coupling(x + shift, v / tau), dtype=float)
                if p.shape not in ((n,), ()):
                    raise RepertoireError(
                        f"coupling(x, xd) must return {n} entries (one per DOF), got shape "
                        f"{p.shape}"
                    )
                if not np.all(np.isfinite(p)):
                    raise RepertoireError(
                        f"coupling(x, xd) returned NaN or inf at step {k} (t = {k * dt:g}): {p}"
                    )
                P[k] = p
            _, vd = transformation_derivatives(
                x, v, theta[k], G[k], x0, f[k], Kv, Dv, tau, formulation, p
            )
            v = v + dt * vd
            x = x + dt * v / tau
            X[k + 1], V[k + 1] = x, v
        if coupling is not None:
            P[-1] = coupling(X[-1] + shift, V[-1] / tau)
    else:
        raise RepertoireError(f"method must be 'exact' or 'euler', got {method!r}")
    _, VD = transformation_derivatives(X, V, theta, G, x0, f, Kv, Dv, tau, formulation, P)
    return Rollout(t=t, theta=theta, x=X + shift, xd=V / tau, xdd=VD / tau)


# --------------------------------------------------------------------------- demonstrations
def minimum_jerk(
    x_start: np.ndarray, x_end: np.ndarray, duration: float, t: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Minimum-jerk segment (closed form) with zero boundary velocity and acceleration.

    Args:
        x_start: Start, shape (n,).
        x_end: End, shape (n,).
        duration: Segment duration [s], > 0.
        t: Sample times in [0, duration], shape (N,).

    Returns:
        ``(x, xd, xdd)`` each of shape (N, n).
    """
    check_positive("duration", duration)
    s = np.clip(np.asarray(t, dtype=float) / duration, 0.0, 1.0)[:, None]
    delta = np.asarray(x_end, dtype=float) - np.asarray(x_start, dtype=float)
    pos = 10 * s**3 - 15 * s**4 + 6 * s**5
    vel = (30 * s**2 - 60 * s**3 + 30 * s**4) / duration
    acc = (60 * s - 180 * s**2 + 120 * s**3) / duration**2
    return x_start + delta * pos, delta * vel, delta * acc


def minimum_jerk_via_points(
    points: np.ndarray, duration: float, n_samples: int
) -> tuple[np.ndarray, np.ndarray]:
    """Minimum-jerk movement through via points (rest-to-rest, smooth through the via points).

    The path is the minimum-jerk polynomial spline through the points: a quintic spline
    (``scipy`` ``make_interp_spline`` with k=5) with zero velocity and acceleration at both
    ends, which is the jerk-optimal interpolant for its knot times. The via points are
    passed at times proportional to the cumulative square root of the distances between
    them (centripetal parametrisation), not to the distances themselves.

    Args:
        points: Via points including start and end, shape (m, n), m >= 2.
        duration: Movement duration [s].
        n_samples: Number of uniform samples, >= 3.

    Returns:
        ``(t, x)`` with shapes (n_samples,), (n_samples, n).
    """
    from scipy.interpolate import make_interp_spline

    points = np.atleast_2d(np.asarray(points, dtype=float))
    check_positive("duration", duration)
    if points.ndim != 2 or points.shape[0] < 2 or points.shape[1] < 1:
        raise RepertoireError(
            f"points must have shape (m, n) with m >= 2 (start and end), got {points.shape}"
        )
    if not np.all(np.isfinite(points)):
        k = int(np.argwhere(~np.isfinite(points))[0, 0])
        raise RepertoireError(f"points contains NaN or inf (first at point {k})")
    if not is_whole(n_samples) or n_samples < 3:
        raise RepertoireError(f"n_samples must be an integer >= 3, got {n_samples!r}")
    t = np.linspace(0.0, duration, n_samples)
    if points.shape[0] == 2:
        x, _, _ = minimum_jerk(points[0], points[1], duration, t)
        return t, x
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    if np.any(seg <= 0):
        raise RepertoireError("consecutive via points must differ")
    knots_t = np.concatenate([[0.0], np.cumsum(np.sqrt(seg))])
    knots_t = knots_t / knots_t[-1] * duration
    zeros = np.zeros(points.shape[1])
    spline = make_interp_spline(
        knots_t,
        points,
        k=5,
        bc_type=([(1, zeros), (2, zeros)], [(1, zeros), (2, zeros)]),
    )
    return t, spline(t)


# --------------------------------------------------------------------------- validation helpers
def check_positive(name: str, value: float) -> float:
    """Raise RepertoireError unless ``value`` is a finite number > 0.

    Args:
        name: Parameter name for the message.
        value: Value to check.
    """
    a = np.asarray(value)
    # a number or a one-entry array of numbers; not a bool or a string ("1" is not a tau)
    v = float(a.reshape(-1)[0]) if a.size == 1 and a.dtype.kind in "iuf" else None
    if v is None or not np.isfinite(v) or v <= 0.0:
        shown = repr(value) if isinstance(value, (str, bool, np.bool_)) else value
        raise RepertoireError(f"{name} must be a finite number > 0, got {shown}")
    return v


def check_n_basis(n_basis: int) -> int:
    """Raise RepertoireError unless ``n_basis`` is an integer >= 1.

    Args:
        n_basis: Number of basis functions.
    """
    if (
        isinstance(n_basis, bool)
        or not isinstance(n_basis, (int, float, np.integer))
        or not math.isfinite(n_basis)
        or int(n_basis) != n_basis
        or n_basis < 1
    ):
        raise RepertoireError(
            f"need at least one basis function (n_basis a whole number >= 1), got {n_basis!r}"
        )
    return int(n_basis)


def check_n_steps(n_steps: int | None, tau: float, dt: float) -> int:
    """The number of rollout steps: ``n_steps`` if an integer >= 1, else ``round(tau / dt)``.

    Raises RepertoireError for a non-integer or ``n_steps < 1`` (or ``round(tau / dt) < 1``
    when ``n_steps`` is None).

    Args:
        n_steps: Requested number of steps, or None.
        tau: Temporal scaling [s] (> 0).
        dt: Time step [s] (> 0).
    """
    if n_steps is None:
        n = int(round(tau / dt))
        if n < 1:
            raise RepertoireError(
                f"dt = {dt} is longer than twice tau = {tau}: round(tau / dt) = 0 steps; "
                "pass n_steps or a smaller dt"
            )
        return n
    if (
        isinstance(n_steps, bool)
        or not isinstance(n_steps, (int, float, np.integer, np.floating))
        or not math.isfinite(n_steps)
        or int(n_steps) != n_steps
        or n_steps < 1
    ):
        raise RepertoireError(f"n_steps must be an integer >= 1, got {n_steps!r}")
    return int(n_steps)


def check_finite_vector(name: str, value, n: int) -> np.ndarray:
    """``value`` as a float vector of ``n`` finite entries; RepertoireError naming it otherwise.

    The one check of vector arguments in the DMP code (the LeafSystems' too).

    Args:
        name: Argument name for the message.
        value: Array-like.
        n: Expected number of entries.
    """
    try:
        v = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError) as err:
        raise RepertoireError(f"{name} must be {n} numbers, got {value!r}") from err
    if v.shape != (n,):
        raise RepertoireError(f"{name} must have {n} entries, got {v.size}: {value}")
    if not np.all(np.isfinite(v)):
        raise RepertoireError(f"{name} contains NaN or inf: {v}")
    return v
