"""Duration model trees and pessimistic failure trees on scikit-learn, as plain data.

Duration (section 4 of Stulp & Beetz, M5-like model trees): a scikit-learn
``DecisionTreeRegressor`` proposes the splits; every leaf gets its own linear
fit (least squares on the leaf's episodes); the tree size (``max_leaf_nodes``)
is chosen among candidates by the *linear-leaf* error on a validation part of
the training set, which prunes the tree to the size that linear leaves need.

Failure: a ``DecisionTreeClassifier`` whose class weights are a cost matrix
(a missed failure costs ``failure_cost`` times a false alarm), as WEKA's
CostSensitiveClassifier, so the tree is pessimistic: it predicts failure
when in doubt.

Both are stored as a :class:`TreeModel`: the nodes (feature, threshold,
children) and one :class:`LeafBox` per leaf with its box (lower, upper per
feature: ``lower < x <= upper``) and its hyperplane (``coef``, ``intercept``;
for a failure tree ``coef = 0`` and ``intercept`` the leaf's failure
probability). The subgoal-refinement issue enumerates these boxes. Models are
printed as rules and saved as JSON with a version
(:mod:`~repertoire.planning.action_models.model_files`).

A duration leaf's prediction is clamped to the durations of the leaf's own training
episodes (``target_min``, ``target_max``): a linear leaf fitted on the episodes it holds
extrapolates into the corners of its box that hold none, and there it predicted durations
below any it saw, negative ones included (the shipped dribble duration tree at 0.01 % of
uniform points of its training box, down to -0.44 s). Models saved by version 1, without
these fields, are read with the physical floor of 0 s and no ceiling.
"""

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from repertoire.checks import check_seed, is_real, is_whole
from repertoire.errors import RepertoireError

MODEL_VERSION = 2
READ_VERSIONS = (1, 2)  # version 1: leaves without target_min / target_max
MIN_EPISODES = 20  # fewer episodes cannot give a 3/4 training part with two leaves of 5
KINDS = ("duration", "failure")


@dataclasses.dataclass
class LeafBox:
    """One leaf: the box of feature space it covers and its linear model.

    Attributes:
        lower: per-feature lower bounds (exclusive; -inf if unbounded).
        upper: per-feature upper bounds (inclusive; +inf if unbounded).
        coef: the hyperplane's coefficients (zeros for a failure tree).
        intercept: the hyperplane's intercept (the failure probability for a
            failure tree).
        samples: training episodes in the leaf.
        target_min: the least value the leaf predicts: the smallest target of its
            training episodes (its hyperplane is clamped to ``[target_min, target_max]``).
        target_max: the largest value the leaf predicts: its episodes' largest target.
    """

    lower: list[float]
    upper: list[float]
    coef: list[float]
    intercept: float
    samples: int
    target_min: float = -math.inf
    target_max: float = math.inf


