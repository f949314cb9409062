"""Footstep planning among predictably moving obstacles (Chestnutt et al., Sec. IV-C, Fig. 5).

Two rows of blocks joined by strings are pulled sideways across a 3 m x 3 m floor (the
first row at 0.18 m/s). The strings span the floor, so the start and goal regions are
disconnected for a 2-D mobile-robot planner; a biped can step over the strings between
blocks if it times its steps. Each episode draws random phases of the two rows, plans
with time in the state (time-indexed grids E(t), Euclidean cost-to-go) and records
success, steps, arrival time and how often the plan waits (steps in place) or
side-steps. Beside that one plan, each episode walks the same scene by receding-horizon
replanning (the paper's limited-horizon search: every round plans within a small node
budget from where the committed steps ended, commits a few steps of the best partial plan,
and plans again; a round that proves the end of a partial plan a trap commits a shorter
prefix, and the trap is avoided from then on) and records how it fared.

Run it with ``python -m repertoire.studies.footstep_dynamic --help``.
"""

import dataclasses
import math
from pathlib import Path

import numpy as np
from repertoire.studies._footstep_common import (
    NONE_OK,
    load_table,
    markdown_table,
    percentile,
    planner_options,
    planner_rows,
)
from repertoire.studies.engine import register_study

from repertoire.errors import RepertoireError


@dataclasses.dataclass
class FootstepDynamicConfig:
    """What every episode shares.

    Attributes:
        row1_speed_m_s: speed of the first row (the paper's 0.18 m/s).
        row2_speed_m_s: speed of the second row.
        row1_spacing_m: centre distance between blocks of the first row.
        row2_spacing_m: centre distance between blocks of the second row.
        block_length_m: block size along the row.
        block_depth_m: block size across the row.
        horizon_s: last time of the time-indexed grids.
        grid_dt_s: spacing of the grid times.
        time_limit_s: planner time limit (generous: the node budget binds first).
        max_expansions: deterministic node budget.
        heuristic_weight: w in g + w h (Euclidean cost-to-go).
        body_radius_m: bounding-circle radius of the 2-D planner's robot.
        table_path: action table file; empty for the nominal table.
        swing_clearance_m: the swing foot clears obstacles up to this height (the blocks
            are 2 cm and the strings 5 mm high, every grid of E(t) carries them).
        receding_round_expansions: node budget of each round of the receding-horizon run
            (:func:`~repertoire.planning.footstep.receding.plan_receding_horizon`); 0: no
            receding-horizon run.
        receding_execute_steps: steps committed per round (fewer where the next round
            proves their end a trap).
        receding_max_rounds: the receding-horizon run gives up after this many planner
            calls.
    """

    row1_speed_m_s: float = 0.18
    row2_speed_m_s: float = 0.12
    row1_spacing_m: float = 0.9
    row2_spacing_m: float = 1.0
    block_length_m: float = 0.5
    block_depth_m: float = 0.2
    horizon_s: float = 40.0
    grid_dt_s: float = 0.1
    time_limit_s: float = 60.0
    max_expansions: int = 100000
    heuristic_weight: float = 1.5
    body_radius_m: float = 0.30
    table_path: str = ""
    swing_clearance_m: float = 0.10
    receding_round_expansions: int = 100
    receding_execute_steps: int = 4
    receding_max_rounds: int = 60

    def validate(self) -> None:
        """Raise RepertoireError if a field is out of range."""
        for name in (
            "row1_spacing_m",
            "row2_spacing_m",
            "block_length_m",
            "block_depth_m",
            "horizon_s",
            "grid_dt_s",
            "time_limit_s",
            "body_radius_m",
            "swing_clearance_m",
        ):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise RepertoireError(f"FootstepDynamicConfig.{name} must be > 0, got {v}")
        for name in ("row1_speed_m_s", "row2_speed_m_s", "heuristic_weight"):
            if not math.isfinite(getattr(self, name)):
                raise RepertoireError(f"FootstepDynamicConfig.{name} must be finite")
        if self.block_length_m >= min(self.row1_spacing_m, self.row2_spacing_m):
            raise RepertoireError("blocks longer than their spacing leave no gap in a row")
        for name in ("max_expansions", "receding_round_expansions"):
            if getattr(self, name) < 0:
                raise RepertoireError(
                    f"FootstepDynamicConfig.{name} must be >= 0, got {getattr(self, name)}"
                )
        for name in ("receding_execute_steps", "receding_max_rounds"):
            if getattr(self, name) < 1:
                raise RepertoireError(
                    f"FootstepDynamicConfig.{name} must be >= 1, got {getattr(self, name)}"
                )


