"""Pieces shared by the footstep planning studies (static and dynamic obstacles).

The leading underscore keeps the study registry from importing this module as a study.
"""

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from repertoire.planning.footstep import ActionTable, PlannerOptions


def load_table(table_path: str) -> "ActionTable":
    """The action table a study config names, or the nominal table for an empty path.

    Imported lazily, as the studies do, so the study registry's discovery stays light.

    Args:
        table_path: action table file (.json/.npz); empty for the nominal table.
    """
    from repertoire.planning.footstep import ActionTable, nominal_action_table

    return ActionTable.load(table_path) if table_path else nominal_action_table()


def planner_options(config, **options) -> "PlannerOptions":
    """The footstep planner's options from a study config's planner fields.

    Args:
        config: a config with ``time_limit_s``, ``heuristic_weight``, ``max_expansions``
            and ``swing_clearance_m``.
        **options: further ``PlannerOptions`` fields (e.g. ``heuristic``).
    """
    from repertoire.planning.footstep import PlannerOptions

    return PlannerOptions(
        time_limit=config.time_limit_s,
        heuristic_weight=config.heuristic_weight,
        max_expansions=config.max_expansions,
        swing_clearance=config.swing_clearance_m,
        **options,
    )


def percentile(values: Sequence[float], q: float) -> float:
    """``np.percentile`` of the values, NaN for none.

    Args:
        values: the sample.
        q: percentile in [0, 100].
    """
    return float(np.percentile(values, q)) if len(values) else float("nan")


NONE_OK = "n/a (no successful plan)"
"""What a table shows for the figures of successful plans when no plan succeeded."""


def markdown_table(rows: Sequence[tuple[str, str]]) -> str:
    """A two-column ``| quantity | value |`` Markdown table.

    Args:
        rows: ``(quantity, value)`` pairs.
    """
    lines = ["| quantity | value |", "|---|---|"] + [f"| {a} | {b} |" for a, b in rows]
    return "\n".join(lines) + "\n"


def planner_rows(
    records: Sequence, *, steps_label: str, steps_over_label: str, time_digits: int
) -> dict[str, tuple[str, str]]:
    """Table rows every footstep study reports, keyed for placing them in its own table.

    The records need ``success``, ``steps``, ``steps_over``, ``nodes_expanded`` and
    ``wall_plan_time_s``.

    Args:
        records: the episodes.
        steps_label: label of the steps row.
        steps_over_label: label of the mean steps-over-obstacles row.
        time_digits: decimals of the plan times.

    Returns:
        rows under ``success``, ``steps``, ``steps_over``, ``plan_time`` and ``nodes``.
    """
    n = len(records)
    ok = [r for r in records if r.success]
    steps = [r.steps for r in ok]
    times = [r.wall_plan_time_s for r in records]
    nodes = [r.nodes_expanded for r in records]
    d = time_digits
    return {
        "success": (
            "footstep planner success",
            f"{len(ok)}/{n} ({100 * len(ok) / max(n, 1):.1f} %)",
        ),
        "steps": (
            steps_label,
            f"{percentile(steps, 50):.0f} [{min(steps)}, {max(steps)}]" if ok else NONE_OK,
        ),
        "steps_over": (
            steps_over_label,
            f"{np.mean([r.steps_over for r in ok]):.2f}" if ok else NONE_OK,
        ),
        "plan_time": (
            "plan time median / 90th pct / max (s)",
            f"{percentile(times, 50):.{d}f} / {percentile(times, 90):.{d}f} / "
            f"{max(times, default=0):.{d}f}",
        ),
        "nodes": (
            "nodes expanded median / 90th pct",
            f"{percentile(nodes, 50):.0f} / {percentile(nodes, 90):.0f}",
        ),
    }
