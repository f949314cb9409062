"""Subgoal refinement: free action parameters that minimise summed predicted duration.

Section 6.2 of Stulp & Beetz (JAIR 2008). A sequence of actions, each with a duration
model over features of the action's parameters, leaves some parameters free (the
approach angle and speed at the ball). Refinement chooses them to minimise the sum of
the predicted durations, looking ``horizon`` actions ahead (:func:`refine_sequence`).

Duration models are model trees: :class:`PiecewiseLinearModel` holds each leaf as a box
in feature space (``lower``/``upper``, +-inf allowed) and a hyperplane (``coef``,
``intercept``). Back-ends:

- ``"corners"`` (:func:`solve_corners`), exact when every feature is affine in at most
  one free parameter (section 6.2.1 extended to sums of trees): leaf boxes map to boxes
  in parameter space, the sum of trees is linear on every intersection of leaf boxes,
  so its minimum is at a corner of one of them. Vectorised in NumPy.
- ``"milp"`` (:func:`solve_milp`), exact for any affine features: a Drake
  MathematicalProgram with one binary per leaf (convex-hull formulation), solved by
  ``MixedIntegerBranchAndBound`` with Clp.
- ``"ga"`` and ``"de"`` (in :mod:`repertoire.planning.black_box`) for features that are
  not affine (angles): the paper's genetic algorithm and scipy's differential evolution.

Where a feature vector lies on a face shared by two leaves, a model predicts the smaller
of their values (the lower envelope), so every minimum is attained and the exact
back-ends return it.
"""

import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol, runtime_checkable

import numpy as np

from repertoire.errors import RepertoireError, SolverError
from repertoire.limits import require_memory

MODEL_FORMAT_VERSION = 1
"""Format version of saved :class:`PiecewiseLinearModel` files."""


def _json_array(a: np.ndarray) -> list:
    return np.where(np.isinf(a), np.where(a > 0, "inf", "-inf"), a.astype(object)).tolist()


@runtime_checkable
class DurationModel(Protocol):
    """What refinement needs from a duration model: leaves as boxes + hyperplanes.

    Attributes (k leaves, d features):
        lower: (k, d) lower corners of the leaf boxes (may be -inf).
        upper: (k, d) upper corners (may be +inf).
        coef: (k, d) hyperplane slopes.
        intercept: (k,) hyperplane offsets.
    """

    lower: np.ndarray
    upper: np.ndarray
    coef: np.ndarray
    intercept: np.ndarray


