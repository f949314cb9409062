"""Footstep plans executed by the physics biped: learned table T vs nominal (commanded) table.

Each episode draws the static-obstacle floor of ``footstep_static`` for its seed
(3 m x 3 m, 2.5 cm cells, flat obstacles the biped may step over), plans footsteps
from corner to corner twice, once with the table T learned on the simulated biped
(``footstep_table`` study, saved as JSON) and once with the nominal table of
commanded displacements, and sends each plan's *commands* to the walking biped.
It measures where each foot really landed: the fraction of steps within 2 cm and
5 degrees of the plan (world frame), per-step errors, whether the run reached the
goal without falling, and how many real footprints touch an obstacle.

The episodes walk open loop, as the paper does. The summary also walks one long plan
(``feedback_walk_steps`` steps of a fixed forward/turn command cycle, predicted with the
learned table) open loop and with world-frame step feedback
(:mod:`repertoire.systems.step_feedback`) and draws each step's landing error
(``feedback_walk.png``): open loop the stance soles' small yaw slips add up to drift.

Run it with ``python -m repertoire.studies.footstep_execution --help``.
"""

import dataclasses
import functools
import json
import math
import time
from pathlib import Path

import numpy as np
from repertoire.diagrams.biped_walk import (
    PLAN_EXPANSIONS,
    execute_plan,
    landing_errors,
    validate_walk_fields,
)
from repertoire.models.biped import LEARNED_TABLE_PATH
from repertoire.planning.footstep.actions import ASIMO_LIKE, nominal_action_table
from repertoire.planning.footstep.footprint import foot_collides_reference
from repertoire.planning.footstep.planner import PlannerOptions, plan_footsteps
from repertoire.planning.footstep.scenes import random_static_scene
from repertoire.planning.footstep.types import ActionTable, FootstepPlan
from repertoire.studies.engine import register_study
from repertoire.systems.walking import SteppingRule

from repertoire.checks import is_whole
from repertoire.errors import RepertoireError

#: The table learned by the footstep_table study on the physics biped (343 sequences).
LEARNED_TABLE = LEARNED_TABLE_PATH
POSITION_TOLERANCE_M = 0.02
YAW_TOLERANCE_RAD = math.radians(5.0)