@dataclasses.dataclass
class FootstepDynamicRecord:
    """One pair of row phases.

    Attributes:
        seed: the episode seed.
        status: planner status.
        success: the plan reaches the goal.
        steps: steps in the plan.
        arrival_s: time at which the last step lands (simulated seconds).
        waits: steps in place (``stop``) in the plan.
        side_steps: side steps in the plan.
        waited_or_side_stepped: the plan contains a step in place or a side step.
        timing_steps_near_rows: steps in place or side steps landing within 0.6 m of a
            row (waiting for a block to pass, as the paper saw at the second row).
        steps_over: steps whose swing foot passes over a string or block.
        nodes_expanded: A* expansions.
        mobile2d_success: the 2-D planner connects start and goal on E(0).
        wall_plan_time_s: planning wall time (timing field).
        reason: why a plan that is not SUCCESS stops short, as the planner says
            (``FootstepPlan.reason``: the start foot hit, landings past the grids); "".
        receding_status: the receding-horizon run's status ("" when it is off).
        receding_success: the receding-horizon run reaches the goal.
        receding_steps: steps it committed.
        receding_arrival_s: time at which its last committed step lands.
        receding_rounds: planner calls it made.
        receding_dead_end_rounds: of those, the calls that proved their start a trap
            (UNREACHABLE), so that a shorter prefix was committed or the round planned
            again around it.
    """

    seed: int
    status: str
    success: bool
    steps: int
    arrival_s: float
    waits: int
    side_steps: int
    waited_or_side_stepped: bool
    timing_steps_near_rows: int
    steps_over: int
    nodes_expanded: int
    mobile2d_success: bool
    wall_plan_time_s: float
    reason: str = ""
    receding_status: str = ""
    receding_success: bool = False
    receding_steps: int = 0
    receding_arrival_s: float = 0.0
    receding_rounds: int = 0
    receding_dead_end_rounds: int = 0


def _scene(config: FootstepDynamicConfig, seed: int):
    from repertoire.planning.footstep.scenes import strings_scene

    return strings_scene(
        seed,
        speeds=(config.row1_speed_m_s, config.row2_speed_m_s),
        spacings=(config.row1_spacing_m, config.row2_spacing_m),
        block_size=(config.block_length_m, config.block_depth_m),
        t_end=config.horizon_s,
        dt=config.grid_dt_s,
    )


def _plan(config: FootstepDynamicConfig, scene, table):
    """The single plan through the scene (``table``: the config's action table, loaded)."""
    from repertoire.planning.footstep import plan_footsteps

    return plan_footsteps(
        scene.env,
        scene.start,
        scene.start_foot,
        scene.goal,
        table,
        planner_options(config, heuristic="euclidean"),
    )


def _plan_receding(config: FootstepDynamicConfig, scene, table):
    """The receding-horizon run: rounds of ``receding_round_expansions`` expansions each."""
    from repertoire.planning.footstep.receding import plan_receding_horizon

    options = planner_options(
        dataclasses.replace(config, max_expansions=config.receding_round_expansions),
        heuristic="euclidean",
    )
    return plan_receding_horizon(
        scene.env,
        scene.start,
        scene.start_foot,
        scene.goal,
        table,
        options,
        execute_steps=config.receding_execute_steps,
        max_rounds=config.receding_max_rounds,
    )


