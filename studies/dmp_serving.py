"""Serving-water study (Pastor et al. 2009, Fig. 12) in the physics simulation.

Each episode draws the bottle and three cups from the seed, builds the
``arm_serving_water`` world (learned DMPs -> RMRC IK -> ID + PD -> arm7,
finger-contact grasping by default) and runs grasp -> (pour -> retreat) x 3.
The pour DMP's goal is set from each cup's position (sec. IV-E: "generalized
to different cup positions simply through changing the goal"). Success: the
bottle's tip passes over every cup (within 3 cm of its axis, inside the rim,
while the bottle is tilted past 60 degrees) and no cup is pushed by more than
1 cm.

Run it with ``python -m repertoire.studies.dmp_serving --help``.
"""

import dataclasses
import time
from pathlib import Path

import numpy as np
from repertoire.studies._dmp_common import (
    OUTCOME_COLOURS,
    check_arm_config,
    legend_below,
    log_stride,
    outcome_handles,
    register_dmp_study,
    stat_pair,
    timing_rows,
    write_table,
)

from repertoire.errors import RepertoireError


@dataclasses.dataclass
class ServingConfig:
    """What every serving episode shares.

    Attributes:
        bottle_x: range [min, max] of the bottle's x [m].
        bottle_y: range of the bottle's y [m].
        cup_x: range of every cup's x [m].
        cup_y: one [min, max] range of y per cup [m] (three ranges, apart enough
            that the cups cannot overlap).
        grasp_mode: ``contact`` (finger friction) or ``grip`` (GraspWrench latch).
        time_step: plant time step [s].
        sim_duration_s: simulated seconds (0 = the whole sequence).
        path_every_s: sampling period of the stored tip path [s].
    """

    bottle_x: list[float] = dataclasses.field(default_factory=lambda: [0.48, 0.56])
    bottle_y: list[float] = dataclasses.field(default_factory=lambda: [-0.32, -0.26])
    cup_x: list[float] = dataclasses.field(default_factory=lambda: [0.58, 0.66])
    cup_y: list[list[float]] = dataclasses.field(
        default_factory=lambda: [[-0.14, -0.06], [0.02, 0.08], [0.16, 0.22]]
    )
    grasp_mode: str = "contact"
    time_step: float = 0.004
    sim_duration_s: float = 0.0
    path_every_s: float = 0.1

    def validate(self) -> None:
        """Raises RepertoireError for an empty or reversed range or a bad value."""
        ranges = [("bottle_x", self.bottle_x), ("bottle_y", self.bottle_y), ("cup_x", self.cup_x)]
        if len(self.cup_y) != 3:
            raise RepertoireError(f"ServingConfig.cup_y needs 3 ranges, got {len(self.cup_y)}")
        ranges += [(f"cup_y[{k}]", r) for k, r in enumerate(self.cup_y)]
        check_arm_config(self, dict(ranges))


@dataclasses.dataclass
class ServingRecord:
    """One serving episode.

    Attributes:
        bottle_xy: the bottle's start.
        cup_xys: the three cups (flattened x1, y1, x2, y2, x3, y3).
        success: all three cups served and none pushed.
        cups_served: how many cups the tip passed over.
        tip_to_cup_1_m: closest horizontal tip-to-axis distance while pouring, cup 1.
        tip_to_cup_2_m: same for cup 2.
        tip_to_cup_3_m: same for cup 3.
        max_cup_displacement_m: how far the bottle or the hand pushed a cup.
        bottle_in_hand_m: bottle grasp point to tcp at the end (slip).
        grasp_reach_error_m: |tcp - goal| at the end of the grasp (physics).
        pour_reach_error_m: the largest |tcp - goal| at the end of a pour.
        failure: empty, or why the run stopped (IK report).
        tip_x: bottle tip x every ``path_every_s`` [m].
        tip_y: bottle tip y.
        tip_tilt: bottle tilt [rad].
        sim_time_s: simulated seconds.
        wall_time_s: wall seconds of the episode (timing field).
        wall_sim_s: wall seconds of the simulation alone (timing field).
    """

    bottle_xy: list[float]
    cup_xys: list[float]
    success: bool
    cups_served: int
    tip_to_cup_1_m: float
    tip_to_cup_2_m: float
    tip_to_cup_3_m: float
    max_cup_displacement_m: float
    bottle_in_hand_m: float
    grasp_reach_error_m: float
    pour_reach_error_m: float
    failure: str
    tip_x: list[float]
    tip_y: list[float]
    tip_tilt: list[float]
    sim_time_s: float
    wall_time_s: float
    wall_sim_s: float


