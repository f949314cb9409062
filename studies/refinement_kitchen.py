"""Subgoal refinement in the kitchen, executed: greedy (h = 1) vs refined (h = 2).

Table 3's kitchen rows of Stulp & Beetz (JAIR 2008): scenario 1 carries a cup from one
table to the other, scenario 2 two cups (:mod:`repertoire.studies._kitchen_plan` builds
the plans: 10 and 21 actions, 9 free parameters per cup). Each episode samples the
robot's start, the cups' places on ``table_0`` and the put targets on ``table_1``,
refines the free parameters with the learned kitchen duration trees once greedily (h =
1: every subgoal for its own action) and once with h = 2 (the receding horizon of
:func:`~repertoire.planning.refinement.refine_sequence`), and executes both plans in
physics with :func:`~repertoire.diagrams.kitchen.run_kitchen_sequence`. Every time in
the table is an executed time (the sum of the actions' durations).

``summarize`` writes the Table 3 row (mean times, mean per-episode improvement ``1 -
t2/t1``, paired t-test) beside the paper's and a paired-time figure.

Run it with ``python -m repertoire.studies.refinement_kitchen --help`` (``scenario: 2``
in a config file for two cups).
"""

import dataclasses
import math
import time
from pathlib import Path

import numpy as np
from repertoire.studies._kitchen_plan import (
    KitchenPlanConfig,
    kitchen_problem,
    load_kitchen_models,
    run_kitchen_plan,
    sample_situation,
)
from repertoire.studies.engine import register_study

#: Table 3 of Stulp & Beetz, kitchen rows: actions, episodes, t1, t2, improvement, p.
PAPER_TABLE3_KITCHEN = {
    1: {"a": 4, "n": 100, "t1": 46.5, "t2": 41.5, "improvement": 0.100, "p": 0.00},
    2: {"a": 13, "n": 100, "t1": 91.7, "t2": 85.4, "improvement": 0.066, "p": 0.00},
}


@dataclasses.dataclass
class RefinementKitchenRecord:
    """One kitchen situation executed with greedy and refined subgoals.

    Attributes:
        start: the robot's start ``[x, y, phi, v]``.
        cups: ``cup_0`` and ``cup_1`` centres, flattened.
        targets: the put targets, flattened.
        params_1: the greedy (h = 1) free parameters.
        predicted_1: the models' predicted plan duration at them [s].
        durations_1: each executed action's duration [s].
        time_1: the executed plan's duration [s] (NaN unless it succeeded).
        status_1: the executed plan's status (``SUCCEEDED``, ``MISSED``, the failed
            action's status, or ``NO_PLAN`` when refinement found no parameters every
            precondition accepts: not executed).
        cup_errors_1: the fetched cups' final distances from their targets [m].
        params_2, predicted_2, durations_2, time_2, status_2, cup_errors_2: the same with
            h = 2.
        wall_refine_s: wall time of both refinements (timing field).
        wall_time_s: wall time of the episode (timing field).
    """

    start: list[float]
    cups: list[float]
    targets: list[float]
    params_1: list[float]
    predicted_1: float
    durations_1: list[float]
    time_1: float
    status_1: str
    cup_errors_1: list[float]
    params_2: list[float]
    predicted_2: float
    durations_2: list[float]
    time_2: float
    status_2: str
    cup_errors_2: list[float]
    wall_refine_s: float
    wall_time_s: float


def refine_kitchen(config: KitchenPlanConfig, start, cups, targets, horizon: int, seed: int):
    """The refined free parameters and the predicted plan duration for a horizon."""
    from repertoire.planning.refinement import refine_sequence

    models = load_kitchen_models(config.models_dir)
    problem, _ = kitchen_problem(start, cups, targets, config, models)
    result = refine_sequence(problem, horizon, config.solver, seed=seed)
    return result.params, float(result.cost)