@dataclass(frozen=True)
class PiecewiseLinearModel:
    """A model tree flattened to its leaves (see :class:`DurationModel`).

    Args:
        lower: (k, d) lower corners of the leaf boxes (-inf allowed).
        upper: (k, d) upper corners (+inf allowed).
        coef: (k, d) slopes of each leaf's hyperplane.
        intercept: (k,) offsets of each leaf's hyperplane.
    """

    lower: np.ndarray
    upper: np.ndarray
    coef: np.ndarray
    intercept: np.ndarray

    def __post_init__(self) -> None:
        arrays = {}
        for name in ("lower", "upper", "coef", "intercept"):
            arrays[name] = np.array(getattr(self, name), dtype=float)
            object.__setattr__(self, name, arrays[name])
        k = arrays["intercept"].reshape(-1).shape[0]
        if arrays["lower"].ndim != 2 or k == 0:
            raise RepertoireError(
                f"a piecewise-linear model needs (k, d) leaf arrays with k >= 1, got lower "
                f"of shape {arrays['lower'].shape} and {k} intercepts"
            )
        shape = arrays["lower"].shape
        for name in ("upper", "coef"):
            if arrays[name].shape != shape:
                raise RepertoireError(f"{name} has shape {arrays[name].shape}, expected {shape}")
        if arrays["intercept"].shape != (shape[0],):
            raise RepertoireError(f"intercept must have shape ({shape[0]},)")
        if np.isnan(arrays["lower"]).any() or np.isnan(arrays["upper"]).any():
            raise RepertoireError("leaf boxes contain NaN; expected numbers or +-inf")
        if not (np.isfinite(arrays["coef"]).all() and np.isfinite(arrays["intercept"]).all()):
            raise RepertoireError("leaf hyperplanes must be finite")
        if (arrays["lower"] > arrays["upper"]).any():
            raise RepertoireError("a leaf box has lower > upper; expected lower <= upper")

    @classmethod
    def from_leaves(cls, leaves) -> "PiecewiseLinearModel":
        """Builds a model from leaf objects with ``lower``, ``upper``, ``coef``, ``intercept``.

        The adapter for model trees that keep a list of leaves (one box and hyperplane
        each). A tree whose leaves are half-open (``lower < f <= upper``) differs from
        this model only on shared faces, where this one takes the smaller neighbour:
        refinement then returns the infimum, approached from inside the cheaper leaf.

        Args:
            leaves: a non-empty sequence of such leaf objects.
        """
        leaves = list(leaves)
        if not leaves:
            raise RepertoireError("a model needs at least one leaf")
        try:
            fields = [
                [getattr(leaf, name) for leaf in leaves]
                for name in ("lower", "upper", "coef", "intercept")
            ]
        except AttributeError as exc:
            raise RepertoireError(
                f"leaves need lower, upper, coef and intercept attributes: {exc}"
            ) from None
        return cls(*fields)

    @property
    def n_leaves(self) -> int:
        return int(self.intercept.shape[0])

    @property
    def n_features(self) -> int:
        return int(self.lower.shape[1])

    def to_dict(self) -> dict:
        """A JSON-ready record (infinities as the strings "inf"/"-inf"), with the format."""
        return {
            "type": "PiecewiseLinearModel",
            "version": MODEL_FORMAT_VERSION,
            **{k: _json_array(getattr(self, k)) for k in ("lower", "upper", "coef", "intercept")},
        }

    @classmethod
    def from_dict(cls, record: dict) -> "PiecewiseLinearModel":
        """Rebuilds a model from :meth:`to_dict`'s record.

        Raises:
            RepertoireError: not a model record, or written by another format version.
        """
        if not isinstance(record, dict) or record.get("type") != "PiecewiseLinearModel":
            raise RepertoireError("not a PiecewiseLinearModel record (missing type)")
        if record.get("version") != MODEL_FORMAT_VERSION:
            raise RepertoireError(
                f"PiecewiseLinearModel record has format version {record.get('version')!r}; "
                f"this repertoire reads version {MODEL_FORMAT_VERSION}: re-export the model"
            )
        try:
            return cls(
                *(np.array(record[k], dtype=float) for k in ("lower", "upper", "coef", "intercept"))
            )
        except KeyError as exc:
            raise RepertoireError(f"PiecewiseLinearModel record lacks {exc}") from None

    def save(self, path: str | Path) -> None:
        """Writes the model as JSON."""
        Path(path).write_text(json.dumps(self.to_dict()))

    @classmethod
    def load(cls, path: str | Path) -> "PiecewiseLinearModel":
        """Reads a model written by :meth:`save` (checks the format version)."""
        try:
            record = json.loads(Path(path).read_text())
        except (OSError, json.JSONDecodeError) as exc:
            raise RepertoireError(f"cannot read a model from {path}: {exc}") from exc
        return cls.from_dict(record)

    def predict(self, features: np.ndarray) -> np.ndarray:
        """Predicted durations for a batch of feature vectors (lower envelope on faces).

        Args:
            features: (n, d) feature vectors.

        Returns:
            (n,) predictions; +inf where a vector lies in no leaf (outside the model's
            domain), which refinement treats as infeasible.
        """
        return predict_leaves(self, features)


def predict_leaves(model: DurationModel, features: np.ndarray) -> np.ndarray:
    """Lower-envelope prediction of any :class:`DurationModel` (see ``predict``)."""
    f = np.atleast_2d(np.asarray(features, dtype=float))
    k, d = model.lower.shape
    if f.shape[1] != d:
        raise RepertoireError(f"features have {f.shape[1]} columns, the model expects {d}")
    require_memory(f.shape[0] * k * (d + 2) * 8.0, f"leaf tests of {f.shape[0]} x {k} leaves")
    inside = np.ones((f.shape[0], k), dtype=bool)
    for j in range(d):  # one (n, k) test per feature: faster than an (n, k, d) reduction
        column = f[:, j : j + 1]
        inside &= (column >= model.lower[:, j]) & (column <= model.upper[:, j])
    values = f @ model.coef.T + model.intercept
    return np.where(inside, values, np.inf).min(axis=1)


@dataclass(frozen=True)
class AffineFeatures:
    """Features affine in the free parameters: ``features = A @ params + b``.

    Args:
        A: (d, P) matrix over all P free parameters of the problem.
        b: (d,) offset (the bound parameters' contribution).
    """

    A: np.ndarray
    b: np.ndarray

    def __post_init__(self) -> None:
        A = np.atleast_2d(np.array(self.A, dtype=float))
        b = np.array(self.b, dtype=float).reshape(-1)
        if A.shape[0] != b.shape[0] or not (np.isfinite(A).all() and np.isfinite(b).all()):
            raise RepertoireError(
                f"AffineFeatures needs finite A (d, P) and b (d,), got {A.shape} and {b.shape}"
            )
        object.__setattr__(self, "A", A)
        object.__setattr__(self, "b", b)

    def __call__(self, params: np.ndarray) -> np.ndarray:
        return np.atleast_2d(params) @ self.A.T + self.b

    def uses(self) -> tuple[int, ...]:
        """Indices of the parameters these features depend on."""
        return tuple(int(i) for i in np.flatnonzero(np.any(self.A != 0.0, axis=0)))


