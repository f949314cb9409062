"""Learning the footstep table T on the simulated biped (Chestnutt et al., Sec. III-A).

Episode ``seed`` (0..342) runs the ``seed``-th sequence of three commanded actions
(7^3 = 343 sequences) from standing on the physics biped (ZMP walking controller
with its stateful stepping rule) and records each step's landed swing sole in the
measured stance sole's frame and the step time (command to the swing foot's first
contact, 4 ms resolution). The summary builds the table with
``ActionTable.from_samples`` (missing keys of a partial run are filled from the
nominal table and counted), saves it as JSON, compares it with the commanded
displacements and with the controller's own rule, and draws the paper's Fig. 2
(effects of the commands from standing and from full-speed walking).

Run it with ``python -m repertoire.studies.footstep_table --help``.
"""

import dataclasses
import json
import time
from pathlib import Path

import numpy as np
from repertoire.diagrams.biped_walk import execute_plan, plan_from_actions, start_feet
from repertoire.planning.footstep.actions import ACTIONS, nominal_action_table
from repertoire.planning.footstep.types import Foot, parse_foot
from repertoire.planning.footstep_learning import (
    covered_keys,
    learn_action_table,
    sequence_for_index,
    step_periods,
    step_samples,
    table_differences,
)
from repertoire.studies.engine import register_study
from repertoire.systems.walking import SteppingRule, realize_plan, realize_step

from repertoire.errors import RepertoireError

NUM_SEQUENCES = len(ACTIONS) ** 3


@dataclasses.dataclass
class FootstepTableConfig:
    """What every episode shares.

    Attributes:
        first_stance: the stance foot of each sequence's first step.
        time_step: plant time step [s].
        contact_approximation: ``sap`` (default), ``lagged`` or ``similar``.
        pelvis_height: pelvis height while walking [m].
        max_speed_change: the controller's stepping rule (see systems/walking.py) [m].
        base_duration: seconds per step at constant speed.
        table_file: file name of the learned table written to the output folder.
    """

    first_stance: str = "left"
    time_step: float = 2e-3
    contact_approximation: str = "sap"
    pelvis_height: float = 0.60
    max_speed_change: float = 0.12
    base_duration: float = 1.0
    table_file: str = "footstep_table.json"

    def validate(self) -> None:
        """Raise RepertoireError if a field is out of range."""
        parse_foot(self.first_stance)
        if not self.table_file.endswith(".json"):
            raise RepertoireError(f"table_file must end with .json, got {self.table_file!r}")
        self.rule().validate()

    def rule(self) -> SteppingRule:
        """The controller's stepping rule."""
        return SteppingRule(
            max_speed_change=self.max_speed_change, base_duration=self.base_duration
        )


@dataclasses.dataclass
class FootstepTableRecord:
    """One sequence of three commands executed from standing.

    Attributes:
        seed: the sequence index (0..342).
        actions: the three commanded actions.
        fell: the biped fell before the third landing.
        steps_measured: landings measured (3 unless it fell).
        dx: landed swing sole in the stance sole frame, x [m], per step.
        dy: same, y [m].
        dyaw: same, yaw [rad].
        duration: step time on a plan's time axis [s]: from the previous step's touch-down
            (the first step: from its command) to this step's (:func:`step_periods`).
        rule_error_m: per step, distance between the measured landing and the
            controller's own target (what the physics added) [m].
        max_tilt_rad: largest pelvis tilt at the measured instants.
        wall_time_s: wall time of the episode.
    """

    seed: int
    actions: list[str]
    fell: bool
    steps_measured: int
    dx: list[float]
    dy: list[float]
    dyaw: list[float]
    duration: list[float]
    rule_error_m: list[float]
    max_tilt_rad: float
    wall_time_s: float


def run_episode(config: FootstepTableConfig, seed: int) -> FootstepTableRecord:
    """Executes the ``seed``-th command sequence from standing and measures its steps.

    Args:
        config: the study config.
        seed: the sequence index in ``[0, 343)``.
    """
    config.validate()
    t0 = time.perf_counter()
    actions = list(sequence_for_index(int(seed)))
    stance, swing = start_feet([0.0, 0.0, 0.0], config.first_stance)
    plan = plan_from_actions(actions, stance, config.first_stance, swing, nominal_action_table())
    result = execute_plan(
        plan,
        rule=config.rule(),
        pelvis_height=config.pelvis_height,
        time_step=config.time_step,
        contact_approximation=config.contact_approximation,
        max_steps=3,
    )
    seq = realize_plan(plan, config.rule())
    periods = step_periods(seq.command_times, result.durations)
    samples = step_samples(actions, config.first_stance, result.stance, result.landed, periods)
    rule_err = [
        float(np.hypot(p[0] - e[0], p[1] - e[1])) for p, e in zip(result.landed, result.expected)
    ]
    return FootstepTableRecord(
        seed=int(seed),
        actions=actions,
        fell=bool(result.fell),
        steps_measured=len(samples),
        dx=[s[4] for s in samples],
        dy=[s[5] for s in samples],
        dyaw=[s[6] for s in samples],
        duration=[s[7] for s in samples],
        rule_error_m=rule_err,
        max_tilt_rad=float(result.max_tilt),
        wall_time_s=time.perf_counter() - t0,
    )


