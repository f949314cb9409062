"""Robustness round 4 of the action models, refinement and subgoal assertion.

Valid but unusual inputs and bad inputs a new user might give; each test pins a
defect found in that round.
"""

import dataclasses
import json

import numpy as np
import pytest
from repertoire.planning.action_models import (
    fit_action_model,
    fit_duration_tree,
    fit_failure_tree,
    load_model,
    save_model,
)
from repertoire.planning.black_box import GaOptions, solve_de, solve_ga
from repertoire.planning.refinement import (
    AffineFeatures,
    DurationTerm,
    PiecewiseLinearModel,
    RefinementProblem,
    refine_sequence,
)
from repertoire.planning.refinement_exact import solve_milp
from repertoire.planning.subgoal_assertion import assert_subgoal
from repertoire.planning.synthetic_models import chain_problem
from repertoire.systems.action_model_predictor import ActionModelPredictor
from repertoire.systems.plan_executor import PlanExecutor

from repertoire.errors import RepertoireError


@dataclasses.dataclass
class Rec:
    a: float
    b: float
    duration: float
    failed: bool
    status: str


def records(n: int = 30) -> list[Rec]:
    rng = np.random.default_rng(5)
    return [
        Rec(float(a), float(b), 1.0 + a, bool(a > 0.5), "SUCCEEDED")
        for a, b in rng.uniform(0, 1, (n, 2))
    ]


def xy(n: int = 40) -> tuple[np.ndarray, np.ndarray]:
    X = np.random.default_rng(1).uniform(0, 1, (n, 2))
    return X, 1.0 + X[:, 0]


def unit_model() -> PiecewiseLinearModel:
    return PiecewiseLinearModel([[0.0]], [[1.0]], [[1.0]], [0.0])


def test_ga_cost_is_the_models_prediction_at_its_parameters():
    # the batch's matrix product rounded differently from a single row: 4e-16 apart
    problem = chain_problem(11, 2, 2, 2, bound=1.3)
    result = solve_ga(problem, seed=11)
    assert result.cost == float(problem.cost(result.params)[0])


@pytest.mark.parametrize("seed", [-1, 2**40, 1.5, float("nan"), True])
def test_bad_seeds_are_named(seed):
    X, y = xy()
    calls = [
        lambda: fit_duration_tree(X, y, ["a", "b"], seed=seed),
        lambda: fit_failure_tree(X, y > 1.5, ["a", "b"], seed=seed),
        lambda: fit_action_model(records(), ["a", "b"], "duration", seed=seed),
        lambda: solve_ga(chain_problem(0, 2, 1, 1), seed=seed),
        lambda: solve_de(chain_problem(0, 2, 1, 1), seed=seed),
        lambda: assert_subgoal(
            np.zeros(2),
            np.ones(2),
            classifier=_Always(True),
            leg_features=lambda a, b: b - a,
            leg_duration=lambda f: f[:, 0],
            lower=np.zeros(2),
            upper=np.ones(2),
            seed=seed,
        ),  # fmt: skip
    ]
    for call in calls:
        with pytest.raises(RepertoireError, match="seed must be a whole number"):
            call()


@pytest.mark.parametrize("cost", ["3", None])
def test_failure_cost_not_a_number_is_named(cost):
    X, y = xy()
    with pytest.raises(RepertoireError, match="failure_cost must be finite"):
        fit_failure_tree(X, y > 1.5, ["a", "b"], failure_cost=cost)
    with pytest.raises(RepertoireError, match="failure_cost must be finite"):
        fit_action_model(records(), ["a", "b"], "failed", failure_cost=cost)


def test_fit_action_model_names_a_non_numeric_target_and_a_string_feature_list():
    with pytest.raises(RepertoireError, match="target field 'status' of record 0 is 'SUCCEEDED'"):
        fit_action_model(records(), ["a", "b"], "status")
    recs = records()
    recs[4] = dataclasses.replace(recs[4], duration=None)
    with pytest.raises(RepertoireError, match="target field 'duration' of record 4 is None"):
        fit_action_model(recs, ["a", "b"], "duration")
    with pytest.raises(RepertoireError, match="got the string 'ab'"):
        fit_action_model(records(), "ab", "duration")


def test_load_model_rejects_inconsistent_trees_without_hanging(tmp_path):
    X, y = xy()
    path = save_model(fit_duration_tree(X, y, ["a", "b"], candidate_leaves=(2,)), tmp_path / "m")
    good = json.loads(path.read_text())
    assert good["feature"][0] >= 0  # a split at the root

    def broken(**change):
        data = {**good, **change}
        (tmp_path / "bad.json").write_text(json.dumps(data))
        return tmp_path / "bad.json"

    cases = {
        "no leaves": dict(leaves=[], leaf_of_node=[-1, -1, -1]),
        "feature 5": dict(feature=[5, -1, -1]),
        "loop": dict(left=[0, -1, -1]),  # the root's left child is itself
        "train_min": dict(train_min=[0.0]),
        "leaf 7": dict(leaf_of_node=[-1, 7, 1]),
    }
    for change in cases.values():
        with pytest.raises(RepertoireError, match="is inconsistent"):
            load_model(broken(**change))
    with pytest.raises(RepertoireError, match="wrong type"):
        load_model(broken(feature=["x", -1, -1]))


def test_affine_features_must_match_the_models_feature_count():
    term = DurationTerm(unit_model(), AffineFeatures(np.ones((2, 1)), [0.0, 0.0]), name="t")
    with pytest.raises(RepertoireError, match="term 't': A has 2 rows"):
        RefinementProblem((term,), [0.0], [1.0])