FeatureMap = AffineFeatures | Callable[[np.ndarray], np.ndarray]
"""Either affine features or any batch function (n, P) -> (n, d)."""


@dataclass(frozen=True)
class DurationTerm:
    """One action of the sequence: its duration model and its features.

    Args:
        model: the action's duration model.
        features: parameters (n, P) -> features (n, d).
        uses: indices of the free parameters the action depends on; derived from
            ``A`` for affine features, required for other feature maps.
        name: label for messages and reports.
    """

    model: DurationModel
    features: FeatureMap
    uses: tuple[int, ...] | None = None
    name: str = ""

    def __post_init__(self) -> None:
        if self.uses is None:
            if not isinstance(self.features, AffineFeatures):
                raise RepertoireError(
                    f"term {self.name!r}: non-affine features need `uses`, the indices of "
                    "the free parameters they read"
                )
            object.__setattr__(self, "uses", self.features.uses())
        object.__setattr__(self, "uses", tuple(int(i) for i in self.uses))

    def predict(self, params: np.ndarray) -> np.ndarray:
        return predict_leaves(self.model, self.features(params))


@dataclass(frozen=True)
class RefinementProblem:
    """Minimise the summed predicted duration of ``terms`` over a box of parameters.

    Args:
        terms: the actions in execution order.
        lower: (P,) lower bounds of the free parameters (finite).
        upper: (P,) upper bounds (finite, >= lower).
        names: optional names of the parameters (e.g. the plan's identities).
    """

    terms: tuple[DurationTerm, ...]
    lower: np.ndarray
    upper: np.ndarray
    names: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        lo = np.array(self.lower, dtype=float).reshape(-1)
        hi = np.array(self.upper, dtype=float).reshape(-1)
        object.__setattr__(self, "terms", tuple(self.terms))
        object.__setattr__(self, "lower", lo)
        object.__setattr__(self, "upper", hi)
        if not self.terms:
            raise RepertoireError("a refinement problem needs at least one action (term)")
        if lo.shape != hi.shape or not (np.isfinite(lo).all() and np.isfinite(hi).all()):
            raise RepertoireError("parameter bounds must be finite arrays of equal length")
        bad = np.flatnonzero(lo > hi)
        if bad.size:
            which = [self.names[i] if self.names else int(i) for i in bad]
            raise RepertoireError(
                f"free parameters {which} have empty ranges (lower > upper); expected lo <= hi"
            )
        if self.names and len(self.names) != lo.size:
            raise RepertoireError(f"{len(self.names)} names for {lo.size} parameters")
        for term in self.terms:
            if any(i < 0 or i >= lo.size for i in term.uses):
                raise RepertoireError(
                    f"term {term.name!r} uses parameters {term.uses}, but there are {lo.size}"
                )
            if isinstance(term.features, AffineFeatures) and term.features.A.shape[1] != lo.size:
                raise RepertoireError(
                    f"term {term.name!r}: A has {term.features.A.shape[1]} columns for "
                    f"{lo.size} parameters"
                )

    @property
    def n_params(self) -> int:
        return int(self.lower.size)

    def cost(self, params: np.ndarray) -> np.ndarray:
        """Summed predicted duration of a batch (n, P) of parameter vectors (+inf outside)."""
        p = np.atleast_2d(np.asarray(params, dtype=float))
        return np.sum([term.predict(p) for term in self.terms], axis=0)


@dataclass(frozen=True)
class RefinementResult:
    """The chosen parameters and their predicted summed duration.

    Args:
        params: (P,) chosen values.
        cost: summed predicted duration at ``params``.
        method: the back-end.
        evaluations: model evaluations (black-box) or cells / B&B solves (exact).
        iterations: generations (GA, DE) or incumbent rounds (MILP).
    """

    params: np.ndarray
    cost: float
    method: str
    evaluations: int = 0
    iterations: int = 0
    steps: tuple["RefinementResult", ...] = field(default=(), repr=False)


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


# --------------------------------------------------------------------------------------
# Horizons


Solver = Callable[[RefinementProblem], RefinementResult]


