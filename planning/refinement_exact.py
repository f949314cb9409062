"""Exact refinement back-ends: corner enumeration and a mixed-integer LP in Drake.

Section 6.2.1 of Stulp & Beetz (JAIR 2008), extended to sums of model trees. Both need
features affine in the free parameters (:class:`~repertoire.planning.refinement.AffineFeatures`):

- :func:`solve_corners`: when every feature reads at most one free parameter, leaf boxes
  map to boxes in parameter space and the sum of trees is linear on every intersection
  of leaf boxes, so its minimum is at a corner of one of them. Leaves are half-open
  (``lower < f <= upper``), so each box is computed as the floats it holds, and a
  corner is a parameter vector the models predict with the cell's leaves. Vectorised
  in NumPy.
- :func:`solve_milp`: any affine features; one binary per leaf (convex-hull
  formulation), solved by Drake's ``MixedIntegerBranchAndBound`` with Clp, its
  solution moved to parameters the models predict with the leaves it chose.

The problem types and the receding horizon live in :mod:`repertoire.planning.refinement`.
"""

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from repertoire.planning.refinement import (
    AffineFeatures,
    DurationTerm,
    RefinementProblem,
    RefinementResult,
)

from repertoire.checks import is_whole
from repertoire.errors import RepertoireError, SolverError
from repertoire.limits import require_memory

# --------------------------------------------------------------------------------------
# Exact back-end (a): corners of leaf-box intersections


_SIGN = np.int64(-(2**63))


def _to_key(x: np.ndarray) -> np.ndarray:
    """Floats -> int64 keys in the same order (adjacent floats get adjacent keys)."""
    i = np.ascontiguousarray(x, dtype=float).view(np.int64)
    return np.where(i >= 0, i, _SIGN - i)


def _from_key(k: np.ndarray) -> np.ndarray:
    k = np.asarray(k, dtype=np.int64)
    return np.where(k >= 0, k, _SIGN - k).view(float)


def _first_true(pred, lo: np.ndarray, hi: np.ndarray, guess: np.ndarray) -> np.ndarray:
    """Per entry, the smallest float x in [lo, hi] with ``pred(x)`` (NaN if none).

    ``pred`` maps an array of floats to booleans and must be monotone (false, then
    true) along the floats. Bisection over their int64 keys, first within 16 floats
    of ``guess`` where that brackets the answer (a few rounds), else over [lo, hi]
    (<= 64 rounds).
    """
    klo, khi = _to_key(lo), _to_key(hi)
    found = pred(_from_key(khi))
    settled = ~found | pred(_from_key(klo))  # none, or lo itself
    khi = np.where(settled, klo, khi)
    g = _to_key(np.clip(np.nan_to_num(guess, nan=0.0), lo, hi))
    near_lo = np.clip(g - 8, klo, khi)
    near_hi = np.clip(g + 8, klo, khi)
    brackets = (near_lo == klo) | ~pred(_from_key(np.maximum(near_lo - 1, klo)))
    brackets &= pred(_from_key(near_hi))
    klo = np.where(brackets, near_lo, klo)
    khi = np.where(brackets, near_hi, khi)
    while True:
        active = klo < khi
        if not active.any():
            break
        mid = klo // 2 + khi // 2 + ((klo % 2) + (khi % 2)) // 2  # no int64 overflow
        t = pred(_from_key(mid))
        khi = np.where(active & t, mid, khi)
        klo = np.where(active & ~t, mid + 1, klo)
    return np.where(found, _from_key(khi), np.nan)


