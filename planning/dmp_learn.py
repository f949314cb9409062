"""Learning DMPs from demonstrations (Pastor et al. 2009, sec. II, eq. 5 / 8).

A least-squares fit of the forcing term solved as a Drake MathematicalProgram (a convex
quadratic cost with the precomputed normal equations, optional ridge term, given or chosen
per DOF by generalised cross-validation), for n-DOF, quaternion and the paper's 10-D
task-space DMPs. The artefacts are in
:mod:`repertoire.planning.dmp`; derivatives of the demonstration in
:mod:`repertoire.planning.dmp_derivatives`.
"""

import numpy as np
from repertoire.planning.dmp import (
    DEFAULT_ALPHA,
    DEFAULT_K,
    QUATERNION_MODES,
    DmpParameters,
    QuaternionDmpParameters,
    TaskSpaceDmp,
    check_demonstration,
    check_per_dof,
    check_unit_quaternions,
)
from repertoire.planning.dmp_derivatives import fit_demonstration
from repertoire.planning.dmp_fit import (
    GCV_GRID,
    RIDGE_CHOICES,
    SINGULAR_RIDGE,
    basis_support,
    build_forcing_fit_program,
    check_ridge,
    fit_forcing_weights,
    forcing_ridge,
    gcv_ridge,
    gcv_scores,
    solve_program,
)
from repertoire.planning.dmp_gaps import gap_rows
from repertoire.planning.dmp_math import (
    basis_centres,
    basis_widths,
    canonical_phase,
    check_formulation,
    check_n_basis,
    check_positive,
    forcing_features,
    forcing_target,
)
from repertoire.planning.dmp_quaternion import (
    angular_velocity,
    check_manifold_growth,
    check_turn,
    quat_conjugate,
    quat_log_error,
    quat_multiply,
)

from repertoire.checks import is_real
from repertoire.errors import RepertoireError

__all__ = [
    # the learners
    "POSITION_ROUNDOFF",
    "REST_VELOCITY",
    "learn_dmp",
    "learn_dmp_from_demonstrations",
    "learn_quaternion_dmp",
    "learn_task_space_dmp",
    "make_quaternions_continuous",
    "start_velocity",
    # their least squares (repertoire.planning.dmp_fit), importable from here as before
    "GCV_GRID",
    "RIDGE_CHOICES",
    "SINGULAR_RIDGE",
    "basis_support",
    "build_forcing_fit_program",
    "check_ridge",
    "fit_forcing_weights",
    "forcing_ridge",
    "gcv_ridge",
    "gcv_scores",
    "solve_program",
]

REST_VELOCITY = 1e-6
"""An estimated start velocity with ``|tau dx/dt|`` at or below this fraction of a DOF's
range (plus the positions' round-off, :data:`POSITION_ROUNDOFF` of their magnitude) is
taken as rest and stored as exactly 0, so rest-to-rest DMPs roll out as before. Such
estimates are the derivative estimator's error at the end of a demonstration at rest
(measured: 3e-13 of the range on a minimum-jerk movement, 3e-8 on a curved quaternion
turn, 3e-13 of |x| on a DOF of the arm library that does not move); a start velocity this
small moves a critically damped rollout by at most ``|tau xd(0)| / (e sqrt(K))``, under
3e-8 of the range with the default K, far below a fit's reproduction error (about 1e-5 on
clean demonstrations)."""

POSITION_ROUNDOFF = 1e-12
"""Relative round-off of demonstrated positions (some 4500 eps) in :func:`start_velocity`."""


def start_velocity(xd0: np.ndarray, x: np.ndarray, tau: float, *, estimated: bool) -> np.ndarray:
    """The demonstration's initial velocity as a DMP keeps it (:attr:`DmpParameters.v0`).

    Eq. 8's targets use the demonstration's velocities, so the learned forcing term
    reproduces the demonstration only from its own initial velocity. An estimated one at
    the estimator's error on a demonstration at rest (:data:`REST_VELOCITY`) is 0; a given
    one is kept as it is.

    Args:
        xd0: Velocity at the first sample, shape (n,).
        x: The demonstration, shape (N, n).
        tau: Its duration [s].
        estimated: Whether ``xd0`` was estimated from the samples.
    """
    xd0 = np.array(xd0, dtype=float).reshape(-1)
    if estimated:
        floor = REST_VELOCITY * np.ptp(x, axis=0) + POSITION_ROUNDOFF * np.abs(x).max(axis=0)
        xd0[np.abs(tau * xd0) <= floor] = 0.0
    return xd0


