"""Subgoal refinement: free action parameters that minimise summed predicted duration.

Section 6.2 of Stulp & Beetz (JAIR 2008). A sequence of actions, each with a duration
model over features of the action's parameters, leaves some parameters free (the
approach angle and speed at the ball). Refinement chooses them to minimise the sum of
the predicted durations, looking ``horizon`` actions ahead (:func:`refine_sequence`).

Duration models are model trees: :class:`PiecewiseLinearModel` holds each leaf as a box
in feature space (``lower``/``upper``, +-inf allowed) and a hyperplane (``coef``,
``intercept``). Back-ends:

- ``"corners"`` and ``"milp"``, exact where features are affine in the free
  parameters (section 6.2.1 extended to sums of trees), in
  :mod:`repertoire.planning.refinement_exact`: corner enumeration of leaf-box
  intersections in NumPy, and a convex-hull MILP solved by Drake's
  ``MixedIntegerBranchAndBound`` with Clp.
- ``"ga"`` and ``"de"`` (in :mod:`repertoire.planning.black_box`) for features that are
  not affine (angles): the paper's genetic algorithm and scipy's differential evolution.

A leaf covers the half-open box ``lower < f <= upper`` (per feature), the rule of the
fitted trees' ``predict`` (go left if ``x <= threshold``): a feature vector on a face
shared by two leaves belongs to the lower one, for every action alike, so the leaves of
a tree partition feature space and :meth:`PiecewiseLinearModel.predict` equals the
tree's prediction everywhere. Where leaves overlap (models not made from a tree), the
smallest value of the leaves that contain a vector is predicted. The exact back-ends
return parameters and the summed prediction *at* them (a value the models attain).
Corner enumeration, and the MILP where each feature reads one parameter, return the
minimum over all floating-point parameter vectors: where the infimum lies on a face
that belongs to the neighbouring leaf, the value at the first float inside the cheaper
leaf. Where features mix parameters, the MILP's value is within about 1e-9 (relative
to the leaves' size) of the infimum (see
:func:`~repertoire.planning.refinement_exact.solve_milp`).
"""

import inspect
import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol, runtime_checkable

import numpy as np

from repertoire.checks import is_whole
from repertoire.errors import RepertoireError
from repertoire.limits import require_memory

MODEL_FORMAT_VERSION = 2
"""Format version of saved :class:`PiecewiseLinearModel` files (2 adds the leaves' clamps;
version 1 files, without them, are still read)."""


def json_array(a) -> list:
    """``a`` as nested JSON lists, infinities as the strings ``"inf"``/``"-inf"``.

    JSON has no infinity, and Python's ``Infinity`` token is refused by other readers
    (JavaScript, jq, serde); ``np.array(..., dtype=float)`` reads the strings back.
    """
    a = np.asarray(a, dtype=float)
    return np.where(np.isinf(a), np.where(a > 0, "inf", "-inf"), a.astype(object)).tolist()