def _float_interval(a, b, L, U, p_lo, p_hi):
    """The floats p in [p_lo, p_hi] with ``L < a * p + b <= U`` in floating point.

    All arguments are arrays of one shape (a != 0), one entry per (leaf, feature).
    ``a * p + b`` rounds exactly as :class:`AffineFeatures` computes a feature read from
    one parameter (the other columns contribute exact zeros), and it is monotone in p,
    so the set is one closed interval of floats [lo, hi]; it is empty where lo > hi
    (returned as lo = +inf, hi = -inf).
    """
    a, b, L, U, p_lo, p_hi = np.broadcast_arrays(
        *(np.asarray(x, dtype=float) for x in (a, b, L, U, p_lo, p_hi))
    )
    shape = a.shape
    a, b, L, U, p_lo, p_hi = (x.ravel() for x in (a, b, L, U, p_lo, p_hi))
    up = a > 0
    # One search for both ends: the first p inside the leaf (features rising: above L;
    # falling: at most U) and the first p past it (rising: above U; falling: at most L).
    T = np.concatenate([np.where(up, L, U), np.where(up, U, L)])
    A2, B2, UP2 = np.concatenate([a, a]), np.concatenate([b, b]), np.concatenate([up, up])

    def pred(p):
        f = A2 * p + B2
        return np.where(UP2, f > T, f <= T)

    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        # a * p + b rounds past T from the midpoint of T and the next float on; T - b
        # is exact where they are close (Sterbenz), so the guess is within a few floats
        flip = ((T - B2) + (np.nextafter(T, np.inf) - T) / 2) / A2
        first = _first_true(pred, np.concatenate([p_lo, p_lo]), np.concatenate([p_hi, p_hi]), flip)
    n = a.size
    lo, first_out = first[:n], first[n:]
    hi = np.where(np.isnan(first_out), p_hi, np.nextafter(first_out, -np.inf))
    empty = np.isnan(lo) | (first_out == p_lo) | (lo > hi)
    return np.where(empty, np.inf, lo).reshape(shape), np.where(empty, -np.inf, hi).reshape(shape)


def _param_boxes(term: DurationTerm, lower: np.ndarray, upper: np.ndarray):
    """A term's leaves mapped to parameter space, exactly in floating point.

    Returns (lo, hi, slope, offset, live) for all k leaves: leaf l holds exactly the
    float parameter vectors in the box [lo_l, hi_l] (its half-open feature box, read
    through the affine features, inside the parameter box); ``live`` is False for leaves
    no such vector reaches. The term's prediction there is ``slope_l @ p + offset_l``.
    """
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
    model = term.searched_model
    k, P = model.lower.shape[0], A.shape[1]
    lo = np.broadcast_to(lower, (k, P)).copy()
    hi = np.broadcast_to(upper, (k, P)).copy()
    live = np.ones(k, dtype=bool)
    constant = ~nz.any(axis=1)
    for j in np.flatnonzero(constant):  # constant feature: the leaf applies or not
        live &= (model.lower[:, j] < b[j]) & (b[j] <= model.upper[:, j])
    rows = np.flatnonzero(~constant)
    if rows.size:
        cols = nz[rows].argmax(axis=1)  # the parameter each feature reads
        t0, t1 = _float_interval(
            A[rows, cols][None],
            b[rows][None],
            model.lower[:, rows],
            model.upper[:, rows],
            lower[cols][None],
            upper[cols][None],
        )
        for n, i in enumerate(cols):
            lo[:, i] = np.maximum(lo[:, i], t0[:, n])
            hi[:, i] = np.minimum(hi[:, i], t1[:, n])
    live &= np.all(lo <= hi, axis=1)
    slope = model.coef @ A
    offset = model.coef @ b + model.intercept
    return lo, hi, slope, offset, live


def _require_linear_leaves(problem: RefinementProblem, boxes=None) -> None:
    """Raises unless every leaf is linear where the parameters can reach it.

    Fitted duration trees clamp each leaf to the durations it saw
    (:class:`~repertoire.planning.refinement.PiecewiseLinearModel`'s ``floor`` / ``ceiling``).
    The exact back-ends minimise hyperplanes, so a clamp must not bind on any live leaf's
    parameter box (``boxes``: :func:`_param_boxes` per term); where features mix
    parameters (no boxes) a clamped model is refused.
    """
    for n, term in enumerate(problem.terms):
        m = term.searched_model
        floor = getattr(m, "floor", None)
        ceiling = getattr(m, "ceiling", None)
        if floor is None or ceiling is None or not getattr(m, "clamped", False):
            continue
        name = term.name or n
        if boxes is None:
            raise RepertoireError(
                f"term {name}'s model clamps its leaves' predictions and its features mix "
                "parameters: the exact back-ends need linear leaves; use method='ga' or 'de'"
            )
        lo, hi, slope, offset, live = boxes[n]
        with np.errstate(invalid="ignore"):  # 0 * inf: a zero slope adds nothing
            least = offset + np.nan_to_num(np.minimum(slope * lo, slope * hi), nan=0.0).sum(1)
            most = offset + np.nan_to_num(np.maximum(slope * lo, slope * hi), nan=0.0).sum(1)
        binds = live & ((least < floor) | (most > ceiling))
        if binds.any():
            leaf = int(np.flatnonzero(binds)[0])
            raise RepertoireError(
                f"term {name}: leaf {leaf}'s hyperplane spans [{least[leaf]:.4g}, "
                f"{most[leaf]:.4g}] in the parameter box, beyond its clamp [{floor[leaf]:.4g}, "
                f"{ceiling[leaf]:.4g}]: the exact back-ends need linear leaves; use "
                "method='ga' or 'de'"
            )


