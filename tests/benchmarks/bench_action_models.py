"""Benchmark of the learned action models: episode throughput, batched prediction, predictor.

Prints (1) GoToPose, DribbleBall and two-joint arm Reach episodes per second
with the study engine on 1 and 2 workers (the ratio is the peer in the same
run; ``--episodes`` sets the 1-worker count, 2 workers run twice as many),
(2) batched predictions per second of a fitted duration model tree and failure
tree (target >= 100,000/s),
with scikit-learn's own DecisionTreeRegressor.predict on the same tree size as
the peer, and (3) the ActionModelPredictor LeafSystem's cost per evaluation,
with GoToPose features and with the arm's Table 7 features.

With ``--dribble-before-after N`` it first runs N DribbleBall episodes on 2
workers with the world built for every episode and with it built once per
worker and reset (``bench_kitchen.before_after``: rates, how the outcome moved).

Run: ``nice -n 10 python tests/benchmarks/bench_action_models.py [--episodes 4]``.
"""

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
from repertoire.planning.action_models import (
    arm_reach_features,
    fit_duration_tree,
    fit_failure_tree,
)
from repertoire.studies.actions_arm_reach import ReachEpisodesConfig
from repertoire.studies.actions_dribble import DribbleEpisodesConfig
from repertoire.studies.actions_goto_pose import GoToPoseEpisodesConfig
from repertoire.studies.engine import run_study
from repertoire.systems.action_model_predictor import (
    ActionModelPredictor,
    goto_pose_parameter_features,
)

STUDIES = {
    "GoToPose": ("actions_goto_pose", GoToPoseEpisodesConfig),
    "DribbleBall": ("actions_dribble", DribbleEpisodesConfig),
    "Reach (arm7, 2 joints)": ("actions_arm_reach", ReachEpisodesConfig),
}


def episodes_per_second(study: str, config, workers: int, episodes: int) -> float:
    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()
        run_study(
            study,
            config,
            episodes=episodes,
            workers=workers,
            store=Path(tmp) / "s.sqlite",
            out_dir=tmp,
            fresh=True,
            progress=False,
        )
        return episodes / (time.perf_counter() - t)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--episodes", type=int, default=8, help="episodes on 1 worker")
    parser.add_argument(
        "--dribble-before-after", type=int, default=0, metavar="N",
        help="first: N DribbleBall episodes built per episode (before) and reused (after)",
    )  # fmt: skip
    args = parser.parse_args()
    if args.dribble_before_after:
        from bench_kitchen import before_after

        settings = {
            "before": DribbleEpisodesConfig(reuse_diagram=False),
            "after": DribbleEpisodesConfig(),
        }
        before_after("actions_dribble", "DribbleBall", settings, args.dribble_before_after)
    for label, (study, config_type) in STUDIES.items():
        e1 = episodes_per_second(study, config_type(), 1, args.episodes)
        e2 = episodes_per_second(study, config_type(), 2, 2 * args.episodes)
        print(f"{label} episodes: {e1:.2f}/s on 1 worker, {e2:.2f}/s on 2 workers ({e2 / e1:.2f}x)")

    rng = np.random.default_rng(0)
    X = np.column_stack(
        [
            rng.uniform(0, 4, 3000),
            rng.uniform(-np.pi, np.pi, 3000),
            rng.uniform(-np.pi, np.pi, 3000),
            rng.uniform(0, 0.5, 3000),
            rng.uniform(0, 0.1, 3000),
        ]
    )
    y = 1 + X[:, 0] / 0.6 + np.abs(X[:, 1]) + 0.5 * np.abs(X[:, 2]) + 0.1 * rng.normal(size=3000)
    names = ["dist", "angle_to", "angle_at", "v", "v_g"]
    dur = fit_duration_tree(X, y, names)
    fail = fit_failure_tree(X, X[:, 0] < 0.8, names)
    Xq = rng.uniform(X.min(0), X.max(0), (200_000, 5))
    for model, label in ((dur, "duration tree"), (fail, "failure tree")):
        t = time.perf_counter()
        model.predict(Xq)
        model.out_of_range(Xq)
        rate = len(Xq) / (time.perf_counter() - t)
        print(
            f"{label} ({len(model.leaves)} leaves): {rate:,.0f} batched predictions/s "
            "(with the range flag)"
        )
    from sklearn.tree import DecisionTreeRegressor

    peer = DecisionTreeRegressor(max_leaf_nodes=max(2, len(dur.leaves)), random_state=0).fit(X, y)
    t = time.perf_counter()
    peer.predict(Xq)
    print(
        f"peer sklearn DecisionTreeRegressor.predict (constant leaves): "
        f"{len(Xq) / (time.perf_counter() - t):,.0f}/s"
    )

    predictor = ActionModelPredictor(dur, fail, 8, goto_pose_parameter_features)
    ctx = predictor.CreateDefaultContext()
    port = predictor.get_input_port()
    out = predictor.GetOutputPort("duration")
    n = 2000
    t = time.perf_counter()
    for k in range(n):
        port.FixValue(ctx, np.array([0, 0, 0, 0.1, 1 + k * 1e-4, 1, 0, 0]))
        out.Eval(ctx)
    print(
        f"ActionModelPredictor (GoToPose features): {1e6 * (time.perf_counter() - t) / n:.0f} us "
        "per evaluation (new parameters each time)"
    )
    # the arm's Table 7 features from the 8 reach parameters [start(4), goal(4)]
    arm = ActionModelPredictor(dur, fail, 8, lambda p: arm_reach_features(p[:4], p[4:]))
    ctx = arm.CreateDefaultContext()
    port, out = arm.get_input_port(), arm.GetOutputPort("duration")
    t = time.perf_counter()
    for k in range(n):
        port.FixValue(ctx, np.array([0.2, 0.1, 1.0, 0, 1 + k * 1e-4, 0, 0.5, 0.2]))
        out.Eval(ctx)
    print(
        f"ActionModelPredictor (arm reach features): {1e6 * (time.perf_counter() - t) / n:.0f} us "
        "per evaluation"
    )


if __name__ == "__main__":
    main()
