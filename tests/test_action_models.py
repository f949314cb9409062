import dataclasses
import json
import math

import numpy as np
import pytest
from repertoire.planning.action_models import (
    MIN_EPISODES,
    angle_at,
    angle_to,
    arm_reach_features,
    distance,
    fit_action_model,
    fit_duration_tree,
    fit_failure_tree,
    goto_pose_features,
    load_model,
    save_model,
    wrap_angle,
)

from repertoire.errors import RepertoireError


def test_features_by_hand():
    # robot at (1, 1) facing +y; goal at (4, 5) facing +x
    assert distance(1, 1, 4, 5) == pytest.approx(5.0)
    beta = math.atan2(4, 3)
    assert angle_to(1, 1, math.pi / 2, 4, 5) == pytest.approx(beta - math.pi / 2)
    assert angle_at(1, 1, 4, 5, 0.0) == pytest.approx(-beta)
    f = goto_pose_features([1, 1, math.pi / 2, 0.3], [4, 5, 0.0, 0.1], mirrored=False)
    np.testing.assert_allclose(f, [5.0, beta - math.pi / 2, -beta, 0.3, 0.1])
    # Table 7: angle_to = |angle_to_signed|, angle_at times sgn(angle_to_signed) (here -1)
    f = goto_pose_features([1, 1, math.pi / 2, 0.3], [4, 5, 0.0, 0.1])
    np.testing.assert_allclose(f, [5.0, math.pi / 2 - beta, beta, 0.3, 0.1])
    # the mirror image (y -> -y, angles negated) has the same features
    mirror = goto_pose_features([1, -1, -math.pi / 2, 0.3], [4, -5, 0.0, 0.1])
    np.testing.assert_allclose(mirror, f)
    # straight ahead (angle_to_signed = 0): sgn counts as +1
    np.testing.assert_allclose(goto_pose_features([0, 0, 0, 0], [2, 0, 0.5, 0])[1:3], [0, 0.5])
    # wrapping: facing -x, goal slightly below +x: turn by pi - 0.01 (not -pi - 0.01)
    assert angle_to(0, 0, math.pi, 1, -0.01) == pytest.approx(
        math.pi - math.atan2(0.01, 1), abs=1e-9
    )
    assert wrap_angle(3 * math.pi) == pytest.approx(math.pi)
    assert wrap_angle(-math.pi) == pytest.approx(math.pi)


def test_mirrored_and_unmirrored_columns_have_different_names():
    from repertoire.planning.action_models import (
        DRIBBLE_FEATURES,
        GOTO_POSE_FEATURES,
        UNMIRRORED_GOTO_POSE_FEATURES,
        goto_pose_feature_names,
    )

    assert goto_pose_feature_names() == GOTO_POSE_FEATURES == DRIBBLE_FEATURES
    assert GOTO_POSE_FEATURES == ("dist", "angle_to", "angle_at", "v", "v_g")
    assert goto_pose_feature_names(mirrored=False) == UNMIRRORED_GOTO_POSE_FEATURES
    assert UNMIRRORED_GOTO_POSE_FEATURES == (
        "dist", "angle_to_unmirrored", "angle_at_unmirrored", "v", "v_g"
    )  # fmt: skip


def test_features_batched_and_bad():
    s = np.array([[0, 0, 0, 0], [1, 0, 0, 0.5]])
    g = np.array([[1, 0, 0, 0], [1, 2, 0, 0]])
    f = goto_pose_features(s, g)
    np.testing.assert_allclose(f[:, 0], [1, 2])
    np.testing.assert_allclose(f[:, 1], [0, math.pi / 2])
    with pytest.raises(RepertoireError, match="finite"):
        goto_pose_features([0, 0, np.nan, 0], [1, 0, 0, 0])
    with pytest.raises(RepertoireError, match="4 values"):
        goto_pose_features([0, 0, 0], [1, 0, 0, 0])
    # one goal for many starts broadcasts; 3 starts for 2 goals, or a 3-D batch, is named
    np.testing.assert_array_equal(goto_pose_features(s, g[1]), goto_pose_features(s, g[[1, 1]]))
    with pytest.raises(RepertoireError, match="3 starts and 2 goals"):
        goto_pose_features(np.zeros((3, 4)), g)
    with pytest.raises(RepertoireError, match=r"got shapes \(2, 2, 4\)"):
        goto_pose_features(np.zeros((2, 2, 4)), np.ones((2, 2, 4)))
    with pytest.raises(RepertoireError, match="3 starts and 2 goals"):
        arm_reach_features(np.zeros((3, 4)), g)