def _leaf_boxes(term: DurationTerm, lower: np.ndarray, upper: np.ndarray):
    """:func:`_param_boxes` of the live leaves only: (lo, hi, slope, offset)."""
    lo, hi, slope, offset, live = _param_boxes(term, lower, upper)
    return lo[live], hi[live], slope[live], offset[live]


def solve_corners(problem: RefinementProblem) -> RefinementResult:
    """Exact minimum by corner enumeration over intersections of leaf boxes.

    Each leaf is mapped to the box of floating-point parameter values whose features
    it holds (``lower < f <= upper``, computed exactly as the features round), so a
    cell holds exactly the parameter vectors that every term predicts with the cell's
    leaves, and its corner is such a vector. Where a leaf's open face lies at the
    infimum, the corner is the first float inside it.

    Args:
        problem: every term's features affine with each feature reading at most one
            parameter (a scaled/shifted parameter or a constant).

    Returns:
        The minimiser (a corner of a cell) and its cost, ``problem.cost(params)``: the
        minimum over all floating-point parameter vectors in the box; ``evaluations``
        is the number of non-empty cells examined.

    Raises:
        RepertoireError: non-affine or mixing features, a leaf whose clamp binds in the
            parameter box, or no cell is non-empty (the parameter box lies outside some
            model's leaves).
    """
    P = problem.n_params
    cell_lo, cell_hi = problem.lower[None].copy(), problem.upper[None].copy()
    cell_slope, cell_offset = np.zeros((1, P)), np.zeros(1)
    # Lower bounds still to come: the best each remaining term can do anywhere in the box.
    _require_linear_leaves(
        problem, [_param_boxes(t, problem.lower, problem.upper) for t in problem.terms]
    )
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
                "parameter box together with the earlier terms (inside the terms' "
                "domains, where given); expected models whose leaves cover the ranges"
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
    cost = float(problem.cost(params)[0])
    if not abs(cost - values[best]) <= 1e-9 * (1.0 + abs(values[best])):
        raise SolverError(  # cells hold exactly the floats of their leaves: a bug if seen
            f"corner enumeration: the models predict {cost} at the optimal corner {params}, "
            f"its cell {values[best]}"
        )
    return RefinementResult(params, cost, "corners", examined, 1)


# --------------------------------------------------------------------------------------
# Exact back-end (b): mixed-integer LP in Drake


@dataclass
class RefinementMilp:
    """The MILP of :func:`build_refinement_milp` and its decision variables."""

    prog: object
    params: np.ndarray
    binaries: list[np.ndarray]
    cost_slope: np.ndarray = field(default_factory=lambda: np.zeros(0))


FACE_MARGIN = 1e-6
"""Default ``face_margin`` of the MILP for features that mix parameters."""


def _margin(face: float, face_margin: float) -> float:
    return face_margin * max(1.0, abs(face))


_NEAR = 1e-3
"""Leaves of two terms whose parameter boxes miss each other by less than this
(relative to the parameter box) get a cut forbidding both (see build_refinement_milp)."""


def _one_parameter_features(problem: RefinementProblem) -> bool:
    """True if every feature of every term reads at most one free parameter."""
    return all(
        isinstance(t.features, AffineFeatures)
        and int((t.features.A != 0).sum(axis=1).max(initial=0)) <= 1
        for t in problem.terms
    )


