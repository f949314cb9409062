"""Refinement inside the models' data: ``DurationTerm(domain=...)`` against closed forms."""

import numpy as np
import pytest
from repertoire.planning.action_models.features import wrap_angle
from repertoire.planning.action_models.trees import fit_duration_tree
from repertoire.planning.refinement import (
    AffineFeatures,
    DurationTerm,
    PiecewiseLinearModel,
    RefinementProblem,
    refine_sequence,
)

from repertoire.errors import RepertoireError

# one unbounded leaf: duration = 5 - f, falling towards large f (the optimum on a face)
FALLING = PiecewiseLinearModel([[-np.inf]], [[np.inf]], [[-1.0]], [5.0])
SOLVERS = [("corners", {}), ("milp", {}), ("ga", {"seed": 0}), ("de", {"seed": 0})]


@pytest.mark.parametrize("solver,options", SOLVERS)
def test_optimum_stays_in_the_training_range(solver, options):
    # p in [0, 10], f = p; the data saw f in [0, 2]: unconstrained the optimum is p = 10
    # (cost -5, an extrapolation), inside the data p = 2 (cost 3)
    free = RefinementProblem((DurationTerm(FALLING, AffineFeatures([[1.0]], [0.0])),), [0], [10])
    assert refine_sequence(free, 1, solver, **options).params[0] == pytest.approx(10, abs=1e-3)
    term = DurationTerm(FALLING, AffineFeatures([[1.0]], [0.0]), domain=([0.0], [2.0]))
    result = refine_sequence(RefinementProblem((term,), [0], [10]), 1, solver, **options)
    assert 0.0 <= result.params[0] <= 2.0
    assert result.params[0] == pytest.approx(2.0, abs=1e-3)
    assert result.cost == pytest.approx(3.0, abs=1e-3)


def test_domain_bounds_are_closed_and_the_inside_is_unchanged():
    model = PiecewiseLinearModel([[-np.inf], [1.0]], [[1.0], [np.inf]], [[1.0], [-1.0]], [0, 3])
    term = DurationTerm(model, AffineFeatures([[1.0]], [0.0]), domain=([0.5], [2.0]))
    f = np.array([[0.5], [0.75], [1.0], [1.5], [2.0]])
    np.testing.assert_array_equal(term.predict(f), model.predict(f))  # both ends included
    outside = np.array([[np.nextafter(0.5, 0.0)], [np.nextafter(2.0, 3.0)], [5.0]])
    np.testing.assert_array_equal(term.predict(outside), np.inf)
    np.testing.assert_allclose(term.predict(outside, within_domain=False), [0.5, 1.0, -2.0])
    assert term.searched_model.n_leaves == 2


def test_features_the_parameters_cannot_change_are_not_constrained():
    # f0 = p driven, f1 = 7 bound (a start the data never saw): only f0 is kept inside
    model = PiecewiseLinearModel([[-np.inf, -np.inf]], [[np.inf, np.inf]], [[-1.0, 0.5]], [5.0])
    term = DurationTerm(
        model, AffineFeatures([[1.0], [0.0]], [0.0, 7.0]), domain=([0.0, 0.0], [2.0, 1.0])
    )
    assert term.feature_uses == ((0,), ())
    result = refine_sequence(RefinementProblem((term,), [0], [10]), 1)
    assert result.params[0] == 2.0 and result.cost == pytest.approx(5 - 2 + 3.5)


@pytest.mark.parametrize("solver", ["ga", "de"])
def test_wrapped_angle_excludes_the_arc_outside_the_data(solver):
    # angle_at = wrap(phi - beta), seen in [-2.99, 3.07]; duration 1 - 0.05 angle_at falls
    # towards pi. With beta = 1 the headings outside the data are the arc
    # phi in (1 + 3.07 - 2 pi, 1 - 2.99) = (-2.213, -1.990), inside [-pi, pi]: no bound
    # on phi excludes it, the domain does. Optimum: angle_at = 3.07, phi = 4.07 - 2 pi.
    beta, lo, hi = 1.0, -2.99, 3.07
    model = PiecewiseLinearModel([[-np.inf]], [[np.inf]], [[-0.05]], [1.0])

    def features(p):
        return wrap_angle(p[:, :1] - beta)

    free = RefinementProblem((DurationTerm(model, features, (0,)),), [-np.pi], [np.pi])
    unconstrained = refine_sequence(free, 1, solver, seed=0)
    assert features(unconstrained.params[None])[0, 0] > hi  # the optimiser extrapolates
    term = DurationTerm(model, features, (0,), domain=([lo], [hi]), feature_uses=((0,),))
    result = refine_sequence(RefinementProblem((term,), [-np.pi], [np.pi]), 1, solver, seed=0)
    angle = features(result.params[None])[0, 0]
    assert lo <= angle <= hi
    assert not 1 + hi - 2 * np.pi < result.params[0] < 1 + lo
    assert angle == pytest.approx(hi, abs=2e-3)
    assert result.cost == pytest.approx(1 - 0.05 * hi, abs=1e-4)