def _piecewise(n=800, seed=0):
    rng = np.random.default_rng(seed)
    X = rng.uniform(-1, 1, (n, 2))
    y = np.where(X[:, 0] > 0, 4 + 3 * X[:, 1], 1 - X[:, 1])  # durations: 0 to 7 s
    return X, y


def test_duration_tree_recovers_linear_pieces_and_boxes():
    X, y = _piecewise()
    m = fit_duration_tree(X, y, ["a", "b"])
    assert len(m.leaves) >= 2
    # most predictions exact (only the leaf straddling a = 0 mixes the pieces)
    err = np.abs(m.predict(X) - y)
    assert np.median(err) < 1e-6
    # leaf boxes partition the space: each point lies in exactly its leaf's box
    idx = m.leaf_index(X)
    for i in range(0, len(X), 37):
        leaf = m.leaves[idx[i]]
        assert np.all(np.array(leaf.lower) < X[i]) and np.all(X[i] <= np.array(leaf.upper))
        assert np.dot(leaf.coef, X[i]) + leaf.intercept == pytest.approx(m.predict(X[i])[0])
    assert "duration =" in m.rules()


def test_single_linear_target_gives_one_exact_leaf():
    rng = np.random.default_rng(1)
    X = rng.uniform(0, 1, (100, 3))
    y = 2.5 + X @ [1.0, -2.0, 0.25]
    m = fit_duration_tree(X, y, ["a", "b", "c"])
    np.testing.assert_allclose(m.predict(X), y, atol=1e-5)
    np.testing.assert_allclose(m.leaves[0].coef, [1.0, -2.0, 0.25], atol=1e-4)


def test_failure_tree_is_pessimistic():
    rng = np.random.default_rng(2)
    X = rng.uniform(-1, 1, (1000, 2))
    p_fail = np.clip(X[:, 0] + 0.5, 0, 1) * 0.6
    failed = rng.uniform(size=1000) < p_fail
    neutral = fit_failure_tree(X, failed, ["a", "b"], failure_cost=1.0)
    pessimist = fit_failure_tree(X, failed, ["a", "b"], failure_cost=5.0)
    assert pessimist.threshold_probability == pytest.approx(1 / 6)
    missed_n = np.sum(failed & ~neutral.predict_failure(X))
    missed_p = np.sum(failed & ~pessimist.predict_failure(X))
    assert missed_p < missed_n
    assert pessimist.predict_failure(X).sum() > neutral.predict_failure(X).sum()


def test_json_round_trip_and_bad_files(tmp_path):
    X, y = _piecewise(200)
    m = fit_duration_tree(X, y, ["a", "b"])
    p = save_model(m, tmp_path / "m.json")
    m2 = load_model(p)
    np.testing.assert_array_equal(m2.predict(X), m.predict(X))
    assert m2.rules() == m.rules()
    data = json.loads(p.read_text())
    data["version"] = 99
    (tmp_path / "v.json").write_text(json.dumps(data))
    with pytest.raises(RepertoireError, match="version 99"):
        load_model(tmp_path / "v.json")
    data = json.loads(p.read_text())
    del data["leaves"]
    (tmp_path / "f.json").write_text(json.dumps(data))
    with pytest.raises(RepertoireError, match="lacks fields.*leaves"):
        load_model(tmp_path / "f.json")
    with pytest.raises(RepertoireError, match="cannot read"):
        load_model(tmp_path / "missing.json")


