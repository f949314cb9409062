"""Soccer plans with random subgoals: the training episodes of the refinement models.

Each episode (Stulp & Beetz, sections 5.1 and 6.3.1) samples a start and a destination
beyond the ball, then a random approach subgoal (angle uniform on the circle, speed
uniform in ``[0, approach_v_max]``) and executes the two-action plan (approachBall, a
GoToPose; dribbleBall, a DribbleBall that fetches the ball and must deliver it) in the
``soccer_plan`` world. The record holds both actions' durations, whether the approach
touched the ball and whether the ball ended held.

``summarize`` fits, on 3/4 of the episodes (``fit_action_model``), the approach's and the
dribble's duration model trees (Table 7 features of each leg, successful legs only) and
the approach's pessimistic failure tree (ball touched or the approach failed), writes
them as JSON (the models the ``refinement_soccer`` and ``subgoal_assertion_soccer``
studies load via ``models_dir``) and a table of their held-out errors.

Run it with ``python -m repertoire.studies.refinement_explore --help``.
"""

import dataclasses
import math
from pathlib import Path

import numpy as np
from repertoire.studies._refinement_common import (
    LEG_FEATURES,
    SoccerPlanConfig,
    approach_features,
    approach_target,
    dribble_features,
    run_plan,
    sample_situation,
)
from repertoire.studies.engine import register_study

MODEL_FILES = {
    "approach_duration": "approach_duration.json",
    "dribble_duration": "dribble_duration.json",
    "approach_failure": "approach_failure.json",
}
"""Model name -> file name in the ``models_dir`` the refinement studies read."""


@dataclasses.dataclass
class RefinementExploreRecord:
    """One plan executed with a random approach subgoal.

    Attributes:
        x, y, phi, v: the start state.
        dest_x, dest_y, dest_phi: the destination pose.
        phi_a: the approach angle at the ball [rad].
        v_a: the approach speed [m/s].
        status: the plan's final ActionStatus name.
        failed_action: the index of the action that failed (-1 if none).
        t_approach: the approach's duration [s] (NaN if it did not succeed).
        t_dribble: the dribble's duration [s] (NaN unless it delivered the ball: succeeded
            with the ball held at the destination).
        touched_ball: the robot touched the ball during the approach.
        approach_failed: touched the ball or the approach did not succeed.
        ball_moved_m: the ball's final distance from its start [m].
        ball_held: the plan ended with the robot holding the ball (DribbleBall's test).
        wall_time_s: wall time of the episode (timing field).
    """

    x: float
    y: float
    phi: float
    v: float
    dest_x: float
    dest_y: float
    dest_phi: float
    phi_a: float
    v_a: float
    status: str
    failed_action: int
    t_approach: float
    t_dribble: float
    touched_ball: bool
    approach_failed: bool
    ball_moved_m: float
    ball_held: bool
    wall_time_s: float


def run_episode(config: SoccerPlanConfig, seed: int) -> RefinementExploreRecord:
    """Runs the plan with a seeded random approach subgoal."""
    config.validate()
    rng = np.random.default_rng(seed)
    start, dest = sample_situation(config, rng)
    phi_a = float(rng.uniform(-math.pi, math.pi))
    v_a = float(rng.uniform(0.0, config.approach_v_max))
    targets = [approach_target(phi_a, v_a, config.approach_distance), dest]
    run = run_plan(config, start, targets, dribble=True)
    t1, t2 = run.finish_times
    failed_action = -1 if run.status == "SUCCEEDED" else run.active
    return RefinementExploreRecord(
        *map(float, start),
        *map(float, dest[:3]),
        phi_a=phi_a,
        v_a=v_a,
        status=run.status,
        failed_action=failed_action,
        t_approach=float(t1) if failed_action != 0 else math.nan,
        t_dribble=float(t2 - t1) if run.status == "SUCCEEDED" else math.nan,
        touched_ball=run.touched_ball_first,
        approach_failed=bool(run.touched_ball_first or failed_action == 0),
        ball_moved_m=run.ball_moved_m,
        ball_held=run.ball_held,
        wall_time_s=run.wall_time_s,
    )