@dataclasses.dataclass
class FootstepExecutionConfig:
    """What every episode shares.

    Attributes:
        size_m: side of the square floor.
        n_strips: long thin flat obstacles per map.
        n_blocks: larger blocks per map.
        table_path: learned action table (JSON); empty: the shipped learned table.
        compare_nominal: also plan and execute with the nominal table.
        max_expansions: deterministic node budget of the planner. The learned table's
            history classes (49 for the shipped one, 1 for the nominal table) multiply the
            lattice's states: on unseen 2 m demo floors (seeds 7000-7011) it needed up to
            270k expansions at weight 1.5 (0.3 s), where the nominal table needs 3k, and a
            60k budget left 2 of 12 learned plans partial (NODE_LIMIT).
        time_limit_s: planner wall-time limit (generous; the node budget binds first).
        heuristic_weight: w in g + w h.
        time_step: plant time step [s].
        contact_approximation: ``sap`` (default), ``lagged`` or ``similar``.
        pelvis_height: pelvis height while walking [m].
        feedback_walk_steps: steps of the long plan the summary walks open loop and
            with step feedback (:func:`long_walk_actions`; 0: no such figure). 102 is
            the 102-step plan of docs/results/footstep.md (226 mm open loop, 0.8 mm with feedback).
        feedback: walk each plan with world-frame step feedback (each step placed on
            the plan's pose from the measured stance sole) instead of its commands open
            loop (the paper's setting, which the learned-vs-nominal comparison is about).
            Needs ``compare_nominal: false``: the nominal table's steps are not the ones
            this controller's commands make, so they are out of the feedback's reach.
    """

    size_m: float = 3.0
    n_strips: int = 4
    n_blocks: int = 2
    table_path: str = ""
    compare_nominal: bool = True
    max_expansions: int = PLAN_EXPANSIONS
    time_limit_s: float = 30.0
    heuristic_weight: float = 1.5
    time_step: float = 2e-3
    contact_approximation: str = "sap"
    pelvis_height: float = 0.60
    feedback: bool = False
    feedback_walk_steps: int = 102

    def validate(self) -> None:
        """Raise RepertoireError if a field is out of range."""
        steps = self.feedback_walk_steps
        if not (is_whole(steps) and (steps == 0 or steps >= 3)):
            raise RepertoireError(
                f"feedback_walk_steps must be 0 (no long walk) or a whole number >= 3, got "
                f"{steps!r}"
            )
        if self.feedback and self.compare_nominal:
            raise RepertoireError(
                "feedback: true needs compare_nominal: false (the nominal table's plans "
                "hold steps up to 0.18 m from the ones the commands make: out of reach)"
            )
        if not (math.isfinite(self.size_m) and self.size_m >= 1.5):
            raise RepertoireError(f"size_m must be >= 1.5, got {self.size_m}")
        if self.n_strips < 0 or self.n_blocks < 0 or self.max_expansions < 0:
            raise RepertoireError("n_strips, n_blocks and max_expansions must be >= 0")
        if not self.time_limit_s > 0:
            raise RepertoireError(f"time_limit_s must be > 0, got {self.time_limit_s}")
        _options(self).validate()  # heuristic_weight and the planner's other limits
        # the walking biped's pelvis height and plant settings (the ground keeps friction 1)
        validate_walk_fields(self.pelvis_height, self.time_step, self.contact_approximation, 1.0)
        path = self.table()
        if not path.is_file():
            raise RepertoireError(
                f"learned action table '{path}' not found; run the footstep_table study "
                "(python -m repertoire.studies.footstep_table -n 343) and pass its JSON"
            )

    def table(self) -> Path:
        """Path of the learned table."""
        return Path(self.table_path) if self.table_path else LEARNED_TABLE


@dataclasses.dataclass
class FootstepExecutionRecord:
    """One map, planned and executed with the learned (``learned_*``) and nominal tables.

    Attributes:
        seed: the map seed.
        learned_status: planner status with the learned table.
        learned_steps: steps in that plan.
        learned_executed: steps that landed before the end or a fall.
        learned_within: steps within 2 cm and 5 degrees of the plan (world frame).
        learned_within_frac: ``learned_within / learned_steps``.
        learned_mean_err_m: mean landing position error against the plan [m].
        learned_max_err_m: largest landing position error [m].
        learned_max_yaw_err_deg: largest landing yaw error [deg].
        learned_step_err_m: mean error of each step relative to the *measured* stance
            sole (the table's own accuracy, without accumulated drift) [m].
        learned_fell: the biped fell.
        learned_reached: no fall and a sole within the plan's goal tolerance at the end.
        learned_on_obstacle: measured footprints touching an obstacle cell.
        nominal_*: the same with the nominal table (zeros when not compared).
        wall_time_s: wall time of the episode.
    """

    seed: int
    learned_status: str
    learned_steps: int
    learned_executed: int
    learned_within: int
    learned_within_frac: float
    learned_mean_err_m: float
    learned_max_err_m: float
    learned_max_yaw_err_deg: float
    learned_step_err_m: float
    learned_fell: bool
    learned_reached: bool
    learned_on_obstacle: int
    nominal_status: str
    nominal_steps: int
    nominal_executed: int
    nominal_within: int
    nominal_within_frac: float
    nominal_mean_err_m: float
    nominal_max_err_m: float
    nominal_max_yaw_err_deg: float
    nominal_step_err_m: float
    nominal_fell: bool
    nominal_reached: bool
    nominal_on_obstacle: int
    wall_time_s: float


def _options(config: FootstepExecutionConfig) -> PlannerOptions:
    return PlannerOptions(
        time_limit=config.time_limit_s,
        heuristic_weight=config.heuristic_weight,
        max_expansions=config.max_expansions,
    )


