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
t2/t1``, paired t-test) beside the paper's and a paired-time figure, and runs one
executed plan again (of the situation whose cups stand nearest each other) while tracing
it to draw how its fingers kept off the standing cups
(Reach and Put refuse a way whose fingers would enter a cup's disc grown by
``CUP_MARGIN``).

Run it with ``python -m repertoire.studies.refinement_kitchen --help`` (``scenario: 2``
in a config file for two cups). ``refinement_kitchen_far`` is the same study registered
with the cups on ``table_0``'s far side (``FAR_CUP_Y_RANGE``; ``repertoire study
refinement_kitchen_far``); the demo runs its first seed.
"""

import dataclasses
import functools
import math
import time
from pathlib import Path

import numpy as np
from repertoire.studies._kitchen_plan import (
    KitchenPlanConfig,
    action_names,
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
    """The refined free parameters and the predicted plan duration for a horizon.

    With ``config.arrival_check`` each window is searched first without checking the arm
    ways from the arrival tolerances' corners (8 more sweeps per way), then checked
    there: if its best plan is clear from them too it is kept (the sweeps only reject
    plans, so it is also the best of the checked ones the search found), else the window
    is searched again with them (a lazy constraint). The plan is checked with them at the
    end in any case (a window without free parameters is not searched).
    """
    from repertoire.planning.black_box import solve_de, solve_ga
    from repertoire.planning.refinement import refine_sequence

    models = load_kitchen_models(config.models_dir)
    sweeps = {"arrival": config.arrival_check}
    problem, _ = kitchen_problem(start, cups, targets, config, models, sweeps=sweeps)
    search = {"ga": solve_ga, "de": solve_de}[config.solver]

    def solve(sub):
        if not config.arrival_check:
            return search(sub, seed=seed)
        sweeps["arrival"] = False
        try:
            unswept = search(sub, seed=seed)
        finally:
            sweeps["arrival"] = True
        if not np.isfinite(unswept.cost) or np.isfinite(sub.cost(unswept.params)[0]):
            return unswept
        return search(sub, seed=seed)

    result = refine_sequence(problem, horizon, solve)
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
    records: list[RefinementKitchenRecord],
    config: KitchenPlanConfig,
    out_dir: Path,
    *,
    stem: str = "refinement_kitchen",
    label: str = "",
) -> dict[str, Path]:
    """Writes the scenario's Table 3 row beside the paper's and a paired-time figure.

    Args:
        records: the study's records.
        config: the config they were run with.
        out_dir: where the files go.
        stem: the files' name stem (``<stem>_<scenario>_tables.md``, ``_paired.png``,
            ``_cups.png``).
        label: added to the titles after the scenario (e.g. ``", far-side cups"``).

    Returns:
        Label -> path of each file written.
    """
    from repertoire.studies.refinement_soccer import (
        paired_cells,
        paired_succeeded,
        paired_times_figure,
        refinement_sentence,
    )

    out_dir = Path(out_dir)
    both, t1, t2, _, _ = paired_succeeded(records)
    paper = PAPER_TABLE3_KITCHEN[config.scenario]
    names = action_names(config.scenario)
    statuses = {h: {} for h in (1, 2)}
    for r in records:
        for h, s in ((1, r.status_1), (2, r.status_2)):
            statuses[h][s] = statuses[h].get(s, 0) + 1
    name = f"Kitchen (scenario {config.scenario}{label})"
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
    tables = out_dir / f"{stem}_{config.scenario}_tables.md"
    tables.write_text("\n".join(md) + "\n")
    figure = paired_times_figure(
        t1, t2,
        f"{name}:\nmean improvement {paired_cells(t1, t2)[3]} (paper {paper['improvement']:.1%})",
        out_dir / f"{stem}_{config.scenario}_paired.png",
    )  # fmt: skip
    out = {"tables": tables, "paired": figure}
    executed = [(r, h) for r in records for h in (2, 1) if getattr(r, f"status_{h}") != "NO_PLAN"]
    if executed:  # the situation whose two cups stand nearest each other (h = 2 first)
        record, h = min(executed, key=lambda e: cups_apart(e[0]))
        out["cups"] = standing_cups_figure(
            config, record, h, out_dir / f"{stem}_{config.scenario}_cups.png", label
        )
    return out


def cups_apart(record) -> float:
    """Horizontal distance between the centres of ``cup_0`` and ``cup_1`` of a record [m]."""
    cups = np.reshape(record.cups, (-1, 3))
    return float(np.hypot(*(cups[1, :2] - cups[0, :2])))


def table_0_steps(scenario: int) -> list[int]:
    """The plan steps in which the robot stands at ``table_0`` with its arm at work.

    The steps after an odd-numbered goToPose (the drive to a stand) up to the next one.

    Args:
        scenario: 1 or 2.
    """
    names = action_names(scenario)
    drives = np.cumsum([n == "goto_pose" for n in names])
    return [i for i, n in enumerate(names) if n != "goto_pose" and drives[i] % 2 == 1]


#: Clearance [m] below which the figure marks the gripper's path and draws the fingers.
CLOSE_M = 0.02


def engaged_steps(scenario: int, cup: int) -> range:
    """The plan steps in which ``cup`` does not stand (it is gripped, carried or let go).

    From the reach down into it to the reach up out of it once put (steps of
    :func:`~repertoire.studies._kitchen_plan.plan_steps`).

    Args:
        scenario: 1 or 2.
        cup: the cup's index (``cup_0``, ``cup_1``); a cup the scenario does not fetch
            stands throughout (an empty range).
    """
    if cup >= scenario:
        return range(0)
    fetch = len(action_names(1))
    first = cup * (fetch + 1)  # each earlier fetch and the reach up out of its cup
    return range(first + 3, min(first + fetch + 1, len(action_names(scenario))))


def standing_cups_figure(
    config: KitchenPlanConfig, record, h: int, out: Path, label: str = ""
) -> Path:
    """Top view and clearance of the fingers around the standing cups in one executed plan.

    Runs the plan of ``record``'s horizon ``h`` again with a
    :class:`~repertoire.studies._kitchen_plan.KitchenTracer`. Left: ``table_0`` from
    above, the cups' discs and the actions' ``CUP_MARGIN`` around them, the gripper
    centre's path (bold where the fingers come within ``CLOSE_M`` of a standing cup), the
    finger boxes where they came nearest to each standing cup, and where each cup ended.
    Right: over time, the finger boxes' clearance from each standing cup: the larger of
    their horizontal gap from its disc and their bottom's height above its rim, so the
    fingers touch the cup where it is at most 0; samples where they are inside the cup's
    disc grown by ``CUP_MARGIN`` and below its rim (the region Reach and Put keep their
    planned ways out of: the margin widens a cup, it does not raise it) are marked.

    Args:
        config: the study config.
        record: the episode.
        h: the horizon whose plan to run (1 or 2).
        out: the PNG to write.
        label: added to the title after the scenario.
    """
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import Circle, Patch, Rectangle
    from matplotlib.transforms import Affine2D
    from repertoire.diagrams.kitchen import KITCHEN_OBSTACLES
    from repertoire.models.diffdrive.generate import CUP_HALF_HEIGHT, CUP_RADIUS
    from repertoire.studies._kitchen_plan import (
        FETCHED,
        KitchenTracer,
        executed_steps,
        plan_geometry,
        run_kitchen_plan,
    )
    from repertoire.systems.kitchen_actions import CUP_MARGIN
    from repertoire.systems.kitchen_geometry import (
        arm_forward,
        chassis_points_to_world,
        finger_boxes,
        finger_disc_gaps,
    )

    tracer = KitchenTracer()
    cups = np.reshape(record.cups, (-1, 3))
    targets = np.reshape(record.targets, (-1, 3))
    params = getattr(record, f"params_{h}")
    run = run_kitchen_plan(config, record.start, cups, targets, params, on_sample=tracer)
    # the tracer counts executed steps; a drive via a corner runs two for one plan action
    _, owner = executed_steps(plan_geometry(params, cups, targets), 0, record.start, cups, config)
    rows, steps = tracer.rows, np.asarray(owner, dtype=int)[tracer.steps]
    every_s = tracer.every * config.time_step  # the rows' spacing [s]
    t, base, q, fingers = rows[:, 0], rows[:, 1:4], rows[:, 4:7], rows[:, 7:9]
    cup_at = rows[:, 9:15].reshape(-1, 2, 3)
    clearance = np.full((len(rows), 2), np.nan)
    grown = np.zeros((len(rows), 2), dtype=bool)  # inside the disc + CUP_MARGIN, below the rim
    for i in range(len(rows)):
        span = [[fingers[i, 0]] * 2, [fingers[i, 1]] * 2]
        rims = cup_at[i, :, 2] + CUP_HALF_HEIGHT
        discs = np.column_stack([cup_at[i, :, :2], np.full(2, CUP_RADIUS), rims])
        centres, _, halves = finger_boxes(base[i], q[i], span)
        above = float(np.min(centres[0, :, 2] - halves[:, 2])) - rims  # bottom over the rim
        gaps = finger_disc_gaps(base[i], q[i], span, discs)[0]
        clearance[i] = np.maximum(gaps, above)
        grown[i] = (gaps <= CUP_MARGIN) & (above <= 0.0)
    standing = np.column_stack(
        [~np.isin(steps, list(engaged_steps(config.scenario, k))) for k in range(2)]
    )
    fig = Figure(figsize=(13, 7.4), layout="constrained")
    top, ax = fig.subplots(1, 2, width_ratios=[1, 1.15])
    cx, cy, yaw, hx, hy, _ = KITCHEN_OBSTACLES[1]  # table_0
    turn = Affine2D().rotate_around(cx, cy, yaw) + top.transData
    top.add_patch(
        Rectangle((cx - hx, cy - hy), 2 * hx, 2 * hy, fc="0.92", ec="0.5", transform=turn)
    )
    gripper = chassis_points_to_world(base, arm_forward(q))
    top.plot(gripper[:, 0], gripper[:, 1], color="0.6", lw=0.7)
    top.plot(base[:, 0], base[:, 1], color="tab:purple", lw=0.8, ls="--")
    close = np.where(np.any(standing & (clearance <= CLOSE_M), axis=1), 1.0, np.nan)
    top.plot(gripper[:, 0] * close, gripper[:, 1] * close, color="tab:blue", lw=2.5)
    colours = ("tab:orange", "tab:green")
    handles = [
        Patch(fc="0.92", ec="0.5", label="table_0"),
        Line2D([], [], color="0.6", lw=0.7, label="gripper centre's path"),
        Line2D([], [], color="tab:purple", lw=0.8, ls="--", label="chassis centre's path"),
        Line2D([], [], ls="", marker="o", ms=4, color="tab:purple", label="chassis at its stand"),
        Line2D(
            [],
            [],
            color="tab:blue",
            lw=2.5,
            label=f"... where the fingers are within {100 * CLOSE_M:g} cm of a standing cup",
        ),
        Line2D(
            [],
            [],
            color="k",
            ls="--",
            lw=0.8,
            label=f"cup disc + {1000 * CUP_MARGIN:g} mm margin up to the rim (Reach, Put)",
        ),
    ]
    for k, name in enumerate(FETCHED):
        start, colour = cup_at[0, k], colours[k]
        top.add_patch(Circle(start[:2], CUP_RADIUS, fc=colour, alpha=0.5, ec=colour))
        top.add_patch(Circle(start[:2], CUP_RADIUS + CUP_MARGIN, fill=False, ec="k", ls="--"))
        top.plot(*cup_at[-1, k, :2], "x", color="k", ms=6)
        gripped = np.flatnonzero(~standing[:, k])
        until = gripped[0] if gripped.size else len(rows)  # it stands until gripped
        moved = 1000 * np.max(np.linalg.norm(cup_at[:until, k] - start, axis=1), initial=0.0)
        role = "fetched" if k < config.scenario else "never fetched"
        when = " before it was gripped" if k < config.scenario else ""
        handles.append(
            Patch(fc=colour, alpha=0.5, label=f"{name} ({role}): moved {moved:.1f} mm{when}")
        )
        watched = np.flatnonzero(standing[:, k])
        i = watched[np.argmin(clearance[watched, k])]
        if clearance[i, k] <= CLOSE_M:  # the finger boxes where they came nearest
            centres, yaws, halves = finger_boxes(
                base[i], q[i], [[fingers[i, 0]] * 2, [fingers[i, 1]] * 2]
            )
            for c, half in zip(centres[0], halves, strict=True):
                tr = Affine2D().rotate_around(c[0], c[1], yaws[0]) + top.transData
                top.add_patch(
                    Rectangle(
                        c[:2] - half[:2],
                        2 * half[0],
                        2 * half[1],
                        fc="none",
                        ec=colour,
                        lw=1.2,
                        transform=tr,
                    )
                )
        handles.append(
            Line2D(
                [],
                [],
                color=colour,
                lw=1.2,
                label=f"finger boxes nearest "
                f"{name}: {1000 * clearance[i, k]:.1f} mm at {t[i]:.2f} s",
            )
        )
        ax.plot(
            t,
            np.where(standing[:, k], 1000 * clearance[:, k], np.nan),
            color=colour,
            lw=1.2,
            label=f"{name}, while it stands",
        )
    handles.append(Line2D([], [], ls="", marker="x", color="k", label="where the cups ended"))
    # the table with a margin, grown to hold the chassis at its stands (where the arm works
    # at table_0) and wherever it drives within 1 m of the table's box
    local = (base[:, :2] - [cx, cy]) @ np.array([[np.cos(yaw), -np.sin(yaw)],
                                                 [np.sin(yaw), np.cos(yaw)]])  # fmt: skip
    at_stand = np.isin(steps, table_0_steps(config.scenario))
    top.plot(base[at_stand, 0], base[at_stand, 1], "o", color="tab:purple", ms=4)
    near = base[at_stand | np.all(np.abs(local) <= [hx + 1.0, hy + 1.0], axis=1), :2]
    lo = np.min([[cx - hx - 0.4, cy - hy - 0.6], *(near - 0.3)], axis=0)
    hi = np.max([[cx + hx + 0.4, cy + hy + 0.2], *(near + 0.3)], axis=0)
    top.set_xlim(lo[0], hi[0])
    top.set_ylim(lo[1], hi[1])
    top.set_aspect("equal")
    top.set_xlabel("x [m]")
    top.set_ylabel("y [m]")
    top.set_title("table_0 from above", fontsize=9)
    top.legend(
        handles=handles, fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncols=2
    )
    ax.axhline(0.0, color="k", lw=0.8, label="touching the cup")
    inside = standing & grown
    ax.plot(np.broadcast_to(t[:, None], inside.shape)[inside], 1000 * clearance[inside], "x",
            color="tab:red", label=f"inside a cup's disc + {1000 * CUP_MARGIN:g} mm, below its "
            f"rim: {int(inside.sum())} samples")  # fmt: skip
    ax.set_yscale("symlog", linthresh=10.0)
    lowest = np.nanmin(np.where(standing, 1000 * clearance, np.nan))
    ax.set_ylim(bottom=min(-2.0, 1.5 * lowest))
    ax.set_xlabel("time from the plan's start [s]")
    ax.set_ylabel(
        "clearance of the finger boxes from a cup [mm]: the larger of the\n"
        "horizontal gap and the height above its rim (symlog: linear below 10)"
    )
    ax.set_title(f"the fingers around the standing cups (every {1000 * every_s:g} ms)", fontsize=9)
    ax.legend(fontsize=8, loc="upper right")
    fig.suptitle(
        f"Kitchen scenario {config.scenario}{label}, the situation whose cups stand nearest "
        f"({cups_apart(record):.2f} m apart): the h = {h} "
        f"plan executed again ({run.status}, {run.total:.1f} s)"
    )
    fig.savefig(out, dpi=110)
    return out


def demo_config() -> KitchenPlanConfig:
    """The demo config: scenario 1 with the shipped models."""
    return KitchenPlanConfig()


def smoke_config() -> KitchenPlanConfig:
    """A tiny config for tests: scenario 1, the start near the tables."""
    return KitchenPlanConfig(x_range=[0.4, 0.8], y_range=[-0.2, 0.2])


#: The far-side cups' y range on ``table_0`` (its far half, away from ``table_1``): the
#: stands are behind the table, where a drop drive must be able to leave the stand
#: (``_kitchen_arm.exit_clear``).
FAR_CUP_Y_RANGE = (1.4, 1.65)


def far_demo_config() -> KitchenPlanConfig:
    """The far-side demo config: :func:`demo_config` with the cups on ``table_0``'s far side."""
    return dataclasses.replace(demo_config(), cup_y_range=list(FAR_CUP_Y_RANGE))


def far_smoke_config() -> KitchenPlanConfig:
    """A tiny far-side config for tests: :func:`smoke_config` with the far-side cups."""
    return dataclasses.replace(smoke_config(), cup_y_range=list(FAR_CUP_Y_RANGE))


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

# The same study on far-side cups (one situation in the demo: its first seed, 0).
FAR_STUDY = register_study(
    "refinement_kitchen_far",
    config_type=KitchenPlanConfig,
    record_type=RefinementKitchenRecord,
    run_episode=run_episode,
    description="refinement_kitchen with the cups on table_0's far side "
    f"(cup_y_range {list(FAR_CUP_Y_RANGE)}): stands beside or behind it",
    summarize=functools.partial(summarize, stem="refinement_kitchen_far", label=", far-side cups"),
    demo_config=far_demo_config,
    demo_episodes=1,
    smoke_config=far_smoke_config,
)
