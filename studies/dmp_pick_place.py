"""Pick-and-place study (Pastor et al. 2009, Fig. 13) in the physics simulation.

Each episode draws the cup, the coaster (start and where it moves after the
placing onset) and the ball obstacle from the seed, builds the
``arm_pick_and_place`` world (learned DMPs -> RMRC IK -> ID + PD -> arm7 with
finger-contact grasping by default) and runs grasp -> place -> release. Success:
the cup stands on the coaster at the end, its axis within 2 cm of the
coaster's centre. Also recorded: the reach error at the end of the grasp and
the place, the closest approach of the tcp to the ball's surface, and the wall
time of the simulation.

Run it with ``python -m repertoire.studies.dmp_pick_place --help``.
"""

import dataclasses
import time
from pathlib import Path

import numpy as np
from repertoire.studies._dmp_common import (
    OUTCOME_COLOURS,
    PICK_PLACE_FIGURES,
    carry_control_points,
    check_arm_config,
    default_obstacle_gamma,
    legend_below,
    obstacle_radius,
    outcome_handles,
    register_dmp_study,
    run_pick_and_place,
    stat_pair,
    timing_rows,
    write_table,
)

from repertoire.errors import RepertoireError


@dataclasses.dataclass
class PickPlaceConfig:
    """What every pick-and-place episode shares.

    Attributes:
        cup_x: range [min, max] of the cup's x [m]; likewise the other ranges.
        cup_y: range of the cup's y [m].
        coaster_x: range of the coaster's starting x [m].
        coaster_y: range of the coaster's starting y [m].
        coaster_shift: range of the distance the coaster moves after onset [m]
            (direction uniform).
        obstacle_beyond: range of how far beyond the cup-coaster midpoint (+x) the
            ball's centre is [m] (drawn again, with ``obstacle_z``, while the ball would
            overlap the open hand at home).
        obstacle_z: range of the ball centre's height [m].
        obstacle_coupling: feed the obstacle into the DMP coupling term (eq. 10).
        obstacle_gamma: gamma of eq. 10 (on the scaled velocity v = tau dx/dt).
        obstacle_beta: the angular decay c of eq. 10.
        obstacle_length_scale: decay length of the distance factor [m] (0 = the paper's
            eq. 10 exactly).
        obstacle_points: control points in the tcp frame where eq. 10 acts (summed);
            ``[[0, 0, 0]]`` = the tcp only.
        grasp_mode: ``contact`` (finger friction) or ``grip`` (GraspWrench latch).
        time_step: plant time step [s].
        sim_duration_s: simulated seconds (0 = the whole sequence); smoke tests
            use a fraction.
        path_every_s: sampling period of the stored tcp path [s].
    """

    cup_x: list[float] = dataclasses.field(default_factory=lambda: [0.50, 0.60])
    cup_y: list[float] = dataclasses.field(default_factory=lambda: [-0.30, -0.18])
    coaster_x: list[float] = dataclasses.field(default_factory=lambda: [0.50, 0.60])
    coaster_y: list[float] = dataclasses.field(default_factory=lambda: [0.02, 0.12])
    coaster_shift: list[float] = dataclasses.field(default_factory=lambda: [0.03, 0.07])
    obstacle_beyond: list[float] = dataclasses.field(default_factory=lambda: [0.10, 0.13])
    obstacle_z: list[float] = dataclasses.field(default_factory=lambda: [0.96, 1.00])
    obstacle_coupling: bool = True
    obstacle_gamma: float = dataclasses.field(default_factory=default_obstacle_gamma)
    obstacle_beta: float = 4.0
    obstacle_length_scale: float = 0.03
    obstacle_points: list[list[float]] = dataclasses.field(default_factory=carry_control_points)
    grasp_mode: str = "contact"
    time_step: float = 0.004
    sim_duration_s: float = 0.0
    path_every_s: float = 0.1

    def validate(self) -> None:
        """Raises RepertoireError for an empty or reversed range or a bad value."""
        names = (
            "cup_x",
            "cup_y",
            "coaster_x",
            "coaster_y",
            "coaster_shift",
            "obstacle_beyond",
            "obstacle_z",
        )
        check_arm_config(self, {n: getattr(self, n) for n in names})