def _plan(scene, table: ActionTable, config: FootstepExecutionConfig) -> FootstepPlan:
    options = _options(config)
    return plan_footsteps(scene.grid, scene.start, scene.start_foot, scene.goal, table, options)


def evaluate_execution(plan: FootstepPlan, result, grid) -> dict:
    """Landing statistics of one executed plan (see the record's fields).

    Args:
        plan: the executed plan.
        result: the ``WalkResult`` of ``execute_plan``.
        grid: the occupancy grid of the map.
    """
    n = plan.num_steps
    pos, yaw = landing_errors(result.landed, plan.poses[1:])
    within = int(np.sum((pos <= POSITION_TOLERANCE_M) & (yaw <= YAW_TOLERANCE_RAD)))
    step_err = []
    poses = plan.poses_array()
    for k, (s, p) in enumerate(zip(result.stance, result.landed)):
        # Planned displacement of step k from its stance (poses[k]) vs the measured one.
        c, sn = math.cos(poses[k][2]), math.sin(poses[k][2])
        d_plan = poses[k + 1][:2] - poses[k][:2]
        d_plan = np.array([c * d_plan[0] + sn * d_plan[1], -sn * d_plan[0] + c * d_plan[1]])
        c, sn = math.cos(s[2]), math.sin(s[2])
        d = np.array(p[:2]) - np.array(s[:2])
        d_meas = np.array([c * d[0] + sn * d[1], -sn * d[0] + c * d[1]])
        step_err.append(float(np.linalg.norm(d_meas - d_plan)))
    goal = np.asarray(plan.goal[:2], float)
    # where the soles stand at the end (a plan of no steps ends where it starts; before,
    # only landings counted, so a 0-step plan from inside the goal was never reached)
    final = list(result.final_soles)
    if not final:  # a WalkResult made without them: the last landing and its stance
        final = [result.landed[-1], result.stance[-1]] if result.landed else []
    reached = (not result.fell) and any(
        np.linalg.norm(np.asarray(f[:2]) - goal) <= plan.goal_tolerance for f in final
    )
    on_obstacle = sum(
        foot_collides_reference(grid, tuple(p), ASIMO_LIKE.foot_length, ASIMO_LIKE.foot_width)
        for p in result.landed
    )
    return {
        "status": plan.status.value,
        "steps": n,
        "executed": len(result.landed),
        "within": within,
        "within_frac": within / n if n else 0.0,
        "mean_err_m": float(pos.mean()) if len(pos) else 0.0,
        "max_err_m": float(pos.max()) if len(pos) else 0.0,
        "max_yaw_err_deg": float(np.degrees(yaw.max())) if len(yaw) else 0.0,
        "step_err_m": float(np.mean(step_err)) if step_err else 0.0,
        "fell": bool(result.fell),
        "reached": bool(reached),
        "on_obstacle": int(on_obstacle),
    }


def _empty() -> dict:
    return {
        "status": "",
        "steps": 0,
        "executed": 0,
        "within": 0,
        "within_frac": 0.0,
        "mean_err_m": 0.0,
        "max_err_m": 0.0,
        "max_yaw_err_deg": 0.0,
        "step_err_m": 0.0,
        "fell": False,
        "reached": False,
        "on_obstacle": 0,
    }


def run_scene(config: FootstepExecutionConfig, seed: int, table: ActionTable):
    """Plans the seeded map with ``table`` and executes the plan; returns (scene, plan, result)."""
    scene = random_static_scene(
        seed, size=config.size_m, n_strips=config.n_strips, n_blocks=config.n_blocks
    )
    plan = _plan(scene, table, config)
    result = execute_plan(
        plan,
        rule=SteppingRule(),
        pelvis_height=config.pelvis_height,
        time_step=config.time_step,
        contact_approximation=config.contact_approximation,
        feedback=config.feedback,
    )
    return scene, plan, result