def _gains(n: int, K, D) -> tuple[np.ndarray, np.ndarray]:
    Kv = check_per_dof("K", DEFAULT_K if K is None else K, n)
    if np.any(~np.isfinite(Kv)) or np.any(Kv <= 0):
        raise RepertoireError(f"K must be finite and > 0, got {K}")
    Dv = 2.0 * np.sqrt(Kv) if D is None else check_per_dof("D", D, n)
    if np.any(~np.isfinite(Dv)) or np.any(Dv < 0):
        raise RepertoireError(f"D must be finite and >= 0, got {D}")
    return Kv, Dv


def _basis(n_basis: int, alpha: float | None, overlap: float, n_samples: int) -> tuple:
    """(alpha, centres, widths) after checking ``n_basis`` against the samples to fit."""
    n_basis = check_n_basis(n_basis)
    if n_basis > n_samples:
        raise RepertoireError(
            f"n_basis = {n_basis} basis functions is more than the {n_samples} demonstration "
            "samples: the forcing term is not determined; use at most as many basis "
            "functions as samples"
        )
    a = DEFAULT_ALPHA if alpha is None else check_positive("alpha", alpha)
    c = basis_centres(n_basis, a)
    return a, c, basis_widths(c, a, overlap)


def _bridge_step(tau: float, centres: np.ndarray, bridge_gaps) -> float:
    """The longest step left unbridged: half the basis spacing in time (inf: no bridges)."""
    if not isinstance(bridge_gaps, (bool, np.bool_)):
        raise RepertoireError(f"bridge_gaps must be True or False, got {bridge_gaps!r}")
    return 0.5 * tau / max(centres.size - 1, 1) if bridge_gaps else np.inf


def _demo_targets(
    t,
    x,
    xd,
    xdd,
    smooth,
    alpha,
    Kv,
    Dv,
    tau,
    formulation,
    centres,
    widths,
    min_displacement=1e-9,
    bridge_gaps=True,
):
    """Regressors and f_target (eq. 5 / 8) at the samples and inside their gaps.

    Gaps longer than half the basis spacing in time get points on the quintic bridge
    through ``smooth`` (the fitted positions; None: fit_demonstration's, computed only if
    there is a gap) and the derivatives (dmp_gaps.gap_rows), so every basis function rests
    on the demonstration rather than on its neighbours' tails. The bridge goes through
    fitted positions, not noisy samples: given exact derivatives and samples with 2 mm
    noise (noisy_sparse_minimum_jerk, seeds 0-39) raw ends took the reproduction error to a
    median of 2 % (fitted ends: 0.25 %, as without bridges; max 0.5 % instead of 2.4 %).
    """
    x0, g = x[0], x[-1]
    if formulation == "old":
        small = np.abs(g - x0) <= min_displacement
        if small.any():
            raise RepertoireError(
                "the old formulation (eq. 5) divides by g - x0, but start equals goal in DOF "
                f"{np.flatnonzero(small).tolist()}; use formulation='new'"
            )
    step = _bridge_step(tau, centres, bridge_gaps)
    if smooth is None and np.any(np.diff(t) > step):
        smooth = fit_demonstration(t, x)[0]
    tb, xb, xdb, xddb = gap_rows(t, x if smooth is None else smooth, xd, xdd, step)
    theta = canonical_phase(np.concatenate([t, tb]) - t[0], tau, alpha)
    x, xd, xdd = np.vstack([x, xb]), np.vstack([xd, xdb]), np.vstack([xdd, xddb])
    F = forcing_target(x, xd, xdd, theta, g, x0, Kv, Dv, tau, formulation)
    return forcing_features(theta, centres, widths), F


def _known_derivative(name: str, value, shape: tuple) -> np.ndarray:
    """A given velocity/acceleration array of the demonstration's shape, all finite."""
    v = np.asarray(value, dtype=float)
    if v.shape != shape and not (v.ndim == 1 and shape[1] == 1 and v.shape == shape[:1]):
        raise RepertoireError(f"{name} must have the demonstration's shape {shape}, got {v.shape}")
    v = v.reshape(shape)
    if not np.all(np.isfinite(v)):
        k = int(np.argwhere(~np.isfinite(v))[0, 0])
        raise RepertoireError(f"{name} contains NaN or inf (first at sample {k})")
    return v


