"""Subgoal refinement back-ends against brute force, horizons, GA/DE, bad input."""

import itertools

import numpy as np
import pytest
from repertoire.planning.black_box import GaOptions, genetic_minimise, solve_de, solve_ga
from repertoire.planning.refinement import (
    AffineFeatures,
    DurationModel,
    DurationTerm,
    PiecewiseLinearModel,
    RefinementProblem,
    refine_sequence,
)
from repertoire.planning.refinement_exact import solve_corners, solve_milp
from repertoire.planning.synthetic_models import chain_problem, random_model_tree
from scipy.optimize import linprog

from repertoire.errors import RepertoireError


def _grid_minimum(problem: RefinementProblem, step: float, nudge: float = 0.0) -> float:
    """Brute force on a grid; with ``nudge``, also at +-nudge from every grid value.

    Leaves are half-open, so an infimum on a face that belongs to the other leaf is only
    approached: the nudged points see it (to nudge times the slope).
    """
    axes = []
    for lo, hi in zip(problem.lower, problem.upper):
        g = np.arange(lo, hi + step / 2, step)
        if nudge:
            g = np.unique(np.clip(np.concatenate([g - nudge, g, g + nudge]), lo, hi))
        axes.append(g)
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, problem.n_params)
    return float(problem.cost(grid).min())


def test_model_predicts_closed_form_on_half_open_leaves():
    # f <= 0: 1 - f ; f > 0: 2 + f  -> on the face f = 0 the leaf below, 1
    model = PiecewiseLinearModel([[-np.inf], [0.0]], [[0.0], [np.inf]], [[-1.0], [1.0]], [1, 2])
    assert isinstance(model, DurationModel)
    np.testing.assert_allclose(model.predict([[-2.0], [0.0], [0.5]]), [3.0, 1.0, 2.5])
    # f <= 0: 2 - f ; f > 0: 1 + f  -> on the face the leaf below too (2), as a tree's
    # predict goes left at x <= threshold, although the leaf above approaches 1
    model = PiecewiseLinearModel([[-np.inf], [0.0]], [[0.0], [np.inf]], [[-1.0], [1.0]], [2, 1])
    np.testing.assert_array_equal(model.predict([[0.0], [np.nextafter(0.0, 1.0)]]), [2.0, 1.0])
    bounded = PiecewiseLinearModel([[0.0]], [[1.0]], [[1.0]], [0.0])
    np.testing.assert_array_equal(bounded.predict([[2.0], [0.0], [1.0]]), [np.inf, np.inf, 1.0])


@pytest.mark.parametrize("seed,fitted", [(0, False), (1, False), (2, True), (3, True)])
def test_exact_backends_match_brute_force_grid(seed, fitted):
    # 3 actions, 2 subgoals x 1 parameter, and x 2 parameters: thresholds map to
    # multiples of 0.125 in parameter space, so a 0.125 grid visits every corner.
    # Grid values and 1e-12 either side of them see every cell's corner (the corner on
    # an open face is approached to 1e-12 times the slope, < 1e-10 here).
    for per, bound in ((1, 1.0), (2, 0.5)):
        problem = chain_problem(seed, 3, per, depth=4, fitted=fitted, bound=bound)
        brute = _grid_minimum(problem, 0.125, nudge=1e-12)
        corners = solve_corners(problem)
        milp = solve_milp(problem)
        for result in (corners, milp):  # a value the models attain at the parameters
            assert result.cost == problem.cost(result.params)[0]
            assert np.all(result.params >= problem.lower)
            assert np.all(result.params <= problem.upper)
        assert corners.cost <= _grid_minimum(problem, 0.125)  # grid points are attained
        assert corners.cost == pytest.approx(brute, abs=1e-10)
        assert milp.cost == pytest.approx(corners.cost, abs=1e-7)