def build_refinement_milp(
    problem: RefinementProblem,
    *,
    reference: float = 0.0,
    scale: float = 1.0,
    face_margin: float = FACE_MARGIN,
    exclude: Sequence[Sequence[int]] = (),
) -> RefinementMilp:
    """Convex-hull MILP of the summed model trees, cost ``scale * (sum - reference)``.

    For each term t and leaf l: a binary z_tl and a copy y_tl of the parameters in the
    leaf's region scaled by z_tl, ``sum_l z_tl = 1``, ``sum_l y_tl = params``; the
    term's duration is ``sum_l (coef_l A) y_tl + (coef_l b + intercept_l) z_tl``. This
    is the convex hull of the union of the leaf regions, so the LP relaxation is tight
    per term.

    Leaves are half-open (``lower < f <= upper``), which an LP cannot state, and Drake's
    branch and bound accepts binaries within its integrality tolerance of 0 or 1 (so a
    little of another leaf's y may be mixed in). Hence:

    - features reading one parameter each: the region of leaf l is the box of floats
      of :func:`_param_boxes`, ``lo_l z <= y <= hi_l z``, leaves no float reaches are
      off, and for two terms sharing a parameter, leaves whose boxes miss each other
      by less than 1e-3 of the parameter box (the two sides of one face) get the cut
      ``z_1 + z_2 <= 1``, so no solution combines them;
    - features mixing parameters: the region is the feature box with its open (lower)
      faces moved in by ``m = face_margin * max(1, |face|)``,
      ``(lower + m) z <= A y + b z <= upper z``; a constant feature (a zero row of A)
      decides its leaves exactly. :func:`solve_milp` excludes (``exclude``) leaf
      combinations whose regions turn out not to meet.

    Args:
        problem: terms with :class:`AffineFeatures`.
        reference: subtracted from the summed duration in the cost.
        scale: multiplies the cost (> 0).
        face_margin: relative shift of the open leaf faces where features mix
            parameters (>= 0).
        exclude: leaf combinations (one leaf index per term) the solution may not take.

    Returns:
        The program, the parameter variables and the binaries per term.
    """
    from pydrake.solvers import MathematicalProgram

    prog = MathematicalProgram()
    P = problem.n_params
    params = prog.NewContinuousVariables(P, "p")
    prog.AddBoundingBoxConstraint(problem.lower, problem.upper, params)
    for n, term in enumerate(problem.terms):
        if not isinstance(term.features, AffineFeatures):
            raise RepertoireError(
                f"the MILP needs affine features; term {term.name or n} has "
                f"{type(term.features).__name__}: use method='ga' or 'de'"
            )
    boxes = None
    if _one_parameter_features(problem):
        boxes = [_param_boxes(t, problem.lower, problem.upper) for t in problem.terms]
    _require_linear_leaves(problem, boxes)
    binaries = []
    eye = np.eye(P)
    for n, term in enumerate(problem.terms):
        A, b = term.features.A, term.features.b
        m = term.searched_model
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
            if boxes is not None:
                lo, hi, _, _, live = boxes[n]
                if not live[leaf]:
                    prog.AddBoundingBoxConstraint(0.0, 0.0, zl)
                    prog.AddBoundingBoxConstraint(0.0, 0.0, yl)
                    continue
                lo_l, hi_l = lo[leaf], hi[leaf]
            else:
                lo_l, hi_l = problem.lower, problem.upper
            prog.AddLinearConstraint(  # y - hi z <= 0 and y - lo z >= 0
                np.vstack([np.hstack([eye, -hi_l[:, None]]), np.hstack([eye, -lo_l[:, None]])]),
                np.hstack([np.full(P, -np.inf), np.zeros(P)]),
                np.hstack([np.zeros(P), np.full(P, np.inf)]),
                vars_,
            )
            rows, lbs, ubs = [], [], []
            for j in range(d) if boxes is None else ():
                lo_f, hi_f = float(m.lower[leaf, j]), float(m.upper[leaf, j])
                if not A[j].any():  # a constant feature: the leaf applies or not
                    if not lo_f < b[j] <= hi_f:
                        prog.AddBoundingBoxConstraint(0.0, 0.0, zl)
                    continue
                fj = np.hstack([A[j], [b[j]]])
                if np.isfinite(lo_f):
                    rows.append(fj - np.hstack([np.zeros(P), [lo_f + _margin(lo_f, face_margin)]]))
                    lbs.append(0.0)
                    ubs.append(np.inf)
                if np.isfinite(hi_f):
                    rows.append(fj - np.hstack([np.zeros(P), [hi_f]]))
                    lbs.append(-np.inf)
                    ubs.append(0.0)
            if rows:
                prog.AddLinearConstraint(np.array(rows), lbs, ubs, vars_)
            slope = m.coef[leaf] @ A
            offset = m.coef[leaf] @ b + m.intercept[leaf]
            prog.AddLinearCost(scale * np.hstack([slope, [offset]]), 0.0, vars_)
        binaries.append(z)
    if boxes is not None:
        _add_face_cuts(prog, problem, boxes, binaries)
    for combination in exclude:
        chosen = [z[leaf] for z, leaf in zip(binaries, combination, strict=True)]
        prog.AddLinearConstraint(np.ones((1, len(chosen))), [-np.inf], [len(chosen) - 1.0], chosen)
    prog.AddLinearCost(np.zeros(P), -scale * reference, params)
    return RefinementMilp(prog, params, binaries)


