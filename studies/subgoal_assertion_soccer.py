"""Subgoal assertion in simulation: ball approaches with and without it (Fig. 16b).

Section 7 of Stulp & Beetz (JAIR 2008). Each episode samples a start and a ball
approach (the pose ``approach_distance`` behind the ball at a uniform approach angle and
speed) and executes it twice in the ``soccer_plan`` world: once as one GoToPose, once
with subgoal assertion: if the approach failure tree (``refinement_explore``'s, in
``models_dir``) predicts a collision with the ball, an intermediate GoToPose subgoal is
inserted, chosen by the paper's GA to minimise the predicted duration of both legs over
the subgoals from which the failure tree predicts the last leg succeeds (Algorithm 4) and
that lie as far from the ball as the tree's training starts (``min_start_clearance``),
clear of the goals, and where the legs' features the subgoal sets lie inside the models'
training ranges (:func:`approach_subgoal`); the plan then runs both legs through the
PlanExecutor. An
approach succeeds when the plan succeeds without touching the ball on either leg; the
robot carries its dribbler (the ``soccer_dribble`` guide arms), as in the
``refinement_explore`` episodes the failure tree was fitted on.

``summarize`` writes Fig. 16(b)'s table (predicted vs observed, with and without
assertion) beside the paper's numbers and polar plots of the outcomes by start
direction relative to the approach (like the paper's Figs. 8, 11 and 16a).

Run it with ``python -m repertoire.studies.subgoal_assertion_soccer --help`` (after
``refinement_explore``).
"""

import dataclasses
import functools
import math
import time
from pathlib import Path

import numpy as np
from repertoire.studies._refinement_common import (
    SoccerPlanConfig,
    approach_target,
    document_shared_fields,
    run_plan,
    sample_situation,
    trained_range,
)
from repertoire.studies.engine import register_study

PAPER_FIG16B = {"success_without": 0.47, "success_with": 0.97, "predicted_fail": 0.52}


@document_shared_fields
@dataclasses.dataclass
class SubgoalAssertionConfig(SoccerPlanConfig):
    """The shared soccer plan settings plus the models and the subgoal box.

    Attributes:
        models_dir: folder with ``approach_duration.json`` and ``approach_failure.json``
            (``refinement_explore``'s output; empty: the models shipped in
            ``repertoire/models/diffdrive/soccer_plan_models``).
        subgoal_margin: the subgoal's x/y stay this far inside the field [m].
    """

    models_dir: str = ""
    subgoal_margin: float = 0.4


@dataclasses.dataclass
class SubgoalAssertionRecord:
    """One ball approach executed with and without subgoal assertion.

    Attributes:
        x, y, phi, v: the start state.
        phi_a, v_a: the approach angle and speed at the ball.
        predicted_fail: the failure tree predicts a collision for the direct approach.
        asserted: a subgoal was inserted (False also when every candidate was rejected).
        sub_x, sub_y, sub_phi, sub_v: the subgoal (NaN when none).
        success_without: the direct approach succeeded without touching the ball.
        touched_without: the direct approach touched the ball (the robot with its
            dribbler, whose guide arms reach 0.14 m ahead of the bumper).
        time_without: its duration [s] (NaN unless it succeeded).
        success_with, touched_with, time_with: the same with assertion (a touch on either
            leg).
        reason: the assertion's reason.
        wall_time_s: wall time of the episode (timing field).
    """

    x: float
    y: float
    phi: float
    v: float
    phi_a: float
    v_a: float
    predicted_fail: bool
    asserted: bool
    sub_x: float
    sub_y: float
    sub_phi: float
    sub_v: float
    success_without: bool
    touched_without: bool
    time_without: float
    success_with: bool
    touched_with: bool
    time_with: float
    reason: str
    wall_time_s: float


class _FailureTreeClassifier:
    """A failure tree as subgoal assertion's classifier (success = not a predicted failure)."""

    def __init__(self, tree):
        self.tree = tree

    def predict_success(self, features: np.ndarray) -> np.ndarray:
        return ~self.tree.predict_failure(features)


@functools.cache
def load_assertion_models(models_dir: str):
    """The approach duration and failure trees (``models_dir`` or the shipped ones)."""
    from repertoire.studies.refinement_soccer import load_models

    return load_models(models_dir, ("approach_duration", "approach_failure"))