def learn_dmp(
    t: np.ndarray,
    x: np.ndarray,
    *,
    n_basis: int = 50,
    K: float | np.ndarray | None = None,
    D: float | np.ndarray | None = None,
    alpha: float | None = None,
    formulation: str = "new",
    ridge: float | str = "auto",
    overlap: float = 0.5,
    derivatives: str = "auto",
    window: int | None = None,
    smoothing: float | None = None,
    xd: np.ndarray | None = None,
    xdd: np.ndarray | None = None,
    names: list[str] | None = None,
    min_displacement: float = 1e-9,
    bridge_gaps: bool = True,
) -> DmpParameters:
    """Learn an n-DOF DMP from one demonstration (eq. 5 or 8 + linear least squares).

    ``tau`` is the demonstration's duration, ``x0``/``goal`` its first/last sample. Steps
    between samples longer than half the basis spacing in time (a dropout, sparse random
    stamps) are bridged by quintic Hermite points through the fitted ends
    (:mod:`repertoire.planning.dmp_gaps`) before the least squares.

    Args:
        t: Time stamps [s], strictly increasing (may be non-uniform), shape (N,), N >= 3.
        x: Positions, shape (N, n) or (N,).
        n_basis: Number of basis functions, >= 1.
        K: Spring constant(s); default 156.25.
        D: Damping; default critically damped ``2 sqrt(K)``.
        alpha: Canonical constant; default ``ln(100)`` (theta(tau) = 0.01).
        formulation: ``"new"`` (eq. 6-8) or ``"old"`` (eq. 1-5).
        ridge: Ridge weight of the least squares, >= 0, ``"gcv"`` to choose it per DOF
            by generalised cross-validation, or ``"auto"`` (the default: 0 unless the data
            leave the weights undetermined, then ``"gcv"``; see :func:`fit_forcing_weights`).
        overlap: Basis-function overlap at neighbouring centres.
        derivatives: ``"auto"``, ``"savgol"``, ``"local_poly"`` or ``"spline"`` (see
            estimate_derivatives; ``"auto"`` is savgol on uniform stamps, local_poly
            otherwise).
        window: Savitzky-Golay / local-polynomial window in samples; None chooses it by
            GCV (local_poly then uses kernel-weighted windows in time instead).
        smoothing: Smoothing-spline lambda.
        xd: Known velocities (skip estimation), shape (N, n).
        xdd: Known accelerations, shape (N, n).
        names: Optional DOF names.
        min_displacement: Old form only: |g - x0| at or below this in any DOF is an error
            (eq. 5 divides by it); 0 allows tiny displacements (to show the blow-up).
        bridge_gaps: Bridge steps longer than half the basis spacing (the default); False
            fits the samples alone (to show what the bridges do).
    """
    t, x = check_demonstration(t, x)
    check_formulation(formulation)
    check_ridge(ridge)
    if not (is_real(min_displacement) and np.isfinite(min_displacement) and min_displacement >= 0):
        raise RepertoireError(
            f"min_displacement must be a finite number >= 0, got {min_displacement!r}"
        )
    n = x.shape[1]
    Kv, Dv = _gains(n, K, D)
    a, c, h = _basis(n_basis, alpha, overlap, t.size)
    smooth = None  # fitted only where a gap needs it (_demo_targets)
    estimated = xd is None
    if xd is None or xdd is None:
        smooth, xd_e, xdd_e = fit_demonstration(
            t, x, method=derivatives, window=window, smoothing=smoothing
        )
        xd = xd_e if xd is None else xd
        xdd = xdd_e if xdd is None else xdd
    xd = _known_derivative("xd", xd, x.shape)
    xdd = _known_derivative("xdd", xdd, x.shape)
    tau = float(t[-1] - t[0])
    Phi, F = _demo_targets(
        t, x, xd, xdd, smooth, a, Kv, Dv, tau, formulation, c, h, min_displacement, bridge_gaps
    )
    weights = fit_forcing_weights(Phi, F, ridge)
    v0 = start_velocity(xd[0], x, tau, estimated=estimated)
    return DmpParameters(
        weights, c, h, Kv, Dv, a, tau, x[0], x[-1], formulation, names=names or [], v0=v0
    )