def test_feature_maps_of_the_wrong_shape_are_named_by_every_black_box():
    term = DurationTerm(unit_model(), lambda p: np.atleast_2d(p)[:, 0], (0,), "flat")
    problem = RefinementProblem((term,), [0.0], [1.0])
    for solver in ("ga", "de"):  # de used to hide it in scipy's RuntimeError
        with pytest.raises(RepertoireError, match="term 'flat': its features"):
            refine_sequence(problem, 1, solver)
    with pytest.raises(RepertoireError, match=r"features must be \(n, 1\)"):
        unit_model().predict(np.zeros((2, 1, 1)))


def test_unknown_solver_options_and_bad_counts_are_named():
    problem = chain_problem(0, 2, 1, 1)
    with pytest.raises(RepertoireError, match=r"solver 'ga' has no options \['sed'\]"):
        refine_sequence(problem, 1, "ga", sed=1)
    with pytest.raises(RepertoireError, match=r"solver 'milp' has no options \['seed'\]"):
        refine_sequence(problem, 1, "milp", seed=1)
    with pytest.raises(RepertoireError, match="horizon True"):
        refine_sequence(problem, True)
    for kw in ({"maxiter": 0}, {"maxiter": -1}, {"popsize": 0}, {"popsize": float("nan")}):
        with pytest.raises(RepertoireError, match=f"{next(iter(kw))} must be a whole number"):
            solve_de(problem, **kw)
    for kw in ({"population_per_parameter": 2.5}, {"stagnation": "5"}, {"max_generations": 1e9}):
        with pytest.raises(RepertoireError, match="invalid GA options"):
            GaOptions(**kw)
    with pytest.raises(RepertoireError, match="max_rounds a whole number"):
        solve_milp(problem, max_rounds=1.5)
    for incumbent in ([0.0, 0.0], [np.nan], [50.0]):
        with pytest.raises(RepertoireError, match=r"incumbent must be \(1,\) parameters inside"):
            solve_milp(problem, incumbent=np.array(incumbent))


def test_from_dict_names_a_non_number():
    record = unit_model().to_dict()
    record["coef"] = [["x"]]
    with pytest.raises(RepertoireError, match="holds a non-number"):
        PiecewiseLinearModel.from_dict(record)


class _Always:
    def __init__(self, ok: bool):
        self.ok = ok

    def predict_success(self, features: np.ndarray) -> np.ndarray:
        return np.full(features.shape[0], self.ok)


def test_subgoal_assertion_names_nan_durations_and_bad_options():
    kw = dict(
        leg_features=lambda a, b: b - a, lower=np.zeros(2), upper=np.ones(2), seed=0
    )  # fmt: skip
    nan = lambda f: np.full(f.shape[0], np.nan)  # noqa: E731
    for ok in (True, False):  # the direct leg; every candidate (used to blame the failure model)
        with pytest.raises(RepertoireError, match="leg_duration gave NaN"):
            assert_subgoal(np.zeros(2), np.ones(2), classifier=_Always(ok), leg_duration=nan, **kw)
    dur = lambda f: f[:, 0]  # noqa: E731
    with pytest.raises(RepertoireError, match="n_fallback must be a whole number"):
        assert_subgoal(
            np.zeros(2), np.ones(2), classifier=_Always(False), leg_duration=dur, n_fallback=1.5,
            **kw,
        )  # fmt: skip
    with pytest.raises(RepertoireError, match="no predict_success"):
        assert_subgoal(np.zeros(2), np.ones(2), classifier=object(), leg_duration=dur, **kw)
    kw.update(lower=np.zeros(0), upper=np.zeros(0))
    with pytest.raises(RepertoireError, match=r"not empty\), got \(0,\)"):
        assert_subgoal(np.zeros(0), np.zeros(0), classifier=_Always(True), leg_duration=dur, **kw)


def test_predictor_num_parameters_and_executor_sizes():
    X, y = xy()
    duration = fit_duration_tree(X, y, ["a", "b"])
    failure = fit_failure_tree(X, y > 1.5, ["a", "b"])
    for n in (-1, 0, 2.0, True):  # -1 used to abort in std::bad_alloc
        with pytest.raises(RepertoireError, match="num_parameters must be a whole number"):
            ActionModelPredictor(duration, failure, n, features=lambda p: p[:2])
    predictor = ActionModelPredictor(duration, failure, np.int64(2))
    context = predictor.CreateDefaultContext()
    predictor.get_input_port(0).FixValue(context, [0.25, 0.5])
    out = predictor.GetOutputPort("duration").Eval(context)[0]
    assert out == duration.predict([[0.25, 0.5]])[0]
    executor = PlanExecutor([[0.0, 1.0]], command_size=np.int64(3), period=np.float64(0.05))
    assert (executor.command_size, executor.period) == (3, 0.05)
    with pytest.raises(RepertoireError, match="period must be finite and > 0, got 'a'"):
        PlanExecutor([[0.0]], period="a")


def test_mixed_bool_and_number_targets_and_float32_overflowing_features_are_named():
    recs = records()
    recs[7] = dataclasses.replace(recs[7], failed=1)  # a stray int among bools
    with pytest.raises(
        RepertoireError, match=r"'failed' mixes bools and numbers \(record 7 is 1\)"
    ):
        fit_action_model(recs, ["a", "b"], "failed")
    X, y = xy()
    X[3, 1] = 1e300
    with pytest.raises(RepertoireError, match=r"features \['b'\] exceed float32's range"):
        fit_duration_tree(X, y, ["a", "b"])
