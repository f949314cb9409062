"""Exact refinement back-ends: corner enumeration and a mixed-integer LP in Drake.

Section 6.2.1 of Stulp & Beetz (JAIR 2008), extended to sums of model trees. Both need
features affine in the free parameters (:class:`~repertoire.planning.refinement.AffineFeatures`):

- :func:`solve_corners`: when every feature reads at most one free parameter, leaf boxes
  map to boxes in parameter space and the sum of trees is linear on every intersection
  of leaf boxes, so its minimum is at a corner of one of them. Vectorised in NumPy.
- :func:`solve_milp`: any affine features; one binary per leaf (convex-hull
  formulation), solved by Drake's ``MixedIntegerBranchAndBound`` with Clp.

The problem types and the receding horizon live in :mod:`repertoire.planning.refinement`.
"""

from dataclasses import dataclass, field

import numpy as np
from repertoire.planning.refinement import (
    AffineFeatures,
    DurationTerm,
    RefinementProblem,
    RefinementResult,
)

from repertoire.errors import RepertoireError, SolverError
from repertoire.limits import require_memory

# --------------------------------------------------------------------------------------
# Exact back-end (a): corners of leaf-box intersections


def _leaf_boxes(term: DurationTerm, lower: np.ndarray, upper: np.ndarray):
    """A term's leaves mapped to parameter space: (lo, hi, slope, offset) per live leaf."""
    features = term.features
    if not isinstance(features, AffineFeatures):
        raise RepertoireError(
            f"corner enumeration needs affine features; term {term.name!r} has "
            f"{type(features).__name__}: use method='ga' or 'de'"
        )
    A, b = features.A, features.b
    nz = A != 0.0
    if (nz.sum(axis=1) > 1).any():
        raise RepertoireError(
            f"corner enumeration needs each feature of term {term.name!r} to depend on at "
            "most one free parameter (boxes stay boxes); use method='milp' for general "
            "affine features"
        )
    model = term.model
    k, P = model.lower.shape[0], A.shape[1]
    lo = np.broadcast_to(lower, (k, P)).copy()
    hi = np.broadcast_to(upper, (k, P)).copy()
    live = np.ones(k, dtype=bool)
    for j in range(A.shape[0]):
        cols = np.flatnonzero(nz[j])
        if cols.size == 0:  # constant feature: the leaf applies or not
            live &= (model.lower[:, j] <= b[j]) & (b[j] <= model.upper[:, j])
            continue
        i, a = cols[0], A[j, cols[0]]
        with np.errstate(invalid="ignore"):
            t0 = (model.lower[:, j] - b[j]) / a
            t1 = (model.upper[:, j] - b[j]) / a
        lo[:, i] = np.maximum(lo[:, i], np.minimum(t0, t1))
        hi[:, i] = np.minimum(hi[:, i], np.maximum(t0, t1))
    live &= np.all(lo <= hi, axis=1)
    slope = model.coef @ A
    offset = model.coef @ b + model.intercept
    return lo[live], hi[live], slope[live], offset[live]


