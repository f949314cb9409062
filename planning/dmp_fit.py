"""The forcing-term least squares of DMP learning (Pastor et al. 2009, eq. 5 / 8).

A convex quadratic cost with the precomputed normal equations, solved as a Drake
MathematicalProgram per DOF, with an optional ridge term given or chosen per DOF by
generalised cross-validation. The learners that build the regressors and targets are in
:mod:`repertoire.planning.dmp_learn`.
"""

import sys
import warnings

import numpy as np
from pydrake.solvers import (
    Binding,
    ChooseBestSolver,
    MakeSolver,
    MathematicalProgram,
    QuadraticCost,
    Solve,
)

from repertoire.checks import is_real
from repertoire.errors import RepertoireError, SolverError, UnderdeterminedFitWarning

RIDGE_CHOICES = ("auto", "gcv")
"""The ridge weights chosen from the data rather than given as a number: ``"gcv"`` by
generalised cross-validation (:func:`gcv_ridge`); ``"auto"`` (the learners' default) 0,
plain least squares, where the data determine the weights (every basis function rests on
at least one sample, :func:`basis_support`, and the normal equations are regular), else
``"gcv"``."""

GCV_GRID = np.logspace(-12.0, 2.0, 57)
"""Relative ridge weights ``mu`` tried by ``ridge="gcv"``: ``ridge = mu tr(Phi^T Phi) / n_basis``
(the mean eigenvalue of the normal equations, so ``mu`` is unit-free), 4 per decade."""


SINGULAR_RIDGE = 1e-8
"""The least relative ridge ``"gcv"`` takes when the normal equations are singular (a basis
function the demonstration never excites): a smaller one leaves the QP unbounded in floating
point (EqConstrainedQP, seen at 1e-12 with alpha = 115)."""


def check_ridge(ridge) -> float | str:
    """``ridge`` as a finite float >= 0 or one of :data:`RIDGE_CHOICES`, else a named error.

    Args:
        ridge: A Tikhonov weight (>= 0), ``"gcv"`` or ``"auto"``.
    """
    if isinstance(ridge, str):
        if ridge in RIDGE_CHOICES:
            return ridge
        raise RepertoireError(
            f"ridge must be a finite number >= 0 or one of {RIDGE_CHOICES}, got {ridge!r}"
        )
    if not (is_real(ridge) and np.isfinite(ridge) and ridge >= 0):
        raise RepertoireError(
            f"ridge must be a finite number >= 0 or one of {RIDGE_CHOICES}, got {ridge!r}"
        )
    return float(ridge)


def gcv_scores(
    features: np.ndarray,
    targets: np.ndarray,
    ridges: np.ndarray,
    gram: np.ndarray | None = None,
) -> np.ndarray:
    """Generalised cross-validation of the ridge fit, per ridge weight and DOF.

    ``GCV(lambda) = N ||(I - A) f||^2 / (N - tr A)^2`` with the influence matrix
    ``A = Phi (Phi^T Phi + lambda I)^-1 Phi^T`` (Golub, Heath and Wahba 1979). With
    ``Phi^T Phi = V diag(s^2) V^T`` (one eigendecomposition of the small normal matrix,
    shared by every DOF) and ``z = diag(1/s) V^T Phi^T f`` (= ``U^T f`` of Phi's SVD):
    ``tr A = sum s^2 / (s^2 + lambda)`` and ``||(I - A) f||^2 = r_0 + sum (lambda z /
    (s^2 + lambda))^2``, where ``r_0`` is the least-squares residual, taken as
    ``||f - Phi Phi^+ f||^2`` (a difference of vectors, not of squared norms, so it stays
    accurate when the fit is nearly exact). Directions with ``s^2`` at round-off of the
    largest count as null (no fit, no degree of freedom).

    Args:
        features: Regressors Phi, shape (N, n_basis).
        targets: Targets, shape (N, n_dims).
        ridges: Ridge weights lambda >= 0, shape (m,).
        gram: ``Phi^T Phi`` if already computed (the fit's program holds it).

    Returns:
        Scores, shape (m, n_dims).
    """
    n, b = features.shape
    e, V = np.linalg.eigh(features.T @ features if gram is None else gram)
    keep = e > b * np.finfo(float).eps * max(float(e.max()), 0.0)
    s2 = np.where(keep, e, 0.0)
    h = V.T @ (features.T @ targets)  # (b, n_dims)
    inv = np.where(keep, 1.0 / np.where(keep, e, 1.0), 0.0)[:, None]
    z2 = h * h * inv  # z^2
    outside = np.sum((targets - features @ (V @ (h * inv))) ** 2, axis=0)  # r_0 per DOF
    lam = np.asarray(ridges, dtype=float)[:, None]
    with np.errstate(invalid="ignore", divide="ignore"):
        shrink = np.where(s2[None, :] + lam > 0, lam / (s2[None, :] + lam), 1.0)  # 1 - filter
    rss = outside[None, :] + (shrink**2) @ z2  # (m, n_dims)
    dof = np.sum(np.where(keep[None, :], 1.0 - shrink, 0.0), axis=1)  # tr A, (m,)
    return n * rss / np.maximum(n - dof, 1e-12)[:, None] ** 2


