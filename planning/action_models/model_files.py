"""Action models as files: :class:`~repertoire.planning.action_models.trees.TreeModel` as JSON.

:func:`save_model` writes standard JSON (no pickle), :func:`load_model` reads it back and
checks every field's values, not only its presence: a NaN threshold, a string where a
number belongs or indices that do not form a tree are refused with the file, the field
and the value.
"""

import dataclasses
import json
import math
from pathlib import Path

from repertoire.planning.action_models.trees import (
    KINDS,
    MODEL_VERSION,
    READ_VERSIONS,
    LeafBox,
    TreeModel,
)
from repertoire.planning.refinement import json_array

from repertoire.checks import is_real, is_whole
from repertoire.errors import RepertoireError

_INF = {"inf": math.inf, "-inf": -math.inf}


def save_model(model: TreeModel, path: str | Path) -> Path:
    """Writes a TreeModel as standard JSON (no pickle).

    The leaves' unbounded faces are written as the strings ``"inf"``/``"-inf"``
    (:func:`~repertoire.planning.refinement.json_array`, as
    :class:`~repertoire.planning.refinement.PiecewiseLinearModel` does). Every other value
    is finite.
    """
    path = Path(path)
    data = dataclasses.asdict(model)
    for leaf in data["leaves"]:
        for key in ("lower", "upper", "target_min", "target_max"):
            leaf[key] = json_array(leaf[key])
    try:
        text = json.dumps(data, allow_nan=False)
    except ValueError as e:
        raise RepertoireError(f"action model holds NaN or inf outside its leaf boxes: {e}") from e
    path.write_text(text)
    return path


def _leaf_bounds(values, path: Path) -> list[float]:
    """A leaf's bounds read back: numbers, or "inf"/"-inf" (older files: Infinity)."""
    out = []
    for v in values:
        if isinstance(v, str) and v in _INF:
            out.append(_INF[v])
        elif is_real(v) and not math.isnan(v):
            out.append(float(v))
        else:
            raise RepertoireError(
                f"action model '{path}' has a leaf bound {v!r}; expected a number, 'inf' or '-inf'"
            )
    return out


_REQUIRED = [f.name for f in dataclasses.fields(TreeModel)]


def load_model(path: str | Path) -> TreeModel:
    """Reads a TreeModel written by :func:`save_model`, checking version and fields.

    Raises:
        RepertoireError: missing file, not JSON, another version, missing fields.
    """
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as e:
        raise RepertoireError(f"cannot read action model '{path}': {e}") from e
    if not isinstance(data, dict):
        raise RepertoireError(f"action model '{path}' is not a JSON object")
    version = data.get("version")
    if version not in READ_VERSIONS:
        raise RepertoireError(
            f"action model '{path}' has version {version!r}; this code reads "
            f"versions {', '.join(map(str, READ_VERSIONS))}: refit the model"
        )
    missing = [k for k in _REQUIRED if k not in data]
    if missing:
        raise RepertoireError(f"action model '{path}' lacks fields {missing}")
    if data["kind"] not in KINDS:
        raise RepertoireError(f"action model kind must be one of {KINDS}, got {data['kind']!r}")
    _check_field_types(data, path)
    try:
        data["leaves"] = [LeafBox(**leaf) for leaf in data["leaves"]]
        for leaf in data["leaves"]:
            leaf.lower = _leaf_bounds(leaf.lower, path)
            leaf.upper = _leaf_bounds(leaf.upper, path)
            if version == 1:  # no targets saved: a duration is never negative
                t_min, t_max = (0.0, math.inf) if data["kind"] == "duration" else (0.0, 1.0)
            else:
                t_min, t_max = _leaf_bounds([leaf.target_min, leaf.target_max], path)
            if not t_min <= t_max:
                raise RepertoireError(
                    f"action model '{path}' has a leaf with target_min {t_min} > target_max {t_max}"
                )
            leaf.target_min, leaf.target_max = t_min, t_max
    except TypeError as e:
        raise RepertoireError(f"action model '{path}' has a malformed leaf: {e}") from e
    n = len(data["feature"])
    for k in ("threshold", "left", "right", "leaf_of_node"):
        if len(data[k]) != n:
            raise RepertoireError(f"action model '{path}': '{k}' has {len(data[k])} nodes, not {n}")
    try:
        _check_structure(data, path)
    except TypeError as e:
        raise RepertoireError(f"action model '{path}' has a field of the wrong type: {e}") from e
    data["version"] = MODEL_VERSION  # read into this version's fields
    return TreeModel(**data)