@dataclasses.dataclass
class PickPlaceRecord:
    """One pick-and-place episode.

    Attributes:
        cup_xy: the cup's start.
        coaster_xy: the coaster's start.
        coaster_final_xy: where the coaster moved to.
        obstacle_xyz: the ball's centre.
        success: the cup stands on the coaster within 2 cm of its centre.
        cup_to_coaster_m: final horizontal distance cup axis - coaster centre.
        cup_height_above_coaster_m: cup bottom above the coaster top at the end.
        cup_tilt_rad: the cup's tilt at the end.
        min_obstacle_clearance_m: closest tcp approach to the ball's surface.
        grasp_reach_error_m: |tcp - goal| at the end of the grasp (physics).
        place_reach_error_m: |tcp - goal| at the end of the place (physics).
        min_ball_gap_m: smallest signed distance between the ball and any collision
            geometry of the arm, hand, fingers or cup (SceneGraph, every 4 ms).
        min_ball_gap_time_s: when it occurred.
        collision_free: ``min_ball_gap_m > 0``.
        grasp_slip_m: the largest distance the cup moved in the hand while carried [m].
        grasp_slip_time_s: when it occurred.
        held_offset_m: how far the cup's axis was from the tcp's when the carry began [m].
        start_delay_s: how long the release waited for the cup to settle on the coaster [s].
        release_object_error_m: the cup's horizontal distance from the coaster's centre
            when the release began [m].
        release_settled: the release found the cup settled (within 1 mm of the centre,
            at rest), not the wait run out.
        failure: empty, or why the run stopped (IK report).
        joint_margins_rad: per arm7 joint, the least distance of the IK's reference from
            the joint's limits over the run [rad] (NaN: nothing ran).
        joint_held_steps: per joint, the IK steps that held it at a limit
            (``joints_at_limits``).
        outcome: ``stopped``, ``grasp_slip`` (the cup moved more than 1 cm in the
            hand), ``placed`` or ``missed`` (``_dmp_common.OUTCOMES``).
        report: the IK's stop message or the grasp slip's, else the placing's when the
            release began before the cup settled, else empty.
        path_x: tcp x every ``path_every_s`` [m].
        path_y: tcp y.
        path_z: tcp z.
        sim_time_s: simulated seconds.
        wall_time_s: wall seconds of the episode (timing field).
        wall_sim_s: wall seconds of the simulation alone (timing field).
    """

    cup_xy: list[float]
    coaster_xy: list[float]
    coaster_final_xy: list[float]
    obstacle_xyz: list[float]
    success: bool
    cup_to_coaster_m: float
    cup_height_above_coaster_m: float
    cup_tilt_rad: float
    min_obstacle_clearance_m: float
    grasp_reach_error_m: float
    place_reach_error_m: float
    min_ball_gap_m: float
    min_ball_gap_time_s: float
    collision_free: bool
    grasp_slip_m: float
    grasp_slip_time_s: float
    held_offset_m: float
    start_delay_s: float
    release_object_error_m: float
    release_settled: float
    failure: str
    joint_margins_rad: list[float]
    joint_held_steps: list[int]
    outcome: str
    report: str
    path_x: list[float]
    path_y: list[float]
    path_z: list[float]
    sim_time_s: float
    wall_time_s: float
    wall_sim_s: float


def sample_scenario(config: PickPlaceConfig, seed: int):
    """The seeded PickPlaceScenario of an episode."""
    from repertoire.diagrams.arm_dmp_scenarios import PickPlaceScenario, ball_gap_at_home

    rng = np.random.default_rng(seed)
    cup = [rng.uniform(*config.cup_x), rng.uniform(*config.cup_y)]
    coaster = [rng.uniform(*config.coaster_x), rng.uniform(*config.coaster_y)]
    angle = rng.uniform(0.0, 2.0 * np.pi)
    shift = rng.uniform(*config.coaster_shift)
    final = [coaster[0] + shift * np.cos(angle), coaster[1] + shift * np.sin(angle)]
    mid = 0.5 * (np.asarray(cup) + np.asarray(coaster))
    for _ in range(100):
        obstacle = [
            float(mid[0] + rng.uniform(*config.obstacle_beyond)),
            float(mid[1]),
            float(rng.uniform(*config.obstacle_z)),
        ]
        # A ball that overlaps the open hand at home is drawn again (the world refuses it).
        if ball_gap_at_home(obstacle) > 0.0:
            break
    else:
        raise RepertoireError(
            "no obstacle placement clear of the arm at home in 100 draws; change "
            "obstacle_beyond / obstacle_z"
        )
    return PickPlaceScenario(
        time_step=config.time_step,
        grasp_mode=config.grasp_mode,
        cup_xy=[float(v) for v in cup],
        coaster_xy=[float(v) for v in coaster],
        coaster_final_xy=[float(v) for v in final],
        obstacle_xyz=obstacle,
        obstacle_coupling=config.obstacle_coupling,
        obstacle_gamma=config.obstacle_gamma,
        obstacle_beta=config.obstacle_beta,
        obstacle_length_scale=config.obstacle_length_scale,
        obstacle_points=[list(map(float, p)) for p in config.obstacle_points],
    )