@pytest.mark.parametrize(
    "change,message",
    [
        (lambda d: d.__setitem__("feature_names", 5), "'feature_names' is 5; expected a list"),
        (lambda d: d.__setitem__("feature_names", ["a", "a"]), "expected distinct names"),
        (lambda d: d.__setitem__("train_min", ["x", 0.0]), r"'train_min'\[0\] is 'x'"),
        (lambda d: d.__setitem__("train_max", [math.nan, 1.0]), r"'train_max'\[0\] is nan"),
        (
            lambda d: d.__setitem__("train_min", [9.0, 0.0]),
            "empty training range: feature 'a' is \\[9.0",
        ),
        (lambda d: d.__setitem__("threshold", [math.nan] * 3), r"'threshold'\[0\] is nan"),
        (lambda d: d.__setitem__("left", [None] * 3), r"'left'\[0\] is None"),
        (lambda d: d.__setitem__("feature", [0.5] * 3), r"'feature'\[0\] is 0.5"),
        (lambda d: d.__setitem__("threshold_probability", "x"), "'threshold_probability' is"),
        (lambda d: d["leaves"][1].__setitem__("coef", [math.nan, 0]), r"leaf 1's 'coef'\[0\]"),
        (lambda d: d["leaves"][0].__setitem__("intercept", None), "leaf 0's 'intercept' is None"),
        (lambda d: d["leaves"][0].__setitem__("samples", "x"), "leaf 0's 'samples' is 'x'"),
        (lambda d: d.__setitem__("leaves", 3), "'leaves' is 3; expected a list"),
    ],
)
def test_model_file_with_wrong_fields_is_refused_naming_field_and_value(tmp_path, change, message):
    # each of these used to load (NaN thresholds, coefficients, training ranges: silent
    # wrong predictions) or fail with a bare conversion error naming neither
    X = np.column_stack([np.linspace(0, 1, 40), np.tile([0.0, 1.0], 20)])
    m = fit_duration_tree(X, np.where(X[:, 0] > 0.5, 2.0, 1.0), ["a", "b"], candidate_leaves=(2,))
    assert len(m.feature) == 3
    data = json.loads(save_model(m, tmp_path / "m.json").read_text())
    change(data)
    (tmp_path / "bad.json").write_text(json.dumps(data))
    with pytest.raises(RepertoireError, match=f"bad.json'.*{message}"):
        load_model(tmp_path / "bad.json")


def test_saved_model_is_standard_json_and_old_infinity_files_load(tmp_path):
    # JSON has no infinity: the unbounded faces are "inf"/"-inf" strings, which a strict
    # reader accepts; files written with Python's Infinity token still load
    X, y = _piecewise(200)
    m = fit_duration_tree(X, y, ["a", "b"])
    assert any(math.isinf(v) for leaf in m.leaves for v in leaf.lower + leaf.upper)
    p = save_model(m, tmp_path / "m.json")

    def refuse(token):
        raise AssertionError(f"non-standard JSON token {token}")

    data = json.loads(p.read_text(), parse_constant=refuse)
    assert "-inf" in data["leaves"][0]["lower"]
    m2 = load_model(p)
    assert m2 == m
    old = tmp_path / "old.json"
    old.write_text(json.dumps(dataclasses.asdict(m), allow_nan=True))
    assert "Infinity" in old.read_text() and load_model(old) == m
    data["leaves"][0]["lower"][0] = "minus infinity"
    (tmp_path / "b.json").write_text(json.dumps(data))
    with pytest.raises(RepertoireError, match="leaf bound 'minus infinity'"):
        load_model(tmp_path / "b.json")