def test_milp_handles_mixing_affine_features_exactly():
    # features mix parameters (f0 = p0 + p1, f1 = p0 - p1): corners refuse, the MILP
    # agrees with enumerating every leaf combination's LP.
    A = np.array([[1.0, 1.0], [1.0, -1.0]])
    terms = tuple(
        DurationTerm(random_model_tree(s, 2, 3), AffineFeatures(A * (1 + s), [0.1, -0.2]))
        for s in range(2)
    )
    problem = RefinementProblem(terms, [-1.0, -1.0], [1.0, 1.0])
    with pytest.raises(RepertoireError, match="use method='milp'"):
        solve_corners(problem)
    best = np.inf
    models = [t.model for t in terms]
    for leaves in itertools.product(*[range(m.n_leaves) for m in models]):
        c, k, rows, rhs = np.zeros(2), 0.0, [], []
        for term, m, leaf in zip(terms, models, leaves, strict=True):
            Af, bf = term.features.A, term.features.b
            c += m.coef[leaf] @ Af
            k += m.coef[leaf] @ bf + m.intercept[leaf]
            for j in range(2):
                if np.isfinite(m.upper[leaf, j]):
                    rows.append(Af[j]), rhs.append(m.upper[leaf, j] - bf[j])
                if np.isfinite(m.lower[leaf, j]):
                    rows.append(-Af[j]), rhs.append(bf[j] - m.lower[leaf, j])
        lp = linprog(c, A_ub=np.array(rows), b_ub=rhs, bounds=[(-1, 1)] * 2)
        if lp.status == 0:
            best = min(best, lp.fun + k)
    milp = solve_milp(problem)
    assert milp.cost == problem.cost(milp.params)[0]
    assert milp.cost == pytest.approx(best, abs=1e-8)  # best: the infimum over closed leaves


def test_black_box_backends_near_exact_and_seeded():
    problem = chain_problem(5, 3, 1, depth=4)
    exact = solve_corners(problem).cost
    ga = solve_ga(problem, seed=3)
    de = solve_de(problem, seed=3)
    for result in (ga, de):
        assert result.cost >= exact - 1e-9  # exact is a true lower bound
        assert result.cost <= exact + 0.02 * abs(exact)
    again = solve_ga(problem, seed=3)
    np.testing.assert_array_equal(again.params, ga.params)
    assert ga.iterations <= 500 and ga.evaluations >= 25 * 2


def test_ga_paper_settings_and_stopping():
    calls = []

    def cost(x):
        calls.append(x.shape[0])
        return np.sum((x - 0.3) ** 2, axis=1) + 1.0

    best, value, evals, generations = genetic_minimise(cost, np.zeros(3), np.ones(3), seed=1)
    assert calls[0] == 75  # 25 chromosomes per free parameter
    assert calls[1] == 75 - 2  # 2% elitism (round(1.5) = 2 elites re-used unevaluated)
    assert generations <= 500 and evals == sum(calls)
    np.testing.assert_allclose(best, 0.3, atol=0.05)
    assert value == pytest.approx(cost(best[None])[0])
    # all-invalid costs keep running until stagnation and report +inf
    _, inf_value, _, gens = genetic_minimise(
        lambda x: np.full(x.shape[0], np.inf), np.zeros(2), np.ones(2), seed=0,
        options=GaOptions(stagnation=5),
    )  # fmt: skip
    assert inf_value == np.inf and gens == 5


def test_horizons():
    problem = chain_problem(7, 4, 2, depth=4)
    exact = solve_corners(problem).cost
    results = {h: refine_sequence(problem, h) for h in (1, 2, 3, 4)}
    assert results[4].cost == pytest.approx(exact, abs=1e-9)
    for r in results.values():
        assert r.cost >= exact - 1e-9
        assert problem.cost(r.params)[0] == pytest.approx(r.cost)
        assert len(r.steps) == 3  # the last action has no free parameter left
    assert results[1].cost >= results[4].cost
    # the MILP back-end follows the same receding horizon
    assert refine_sequence(problem, 2, "milp").cost == pytest.approx(results[2].cost, abs=1e-6)
    ga = refine_sequence(problem, 2, "ga", seed=0)
    assert ga.method == "ga" and ga.cost >= exact - 1e-9