def approach_subgoal(config: SubgoalAssertionConfig, start, target, seed: int):
    """Subgoal assertion (Algorithms 3-4) for the approach ``start -> target``.

    A subgoal is allowed where the failure tree saw starts (``min_start_clearance`` from
    the ball, clear of the goals) and where both legs' features that the subgoal sets lie
    inside the models' training ranges (all but the first leg's start speed and the last
    leg's goal speed): the search does not optimise the models' extrapolation.

    Returns:
        The :class:`~repertoire.planning.subgoal_assertion.SubgoalAssertion`.
    """
    from repertoire.diagrams.soccer import BALL_POSITION, clear_of_goals
    from repertoire.planning.action_models.features import goto_pose_features
    from repertoire.planning.subgoal_assertion import assert_subgoal

    start, target = np.asarray(start, dtype=float), np.asarray(target, dtype=float)
    duration, failure = load_assertion_models(config.models_dir)
    m = config.subgoal_margin
    bx, by = BALL_POSITION

    def features(a: np.ndarray, b: np.ndarray) -> np.ndarray:  # un-mirrored, as fitted
        return np.atleast_2d(goto_pose_features(a, b, mirrored=False))

    names = duration.feature_names  # dist, angle_to, angle_at, v, v_g
    first_driven, last_driven = [n for n in names if n != names[3]], names[:4]

    def allowed(subgoals: np.ndarray) -> np.ndarray:
        gap = np.hypot(subgoals[:, 0] - bx, subgoals[:, 1] - by)
        ok = (gap >= config.min_start_clearance) & clear_of_goals(subgoals[:, 0], subgoals[:, 1])
        first = features(np.repeat(start[None], len(subgoals), axis=0), subgoals)
        last = features(subgoals, np.repeat(target[None], len(subgoals), axis=0))
        ok &= ~duration.out_of_range(first, first_driven)
        for tree in (duration, failure):
            ok &= ~tree.out_of_range(last, last_driven)
        return ok

    # the subgoal's speed is the first leg's v_g and the second's v: search it where both
    # models saw data
    uses = [(tree, f) for tree in (duration, failure) for f in ("v", "v_g")]
    v_lo, v_hi = trained_range(0.0, config.approach_v_max, uses)
    return assert_subgoal(
        start,
        target,
        classifier=_FailureTreeClassifier(failure),
        leg_features=features,
        leg_duration=duration.predict,
        lower=np.array([-3.0 + m, -2.0 + m, -math.pi, v_lo]),
        upper=np.array([3.0 - m, 2.0 - m, math.pi, v_hi]),
        seed=seed,
        allowed=allowed,
    )


def run_episode(config: SubgoalAssertionConfig, seed: int) -> SubgoalAssertionRecord:
    """Executes one ball approach directly and with subgoal assertion."""
    from repertoire.planning.action_models.features import goto_pose_features

    config.validate()
    t0 = time.perf_counter()
    rng = np.random.default_rng(seed)
    start, _ = sample_situation(config, rng)
    phi_a = float(rng.uniform(-math.pi, math.pi))
    v_a = float(rng.uniform(0.0, config.approach_v_max))
    target = approach_target(phi_a, v_a, config.approach_distance)
    _, failure = load_assertion_models(config.models_dir)
    assertion = approach_subgoal(config, start, target, seed)
    leg = goto_pose_features(start, target, mirrored=False)[None]
    predicted_fail = bool(failure.predict_failure(leg)[0])
    # by the dribbling robot (its guide arms on), as in the failure tree's episodes
    direct = run_plan(config, start, [target], dribbler=True)
    if assertion.asserted:
        with_run = run_plan(config, start, [assertion.subgoal, target], dribbler=True)
        sub = [float(s) for s in assertion.subgoal]
    else:  # the same plan: a deterministic simulation gives the same run
        with_run, sub = direct, [math.nan] * 4

    def outcome(run):
        # a touch on either leg (before, one on the approach after a subgoal went uncounted)
        ok = run.status == "SUCCEEDED" and not run.touched_ball_goto
        return ok, run.touched_ball_goto, run.finish_times[-1] if ok else math.nan

    return SubgoalAssertionRecord(
        *map(float, start),
        phi_a=phi_a,
        v_a=v_a,
        predicted_fail=predicted_fail,
        asserted=assertion.asserted,
        sub_x=sub[0],
        sub_y=sub[1],
        sub_phi=sub[2],
        sub_v=sub[3],
        **dict(zip(("success_without", "touched_without", "time_without"), outcome(direct))),
        **dict(zip(("success_with", "touched_with", "time_with"), outcome(with_run))),
        reason=assertion.reason,
        wall_time_s=time.perf_counter() - t0,
    )