@dataclasses.dataclass
class TreeModel:
    """A tree with linear leaves, independent of scikit-learn once fitted.

    Attributes:
        kind: ``"duration"`` (predicts a value) or ``"failure"`` (predicts a
            failure probability; failure if >= ``threshold``).
        feature_names: the features' names, in column order.
        feature: per node, the split feature index (-1 for a leaf).
        threshold: per node, the split threshold (go left if x <= threshold).
        left: per node, the left child (-1 for a leaf).
        right: per node, the right child (-1 for a leaf).
        leaf_of_node: per node, the index into ``leaves`` (-1 for a split).
        leaves: the leaves' boxes and hyperplanes.
        train_min: per-feature minimum seen in training.
        train_max: per-feature maximum seen in training.
        threshold_probability: failure decision threshold (failure trees).
        version: the file format version.
    """

    kind: str
    feature_names: list[str]
    feature: list[int]
    threshold: list[float]
    left: list[int]
    right: list[int]
    leaf_of_node: list[int]
    leaves: list[LeafBox]
    train_min: list[float]
    train_max: list[float]
    threshold_probability: float = 0.5
    version: int = MODEL_VERSION

    def _check_x(self, X) -> np.ndarray:
        try:
            X = np.asarray(X, dtype=float)
        except (TypeError, ValueError) as e:
            raise RepertoireError(
                f"features must be numbers, rows of {self.feature_names}: {e}"
            ) from e
        if X.ndim == 1:
            X = X[None, :]
        if X.ndim != 2 or X.shape[1] != len(self.feature_names):
            raise RepertoireError(
                f"features must be (n, {len(self.feature_names)}) for "
                f"{self.feature_names}, got shape {X.shape}"
            )
        if not np.all(np.isfinite(X)):
            bad = sorted({self.feature_names[j] for j in np.nonzero(~np.isfinite(X))[1]})
            raise RepertoireError(f"features {bad} hold NaN or inf; every feature must be finite")
        return X

    def _arrays(self) -> dict[str, np.ndarray]:
        """The nodes and leaves as arrays, built once (the fields are not changed after a fit)."""
        cached = self.__dict__.get("_cached_arrays")
        if cached is None:
            cached = {
                "feature": np.asarray(self.feature, dtype=int),
                "threshold": np.asarray(self.threshold, dtype=float),
                "left": np.asarray(self.left, dtype=int),
                "right": np.asarray(self.right, dtype=int),
                "leaf_of_node": np.asarray(self.leaf_of_node, dtype=int),
                "coef": np.array([leaf.coef for leaf in self.leaves], dtype=float),
                "intercept": np.array([leaf.intercept for leaf in self.leaves], dtype=float),
                "target_min": np.array([leaf.target_min for leaf in self.leaves], dtype=float),
                "target_max": np.array([leaf.target_max for leaf in self.leaves], dtype=float),
                "train_min": np.asarray(self.train_min, dtype=float),
                "train_max": np.asarray(self.train_max, dtype=float),
            }
            self.__dict__["_cached_arrays"] = cached
        return cached

    def leaf_index(self, X) -> np.ndarray:
        """The leaf (index into ``leaves``) of each row of ``X``."""
        X = self._check_x(X)
        a = self._arrays()
        feature, thr, left, right = a["feature"], a["threshold"], a["left"], a["right"]
        node = np.zeros(len(X), dtype=int)
        rows = np.arange(len(X))
        while True:
            f = feature[node]
            active = f >= 0
            if not active.any():
                break
            go_left = X[rows, np.maximum(f, 0)] <= thr[node]
            node = np.where(active, np.where(go_left, left[node], right[node]), node)
        return a["leaf_of_node"][node]

    def predict(self, X) -> np.ndarray:
        """Duration (or failure probability) per row, from the leaf's hyperplane.

        The hyperplane is clamped to the leaf's ``[target_min, target_max]``.
        """
        X = self._check_x(X)
        idx = self.leaf_index(X)
        a = self._arrays()
        linear = np.einsum("ij,ij->i", X, a["coef"][idx]) + a["intercept"][idx]
        return np.clip(linear, a["target_min"][idx], a["target_max"][idx])

    def predict_failure(self, X) -> np.ndarray:
        """True where a failure tree predicts failure."""
        if self.kind != "failure":
            raise RepertoireError("predict_failure needs a failure tree, this is a duration tree")
        return self.predict(X) >= self.threshold_probability

    def out_of_range(self, X, features: Sequence[str] | None = None) -> np.ndarray:
        """True per row where any feature lies outside the training range.

        Args:
            X: ``(n, d)`` feature rows.
            features: names of the features to check (default: all), e.g. only those a
                refinement's free parameters drive.
        """
        X = self._check_x(X)
        a = self._arrays()
        out = (X < a["train_min"]) | (X > a["train_max"])
        if features is not None:
            names = [features] if isinstance(features, str) else list(features)
            unknown = sorted(set(names) - set(self.feature_names))
            if unknown:
                raise RepertoireError(
                    f"features {unknown} are not the model's; its features are {self.feature_names}"
                )
            out = out[:, [self.feature_names.index(n) for n in names]]
        return np.any(out, axis=1)

    def rules(self) -> str:
        """The tree as readable if-then rules, one per leaf."""
        lines = []
        for k, leaf in enumerate(self.leaves):
            conds = []
            for j, name in enumerate(self.feature_names):
                lo, hi = leaf.lower[j], leaf.upper[j]
                if math.isfinite(lo) and math.isfinite(hi):
                    conds.append(f"{lo:.3g} < {name} <= {hi:.3g}")
                elif math.isfinite(lo):
                    conds.append(f"{name} > {lo:.3g}")
                elif math.isfinite(hi):
                    conds.append(f"{name} <= {hi:.3g}")
            cond = " and ".join(conds) or "always"
            if self.kind == "failure":
                verdict = "FAIL" if leaf.intercept >= self.threshold_probability else "succeed"
                then = f"{verdict} (p_fail={leaf.intercept:.2f})"
            else:
                terms = " ".join(
                    f"{c:+.3g}*{n}" for c, n in zip(leaf.coef, self.feature_names) if c != 0
                )
                then = f"duration = {leaf.intercept:.3g} {terms}".rstrip()
                if math.isfinite(leaf.target_min) or math.isfinite(leaf.target_max):
                    then += f", within [{leaf.target_min:.3g}, {leaf.target_max:.3g}]"
            lines.append(f"rule {k} [{leaf.samples} episodes]: if {cond} then {then}")
        return "\n".join(lines)


