"""Shared summary pieces of the action studies: Table 1 rows, failure tables, learning curves.

Each action study (``actions_dribble``, ``actions_arm_reach``) fits a duration
model tree on its succeeded episodes and a pessimistic failure tree on all of
them with :func:`~repertoire.planning.action_models.fit_action_model` (3/4
train, 1/4 held out), and writes the paper's Table 1 row beside ours.
"""

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from repertoire.planning.action_models.features import GOTO_POSE_FEATURES, goto_pose_features

# Table 7's goToPose features of a record with start (x, y, phi, v) and goal
# (x_g, y_g, phi_g, v_g) fields, by name (dribbleBall uses the same features).
POSE_FEATURE_FUNCS: dict[str, Callable[[Any], float]] = {
    name: (
        lambda r, j=j: float(
            goto_pose_features([r.x, r.y, r.phi, r.v], [r.x_g, r.y_g, r.phi_g, r.v_g])[j]
        )
    )
    for j, name in enumerate(GOTO_POSE_FEATURES)
}


def min_records() -> int:
    """Episodes needed to fit: ``MIN_EPISODES`` training episodes are 3/4 of them."""
    from repertoire.planning.action_models import MIN_EPISODES

    return MIN_EPISODES * 4 // 3 + 1


def too_few_note(path: Path, n: int, n_done: int) -> dict[str, Path]:
    """Writes why nothing was fitted; returns ``{"tables": path}``."""
    path.write_text(
        f"{n} episodes ({n_done} succeeded): too few to fit; at least {min_records()} "
        "are needed (of both kinds for the failure tree).\n"
    )
    return {"tables": path}


def table1_and_failure(
    action: str,
    records: Sequence[Any],
    done: Sequence[Any],
    features: dict[str, Callable[[Any], float]],
    paper: dict[str, float],
    failure_label: str,
) -> tuple[list[str], Any, Any]:
    """Markdown of Table 1 (duration) and the failure confusion matrix.

    Args:
        action: the action's name in the table.
        records: all episodes (failure tree).
        done: succeeded episodes (duration tree).
        features: feature name -> function of a record.
        paper: ``episodes`` (3/4 n_e), ``mean`` and ``mae`` of the paper's Table 1 row.
        failure_label: what the failure flag means, for the caption.

    Returns:
        ``(markdown lines, duration FittedModel, failure FittedModel or None)``.
    """
    from repertoire.planning.action_models import fit_action_model

    dur = fit_action_model(list(done), features, "duration")
    n_fail = sum(bool(r.failed) for r in records)
    fail = None
    if 0 < n_fail < len(records):
        fail = fit_action_model(list(records), features, "failed")
    md = [
        "## Table 1: duration model (held-out quarter)",
        "",
        "| action | episodes (3/4 train) | mean duration (s) | MAE (s) |",
        "|---|---|---|---|",
        f"| {action}, ours | {len(done)} ({dur.n_train}) | "
        f"{np.mean([r.duration for r in done]):.2f} | {dur.mae:.3f} |",
        f"| {action}, paper (Table 1) | {paper['episodes'] * 4 // 3} ({paper['episodes']}) | "
        f"{paper['mean']} | {paper['mae']} |",
        "",
        f"## Failure tree ({failure_label}), held-out quarter",
        "",
    ]
    if fail is None:
        md.append(f"{n_fail} of {len(records)} episodes failed: no failure tree (one class).")
    else:
        (tn, fp), (fn, tp) = fail.confusion
        md += [
            "| | predicted success | predicted failure |",
            "|---|---|---|",
            f"| actual success | {tn} | {fp} |",
            f"| actual failure | {fn} | {tp} |",
            "",
            f"Correct: {fail.accuracy:.1%}; missed failures (pessimism): {fn} of {fn + tp}.",
        ]
    md += ["", "## Duration tree rules", "", "```", dur.model.rules(), "```"]
    return md, dur, fail


def learning_curve_figure(
    records: Sequence[Any],
    is_done: Callable[[Any], bool],
    features: dict[str, Callable[[Any], float]],
    paper_mae: float,
    title: str,
    path: Path,
) -> Path:
    """Held-out duration MAE and failure accuracy against the number of episodes (PNG)."""
    from matplotlib.figure import Figure
    from repertoire.planning.action_models import fit_action_model

    # doubling sizes, the last one replaced by all records when they are within 25% of it
    sizes = [n for n in (40, 80, 160, 320, 640, 1280) if n * 1.25 < len(records)] + [len(records)]
    ns_d, maes, ns_f, accs = [], [], [], []
    for n in sizes:
        sub = list(records[:n])
        sub_done = [r for r in sub if is_done(r)]
        if len(sub_done) >= min_records():
            ns_d.append(n)
            maes.append(fit_action_model(sub_done, features, "duration").mae)
        n_fail = sum(bool(r.failed) for r in sub)
        if 0 < n_fail < n and n >= min_records():
            ns_f.append(n)
            accs.append(fit_action_model(sub, features, "failed").accuracy)
    fig = Figure(figsize=(6.5, 4.0), layout="constrained")
    ax = fig.add_subplot()
    ax.plot(ns_d, maes, "o-", color="tab:blue", label="duration MAE (s), held-out")
    ax.axhline(paper_mae, color="tab:blue", ls=":", label="paper's MAE (Table 1)")
    ax.set_xscale("log")
    ax.set_xlabel("episodes")
    ax.set_ylabel("MAE (s)")
    ax.set_ylim(bottom=0)
    h, lab = ax.get_legend_handles_labels()
    if ns_f:  # a failure tree needs both outcomes
        ax2 = ax.twinx()
        ax2.plot(ns_f, accs, "s-", color="tab:red", label="failure tree accuracy, held-out")
        ax2.set_ylabel("fraction correct")
        ax2.set_ylim(0, 1)
        h2, l2 = ax2.get_legend_handles_labels()
        h, lab = h + h2, lab + l2
    ax.legend(h, lab, loc="lower left", fontsize=8)
    ax.set_xticks(sizes, [str(n) for n in sizes])
    ax.minorticks_off()
    ax.set_title(title)
    fig.savefig(path, dpi=110)
    return path


def polar_duration_figure(model, title: str, path: Path) -> Path:
    """Fig. 7: a duration model's prediction around a goal at the origin facing +x.

    Starts at 0.75, 1.5 and 2.5 m in every direction, facing the goal, at rest.
    """
    from matplotlib.figure import Figure
    from repertoire.planning.action_models.features import goto_pose_features

    fig = Figure(figsize=(5.5, 5.0), layout="constrained")
    ax = fig.add_subplot(projection="polar")
    theta = np.linspace(-np.pi, np.pi, 181)
    for dist, colour in ((0.75, "tab:green"), (1.5, "tab:blue"), (2.5, "tab:purple")):
        start = np.column_stack(
            [dist * np.cos(theta), dist * np.sin(theta), theta + np.pi, np.zeros_like(theta)]
        )
        goal = np.tile([0.0, 0.0, 0.0, 0.0], (len(theta), 1))
        pred = model.predict(goto_pose_features(start, goal))
        ax.plot(theta, pred, color=colour, label=f"start {dist} m away, facing the goal")
    ax.set_title(title)
    ax.legend(loc="upper left", bbox_to_anchor=(-0.15, -0.05), fontsize=8)
    fig.savefig(path, dpi=110)
    return path