def test_non_affine_features_use_black_box():
    # duration depends on an angle through cos: only GA/DE apply
    model = PiecewiseLinearModel([[-np.inf]], [[np.inf]], [[-1.0]], [2.0])
    term = DurationTerm(model, lambda p: np.cos(p[:, :1]), uses=(0,), name="turn")
    problem = RefinementProblem((term,), [-np.pi], [np.pi])
    with pytest.raises(RepertoireError, match="needs affine features"):
        solve_corners(problem)
    with pytest.raises(RepertoireError, match="needs affine features"):
        solve_milp(problem)
    assert solve_ga(problem, seed=0).cost == pytest.approx(1.0, abs=1e-4)
    assert refine_sequence(problem, 1, "de", seed=0).cost == pytest.approx(1.0, abs=1e-6)


def test_model_from_leaf_objects():
    from types import SimpleNamespace

    leaves = [
        SimpleNamespace(lower=[-np.inf], upper=[0.0], coef=[-1.0], intercept=1.0),
        SimpleNamespace(lower=[0.0], upper=[np.inf], coef=[1.0], intercept=2.0),
    ]
    model = PiecewiseLinearModel.from_leaves(leaves)
    np.testing.assert_allclose(model.predict([[-2.0], [0.0], [0.5]]), [3.0, 1.0, 2.5])
    with pytest.raises(RepertoireError, match="need lower, upper, coef and intercept"):
        PiecewiseLinearModel.from_leaves([SimpleNamespace(lower=[0.0])])
    with pytest.raises(RepertoireError, match="at least one leaf"):
        PiecewiseLinearModel.from_leaves([])


def test_model_save_load_roundtrip_and_version(tmp_path):
    model = random_model_tree(4, 3, 4)
    model.save(tmp_path / "m.json")
    back = PiecewiseLinearModel.load(tmp_path / "m.json")
    for name in ("lower", "upper", "coef", "intercept"):
        np.testing.assert_array_equal(getattr(back, name), getattr(model, name))
    record = model.to_dict()
    record["version"] = 0
    with pytest.raises(RepertoireError, match="format version 0"):
        PiecewiseLinearModel.from_dict(record)
    with pytest.raises(RepertoireError, match="missing type"):
        PiecewiseLinearModel.from_dict({"lower": []})


def test_every_candidate_invalid_gives_infinite_cost():
    model = PiecewiseLinearModel([[-np.inf]], [[np.inf]], [[1.0]], [1.0])
    rejected = DurationTerm(model, lambda p: np.full((p.shape[0], 1), np.nan), uses=(0,))
    problem = RefinementProblem((rejected,), [0.0], [1.0])
    opts = GaOptions(stagnation=3)
    assert refine_sequence(problem, 1, "ga", seed=0, options=opts).cost == np.inf


def test_bad_input():
    problem = chain_problem(0, 3, 1, depth=2)
    with pytest.raises(RepertoireError, match="horizon 4 is not in 1..3"):
        refine_sequence(problem, 4)
    with pytest.raises(RepertoireError, match="horizon 0"):
        refine_sequence(problem, 0)
    with pytest.raises(RepertoireError, match="empty ranges"):
        RefinementProblem(problem.terms, [0.0, 1.0], [1.0, 0.5], ("pos2.phi", "pos3.phi"))
    with pytest.raises(RepertoireError, match="at least one action"):
        RefinementProblem((), [0.0], [1.0])
    with pytest.raises(RepertoireError, match=r"parameters \[1\] have the non-finite ranges"):
        RefinementProblem(problem.terms, [0.0, 0.0], [1.0, np.inf])
    with pytest.raises(RepertoireError, match=r"\['pos3.phi'\] have the non-finite ranges \[\[nan"):
        RefinementProblem(problem.terms, [0.0, np.nan], [1.0, 1.0], ("pos2.phi", "pos3.phi"))
    with pytest.raises(RepertoireError, match="2 lower and 3 upper bounds"):
        RefinementProblem(problem.terms, [0.0, 0.0], [1.0, 1.0, 1.0])
    with pytest.raises(RepertoireError, match="takes no options"):
        refine_sequence(problem, 1, "corners", seed=0)
    with pytest.raises(RepertoireError, match="unknown solver"):
        refine_sequence(problem, 1, "simplex")
    with pytest.raises(RepertoireError, match="lower > upper"):
        PiecewiseLinearModel([[1.0]], [[0.0]], [[0.0]], [0.0])
    with pytest.raises(RepertoireError, match="non-affine features need `uses`"):
        DurationTerm(PiecewiseLinearModel([[0.0]], [[1.0]], [[0.0]], [0.0]), np.cos)
    with pytest.raises(RepertoireError, match="invalid GA options"):
        GaOptions(elite_fraction=1.5)
    outside = RefinementProblem(
        (DurationTerm(PiecewiseLinearModel([[5.0]], [[6.0]], [[0.0]], [1.0]),
                      AffineFeatures([[1.0]], [0.0])),), [0.0], [1.0],
    )  # fmt: skip
    with pytest.raises(RepertoireError, match="no leaf of its model covers"):
        solve_corners(outside)