def solve_corners(problem: RefinementProblem) -> RefinementResult:
    """Exact minimum by corner enumeration over intersections of leaf boxes.

    Args:
        problem: every term's features affine with each feature reading at most one
            parameter (a scaled/shifted parameter or a constant).

    Returns:
        The minimiser (a corner of a cell) and its cost; ``evaluations`` is the number
        of non-empty cells examined.

    Raises:
        RepertoireError: non-affine or mixing features, or no cell is non-empty (the
            parameter box lies outside some model's leaves).
    """
    P = problem.n_params
    cell_lo, cell_hi = problem.lower[None].copy(), problem.upper[None].copy()
    cell_slope, cell_offset = np.zeros((1, P)), np.zeros(1)
    # Lower bounds still to come: the best each remaining term can do anywhere in the box.
    boxes = [_leaf_boxes(t, problem.lower, problem.upper) for t in problem.terms]
    best_rest = [
        float(np.min(o + np.minimum(s * lo, s * hi).sum(axis=1))) if o.size else np.inf
        for lo, hi, s, o in boxes
    ]
    examined = 0
    for n, (lo, hi, slope, offset) in enumerate(boxes):
        u = np.asarray(problem.terms[n].uses, dtype=int)
        c, k = cell_lo.shape[0], lo.shape[0]
        require_memory(c * k * (2 * u.size + 1) * 8.0, f"{c} cells x {k} leaves of term {n}")
        if u.size:  # which (cell, leaf) pairs intersect: test only the columns used
            meet_lo = np.maximum(cell_lo[:, None, u], lo[None, :, u])
            meet_hi = np.minimum(cell_hi[:, None, u], hi[None, :, u])
            ci, li = np.nonzero(np.all(meet_lo <= meet_hi, axis=2))
        else:
            ci, li = np.repeat(np.arange(c), k), np.tile(np.arange(k), c)
        examined += ci.size
        cell_lo, cell_hi = cell_lo[ci], cell_hi[ci]
        if u.size:
            cell_lo[:, u] = np.maximum(cell_lo[:, u], lo[li][:, u])
            cell_hi[:, u] = np.minimum(cell_hi[:, u], hi[li][:, u])
        cell_slope = cell_slope[ci] + slope[li]
        cell_offset = cell_offset[ci] + offset[li]
        if cell_lo.shape[0] == 0:
            raise RepertoireError(
                f"term {problem.terms[n].name or n}: no leaf of its model covers the "
                "parameter box together with the earlier terms; expected models whose "
                "leaves cover the ranges"
            )
        # Eliminate parameters no later term reads (dynamic programming along the
        # sequence): fix them at their best corner, then of the cells that agree on
        # everything later terms can see, keep the cheapest.
        later = {i for t in problem.terms[n + 1 :] for i in t.uses}
        dead = np.array([i for i in range(P) if i not in later], dtype=int)
        if dead.size:
            s = cell_slope[:, dead]
            val = np.where(s > 0, cell_lo[:, dead], cell_hi[:, dead])
            cell_offset = cell_offset + (s * val).sum(axis=1)
            cell_lo[:, dead], cell_hi[:, dead], cell_slope[:, dead] = val, val, 0.0
            alive = np.array(sorted(later), dtype=int)
            key = np.hstack([cell_lo[:, alive], cell_hi[:, alive], cell_slope[:, alive]])
            _, group = np.unique(key, axis=0, return_inverse=True)
            order = np.lexsort((cell_offset, group.reshape(-1)))
            first = order[np.r_[True, np.diff(group.reshape(-1)[order]) != 0]]
            cell_lo, cell_hi = cell_lo[first], cell_hi[first]
            cell_slope, cell_offset = cell_slope[first], cell_offset[first]
        if n + 1 < len(boxes) and cell_lo.shape[0] > 32:
            # Prune cells whose lower bound (own minimum + the other terms' global
            # minima) exceeds the true cost at the best few cells' corners (upper bound).
            own = cell_offset + np.minimum(cell_slope * cell_lo, cell_slope * cell_hi).sum(1)
            bound = own + sum(best_rest[n + 1 :])
            few = np.argsort(own)[:8]
            corners = np.where(cell_slope[few] > 0, cell_lo[few], cell_hi[few])
            upper_bound = float(np.min(problem.cost(corners)))
            keep = bound <= upper_bound + 1e-9 * max(1.0, abs(upper_bound))
            cell_lo, cell_hi = cell_lo[keep], cell_hi[keep]
            cell_slope, cell_offset = cell_slope[keep], cell_offset[keep]
    values = cell_offset + np.minimum(cell_slope * cell_lo, cell_slope * cell_hi).sum(axis=1)
    best = int(np.argmin(values))
    params = np.where(cell_slope[best] > 0, cell_lo[best], cell_hi[best])
    return RefinementResult(params, float(values[best]), "corners", examined, 1)


# --------------------------------------------------------------------------------------
# Exact back-end (b): mixed-integer LP in Drake


@dataclass
class RefinementMilp:
    """The MILP of :func:`build_refinement_milp` and its decision variables."""

    prog: object
    params: np.ndarray
    binaries: list[np.ndarray]
    cost_slope: np.ndarray = field(default_factory=lambda: np.zeros(0))