def sample_scenario(config: ServingConfig, seed: int):
    """The seeded ServingScenario of an episode."""
    from repertoire.diagrams.arm_dmp_scenarios import ServingScenario

    rng = np.random.default_rng(seed)
    bottle = [float(rng.uniform(*config.bottle_x)), float(rng.uniform(*config.bottle_y))]
    cups = [[float(rng.uniform(*config.cup_x)), float(rng.uniform(*r))] for r in config.cup_y]
    return ServingScenario(
        time_step=config.time_step, grasp_mode=config.grasp_mode, bottle_xy=bottle, cup_xys=cups
    )


def run_episode(config: ServingConfig, seed: int) -> ServingRecord:
    """Builds and runs one seeded serving episode.

    Args:
        config: the study config.
        seed: the episode seed.
    """
    from repertoire.diagrams.arm_dmp import build_serving_water
    from repertoire.diagrams.arm_dmp_results import (
        IkTargetError,
        point_log,
        run_arm_world,
        serving_figures,
    )
    from repertoire.diagrams.arm_dmp_scenarios import SERVING_LABELS, segment_timing

    t0 = time.perf_counter()
    config.validate()
    scenario = sample_scenario(config, seed)
    nan = float("nan")
    keys = (
        "tip_to_cup_1_m",
        "tip_to_cup_2_m",
        "tip_to_cup_3_m",
        "max_cup_displacement_m",
        "bottle_in_hand_m",
        "grasp_reach_error_m",
        "pour_reach_error_m",
    )
    figures = dict.fromkeys(keys, nan)
    failure, wall_sim, duration, served = "", 0.0, 0.0, 0
    tip_x = tip_y = tip_z = np.zeros(0)
    try:
        diagram = build_serving_water(scenario)
        _, duration = segment_timing(SERVING_LABELS, scenario.settle_time)
        if config.sim_duration_s > 0:
            duration = min(duration, config.sim_duration_s)
        context, wall_sim = run_arm_world(diagram, duration)
        all_figures = serving_figures(diagram, context)
        served = int(all_figures["cups_served"])
        figures.update({k: all_figures[k] for k in keys})
        tip = point_log(diagram, context, "tip_log")
        step = log_stride(config.path_every_s)
        tip_x, tip_y, tip_z = tip.point[::step, 0], tip.point[::step, 1], tip.axis[::step, 2]
    except (IkTargetError, RepertoireError) as e:
        failure = str(e)
    success = not failure and served == 3 and figures["max_cup_displacement_m"] < 0.01
    tilt = np.arccos(np.clip(tip_z, -1.0, 1.0))
    return ServingRecord(
        bottle_xy=scenario.bottle_xy,
        cup_xys=[float(v) for xy in scenario.cup_xys for v in xy],
        success=bool(success),
        cups_served=served,
        **{k: float(v) for k, v in figures.items()},
        failure=failure,
        tip_x=[round(float(v), 5) for v in tip_x],
        tip_y=[round(float(v), 5) for v in tip_y],
        tip_tilt=[round(float(v), 4) for v in tilt],
        sim_time_s=float(duration),
        wall_time_s=time.perf_counter() - t0,
        wall_sim_s=float(wall_sim),
    )


