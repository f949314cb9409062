"""Black-box refinement back-ends: the paper's genetic algorithm and differential evolution.

Section 6.2.2 of Stulp & Beetz (JAIR 2008). Used where features are not affine in the
free parameters (angles, distances), so the exact back-ends of
:mod:`repertoire.planning.refinement` do not apply. Both minimise
:meth:`RefinementProblem.cost`; +inf (a parameter vector outside some model's leaves,
or a subgoal the failure model rejects, the paper's INVALID) gets the lowest fitness.
"""

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from repertoire.planning.refinement import RefinementProblem, RefinementResult

from repertoire.checks import check_seed, is_real, is_whole
from repertoire.errors import RepertoireError


@dataclass(frozen=True)
class GaOptions:
    """The paper's GA settings (section 6.2.2).

    Args:
        population_per_parameter: chromosomes per free parameter (25).
        elite_fraction: best fraction copied unchanged (0.02; at least one).
        crossover_fraction: fraction of offspring made by two-point crossover (0.65).
        mutation_sigma: Gaussian mutation step as a fraction of each range (ours: 0.1).
        mutation_rate: probability that a gene of a non-elite chromosome mutates
            (ours; default 1 / number of genes).
        stagnation: stop after this many generations without a better best (50).
        max_generations: stop after this many generations (500).
    """

    population_per_parameter: int = 25
    elite_fraction: float = 0.02
    crossover_fraction: float = 0.65
    mutation_sigma: float = 0.1
    mutation_rate: float | None = None
    stagnation: int = 50
    max_generations: int = 500

    def __post_init__(self) -> None:
        whole = (self.population_per_parameter, self.stagnation, self.max_generations)
        real = (self.elite_fraction, self.crossover_fraction, self.mutation_sigma)
        rate = () if self.mutation_rate is None else (self.mutation_rate,)
        if not (
            all(is_whole(v) for v in whole)
            and all(is_real(v) and np.isfinite(v) for v in real + rate)
        ):
            raise RepertoireError(
                f"invalid GA options {self}: expected whole counts, finite numbers"
            )
        ok = (
            self.population_per_parameter >= 2
            and 0 <= self.elite_fraction < 1
            and 0 <= self.crossover_fraction <= 1
            and self.mutation_sigma >= 0
            and (self.mutation_rate is None or 0 <= self.mutation_rate <= 1)
            and self.stagnation >= 1
            and self.max_generations >= 1
        )
        if not ok:
            raise RepertoireError(f"invalid GA options {self}")


def genetic_minimise(
    cost: Callable[[np.ndarray], np.ndarray],
    lower: np.ndarray,
    upper: np.ndarray,
    *,
    seed: int,
    options: GaOptions | None = None,
) -> tuple[np.ndarray, float, int, int]:
    """The paper's GA on a batch cost function over a box.

    Fitness ``f_c = t_max + t_min - t_c`` over the valid chromosomes (invalid ones,
    cost +inf, get 0); fitness-proportionate selection; 2% elitism; two-point crossover
    on 65% of the offspring; Gaussian mutation of the non-elite ones, kept in range.

    Args:
        cost: (n, P) -> (n,) costs, +inf for invalid.
        lower: (P,) lower bounds.
        upper: (P,) upper bounds.
        seed: random seed (same seed, same result).
        options: GA settings (default: the paper's).

    Returns:
        (best parameters, best cost, cost evaluations, generations).
    """
    seed = check_seed(seed)
    opts = options or GaOptions()
    lower = np.asarray(lower, dtype=float)
    upper = np.asarray(upper, dtype=float)
    span = upper - lower
    P = lower.size
    free = int(np.count_nonzero(span > 0))
    n_pop = opts.population_per_parameter * max(1, free)
    n_elite = max(1, int(round(opts.elite_fraction * n_pop)))
    rate = opts.mutation_rate if opts.mutation_rate is not None else 1.0 / max(1, free)
    rng = np.random.default_rng(seed)
    pop = rng.uniform(lower, upper, (n_pop, P))
    costs = cost(pop)
    evaluations = n_pop
    best_i = int(np.argmin(costs))
    best, best_cost = pop[best_i].copy(), float(costs[best_i])
    stagnant = 0
    generation = 0
    while generation < opts.max_generations and stagnant < opts.stagnation:
        generation += 1
        order = np.argsort(costs, kind="stable")
        elites = pop[order[:n_elite]]
        valid = np.isfinite(costs)
        if valid.any():
            t_max, t_min = costs[valid].max(), costs[valid].min()
            # the paper's f = t_max + t_min - t (durations are > 0); for costs <= 0 the
            # offset t_min is replaced by the spread so fitness stays positive
            offset = t_min if t_min > 0 else max(t_max - t_min, 1e-12)
            fitness = np.where(valid, t_max + offset - np.where(valid, costs, t_max), 0.0)
        else:
            fitness = np.zeros(n_pop)
        prob = fitness / fitness.sum() if fitness.sum() > 0 else np.full(n_pop, 1.0 / n_pop)
        n_child = n_pop - n_elite
        parents = pop[rng.choice(n_pop, size=n_child, p=prob)]
        mates = pop[rng.choice(n_pop, size=n_child, p=prob)]
        children = parents.copy()
        crossing = rng.random(n_child) < opts.crossover_fraction
        if P >= 2 and crossing.any():
            cuts = np.sort(rng.integers(0, P + 1, size=(n_child, 2)), axis=1)
            genes = np.arange(P)
            swap = (genes >= cuts[:, :1]) & (genes < cuts[:, 1:]) & crossing[:, None]
            children = np.where(swap, mates, children)
        elif crossing.any():
            children[crossing] = mates[crossing]
        mutate = rng.random((n_child, P)) < rate
        step = rng.normal(0.0, 1.0, (n_child, P)) * opts.mutation_sigma * span
        children = np.clip(children + np.where(mutate, step, 0.0), lower, upper)
        pop = np.vstack([elites, children])
        costs = np.concatenate([costs[order[:n_elite]], cost(children)])
        evaluations += n_child
        i = int(np.argmin(costs))
        if costs[i] < best_cost:
            best, best_cost, stagnant = pop[i].copy(), float(costs[i]), 0
        else:
            stagnant += 1
    return best, best_cost, evaluations, generation