@runtime_checkable
class DurationModel(Protocol):
    """What refinement needs from a duration model: leaves as boxes + hyperplanes.

    Attributes (k leaves, d features; a leaf covers ``lower < f <= upper``):
        lower: (k, d) lower corners of the leaf boxes, exclusive (may be -inf).
        upper: (k, d) upper corners, inclusive (may be +inf).
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
        lower: (k, d) lower corners of the leaf boxes, exclusive (-inf allowed).
        upper: (k, d) upper corners, inclusive (+inf allowed).
        coef: (k, d) slopes of each leaf's hyperplane.
        intercept: (k,) offsets of each leaf's hyperplane.
        floor: (k,) least value each leaf predicts (its hyperplane is clamped to
            ``[floor, ceiling]``; default -inf: no clamp). Fitted duration trees clamp
            every leaf to the durations it was fitted on, so a linear leaf extrapolating
            into a corner of its box never predicts a negative duration.
        ceiling: (k,) largest value each leaf predicts (default +inf).
    """

    lower: np.ndarray
    upper: np.ndarray
    coef: np.ndarray
    intercept: np.ndarray
    floor: np.ndarray | None = None
    ceiling: np.ndarray | None = None

    def __post_init__(self) -> None:
        arrays = {}
        for name in ("lower", "upper", "coef", "intercept"):
            arrays[name] = np.array(getattr(self, name), dtype=float)
            object.__setattr__(self, name, arrays[name])
        k = arrays["intercept"].reshape(-1).shape[0]
        for name, default in (("floor", -np.inf), ("ceiling", np.inf)):
            value = getattr(self, name)
            value = np.full(k, default) if value is None else np.array(value, dtype=float)
            if value.shape != (k,) or np.isnan(value).any():
                raise RepertoireError(
                    f"{name} must be {k} numbers (one per leaf, +-inf allowed), got "
                    f"{value.tolist()!r}"
                )
            arrays[name] = value
            object.__setattr__(self, name, value)
        if (arrays["floor"] > arrays["ceiling"]).any():
            raise RepertoireError("a leaf's floor exceeds its ceiling; expected floor <= ceiling")
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

        Leaves with ``target_min`` / ``target_max`` (fitted trees' leaves) give the clamps
        ``floor`` / ``ceiling``.

        The adapter for model trees that keep a list of leaves (one box and hyperplane
        each). Leaves are half-open (``lower < f <= upper``) as the trees' own
        (:class:`~repertoire.planning.action_models.trees.LeafBox`), so this model
        predicts what the tree predicts at every feature vector, faces included.

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
        floor = [getattr(leaf, "target_min", -np.inf) for leaf in leaves]
        ceiling = [getattr(leaf, "target_max", np.inf) for leaf in leaves]
        return cls(*fields, floor=floor, ceiling=ceiling)

    @property
    def clamped(self) -> bool:
        """True if any leaf's prediction is clamped (a finite floor or ceiling)."""
        return bool(np.isfinite(self.floor).any() or np.isfinite(self.ceiling).any())

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
            **{
                k: json_array(getattr(self, k))
                for k in ("lower", "upper", "coef", "intercept", "floor", "ceiling")
            },
        }

    @classmethod
    def from_dict(cls, record: dict) -> "PiecewiseLinearModel":
        """Rebuilds a model from :meth:`to_dict`'s record.

        Raises:
            RepertoireError: not a model record, or written by another format version.
        """
        if not isinstance(record, dict) or record.get("type") != "PiecewiseLinearModel":
            raise RepertoireError("not a PiecewiseLinearModel record (missing type)")
        if record.get("version") not in (1, MODEL_FORMAT_VERSION):
            raise RepertoireError(
                f"PiecewiseLinearModel record has format version {record.get('version')!r}; "
                f"this repertoire reads versions 1-{MODEL_FORMAT_VERSION}: re-export the model"
            )
        try:
            arrays = [
                np.array(record[k], dtype=float) for k in ("lower", "upper", "coef", "intercept")
            ]
            clamps = {  # version 1: no clamps
                k: np.array(record[k], dtype=float) for k in ("floor", "ceiling") if k in record
            }
        except KeyError as exc:
            raise RepertoireError(f"PiecewiseLinearModel record lacks {exc}") from None
        except (TypeError, ValueError) as exc:
            raise RepertoireError(
                f"PiecewiseLinearModel record holds a non-number: {exc}"
            ) from None
        return cls(*arrays, **clamps)

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
        """Predicted durations for a batch of feature vectors.

        A vector belongs to the leaves with ``lower < f <= upper`` in every feature
        (one leaf for a tree's partition; the smallest value where leaves overlap).

        Args:
            features: (n, d) feature vectors.

        Returns:
            (n,) predictions, each leaf's hyperplane clamped to its ``[floor, ceiling]``;
            +inf where a vector lies in no leaf (outside the model's domain, a leaf's
            finite ``lower`` face included), which refinement treats as infeasible.
        """
        return predict_leaves(self, features)