def learn_dmp_from_demonstrations(
    demonstrations: list[tuple[np.ndarray, np.ndarray]],
    *,
    n_basis: int = 50,
    K: float | np.ndarray | None = None,
    D: float | np.ndarray | None = None,
    alpha: float | None = None,
    formulation: str = "new",
    ridge: float | str = "auto",
    overlap: float = 0.5,
    derivatives: str = "auto",
    names: list[str] | None = None,
    bridge_gaps: bool = True,
) -> DmpParameters:
    """Learn one DMP from several demonstrations (a joint least-squares fit).

    Each demonstration keeps its own duration (tau), start and goal when its f_target is
    computed; the weights minimise the summed squared error over all of them, each
    demonstration's mean squared error weighing the same (a densely sampled demonstration
    does not outweigh a sparse one; with equal sample counts this is the plain sum). The
    result's tau, x0 and goal are the means over the demonstrations.

    Args:
        demonstrations: List of ``(t, x)`` pairs with the same number of DOF.
        n_basis: Number of basis functions.
        K: Spring constant(s).
        D: Damping; default critically damped.
        alpha: Canonical constant.
        formulation: ``"new"`` or ``"old"``.
        ridge: Ridge weight >= 0, ``"gcv"`` or ``"auto"`` (see :func:`fit_forcing_weights`).
        overlap: Basis overlap.
        derivatives: Derivative method.
        names: Optional DOF names.
        bridge_gaps: Bridge each demonstration's long steps (see :func:`learn_dmp`).
    """
    if not demonstrations:
        raise RepertoireError("need at least one demonstration, got an empty list")
    check_ridge(ridge)
    for i, demo in enumerate(demonstrations):
        if not (isinstance(demo, (tuple, list)) and len(demo) == 2):
            raise RepertoireError(
                f"demonstration {i} must be a (t, x) pair, got {type(demo).__name__}"
                + (f" of length {len(demo)}" if isinstance(demo, (tuple, list)) else "")
            )
    demos = [
        check_demonstration(t, x, name=f"demonstration {i}")
        for i, (t, x) in enumerate(demonstrations)
    ]
    n = demos[0][1].shape[1]
    for i, (_, x) in enumerate(demos):
        if x.shape[1] != n:
            raise RepertoireError(
                f"demonstration {i} has {x.shape[1]} DOF, demonstration 0 has {n}"
            )
    Kv, Dv = _gains(n, K, D)
    a, c, h = _basis(n_basis, alpha, overlap, sum(t.size for t, _ in demos))
    feats, targs, taus, v_starts, moves = [], [], [], [], []
    for i, (t, x) in enumerate(demos):
        tau = float(t[-1] - t[0])
        try:
            smooth, xd, xdd = fit_demonstration(t, x, method=derivatives)
            Phi, F = _demo_targets(
                t, x, xd, xdd, smooth, a, Kv, Dv, tau, formulation, c, h, 1e-9, bridge_gaps
            )
        except RepertoireError as err:  # say which demonstration
            raise type(err)(f"demonstration {i}: {err}") from err
        feats.append(Phi)
        targs.append(F)
        taus.append(tau)
        v_starts.append(tau * start_velocity(xd[0], x, tau, estimated=True))
        moves.append(x[-1] - x[0])
    # Each demonstration weighs the same, whatever its sampling rate: rows scaled by
    # sqrt(most rows / its rows), 1 when all have as many (a 10 kHz demonstration outweighed
    # a 100 Hz one 100 to 1: opposite bumps of 0.3 were learned as -0.293, not their mean).
    most = max(F.shape[0] for F in targs)
    scale = [np.sqrt(most / F.shape[0]) for F in targs]
    Phi = np.vstack([s * P for s, P in zip(scale, feats)])
    weights = fit_forcing_weights(Phi, np.vstack([s * F for s, F in zip(scale, targs)]), ridge)
    x0 = np.mean([x[0] for _, x in demos], axis=0)
    g = np.mean([x[-1] for _, x in demos], axis=0)
    tau = float(np.mean(taus))
    # the mean scaled start velocity tau xd(0) (what each demonstration's eq. 8 saw); the
    # old form (eq. 5) learns each demonstration divided by its g - x0 (nonzero, checked
    # above), so its start velocity is averaged so too and scaled to the mean g - x0
    if formulation == "old":
        v0 = np.mean([v / m for v, m in zip(v_starts, moves)], axis=0) * (g - x0) / tau
    else:
        v0 = np.mean(v_starts, axis=0) / tau
    return DmpParameters(
        weights, c, h, Kv, Dv, a, tau, x0, g, formulation, names=names or [], v0=v0
    )