def gcv_ridge(
    features: np.ndarray, targets: np.ndarray, gram: np.ndarray | None = None
) -> np.ndarray:
    """Per-DOF ridge weights minimising :func:`gcv_scores` over :data:`GCV_GRID`.

    The grid is ``GCV_GRID * tr(Phi^T Phi) / n_basis``. Of the weights scoring within 1e-6
    (relative) of a DOF's minimum, or of a round-off floor, the smallest wins, so a clean
    demonstration keeps an essentially exact fit.

    Args:
        features: Regressors Phi, shape (N, n_basis).
        targets: Targets, shape (N, n_dims).
        gram: ``Phi^T Phi`` if already computed.

    Returns:
        Ridge weights, shape (n_dims,).
    """
    gram = features.T @ features if gram is None else gram
    ridges = GCV_GRID * float(np.trace(gram)) / features.shape[1]
    scores = gcv_scores(features, targets, ridges, gram)
    floor = features.shape[0] * (1e-12 * np.max(np.abs(targets), axis=0, initial=0.0)) ** 2
    best = np.maximum(scores.min(axis=0), floor) * (1.0 + 1e-6)
    chosen = ridges[np.argmax(scores <= best[None, :], axis=0)]
    if np.linalg.matrix_rank(gram) < gram.shape[0]:  # singular: the ridge must make the
        # Hessian positive definite in the solver's arithmetic, not only in exact terms
        chosen = np.maximum(chosen, SINGULAR_RIDGE * float(np.trace(gram)) / gram.shape[0])
    return chosen


def build_forcing_fit_program(
    features: np.ndarray, ridge: float = 0.0
) -> tuple[MathematicalProgram, np.ndarray, Binding[QuadraticCost]]:
    """Least-squares fit of one DOF's forcing weights as a MathematicalProgram.

    Minimises ``||Phi w - f||^2 + ridge ||w||^2`` with the normal equations precomputed:
    a convex QuadraticCost with Hessian ``2 (Phi^T Phi + ridge I)``. The Hessian is the same
    for every DOF (eq. 8's regressors do not depend on the DOF), so one program serves them
    all: :func:`fit_forcing_weights` only updates the cost's linear term ``-2 Phi^T f_d``
    (and the ridge on its diagonal when it differs per DOF).
    This is about 6x faster than one stacked program over all DOFs, whose dense KKT system
    grows with the square of the number of DOFs.

    Args:
        features: Regressors Phi, shape (N, n_basis).
        ridge: Ridge (Tikhonov) weight, a finite number >= 0.

    Returns:
        ``(prog, w, cost)``: the program, its (n_basis,) decision variables, and the cost
        binding (linear term zero until set).
    """
    if isinstance(check_ridge(ridge), str):
        raise RepertoireError(
            f"build_forcing_fit_program needs a numeric ridge, got {ridge!r}; "
            "fit_forcing_weights chooses it"
        )
    b = features.shape[1]
    prog = MathematicalProgram()
    w = prog.NewContinuousVariables(b, "w")
    H = features.T @ features
    if ridge > 0:
        H = H + ridge * np.eye(b)
    cost = prog.AddQuadraticCost(2.0 * H, np.zeros(b), 0.0, w, is_convex=True)
    return prog, w, cost


def solve_program(prog: MathematicalProgram, what: str = "program", *, solver=None):
    """Solve and check ``is_success()``; raise SolverError naming the solver otherwise.

    Args:
        prog: The program.
        what: Description used in the error message.
        solver: A solver instance to reuse (default: Drake's best choice for ``prog``).
    """
    result = Solve(prog) if solver is None else solver.Solve(prog)
    if not result.is_success():
        raise SolverError(
            f"{what}: solver {result.get_solver_id().name()} failed with "
            f"{result.get_solution_result()}"
        )
    return result


def forcing_ridge(
    features: np.ndarray,
    targets: np.ndarray,
    ridge: float | str,
    gram: np.ndarray | None = None,
) -> np.ndarray:
    """The ridge weight each DOF's forcing fit uses: ``ridge`` itself, or the GCV choice.

    Args:
        features: Regressors, shape (N, n_basis).
        targets: Targets, shape (N, n_dims).
        ridge: A finite number >= 0, ``"gcv"`` (:func:`gcv_ridge`) or ``"auto"`` (0 where
            the data determine the weights, else ``"gcv"``: see :data:`RIDGE_CHOICES`).
        gram: ``Phi^T Phi`` if already computed.

    Returns:
        Ridge weights, shape (n_dims,).
    """
    ridge = check_ridge(ridge)
    if ridge == "auto":  # regularise where the data do not determine the weights
        gram = features.T @ features if gram is None else gram
        weak = float(np.min(basis_support(features))) < 1.0
        ridge = "gcv" if weak or np.linalg.matrix_rank(gram) < gram.shape[0] else 0.0
    if ridge == "gcv":
        return gcv_ridge(features, targets, gram)
    return np.full(targets.shape[1], ridge)