def _check_field_types(data: dict, path: Path) -> None:
    """Every field of a model file holds values of its type, or an error naming field and value.

    Only the leaves' box bounds may be infinite (read by :func:`_leaf_bounds`): a NaN
    threshold sends every vector right, a NaN coefficient predicts NaN, a NaN training
    range flags nothing as out of range; none of these may load silently.
    """

    def fail(field: str, value, expected: str, problem: str = "a field of the wrong type"):
        raise RepertoireError(
            f"action model '{path}' has {problem}: {field} is {repr(value)[:80]}; "
            f"expected {expected}"
        )

    def numbers(field: str, values, whole: bool = False) -> None:  # lengths: _check_structure
        ok = is_whole if whole else (lambda v: is_real(v) and math.isfinite(v))
        kind = "whole numbers" if whole else "finite numbers"
        if not isinstance(values, list):
            fail(field, values, f"a list of {kind}")
        for i, v in enumerate(values):
            if not ok(v):
                fail(f"{field}[{i}]", v, f"a {kind[:-1]}")

    names = data["feature_names"]
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        fail("'feature_names'", names, "a list of feature names (strings)")
    if len(set(names)) != len(names):
        fail("'feature_names'", names, "distinct names")
    for field in ("feature", "left", "right", "leaf_of_node"):
        numbers(f"'{field}'", data[field], whole=True)
    for field in ("threshold", "train_min", "train_max"):
        numbers(f"'{field}'", data[field])
    for j, seen in enumerate(zip(data["train_min"], data["train_max"])):
        if seen[0] > seen[1]:
            name = repr(names[j]) if j < len(names) else j
            fail(f"feature {name}", list(seen), "train_min <= train_max", "an empty training range")
    p = data["threshold_probability"]
    if not (is_real(p) and 0.0 <= p <= 1.0):
        fail("'threshold_probability'", p, "a number in [0, 1]")
    if not isinstance(data["leaves"], list):
        fail("'leaves'", data["leaves"], "a list of leaf records")
    for j, leaf in enumerate(data["leaves"]):
        if not isinstance(leaf, dict):
            fail(f"leaf {j}", leaf, "a record of lower, upper, coef, intercept, samples")
        if "coef" in leaf:
            numbers(f"leaf {j}'s 'coef'", leaf["coef"])
        if "intercept" in leaf and not (
            is_real(leaf["intercept"]) and math.isfinite(leaf["intercept"])
        ):
            fail(f"leaf {j}'s 'intercept'", leaf["intercept"], "a finite number")
        if "samples" in leaf and not is_whole(leaf["samples"]):
            fail(f"leaf {j}'s 'samples'", leaf["samples"], "a whole number")


def _check_structure(data: dict, path: Path) -> None:
    """Node indices, leaf indices and per-feature lengths consistent, or a named error.

    Children come after their parent (as scikit-learn numbers them), so prediction
    cannot loop.
    """
    n, k, d = len(data["feature"]), len(data["leaves"]), len(data["feature_names"])
    bad = []
    if n == 0 or k == 0:
        bad.append(f"{n} nodes and {k} leaves (at least one of each is needed)")
    for name in ("train_min", "train_max"):
        if len(data[name]) != d:
            bad.append(f"'{name}' has {len(data[name])} values for {d} features")
    for j, leaf in enumerate(data["leaves"]):
        sizes = {len(leaf.lower), len(leaf.upper), len(leaf.coef)}
        if sizes != {d}:
            bad.append(f"leaf {j} has lower/upper/coef of lengths {sorted(sizes)}, not {d}")
    for i in range(n):
        f, left, right, leaf = (
            data[key][i] for key in ("feature", "left", "right", "leaf_of_node")
        )
        split = f >= 0
        if split and not (f < d and i < left < n and i < right < n and leaf == -1):
            bad.append(f"split node {i} has feature {f}, children {left}, {right}, leaf {leaf}")
        if not split and not (0 <= leaf < k):
            bad.append(f"leaf node {i} points at leaf {leaf} of {k}")
    if bad:
        raise RepertoireError(f"action model '{path}' is inconsistent: {'; '.join(bad[:3])}")