def _check_whole(name: str, value, least: int) -> int:
    """``value`` as an int >= ``least``, or a RepertoireError naming it."""
    if not is_whole(value) or value < least:
        raise RepertoireError(f"{name} must be a whole number >= {least}, got {value!r}")
    return int(value)


def _check_cost(failure_cost) -> float:
    if not (is_real(failure_cost) and math.isfinite(failure_cost) and failure_cost > 0):
        raise RepertoireError(f"failure_cost must be finite and > 0, got {failure_cost!r}")
    return float(failure_cost)


def _check_names(feature_names) -> list[str]:
    """The feature names as a list of distinct strings, or a RepertoireError naming them."""
    if isinstance(feature_names, str):
        raise RepertoireError(
            f"feature_names must be a sequence of names, got the string {feature_names!r}; "
            f"write [{feature_names!r}] for one feature"
        )
    names = list(feature_names)
    if not all(isinstance(n, str) for n in names) or len(set(names)) != len(names):
        raise RepertoireError(f"feature_names must be distinct strings, got {names!r}")
    return names


def _check_training(X, y, feature_names: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
    feature_names = _check_names(feature_names)
    try:
        X = np.asarray(X, dtype=float)
        y = np.asarray(y, dtype=float)
    except (TypeError, ValueError) as e:
        raise RepertoireError(f"X and y must be numeric arrays (rows of equal length): {e}") from e
    if X.size == 0 or y.size == 0:
        raise RepertoireError(
            f"no training episodes (X of shape {X.shape}, y of shape {y.shape}); at least "
            f"{MIN_EPISODES} are needed"
        )
    if X.ndim != 2 or X.shape[1] != len(feature_names) or y.ndim != 1 or len(y) != len(X):
        raise RepertoireError(
            f"need X of shape (n, {len(feature_names)}) and y of shape (n,), got {X.shape}, "
            f"{y.shape}"
        )
    if len(X) < MIN_EPISODES:
        raise RepertoireError(
            f"{len(X)} episodes are too few to train an action model; at least {MIN_EPISODES} "
            "are needed (the paper uses hundreds to thousands)"
        )
    if not np.all(np.isfinite(X)):
        bad = sorted({feature_names[j] for j in np.nonzero(~np.isfinite(X))[1]})
        raise RepertoireError(f"training features {bad} hold NaN or inf")
    big = np.abs(X) > np.finfo(np.float32).max  # scikit-learn's trees split in float32
    if big.any():
        bad = sorted({feature_names[j] for j in np.nonzero(big)[1]})
        raise RepertoireError(f"training features {bad} exceed float32's range (3.4e38)")
    _check_targets(y, "row")
    return X, y


def _check_targets(y: np.ndarray, row: str, nonnegative: bool = False) -> None:
    """Finite targets (and >= 0 if ``nonnegative``), or a RepertoireError naming a bad one.

    Args:
        y: the targets.
        row: what an index of ``y`` names in the message (``"record"``, ...).
        nonnegative: True for durations, which are never negative.
    """
    bad = np.flatnonzero(~np.isfinite(y))
    if bad.size:
        raise RepertoireError(
            f"{bad.size} of {y.size} targets are NaN or inf (the first: {row} {bad[0]}, "
            f"{y[bad[0]]}); every target must be finite"
        )
    if nonnegative and (y < 0).any():
        least = int(np.argmin(y))
        raise RepertoireError(
            f"{int(np.sum(y < 0))} of {y.size} durations are negative (the least: {row} {least}, "
            f"{y[least]:.6g}); a duration is never negative (a signed target such as a "
            "clearance: fit with nonnegative=False, on the actions_fit command line "
            "--signed-target)"
        )


def _extract(sk_tree, feature_names, X, leaf_models, kind, threshold_probability) -> TreeModel:
    """Turns a fitted sklearn tree plus per-leaf (coef, intercept) into a TreeModel."""
    t = sk_tree.tree_
    d = len(feature_names)
    n_nodes = t.node_count
    leaf_of_node = [-1] * n_nodes
    leaves: list[LeafBox] = []
    stack = [(0, np.full(d, -np.inf), np.full(d, np.inf))]
    while stack:
        node, lo, hi = stack.pop()
        if t.children_left[node] < 0:
            coef, icpt, n, t_min, t_max = leaf_models[node]
            leaf_of_node[node] = len(leaves)
            leaves.append(
                LeafBox(lo.tolist(), hi.tolist(), list(map(float, coef)), icpt, n, t_min, t_max)
            )
            continue
        f, thr = int(t.feature[node]), float(t.threshold[node])
        hi_l = hi.copy()
        hi_l[f] = min(hi_l[f], thr)
        lo_r = lo.copy()
        lo_r[f] = max(lo_r[f], thr)
        stack.append((int(t.children_right[node]), lo_r, hi.copy()))
        stack.append((int(t.children_left[node]), lo.copy(), hi_l))
    is_leaf = t.children_left < 0
    return TreeModel(
        kind=kind,
        feature_names=list(feature_names),
        feature=[-1 if is_leaf[i] else int(t.feature[i]) for i in range(n_nodes)],
        threshold=[0.0 if is_leaf[i] else float(t.threshold[i]) for i in range(n_nodes)],
        left=[int(c) for c in t.children_left],
        right=[int(c) for c in t.children_right],
        leaf_of_node=leaf_of_node,
        leaves=leaves,
        train_min=X.min(axis=0).tolist(),
        train_max=X.max(axis=0).tolist(),
        threshold_probability=float(threshold_probability),
    )


def _linear_leaves(sk_tree, X, y, ridge: float) -> dict[int, tuple]:
    """Per leaf node: the hyperplane's (coef, intercept), its episodes and their target range."""
    node = sk_tree.apply(X)
    out = {}
    for leaf in np.unique(node):
        m = node == leaf
        Xl, yl = X[m], y[m]
        mu = Xl.mean(axis=0)
        Xc = Xl - mu
        if ridge > 0:
            A = Xc.T @ Xc + ridge * len(Xl) * np.eye(X.shape[1])
            coef = np.linalg.solve(A, Xc.T @ (yl - yl.mean()))
        else:  # least squares; the minimum-norm fit if the leaf's design is singular
            coef = np.linalg.lstsq(Xc, yl - yl.mean(), rcond=None)[0]
        out[int(leaf)] = (
            coef,
            float(yl.mean() - mu @ coef),
            int(m.sum()),
            float(yl.min()),
            float(yl.max()),
        )
    return out


def fit_duration_tree(
    X,
    y,
    feature_names: Sequence[str],
    *,
    seed: int = 0,
    min_samples_leaf: int | None = None,
    candidate_leaves: Sequence[int] = (1, 2, 4, 8, 16, 32),
    ridge: float = 1e-10,
    nonnegative: bool = True,
) -> TreeModel:
    """Fits an M5-like model tree (linear leaves, size chosen by linear-leaf error).

    Args:
        X: ``(n, d)`` features.
        y: ``(n,)`` durations.
        feature_names: the ``d`` names.
        seed: seed of the validation split and the tree (a whole number in 0..2**32 - 1).
        min_samples_leaf: episodes per leaf at least, a whole number >= 1 (default
            ``max(5, 4 d)``).
        candidate_leaves: tree sizes tried (whole numbers >= 1); the one with the
            smallest validation MAE of the linear-leaf model wins (pruning). Sizes
            whose leaves could not each hold ``min_samples_leaf`` episodes are skipped.
        ridge: Tikhonov weight of the leaf fits (relative to the leaf size; finite,
            >= 0). With 0 the leaves are plain least squares (``numpy.linalg.lstsq``):
            where a leaf's features are collinear (a constant feature, say), the
            minimum-norm coefficients.
        nonnegative: True (durations): a negative target is refused, so every leaf's
            clamp, and with it every prediction, is >= 0. False for a signed target
            (a clearance, say).

    Returns:
        The fitted :class:`TreeModel` of kind ``"duration"``, refitted on all of ``X``.

    Raises:
        RepertoireError: bad shapes, too few episodes, NaN, a negative duration, or a
            bad option (named).
    """
    from sklearn.tree import DecisionTreeRegressor

    if not (is_real(ridge) and math.isfinite(ridge) and ridge >= 0):
        raise RepertoireError(f"ridge must be a finite number >= 0, got {ridge!r}")
    seed = check_seed(seed)
    if min_samples_leaf is not None:
        min_samples_leaf = _check_whole("min_samples_leaf", min_samples_leaf, 1)
    candidate_leaves = list(candidate_leaves)
    if not candidate_leaves:
        raise RepertoireError("candidate_leaves is empty; expected tree sizes such as (1, 2, 4)")
    for k in candidate_leaves:
        _check_whole("each of candidate_leaves", k, 1)
    if not isinstance(nonnegative, bool | np.bool_):
        raise RepertoireError(f"nonnegative must be True or False, got {nonnegative!r}")
    X, y = _check_training(X, y, feature_names)
    _check_targets(y, "row", nonnegative)
    d = X.shape[1]
    msl = min_samples_leaf if min_samples_leaf is not None else max(5, 4 * d)
    rng = np.random.default_rng(seed)
    perm = rng.permutation(len(X))
    n_val = max(1, len(X) // 5)
    val, fit = perm[:n_val], perm[n_val:]

    def make_tree(k: int, n: int):
        if k == 1:  # a single leaf: one hyperplane over everything
            return DecisionTreeRegressor(min_samples_leaf=n)
        return DecisionTreeRegressor(max_leaf_nodes=k, min_samples_leaf=msl, random_state=seed)

    best, best_err = 1, np.inf
    for k in candidate_leaves:
        if k * msl > len(fit):
            continue
        tree = make_tree(k, len(fit)).fit(X[fit], y[fit])
        leaves = _linear_leaves(tree, X[fit], y[fit], ridge)
        model = _extract(tree, feature_names, X[fit], leaves, "duration", 0.5)
        err = float(np.mean(np.abs(model.predict(X[val]) - y[val])))
        if err < best_err - 1e-12:
            best, best_err = k, err
    tree = make_tree(best, len(X)).fit(X, y)
    return _extract(tree, feature_names, X, _linear_leaves(tree, X, y, ridge), "duration", 0.5)


def fit_failure_tree(
    X,
    failed,
    feature_names: Sequence[str],
    *,
    failure_cost: float = 3.0,
    seed: int = 0,
    min_samples_leaf: int = 10,
    max_leaf_nodes: int = 24,
) -> TreeModel:
    """Fits a pessimistic decision tree for failure (cost-weighted classes).

    Args:
        X: ``(n, d)`` features.
        failed: ``(n,)`` booleans, True where the episode failed.
        feature_names: the ``d`` names.
        failure_cost: cost of predicting success for a failure relative to the
            cost of a false alarm (> 1 makes the tree pessimistic). The leaf
            decides failure when its failure probability is at least
            ``1 / (1 + failure_cost)`` (minimum expected cost).
        seed: the tree's seed (a whole number in 0..2**32 - 1).
        min_samples_leaf: episodes per leaf at least (a whole number >= 1).
        max_leaf_nodes: the largest tree (a whole number >= 2).

    Returns:
        The fitted :class:`TreeModel` of kind ``"failure"``.

    Raises:
        RepertoireError: bad shapes, too few episodes, NaN, non-boolean targets, or a
            bad option (named).
    """
    from sklearn.tree import DecisionTreeClassifier

    failure_cost = _check_cost(failure_cost)
    seed = check_seed(seed)
    min_samples_leaf = _check_whole("min_samples_leaf", min_samples_leaf, 1)
    max_leaf_nodes = _check_whole("max_leaf_nodes", max_leaf_nodes, 2)
    X, y = _check_training(X, failed, feature_names)
    if not np.all((y == 0) | (y == 1)):
        raise RepertoireError("failure targets must be booleans (True = failed)")
    tree = DecisionTreeClassifier(
        class_weight={0.0: 1.0, 1.0: failure_cost},
        min_samples_leaf=min_samples_leaf,
        max_leaf_nodes=max_leaf_nodes,
        random_state=seed,
    ).fit(X, y)
    node = tree.apply(X)
    leaves = {}
    d = X.shape[1]
    for leaf in np.unique(node):
        m = node == leaf
        leaves[int(leaf)] = (np.zeros(d), float(y[m].mean()), int(m.sum()), 0.0, 1.0)
    return _extract(tree, feature_names, X, leaves, "failure", 1.0 / (1.0 + failure_cost))


@dataclasses.dataclass
class FittedModel:
    """A model fitted by :func:`fit_action_model` with its held-out evaluation.

    Attributes:
        model: the tree (refitted on the training 3/4).
        n_train: training episodes.
        n_test: held-out episodes.
        mae: held-out mean absolute error (duration models; NaN otherwise).
        mean_target: mean target over all episodes.
        confusion: held-out ``[[tn, fp], [fn, tp]]`` with failure the positive
            class (failure models; empty otherwise).
        accuracy: held-out fraction correct (failure models; NaN otherwise).
    """

    model: TreeModel
    n_train: int
    n_test: int
    mae: float
    mean_target: float
    confusion: list[list[int]]
    accuracy: float


FeatureSpec = Sequence[str] | Mapping[str, Callable[[Any], float]]


def _feature_matrix(records: Sequence[Any], features: FeatureSpec) -> tuple[np.ndarray, list[str]]:
    if isinstance(features, Mapping):
        names = list(features)
        funcs = list(features.values())
    else:
        names = list(features)
        funcs = [lambda r, n=n: getattr(r, n) for n in names]
    if not names:
        raise RepertoireError("fit_action_model needs at least one feature")
    rows = []
    for i, rec in enumerate(records):
        try:
            rows.append([float(f(rec)) for f in funcs])
        except (AttributeError, TypeError, ValueError, KeyError) as e:
            raise RepertoireError(
                f"record {i} ({type(rec).__name__}) gives no feature among {names}: {e}"
            ) from e
    return np.asarray(rows, dtype=float).reshape(len(rows), len(names)), names


def fit_action_model(
    records: Sequence[Any],
    features: FeatureSpec,
    target: str,
    *,
    seed: int = 0,
    failure_cost: float = 3.0,
    nonnegative: bool = True,
) -> FittedModel:
    """Fits a duration model tree or a pessimistic failure tree on any study's records.

    A boolean target field gives a failure tree (True = failed), a numeric one a
    duration model tree. The records are shuffled (seeded); the first 3/4 train
    the model, the last quarter measures it.

    Args:
        records: typed records (e.g. from ``load_records``).
        features: field names, or ``{name: function(record) -> float}``.
        target: the record field to predict.
        seed: the shuffle and tree seed.
        failure_cost: cost ratio for failure trees (see :func:`fit_failure_tree`).
        nonnegative: a numeric target is a duration, never negative (a negative one is
            refused, naming its record); False for a signed target (a clearance).

    Returns:
        A :class:`FittedModel`.

    Raises:
        RepertoireError: too few records, a missing field, NaN features or targets, a
            negative duration.
    """
    seed = check_seed(seed)
    failure_cost = _check_cost(failure_cost)
    if isinstance(features, str):
        raise RepertoireError(
            f"features must be a sequence of field names or a mapping, got the string "
            f"{features!r}; write [{features!r}] for one feature"
        )
    records = list(records)
    if len(records) < MIN_EPISODES:
        raise RepertoireError(
            f"{len(records)} episodes are too few to train an action model; at least "
            f"{MIN_EPISODES} are needed"
        )
    X, names = _feature_matrix(records, features)
    try:
        raw = [getattr(r, target) for r in records]
    except AttributeError as e:
        raise RepertoireError(f"records have no target field {target!r}") from e
    flags = [isinstance(v, bool | np.bool_) for v in raw]
    is_bool = all(flags)
    if any(flags) and not is_bool:  # a stray 0/1 would silently make a duration model
        i = flags.index(False)
        raise RepertoireError(
            f"target field {target!r} mixes bools and numbers (record {i} is {raw[i]!r}): "
            "bools in every record for a failure model, numbers for a duration model"
        )
    for i, v in enumerate(raw):
        if isinstance(v, bool | np.bool_):
            continue
        if not is_real(v):
            raise RepertoireError(
                f"target field {target!r} of record {i} is {repr(v)[:60]}; expected a number (a "
                "duration model) or a bool (a failure model) in every record"
            )
    y = np.asarray(raw, dtype=float)
    if not is_bool:
        _check_targets(y, f"{target!r} of record", nonnegative)
    perm = np.random.default_rng(seed).permutation(len(records))
    n_train = (3 * len(records)) // 4
    tr, te = perm[:n_train], perm[n_train:]
    if len(tr) < MIN_EPISODES:
        raise RepertoireError(
            f"{len(records)} episodes leave {len(tr)} for training; at least "
            f"{math.ceil(MIN_EPISODES * 4 / 3)} episodes are needed"
        )
    if is_bool:
        model = fit_failure_tree(X[tr], y[tr], names, failure_cost=failure_cost, seed=seed)
        pred = model.predict_failure(X[te])
        truth = y[te] == 1
        conf = [
            [int(np.sum(~truth & ~pred)), int(np.sum(~truth & pred))],
            [int(np.sum(truth & ~pred)), int(np.sum(truth & pred))],
        ]
        acc = float(np.mean(pred == truth))
        return FittedModel(model, len(tr), len(te), math.nan, float(y.mean()), conf, acc)
    model = fit_duration_tree(X[tr], y[tr], names, seed=seed, nonnegative=nonnegative)
    mae = float(np.mean(np.abs(model.predict(X[te]) - y[te])))
    return FittedModel(model, len(tr), len(te), mae, float(y.mean()), [], math.nan)