def solve_ga(
    problem: RefinementProblem, *, seed: int = 0, options: GaOptions | None = None
) -> RefinementResult:
    """Refinement with the paper's genetic algorithm (see :func:`genetic_minimise`)."""
    params, _, evals, gens = genetic_minimise(
        problem.cost, problem.lower, problem.upper, seed=seed, options=options
    )
    # the cost at the returned parameters alone: a batch's rounding may differ in the last bit
    return RefinementResult(params, float(problem.cost(params)[0]), "ga", evals, gens)


def solve_de(
    problem: RefinementProblem, *, seed: int = 0, maxiter: int = 300, popsize: int = 15
) -> RefinementResult:
    """Refinement with scipy's differential evolution (vectorised, no gradient polish).

    +inf costs (invalid) are replaced by a finite penalty above every valid cost seen so
    far, since differential evolution needs finite values.

    Args:
        problem: the refinement problem.
        seed: random seed (a whole number in 0..2**32 - 1).
        maxiter: generations (a whole number >= 1).
        popsize: population multiplier (scipy's meaning; a whole number >= 1).
    """
    from scipy.optimize import differential_evolution

    seed = check_seed(seed)
    for name, value in (("maxiter", maxiter), ("popsize", popsize)):
        if not is_whole(value) or value < 1:
            raise RepertoireError(f"{name} must be a whole number >= 1, got {value!r}")
    span = problem.upper - problem.lower
    free = span > 0
    if not free.any():
        p = problem.lower.copy()
        return RefinementResult(p, float(problem.cost(p)[0]), "de", 1, 0)
    base = problem.lower.copy()
    worst = [0.0]

    errors: list[RepertoireError] = []

    def batch(x: np.ndarray) -> np.ndarray:  # scipy passes (n_free, S) when vectorised
        full = np.repeat(base[None], x.shape[1], axis=0)
        full[:, free] = x.T
        try:
            c = problem.cost(full)
        except RepertoireError as e:  # scipy would hide it in a RuntimeError
            errors.append(e)
            raise
        ok = np.isfinite(c)
        if ok.any():
            worst[0] = max(worst[0], float(c[ok].max()))
        return np.where(ok, c, 10.0 * (abs(worst[0]) + 1.0))

    try:
        result = differential_evolution(
            batch,
            list(zip(problem.lower[free], problem.upper[free], strict=True)),
            seed=seed,
            maxiter=maxiter,
            popsize=popsize,
            tol=1e-10,
            polish=False,
            vectorized=True,
            updating="deferred",
        )
    except RuntimeError:
        if errors:
            raise errors[0] from None
        raise
    params = base.copy()
    params[free] = result.x
    return RefinementResult(
        params, float(problem.cost(params)[0]), "de", int(result.nfev), int(result.nit)
    )