def test_exact_optimum_is_attained_on_shared_faces():
    # Fuzz reproducer: on faces several terms share, each term used to take its cheaper
    # side independently (8.529301 at [0.125, -0.3, -0.125, 0.25]), a combination no
    # parameter vector has. Leaves are half-open for every term alike now.
    problem = chain_problem(109, 3, 2, 4, fitted=True, bound=0.3)
    corners = refine_sequence(problem, 3, "corners")
    milp = refine_sequence(problem, 3, "milp")
    for result in (corners, milp):
        assert result.cost == problem.cost(result.params)[0]
        assert result.cost == pytest.approx(8.606014, abs=1e-6)
    assert milp.cost == pytest.approx(corners.cost, abs=1e-9)
    # every open orthant 1e-9 away: none better (to the slope), one as good
    signs = np.array(list(itertools.product([-1.0, 1.0], repeat=problem.n_params)))
    near = np.clip(corners.params + 1e-9 * signs, problem.lower, problem.upper)
    assert problem.cost(near).min() == pytest.approx(corners.cost, abs=1e-8)
    samples = np.random.default_rng(0).uniform(problem.lower, problem.upper, (20000, 4))
    assert problem.cost(samples).min() >= corners.cost


@pytest.mark.parametrize("seed", range(6))
def test_exact_backends_on_random_chains(seed):
    # fresh chains (random and fitted trees, 1-2 parameters per subgoal, bounds off the
    # threshold grid too): corners and the MILP agree, attain their cost, and neither
    # 4000 samples nor points 1e-9 around the optimum do better
    rng = np.random.default_rng(1000 + seed)
    per, depth = int(rng.integers(1, 3)), int(rng.integers(2, 5))
    bound = float(rng.choice([0.3, 0.55, 1.0]))
    problem = chain_problem(200 + seed, 3, per, depth, fitted=bool(seed % 2), bound=bound)
    corners = solve_corners(problem)
    milp = solve_milp(problem)
    for result in (corners, milp):
        assert result.cost == problem.cost(result.params)[0]
    assert milp.cost == pytest.approx(corners.cost, abs=1e-7)
    samples = rng.uniform(problem.lower, problem.upper, (4000, problem.n_params))
    signs = np.array(list(itertools.product([-1.0, 0.0, 1.0], repeat=problem.n_params)))
    near = np.clip(corners.params + 1e-9 * signs, problem.lower, problem.upper)
    assert problem.cost(np.vstack([samples, near])).min() >= corners.cost - 1e-8


def test_model_from_tree_predicts_as_the_tree_on_thresholds():
    from repertoire.planning.action_models.trees import fit_duration_tree

    rng = np.random.default_rng(3)
    X = rng.uniform(-1, 1, (300, 2))
    y = 2 + np.abs(X[:, 0] - 0.2) + 3 * (X[:, 1] > 0.1) + 0.1 * rng.normal(size=300)
    tree = fit_duration_tree(X, y, ["a", "b"])
    model = PiecewiseLinearModel.from_leaves(tree.leaves)
    assert model.n_leaves > 2
    thresholds = [t for t, f in zip(tree.threshold, tree.feature) if f >= 0]
    on_faces = np.array([[t, u] for t in thresholds for u in thresholds])
    for points in (X, on_faces):
        np.testing.assert_allclose(model.predict(points), tree.predict(points), rtol=1e-12)