def run_episode(config: PickPlaceConfig, seed: int) -> PickPlaceRecord:
    """Builds and runs one seeded pick-and-place episode.

    Args:
        config: the study config.
        seed: the episode seed.
    """
    t0 = time.perf_counter()
    config.validate()
    scenario = sample_scenario(config, seed)
    run = run_pick_and_place(scenario, config.sim_duration_s, config.path_every_s)
    return PickPlaceRecord(
        cup_xy=scenario.cup_xy,
        coaster_xy=scenario.coaster_xy,
        coaster_final_xy=scenario.coaster_final_xy,
        obstacle_xyz=scenario.obstacle_xyz,
        success=run["placed"],
        **{k: float(run[k]) for k in PICK_PLACE_FIGURES},
        collision_free=bool(run["min_ball_gap_m"] > 0.0),
        failure=run["failure"],
        joint_margins_rad=[round(float(v), 6) for v in run["joint_margins"]],
        joint_held_steps=[int(v) for v in run["joint_held_steps"]],
        outcome=run["outcome"],
        report=run["report"],
        path_x=[round(float(v), 5) for v in run["path"][:, 0]],
        path_y=[round(float(v), 5) for v in run["path"][:, 1]],
        path_z=[round(float(v), 5) for v in run["path"][:, 2]],
        sim_time_s=float(run["duration"]),
        wall_time_s=time.perf_counter() - t0,
        wall_sim_s=float(run["wall"]),
    )


def carry_clearance(record: PickPlaceRecord, config: PickPlaceConfig) -> float:
    """Closest approach of the tcp to the ball's surface during the placing movement [m].

    Read from the stored tcp path (one point every ``path_every_s`` from t = 0) over
    the place segment's time window.
    """
    from repertoire.diagrams.arm_dmp_scenarios import (
        PICK_PLACE_LABELS,
        PickPlaceScenario,
        segment_timing,
    )

    if not record.path_x:
        return float("nan")
    starts, _ = segment_timing(PICK_PLACE_LABELS, PickPlaceScenario().settle_time)
    t = np.arange(len(record.path_x)) * config.path_every_s
    rows = (t >= starts[1]) & (t < starts[2])
    if not rows.any():
        return float("nan")
    p = np.column_stack([record.path_x, record.path_y, record.path_z])[rows]
    return float(
        np.min(np.linalg.norm(p - np.asarray(record.obstacle_xyz), axis=1)) - obstacle_radius()
    )