def run_episode(config: FootstepDynamicConfig, seed: int) -> FootstepDynamicRecord:
    """Plan through the moving rows with the seeded phases.

    Args:
        config: the study config.
        seed: the episode seed (the phases of the rows).

    Returns:
        The episode's record.
    """
    from repertoire.planning.footstep import plan_mobile2d
    from repertoire.planning.footstep.metrics import action_counts, steps_over_obstacles

    config.validate()
    scene = _scene(config, seed)
    table = load_table(config.table_path)  # once for both runs (a file when table_path is set)
    plan = _plan(config, scene, table)
    counts = action_counts(plan)
    mobile = plan_mobile2d(scene.env.at(0.0), scene.body_start, scene.goal, config.body_radius_m)
    waits, side = counts.get("stop", 0), counts.get("side_step", 0)
    receding = {}
    if config.receding_round_expansions > 0:
        run = _plan_receding(config, scene, table)
        receding = dict(
            receding_status=run.plan.status.value,
            receding_success=run.plan.succeeded,
            receding_steps=run.plan.num_steps,
            receding_arrival_s=float(run.plan.times[-1]),
            receding_rounds=run.rounds,
            receding_dead_end_rounds=run.statuses.count("UNREACHABLE"),
        )
    return FootstepDynamicRecord(
        seed=int(seed),
        status=plan.status.value,
        success=plan.succeeded,
        steps=plan.num_steps,
        arrival_s=float(plan.times[-1]),
        waits=waits,
        side_steps=side,
        waited_or_side_stepped=bool(waits + side > 0),
        timing_steps_near_rows=sum(
            1
            for k, a in enumerate(plan.actions, start=1)
            if a in ("stop", "side_step")
            and min(abs(plan.poses[k][1] - y) for y in scene.rows_y) < 0.6
        ),
        steps_over=steps_over_obstacles(scene.env, plan),
        nodes_expanded=plan.nodes_expanded,
        mobile2d_success=mobile.status == "SUCCESS",
        wall_plan_time_s=float(plan.planning_time_s),
        reason=plan.reason,
        **receding,
    )


def summary_table(
    records: list[FootstepDynamicRecord], config: "FootstepDynamicConfig | None" = None
) -> str:
    """Markdown table of the headline figures.

    Args:
        records: the episodes.
        config: the study config (names the receding-horizon run's budget); None: the
            receding-horizon rows are left out.
    """
    n = len(records)
    ok = [r for r in records if r.success]
    arrivals = [r.arrival_s for r in ok]
    common = planner_rows(
        records,
        steps_label="steps median [min, max]",
        steps_over_label="steps over strings or blocks per plan (mean)",
        time_digits=3,
    )
    rows = [
        ("phase pairs", f"{n}"),
        common["success"],
        (
            "2-D bounding-circle planner success (on E(0))",
            f"{sum(r.mobile2d_success for r in records)}/{n}",
        ),
        (
            "plans that wait (step in place) or side-step",
            f"{sum(r.waited_or_side_stepped for r in ok)}/{len(ok)}",
        ),
        (
            "plans that wait or side-step within 0.6 m of a row",
            f"{sum(r.timing_steps_near_rows > 0 for r in ok)}/{len(ok)}",
        ),
        (
            "plans that wait / that side-step",
            f"{sum(r.waits > 0 for r in ok)} / {sum(r.side_steps > 0 for r in ok)}",
        ),
        common["steps"],
        (
            "arrival time median [min, max] (s)",
            f"{percentile(arrivals, 50):.1f} [{min(arrivals, default=0):.1f}, "
            f"{max(arrivals, default=0):.1f}]",
        ),
        common["steps_over"],
        common["plan_time"],
        common["nodes"],
    ]
    if config is not None and config.receding_round_expansions > 0:
        rows += _receding_rows(records, config)
    return markdown_table(rows)


def _receding_rows(
    records: list[FootstepDynamicRecord], config: FootstepDynamicConfig
) -> list[tuple[str, str]]:
    """The receding-horizon run's rows of the summary table."""
    n = len(records)
    ok = [r for r in records if r.receding_success]
    both = [r for r in ok if r.success]
    rounds = [r.receding_rounds for r in records]
    label = (
        f"receding horizon ({config.receding_round_expansions} expansions per round, "
        f"{config.receding_execute_steps} steps committed)"
    )
    later = [r.receding_arrival_s - r.arrival_s for r in both]
    return [
        (f"{label}: success", f"{len(ok)}/{n}"),
        (
            f"{label}: arrival later than the single plan's, median [min, max] (s)",
            f"{percentile(later, 50):.1f} [{min(later, default=0):.1f}, "
            f"{max(later, default=0):.1f}]"
            if both
            else NONE_OK,
        ),
        (
            f"{label}: planner calls median [min, max]",
            f"{percentile(rounds, 50):.0f} [{min(rounds, default=0)}, {max(rounds, default=0)}]",
        ),
        (
            f"{label}: calls that proved a dead end (total; episodes with one)",
            f"{sum(r.receding_dead_end_rounds for r in records)}; "
            f"{sum(r.receding_dead_end_rounds > 0 for r in records)}/{n}",
        ),
    ]


