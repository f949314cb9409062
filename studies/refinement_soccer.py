"""Subgoal refinement in simulation: greedy (h = 1) vs refined (h = 2) soccer plans.

Table 3 and section 6.3.2 of Stulp & Beetz (JAIR 2008). Each episode samples a start
and a destination beyond the ball (as ``refinement_explore``), plans with PDDL,
instantiates the plan (Algorithm 2: the approach angle and speed stay free), refines
the free parameters with the learned duration models (``models_dir``, written by
``refinement_explore``) once greedily (h = 1: the approach alone) and once with h = 2
(approach + dribble), and executes both plans in the ``soccer_plan`` world. Every time in
the tables is an executed time.

``summarize`` writes Table 3 (mean times, the mean per-episode improvement
``1 - t2/t1`` and a paired t-test, beside the paper's numbers) and section 6.3.2: a
decision tree trained on every other paired episode predicts from the situation whether
refinement helps; on the others refinement is then applied only where it predicts so.

Run it with ``python -m repertoire.studies.refinement_soccer --help`` (``models_dir``:
``refinement_explore``'s output folder, or the shipped models).
"""

import dataclasses
import functools
import math
import time
from pathlib import Path

import numpy as np
from repertoire.studies._refinement_common import (
    SoccerPlanConfig,
    approach_succeeds,
    approach_target,
    check_leg_model,
    document_shared_fields,
    instantiated_plan,
    mode_settled_headings,
    run_plan,
    sample_situation,
    soccer_duration_models,
    trained_range,
)
from repertoire.studies.engine import register_study

from repertoire.errors import RepertoireError

PAPER_TABLE3_SOCCER_SIM = {"n": 1000, "t1": 9.8, "t2": 9.1, "improvement": 0.066, "p": 0.00}
PAPER_SELECTIVE = {"always": 0.066, "selective": 0.086, "tree_accuracy": 0.87}
SHIPPED_MODELS = "soccer_plan_models"
"""Folder in ``repertoire/models/diffdrive`` with the trees fitted on refinement_explore's
416 episodes (the demo's models; refit with ``refinement_explore``)."""
SITUATION_FEATURES = ("dist_ball", "angle_to_ball", "turn_at_ball", "v", "dribble_dist")


@document_shared_fields
@dataclasses.dataclass
class RefinementSoccerConfig(SoccerPlanConfig):
    """The shared soccer plan settings plus where the models are and the search.

    Attributes:
        models_dir: folder with ``approach_duration.json``, ``dribble_duration.json`` and
            ``approach_failure.json`` (``refinement_explore``'s output folder; empty: the
            models shipped in ``repertoire/models/diffdrive/soccer_plan_models``).
        solver: refinement back-end for these non-affine features, ``"ga"`` or ``"de"``.
    """

    models_dir: str = ""
    solver: str = "ga"

    def validate(self) -> None:
        """Raises RepertoireError naming the first bad field."""
        super().validate()
        if self.solver not in ("ga", "de"):
            raise RepertoireError(f"solver must be 'ga' or 'de' (angles), got {self.solver!r}")


@dataclasses.dataclass
class RefinementSoccerRecord:
    """One situation executed with the greedy and the refined subgoal.

    Attributes:
        x, y, phi, v: the start state.
        dest_x, dest_y, dest_phi: the destination pose.
        phi_1, v_1: the greedy (h = 1) approach angle and speed.
        predicted_1: the models' predicted plan duration at the greedy subgoal [s].
        time_1: the executed plan's duration [s] (NaN unless it succeeded).
        status_1: the executed plan's status.
        phi_2, v_2, predicted_2, time_2, status_2: the same with h = 2.
        wall_refine_s: wall time of both refinements (timing field).
        wall_time_s: wall time of the episode (timing field).
        ball_moved_1, ball_moved_2: how far each plan moved the ball from its start [m]
            (NaN if not recorded; the engine refuses older stores without these fields).
        ball_held_1, ball_held_2: each plan ended with the ball held (DribbleBall's test;
            a plan succeeded only so).
    """

    x: float
    y: float
    phi: float
    v: float
    dest_x: float
    dest_y: float
    dest_phi: float
    phi_1: float
    v_1: float
    predicted_1: float
    time_1: float
    status_1: str
    phi_2: float
    v_2: float
    predicted_2: float
    time_2: float
    status_2: str
    wall_refine_s: float
    wall_time_s: float
    ball_moved_1: float = math.nan
    ball_moved_2: float = math.nan
    ball_held_1: bool = False
    ball_held_2: bool = False


