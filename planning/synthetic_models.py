"""Seeded synthetic model trees and action chains, for tests and benchmarks of refinement.

A model tree here is grown by recursive axis-aligned splits at thresholds on a grid (so
exact optima lie on a grid a brute-force search can visit), with a random hyperplane
per leaf whose predictions stay positive over the parameter box (durations).
"""

import numpy as np
from repertoire.planning.refinement import (
    AffineFeatures,
    DurationTerm,
    PiecewiseLinearModel,
    RefinementProblem,
)

from repertoire.errors import RepertoireError


def random_model_tree(
    seed: int,
    n_features: int,
    depth: int,
    *,
    extent: float = 2.0,
    grid: float = 0.25,
    fitted: bool = False,
) -> PiecewiseLinearModel:
    """A random model tree of up to ``2**depth`` leaves over R^n_features.

    Splits are at multiples of ``grid`` inside [-extent, extent]; the outermost leaves
    extend to +-inf. With ``fitted=False`` each leaf predicts ``intercept + coef @ f``
    with random |coef| <= 1 and an intercept keeping it positive for |f| <= extent (a
    harsh, discontinuous landscape). With ``fitted=True`` each leaf's hyperplane is the
    least-squares fit, over seeded samples of the leaf's box (clipped to the extent), of
    a smooth positive duration ``2 + sum_i a_i |f_i - m_i| + b @ f``, the way an M5
    model tree fits its leaves: nearly continuous, as learned duration models are.

    Args:
        seed: random seed.
        n_features: feature dimension d >= 1.
        depth: split depth >= 0.
        extent: half-width of the region holding the split thresholds.
        grid: spacing of the thresholds (> 0).
        fitted: fit leaves to a smooth function instead of drawing them at random.
    """
    if n_features < 1 or depth < 0 or not (grid > 0 and extent > grid):
        raise RepertoireError(
            f"need n_features >= 1, depth >= 0, extent > grid > 0; got {n_features}, "
            f"{depth}, {extent}, {grid}"
        )
    rng = np.random.default_rng(seed)
    leaves: list[tuple[np.ndarray, np.ndarray]] = []
    stack = [(np.full(n_features, -np.inf), np.full(n_features, np.inf), depth)]
    while stack:
        lo, hi, level = stack.pop()
        j = int(rng.integers(n_features))
        a = max(lo[j], -extent)
        b = min(hi[j], extent)
        thresholds = np.arange(np.ceil(a / grid + 1e-9), np.floor(b / grid - 1e-9) + 1) * grid
        if level == 0 or thresholds.size == 0:
            leaves.append((lo, hi))
            continue
        t = float(rng.choice(thresholds))
        left_hi, right_lo = hi.copy(), lo.copy()
        left_hi[j], right_lo[j] = t, t
        stack.append((lo, left_hi, level - 1))
        stack.append((right_lo, hi, level - 1))
    lower = np.array([lo for lo, _ in leaves])
    upper = np.array([hi for _, hi in leaves])
    if not fitted:
        coef = rng.uniform(-1.0, 1.0, lower.shape)
        intercept = np.abs(coef).sum(axis=1) * extent + rng.uniform(0.5, 3.0, len(leaves))
        return PiecewiseLinearModel(lower, upper, coef, intercept)
    a = rng.uniform(0.2, 1.0, n_features)
    m = rng.uniform(-extent / 2, extent / 2, n_features)
    slope = rng.uniform(-0.3, 0.3, n_features) * a
    coef = np.empty(lower.shape)
    intercept = np.empty(len(leaves))
    for i in range(len(leaves)):
        lo = np.clip(lower[i], -extent, extent)
        hi = np.clip(upper[i], -extent, extent)
        x = rng.uniform(lo, hi, (8 * (n_features + 1), n_features))
        y = 2.0 + np.abs(x - m) @ a + x @ slope
        design = np.hstack([x, np.ones((x.shape[0], 1))])
        fit = np.linalg.lstsq(design, y, rcond=None)[0]
        coef[i], intercept[i] = fit[:-1], fit[-1]
    return PiecewiseLinearModel(lower, upper, coef, intercept)


def chain_problem(
    seed: int,
    n_actions: int,
    per_subgoal: int,
    depth: int,
    *,
    bound: float = 1.0,
    fitted: bool = False,
) -> RefinementProblem:
    """A sequence like the paper's: action i reads the free parameters of subgoals i-1, i.

    There are ``n_actions - 1`` intermediate subgoals with ``per_subgoal`` free
    parameters each, ranges [-bound, bound]; the first action reads only subgoal 0 and
    the last only the last subgoal. Features are the parameters themselves scaled by 2
    and shifted by 0.5 (affine, one parameter per feature).

    Args:
        seed: random seed (one tree per action, seeded ``seed * 1000 + i``).
        n_actions: actions >= 2.
        per_subgoal: free parameters per subgoal >= 1.
        depth: tree depth.
        bound: half-width of every parameter range.
        fitted: trees fitted to smooth durations (see :func:`random_model_tree`).
    """
    if n_actions < 2 or per_subgoal < 1:
        raise RepertoireError(f"need n_actions >= 2 and per_subgoal >= 1, got {n_actions}")
    P = (n_actions - 1) * per_subgoal
    terms = []
    for i in range(n_actions):
        cols = list(range(max(0, i - 1) * per_subgoal, min(i + 1, n_actions - 1) * per_subgoal))
        A = np.zeros((len(cols), P))
        A[np.arange(len(cols)), cols] = 2.0
        model = random_model_tree(seed * 1000 + i, len(cols), depth, fitted=fitted)
        terms.append(DurationTerm(model, AffineFeatures(A, np.full(len(cols), 0.5)), name=f"a{i}"))
    return RefinementProblem(tuple(terms), np.full(P, -bound), np.full(P, bound))