def run_episode(config: KitchenPlanConfig, seed: int) -> RefinementKitchenRecord:
    """Refines the situation's plan with h = 1 and h = 2 and executes both."""
    config.validate()
    t0 = time.perf_counter()
    start, cups, targets = sample_situation(config, np.random.default_rng(seed))
    refined = [refine_kitchen(config, start, cups, targets, h, seed) for h in (1, 2)]
    wall_refine = time.perf_counter() - t0
    out: list = []
    for params, predicted in refined:
        values = [float(p) for p in params]
        if not math.isfinite(predicted):  # no parameters every precondition accepts
            out += [values, predicted, [], math.nan, "NO_PLAN", []]
            continue
        run = run_kitchen_plan(config, start, cups, targets, params)
        t = run.total if run.status == "SUCCEEDED" else math.nan
        out += [values, predicted, run.durations, t, run.status, run.cup_errors]
    return RefinementKitchenRecord(
        [float(s) for s in start],
        [float(c) for c in np.ravel(cups)],
        [float(t) for t in np.ravel(targets)],
        *out,
        wall_refine_s=wall_refine,
        wall_time_s=time.perf_counter() - t0,
    )


def summarize(
    records: list[RefinementKitchenRecord], config: KitchenPlanConfig, out_dir: Path
) -> dict[str, Path]:
    """Writes the scenario's Table 3 row beside the paper's and a paired-time figure."""
    from repertoire.studies.refinement_soccer import (
        paired_cells,
        paired_succeeded,
        paired_times_figure,
        refinement_sentence,
    )

    out_dir = Path(out_dir)
    both, t1, t2, _, _ = paired_succeeded(records)
    paper = PAPER_TABLE3_KITCHEN[config.scenario]
    from repertoire.studies._kitchen_plan import action_names

    names = action_names(config.scenario)
    statuses = {h: {} for h in (1, 2)}
    for r in records:
        for h, s in ((1, r.status_1), (2, r.status_2)):
            statuses[h][s] = statuses[h].get(s, 0) + 1
    name = f"Kitchen (scenario {config.scenario})"
    md = [
        f"## Table 3: subgoal refinement, {name}, executed episodes",
        "",
        "| | a | n | t̄1 (s) | t̄2 (s) | t̄2/1 | p |",
        "|---|---|---|---|---|---|---|",
        f"| paper | {paper['a']} | {paper['n']} | {paper['t1']} | {paper['t2']} | "
        f"{paper['improvement']:.1%} | {paper['p']:.2f} |",
        f"| ours | {len(names)} | " + " | ".join(paired_cells(t1, t2)) + " |",
        "",
        f"{len(records)} situations; plan outcomes with h = 1: {statuses[1]}, with h = 2: "
        f"{statuses[2]} (MISSED: every action succeeded but a cup ended more than "
        f"{config.deliver_tolerance} m from its target; NO_PLAN: no valid parameters, not "
        f"executed). The table pairs the {len(both)} "
        "situations where both plans delivered. "
        + refinement_sentence(config.solver, t1, t2, both),
    ]
    if both:
        d1 = np.array([r.durations_1 for r in both])
        d2 = np.array([r.durations_2 for r in both])
        md += [
            "",
            "Mean executed duration per action (s):",
            "",
            "| action | " + " | ".join(f"{i}:{a}" for i, a in enumerate(names)) + " |",
            "|---|" + "---|" * d1.shape[1],
            "| h = 1 | " + " | ".join(f"{v:.2f}" for v in d1.mean(axis=0)) + " |",
            "| h = 2 | " + " | ".join(f"{v:.2f}" for v in d2.mean(axis=0)) + " |",
        ]
    tables = out_dir / f"refinement_kitchen_{config.scenario}_tables.md"
    tables.write_text("\n".join(md) + "\n")
    figure = paired_times_figure(
        t1, t2,
        f"{name}: mean improvement {paired_cells(t1, t2)[3]} (paper {paper['improvement']:.1%})",
        out_dir / f"refinement_kitchen_{config.scenario}_paired.png",
    )  # fmt: skip
    return {"tables": tables, "paired": figure}


def demo_config() -> KitchenPlanConfig:
    """The demo config: scenario 1 with the shipped models."""
    return KitchenPlanConfig()


def smoke_config() -> KitchenPlanConfig:
    """A tiny config for tests: scenario 1, the start near the tables."""
    return KitchenPlanConfig(x_range=[0.4, 0.8], y_range=[-0.2, 0.2])


register_study(
    "refinement_kitchen",
    config_type=KitchenPlanConfig,
    record_type=RefinementKitchenRecord,
    run_episode=run_episode,
    description="kitchen cup-fetching plans refined greedily (h = 1) and with h = 2, "
    "executed: Table 3 kitchen rows",
    summarize=summarize,
    demo_config=demo_config,
    demo_episodes=2,
    smoke_config=smoke_config,
).run_if_main(__name__)