def models_folder(models_dir: str, shipped: str = SHIPPED_MODELS) -> Path:
    """``models_dir``, or for ``""`` the ``shipped`` folder of ``repertoire.models.diffdrive``."""
    if models_dir:
        return Path(models_dir)
    from importlib.resources import files

    return Path(str(files("repertoire.models.diffdrive") / shipped))


def load_models(models_dir: str, names) -> tuple:
    """The named trees (``refinement_explore``'s ``MODEL_FILES`` keys) from ``models_dir``."""
    from repertoire.planning.action_models import load_model
    from repertoire.studies.refinement_explore import MODEL_FILES

    unknown = [k for k in names if k not in MODEL_FILES]
    if unknown:
        raise RepertoireError(f"no action models named {unknown}; expected {list(MODEL_FILES)}")
    folder = models_folder(models_dir)
    paths = [folder / MODEL_FILES[k] for k in names]
    missing = [str(p) for p in paths if not p.is_file()]
    if missing:
        raise RepertoireError(
            f"no action models {missing}: run refinement_explore first (its --out-dir is "
            "the models_dir)"
        )
    models = tuple(load_model(p) for p in paths)
    for model, path in zip(models, paths, strict=True):
        check_leg_model(model, path)
    return models


@functools.cache
def load_duration_models(models_dir: str):
    """The approach and dribble duration trees (read once per process)."""
    return load_models(models_dir, ("approach_duration", "dribble_duration"))


@functools.cache
def load_failure_model(models_dir: str):
    """The approach failure tree (read once per process)."""
    return load_models(models_dir, ("approach_failure",))[0]


def refine_subgoal(config: RefinementSoccerConfig, start, dest, horizon: int, seed: int):
    """The refined approach ``(phi, v)`` and the predicted plan duration for a horizon.

    The approach speed is searched inside the duration models' training range
    (:func:`~repertoire.studies._refinement_common.trained_range`), and the angle where
    every feature it drives lies inside the models' training boxes
    (:func:`~repertoire.studies._refinement_common.soccer_duration_models`); where no
    angle does, over all angles (the models extrapolate; ``out_of_range`` flags it). With
    the dribble in the horizon (h >= 2) the angle is searched only where the plan settles
    the dribble's collect mode (``_refinement_common.mode_settled_headings``), each such
    interval on its own; the cheaper wins. Subgoals from which the approach failure tree
    predicts the approach touches the ball are INVALID (section 7.2's Algorithm 4,
    :func:`~repertoire.studies._refinement_common.approach_succeeds`); only where it
    predicts failure for every subgoal found is the plan refined without it. Returns
    the angle wrapped to ``[-pi, pi]``.
    """
    from repertoire.planning.plans import Range, refinement_problem
    from repertoire.planning.refinement import refine_sequence

    approach, dribble = load_duration_models(config.models_dir)
    plan = instantiated_plan(start, dest, config)
    # the speed at the ball is the approach's v_g and the dribble's v: search it where both
    # models saw data (trained_range)
    speed = plan.ranges["pos2.v"]
    if not speed.is_bound:
        narrowed = trained_range(speed.lo, speed.hi, ((approach, "v_g"), (dribble, "v")))
        plan = dataclasses.replace(plan, ranges={**plan.ranges, "pos2.v": Range(*narrowed)})
    plans = [plan]
    if horizon >= 2 and not plan.ranges["pos2.phi"].is_bound:
        # the dribble in view: only headings whose collect mode the plan settles
        plans = [
            dataclasses.replace(plan, ranges={**plan.ranges, "pos2.phi": Range(lo, hi)})
            for lo, hi in mode_settled_headings(dest, config)
        ]
    succeeds = {0: approach_succeeds(load_failure_model(config.models_dir), config)}
    best = None
    # no valid subgoal inside the data: the models extrapolate; none predicted to succeed
    # at all: the failure tree is set aside (the plan kept, as subgoal assertion does)
    for checked, within_data in ((True, True), (True, False), (False, True), (False, False)):
        models = soccer_duration_models(approach, dribble, config, within_data=within_data)
        for candidate in plans:
            problem = refinement_problem(candidate, models, succeeds=succeeds if checked else None)
            result = refine_sequence(problem, horizon, config.solver, seed=seed)
            if best is None or result.cost < best[2].cost:
                best = (candidate, problem, result)
        if np.isfinite(best[2].cost):
            break
    plan, problem, result = best
    # bound identities too: with approach_v_max = 0 the approach speed is not free
    values = {pid: r.lo for pid, r in plan.ranges.items() if r.is_bound}
    values |= dict(zip(problem.names, result.params, strict=True))
    phi = math.remainder(float(values["pos2.phi"]), 2.0 * math.pi)
    return phi, values["pos2.v"], result.cost


