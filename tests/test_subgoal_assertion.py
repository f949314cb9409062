"""Subgoal assertion's optimisation core (section 7, Algorithms 3-4)."""

import numpy as np
import pytest
from repertoire.planning.subgoal_assertion import FailureClassifier, assert_subgoal

from repertoire.errors import RepertoireError


def leg_features(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance and the heading of the leg (non-affine features of 2-D points)."""
    d = b - a
    return np.column_stack([np.hypot(d[:, 0], d[:, 1]), np.arctan2(d[:, 1], d[:, 0])])


def leg_duration(features: np.ndarray) -> np.ndarray:
    return 1.0 + features[:, 0]  # 1 s per leg plus 1 s per metre


class ApproachFromLeft:
    """Success for legs of >= 0.5 m heading within 30 degrees of +x (from the left)."""

    def predict_success(self, features: np.ndarray) -> np.ndarray:
        return (np.abs(features[:, 1]) <= np.radians(30.0)) & (features[:, 0] >= 0.5)


class NeverSucceeds:
    def predict_success(self, features: np.ndarray) -> np.ndarray:
        return np.zeros(features.shape[0], dtype=bool)


BOUNDS = {"lower": np.array([-3.0, -3.0]), "upper": np.array([3.0, 3.0])}


def test_direct_leg_kept_when_predicted_to_succeed():
    result = assert_subgoal(
        np.array([-1.0, 0.1]), np.zeros(2), classifier=ApproachFromLeft(),
        leg_features=leg_features, leg_duration=leg_duration, seed=0, **BOUNDS,
    )  # fmt: skip
    assert isinstance(ApproachFromLeft(), FailureClassifier)
    assert not result.asserted and result.subgoal is None
    assert result.predicted_duration == pytest.approx(1.0 + np.hypot(1.0, 0.1))
    assert result.reason == "direct leg predicted to succeed"


def test_subgoal_inserted_in_success_region_and_near_optimal():
    start, goal = np.array([1.0, 0.0]), np.zeros(2)  # approaching from the right fails
    result = assert_subgoal(
        start, goal, classifier=ApproachFromLeft(), leg_features=leg_features,
        leg_duration=leg_duration, seed=4, **BOUNDS,
    )  # fmt: skip
    assert result.asserted
    last = leg_features(result.subgoal[None], goal[None])
    assert ApproachFromLeft().predict_success(last)[0]
    # closed form: 2 legs (2 s) + |start - s| + |s - goal| with s in the success region
    # (30-degree cone left of the goal, >= 0.5 m): s = 0.5 (-cos 30, +-sin 30)
    s = 0.5 * np.array([-np.cos(np.pi / 6), np.sin(np.pi / 6)])
    best = 2.0 + np.linalg.norm(start - s) + 0.5
    assert best <= result.predicted_duration <= best + 0.05
    assert np.linalg.norm(np.abs(result.subgoal) - np.abs(s)) < 0.1
    again = assert_subgoal(
        start, goal, classifier=ApproachFromLeft(), leg_features=leg_features,
        leg_duration=leg_duration, seed=4, **BOUNDS,
    )  # fmt: skip
    np.testing.assert_array_equal(again.subgoal, result.subgoal)


def test_allowed_rules_out_subgoals_besides_the_failure_model():
    start, goal = np.array([1.0, 0.0]), np.zeros(2)
    result = assert_subgoal(
        start, goal, classifier=ApproachFromLeft(), leg_features=leg_features,
        leg_duration=leg_duration, seed=4, allowed=lambda s: s[:, 1] <= -0.1, **BOUNDS,
    )  # fmt: skip
    assert result.asserted and result.subgoal[1] <= -0.1
    # the lower of the two mirror-image optima: s = 0.5 (-cos 30, -sin 30)
    s = 0.5 * np.array([-np.cos(np.pi / 6), -np.sin(np.pi / 6)])
    best = 2.0 + np.linalg.norm(start - s) + 0.5
    assert best <= result.predicted_duration <= best + 0.05
    none = assert_subgoal(
        start, goal, classifier=ApproachFromLeft(), leg_features=leg_features,
        leg_duration=leg_duration, seed=4, allowed=lambda s: s[:, 1] > 5.0, n_fallback=50,
        **BOUNDS,
    )  # fmt: skip
    assert not none.asserted and "keeping the plan unchanged" in none.reason


def test_every_candidate_failing_keeps_the_plan_and_says_so():
    result = assert_subgoal(
        np.array([1.0, 0.0]), np.zeros(2), classifier=NeverSucceeds(),
        leg_features=leg_features, leg_duration=leg_duration, seed=0, n_fallback=100, **BOUNDS,
    )  # fmt: skip
    assert not result.asserted and result.subgoal is None
    assert "predicts failure from every one of" in result.reason
    assert "keeping the plan unchanged" in result.reason
    assert result.predicted_duration == pytest.approx(2.0)


def test_bad_input():
    kw = dict(classifier=ApproachFromLeft(), leg_features=leg_features, leg_duration=leg_duration)
    with pytest.raises(RepertoireError, match="one shape"):
        assert_subgoal(np.zeros(3), np.zeros(2), seed=0, **kw, **BOUNDS)
    with pytest.raises(RepertoireError, match="empty subgoal ranges"):
        assert_subgoal(np.ones(2), np.zeros(2), seed=0, lower=np.ones(2), upper=np.zeros(2), **kw)
    with pytest.raises(RepertoireError, match="finite"):
        assert_subgoal(np.array([np.nan, 0.0]), np.zeros(2), seed=0, **kw, **BOUNDS)


class Answers:
    """A classifier answering with a fixed function of the features (bad on purpose)."""

    def __init__(self, answer) -> None:
        self.answer = answer

    def predict_success(self, features: np.ndarray) -> np.ndarray:
        return self.answer(features)


def test_callbacks_giving_other_than_one_answer_per_leg_are_named():
    # a NaN verdict read as success, a short one raised a bare numpy broadcast error, and a
    # single `allowed` verdict was broadcast over every candidate
    start, goal = np.array([1.0, 0.0]), np.zeros(2)
    kw = dict(leg_features=leg_features, leg_duration=leg_duration, seed=0, **BOUNDS)
    nan = Answers(lambda f: np.full(f.shape[0], np.nan))
    with pytest.raises(
        RepertoireError, match=r"predict_success gave \[nan\] .* expected 1 booleans"
    ):
        assert_subgoal(start, goal, classifier=nan, **kw)
    short = Answers(lambda f: np.zeros(3, dtype=bool))
    with pytest.raises(
        RepertoireError, match=r"gave \[False, False, False\] \(shape \(3,\)\) for 1"
    ):
        assert_subgoal(start, goal, classifier=short, **kw)
    with pytest.raises(
        RepertoireError, match=r"allowed gave \[True\] \(shape \(1,\)\) for 50 rows"
    ):
        assert_subgoal(start, goal, classifier=ApproachFromLeft(), allowed=lambda s: [True], **kw)
    with pytest.raises(RepertoireError, match=r"leg_features gave shape \(1, 2\) for 50 legs"):
        assert_subgoal(start, goal, classifier=ApproachFromLeft(), **{
            **kw, "leg_features": lambda a, b: leg_features(a[:1], b[:1])})  # fmt: skip