def test_a_feature_fixed_by_an_earlier_step_no_longer_constrains():
    # term 0: 5 - p0, data f in [0, 2]; term 1: 2 f0 + 3 - f1 with f = (p0, p1), data in
    # [0, 1]^2. Greedy (h = 1) fixes p0 = 2 for term 0 alone, outside term 1's data; step 2
    # still chooses p1 = 1 (term 1's f0 is no longer driven). h = 2 keeps both inside.
    t0 = DurationTerm(FALLING, AffineFeatures([[1.0, 0.0]], [0.0]), domain=([0.0], [2.0]))
    m1 = PiecewiseLinearModel([[-np.inf, -np.inf]], [[np.inf, np.inf]], [[2.0, -1.0]], [3.0])
    t1 = DurationTerm(m1, AffineFeatures(np.eye(2), [0.0, 0.0]), domain=([0, 0], [1, 1]))
    problem = RefinementProblem((t0, t1), [0, 0], [3, 3])
    greedy = refine_sequence(problem, 1)
    np.testing.assert_array_equal(greedy.params, [2.0, 1.0])
    assert greedy.cost == pytest.approx(3.0 + 4.0 + 2.0)  # the models' (extrapolated) sum
    assert problem.cost(greedy.params)[0] == np.inf  # term 1 reads p0 = 2 outside its data
    assert problem.cost(greedy.params, within_domain=False)[0] == pytest.approx(greedy.cost)
    refined = refine_sequence(problem, 2)
    np.testing.assert_array_equal(refined.params, [0.0, 1.0])
    assert refined.cost == pytest.approx(5.0 + 2.0)


def test_a_domain_no_parameter_reaches_gives_infinite_cost():
    # f = p + 5 with p in [0, 1]: the data's f in [0, 2] is out of reach; like an all-INVALID
    # plan, the result says so (+inf) instead of returning arbitrary parameters' extrapolation
    term = DurationTerm(FALLING, AffineFeatures([[1.0]], [5.0]), domain=([0.0], [2.0]))
    problem = RefinementProblem((term,), [0], [1])
    for solver in ("ga", "de"):
        assert refine_sequence(problem, 1, solver, seed=0).cost == np.inf
    with pytest.raises(RepertoireError, match="no leaf of its model covers .* domains"):
        refine_sequence(problem, 1, "corners")
    with pytest.raises(
        RepertoireError, match=r"outside the models' leaves \(or the terms' domains"
    ):
        refine_sequence(problem, 1, "milp")


def test_fitted_tree_optimum_stays_in_its_training_range():
    # a tree fitted on y = 3 - 2 x, x in [0.2, 0.9]; searched over [0, 2] the optimum is the
    # largest x it saw (its linear leaf extrapolates below every duration it saw beyond)
    rng = np.random.default_rng(0)
    x = rng.uniform(0.2, 0.9, 200)
    tree = fit_duration_tree(x[:, None], 3 - 2 * x, ["x"], seed=0)
    model = PiecewiseLinearModel.from_leaves(tree.leaves)
    box = (tree.train_min, tree.train_max)
    for solver in ("ga", "de"):
        term = DurationTerm(model, lambda p: p[:, :1], (0,), domain=box, feature_uses=((0,),))
        result = refine_sequence(RefinementProblem((term,), [0], [2]), 1, solver, seed=1)
        assert tree.train_min[0] <= result.params[0] <= tree.train_max[0]
        assert result.params[0] == pytest.approx(tree.train_max[0], abs=1e-3)
        assert not tree.out_of_range(result.params[None])[0]


def test_bad_domains_are_named():
    affine = AffineFeatures([[1.0]], [0.0])
    with pytest.raises(RepertoireError, match="1 numbers each .* got 2 and 1"):
        DurationTerm(FALLING, affine, domain=([0.0, 1.0], [2.0]))
    with pytest.raises(RepertoireError, match=r"lower \[nan\]"):
        DurationTerm(FALLING, affine, domain=([np.nan], [2.0]))
    with pytest.raises(RepertoireError, match=r"lower \[3.0\] and upper \[2.0\]"):
        DurationTerm(FALLING, affine, domain=([3.0], [2.0]))
    with pytest.raises(RepertoireError, match="domain must be"):
        DurationTerm(FALLING, affine, domain=5.0)
    with pytest.raises(RepertoireError, match="a domain needs `feature_uses`"):
        DurationTerm(FALLING, np.cos, (0,), domain=([0.0], [1.0]))
    with pytest.raises(RepertoireError, match=r"reads parameters \[3\], which are not"):
        DurationTerm(FALLING, np.cos, (0,), domain=([0.0], [1.0]), feature_uses=((3,),))
    with pytest.raises(RepertoireError, match="feature_uses has 2 entries"):
        DurationTerm(FALLING, np.cos, (0,), domain=([0.0], [1.0]), feature_uses=((0,), ()))
    with pytest.raises(RepertoireError, match=r"feature_uses \(\(\),\) differs from what A"):
        DurationTerm(FALLING, affine, domain=([0.0], [1.0]), feature_uses=((),))
    problem = RefinementProblem((DurationTerm(FALLING, affine),), [0.0], [1.0])
    with pytest.raises(RepertoireError, match=r"must be \(n, 1\) for this problem, got shape"):
        problem.cost([[0.1, 0.2]])  # was a bare matmul error
    bounded = PiecewiseLinearModel([[5.0]], [[6.0]], [[0.0]], [1.0])
    with pytest.raises(RepertoireError, match="no leaf of its model meets the domain"):
        DurationTerm(bounded, affine, domain=([0.0], [2.0]))