def test_out_of_range_flag_and_nan():
    X, y = _piecewise(200)
    m = fit_duration_tree(X, y, ["a", "b"])
    flags = m.out_of_range([[0.0, 0.0], [2.0, 0.0], [0.0, -1.5]])
    assert flags.tolist() == [False, True, True]
    # only the named features (those a refinement's free parameters drive)
    assert m.out_of_range([[0.0, 0.0], [2.0, 0.0], [0.0, -1.5]], ["b"]).tolist() == [0, 0, 1]
    assert m.out_of_range([[2.0, 0.0]], "a").tolist() == [True]
    assert m.out_of_range([[2.0, 0.0]], []).tolist() == [False]
    with pytest.raises(RepertoireError, match=r"features \['c'\] are not the model's"):
        m.out_of_range([[0.0, 0.0]], ["a", "c"])
    with pytest.raises(RepertoireError, match=r"\['b'\].*NaN"):
        m.predict([[0.0, np.nan]])
    with pytest.raises(RepertoireError, match=r"features must be numbers, rows of \['a', 'b'\]"):
        m.predict([0.5, "x"])


def test_a_negative_or_nan_duration_is_refused_naming_its_row():
    # durations are never negative: a negative one was fitted, the leaf's clamp took it as
    # its floor, and the tree predicted negative durations (down to the least one seen)
    X, y = _piecewise(100)
    y[[7, 40]] = [-0.25, -1.5]
    with pytest.raises(
        RepertoireError, match=r"2 of 100 durations are negative \(the least: row 40, -1\.5\); a"
    ):
        fit_duration_tree(X, y, ["a", "b"])
    signed = fit_duration_tree(X, y, ["a", "b"], nonnegative=False)  # a signed target
    assert min(leaf.target_min for leaf in signed.leaves) == -1.5
    y[[7, 40]] = [np.nan, np.inf]
    with pytest.raises(
        RepertoireError, match=r"2 of 100 targets are NaN or inf \(the first: row 7, nan"
    ):
        fit_duration_tree(X, y, ["a", "b"], nonnegative=False)
    with pytest.raises(RepertoireError, match="nonnegative must be True or False, got 'no'"):
        fit_duration_tree(X, np.abs(y), ["a", "b"], nonnegative="no")
    # fit_action_model names the record and the field, before the shuffled split
    recs = [_Rec(a, b, 1.0 + a, False) for a, b in X]
    recs[12].t = -0.5
    with pytest.raises(
        RepertoireError, match=r"1 of 100 durations are negative \(the least: 't' of record 12"
    ):
        fit_action_model(recs, ["a", "b"], "t")
    fitted = fit_action_model(recs, ["a", "b"], "t", nonnegative=False)
    assert fitted.model.kind == "duration" and (fitted.n_train, fitted.n_test) == (75, 25)
    # with non-negative durations every leaf's floor, and so every prediction, is >= 0
    m = fit_duration_tree(X, np.abs(np.nan_to_num(y)), ["a", "b"])
    assert min(leaf.target_min for leaf in m.leaves) >= 0.0
    far = np.random.default_rng(1).uniform(-50, 50, (20_000, 2))
    assert m.predict(far).min() >= 0.0


def test_too_few_episodes_and_nan_training():
    for empty in ([], np.zeros((0, 2))):  # [] was "need X of shape (n, 2)... got (0,)"
        with pytest.raises(RepertoireError, match=r"no training episodes \(X of shape \(0"):
            fit_duration_tree(empty, [], ["a", "b"])
        with pytest.raises(RepertoireError, match="no training episodes"):
            fit_failure_tree(empty, [], ["a", "b"])
    X, y = _piecewise(MIN_EPISODES - 1)
    with pytest.raises(RepertoireError, match=f"at least {MIN_EPISODES}"):
        fit_duration_tree(X, y, ["a", "b"])
    X, y = _piecewise(100)
    X[3, 1] = np.nan
    with pytest.raises(RepertoireError, match=r"\['b'\]"):
        fit_duration_tree(X, y, ["a", "b"])