def _add_face_cuts(prog, problem: RefinementProblem, boxes, binaries) -> None:
    """``z_a + z_b <= 1`` for leaves of two terms whose float boxes just miss each other."""
    near = _NEAR * np.maximum(1.0, np.abs(np.hstack([problem.lower, problem.upper])).max())
    n = len(problem.terms)
    for t1 in range(n):
        for t2 in range(t1 + 1, n):
            shared = sorted(set(problem.terms[t1].uses) & set(problem.terms[t2].uses))
            if not shared:
                continue
            lo1, hi1, _, _, live1 = boxes[t1]
            lo2, hi2, _, _, live2 = boxes[t2]
            gap = np.max(
                np.maximum(lo1[:, None, shared], lo2[None, :, shared])
                - np.minimum(hi1[:, None, shared], hi2[None, :, shared]),
                axis=2,
            )
            pairs = np.argwhere(live1[:, None] & live2[None, :] & (gap > 0) & (gap <= near))
            for a, c in pairs:
                prog.AddLinearConstraint(
                    np.ones((1, 2)), [-np.inf], [1.0], [binaries[t1][a], binaries[t2][c]]
                )


def solve_milp(
    problem: RefinementProblem,
    *,
    incumbent: np.ndarray | None = None,
    abs_tol: float = 1e-7,
    max_rounds: int = 20,
    face_margin: float = FACE_MARGIN,
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

    Leaves are half-open (see :func:`build_refinement_milp` for how the MILP keeps two
    terms from taking the two sides of one face). When each feature reads at most one
    parameter, the solution then moves to the optimal corner of its leaves' cell, as
    :func:`solve_corners` computes it, so both return the same minimum. With features
    that mix parameters, the point is moved from the optimum of its leaves' LP just
    far enough towards their centre that the models predict it with those leaves (see
    :func:`_realise`): within about 1e-9 of the leaves' size times the cost's slope of
    the infimum, or, where leaves meet only without an interior, possibly missed.
    Either way the returned cost is ``problem.cost(params)``, the models' prediction
    at the returned parameters.

    ``MixedIntegerBranchAndBound.Solve`` returns a ``SolutionResult`` rather than a
    ``MathematicalProgramResult``, so success is checked as ``kSolutionFound``.

    Args:
        problem: terms with :class:`AffineFeatures`.
        incumbent: (P,) a feasible starting point; default the best of the box centre and
            64 seeded samples of the box.
        abs_tol: absolute optimality tolerance in seconds of duration (> 0).
        max_rounds: incumbent rounds before giving up (>= 1).
        face_margin: where features mix parameters, how far (relative to the face's
            magnitude, at least 1) the MILP's solutions keep inside their leaves' open
            faces (>= 0). Leaf combinations that turn out to hold no parameters are
            excluded and the MILP solved again (a round); where branch and bound fails
            with this margin it is tried again with a tenth of it (down to 1e-9 of it).

    Raises:
        SolverError: branch and bound (Clp) failed, naming the solution result, or its
            solution left its chosen leaves.
        RepertoireError: non-affine features, bad tolerances or an infeasible incumbent.
    """
    from pydrake.solvers import ClpSolver, MixedIntegerBranchAndBound, SolutionResult

    whole = is_whole(max_rounds)
    if not (whole and max_rounds >= 1 and abs_tol > 0 and np.isfinite(abs_tol)):
        raise RepertoireError(
            f"abs_tol must be finite and > 0 and max_rounds a whole number >= 1, got "
            f"{abs_tol!r}, {max_rounds!r}"
        )
    if not (np.isfinite(face_margin) and face_margin >= 0):
        raise RepertoireError(f"face_margin must be finite and >= 0, got {face_margin}")
    if incumbent is None:
        rng = np.random.default_rng(0)
        samples = rng.uniform(problem.lower, problem.upper, (64, problem.n_params))
        samples = np.vstack([(problem.lower + problem.upper) / 2, samples])
        costs = problem.cost(samples)
        incumbent = samples[int(np.argmin(costs))]
    incumbent = np.asarray(incumbent, dtype=float)
    if incumbent.shape != (problem.n_params,) or not (
        np.all(incumbent >= problem.lower) and np.all(incumbent <= problem.upper)
    ):
        raise RepertoireError(
            f"the MILP incumbent must be ({problem.n_params},) parameters inside the box "
            f"{problem.lower.tolist()}..{problem.upper.tolist()}, got {incumbent.tolist()}"
        )
    j_inc = float(problem.cost(incumbent)[0])
    if not np.isfinite(j_inc):
        raise RepertoireError(
            "the MILP incumbent lies outside the models' leaves (or the terms' domains)"
        )
    scale = 1e-2 / abs_tol
    exclude: list[list[int]] = []
    one_each = _one_parameter_features(problem)
    for rounds in range(1, max_rounds + 1):
        # Drake's branch and bound may call the MILP with a margin infeasible; a smaller
        # margin (features mixing parameters: the only ones it applies to) may pass.
        margin = face_margin
        while True:
            milp = build_refinement_milp(
                problem, reference=j_inc, scale=scale, face_margin=margin, exclude=exclude
            )
            bnb = MixedIntegerBranchAndBound(milp.prog, ClpSolver.id())
            try:
                status = bnb.Solve()
            except RuntimeError as exc:
                status = exc
            if status == SolutionResult.kSolutionFound:
                break
            if one_each or margin <= 1e-9 * face_margin:
                raise SolverError(
                    f"MixedIntegerBranchAndBound with Clp failed on the refinement MILP "
                    f"(face_margin {margin:g}): {status}"
                )
            margin /= 10.0
        params = np.clip(bnb.GetSolution(milp.params), problem.lower, problem.upper)
        leaves = [int(np.argmax(bnb.GetSolution(z))) for z in milp.binaries]
        realised = _realise(problem, params, leaves)
        if realised is None:  # no parameters lie in these leaves: solve again without them
            exclude.append(leaves)
            continue
        params, j = realised
        if j >= j_inc - abs_tol:
            if j < j_inc:
                incumbent, j_inc = params, j
            return RefinementResult(incumbent, j_inc, "milp", rounds, rounds)
        incumbent, j_inc = params, j
    raise SolverError(
        f"MixedIntegerBranchAndBound with Clp: still improving after {max_rounds} incumbent "
        f"rounds ({len(exclude)} of them chose leaves no parameters lie in); raise max_rounds"
    )


def _realise(
    problem: RefinementProblem, params: np.ndarray, leaves: list[int]
) -> tuple[np.ndarray, float] | None:
    """Parameters the models predict with the MILP's leaves, and the cost; None if none.

    With features reading one parameter each, the leaves' cell is a box of floats
    (:func:`_param_boxes`) and the point moves to its optimal corner (coordinates the
    cost does not depend on stay, clipped into the box), as :func:`solve_corners`
    chooses it. Otherwise the LP over the chosen leaves' closed boxes is solved, and
    the first point the models predict with those leaves is taken, going from its
    solution (then from the MILP's own point) 1e-9, 1e-8, ... of the way towards the
    centre of the largest ball inside the leaves (Clp leaves its points up to its
    tolerance off the faces). Leaves that meet only in a set without interior (features
    reading the same combination of parameters, with faces that coincide) may hold
    no float the walk finds: None, and the MILP excludes them.
    """
    if _one_parameter_features(problem):
        lo, hi = problem.lower.copy(), problem.upper.copy()
        slope = np.zeros(problem.n_params)
        for term, leaf in zip(problem.terms, leaves, strict=True):
            t_lo, t_hi, t_slope, _, _ = _param_boxes(term, problem.lower, problem.upper)
            lo, hi = np.maximum(lo, t_lo[leaf]), np.minimum(hi, t_hi[leaf])
            slope += t_slope[leaf]
        if not np.all(lo <= hi):
            return None
        candidates = [np.where(slope > 0, lo, np.where(slope < 0, hi, np.clip(params, lo, hi)))]
    else:  # Clp puts the LP's point on the faces, to its tolerance; walk into the leaves
        on_faces = _leaves_lp(problem, leaves)
        centre = _leaves_centre(problem, leaves)
        candidates = []
        for start in (on_faces, params):
            if start is None:
                continue
            candidates.append(start)
            if centre is not None:
                steps = 10.0 ** -np.arange(9, -1, -1)
                candidates += [start + t * (centre - start) for t in steps]
    for point in candidates:
        if point is None:
            continue
        cost = float(problem.cost(point)[0])
        if cost <= _in_leaves(problem, point, leaves) + 1e-9 * (1.0 + abs(cost)):
            return point, cost
    return None


def _in_leaves(problem: RefinementProblem, params: np.ndarray, leaves: list[int]) -> float:
    """The summed duration at ``params`` with each term in the given leaf."""
    total = 0.0
    for term, leaf in zip(problem.terms, leaves, strict=True):
        m = term.searched_model
        total += float(m.coef[leaf] @ term.features(params)[0] + m.intercept[leaf])
    return total


def _leaves_lp(problem: RefinementProblem, leaves: list[int]) -> np.ndarray | None:
    """The minimiser over the chosen leaves' closed boxes (Clp), or None."""
    from pydrake.solvers import ClpSolver, MathematicalProgram

    prog = MathematicalProgram()
    p = prog.NewContinuousVariables(problem.n_params, "p")
    prog.AddBoundingBoxConstraint(problem.lower, problem.upper, p)
    slope = np.zeros(problem.n_params)
    for term, leaf in zip(problem.terms, leaves, strict=True):
        A, b, m = term.features.A, term.features.b, term.searched_model
        lo, hi = m.lower[leaf], m.upper[leaf]
        rows = np.flatnonzero(A.any(axis=1))  # constant features: the MILP decided them
        prog.AddLinearConstraint(A[rows], (lo - b)[rows], (hi - b)[rows], p)
        slope += m.coef[leaf] @ A
    prog.AddLinearCost(slope, 0.0, p)
    result = ClpSolver().Solve(prog)
    if not result.is_success():
        return None
    return np.clip(result.GetSolution(p), problem.lower, problem.upper)


def _leaves_centre(problem: RefinementProblem, leaves: list[int]) -> np.ndarray | None:
    """Centre of the largest ball (radius <= 1) in the chosen leaves and the box, or None.

    None if the leaves meet in no set with an interior (Clp's radius below 1e-9).
    """
    from pydrake.solvers import ClpSolver, MathematicalProgram

    P = problem.n_params
    prog = MathematicalProgram()
    p = prog.NewContinuousVariables(P, "p")
    r = prog.NewContinuousVariables(1, "r")
    x = np.hstack([p, r])
    eye = np.eye(P)
    inf = np.full(P, np.inf)
    prog.AddLinearConstraint(np.hstack([eye, -np.ones((P, 1))]), problem.lower, inf, x)
    prog.AddLinearConstraint(np.hstack([eye, np.ones((P, 1))]), -inf, problem.upper, x)
    prog.AddBoundingBoxConstraint(0.0, 1.0, r)
    for term, leaf in zip(problem.terms, leaves, strict=True):
        A, b, m = term.features.A, term.features.b, term.searched_model
        for j in np.flatnonzero(A.any(axis=1)):
            norm = float(np.linalg.norm(A[j]))
            if np.isfinite(m.lower[leaf, j]):  # A p + b - r |A| >= lower
                row = np.hstack([A[j], [-norm]])[None]
                prog.AddLinearConstraint(row, [m.lower[leaf, j] - b[j]], [np.inf], x)
            if np.isfinite(m.upper[leaf, j]):  # A p + b + r |A| <= upper
                row = np.hstack([A[j], [norm]])[None]
                prog.AddLinearConstraint(row, [-np.inf], [m.upper[leaf, j] - b[j]], x)
    prog.AddLinearCost([-1.0], 0.0, r)
    result = ClpSolver().Solve(prog)
    if not result.is_success() or result.GetSolution(r)[0] < 1e-9:
        return None
    return np.clip(result.GetSolution(p), problem.lower, problem.upper)
