"""Shared summary pieces of the action studies: Table 1 rows, failure tables, learning curves.

Each action study (``actions_goto_pose``, ``actions_dribble``,
``actions_arm_reach``, ``actions_kitchen``) fits a duration model tree on its
succeeded episodes and a pessimistic failure tree on all of them with
:func:`~repertoire.planning.action_models.fit_action_model` (3/4 train, 1/4
held out), and writes the paper's Table 1 row beside ours.
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


def failure_table(
    records: Sequence[Any],
    features: dict[str, Callable[[Any], float]],
    heading: str,
    paper_accuracy: float | None = None,
) -> tuple[list[str], Any]:
    """Markdown of the pessimistic failure tree's held-out confusion matrix.

    Args:
        records: all episodes (with a ``failed`` flag).
        features: feature name -> function of a record.
        heading: the section's title.
        paper_accuracy: the paper's fraction correct, printed beside ours.

    Returns:
        ``(markdown lines, failure FittedModel or None when one class)``.
    """
    from repertoire.planning.action_models import fit_action_model

    n_fail = sum(bool(r.failed) for r in records)
    md = [f"## {heading}", ""]
    if not 0 < n_fail < len(records):
        md.append(f"{n_fail} of {len(records)} episodes failed: no failure tree (one class).")
        return md, None
    fail = fit_action_model(list(records), features, "failed")
    (tn, fp), (fn, tp) = fail.confusion
    paper = "" if paper_accuracy is None else f", paper ~{paper_accuracy:.0%}"
    md += [
        "| | predicted success | predicted failure |",
        "|---|---|---|",
        f"| actual success | {tn} | {fp} |",
        f"| actual failure | {fn} | {tp} |",
        "",
        f"Correct: ours {fail.accuracy:.1%}{paper}; missed failures (pessimism): {fn} of "
        f"{fn + tp}.",
    ]
    return md, fail


def table1_and_failure(
    action: str,
    records: Sequence[Any],
    done: Sequence[Any],
    features: dict[str, Callable[[Any], float]],
    paper: dict[str, float],
    failure_label: str,
    *,
    failure_heading: str | None = None,
    paper_accuracy: float | None = None,
) -> tuple[list[str], Any, Any]:
    """Markdown of Table 1 (duration) and the failure confusion matrix.

    Args:
        action: the action's name in the table.
        records: all episodes (failure tree).
        done: succeeded episodes (duration tree).
        features: feature name -> function of a record.
        paper: ``episodes`` (3/4 n_e), ``mean`` and ``mae`` of the paper's Table 1 row.
        failure_label: what the failure flag means, for the caption.
        failure_heading: the failure section's title (default from ``failure_label``).
        paper_accuracy: the paper's failure-tree fraction correct, if it gives one.

    Returns:
        ``(markdown lines, duration FittedModel, failure FittedModel or None)``.
    """
    from repertoire.planning.action_models import fit_action_model

    dur = fit_action_model(list(done), features, "duration")
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
    ]
    heading = failure_heading or f"Failure tree ({failure_label}), held-out quarter"
    fail_md, fail = failure_table(records, features, heading, paper_accuracy)
    md += [*fail_md, "", "## Duration tree rules", "", "```", dur.model.rules(), "```"]
    return md, dur, fail


def summarize_action_study(
    name: str,
    action: str,
    records: Sequence[Any],
    out_dir: Path,
    is_done: Callable[[Any], bool],
    features: dict[str, Callable[[Any], float]],
    paper: dict[str, float],
    failure_label: str,
    curve_title: str,
    *,
    preamble: str | None = None,
    polar_title: str | None = None,
    failure_heading: str | None = None,
    paper_accuracy: float | None = None,
) -> dict[str, Path]:
    """The summary of one action study: Table 1 and failure tree, learning curves, polar plot.

    Writes ``{name}_tables.md`` (or, below ``min_records()`` done episodes, why nothing
    was fitted), ``{name}_learning_curves.png`` and, with ``polar_title``,
    ``{name}_polar.png`` (Fig. 7) into ``out_dir``.

    Args:
        name: the study's name (the files' prefix).
        action: the action's name in Table 1.
        records: all episodes in seed order.
        out_dir: the output folder.
        is_done: whether a record's duration is learned (succeeded).
        features: feature name -> function of a record.
        paper: the paper's Table 1 row (see :func:`table1_and_failure`).
        failure_label: what the failure flag means, for the caption.
        curve_title: the learning curves' title.
        preamble: a line put before the tables.
        polar_title: the polar plot's title; None for no polar plot.
        failure_heading: the failure section's title (default from ``failure_label``).
        paper_accuracy: the paper's failure-tree fraction correct, if it gives one.

    Returns:
        Paths by name: ``tables``, ``learning_curves`` and ``polar`` (only ``tables`` when
        too few episodes succeeded).
    """
    out_dir = Path(out_dir)
    tables = out_dir / f"{name}_tables.md"
    done = [r for r in records if is_done(r)]
    if len(done) < min_records():
        return too_few_note(tables, len(records), len(done))
    md, dur, _ = table1_and_failure(
        action,
        records,
        done,
        features,
        paper,
        failure_label,
        failure_heading=failure_heading,
        paper_accuracy=paper_accuracy,
    )
    if preamble is not None:
        md.insert(0, preamble)
    tables.write_text("\n".join(md) + "\n")
    paths = {"tables": tables}
    paths["learning_curves"] = learning_curve_figure(
        records,
        is_done,
        features,
        paper["mae"],
        curve_title,
        out_dir / f"{name}_learning_curves.png",
        paper_accuracy=paper_accuracy,
    )
    if polar_title is not None:
        paths["polar"] = polar_duration_figure(
            dur.model, polar_title, out_dir / f"{name}_polar.png"
        )
    return paths


def learning_curve_figure(
    records: Sequence[Any],
    is_done: Callable[[Any], bool],
    features: dict[str, Callable[[Any], float]],
    paper_mae: float,
    title: str,
    path: Path,
    *,
    paper_accuracy: float | None = None,
    more_features: tuple[str, dict[str, Callable[[Any], float]]] | None = None,
) -> Path:
    """Held-out duration MAE and failure accuracy against the number of episodes (PNG).

    Args:
        records: all episodes in seed order (the first n are used at size n).
        is_done: whether a record's duration is learned (succeeded).
        features: feature name -> function of a record.
        paper_mae: the paper's MAE (a dotted line).
        title: the figure's title.
        path: the PNG to write.
        paper_accuracy: the paper's failure-tree accuracy (a dotted line), if any.
        more_features: ``(label, features)``: a second duration-MAE curve with other features.
    """
    from matplotlib.figure import Figure
    from repertoire.planning.action_models import fit_action_model

    # doubling sizes, the last one replaced by all records when they are within 25% of it
    sizes = [n for n in (40, 80, 160, 320, 640, 1280, 2560) if n * 1.25 < len(records)]
    sizes.append(len(records))
    curves: dict[str, tuple[list, list]] = {"duration MAE (s), held-out": ([], [])}
    if more_features is not None:
        curves[f"duration MAE (s), held-out, {more_features[0]}"] = ([], [])
    ns_f, accs = [], []
    for n in sizes:
        sub = list(records[:n])
        sub_done = [r for r in sub if is_done(r)]
        if len(sub_done) >= min_records():
            feature_sets = [features] + ([more_features[1]] if more_features else [])
            for (ns, maes), funcs in zip(curves.values(), feature_sets):
                ns.append(n)
                maes.append(fit_action_model(sub_done, funcs, "duration").mae)
        n_fail = sum(bool(r.failed) for r in sub)
        if 0 < n_fail < n and n >= min_records():
            ns_f.append(n)
            accs.append(fit_action_model(sub, features, "failed").accuracy)
    # two panels, not twin axes: on twin axes an MAE and an accuracy hid each other
    fig = Figure(figsize=(6.5, 6.0 if ns_f else 4.0), layout="constrained")
    axes = fig.subplots(2 if ns_f else 1, 1, sharex=True, squeeze=False)[:, 0]
    ax = axes[0]
    for (label, (ns, maes)), colour in zip(curves.items(), ("tab:blue", "tab:green")):
        ax.plot(ns, maes, "o-", color=colour, label=label)
    ax.axhline(paper_mae, color="tab:blue", ls=":", label="paper's MAE (Table 1)")
    ax.set_ylabel("duration MAE (s)")
    ax.set_ylim(bottom=0)
    ax.legend(loc="lower left", fontsize=8)
    if ns_f:  # a failure tree needs both outcomes
        ax2 = axes[1]
        ax2.plot(ns_f, accs, "s-", color="tab:red", label="failure tree accuracy, held-out")
        if paper_accuracy is not None:
            ax2.axhline(paper_accuracy, color="tab:red", ls=":", label="paper's accuracy")
        ax2.set_ylabel("failure tree: fraction correct")
        ax2.set_ylim(0, 1.05)  # a fraction of 1 drawn whole, not cut by the frame
        ax2.legend(loc="lower left", fontsize=8)
    for a in axes:
        a.set_xscale("log")
        a.set_xticks(sizes, [str(n) for n in sizes])
        a.minorticks_off()
    axes[-1].set_xlabel("episodes (log scale)")
    fig.suptitle(title)
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
    below_zero = 0
    for dist, colour in ((0.75, "tab:green"), (1.5, "tab:blue"), (2.5, "tab:purple")):
        start = np.column_stack(
            [dist * np.cos(theta), dist * np.sin(theta), theta + np.pi, np.zeros_like(theta)]
        )
        goal = np.tile([0.0, 0.0, 0.0, 0.0], (len(theta), 1))
        pred = model.predict(goto_pose_features(start, goal))
        below_zero += int(np.sum(pred < 0))
        # a polar radius cannot show a negative duration honestly: draw it at 0 and say so
        ax.plot(theta, np.maximum(pred, 0.0), color=colour,
                label=f"start {dist} m away, facing the goal")  # fmt: skip
    ax.set_rmin(0.0)
    if below_zero:
        title += f"\n({below_zero} of {3 * len(theta)} predictions below 0 s drawn at 0)"
    ax.set_title(title)
    ax.legend(loc="upper left", bbox_to_anchor=(-0.15, -0.05), fontsize=8)
    fig.savefig(path, dpi=110)
    return path