def test_milp_bad_face_margin():
    problem = chain_problem(0, 3, 1, depth=2)
    with pytest.raises(RepertoireError, match="face_margin must be finite and >= 0, got -1"):
        solve_milp(problem, face_margin=-1.0)


def test_leaf_faces_map_to_the_exact_floats_they_hold():
    # _float_interval: the floats p in [p_lo, p_hi] with L < a p + b <= U as numpy rounds
    # a p + b; checked at both ends and one float beyond each
    from repertoire.planning.refinement_exact import _float_interval

    rng = np.random.default_rng(0)
    n = 4000
    a = rng.choice([-3.0, -2.0, -0.7, 0.1, 0.5, 2.0, 3.0, 1e-3, 7e4], n)
    b = rng.choice([0.0, 0.5, 0.1, -0.3, 1e8, 1 / 3], n)
    L = b + a * rng.choice([-1.0, -0.5, 0.0, 0.125, 1e-17, 0.3, 0.7], n)
    L[rng.random(n) < 0.1] = -np.inf
    U = np.maximum(L, b + a * rng.choice([-0.2, 0.0, 0.125, 0.3, 1.0, 1e-17], n))
    U[rng.random(n) < 0.1] = np.inf
    L, U = np.minimum(L, U), np.maximum(L, U)
    p_lo, p_hi = -np.ones(n), np.ones(n)
    lo, hi = _float_interval(a, b, L, U, p_lo, p_hi)

    def inside(p):
        with np.errstate(over="ignore", invalid="ignore"):  # empty ones: p = +-inf
            f = a * p + b
        return (f > L) & (f <= U) & (p >= p_lo) & (p <= p_hi)

    some = lo <= hi
    assert 0.3 < some.mean() < 1.0
    assert np.all(inside(lo)[some]) and np.all(inside(hi)[some])
    assert not np.any(inside(np.nextafter(lo, -np.inf))[some])
    assert not np.any(inside(np.nextafter(hi, np.inf))[some])
    # empty intervals: no float of a fine grid (nor the ends) is inside
    grid = np.linspace(-1, 1, 2001)[:, None]
    assert not np.any(inside(grid)[:, ~some])


def test_clamped_leaves_exact_back_ends_and_black_box():
    # one leaf, duration = 2 p on p in [0, 1], clamped to [floor, 5]
    def problem(floor: float, A=((1.0,),), upper=(1.0,)):
        model = PiecewiseLinearModel([[-np.inf]], [[np.inf]], [[2.0]], [0.0], [floor], [5.0])
        features = AffineFeatures(np.array(A), np.zeros(1))
        term = DurationTerm(model, features, uses=tuple(range(len(upper))), name="t")
        return RefinementProblem((term,), np.zeros(len(upper)), np.array(upper))

    loose = problem(-1.0)  # the clamp never binds in the box: the exact back-ends apply
    assert loose.terms[0].model.clamped
    assert solve_corners(loose).cost == 0.0 and solve_milp(loose).cost == pytest.approx(0.0)
    tight = problem(0.5)  # binds below p = 0.25: a flat piece the hyperplane does not know
    np.testing.assert_allclose(tight.cost(np.array([[0.0], [0.5], [1.0]])), [0.5, 1.0, 2.0])
    for solve in (solve_corners, solve_milp):
        with pytest.raises(RepertoireError, match=r"leaf 0's hyperplane spans \[0, 2\]"):
            solve(tight)
    mixing = problem(-1.0, A=((1.0, 1.0),), upper=(1.0, 1.0))  # f = p0 + p1
    with pytest.raises(RepertoireError, match="mix parameters: the exact back-ends"):
        solve_milp(mixing)
    assert solve_ga(tight, seed=0).cost == pytest.approx(0.5)
    with pytest.raises(RepertoireError, match=r"floor must be 1 numbers .*nan"):
        PiecewiseLinearModel([[0.0]], [[1.0]], [[1.0]], [0.0], [np.nan])
    with pytest.raises(RepertoireError, match="floor exceeds its ceiling"):
        PiecewiseLinearModel([[0.0]], [[1.0]], [[1.0]], [0.0], [2.0], [1.0])