def test_bad_fit_options_name_the_value():
    X, y = _piecewise(100)
    failed = y > np.median(y)
    cases = [
        (lambda: fit_duration_tree(X, y, ["a", "b"], ridge=-1.0), r"ridge .*>= 0, got -1\.0"),
        (lambda: fit_duration_tree(X, y, ["a", "b"], ridge=np.nan), r"ridge .*got nan"),
        (lambda: fit_duration_tree(X, y, ["a", "b"], min_samples_leaf=-3), "min_samples_leaf.* -3"),
        (lambda: fit_duration_tree(X, y, ["a", "b"], min_samples_leaf=0), "min_samples_leaf.* 0"),
        (lambda: fit_duration_tree(X, y, ["a", "b"], min_samples_leaf=2.5), "min_samples_l.* 2.5"),
        (lambda: fit_duration_tree(X, y, ["a", "b"], candidate_leaves=(2, 0)), "candidate.* 0"),
        (lambda: fit_duration_tree(X, y, ["a", "b"], candidate_leaves=()), "candidate_leaves"),
        (lambda: fit_duration_tree(X, y[:, None], ["a", "b"]), r"y of shape \(n,\).*\(100, 1\)"),
        (
            lambda: fit_failure_tree(X, failed, ["a", "b"], min_samples_leaf=0),
            "min_samples_leaf.* 0",
        ),
        (lambda: fit_failure_tree(X, failed, ["a", "b"], max_leaf_nodes=1), "max_leaf_nodes.* 1"),
        (lambda: fit_failure_tree(X, failed[:, None], ["a", "b"]), r"\(100, 1\)"),
        # a string is not a list of names ("ab" once fitted features named 'a' and 'b')
        (lambda: fit_duration_tree(X, y, "ab"), "the string 'ab'; write \\['ab'\\]"),
        (lambda: fit_failure_tree(X, failed, ["a", "a"]), r"distinct strings.*\['a', 'a'\]"),
        (lambda: fit_duration_tree(X, y, ["a", 3]), r"distinct strings.*\['a', 3\]"),
        (lambda: fit_duration_tree([[1.0, 2.0], [3.0]], [1, 2], ["a", "b"]), "rows of equal"),
    ]
    for fit, message in cases:
        with pytest.raises(RepertoireError, match=message):
            fit()