def approach_feature_funcs(config: SoccerPlanConfig) -> dict:
    """Table 7 features of a record's approach leg, by name."""
    return {
        name: (
            lambda r, j=j: float(
                approach_features([r.x, r.y, r.phi, r.v], r.phi_a, r.v_a, config.approach_distance)[
                    0, j
                ]
            )
        )
        for j, name in enumerate(LEG_FEATURES)
    }


def dribble_feature_funcs(config: SoccerPlanConfig) -> dict:
    """Table 7 features of a record's dribble leg (from the planned approach state)."""
    return {
        name: (
            lambda r, j=j: float(
                dribble_features(
                    r.phi_a, r.v_a, [r.dest_x, r.dest_y, r.dest_phi, 0.0], config.approach_distance
                )[0, j]
            )
        )
        for j, name in enumerate(LEG_FEATURES)
    }


def summarize(
    records: list[RefinementExploreRecord], config: SoccerPlanConfig, out_dir: Path
) -> dict[str, Path]:
    """Fits and saves the approach/dribble duration trees and the approach failure tree."""
    from repertoire.planning.action_models import MIN_EPISODES, fit_action_model, save_model

    out_dir = Path(out_dir)
    need = MIN_EPISODES * 4 // 3 + 1
    approach_ok = [r for r in records if not r.approach_failed and not math.isnan(r.t_approach)]
    dribble_ok = [r for r in records if not math.isnan(r.t_dribble)]
    tables = out_dir / "refinement_explore_tables.md"
    if min(len(approach_ok), len(dribble_ok), len(records)) < need:
        tables.write_text(
            f"{len(records)} episodes ({len(approach_ok)} clean approaches, {len(dribble_ok)} "
            f"dribbles): too few to fit; at least {need} of each are needed.\n"
        )
        return {"tables": tables}
    fits = {
        "approach_duration": fit_action_model(
            approach_ok, approach_feature_funcs(config), "t_approach"
        ),
        "dribble_duration": fit_action_model(
            dribble_ok, dribble_feature_funcs(config), "t_dribble"
        ),
        "approach_failure": fit_action_model(
            records, approach_feature_funcs(config), "approach_failed"
        ),
    }
    paths = {name: save_model(fit.model, out_dir / MODEL_FILES[name]) for name, fit in fits.items()}
    (tn, fp), (fn, tp) = fits["approach_failure"].confusion
    md = [
        "## Refinement models (fitted on 3/4 of the episodes, measured on the rest)",
        "",
        f"{len(records)} episodes with random approach subgoals; plan succeeded (ball "
        f"delivered) in {sum(r.status == 'SUCCEEDED' for r in records)}, approach touched "
        f"the ball in {sum(r.touched_ball for r in records)}.",
        "",
        "| model | episodes | leaves | mean (s) | held-out MAE (s) / accuracy |",
        "|---|---|---|---|---|",
    ]
    for name, fit in fits.items():
        score = f"{fit.accuracy:.1%}" if "failure" in name else f"{fit.mae:.3f}"
        md.append(
            f"| {name} | {fit.n_train + fit.n_test} | {len(fit.model.leaves)} | "
            f"{fit.mean_target:.3f} | {score} |"
        )
    md += [
        "",
        f"Approach failure tree, held-out: {tn} true successes, {fp} false alarms, "
        f"{fn} missed failures, {tp} caught failures.",
    ]
    tables.write_text("\n".join(md) + "\n")
    return {"tables": tables, **paths}


def demo_config() -> SoccerPlanConfig:
    """The demo config (the shared defaults)."""
    return SoccerPlanConfig()


def smoke_config() -> SoccerPlanConfig:
    """A tiny config for tests: starts near the ball, short dribbles, short timeouts."""
    return SoccerPlanConfig(
        x_range=[-0.2, 0.2],
        y_range=[0.0, 0.6],
        dribble_distance_range=[0.6, 0.7],
        timeout=8.0,
        dribble_gains={"timeout": 10.0},
    )


register_study(
    "refinement_explore",
    config_type=SoccerPlanConfig,
    record_type=RefinementExploreRecord,
    run_episode=run_episode,
    description="soccer plans with random approach subgoals: the refinement models' episodes",
    summarize=summarize,
    demo_config=demo_config,
    demo_episodes=8,
    smoke_config=smoke_config,
).run_if_main(__name__)