def build_refinement_milp(
    problem: RefinementProblem, *, reference: float = 0.0, scale: float = 1.0
) -> RefinementMilp:
    """Convex-hull MILP of the summed model trees, cost ``scale * (sum - reference)``.

    For each term t and leaf l: a binary z_tl and a copy y_tl of the parameters with
    ``lower z <= y <= upper z``, ``leaf.lower z <= A y + b z <= leaf.upper z`` (finite
    sides), ``sum_l z_tl = 1``, ``sum_l y_tl = params``; the term's duration is
    ``sum_l (coef_l A) y_tl + (coef_l b + intercept_l) z_tl``. This is the convex hull
    of the union of the leaf polytopes, so the LP relaxation is tight per term.

    Args:
        problem: terms with :class:`AffineFeatures`.
        reference: subtracted from the summed duration in the cost.
        scale: multiplies the cost (> 0).

    Returns:
        The program, the parameter variables and the binaries per term.
    """
    from pydrake.solvers import MathematicalProgram

    prog = MathematicalProgram()
    P = problem.n_params
    params = prog.NewContinuousVariables(P, "p")
    prog.AddBoundingBoxConstraint(problem.lower, problem.upper, params)
    binaries = []
    const = -reference
    for n, term in enumerate(problem.terms):
        if not isinstance(term.features, AffineFeatures):
            raise RepertoireError(
                f"the MILP needs affine features; term {term.name or n} has "
                f"{type(term.features).__name__}: use method='ga' or 'de'"
            )
        A, b = term.features.A, term.features.b
        m = term.model
        k, d = m.lower.shape
        z = prog.NewBinaryVariables(k, f"z{n}")
        y = prog.NewContinuousVariables(k, P, f"y{n}")
        prog.AddLinearEqualityConstraint(np.ones((1, k)), [1.0], z)
        for i in range(P):  # sum_l y_li = p_i
            prog.AddLinearEqualityConstraint(
                np.hstack([np.ones(k), [-1.0]])[None], [0.0], np.hstack([y[:, i], [params[i]]])
            )
        for leaf in range(k):
            zl, yl = z[leaf], y[leaf]
            vars_ = np.hstack([yl, [zl]])
            box = np.hstack([np.eye(P), np.zeros((P, 1))])
            prog.AddLinearConstraint(  # y - upper z <= 0 and y - lower z >= 0
                np.vstack([box - np.hstack([np.zeros((P, P)), problem.upper[:, None]]),
                           box - np.hstack([np.zeros((P, P)), problem.lower[:, None]])]),
                np.hstack([np.full(P, -np.inf), np.zeros(P)]),
                np.hstack([np.zeros(P), np.full(P, np.inf)]),
                vars_,
            )  # fmt: skip
            rows, lbs, ubs = [], [], []
            for j in range(d):
                fj = np.hstack([A[j], [b[j]]])
                if np.isfinite(m.lower[leaf, j]):
                    rows.append(fj - np.hstack([np.zeros(P), [m.lower[leaf, j]]]))
                    lbs.append(0.0)
                    ubs.append(np.inf)
                if np.isfinite(m.upper[leaf, j]):
                    rows.append(fj - np.hstack([np.zeros(P), [m.upper[leaf, j]]]))
                    lbs.append(-np.inf)
                    ubs.append(0.0)
            if rows:
                prog.AddLinearConstraint(np.array(rows), lbs, ubs, vars_)
            slope = m.coef[leaf] @ A
            offset = m.coef[leaf] @ b + m.intercept[leaf]
            prog.AddLinearCost(scale * np.hstack([slope, [offset]]), 0.0, vars_)
        binaries.append(z)
    prog.AddLinearCost(np.zeros(P), scale * const, params)
    return RefinementMilp(prog, params, binaries)