def summarize(
    records: list[PickPlaceRecord], config: PickPlaceConfig, out_dir: Path
) -> dict[str, Path]:
    """Top view of every episode and the final cup-to-coaster distances; a Markdown table.

    Returns:
        ``{"top_view": png, "distances": png, "results": md}``.
    """
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import Circle
    from matplotlib.ticker import MaxNLocator

    out_dir = Path(out_dir)
    fig = Figure(figsize=(11, 5), layout="constrained")
    ax, ax2 = fig.subplots(1, 2, width_ratios=[1.3, 1])

    radius = obstacle_radius()
    for k, r in enumerate(records):
        color = OUTCOME_COLOURS[bool(r.success)]
        if k < 25 and r.path_x:
            ax.plot(r.path_y, r.path_x, color=color, lw=0.7, alpha=0.6)
        ax.plot(r.cup_xy[1], r.cup_xy[0], "o", color="tab:purple", ms=4, mfc="none")
        # markers (not only the arrow, which does not widen the axes: coasters fell outside)
        ax.plot(r.coaster_xy[1], r.coaster_xy[0], "s", color="tab:brown", ms=4, mfc="none")
        ax.plot(r.coaster_final_xy[1], r.coaster_final_xy[0], "s", color="tab:brown", ms=4)
        ax.annotate(
            "",
            xy=(r.coaster_final_xy[1], r.coaster_final_xy[0]),
            xytext=(r.coaster_xy[1], r.coaster_xy[0]),
            arrowprops={"arrowstyle": "->", "color": "tab:brown", "lw": 0.6},
        )
        ax.add_patch(
            Circle(
                (r.obstacle_xyz[1], r.obstacle_xyz[0]),
                radius,
                fill=False,
                color="tab:blue",
                lw=0.4,
                alpha=0.5,
            )
        )
    ax.set_xlabel("y (m, left)")
    ax.set_ylabel("x (m, forward)")
    ax.invert_xaxis()
    ax.set_aspect("equal")
    ax.set_title(f"top view of {len(records)} episodes (tcp paths: first 25)")
    handles = [
        *outcome_handles([r.success for r in records[:25] if r.path_x], "tcp path"),
        Line2D([], [], ls="", marker="o", mfc="none", color="tab:purple", label="cup start"),
        Line2D([], [], ls="", marker="s", mfc="none", color="tab:brown", label="coaster start"),
        Line2D([], [], ls="", marker="s", color="tab:brown", label="coaster end (arrow: move)"),
        Line2D([], [], ls="", marker="o", mfc="none", ms=10, color="tab:blue", label="ball"),
    ]
    legend_below(ax, handles, ncols=3)  # below the axes: inside, it covered balls and paths
    d = np.array([r.cup_to_coaster_m for r in records], dtype=float)
    cm = d[np.isfinite(d)] * 100
    # The axis ends just past the data (at least past the 2 cm bound, at most at 10 cm);
    # larger distances are counted in the last bin, and the label says how many.
    upper = float(np.clip(np.ceil(cm.max() * 2) / 2, 2.5, 10.0)) if cm.size else 2.5
    over = int(np.sum(cm > upper))
    ax2.hist(np.minimum(cm, upper), bins=np.linspace(0.0, upper, 26), color="tab:gray")
    ax2.set_xlim(0.0, upper)
    ax2.axvline(2.0, color="tab:red", ls="--", label="2 cm success bound")
    clipped = f"; {over} above {upper:g} cm counted at {upper:g}" if over else ""
    ax2.set_xlabel(f"final cup axis to coaster centre (cm)\n{clipped[2:]}".rstrip())
    ax2.set_ylabel("episodes")
    ax2.yaxis.set_major_locator(MaxNLocator(integer=True))
    rate = np.mean([r.success for r in records]) if records else float("nan")
    ax2.set_title(f"success {rate:.0%} of {len(records)} episodes")
    ax2.legend()
    fig.suptitle("pick a cup, place it on a moving coaster, around a ball (arm7, learned DMPs)")
    top = out_dir / "dmp_pick_place_top_view.png"
    fig.savefig(top, dpi=110)

    fig = Figure(figsize=(11, 4), layout="constrained")
    ax, ax2 = fig.subplots(1, 2)
    grasp = np.array([r.grasp_reach_error_m for r in records], dtype=float) * 1000
    place = np.array([r.place_reach_error_m for r in records], dtype=float) * 1000
    clearance = np.array([r.min_obstacle_clearance_m for r in records], dtype=float) * 100
    carry = np.array([carry_clearance(r, config) for r in records]) * 100
    episodes = np.arange(len(records))
    ax.scatter(episodes, grasp, s=10, label="end of grasp")
    for a in (ax, ax2):
        a.xaxis.set_major_locator(MaxNLocator(integer=True))  # episodes are whole
    ax.scatter(episodes, place, s=10, label="end of place (cup in hand)")
    ax.axhline(5.0, color="tab:red", ls="--", lw=0.8, label="5 mm")
    ax.set_xlabel("episode")
    ax.set_ylabel("|tcp - goal| in the physics simulation (mm)")
    reach = np.concatenate([grasp, place])
    reach = reach[np.isfinite(reach)]
    ax.set_ylim(0, max(5.5, 1.1 * float(reach.max())) if reach.size else 5.5)  # 5 mm line shown
    ax.legend(fontsize=8)
    ax.set_title("reach errors")
    ax2.scatter(episodes, carry, s=10, label="while carrying the cup")
    ax2.scatter(episodes, clearance, s=10, marker="x", label="over the whole run")
    ax2.axhline(3.5, color="tab:red", ls="--", lw=0.8, label="cup radius 3.5 cm")
    ax2.set_xlabel("episode")
    ax2.set_ylabel("closest tcp approach to the ball's surface (cm)")
    ax2.legend(fontsize=8)
    ax2.set_title("obstacle clearance")
    fig.suptitle(f"pick and place: reach errors and ball clearance of {len(records)} episodes")
    errors = out_dir / "dmp_pick_place_errors.png"
    fig.savefig(errors, dpi=110)

    ball_gap = np.array([r.min_ball_gap_m for r in records], dtype=float)
    slip_mm = np.array([r.grasp_slip_m for r in records], dtype=float) * 1000
    release_mm = np.array([r.release_object_error_m for r in records], dtype=float) * 1000
    wait_s = np.array([r.start_delay_s for r in records], dtype=float)
    lines = [
        "| figure | value |",
        "|---|---|",
        f"| episodes | {len(records)} |",
        f"| success (cup on coaster within 2 cm) | {rate:.1%} |",
        f"| IK reports (stopped runs) | {sum(bool(r.failure) for r in records)} |",
        "| grasp slips (the cup moved > 1 cm in the hand) | "
        f"{sum(r.outcome == 'grasp_slip' for r in records)} |",
        "| cup's slip in the hand, median / max [mm] | "
        f"{stat_pair(slip_mm, np.median, np.max, 1)} |",
        "| collision-free (ball vs arm/hand/fingers/cup gap > 0) | "
        f"{np.mean([r.collision_free for r in records]) if records else float('nan'):.1%} |",
        "| smallest ball gap (SceneGraph), min / median [cm] | "
        f"{stat_pair(ball_gap * 100, np.min, np.median)} |",
        f"| cup to coaster, median / max [cm] | {stat_pair(d * 100, np.median, np.max)} |",
        "| release found the cup settled (within 1 mm of the centre, at rest) | "
        f"{sum(r.release_settled == 1.0 for r in records)} of {len(records)} |",
        "| cup to coaster when the release began, median / max [mm] | "
        f"{stat_pair(release_mm, np.median, np.max)} |",
        "| release waited past its due time, median / max [s] | "
        f"{stat_pair(wait_s, np.median, np.max)} |",
        f"| grasp reach error, median / max [mm] | {stat_pair(grasp, np.median, np.max)} |",
        f"| place reach error, median / max [mm] | {stat_pair(place, np.median, np.max)} |",
        "| tcp clearance to the ball over the run, min / median [cm] | "
        f"{stat_pair(clearance, np.min, np.median)} |",
        "| tcp clearance to the ball while carrying the cup, min / median [cm] | "
        f"{stat_pair(carry, np.min, np.median)} |",
        *timing_rows(records),
    ]
    table = write_table(out_dir, "dmp_pick_place_results.md", lines)
    limits = joint_limits_figure(records, out_dir / "dmp_pick_place_joint_limits.png")
    return {"top_view": top, "errors": errors, "results": table, "joint_limits": limits}


