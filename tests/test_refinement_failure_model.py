"""refinement_soccer consults the approach failure tree (section 7.2's Algorithm 4).

In session 36's Table 3 run (seeds 0-999) all 5 refined plans that timed out (165, 474,
729, 777, 807) had their h = 2 approach touch the ball and push it away; the shipped
approach failure tree predicted that collision for 4 of their subgoals (p_fail 0.40-0.55,
threshold 0.25). The refinement now treats such subgoals as INVALID.
"""

import json
import math
import shutil

import numpy as np
import pytest
from repertoire.studies._refinement_common import (
    approach_features,
    approach_succeeds,
    sample_situation,
)
from repertoire.studies.refinement_soccer import (
    RefinementSoccerConfig,
    load_failure_model,
    models_folder,
    refine_subgoal,
)

# seed -> session 36's h = 2 approach (phi, v) that touched the ball
TOUCHED = {
    165: (3.1035696311838312, 0.0899332773094486),
    474: (-0.7411625706303803, 0.0899332773094486),
    729: (1.6729381689464433, 0.0899332773094486),
    807: (0.9641595458518503, 0.0899332773094486),
}


def _params(start, phi, v):
    """The approach action's parameters (name -> (n,) values) for subgoals ``phi, v``."""
    phi, v = np.atleast_1d(phi).astype(float), np.atleast_1d(v).astype(float)
    n = len(phi)
    names = ("x", "y", "phi", "v")
    return {k: np.full(n, float(s)) for k, s in zip(names, start, strict=True)} | {
        "phi_g": phi,
        "v_g": v,
    }


def test_approach_succeeds_is_the_failure_trees_verdict():
    config = RefinementSoccerConfig()
    tree = load_failure_model(config.models_dir)
    start, _ = sample_situation(config, np.random.default_rng(474))
    phis = np.array([TOUCHED[474][0], -2.441])
    params = _params(start, phis, [0.09, 0.09])
    # session 36's subgoal: the approach ends facing back at the start (angle_at -3.09 rad,
    # 1.51 m): the leaf "dist <= 1.91 and angle_at <= -2.8", p_fail 6 / 11 = 0.55
    features = approach_features(start, phis, [0.09, 0.09], config.approach_distance)
    assert features[0, 2] == pytest.approx(-3.093, abs=1e-3) and features[0, 0] < 1.91
    assert tree.predict(features) == pytest.approx([6 / 11, 0.0], abs=1e-12)
    np.testing.assert_array_equal(approach_succeeds(tree, config)(params), [False, True])


@pytest.mark.parametrize("seed", sorted(TOUCHED))
def test_refined_subgoal_avoids_a_predicted_collision(seed):
    config = RefinementSoccerConfig()
    tree = load_failure_model(config.models_dir)
    succeeds = approach_succeeds(tree, config)
    start, dest = sample_situation(config, np.random.default_rng(seed))
    assert not succeeds(_params(start, *TOUCHED[seed]))[0]  # was chosen, predicted to fail
    phi, v, predicted = refine_subgoal(config, start, dest, 2, seed)
    assert succeeds(_params(start, phi, v))[0] and np.isfinite(predicted)
    assert abs(math.remainder(phi - TOUCHED[seed][0], 2.0 * math.pi)) > 1.0


def _models_with_failure_probability(tmp_path, p_fail: float):
    """The shipped models, with every leaf of the failure tree at ``p_fail``."""
    folder = tmp_path / f"p{p_fail}"
    shutil.copytree(models_folder(""), folder)
    path = folder / "approach_failure.json"
    data = json.loads(path.read_text())
    for leaf in data["leaves"]:
        leaf["intercept"] = p_fail
    path.write_text(json.dumps(data))
    return str(folder)


def test_a_tree_that_predicts_failure_everywhere_keeps_the_plan(tmp_path):
    # no subgoal predicted to succeed: the refinement sets the tree aside, as subgoal
    # assertion keeps a plan whose every candidate it rejects; the result is the one a
    # tree predicting success everywhere gives (the refinement without the tree)
    start, dest = sample_situation(RefinementSoccerConfig(), np.random.default_rng(474))
    results = []
    for p_fail in (1.0, 0.0):
        models_dir = _models_with_failure_probability(tmp_path, p_fail)
        config = RefinementSoccerConfig(models_dir=models_dir)
        results.append(refine_subgoal(config, start, dest, 2, 474))
    assert results[0] == results[1]
    assert np.isfinite(results[0][2])


def test_refined_plan_that_touched_the_ball_now_delivers_it():
    """Seed 474 (Table 3): session 36's h = 2 plan timed out after its approach pushed the
    ball away; the refined plan now delivers it in 8.0 s (greedy 13.2 s)."""
    from repertoire.studies.refinement_soccer import run_episode

    record = run_episode(RefinementSoccerConfig(), 474)
    assert record.status_2 == "SUCCEEDED" and record.ball_held_2
    assert record.time_2 < record.time_1