def run_episode(config: RefinementSoccerConfig, seed: int) -> RefinementSoccerRecord:
    """Refines the situation's subgoal with h = 1 and h = 2 and executes both plans."""
    config.validate()
    t0 = time.perf_counter()
    start, dest = sample_situation(config, np.random.default_rng(seed))
    subgoals = [refine_subgoal(config, start, dest, h, seed) for h in (1, 2)]
    wall_refine = time.perf_counter() - t0
    out, moved, held = [], [], []
    for phi_a, v_a, predicted in subgoals:
        targets = [approach_target(phi_a, v_a, config.approach_distance), dest]
        run = run_plan(config, start, targets, dribble=True)
        t = run.finish_times[-1] if run.status == "SUCCEEDED" else math.nan
        out += [float(phi_a), float(v_a), float(predicted), float(t), run.status]
        moved.append(float(run.ball_moved_m))
        held.append(run.ball_held)
    return RefinementSoccerRecord(
        *map(float, start),
        *map(float, dest[:3]),
        *out,
        wall_refine_s=wall_refine,
        wall_time_s=time.perf_counter() - t0,
        ball_moved_1=moved[0],
        ball_moved_2=moved[1],
        ball_held_1=held[0],
        ball_held_2=held[1],
    )


def outcome_sentence(records) -> str:
    """Per horizon how the plans that did not succeed ended (statuses, balls held).

    A plan succeeds only when its DribbleBall delivers the ball (held at the destination);
    a plan that failed or timed out may still hold the ball (a dribble that ran out of
    time on the way).
    """
    parts = []
    for h in (1, 2):
        failed = [r for r in records if getattr(r, f"status_{h}") != "SUCCEEDED"]
        kinds = sorted({getattr(r, f"status_{h}") for r in failed})
        counts = ", ".join(
            f"{sum(getattr(r, f'status_{h}') == k for r in failed)} {k}" for k in kinds
        )
        held = sum(bool(getattr(r, f"ball_held_{h}")) for r in failed)
        parts.append(
            f"h = {h} {len(failed)}" + (f" ({counts}; {held} holding the ball)" if failed else "")
        )
    return (
        "A plan succeeds only when it delivers the ball (DribbleBall succeeds with it held at "
        f"the destination); plans that did not: {', '.join(parts)}."
    )