def joint_limits_figure(records: list[PickPlaceRecord], out: Path) -> Path:
    """The episodes' joint-limit margins and a probe run that the limits stop.

    Left: per arm7 joint, each episode's least distance of the IK reference from the
    joint's limits, and how many IK steps held it at one. Right:
    :func:`~repertoire.studies._dmp_common.joint_limit_probe`'s joints over time, each
    scaled to its range (0 lower limit, 1 upper), the steps where the IK held one by a
    limit marked (``joints_at_limits``: its velocity bound came from the limit, braking
    toward it or resting on it), and where the IK stopped the run.

    Args:
        records: the episodes.
        out: the PNG to write.
    """
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from repertoire.models.arm7 import ARM_JOINTS, arm7_joint_limits
    from repertoire.studies._dmp_common import PROBE_TURN_RAD, joint_limit_probe

    lower, upper = arm7_joint_limits()
    colours = [f"C{j}" for j in range(len(ARM_JOINTS))]
    fig = Figure(figsize=(13, 5.4), layout="constrained")
    ax, ax2 = fig.subplots(1, 2, width_ratios=[1, 1.3])
    margins = np.array([r.joint_margins_rad for r in records], dtype=float).reshape(
        -1, len(ARM_JOINTS)
    )
    held = np.array([r.joint_held_steps for r in records], dtype=int).reshape(-1, len(ARM_JOINTS))
    placed = np.array([bool(r.success) for r in records], dtype=bool)
    for j in range(len(ARM_JOINTS)):
        for mask, fill in ((placed, colours[j]), (~placed, "none")):
            ax.plot(np.full(mask.sum(), j), margins[mask, j], "o", mfc=fill, color=colours[j])
        ax.annotate(f"held\n{held[:, j].sum()}", (j, 1.0), xycoords=("data", "axes fraction"),
                    xytext=(0, -2), textcoords="offset points", ha="center", va="top",
                    fontsize=7)  # fmt: skip
    ax.axhline(0.0, color="k", lw=0.8)
    ax.set_xticks(range(len(ARM_JOINTS)))
    ax.set_xticklabels(
        [f"{n}\n[{lo:g}, {hi:g}]" for n, lo, hi in zip(ARM_JOINTS, lower, upper, strict=True)],
        rotation=30,
        ha="right",
        fontsize=8,
    )
    ax.set_ylim(bottom=-0.05)
    ax.set_ylabel("the IK reference's least distance\nfrom a limit over the run [rad]")
    runs_held = int(np.sum(held.sum(axis=1) > 0))
    unrun = int(np.sum(~np.isfinite(margins).all(axis=1)))
    ax.set_title(
        f"{len(records)} episodes ({unrun} refused before running), a circle each;\n"
        f"filled: cup placed; {runs_held} with a joint held by a limit\n"
        f"(top: IK steps held, per joint)",
        fontsize=9,
    )
    ax.set_ylim(top=max(1.25, float(np.nanmax(margins, initial=0.0)) * 1.2))
    recorder, report = joint_limit_probe()
    t, scaled = recorder.times, (recorder.q - lower) / (upper - lower)
    for j, name in enumerate(ARM_JOINTS):
        ax2.plot(t, scaled[:, j], color=colours[j], lw=1.2, label=name)
        for sign, marker in ((1.0, "^"), (-1.0, "v")):
            at = recorder.held[:, j] == sign
            ax2.plot(t[at], scaled[at, j], marker, ms=4, color=colours[j], ls="")
    ax2.axhline(0.0, color="k", lw=0.6)
    ax2.axhline(1.0, color="k", lw=0.6)
    handles, _ = ax2.get_legend_handles_labels()
    handles += [
        # joints_at_limits: the step's velocity bound came from the limit (braking or on it)
        Line2D([], [], ls="", marker="^", color="k", label="IK step held by the upper limit"),
        Line2D([], [], ls="", marker="v", color="k", label="IK step held by the lower limit"),
    ]
    if report:
        ax2.axvline(t[-1], color="tab:red", ls="--", lw=1)
        handles.append(
            Line2D([], [], color="tab:red", ls="--", label=f"IK stops the run ({t[-1]:.2f} s)")
        )
    ax2.legend(handles=handles, fontsize=7, loc="center left", bbox_to_anchor=(1.01, 0.5))
    ax2.set_xlabel("time [s]")
    ax2.set_ylabel("IK reference joint position, scaled to its limits (0 lower, 1 upper)")
    stop = report.split("IK reported ", 1)[-1].split(" in segment")[0] if report else "no stop"
    clause = "joints held at a limit: "
    held_text = report.split(clause, 1)[1].split(" (the desired")[0] if clause in report else ""
    ax2.set_title(
        f"probe: the hand at home asked to turn {PROBE_TURN_RAD:g} rad about its x axis\n"
        f"{stop}" + (f"\nheld: {held_text}" if held_text else ""),
        fontsize=9,
    )
    fig.suptitle("arm7's joint limits: the pick-and-place episodes, and a goal beyond them")
    fig.savefig(out, dpi=110)
    return out


register_dmp_study(
    __name__,
    PickPlaceConfig,
    PickPlaceRecord,
    description="arm7 + learned DMPs: pick a cup, place it on a moving coaster around a ball; "
    "success rate over random layouts",
    demo_episodes=4,
    # a tiny config for tests: the first 0.3 s of an episode
    smoke=dict(sim_duration_s=0.3),
)
