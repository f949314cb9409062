"""Benchmark of the learned action models: episode throughput, batched prediction, predictor.

Prints (1) GoToPose episodes per second with the study engine on 1 and 2
workers (the ratio is the peer in the same run), (2) batched predictions per
second of a fitted duration model tree and failure tree (target >= 100,000/s),
with scikit-learn's own DecisionTreeRegressor.predict on the same tree size as
the peer, and (3) the ActionModelPredictor LeafSystem's cost per evaluation.
"""

import tempfile
import time
from pathlib import Path

import numpy as np
from repertoire.planning.action_models import fit_duration_tree, fit_failure_tree
from repertoire.studies.actions_goto_pose import GoToPoseEpisodesConfig
from repertoire.studies.engine import run_study
from repertoire.systems.action_model_predictor import (
    ActionModelPredictor,
    goto_pose_parameter_features,
)


def episodes_per_second(workers: int, episodes: int) -> float:
    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()
        run_study(
            "actions_goto_pose",
            GoToPoseEpisodesConfig(),
            episodes=episodes,
            workers=workers,
            store=Path(tmp) / "s.sqlite",
            out_dir=tmp,
            fresh=True,
            progress=False,
        )
        return episodes / (time.perf_counter() - t)


def main() -> None:
    e1 = episodes_per_second(1, 8)
    e2 = episodes_per_second(2, 16)
    print(f"GoToPose episodes: {e1:.2f}/s on 1 worker, {e2:.2f}/s on 2 workers ({e2 / e1:.2f}x)")

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
        f"ActionModelPredictor: {1e6 * (time.perf_counter() - t) / n:.0f} us per evaluation "
        "(new parameters each time)"
    )


if __name__ == "__main__":
    main()