def predict_leaves(model: DurationModel, features: np.ndarray) -> np.ndarray:
    """Prediction of any :class:`DurationModel`, leaves half-open (see ``predict``)."""
    f = np.atleast_2d(np.asarray(features, dtype=float))
    k, d = model.lower.shape
    if f.ndim != 2 or f.shape[1] != d:
        raise RepertoireError(f"features must be (n, {d}) for this model, got shape {f.shape}")
    require_memory(f.shape[0] * k * (d + 2) * 8.0, f"leaf tests of {f.shape[0]} x {k} leaves")
    inside = np.ones((f.shape[0], k), dtype=bool)
    for j in range(d):  # one (n, k) test per feature: faster than an (n, k, d) reduction
        column = f[:, j : j + 1]
        inside &= (column > model.lower[:, j]) & (column <= model.upper[:, j])
    values = f @ model.coef.T + model.intercept
    floor, ceiling = getattr(model, "floor", None), getattr(model, "ceiling", None)
    if floor is not None and ceiling is not None:  # PiecewiseLinearModel's clamps
        values = np.clip(values, floor, ceiling)
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

    A learned model is only evidence inside the data it was fitted on; beyond, its linear
    leaves extrapolate, and a search that minimises them is drawn to exactly such places
    (a leaf falling towards a face of its box puts the optimum there). With ``domain``
    (e.g. a fitted tree's ``train_min`` / ``train_max``) the term predicts +inf, like an
    INVALID subgoal, wherever a feature that the free parameters *drive* lies outside
    it; features fixed by bound parameters (a start outside the data, a plan that ends at
    rest) cannot be chosen and are not constrained. The searches (all back-ends) thus
    keep refined parameters inside the data wherever that is possible.

    Args:
        model: the action's duration model.
        features: parameters (n, P) -> features (n, d).
        uses: indices of the free parameters the action depends on; derived from
            ``A`` for affine features, required for other feature maps.
        name: label for messages and reports.
        domain: optional ``(lower, upper)``, d numbers each (+-inf allowed, lower <=
            upper): the closed box of features where the model is trusted.
        feature_uses: per feature, the indices of the free parameters it reads (a subset
            of ``uses``); derived from ``A`` for affine features (a given one must
            agree), required for other feature maps when ``domain`` is given. A feature
            reading none is not constrained by ``domain``.
    """

    model: DurationModel
    features: FeatureMap
    uses: tuple[int, ...] | None = None
    name: str = ""
    domain: tuple[np.ndarray, np.ndarray] | None = None
    feature_uses: tuple[tuple[int, ...], ...] | None = None

    def __post_init__(self) -> None:
        affine = isinstance(self.features, AffineFeatures)
        if self.uses is None:
            if not affine:
                raise RepertoireError(
                    f"term {self.name!r}: non-affine features need `uses`, the indices of "
                    "the free parameters they read"
                )
            object.__setattr__(self, "uses", self.features.uses())
        object.__setattr__(self, "uses", tuple(int(i) for i in self.uses))
        d = self.model.lower.shape[1]
        rows_ok = not affine or self.features.A.shape[0] == d  # else RefinementProblem says so
        if not rows_ok and self.domain is not None:
            raise RepertoireError(
                f"term {self.name!r}: A has {self.features.A.shape[0]} rows (features) for a "
                f"model of {d} features"
            )
        if affine and rows_ok:
            derived = tuple(tuple(np.flatnonzero(row).tolist()) for row in self.features.A != 0)
            given = self.feature_uses
            if given is not None and tuple(tuple(int(i) for i in r) for r in given) != derived:
                raise RepertoireError(
                    f"term {self.name!r}: feature_uses {given!r} differs from what A reads, "
                    f"{derived!r}; leave it out for affine features"
                )
            object.__setattr__(self, "feature_uses", derived)
        if self.feature_uses is not None:
            object.__setattr__(self, "feature_uses", self._checked_feature_uses(d))
        if self.domain is not None:
            if self.feature_uses is None:
                raise RepertoireError(
                    f"term {self.name!r}: a domain needs `feature_uses` (per feature, the "
                    "free parameters it reads) for non-affine features, so that features "
                    "the parameters cannot change are not constrained"
                )
            object.__setattr__(self, "domain", _checked_domain(self.domain, d, self.name))
        object.__setattr__(self, "_searched", self._cut_to_domain())

    def _checked_feature_uses(self, d: int) -> tuple[tuple[int, ...], ...]:
        try:
            rows = tuple(tuple(int(i) for i in row) for row in self.feature_uses)
        except (TypeError, ValueError):
            raise RepertoireError(
                f"term {self.name!r}: feature_uses must hold one sequence of parameter "
                f"indices per feature, got {self.feature_uses!r}"
            ) from None
        if len(rows) != d:
            raise RepertoireError(
                f"term {self.name!r}: feature_uses has {len(rows)} entries for a model of "
                f"{d} features"
            )
        stray = sorted({i for row in rows for i in row} - set(self.uses))
        if stray:
            raise RepertoireError(
                f"term {self.name!r}: feature_uses reads parameters {stray}, which are not "
                f"in its uses {self.uses}"
            )
        return rows

    def _cut_to_domain(self) -> DurationModel:
        """The model with its leaves cut to ``domain`` on the driven features."""
        if self.domain is None:
            return self.model
        driven = np.array([bool(row) for row in self.feature_uses])
        lo_d, hi_d = self.domain
        m = self.model
        # leaves are half-open (lower < f <= upper): f >= lo  <=>  f > nextafter(lo, -inf)
        lower = np.where(driven, np.maximum(m.lower, np.nextafter(lo_d, -np.inf)), m.lower)
        upper = np.where(driven, np.minimum(m.upper, hi_d), m.upper)
        keep = np.all(lower < upper, axis=1)
        if not keep.any():
            raise RepertoireError(
                f"term {self.name!r}: no leaf of its model meets the domain "
                f"[{lo_d.tolist()}, {hi_d.tolist()}] on the features the parameters drive"
            )
        k = m.intercept.shape[0]
        floor = getattr(m, "floor", None)
        ceiling = getattr(m, "ceiling", None)
        floor = np.full(k, -np.inf) if floor is None else np.asarray(floor, dtype=float)
        ceiling = np.full(k, np.inf) if ceiling is None else np.asarray(ceiling, dtype=float)
        return PiecewiseLinearModel(
            lower[keep], upper[keep], m.coef[keep], m.intercept[keep], floor[keep], ceiling[keep]
        )

    @property
    def searched_model(self) -> DurationModel:
        """What the searches minimise: ``model`` cut to ``domain`` on driven features.

        ``model`` itself without a domain.
        """
        return self._searched

    def predict(self, params: np.ndarray, *, within_domain: bool = True) -> np.ndarray:
        """Predicted durations of a batch (n, P) of parameter vectors.

        Args:
            params: the parameter vectors.
            within_domain: True: +inf where a driven feature leaves ``domain`` (what the
                searches see); False: ``model``'s prediction there (an extrapolation).
        """
        n = np.atleast_2d(params).shape[0]
        features = np.asarray(self.features(params), dtype=float)
        d = self.model.lower.shape[1]
        if features.shape != (n, d):
            raise RepertoireError(
                f"term {self.name!r}: its features of {n} parameter vectors have shape "
                f"{features.shape}; its model expects ({n}, {d})"
            )
        return predict_leaves(self.searched_model if within_domain else self.model, features)


def _checked_domain(domain, d: int, name: str) -> tuple[np.ndarray, np.ndarray]:
    """``domain`` as two (d,) float arrays with lower <= upper, or a RepertoireError."""
    try:
        lo, hi = (np.array(side, dtype=float).reshape(-1) for side in domain)
    except (TypeError, ValueError):
        raise RepertoireError(
            f"term {name!r}: domain must be (lower, upper), {d} numbers each, got {domain!r}"
        ) from None
    if lo.shape != (d,) or hi.shape != (d,):
        raise RepertoireError(
            f"term {name!r}: domain must be (lower, upper), {d} numbers each (one per "
            f"feature), got {lo.size} and {hi.size}"
        )
    if np.isnan(lo).any() or np.isnan(hi).any() or (lo > hi).any():
        raise RepertoireError(
            f"term {name!r}: domain needs lower <= upper without NaN (+-inf allowed), got "
            f"lower {lo.tolist()} and upper {hi.tolist()}"
        )
    return lo, hi


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
        if lo.shape != hi.shape:
            raise RepertoireError(
                f"parameter bounds must be arrays of equal length, got {lo.size} lower and "
                f"{hi.size} upper bounds"
            )
        if self.names and len(self.names) != lo.size:
            raise RepertoireError(f"{len(self.names)} names for {lo.size} parameters")
        bad = np.flatnonzero(~(np.isfinite(lo) & np.isfinite(hi)))
        if bad.size:
            which = [self.names[i] if self.names else int(i) for i in bad]
            raise RepertoireError(
                f"free parameters {which} have the non-finite ranges "
                f"{[[float(lo[i]), float(hi[i])] for i in bad]}; refinement searches a "
                "finite box: give each a finite range (e.g. the belief state's default)"
            )
        bad = np.flatnonzero(lo > hi)
        if bad.size:
            which = [self.names[i] if self.names else int(i) for i in bad]
            raise RepertoireError(
                f"free parameters {which} have empty ranges (lower > upper); expected lo <= hi"
            )
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
            d = term.model.lower.shape[1]
            if isinstance(term.features, AffineFeatures) and term.features.A.shape[0] != d:
                raise RepertoireError(
                    f"term {term.name!r}: A has {term.features.A.shape[0]} rows (features) "
                    f"for a model of {d} features"
                )

    @property
    def n_params(self) -> int:
        return int(self.lower.size)

    def cost(self, params: np.ndarray, *, within_domain: bool = True) -> np.ndarray:
        """Summed predicted duration of a batch (n, P) of parameter vectors (+inf outside).

        Args:
            params: the parameter vectors.
            within_domain: True (what the searches minimise): +inf where a term's driven
                feature leaves its ``domain``; False: the models' extrapolation there.
        """
        p = np.atleast_2d(np.asarray(params, dtype=float))
        if p.ndim != 2 or p.shape[1] != self.n_params:
            raise RepertoireError(
                f"parameters must be (n, {self.n_params}) for this problem, got shape {p.shape}"
            )
        return np.sum([t.predict(p, within_domain=within_domain) for t in self.terms], axis=0)


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
            sub_terms.append(DurationTerm(term.model, feats, name=term.name, domain=term.domain))
        else:
            feats = _Embedded(term.features, full, np.asarray(used, dtype=int))
            local = tuple(used.index(i) for i in term.uses if i in used)
            # a feature whose parameters are all fixed now is no longer constrained
            reads = None
            if term.feature_uses is not None:
                reads = tuple(
                    tuple(used.index(i) for i in r if i in used) for r in term.feature_uses
                )
            sub_terms.append(DurationTerm(term.model, feats, local, term.name, term.domain, reads))
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

    Terms with a ``domain`` constrain, at each step, the features that the step's still
    free parameters drive; a feature an earlier step fixed outside the domain (a greedy
    step choosing a heading for its own action alone) no longer constrains later steps.

    Returns:
        All parameters, the *whole* sequence's predicted duration at them, and one
        result per step in ``steps``. The cost is +inf when the back-end found no
        parameters every model accepts (all candidates INVALID, e.g. a failure model
        rejecting every subgoal, or no parameters inside the terms' domains): keep the
        unrefined plan then. Otherwise it is the models' prediction without domains
        (``cost(params, within_domain=False)``): where a fixed feature lies outside a
        domain, the models' extrapolation.
    """
    n = len(problem.terms)
    if not is_whole(horizon) or not 1 <= horizon <= n:
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
    found = all(np.isfinite(s.cost) for s in steps)
    return RefinementResult(
        params,
        float(problem.cost(params, within_domain=False)[0]) if found else np.inf,
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
        from repertoire.planning.refinement_exact import solve_corners

        return solve_corners
    if solver in ("milp", "ga", "de"):
        from repertoire.planning import black_box, refinement_exact

        fn = {
            "milp": refinement_exact.solve_milp,
            "ga": black_box.solve_ga,
            "de": black_box.solve_de,
        }[solver]
        known = [n for n, p in inspect.signature(fn).parameters.items() if p.kind == p.KEYWORD_ONLY]
        unknown = sorted(set(options) - set(known))
        if unknown:
            raise RepertoireError(f"solver {solver!r} has no options {unknown}; it takes {known}")
        return lambda p: fn(p, **options)
    raise RepertoireError(
        f"unknown solver {solver!r}; expected corners, milp, ga, de or a function"
    )