def make_quaternions_continuous(q: np.ndarray) -> np.ndarray:
    """Flip signs so consecutive quaternions are on the same hemisphere (q and -q agree).

    Args:
        q: Shape (N, 4).
    """
    q = np.array(q, dtype=float)
    dots = np.sum(q[1:] * q[:-1], axis=1)
    flips = np.cumsum(dots < 0) % 2
    q[1:][flips == 1] *= -1.0
    return q


def learn_quaternion_dmp(
    t: np.ndarray,
    q: np.ndarray,
    *,
    mode: str = "manifold",
    n_basis: int = 50,
    K: float | None = None,
    D: float | None = None,
    alpha: float | None = None,
    ridge: float | str = "auto",
    overlap: float = 0.5,
    derivatives: str = "auto",
    unit_tolerance: float = 1e-6,
    bridge_gaps: bool = True,
) -> QuaternionDmpParameters:
    """Learn an orientation DMP from a unit-quaternion demonstration.

    ``mode="component"`` is the paper's approach (sec. IV-B: one transformation system per
    component, post-normalised at the output). ``mode="manifold"`` learns the forcing term
    of ``tau eta' = K e(g,q) - D eta - K e(g,q0) theta + K f`` with ``e = 2 log(g q^*)``
    and ``eta = tau omega``; its rollout keeps |q| = 1 to rounding. The demonstration's
    signs are made continuous first, and ``e = 2 log(g q^*)`` is taken on S^3 without a
    hemisphere flip (Ude et al. 2014), so it is continuous along the demonstration even
    where the rotation left to the goal passes 180 deg (demonstrations turning more than
    180 deg, or detours); only a sample a full 360 deg turn from the goal is refused.

    Args:
        t: Time stamps, shape (N,).
        q: Quaternions (w, x, y, z), shape (N, 4), unit norm within unit_tolerance.
        mode: ``"component"`` or ``"manifold"``.
        n_basis: Number of basis functions.
        K: Spring constant; default 156.25.
        D: Damping; default 2 sqrt(K).
        alpha: Canonical constant.
        ridge: Ridge weight >= 0, ``"gcv"`` or ``"auto"`` (see :func:`fit_forcing_weights`).
        overlap: Basis overlap.
        derivatives: Derivative method.
        unit_tolerance: Allowed deviation of |q| from 1 (the samples are normalised).
        bridge_gaps: Bridge long steps between samples (see :func:`learn_dmp`; on-manifold:
            the bridge in R^4 projected onto the unit sphere).
    """
    t, q = check_demonstration(t, q, name="quaternion demonstration")
    check_unit_quaternions(q, tolerance=unit_tolerance, name="quaternion demonstration")
    if mode not in QUATERNION_MODES:
        raise RepertoireError(f"mode must be one of {QUATERNION_MODES}, got {mode!r}")
    check_ridge(ridge)
    q = make_quaternions_continuous(q / np.linalg.norm(q, axis=1, keepdims=True))
    Kv, Dv = _gains(1, K, D)
    if mode == "component":
        p = learn_dmp(
            t,
            q,
            n_basis=n_basis,
            K=Kv[0],
            D=Dv[0],
            alpha=alpha,
            ridge=ridge,
            overlap=overlap,
            derivatives=derivatives,
            bridge_gaps=bridge_gaps,
        )
        return QuaternionDmpParameters(
            p.weights,
            p.centres,
            p.widths,
            Kv[0],
            Dv[0],
            p.alpha,
            p.tau,
            q[0],
            q[-1],
            mode,
            omega0=angular_velocity(q[0], p.v0),
        )
    a, c, h = _basis(n_basis, alpha, overlap, t.size)
    tau = float(t[-1] - t[0])
    step = _bridge_step(tau, c, bridge_gaps)
    smooth, qd, qdd = fit_demonstration(t, q, method=derivatives)
    g, q0 = q[-1], q[0]
    turn = 2.0 * np.arccos(np.clip(q @ g, -1.0, 1.0))
    k = int(np.argmax(turn))
    check_turn(g, q[k], what=f"from demonstration sample {k} to the goal (last sample)")
    e = quat_log_error(g, q)
    # Between two samples the error can also jump across a full turn (its axis flips while
    # its angle stays near 360 deg): the demonstration turns a full turn or more.
    angle = np.linalg.norm(e, axis=1)
    jump = (np.sum(e[1:] * e[:-1], axis=1) < 0.0) & (angle[1:] + angle[:-1] > 2.0 * np.pi)
    if jump.any():
        k = int(np.argmax(jump))
        raise RepertoireError(
            f"the quaternion demonstration passes a full 360 deg turn from the goal between "
            f"samples {k} and {k + 1} (it turns 360 deg or more): the on-manifold quaternion "
            "DMP turns less than a full turn; use mode='component' or split the movement"
        )
    check_manifold_growth(t, q, g, Kv[0], Dv[0])
    # gaps bridged as learn_dmp does, in R^4 and projected back onto S^3 (dmp_gaps)
    tb, qb, qdb, qddb = gap_rows(t, smooth, qd, qdd, step)
    qb = qb / np.linalg.norm(qb, axis=1, keepdims=True)
    q, qd, qdd = np.vstack([q, qb]), np.vstack([qd, qdb]), np.vstack([qdd, qddb])
    e = np.vstack([e, quat_log_error(g, qb)])
    omega = angular_velocity(q, qd)
    omegad = 2.0 * quat_multiply(qdd, quat_conjugate(q))[:, 1:]
    theta = canonical_phase(np.concatenate([t, tb]) - t[0], tau, a)
    F = (
        (tau * tau * omegad + Dv[0] * tau * omega) / Kv[0]
        - e
        + quat_log_error(g, q0)[None] * theta[:, None]
    )
    weights = fit_forcing_weights(forcing_features(theta, c, h), F, ridge)
    # omega[0]: the first sample's angular velocity (the rows after N are bridges)
    omega0 = start_velocity(omega[0], e[: t.size], tau, estimated=True)
    return QuaternionDmpParameters(weights, c, h, Kv[0], Dv[0], a, tau, q0, g, mode, omega0)