def run_episode(config: FootstepExecutionConfig, seed: int) -> FootstepExecutionRecord:
    """Plans and executes one map with the learned (and the nominal) table.

    Args:
        config: the study config.
        seed: the map seed.
    """
    config.validate()
    t0 = time.perf_counter()
    learned = ActionTable.load(config.table())
    scene, plan, result = run_scene(config, seed, learned)
    stats = {"learned": evaluate_execution(plan, result, scene.grid), "nominal": _empty()}
    if config.compare_nominal:
        scene, plan, result = run_scene(config, seed, nominal_action_table())
        stats["nominal"] = evaluate_execution(plan, result, scene.grid)
    fields = {f"{which}_{k}": v for which, s in stats.items() for k, v in s.items()}
    return FootstepExecutionRecord(seed=int(seed), wall_time_s=time.perf_counter() - t0, **fields)


FOOT_COLOURS = ("tab:blue", "tab:orange")  # left, right: neither is the obstacles' red


def _draw_example(config: FootstepExecutionConfig, seed: int, out: Path) -> Path:
    """Fig. 3-style plot: map, planned footprints and the real landings, both tables."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch, Rectangle
    from matplotlib.transforms import Affine2D

    tables = [("learned T", ActionTable.load(config.table()))]
    if config.compare_nominal:
        tables.append(("nominal T", nominal_action_table()))
    fig, axes = plt.subplots(1, len(tables), figsize=(6 * len(tables), 6.8))
    axes = np.atleast_1d(axes)
    for ax, (label, table) in zip(axes, tables):
        scene, plan, result = run_scene(config, seed, table)
        occ = scene.grid.occupied
        x0, y0 = scene.grid.origin
        sx, sy = scene.grid.size
        ax.imshow(
            occ.T,
            origin="lower",
            extent=(x0, x0 + sx, y0, y0 + sy),
            cmap="Reds",
            alpha=0.8,
            vmin=0,
            vmax=1.5,
        )
        for k, p in enumerate(plan.poses):
            color = FOOT_COLOURS[plan.feet[k]]
            tr = Affine2D().rotate_around(p[0], p[1], p[2]) + ax.transData
            ax.add_patch(
                Rectangle(
                    (p[0] - 0.08, p[1] - 0.05), 0.16, 0.10, fill=False, ec=color, transform=tr
                )
            )
        landed = np.asarray(result.landed).reshape(-1, 3)
        ax.plot(landed[:, 0], landed[:, 1], "k.", ms=5, label="real landings")
        ax.plot(*scene.goal, "g*", ms=14, label="goal")
        stats = evaluate_execution(plan, result, scene.grid)
        ax.set_title(
            f"{label}: {stats['within']}/{stats['steps']} steps within 2 cm/5 deg\n"
            f"largest landing error {1000 * stats['max_err_m']:.1f} mm, "
            f"goal {'reached' if stats['reached'] else 'not reached'}"
        )
        ax.set_xlim(x0, x0 + sx)
        ax.set_ylim(y0, y0 + sy)
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        handles, _ = ax.get_legend_handles_labels()
        handles = [
            Patch(facecolor="white", edgecolor=FOOT_COLOURS[0], label="planned left foot"),
            Patch(facecolor="white", edgecolor=FOOT_COLOURS[1], label="planned right foot"),
            # an occupied cell is 1 on the 0..1.5 colour scale of the map above
            Patch(color=plt.cm.Reds(1.0 / 1.5), alpha=0.8, label="obstacle cells"),
            *handles,
        ]
        # below the map: inside, it covered obstacle cells and footprints
        ax.legend(
            handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=3, fontsize=8
        )
    fig.suptitle(f"seed {seed}: one footstep plan per action table, executed by the physics biped")
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


#: The long walk's command cycle (the 102-step plan of session 33, docs/results/footstep.md).
LONG_WALK_CYCLE = ("forward_long", "turn_left", "forward_medium", "turn_right")
#: Where the long walk starts: the soles' midpoint ``[x, y, yaw]``; the right foot stands.
LONG_WALK_START = (0.3, -0.2, 0.4)
#: Colours of the open-loop and the feedback walk in the feedback figure.
WALK_COLOURS = {False: "tab:red", True: "tab:blue"}
WALK_LABELS = {False: "open loop (commands)", True: "with step feedback"}


def long_walk_actions(steps: int) -> list[str]:
    """The long walk's ``steps`` commands: :data:`LONG_WALK_CYCLE` repeated, then two stops.

    Args:
        steps: the plan's steps (>= 3).

    Raises:
        RepertoireError: ``steps`` not a whole number >= 3.
    """
    if not (is_whole(steps) and steps >= 3):
        raise RepertoireError(f"a long walk needs a whole number >= 3 of steps, got {steps!r}")
    moving = [LONG_WALK_CYCLE[k % len(LONG_WALK_CYCLE)] for k in range(steps - 2)]
    return moving + ["stop", "stop"]


def feedback_walk(config: FootstepExecutionConfig, steps: int):
    """Walks the long plan of ``steps`` steps open loop and with step feedback.

    The plan is the learned table's prediction of :func:`long_walk_actions` from
    :data:`LONG_WALK_START` (what a footstep planner outputs for these commands).

    Args:
        config: the study config (table, plant and walking settings).
        steps: the plan's steps.

    Returns:
        ``(plan, {False: open-loop WalkResult, True: feedback WalkResult})``.
    """
    from repertoire.diagrams.biped_walk import plan_from_actions, start_feet

    stance, swing = start_feet(list(LONG_WALK_START), "right")
    table = ActionTable.load(config.table())
    plan = plan_from_actions(long_walk_actions(steps), stance, "right", swing, table)
    results = {
        fb: execute_plan(
            plan,
            rule=SteppingRule(),
            pelvis_height=config.pelvis_height,
            time_step=config.time_step,
            contact_approximation=config.contact_approximation,
            feedback=fb,
        )
        for fb in (False, True)
    }
    return plan, results


def draw_feedback_walk(plan: FootstepPlan, results: dict, out: Path) -> Path:
    """Top view of the long plan and each step's landing error, open loop vs feedback.

    Args:
        plan: the walked plan.
        results: ``{False: open-loop WalkResult, True: feedback WalkResult}``.
        out: the PNG to write.
    """
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import Rectangle
    from matplotlib.transforms import Affine2D

    fig = Figure(figsize=(13, 5.6), layout="constrained")
    top, ax = fig.subplots(1, 2, width_ratios=[1, 1.25])
    for k, p in enumerate(plan.poses):
        tr = Affine2D().rotate_around(p[0], p[1], p[2]) + top.transData
        top.add_patch(Rectangle((p[0] - 0.08, p[1] - 0.05), 0.16, 0.10, fill=False, lw=0.5,
                                ec=FOOT_COLOURS[plan.feet[k]], transform=tr))  # fmt: skip
    handles = [
        Line2D([], [], color=FOOT_COLOURS[0], lw=1, label="planned left sole"),
        Line2D([], [], color=FOOT_COLOURS[1], lw=1, label="planned right sole"),
    ]
    floor = 0.1  # [mm]: the log axis' floor
    for fb, result in results.items():
        pos, yaw = landing_errors(result.landed, plan.poses[1:])
        landed = np.asarray(result.landed, float).reshape(-1, 3)
        colour, name = WALK_COLOURS[fb], WALK_LABELS[fb]
        marker = ".x"[not fb]  # open loop on top, as crosses: the drift shows beside the dots
        top.plot(landed[:, 0], landed[:, 1], marker, ms=4, color=colour, zorder=3 - fb)
        fell = f", fell after {len(landed)}" if result.fell else ""
        within = int(np.sum(pos <= POSITION_TOLERANCE_M))
        label = (
            f"{name}: largest {1000 * pos.max(initial=0.0):.1f} mm, "
            f"{np.degrees(yaw.max(initial=0.0)):.2f} deg; {within}/{plan.num_steps} "
            f"within 2 cm{fell}"
        )
        handles.append(
            Line2D([], [], ls="", marker=marker, color=colour, label=f"{name}: landings")
        )
        steps = np.arange(1, len(pos) + 1)
        ax.plot(steps, np.maximum(1000 * pos, floor), ".-", ms=3, lw=0.8, color=colour,
                label=label)  # fmt: skip
    top.set_aspect("equal")
    top.autoscale_view()
    top.set_xlabel("x [m]")
    top.set_ylabel("y [m]")
    top.set_title(f"the plan ({plan.num_steps} steps of {', '.join(LONG_WALK_CYCLE)})",
                  fontsize=9)  # fmt: skip
    top.legend(handles=handles, fontsize=8, loc="best")
    ax.axhline(1000 * POSITION_TOLERANCE_M, color="k", ls="--", lw=0.8, label="2 cm tolerance")
    ax.set_yscale("log")
    ax.set_ylim(bottom=floor * 0.8)
    ax.set_xlabel("step of the plan")
    ax.set_ylabel(f"landing error vs the plan, world frame [mm]\n(log; below {floor} mm "
                  f"drawn at {floor})")  # fmt: skip
    ax.set_title("where each foot landed, against the plan's pose of that step", fontsize=9)
    ax.legend(fontsize=8, loc="lower right")  # below the open-loop curve, above feedback
    fig.suptitle("one long footstep plan (learned table) walked by the physics biped: open loop "
                 "vs world-frame step feedback")  # fmt: skip
    fig.savefig(out, dpi=110)
    return out


def execution_rows(records: list, tables: tuple[str, ...]) -> dict[str, dict]:
    """The summary row of each table over the episodes.

    Landing errors are averaged over the runs that landed a step: a run that fell before
    its first landing (or a plan of no steps) has no error to measure, and before session
    32 it entered the means and medians as a perfect 0 m.

    Args:
        records: the episodes (:class:`FootstepExecutionRecord`).
        tables: ``learned`` and/or ``nominal``.

    Returns:
        ``{table: {figure: value}}``; the landing-error figures are None when no run
        landed a step.
    """
    rows = {}
    for which in tables:
        values = functools.partial(_values, which)
        landed = [r for r in records if getattr(r, f"{which}_executed") > 0]
        steps = sum(values("steps", records))
        within = sum(values("within", records))
        rows[which] = {
            "runs": len(records),
            "steps": steps,
            "steps_within_2cm_5deg": within / steps if steps else 0.0,
            "runs_reached_goal_without_fall": float(np.mean(values("reached", records)))
            if records
            else 0.0,
            "runs_fell": int(sum(values("fell", records))),
            "runs_without_landings": len(records) - len(landed),
            "mean_landing_error_m": _mean(values("mean_err_m", landed)),
            "median_max_landing_error_m": float(np.median(values("max_err_m", landed)))
            if landed
            else None,
            "mean_step_error_m": _mean(values("step_err_m", landed)),
            "landings_on_obstacles": int(sum(values("on_obstacle", records))),
            "plans_success": int(sum(v == "SUCCESS" for v in values("status", records))),
        }
    return rows


def _values(which: str, field: str, records: list) -> list:
    return [getattr(r, f"{which}_{field}") for r in records]


def _mean(values: list[float]) -> float | None:
    """Mean, None (null in the JSON) for no values: no landing was measured."""
    return float(np.mean(values)) if values else None


def summarize(records: list, config: FootstepExecutionConfig, out_dir: Path) -> dict:
    """Writes the execution table (Markdown + JSON), a histogram and an example figure.

    Args:
        records: the episodes.
        config: the study config.
        out_dir: output folder.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    out_dir = Path(out_dir)
    out = {}
    rows = execution_rows(
        records, ("learned", "nominal") if config.compare_nominal else ("learned",)
    )
    path = out_dir / "execution_summary.json"
    path.write_text(json.dumps(rows, indent=1))
    out["execution_summary"] = path
    keys = list(next(iter(rows.values())).keys())
    lines = ["| table | " + " | ".join(keys) + " |", "|---" * (len(keys) + 1) + "|"]
    for which, row in rows.items():
        lines.append(
            f"| {which} | "
            + " | ".join(f"{v:.4g}" if isinstance(v, float) else str(v) for v in row.values())
            + " |"
        )
    md = out_dir / "execution_summary.md"
    md.write_text("\n".join(lines) + "\n")
    out["execution_table"] = md
    fig, ax = plt.subplots(figsize=(6, 4))
    measured = {w: [r for r in records if getattr(r, f"{w}_executed") > 0] for w in rows}
    largest = max(
        [100 * getattr(r, f"{w}_max_err_m") for w in rows for r in measured[w]], default=1.0
    )
    bins = np.geomspace(0.1, max(largest * 1.1, 1.0), 40)
    # side by side in each bin: overlaid translucent bars mixed into a colour of neither
    ax.hist(
        [[max(100 * getattr(r, f"{w}_max_err_m"), 0.1) for r in measured[w]] for w in rows],
        bins=bins,
        label=[f"{which} table" for which in rows],
    )
    ax.set_xscale("log")
    ax.axvline(100 * POSITION_TOLERANCE_M, color="k", ls="--", lw=1, label="2 cm tolerance")
    ax.set_xlabel(
        "largest landing error of a run [cm] (world frame, vs plan; log scale;\n"
        "errors below 0.1 cm drawn at 0.1)"
    )
    ax.set_ylabel("runs")
    n_measured = max(len(v) for v in measured.values()) if measured else 0
    ax.set_title(f"largest landing error of each of {n_measured} executed plans with landings")
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))  # counts: whole ticks
    ax.legend()
    fig.tight_layout()
    hist = out_dir / "landing_error_hist.png"
    fig.savefig(hist, dpi=110)
    plt.close(fig)
    out["landing_error_hist"] = hist
    if records:
        out["example"] = _draw_example(
            config, int(records[0].seed), out_dir / "example_execution.png"
        )
    if config.feedback_walk_steps:
        try:
            plan, results = feedback_walk(config, config.feedback_walk_steps)
        except RepertoireError as e:  # e.g. a table whose steps the feedback cannot reach
            note = out_dir / "feedback_walk_refused.txt"
            note.write_text(f"the long walk was not drawn: {e}\n")
            out["feedback_walk_refused"] = note
        else:
            out["feedback_walk"] = draw_feedback_walk(plan, results, out_dir / "feedback_walk.png")
    return out


def demo_config() -> FootstepExecutionConfig:
    """The demo config: a 2 m floor so that the demo's two episodes take about a minute.

    Its long walk has 40 steps (about 8 s each way; open loop about 30 mm off by its
    end); the real run uses the default config (the paper's 3 m floor, the 102-step walk
    of docs/results/footstep.md) with 50+ seeds.
    """
    return FootstepExecutionConfig(size_m=2.0, n_strips=2, n_blocks=1, feedback_walk_steps=40)


def smoke_config() -> FootstepExecutionConfig:
    """A tiny config for tests: a 1.5 m floor with one strip, learned table only."""
    return FootstepExecutionConfig(
        size_m=1.5,
        n_strips=1,
        n_blocks=0,
        max_expansions=5000,
        compare_nominal=False,
        feedback_walk_steps=0,
    )


register_study(
    "footstep_execution",
    config_type=FootstepExecutionConfig,
    record_type=FootstepExecutionRecord,
    run_episode=run_episode,
    description="footstep plans (learned vs nominal T) executed by the physics biped: "
    "landing accuracy, goal reached",
    summarize=summarize,
    demo_config=demo_config,
    demo_episodes=2,
    smoke_config=smoke_config,
).run_if_main(__name__)