def fig16b_table(records: list[SubgoalAssertionRecord]) -> list[str]:
    """Fig. 16(b): predicted vs observed outcome, in % of all episodes, with both runs."""
    n = len(records)

    def pct(k: int) -> str:
        return f"{100.0 * k / n:.0f}%"

    rows = []
    for label, pred in (("Predicted fail", True), ("Predicted success", False)):
        sub = [r for r in records if r.predicted_fail == pred]
        fail_wo = sum(not r.success_without for r in sub)
        fail_w = sum(not r.success_with for r in sub)
        rows.append(
            f"| {label} | {pct(fail_w)} ({pct(fail_wo)} without) | "
            f"{pct(len(sub) - fail_w)} ({pct(len(sub) - fail_wo)} without) | {pct(len(sub))} |"
        )
    ok_wo = sum(r.success_without for r in records)
    ok_w = sum(r.success_with for r in records)
    return [
        "## Fig. 16(b): ball approaches with subgoal assertion (without in brackets)",
        "",
        "| | observed fail | observed success | total |",
        "|---|---|---|---|",
        *rows,
        f"| total | {pct(n - ok_w)} ({pct(n - ok_wo)} without) | {pct(ok_w)} "
        f"({pct(ok_wo)} without) | {n} episodes |",
        "",
        "| | success without | success with | predicted fail |",
        "|---|---|---|---|",
        f"| paper (100 episodes) | {PAPER_FIG16B['success_without']:.0%} | "
        f"{PAPER_FIG16B['success_with']:.0%} | {PAPER_FIG16B['predicted_fail']:.0%} |",
        f"| ours ({n} episodes) | {ok_wo / n:.0%} | {ok_w / n:.0%} | "
        f"{sum(r.predicted_fail for r in records) / n:.0%} |",
        "",
    ]


def summarize(
    records: list[SubgoalAssertionRecord], config: SubgoalAssertionConfig, out_dir: Path
) -> dict[str, Path]:
    """Writes the Fig. 16(b) table and the polar outcome plots."""
    from matplotlib.figure import Figure
    from repertoire.diagrams.soccer import BALL_POSITION

    out_dir = Path(out_dir)
    tables = out_dir / "subgoal_assertion_tables.md"
    if not records:
        tables.write_text("no episodes\n")
        return {"tables": tables}
    md = fig16b_table(records)
    asserted = [r for r in records if r.asserted]
    needless = [r for r in asserted if r.success_without and r.success_with]
    if needless:
        slow = np.mean([r.time_with / r.time_without - 1 for r in needless])
        md.append(
            f"Assertion applied where the direct approach already succeeded: "
            f"{len(needless)} episodes, {slow:+.0%} slower (paper: 10% of episodes, 8% slower)."
        )
    kept = sum(r.predicted_fail and not r.asserted for r in records)
    md.append(f"Predicted failures where every candidate subgoal was rejected (plan kept): {kept}.")
    tables.write_text("\n".join(md) + "\n")

    bx, by = BALL_POSITION
    # start direction and distance seen from the ball, in the approach's frame: 180 deg is
    # straight behind the approach pose (an easy approach), 0 deg beyond the ball
    theta = np.array([math.atan2(r.y - by, r.x - bx) - r.phi_a for r in records], dtype=float)
    radius = np.array([math.hypot(r.x - bx, r.y - by) for r in records])
    fig = Figure(figsize=(10.0, 5.2), layout="constrained")
    for k, (field, title) in enumerate(
        (("success_without", "without assertion"), ("success_with", "with assertion"))
    ):
        ax = fig.add_subplot(1, 2, k + 1, projection="polar")
        ok = np.array([getattr(r, field) for r in records], dtype=bool)
        ax.scatter(theta[ok], radius[ok], s=10, c="tab:green", label=f"success ({ok.sum()})")
        ax.scatter(
            theta[~ok], radius[~ok], s=14, c="tab:red", marker="x", label=f"fail ({(~ok).sum()})"
        )
        ax.set_title(f"{title}: {ok.mean():.0%} succeed\n(start seen from the ball, m)")
        ax.set_rlabel_position(112)
        # headroom: autoscaling put the farthest starts on the rim, half hidden by it
        ax.set_rlim(0.0, 1.12 * float(radius.max()))
        ax.legend(loc="lower left", bbox_to_anchor=(-0.1, -0.12), fontsize=8)
    fig.suptitle("Ball approach outcome by start direction; approach heading points to 0°")
    polar = out_dir / "subgoal_assertion_polar.png"
    fig.savefig(polar, dpi=110)
    return {"tables": tables, "polar": polar}


def demo_config() -> SubgoalAssertionConfig:
    """The demo config (the shared defaults, the shipped models)."""
    return SubgoalAssertionConfig()


def smoke_config() -> SubgoalAssertionConfig:
    """A tiny config for tests: starts near the ball, a short timeout, shipped models."""
    return SubgoalAssertionConfig(x_range=[-0.2, 0.2], y_range=[0.0, 0.6], timeout=8.0)


register_study(
    "subgoal_assertion_soccer",
    config_type=SubgoalAssertionConfig,
    record_type=SubgoalAssertionRecord,
    run_episode=run_episode,
    description="ball approaches with and without subgoal assertion, executed: Fig. 16(b)",
    summarize=summarize,
    demo_config=demo_config,
    demo_episodes=6,
    smoke_config=smoke_config,
).run_if_main(__name__)