def test_ridge_zero_is_least_squares_even_with_a_constant_feature():
    rng = np.random.default_rng(0)
    X = np.column_stack([rng.uniform(0, 1, 100), np.ones(100)])
    y = 1.0 + 2.0 * X[:, 0]
    m = fit_duration_tree(X, y, ["a", "const"], ridge=0.0, candidate_leaves=(1,))
    assert len(m.leaves) == 1
    # minimum-norm least squares: the constant column gets no weight, the fit is exact
    np.testing.assert_allclose(m.leaves[0].coef, [2.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(m.predict(X), y, atol=1e-12)


class _Rec:
    def __init__(self, a, b, t, ok):
        self.a, self.b, self.t, self.ok = a, b, t, ok


def test_fit_action_model_generic():
    rng = np.random.default_rng(3)
    recs = []
    for _ in range(400):
        a, b = rng.uniform(-1, 1, 2)
        recs.append(_Rec(a, b, 3 + 2 * a + 0.5 * b, bool(a > 0.6)))
    dur = fit_action_model(recs, ["a", "b"], "t")
    assert dur.n_train == 300 and dur.n_test == 100
    assert dur.mae < 1e-4
    fail = fit_action_model(recs, {"a": lambda r: r.a, "b2": lambda r: 2 * r.b}, "ok")
    assert fail.model.kind == "failure"
    assert fail.accuracy > 0.9
    assert sum(map(sum, fail.confusion)) == 100
    with pytest.raises(RepertoireError, match="at least 20"):
        fit_action_model(recs[:10], ["a"], "t")
    with pytest.raises(RepertoireError, match="no target field 'zz'"):
        fit_action_model(recs, ["a"], "zz")
    with pytest.raises(RepertoireError, match="gives no feature"):
        fit_action_model(recs, ["nope"], "t")


def test_prediction_throughput_is_batched():
    # Exactness of batched vs one-at-a-time prediction (speed is measured in the benchmark).
    X, y = _piecewise(400)
    m = fit_duration_tree(X, y, ["a", "b"])
    batch = m.predict(X)
    single = np.array([m.predict(x)[0] for x in X[:50]])
    np.testing.assert_array_equal(batch[:50], single)


def _triangle(n: int = 200):
    """Episodes only where a + b <= 1; y = 5 - 4a - 4b, so the linear leaf gives -3 at (1, 1)."""
    rng = np.random.default_rng(2)
    X = rng.uniform(0, 1, (4 * n, 2))
    X = X[X.sum(axis=1) <= 1][:n]
    return X, 5.0 - 4.0 * X[:, 0] - 4.0 * X[:, 1]


def test_duration_leaves_are_clamped_to_their_episodes_durations():
    # a linear leaf extrapolating into its box's empty corner predicted a negative duration
    X, y = _triangle()
    m = fit_duration_tree(X, y, ["a", "b"], candidate_leaves=(1,))
    (leaf,) = m.leaves
    assert (leaf.target_min, leaf.target_max) == (y.min(), y.max())
    np.testing.assert_allclose(leaf.coef, [-4.0, -4.0], atol=1e-6)
    corner = [m.train_max, [0.9, 0.8], [0.1, 0.1], [0.25, 0.25]]  # (0.96, 0.94) first
    assert not m.out_of_range(corner).any()  # all inside the training box
    linear = 5.0 - 4.0 * np.sum(corner, axis=1)  # about -2.6, -1.8, 4.2, 3
    np.testing.assert_allclose(m.predict(corner), np.clip(linear, y.min(), y.max()), atol=1e-6)
    assert m.predict(corner)[0] == y.min() > 0 > linear[0]
    assert "within [" in m.rules()
    # the refinement's view of the tree clamps the same way
    from repertoire.planning.refinement import PiecewiseLinearModel

    pl = PiecewiseLinearModel.from_leaves(m.leaves)
    assert pl.clamped and pl.predict(np.array(corner)).tolist() == m.predict(corner).tolist()
    back = PiecewiseLinearModel.from_dict(json.loads(json.dumps(pl.to_dict())))
    assert back.predict(np.array(corner)).tolist() == m.predict(corner).tolist()


def test_clamps_round_trip_and_version_1_files_get_the_zero_floor(tmp_path):
    X, y = _triangle()
    m = fit_duration_tree(X, y, ["a", "b"], candidate_leaves=(1,))
    assert load_model(save_model(m, tmp_path / "m.json")) == m
    data = dataclasses.asdict(m)
    data["version"] = 1  # written before the clamps: no target_min / target_max
    for leaf in data["leaves"]:
        del leaf["target_min"], leaf["target_max"]
        leaf["intercept"] -= 4.0  # a leaf that predicts -7 s at (1, 1)
        leaf["lower"], leaf["upper"] = ["-inf"] * 2, ["inf"] * 2
    (tmp_path / "v1.json").write_text(json.dumps(data))
    old = load_model(tmp_path / "v1.json")
    assert (old.leaves[0].target_min, old.leaves[0].target_max) == (0.0, math.inf)
    np.testing.assert_allclose(old.predict([[1.0, 1.0], [0.0, 0.0]]), [0.0, 1.0], atol=1e-6)
    data["version"] = 2
    data["leaves"][0] |= {"target_min": 3.0, "target_max": 2.0}
    (tmp_path / "bad.json").write_text(json.dumps(data))
    with pytest.raises(RepertoireError, match="target_min 3.0 > target_max 2.0"):
        load_model(tmp_path / "bad.json")


def test_shipped_duration_trees_never_predict_a_negative_duration():
    # the shipped dribble tree's leaf 7 (angle_at slope -11) went to -0.44 s inside its box
    from importlib.resources import files

    folder = files("repertoire.models.diffdrive")
    for name in (
        "soccer_plan_models/dribble_duration.json",
        "kitchen_plan_models/reach_duration.json",
    ):
        m = load_model(str(folder / name))
        X = np.random.default_rng(0).uniform(m.train_min, m.train_max, (200_000, len(m.train_min)))
        assert m.predict(X).min() >= 0.0