def situation_features(records) -> np.ndarray:
    """``(n, 5)`` features of a situation (section 6.3.2): how far and how turned.

    Columns: distance start -> ball, |angle to the ball| from the start heading, |turn
    at the ball| between the start -> ball and ball -> destination directions, start
    speed, ball -> destination distance.
    """
    from repertoire.diagrams.soccer import BALL_POSITION

    bx, by = BALL_POSITION
    rows = []
    for r in records:
        to_ball = math.atan2(by - r.y, bx - r.x)
        to_dest = math.atan2(r.dest_y - by, r.dest_x - bx)
        rows.append(
            [
                math.hypot(bx - r.x, by - r.y),
                abs(math.remainder(to_ball - r.phi, 2 * math.pi)),
                abs(math.remainder(to_dest - to_ball, 2 * math.pi)),
                r.v,
                math.hypot(r.dest_x - bx, r.dest_y - by),
            ]
        )
    return np.array(rows, dtype=float).reshape(-1, len(SITUATION_FEATURES))


def paired_improvement(t1: np.ndarray, t2: np.ndarray) -> tuple[float, float]:
    """The paper's mean improvement ``mean(1 - t2/t1)`` and the paired t-test p-value.

    Either is NaN where it is undefined: the improvement without pairs, p with fewer
    than two pairs or identical paired times (no variance to test); :func:`paired_cells`
    says which in a table.
    """
    from scipy.stats import ttest_rel

    t1, t2 = np.asarray(t1, dtype=float), np.asarray(t2, dtype=float)
    improvement = float(np.mean(1 - t2 / t1)) if t1.size else math.nan
    if t1.size < 2 or np.array_equal(t1, t2):
        return improvement, math.nan
    return improvement, float(ttest_rel(t1, t2).pvalue)


def paired_cells(t1: np.ndarray, t2: np.ndarray) -> list[str]:
    """Table cells ``n, mean t1, mean t2, improvement, p`` of paired times, "n/a" with why.

    Args:
        t1: the first (baseline) time of each pair [s].
        t2: the second time of each pair [s].

    Returns:
        Five strings; a figure the pairs do not define reads ``n/a (...)``, not ``nan``.
    """
    n = len(t1)
    improvement, p = paired_improvement(t1, t2)
    if n == 0:
        return ["0", "n/a", "n/a", "n/a (no paired episode)", "n/a (no paired episode)"]
    if n < 2:
        p_cell = f"n/a ({n} paired episode, need >= 2)"
    elif not math.isfinite(p):
        p_cell = "n/a (paired times identical)"
    else:
        p_cell = f"{p:.2g}"
    return [str(n), f"{np.mean(t1):.2f}", f"{np.mean(t2):.2f}", f"{improvement:.1%}", p_cell]


def refinement_sentence(solver: str, t1: np.ndarray, t2: np.ndarray, both: list) -> str:
    """The sentence comparing paired h = 1 and h = 2 runs: faster / slower counts, predictions.

    Args:
        solver: the refinement's solver name.
        t1: h = 1 time of each pair [s].
        t2: h = 2 time of each pair [s].
        both: the paired records (``predicted_1``/``predicted_2`` fields).
    """
    predicted = (
        f"{np.mean([r.predicted_1 for r in both]):.2f} / "
        f"{np.mean([r.predicted_2 for r in both]):.2f} s."
        if both
        else "-"
    )
    return (
        f"Refinement ({solver}) faster in {int(np.sum(t2 < t1))}, slower in "
        f"{int(np.sum(t2 > t1))}. Predicted plan time (models) h = 1 / h = 2: {predicted}"
    )


def paired_succeeded(records) -> tuple[list, np.ndarray, np.ndarray, float, float]:
    """The records whose h = 1 and h = 2 plans both succeeded, their times, improvement and p.

    Returns:
        ``(both, t1, t2, improvement, p)`` over records with ``status_1``/``status_2``
        and ``time_1``/``time_2`` fields.
    """
    both = [r for r in records if r.status_1 == r.status_2 == "SUCCEEDED"]
    t1 = np.array([r.time_1 for r in both])
    t2 = np.array([r.time_2 for r in both])
    return (both, t1, t2, *paired_improvement(t1, t2))