def solve_milp(
    problem: RefinementProblem,
    *,
    incumbent: np.ndarray | None = None,
    abs_tol: float = 1e-7,
    max_rounds: int = 20,
) -> RefinementResult:
    """Exact minimum by the MILP, solved with Drake's MixedIntegerBranchAndBound + Clp.

    Drake's branch and bound stops when the upper and lower bounds are within an
    absolute gap of 1e-2 *or* a relative gap of 1% (of the lower bound's magnitude);
    Python cannot change either. We therefore minimise ``S * (J - J_inc)`` with
    ``S = 1e-2 / abs_tol`` and ``J_inc`` the cost of a good incumbent: near the optimum
    the scaled cost is about 0, so the relative test cannot fire before the absolute
    one, which in original units is ``abs_tol``. If the solve finds a solution better
    than the incumbent by more than ``abs_tol`` (then the relative test may have stopped
    it up to 1% of the improvement early), it becomes the new incumbent and we solve
    again; each round shrinks the remaining error at least a hundredfold.

    Args:
        problem: terms with :class:`AffineFeatures`.
        incumbent: (P,) a feasible starting point; default the best of the box centre and
            64 seeded samples of the box.
        abs_tol: absolute optimality tolerance in seconds of duration (> 0).
        max_rounds: incumbent rounds before giving up (>= 1).

    ``MixedIntegerBranchAndBound.Solve`` returns a ``SolutionResult`` rather than a
    ``MathematicalProgramResult``, so success is checked as ``kSolutionFound``.

    Raises:
        SolverError: branch and bound (Clp) failed, naming the solution result.
        RepertoireError: non-affine features, bad tolerances or an infeasible incumbent.
    """
    from pydrake.solvers import ClpSolver, MixedIntegerBranchAndBound, SolutionResult

    if not (abs_tol > 0 and max_rounds >= 1):
        raise RepertoireError(
            f"abs_tol must be > 0 and max_rounds >= 1, got {abs_tol}, {max_rounds}"
        )
    if incumbent is None:
        rng = np.random.default_rng(0)
        samples = rng.uniform(problem.lower, problem.upper, (64, problem.n_params))
        samples = np.vstack([(problem.lower + problem.upper) / 2, samples])
        costs = problem.cost(samples)
        incumbent = samples[int(np.argmin(costs))]
    incumbent = np.asarray(incumbent, dtype=float).reshape(-1)
    j_inc = float(problem.cost(incumbent)[0])
    if not np.isfinite(j_inc):
        raise RepertoireError("the MILP incumbent lies outside the models' leaves")
    scale = 1e-2 / abs_tol
    for rounds in range(1, max_rounds + 1):
        milp = build_refinement_milp(problem, reference=j_inc, scale=scale)
        bnb = MixedIntegerBranchAndBound(milp.prog, ClpSolver.id())
        status = bnb.Solve()
        if status != SolutionResult.kSolutionFound:
            raise SolverError(
                f"MixedIntegerBranchAndBound with Clp failed on the refinement MILP: {status}"
            )
        params = np.clip(bnb.GetSolution(milp.params), problem.lower, problem.upper)
        leaves = [int(np.argmax(bnb.GetSolution(z))) for z in milp.binaries]
        params = _snap_to_faces(problem, params, leaves)
        j = _cost_in_leaves(problem, params, leaves)
        if j >= j_inc - abs_tol:
            if j < j_inc:
                incumbent, j_inc = params, j
            return RefinementResult(incumbent, j_inc, "milp", rounds, rounds)
        incumbent, j_inc = params, j
    raise SolverError(
        f"MixedIntegerBranchAndBound with Clp: still improving after {max_rounds} incumbent "
        "rounds; raise max_rounds"
    )


def _snap_to_faces(problem: RefinementProblem, params: np.ndarray, leaves: list[int]):
    """Moves parameters within 1e-7 of a chosen leaf's face (or a range end) onto it.

    Clp's vertices are accurate to about 1e-9; a model tree is discontinuous across
    leaf faces, so a later step of a receding horizon must see the exact face value.
    Only features that read one parameter define faces that can be snapped to.
    """
    out = params.copy()
    faces: list[list[float]] = [[lo, hi] for lo, hi in zip(problem.lower, problem.upper)]
    for term, leaf in zip(problem.terms, leaves, strict=True):
        A, b, m = term.features.A, term.features.b, term.model
        for j in range(A.shape[0]):
            cols = np.flatnonzero(A[j])
            if cols.size == 1:
                for edge in (m.lower[leaf, j], m.upper[leaf, j]):
                    if np.isfinite(edge):
                        faces[cols[0]].append((edge - b[j]) / A[j, cols[0]])
    for i, candidates in enumerate(faces):
        c = np.asarray(candidates)
        near = np.abs(c - out[i]) <= 1e-7 * (1.0 + np.abs(c))
        if near.any():
            out[i] = c[near][np.argmin(np.abs(c[near] - out[i]))]
    return out


def _cost_in_leaves(problem: RefinementProblem, params: np.ndarray, leaves: list[int]) -> float:
    """Summed duration with each term in the given leaf.

    The optimum lies on leaf faces and Clp returns it to about 1e-9, so evaluating the
    lower envelope at the returned point may pick a neighbouring leaf of a discontinuous
    tree; the MILP's chosen leaves are the ones it certified.
    """
    total = 0.0
    for term, leaf in zip(problem.terms, leaves, strict=True):
        f = term.features(params)[0]
        m = term.model
        slack = 1e-6 * (1.0 + np.abs(f))
        if np.any(f < m.lower[leaf] - slack) or np.any(f > m.upper[leaf] + slack):
            raise SolverError(
                f"MixedIntegerBranchAndBound with Clp: solution lies outside its chosen leaf "
                f"{leaf} of term {term.name!r} (numerical trouble)"
            )
        total += float(m.coef[leaf] @ f + m.intercept[leaf])
    return total