def basis_support(features: np.ndarray) -> np.ndarray:
    """How many samples' worth of data each basis function's weight rests on.

    ``m_i = sum_n psi_i(theta_n) / sum_j psi_j(theta_n)``: the normalised activations summed
    over the samples (the phase gate cancels: each feature row sums to theta_n). A weight
    with ``m_i < 1`` is fitted to less than one sample, e.g. a basis function over a gap
    between sparse time stamps; without a ridge its value is left to the noise.

    Args:
        features: Regressors Phi (:func:`forcing_features`), shape (N, n_basis).

    Returns:
        Support per basis function, shape (n_basis,).
    """
    rows = features.sum(axis=1, keepdims=True)
    return np.sum(features / np.where(rows > 0.0, rows, 1.0), axis=0)


def _warn_unsupported_basis(features: np.ndarray) -> None:
    """UnderdeterminedFitWarning when a basis function rests on less than one sample."""
    m = basis_support(features)
    weak = np.flatnonzero(m < 1.0)
    if weak.size:
        k = int(weak[np.argmin(m[weak])])
        warnings.warn(
            f"{weak.size} of the {m.size} forcing-term basis functions rest on less than one "
            f"demonstration sample (basis function {k}: {m[k]:.2f} samples' worth), e.g. over "
            "gaps between sparse time stamps: with ridge=0 their weights fit the noise; pass "
            "ridge='auto' (the default) or 'gcv' (chosen by generalised cross-validation), "
            "fewer basis functions or more samples",
            UnderdeterminedFitWarning,
            stacklevel=_outside_level(),
        )


LEARNING_MODULES = frozenset({__name__, "repertoire.planning.dmp_learn"})
"""The modules a learner's call passes through before the least squares warns."""


def _outside_level() -> int:
    """The ``stacklevel`` of the first caller outside :data:`LEARNING_MODULES`.

    A warning raised for ``learn_dmp``, ``learn_quaternion_dmp`` (which calls it) or any
    other learner then names the user's line, however deep in these modules it was raised.
    """
    frame, level = sys._getframe(1), 1  # the function that warns: stacklevel 1
    while frame.f_back is not None and frame.f_globals.get("__name__") in LEARNING_MODULES:
        frame, level = frame.f_back, level + 1
    return level


def fit_forcing_weights(
    features: np.ndarray, targets: np.ndarray, ridge: float | str = "auto"
) -> np.ndarray:
    """Build the forcing fit once and solve it per DOF; returns weights (n_dims, n_basis).

    Args:
        features: Regressors, shape (N, n_basis).
        targets: Targets, shape (N, n_dims).
        ridge: Ridge weight, a finite number >= 0, ``"gcv"``: chosen per DOF by
            generalised cross-validation (:func:`gcv_ridge`), or ``"auto"`` (the default):
            0 where every basis function rests on at least one sample
            (:func:`basis_support`) and the normal equations are regular, else ``"gcv"``.
            With ``ridge=0`` an UnderdeterminedFitWarning says when a basis function rests
            on less than one sample. GCV counts whatever the basis functions cannot fit as
            noise: stacked demonstrations that differ systematically are shrunk towards
            f = 0 (three clean demos with goals 0.8-1.2: 2.8e-3 off their mean with "gcv",
            6e-5 with 0), which is why ``"auto"`` uses it only where it must.
    """
    check_ridge(ridge)
    if ridge == 0:
        _warn_unsupported_basis(features)
    prog, w, cost = build_forcing_fit_program(features, 0.0)
    Q0 = cost.evaluator().Q()
    ridges = forcing_ridge(features, targets, ridge, gram=0.5 * Q0)  # Q0 = 2 Phi^T Phi
    linear = -2.0 * (features.T @ targets)
    constant = np.sum(targets * targets, axis=0)
    solver = MakeSolver(ChooseBestSolver(prog))
    weights = np.empty((targets.shape[1], features.shape[1]))
    eye = np.eye(features.shape[1])
    for d in range(targets.shape[1]):
        Q = Q0 + 2.0 * ridges[d] * eye if ridges[d] > 0 else Q0
        cost.evaluator().UpdateCoefficients(Q, linear[:, d], float(constant[d]), is_convex=True)
        try:
            result = solve_program(prog, "DMP forcing-term least squares", solver=solver)
        except SolverError as e:
            rank = int(np.linalg.matrix_rank(features.T @ features))
            if rank < features.shape[1]:  # singular normal equations: say why
                raise RepertoireError(
                    f"the forcing term's {features.shape[1]} basis functions are not all "
                    f"excited by the demonstration (normal equations of rank {rank}; e.g. a phase "
                    "that decays before the basis centres, from a large alpha): use fewer "
                    "basis functions, a smaller alpha or ridge > 0 (or ridge='gcv')"
                ) from e
            raise
        weights[d] = result.GetSolution(w)
    return weights