def samples_of(records: list[FootstepTableRecord], first_stance: str) -> list[tuple]:
    """Table samples of every measured step of the records."""
    samples = []
    for r in records:
        hist = ["stop", "stop"]
        foot = parse_foot(first_stance)
        for k in range(r.steps_measured):
            a = r.actions[k]
            samples.append(
                (
                    hist[-2],
                    hist[-1],
                    foot.name.lower(),
                    a,
                    r.dx[k],
                    r.dy[k],
                    r.dyaw[k],
                    r.duration[k],
                )
            )
            hist.append(a)
            foot = foot.other()
    return samples


def rule_table_displacement(rule: SteppingRule) -> np.ndarray:
    """The controller's own targets (no physics) for every key, shape (7, 7, 2, 7, 3)."""
    n = len(ACTIONS)
    out = np.zeros((n, n, 2, n, 3))
    for i in range(n):
        for j in range(n):
            for f in (0, 1):
                for a in range(n):
                    d, _ = realize_step(ACTIONS[i], ACTIONS[j], ACTIONS[a], Foot(f), rule)
                    out[i, j, f, a] = d
    return out


def _draw_fig2(table, nominal, out: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D
    from matplotlib.patches import Rectangle
    from matplotlib.transforms import Affine2D

    fig, axes = plt.subplots(1, 2, figsize=(10, 5.2), sharey=True)
    histories = [
        ("stop", "stop", "from standing"),
        ("forward_long", "forward_long", "from full speed"),
    ]
    colors = plt.cm.tab10(np.linspace(0, 1, 10))
    for ax, (h2, h1, title) in zip(axes, histories):
        ax.add_patch(Rectangle((-0.08, -0.05), 0.16, 0.10, color="k"))
        for k, a in enumerate(ACTIONS):
            (cx, cy), (lx, ly) = (t.lookup(h2, h1, "right", a)[:2] for t in (nominal, table))
            moved = np.hypot(lx - cx, ly - cy) > 0.02
            for tab, style in (
                (nominal, dict(fill=False, ls="--", lw=1.0)),
                # a solid edge, and on top when it moved: under the other actions' fills a
                # learned box was lost
                (table, dict(fc=(*colors[k][:3], 0.55), ec=colors[k], lw=1.4, zorder=2 + moved)),
            ):
                dx, dy, dyaw, _ = tab.lookup(h2, h1, "right", a)
                tr = Affine2D().rotate_around(dx, dy, dyaw) + ax.transData
                colour = {} if "ec" in style else {"color": colors[k]}
                ax.add_patch(
                    Rectangle((dx - 0.08, dy - 0.05), 0.16, 0.10, transform=tr, **colour, **style)
                )
            if moved:  # where the learned landing went
                ax.annotate(
                    "",
                    xy=(lx, ly),
                    xytext=(cx, cy),
                    arrowprops=dict(arrowstyle="->", color=colors[k], lw=1.5),
                )
        ax.set_title(f"left-foot landings {title}\n(filled: learned, dashed: commanded)")
        ax.set_xlim(-0.25, 0.5)
        ax.set_ylim(-0.12, 0.42)
        ax.set_aspect("equal")
        ax.set_xlabel("x in right-sole frame [m]")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("y [m]")
    handles = [Rectangle((0, 0), 1, 1, color=colors[k], alpha=0.55) for k in range(len(ACTIONS))]
    labels = [f"action {a}" for a in ACTIONS]
    handles += [
        Rectangle((0, 0), 1, 1, color="k"),
        Rectangle((0, 0), 1, 1, fc=(0.5, 0.5, 0.5, 0.55), ec="0.5", lw=1.4),
        Rectangle((0, 0), 1, 1, fill=False, ls="--", ec="0.3"),
        Line2D([], [], ls="", marker=r"$\longrightarrow$", ms=22, color="0.3"),
    ]
    labels += [
        "right sole (stance)",
        "learned landing (filled)",
        "commanded landing (dashed)",
        "commanded -> learned (moved > 2 cm)",
    ]
    fig.legend(handles, labels, loc="lower center", ncol=4, fontsize=8)
    fig.suptitle("Fig. 2: the action table learned on the physics biped vs the commanded steps")
    fig.tight_layout(rect=(0, 0.12, 1, 1))
    fig.savefig(out, dpi=130)
    plt.close(fig)
    return out


def summarize(
    records: list[FootstepTableRecord], config: FootstepTableConfig, out_dir: Path
) -> dict:
    """Builds and saves the learned table and its comparison with the commands and the rule.

    Args:
        records: the episodes.
        config: the study config.
        out_dir: output folder.
    """
    out_dir = Path(out_dir)
    samples = samples_of([r for r in records if r.steps_measured > 0], config.first_stance)
    nominal = nominal_action_table()
    n_keys = len(ACTIONS) ** 3 * 2
    covered = len(covered_keys(samples)) if samples else 0
    table, filled = learn_action_table(samples, fill_from=nominal)
    path = out_dir / config.table_file
    table.save(path)
    diff = table_differences(table, nominal)
    rule_disp = rule_table_displacement(config.rule())
    measured = np.zeros(table.duration.shape, dtype=bool)
    idx = {a: k for k, a in enumerate(ACTIONS)}
    for s in samples:
        measured[idx[s[0]], idx[s[1]], int(parse_foot(s[2])), idx[s[3]]] = True
    phys = np.linalg.norm(table.displacement[..., :2] - rule_disp[..., :2], axis=-1)
    rule_vs_nominal = np.linalg.norm(rule_disp[..., :2] - nominal.displacement[..., :2], axis=-1)
    lookups = {}
    for key in [
        ("stop", "stop", "right", "forward_long"),
        ("forward_long", "stop", "right", "forward_long"),
        ("forward_long", "forward_long", "right", "forward_long"),
        ("forward_long", "forward_long", "right", "stop"),
        ("stop", "stop", "right", "stop"),
        ("forward_long", "forward_long", "right", "turn_left"),
    ]:
        lookups[" ".join(key)] = {
            "learned": [round(v, 4) for v in table.lookup(*key)],
            "commanded": [round(v, 4) for v in nominal.lookup(*key)],
        }
    summary = {
        "episodes": len(records),
        "fell": int(sum(r.fell for r in records)),
        "samples": len(samples),
        "keys_covered": covered,
        "keys_total": n_keys,
        "keys_filled_from_nominal": filled,
        "learned_vs_commanded_max_m": diff["max_position_diff_m"],
        "learned_vs_commanded_mean_m": diff["mean_position_diff_m"],
        "fraction_keys_over_2cm_from_commanded": diff["fraction_over_2cm"],
        "rule_vs_commanded_max_m": float(rule_vs_nominal.max()),
        "physics_vs_rule_measured_max_m": float(phys[measured].max()) if measured.any() else 0.0,
        "physics_vs_rule_measured_mean_m": float(phys[measured].mean()) if measured.any() else 0.0,
        "duration_range_s": [float(table.duration.min()), float(table.duration.max())],
        "lookups (dx, dy, dyaw, duration)": lookups,
        "table": str(path),
    }
    summary_path = out_dir / "table_summary.json"
    summary_path.write_text(json.dumps(summary, indent=1))
    lines = ["# Learned footstep table T vs commanded displacements", ""]
    for k, v in summary.items():
        if k != "lookups (dx, dy, dyaw, duration)":
            lines.append(f"- {k}: {v}")
    lines += [
        "",
        "| key (a_prev2 a_prev1 stance a) | learned (dx, dy, dyaw, T) | commanded |",
        "|---|---|---|",
    ]
    for k, v in lookups.items():
        lines.append(f"| {k} | {v['learned']} | {v['commanded']} |")
    md = out_dir / "table_vs_commanded.md"
    md.write_text("\n".join(lines) + "\n")
    fig = _draw_fig2(table, nominal, out_dir / "fig2_state_dependence.png")
    return {"table": path, "summary": summary_path, "comparison": md, "fig2": fig}


def demo_config() -> FootstepTableConfig:
    """The demo config (the default; run a few sequences)."""
    return FootstepTableConfig()


def smoke_config() -> FootstepTableConfig:
    """A tiny config for tests (the default settings; tests run few seeds)."""
    return FootstepTableConfig()


register_study(
    "footstep_table",
    config_type=FootstepTableConfig,
    record_type=FootstepTableRecord,
    run_episode=run_episode,
    description="learn the footstep table T: 343 three-command sequences on the physics biped",
    summarize=summarize,
    demo_config=demo_config,
    demo_episodes=2,
    smoke_config=smoke_config,
).run_if_main(__name__)