def summarize(
    records: list[RefinementSoccerRecord], config: RefinementSoccerConfig, out_dir: Path
) -> dict[str, Path]:
    """Writes Table 3, the section 6.3.2 selective refinement and a paired-time figure."""
    from sklearn.tree import DecisionTreeClassifier, export_text

    out_dir = Path(out_dir)
    both, t1, t2, _, _ = paired_succeeded(records)
    n = len(records)
    ok1 = sum(r.status_1 == "SUCCEEDED" for r in records)
    ok2 = sum(r.status_2 == "SUCCEEDED" for r in records)
    paper = PAPER_TABLE3_SOCCER_SIM
    md = [
        "## Table 3: subgoal refinement, soccer (simulated), executed episodes",
        "",
        "| | a | n | t̄1 (s) | t̄2 (s) | t̄2/1 | p |",
        "|---|---|---|---|---|---|---|",
        f"| paper | 2 | {paper['n']} | {paper['t1']} | {paper['t2']} | "
        f"{paper['improvement']:.1%} | {paper['p']:.2f} |",
        "| ours | 2 | " + " | ".join(paired_cells(t1, t2)) + " |",
        "",
        f"{n} episodes; plan succeeded with h = 1 in {ok1}, with h = 2 in {ok2}; the table "
        f"pairs the {len(both)} where both succeeded. "
        + refinement_sentence(config.solver, t1, t2, both)
        + " "
        + outcome_sentence(records),
        "",
    ]
    # section 6.3.2: predict from the situation whether refinement helps
    train, test = both[0::2], both[1::2]  # records come in seed order
    if len(train) >= 20 and len(test) >= 2:
        X = situation_features(train)
        y = np.array([r.time_2 < r.time_1 for r in train])
        tree = DecisionTreeClassifier(max_depth=2, min_samples_leaf=10, random_state=0)
        tree.fit(X, y)
        Xt = situation_features(test)
        yt = np.array([r.time_2 < r.time_1 for r in test])
        pred = tree.predict(Xt)
        a1 = np.array([r.time_1 for r in test])
        a2 = np.array([r.time_2 for r in test])
        sel = np.where(pred, a2, a1)
        always, p_always = paired_improvement(a1, a2)[0], paired_cells(a1, a2)[4]
        selective, p_sel = paired_improvement(a1, sel)[0], paired_cells(a1, sel)[4]
        md += [
            "## Section 6.3.2: refine only where a decision tree predicts it helps",
            "",
            f"Tree (depth <= 2) trained on {len(train)} paired episodes (every other one), "
            f"tested on {len(test)} others.",
            "",
            "| | tree accuracy | improvement, always refine | improvement, selective |",
            "|---|---|---|---|",
            f"| paper | {PAPER_SELECTIVE['tree_accuracy']:.0%} | "
            f"{PAPER_SELECTIVE['always']:.1%} | {PAPER_SELECTIVE['selective']:.1%} |",
            f"| ours | {np.mean(pred == yt):.0%} | {always:.1%} (p {p_always}) | "
            f"{selective:.1%} (p {p_sel}) |",
            "",
            f"Refinement applied to {int(pred.sum())} of {len(test)} test episodes; it "
            f"truly helped in {int(yt.sum())} of the {len(test)}.",
            "",
            "```",
            export_text(tree, feature_names=list(SITUATION_FEATURES)),
            "```",
        ]
    tables = out_dir / "refinement_soccer_tables.md"
    tables.write_text("\n".join(md) + "\n")
    figure = paired_times_figure(
        t1, t2, f"Subgoal refinement: mean improvement {paired_cells(t1, t2)[3]} (paper 6.6%)",
        out_dir / "refinement_soccer_paired.png",
    )  # fmt: skip
    out = {"tables": tables, "paired": figure}
    if both:  # the situation where greedy and refined angles differ most
        turn = [abs(math.remainder(r.phi_2 - r.phi_1, 2 * math.pi)) for r in both]
        example = both[int(np.argmax(turn))]
        out["polar"] = fig11_polar(example, config, out_dir / "refinement_soccer_fig11.png")
    return out