def summarize(
    records: list[FootstepDynamicRecord], config: FootstepDynamicConfig, out_dir: Path
) -> dict[str, Path]:
    """Write the headline table, a Fig. 5-like snapshot figure and the arrival times.

    Args:
        records: the episodes.
        config: the study config.
        out_dir: output folder.

    Returns:
        ``{label: path}`` of the files written.
    """
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator
    from repertoire.planning.footstep.plot import dynamic_plan_figure

    out_dir = Path(out_dir)
    out: dict[str, Path] = {}
    md = out_dir / "footstep_dynamic.md"
    md.write_text("# Footstep planning, moving obstacles\n\n" + summary_table(records, config))
    out["table"] = md
    # snapshot figure of a plan that waits or side-steps (else the first success)
    chosen = next((r for r in records if r.success and r.waited_or_side_stepped), None)
    chosen = chosen or next((r for r in records if r.success), None)
    if chosen is not None:
        scene = _scene(config, chosen.seed)
        plan = _plan(config, scene, load_table(config.table_path))
        path = dynamic_plan_figure(
            scene.env,
            plan,
            out_dir / "footstep_dynamic_snapshots.png",
            panels=9,
            title="two rows of blocks on strings moving sideways, drawn where they are at "
            f"each step's landing time\nseed {chosen.seed}: {plan.num_steps} steps "
            f"({chosen.waits} in place, {chosen.side_steps} side), arrival "
            f"{chosen.arrival_s:.1f} s",
        )
        out["snapshots"] = path
    if records:
        fig = Figure(figsize=(8, 3.2), dpi=110)
        ax = fig.add_subplot(1, 2, 1)
        series = [([r.arrival_s for r in records if r.success], "#1f5fd6", "one plan")]
        if config.receding_round_expansions > 0:
            series.append(
                (
                    [r.receding_arrival_s for r in records if r.receding_success],
                    "#7a7a7a",
                    f"receding horizon ({config.receding_round_expansions} expansions / round)",
                )
            )
        arrivals = [a for values, _, _ in series for a in values]
        bins = np.linspace(min(arrivals, default=0), max(arrivals, default=1) + 1e-9, 16)
        ax.hist(  # bars side by side, one colour per run
            [values for values, _, _ in series],
            bins=bins,
            color=[color for _, color, _ in series],
            label=[f"{label}: {len(values)}" for values, _, label in series],
        )
        ax.set_ylim(0, ax.get_ylim()[1] * 1.6)  # headroom: the legend above the bars
        ax.legend(loc="upper right", fontsize=7, title="successful runs", title_fontsize=7)
        ax.set_xlabel("arrival time (s)")
        ax.set_ylabel("phase pairs")
        ax.set_title("arrival time of each successful run", fontsize=10)
        ax = fig.add_subplot(1, 2, 2)
        ax.hist(
            [r.waits + r.side_steps for r in records if r.success],
            bins=np.arange(-0.5, 8.5),
            color="#d6541f",
        )
        ax.set_xlabel("steps in place + side steps per plan")
        ax.set_ylabel("phase pairs")
        ax.set_title("waiting and dodging per successful plan (one plan)", fontsize=10)
        for a in fig.axes:
            a.yaxis.set_major_locator(MaxNLocator(integer=True))  # counts
        n_ok = sum(r.success for r in records)
        n_rh = sum(r.receding_success for r in records)
        fig.suptitle(
            f"one plan reaches the goal on {n_ok} of {len(records)} random row-phase pairs"
            + (f", the receding horizon on {n_rh}" if config.receding_round_expansions else ""),
            fontsize=10,
        )
        fig.tight_layout()
        path = out_dir / "footstep_dynamic_distributions.png"
        fig.savefig(path)
        out["distributions"] = path
    return out


def demo_config() -> FootstepDynamicConfig:
    """The demo config: the default scene."""
    return FootstepDynamicConfig()


def smoke_config() -> FootstepDynamicConfig:
    """A tiny config for tests: short horizon, small node budget."""
    return FootstepDynamicConfig(horizon_s=15.0, grid_dt_s=0.2, max_expansions=3000)


register_study(
    "footstep_dynamic",
    config_type=FootstepDynamicConfig,
    record_type=FootstepDynamicRecord,
    run_episode=run_episode,
    description="footstep plans through two rows of moving blocks joined by strings",
    summarize=summarize,
    demo_config=demo_config,
    demo_episodes=6,
    smoke_config=smoke_config,
).run_if_main(__name__)