def _restrict(problem: RefinementProblem, terms: Sequence[int], fixed: dict[int, float]):
    """The sub-problem over the still-free parameters ``terms`` use, others fixed."""
    used = sorted({i for t in terms for i in problem.terms[t].uses} - set(fixed))
    full = (problem.lower + problem.upper) / 2
    for i, v in fixed.items():
        full[i] = v
    sub_terms = []
    for t in terms:
        term = problem.terms[t]
        if isinstance(term.features, AffineFeatures):
            A = term.features.A
            feats = AffineFeatures(A[:, used], term.features.b + A @ _masked(full, used))
            sub_terms.append(DurationTerm(term.model, feats, name=term.name))
        else:
            feats = _Embedded(term.features, full, np.asarray(used, dtype=int))
            local = tuple(used.index(i) for i in term.uses if i in used)
            sub_terms.append(DurationTerm(term.model, feats, local, term.name))
    names = tuple(problem.names[i] for i in used) if problem.names else ()
    sub = RefinementProblem(tuple(sub_terms), problem.lower[used], problem.upper[used], names)
    return sub, used


def _masked(full: np.ndarray, used: Sequence[int]) -> np.ndarray:
    out = full.copy()
    out[list(used)] = 0.0
    return out


@dataclass(frozen=True)
class _Embedded:
    """A feature map over all parameters, evaluated from a subset (others fixed)."""

    features: Callable[[np.ndarray], np.ndarray]
    base: np.ndarray
    used: np.ndarray

    def __call__(self, params: np.ndarray) -> np.ndarray:
        p = np.atleast_2d(params)
        full = np.repeat(self.base[None], p.shape[0], axis=0)
        full[:, self.used] = p
        return self.features(full)


def refine_sequence(
    problem: RefinementProblem, horizon: int, solver: Solver | str = "corners", **options
) -> RefinementResult:
    """Receding-horizon refinement: action i's free parameters are chosen looking h ahead.

    For i = 1..n: minimise the summed durations of actions i..i+h-1 over their still
    free parameters, then fix the parameters action i uses. ``horizon = 1`` is the
    paper's greedy baseline (each subgoal chosen for the current action alone),
    ``horizon = 2`` its subgoal refinement, ``horizon = n`` the global optimum.
    Parameters no action uses are set to the middle of their range.

    Args:
        problem: the whole sequence.
        horizon: 1 <= h <= number of actions.
        solver: ``"corners"``, ``"milp"``, ``"ga"``, ``"de"`` or a function of a problem.
        **options: passed to the named back-end (``seed=`` for ``"ga"`` and ``"de"``).

    Returns:
        All parameters, the *whole* sequence's predicted duration at them, and one
        result per step in ``steps``. The cost is +inf when the back-end found no
        parameters every model accepts (all candidates INVALID, e.g. a failure model
        rejecting every subgoal): keep the unrefined plan then.
    """
    n = len(problem.terms)
    if not isinstance(horizon, int | np.integer) or not 1 <= horizon <= n:
        raise RepertoireError(
            f"horizon {horizon} is not in 1..{n}: the plan has {n} actions, so the horizon "
            "must be a whole number between 1 and that"
        )
    solve = _named_solver(solver, options)
    fixed: dict[int, float] = {}
    steps = []
    for i in range(n):
        window = range(i, min(n, i + horizon))
        sub, used = _restrict(problem, window, fixed)
        if used:
            result = solve(sub)
            steps.append(result)
            own = set(problem.terms[i].uses)
            for local, idx in enumerate(used):
                if idx in own:
                    fixed[idx] = float(result.params[local])
    params = (problem.lower + problem.upper) / 2
    for idx, v in fixed.items():
        params[idx] = v
    name = steps[0].method if steps else "none"
    return RefinementResult(
        params,
        float(problem.cost(params)[0]),
        name,
        sum(s.evaluations for s in steps),
        len(steps),
        tuple(steps),
    )


def _named_solver(solver: Solver | str, options: dict) -> Solver:
    if callable(solver):
        if options:
            raise RepertoireError("options are only for named solvers")
        return solver
    if solver == "corners":
        if options:
            raise RepertoireError(f"corner enumeration takes no options, got {sorted(options)}")
        return solve_corners
    if solver == "milp":
        return lambda p: solve_milp(p, **options)
    if solver in ("ga", "de"):
        from repertoire.planning import black_box

        fn = black_box.solve_ga if solver == "ga" else black_box.solve_de
        return lambda p: fn(p, **options)
    raise RepertoireError(
        f"unknown solver {solver!r}; expected corners, milp, ga, de or a function"
    )