def summarize(records: list[ServingRecord], config: ServingConfig, out_dir: Path) -> dict:
    """Top view of the bottle tip over the cups and the tip distances (one PNG); a table.

    Returns:
        ``{"top_view": png, "results": md}``.
    """
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import Circle
    from matplotlib.ticker import MaxNLocator
    from repertoire.models.arm7 import CUP_RADIUS

    out_dir = Path(out_dir)
    fig = Figure(figsize=(11, 5), layout="constrained")
    ax, ax2 = fig.subplots(1, 2, width_ratios=[1.3, 1])
    for r in records[:12]:
        color = OUTCOME_COLOURS[bool(r.success)]
        tilt = np.asarray(r.tip_tilt)
        x, y = np.asarray(r.tip_x), np.asarray(r.tip_y)
        pouring = tilt > np.pi / 3
        ax.plot(y, x, color="0.7", lw=0.5)
        ax.plot(np.where(pouring, y, np.nan), np.where(pouring, x, np.nan), color=color, lw=1.2)
        for j in range(3):
            cx, cy = r.cup_xys[2 * j], r.cup_xys[2 * j + 1]
            ax.add_patch(Circle((cy, cx), CUP_RADIUS, fill=False, color="tab:purple", lw=0.5))
        ax.plot(r.bottle_xy[1], r.bottle_xy[0], "s", color="tab:blue", ms=4, mfc="none")
    ax.set_xlabel("y (m, left)")
    ax.set_ylabel("x (m, forward)")
    ax.invert_xaxis()
    ax.set_aspect("equal")
    shown = min(len(records), 12)
    ax.set_title(f"top view: bottle tip of the first {shown} episodes")
    handles = [
        Line2D([], [], color="0.7", lw=0.5, label="bottle tip path"),
        *outcome_handles([r.success for r in records[:shown]], "tip while tilted > 60 deg", lw=1.2),
        Line2D([], [], ls="", marker="o", ms=10, mfc="none", color="tab:purple", label="cup rim"),
        Line2D([], [], ls="", marker="s", ms=4, mfc="none", color="tab:blue", label="bottle start"),
    ]
    legend_below(ax, handles, ncols=2)
    d = np.array(
        [[r.tip_to_cup_1_m, r.tip_to_cup_2_m, r.tip_to_cup_3_m] for r in records], dtype=float
    )
    cm = d[np.isfinite(d)] * 100
    # The axis ends just past the data and the 3 cm bound (at most at 6 cm; larger distances
    # are counted in the last bin, and the label says how many).
    upper = float(np.clip(np.ceil(cm.max() * 2) / 2, 3.5, 6.0)) if cm.size else 3.5
    over = int(np.sum(cm > upper))
    bins = np.linspace(0.0, upper, 36)
    # stacked: each pour counted once in its cup's colour (overlaid bars mixed the colours)
    per_cup = [np.minimum(d[:, j][np.isfinite(d[:, j])] * 100, upper) for j in range(3)]
    ax2.hist(per_cup, bins=bins, stacked=True, label=[f"cup {j + 1}" for j in range(3)])
    ax2.set_xlim(0.0, upper)
    ax2.set_ylim(bottom=0.0)  # counts: with no pour at all the default range went negative
    if not cm.size:
        ax2.set_ylim(0.0, 1.0)
        ax2.text(
            0.5,
            0.5,
            "no episode poured over a cup\n(no tip distance to show)",
            transform=ax2.transAxes,
            ha="center",
            va="center",
        )
    ax2.axvline(3.0, color="tab:red", ls="--", label="3 cm (inside the rim)")
    clipped = f"; {over} above {upper:g} cm counted at {upper:g}" if over else ""
    ax2.set_xlabel(f"closest tip-to-cup-axis distance while pouring (cm)\n{clipped[2:]}".rstrip())
    ax2.set_ylabel("cup pours (stacked by cup)")
    ax2.yaxis.set_major_locator(MaxNLocator(integer=True))
    rate = np.mean([r.success for r in records]) if records else float("nan")
    ax2.set_title(f"success {rate:.0%} of {len(records)} episodes")
    ax2.legend()
    fig.suptitle("grasp a bottle and pour over three cups (arm7, learned DMPs)")
    top = out_dir / "dmp_serving_top_view.png"
    fig.savefig(top, dpi=110)
    grasp = np.array([r.grasp_reach_error_m for r in records], dtype=float) * 1000
    pour = np.array([r.pour_reach_error_m for r in records], dtype=float) * 1000
    slip = np.array([r.bottle_in_hand_m for r in records], dtype=float) * 1000
    lines = [
        "| figure | value |",
        "|---|---|",
        f"| episodes | {len(records)} |",
        f"| success (tip over all 3 cups, none pushed) | {rate:.1%} |",
        f"| cups served, mean | {np.mean([r.cups_served for r in records]):.2f} of 3 |",
        f"| IK reports (stopped runs) | {sum(bool(r.failure) for r in records)} |",
        f"| tip to cup axis, median / max [cm] | {stat_pair(d * 100, np.median, np.max)} |",
        f"| grasp reach error, median / max [mm] | {stat_pair(grasp, np.median, np.max)} |",
        "| pour reach error (bottle in hand), median / max [mm] | "
        f"{stat_pair(pour, np.median, np.max)} |",
        "| bottle grasp point to tcp at the end, median / max [mm] | "
        f"{stat_pair(slip, np.median, np.max, 1)} |",
        *timing_rows(records),
    ]
    table = write_table(out_dir, "dmp_serving_results.md", lines)
    return {"top_view": top, "results": table}


register_dmp_study(
    __name__,
    ServingConfig,
    ServingRecord,
    description="arm7 + learned DMPs: grasp a bottle and pour over three cups; success rate "
    "over random layouts",
    demo_episodes=3,
    # a tiny config for tests: the first 0.3 s of an episode
    smoke=dict(sim_duration_s=0.3),
)