def learn_task_space_dmp(
    t: np.ndarray,
    positions: np.ndarray,
    quaternions: np.ndarray,
    fingers: np.ndarray | None = None,
    *,
    orientation_mode: str = "manifold",
    n_basis: int = 50,
    K: float | None = None,
    alpha: float | None = None,
    ridge: float | str = "auto",
) -> TaskSpaceDmp:
    """Learn the paper's 10-D DMP (position + quaternion + fingers) from one demonstration.

    Args:
        t: Time stamps, shape (N,).
        positions: End-effector positions p_WE, shape (N, 3).
        quaternions: End-effector orientations (w, x, y, z), shape (N, 4).
        fingers: Finger positions, shape (N, k), or None.
        orientation_mode: ``"component"`` (paper) or ``"manifold"``.
        n_basis: Number of basis functions.
        K: Spring constant; default 156.25.
        alpha: Canonical constant.
        ridge: Ridge weight >= 0, ``"gcv"`` or ``"auto"`` (see :func:`fit_forcing_weights`).
    """
    check_ridge(ridge)
    positions = np.asarray(positions, float)
    if positions.ndim != 2 or positions.shape[1] != 3:
        raise RepertoireError(f"positions must have shape (N, 3), got {positions.shape}")
    pos = learn_dmp(
        t, positions, n_basis=n_basis, K=K, alpha=alpha, ridge=ridge, names=["x", "y", "z"]
    )
    ori = learn_quaternion_dmp(
        t, quaternions, mode=orientation_mode, n_basis=n_basis, K=K, alpha=alpha, ridge=ridge
    )
    fin = None
    if fingers is not None:
        fin = learn_dmp(t, fingers, n_basis=n_basis, K=K, alpha=alpha, ridge=ridge)
    return TaskSpaceDmp(pos, ori, fin)