def paired_times_figure(t1: np.ndarray, t2: np.ndarray, title: str, path: Path) -> Path:
    """Scatter of paired executed plan times, greedy (x) vs refined (y), with the diagonal."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(5.5, 5.0), layout="constrained")
    ax = fig.add_subplot()
    if len(t1):
        ax.scatter(t1, t2, s=8, alpha=0.6, label=f"episodes (n = {len(t1)})")
        lim = [min(t1.min(), t2.min()) * 0.95, max(t1.max(), t2.max()) * 1.05]
        ax.plot(lim, lim, "k--", lw=1, label="equal time")
        ax.set_xlim(lim)
        ax.set_ylim(lim)
        ax.legend(loc="upper left")
    ax.set_xlabel("executed plan time, greedy h = 1 (s)")
    ax.set_ylabel("executed plan time, refined h = 2 (s)")
    ax.set_title(title, fontsize=10)
    fig.savefig(path, dpi=110)
    return path


def fig11_polar(record: RefinementSoccerRecord, config: RefinementSoccerConfig, path: Path):
    """Fig. 11 for one situation: predicted durations over the approach angle.

    Three polar plots (approach, dribble, their sum) of the models' predictions at the
    refined approach speed, with the greedy (h = 1) and refined (h = 2) angles marked.
    """
    from matplotlib.figure import Figure
    from repertoire.studies._refinement_common import approach_features, dribble_features

    approach, dribble = load_duration_models(config.models_dir)
    theta = np.linspace(-np.pi, np.pi, 361)
    start = [record.x, record.y, record.phi, record.v]
    dest = [record.dest_x, record.dest_y, record.dest_phi, 0.0]
    d = config.approach_distance
    t_a = approach.predict(approach_features(start, theta, record.v_2, d))
    t_d = dribble.predict(dribble_features(theta, record.v_2, dest, d))
    fig = Figure(figsize=(12.0, 4.6), layout="constrained")
    for k, (values, title) in enumerate(
        ((t_a, "approachBall"), (t_d, "dribbleBall"), (t_a + t_d, "sum (refinement's cost)"))
    ):
        ax = fig.add_subplot(1, 3, k + 1, projection="polar")
        ax.plot(theta, values, color="tab:blue", label="predicted duration (s, radial)")
        for phi, style, label in ((record.phi_1, "tab:orange", "greedy h = 1"),
                                  (record.phi_2, "tab:green", "refined h = 2")):  # fmt: skip
            ax.plot([phi, phi], [0, values.max()], color=style, lw=2, label=f"{label} angle")
        ax.set_title(title)
        ax.set_rlabel_position(200)
        if k == 0:
            ax.legend(loc="upper left", bbox_to_anchor=(-0.25, -0.02), fontsize=8)
    fig.suptitle(
        f"Fig. 11 for one situation: approach angle at the ball (angular), speed "
        f"{record.v_2:.2f} m/s; executed plan times {record.time_1:.2f} s (h = 1) and "
        f"{record.time_2:.2f} s (h = 2)"
    )
    fig.savefig(path, dpi=110)
    return path


def demo_config() -> RefinementSoccerConfig:
    """The demo config (the shared defaults)."""
    return RefinementSoccerConfig()


def smoke_config() -> RefinementSoccerConfig:
    """A tiny config for tests: starts near the ball, short dribbles, shipped models."""
    return RefinementSoccerConfig(
        x_range=[-0.2, 0.2],
        y_range=[0.0, 0.6],
        dribble_distance_range=[0.6, 0.7],
        timeout=8.0,
        dribble_gains={"timeout": 10.0},
    )


register_study(
    "refinement_soccer",
    config_type=RefinementSoccerConfig,
    record_type=RefinementSoccerRecord,
    run_episode=run_episode,
    description="soccer plans refined greedily (h = 1) and with h = 2, executed: Table 3",
    summarize=summarize,
    demo_config=demo_config,
    demo_episodes=8,
    smoke_config=smoke_config,
).run_if_main(__name__)
