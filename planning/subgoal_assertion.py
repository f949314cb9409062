"""Subgoal assertion's optimisation core (section 7 of Stulp & Beetz, JAIR 2008).

When the failure model predicts that going straight from ``start`` to ``goal`` fails
(the robot bumps the ball it approaches), an intermediate pose is inserted: the
subgoal minimises the predicted duration of start -> subgoal -> goal over the subgoals
from which the failure model predicts that the last leg succeeds (Algorithm 4: other
subgoals are INVALID). Features of poses are angles and distances, not affine, so the
paper's genetic algorithm does the search. If the failure model rejects every
candidate, the result says so and the plan is kept.
"""

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
from repertoire.planning.black_box import GaOptions, genetic_minimise

from repertoire.checks import check_seed, is_whole
from repertoire.errors import RepertoireError


@runtime_checkable
class FailureClassifier(Protocol):
    """What subgoal assertion needs from a failure model."""

    def predict_success(self, features: np.ndarray) -> np.ndarray:
        """(n, d) features -> (n,) booleans, True where success is predicted."""
        ...


LegFeatures = Callable[[np.ndarray, np.ndarray], np.ndarray]
"""(from states (n, s), to states (n, s)) -> (n, d) features of one goToPose leg."""

LegDuration = Callable[[np.ndarray], np.ndarray]
"""(n, d) features -> (n,) predicted durations of a leg (e.g. a model's ``predict``)."""


@dataclass(frozen=True)
class SubgoalAssertion:
    """The outcome of :func:`assert_subgoal`.

    Args:
        asserted: True if a subgoal was inserted.
        subgoal: (s,) the inserted intermediate state, or None.
        predicted_duration: predicted duration of the resulting plan (one or two legs),
            +inf if the kept plan's single leg is outside the duration model.
        reason: why (direct leg predicted to succeed; subgoal found; every candidate
            predicted to fail, plan kept).
        candidates: subgoals evaluated.
    """

    asserted: bool
    subgoal: np.ndarray | None
    predicted_duration: float
    reason: str
    candidates: int = 0


def assert_subgoal(
    start: np.ndarray,
    goal: np.ndarray,
    *,
    classifier: FailureClassifier,
    leg_features: LegFeatures,
    leg_duration: LegDuration,
    lower: np.ndarray,
    upper: np.ndarray,
    seed: int,
    options: GaOptions | None = None,
    n_fallback: int = 2000,
    allowed: Callable[[np.ndarray], np.ndarray] | None = None,
) -> SubgoalAssertion:
    """Inserts an intermediate state if the direct leg is predicted to fail.

    Args:
        start: (s,) the current state, e.g. [x, y, phi, v].
        goal: (s,) the target state.
        classifier: predicts success of a leg from its features.
        leg_features: features of legs from/to batches of states.
        leg_duration: predicted duration of legs from their features.
        lower: (s,) lower bounds of the subgoal (finite).
        upper: (s,) upper bounds of the subgoal (finite, >= lower).
        seed: seed of the genetic algorithm and of the fallback sample.
        options: GA settings (default: the paper's).
        n_fallback: seeded uniform candidates checked when the GA finds no valid one
            (a whole number >= 0).
        allowed: optional (n, s) subgoals -> (n,) booleans, False for subgoals ruled out
            besides the failure model (e.g. too close to the ball, where the failure
            model was never trained); those are INVALID too.

    Returns:
        The assertion; ``asserted`` is False both when no subgoal is needed and when the
        failure model rejects every candidate (``reason`` says which).

    Raises:
        RepertoireError: mismatched shapes, non-finite values, empty ranges, a bad seed,
            NaN leg durations, or leg features, a classifier or ``allowed`` giving other
            than one row / one boolean per leg.
    """
    start = np.asarray(start, dtype=float).reshape(-1)
    goal = np.asarray(goal, dtype=float).reshape(-1)
    lower = np.asarray(lower, dtype=float).reshape(-1)
    upper = np.asarray(upper, dtype=float).reshape(-1)
    if not (start.shape == goal.shape == lower.shape == upper.shape) or start.size == 0:
        raise RepertoireError(
            f"start, goal, lower, upper must have one shape (not empty), got {start.shape}, "
            f"{goal.shape}, {lower.shape}, {upper.shape}"
        )
    arrays = (start, goal, lower, upper)
    if not all(np.isfinite(a).all() for a in arrays):
        raise RepertoireError("start, goal and the subgoal bounds must be finite")
    if (lower > upper).any():
        raise RepertoireError(f"empty subgoal ranges at {np.flatnonzero(lower > upper)}")
    seed = check_seed(seed)
    if not is_whole(n_fallback) or n_fallback < 0:
        raise RepertoireError(f"n_fallback must be a whole number >= 0, got {n_fallback!r}")
    if not isinstance(classifier, FailureClassifier):
        raise RepertoireError(
            f"classifier {type(classifier).__name__} has no predict_success(features) method"
        )

    def features_of(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        f = np.asarray(leg_features(a, b), dtype=float)
        if f.ndim != 2 or f.shape[0] != a.shape[0]:
            raise RepertoireError(
                f"leg_features gave shape {f.shape} for {a.shape[0]} legs; expected "
                f"({a.shape[0]}, d), one row of features per leg"
            )
        return f

    def verdicts(name: str, fn, values: np.ndarray) -> np.ndarray:
        ok = np.asarray(fn(values)).reshape(-1)
        if ok.shape != (values.shape[0],) or not np.isin(ok, (0, 1)).all():
            raise RepertoireError(
                f"{name} gave {ok.tolist()[:6]!r} (shape {ok.shape}) for {values.shape[0]} "
                f"rows; expected {values.shape[0]} booleans"
            )
        return ok.astype(bool)

    def durations(features: np.ndarray) -> np.ndarray:
        t = np.asarray(leg_duration(features), dtype=float).reshape(-1)
        if np.isnan(t).any():
            raise RepertoireError(
                f"leg_duration gave NaN for the leg features {features[np.isnan(t)][0].tolist()}; "
                "expected durations (+inf where the duration model does not apply)"
            )
        return t

    direct = features_of(start[None], goal[None])
    if verdicts("classifier.predict_success", classifier.predict_success, direct)[0]:
        t = float(durations(direct)[0])
        return SubgoalAssertion(False, None, t, "direct leg predicted to succeed", 0)

    def cost(subgoals: np.ndarray) -> np.ndarray:
        n = subgoals.shape[0]
        first = features_of(np.repeat(start[None], n, axis=0), subgoals)
        last = features_of(subgoals, np.repeat(goal[None], n, axis=0))
        ok = verdicts("classifier.predict_success", classifier.predict_success, last)
        if allowed is not None:
            ok &= verdicts("allowed", allowed, subgoals)
        t = durations(first) + durations(last)
        return np.where(ok, t, np.inf)

    best, best_cost, evals, _ = genetic_minimise(cost, lower, upper, seed=seed, options=options)
    if not np.isfinite(best_cost) and n_fallback:
        sample = np.random.default_rng(seed).uniform(lower, upper, (n_fallback, lower.size))
        costs = cost(sample)
        evals += n_fallback
        i = int(np.argmin(costs))
        best, best_cost = sample[i], float(costs[i])
    if not np.isfinite(best_cost):
        kept = float(durations(direct)[0])
        return SubgoalAssertion(
            False,
            None,
            kept,
            f"the failure model predicts failure from every one of {evals} candidate "
            "subgoals; keeping the plan unchanged",
            evals,
        )
    return SubgoalAssertion(True, best, best_cost, "direct leg predicted to fail", evals)
