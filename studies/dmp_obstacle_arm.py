"""Obstacle on the carry path (Pastor et al. 2009, Fig. 13, third row) in the physics simulation.

Each episode draws a cup and a coaster from the seed, rolls the learned place
DMP out without coupling (:func:`repertoire.diagrams.arm_dmp_scenarios.carry_path`) and
puts the ball (radius 6 cm, on its post) on that path: at a seeded fraction of
its arc length, shifted by a few cm sideways and down, where the carried cup or
the fingers hit it when nothing steers. The same layout then runs twice in the
``arm_pick_and_place`` world: with the DMP coupling term (eq. 10 at the tcp,
the cup's lower part, the two finger groups and the palm (centre and ends),
faded with the distance to the ball:
:class:`repertoire.systems.obstacle_coupling.MultiPointObstacleCoupling`) and without it.
Recorded per arm: success (the cup stands on the coaster, within 2 cm of its
centre), collision-free (the smallest signed distance between the
ball and any collision geometry of the arm, hand, fingers or cup, from
SceneGraph every 4 ms, stays > 0), that distance, and the tcp path.

Run it with ``python -m repertoire.studies.dmp_obstacle_arm --help``.
"""

import dataclasses
import time
from pathlib import Path

import numpy as np
from repertoire.studies._dmp_common import (
    carry_control_points,
    check_arm_config,
    default_obstacle_gamma,
    obstacle_radius,
    register_dmp_study,
    run_pick_and_place,
    write_table,
)

from repertoire.errors import RepertoireError

ARMS = ("coupled", "uncoupled")
#: The ball's centre stays this far from the tcp at home (the open hand starts there; at
#: 0.123 m the thumb touches the ball, at 0.141 m it is 9 mm clear) [m]; placements
#: closer are drawn again.
HOME_CLEARANCE = 0.145


@dataclasses.dataclass
class ObstacleArmConfig:
    """What every episode shares.

    Attributes:
        cup_x: range [min, max] of the cup's x [m]; likewise the other ranges.
        cup_y: range of the cup's y [m].
        coaster_x: range of the coaster's x [m] (it stays put in this study).
        coaster_y: range of the coaster's y [m].
        path_fraction: range of where along the uncoupled carry path (fraction of its
            arc length) the ball's centre sits (drawn again while the ball would be
            within HOME_CLEARANCE of the hand at home, or touch the arm there).
        offset_x: range of the ball's shift along world x (across the carry) [m].
        offset_z: range of the ball's shift along world z [m] (negative: below the tcp
            path, into the carried cup).
        obstacle_gamma: gamma of eq. 10 (on the scaled velocity v = tau dx/dt).
        obstacle_beta: the angular decay c of eq. 10.
        obstacle_length_scale: decay length of the distance factor [m] (0 = eq. 10).
        obstacle_points: control points in the tcp frame ([[0, 0, 0]] = tcp only).
        time_step: plant time step [s].
        sim_duration_s: simulated seconds (0 = the whole sequence).
        path_every_s: sampling period of the stored tcp paths [s].
    """

    cup_x: list[float] = dataclasses.field(default_factory=lambda: [0.52, 0.58])
    cup_y: list[float] = dataclasses.field(default_factory=lambda: [-0.28, -0.22])
    coaster_x: list[float] = dataclasses.field(default_factory=lambda: [0.52, 0.58])
    coaster_y: list[float] = dataclasses.field(default_factory=lambda: [0.19, 0.24])
    path_fraction: list[float] = dataclasses.field(default_factory=lambda: [0.60, 0.68])
    offset_x: list[float] = dataclasses.field(default_factory=lambda: [-0.02, 0.02])
    offset_z: list[float] = dataclasses.field(default_factory=lambda: [-0.01, 0.0])
    obstacle_gamma: float = dataclasses.field(default_factory=default_obstacle_gamma)
    obstacle_beta: float = 4.0
    obstacle_length_scale: float = 0.03
    obstacle_points: list[list[float]] = dataclasses.field(default_factory=carry_control_points)
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
            "path_fraction",
            "offset_x",
            "offset_z",
        )
        check_arm_config(self, {n: getattr(self, n) for n in names})
        if not (0.0 <= self.path_fraction[0] and self.path_fraction[1] <= 1.0):
            raise RepertoireError(
                f"ObstacleArmConfig.path_fraction must lie in [0, 1], got {self.path_fraction}"
            )


@dataclasses.dataclass
class ObstacleArmRecord:
    """One layout, run with and without coupling.

    Attributes:
        cup_xy: the cup's start.
        coaster_xy: the coaster (fixed).
        obstacle_xyz: the ball's centre.
        uncoupled_path_gap_m: the ball's surface to the uncoupled carry path (tcp) [m].
        success: per arm (``coupled``, ``uncoupled``): the cup on the coaster within 2 cm.
        collision_free: per arm: the smallest ball gap stayed > 0.
        min_ball_gap_m: per arm: smallest signed distance ball - arm/hand/fingers/cup [m].
        min_ball_gap_time_s: per arm: when it occurred.
        cup_to_coaster_m: per arm: final horizontal distance cup axis - coaster centre.
        grasp_slip_m: per arm: the largest distance the cup moved in the hand while
            carried [m].
        outcome: per arm: ``stopped``, ``grasp_slip`` (the cup moved more than 1 cm in
            the hand), ``placed`` or ``missed`` (``_dmp_common.OUTCOMES``).
        failure: per arm: empty, or why the run stopped.
        path_x: per arm: tcp x every ``path_every_s``.
        path_y: per arm: tcp y.
        path_z: per arm: tcp z.
        sim_time_s: simulated seconds per run.
        wall_time_s: wall seconds of the episode (timing field).
        wall_sim_s: wall seconds of the two simulations alone (timing field).
    """

    cup_xy: list[float]
    coaster_xy: list[float]
    obstacle_xyz: list[float]
    uncoupled_path_gap_m: float
    success: dict[str, bool]
    collision_free: dict[str, bool]
    min_ball_gap_m: dict[str, float]
    min_ball_gap_time_s: dict[str, float]
    cup_to_coaster_m: dict[str, float]
    grasp_slip_m: dict[str, float]
    outcome: dict[str, str]
    failure: dict[str, str]
    path_x: dict[str, list[float]]
    path_y: dict[str, list[float]]
    path_z: dict[str, list[float]]
    sim_time_s: float
    wall_time_s: float
    wall_sim_s: float


def sample_scenario(config: ObstacleArmConfig, seed: int, *, coupling: bool = True):
    """The seeded PickPlaceScenario of an episode (the ball on the carry path).

    Args:
        config: the study config.
        seed: the episode seed.
        coupling: whether the ball feeds the DMP coupling term.

    Returns:
        ``(scenario, gap of the ball's surface to the uncoupled tcp carry path [m])``.
    """
    from repertoire.diagrams.arm_dmp_scenarios import (
        PickPlaceScenario,
        ball_gap_at_home,
        carry_path,
        carry_path_point,
    )
    from repertoire.planning.arm_library import home_tcp_pose

    rng = np.random.default_rng(seed)
    cup = [float(rng.uniform(*config.cup_x)), float(rng.uniform(*config.cup_y))]
    coaster = [float(rng.uniform(*config.coaster_x)), float(rng.uniform(*config.coaster_y))]
    home = home_tcp_pose().translation()
    for _ in range(100):
        fraction = rng.uniform(*config.path_fraction)
        offset = np.array([rng.uniform(*config.offset_x), 0.0, rng.uniform(*config.offset_z)])
        centre = carry_path_point(cup, coaster, fraction) + offset
        # clear of the hand, and of the whole arm (the scenario refuses a ball that
        # overlaps the arm where it starts: an elbow or forearm, not only the hand)
        if np.linalg.norm(centre - home) >= HOME_CLEARANCE and ball_gap_at_home(centre) > 0.0:
            break
    else:
        raise RepertoireError(
            f"no ball placement {HOME_CLEARANCE} m away from the tcp at home and clear of the "
            "arm in 100 draws; move path_fraction away from the middle of the carry path"
        )
    gap = float(
        np.min(np.linalg.norm(carry_path(cup, coaster) - centre, axis=1)) - obstacle_radius()
    )
    scenario = PickPlaceScenario(
        time_step=config.time_step,
        cup_xy=cup,
        coaster_xy=coaster,
        coaster_final_xy=list(coaster),
        obstacle_xyz=[round(float(v), 5) for v in centre],
        obstacle_coupling=coupling,
        obstacle_gamma=config.obstacle_gamma,
        obstacle_beta=config.obstacle_beta,
        obstacle_length_scale=config.obstacle_length_scale,
        obstacle_points=[list(map(float, p)) for p in config.obstacle_points],
    )
    return scenario, gap


def run_episode(config: ObstacleArmConfig, seed: int) -> ObstacleArmRecord:
    """Builds one seeded layout and runs it with and without coupling.

    Args:
        config: the study config.
        seed: the episode seed.
    """
    t0 = time.perf_counter()
    config.validate()
    runs, scenario, gap = {}, None, float("nan")
    for arm in ARMS:
        scenario, gap = sample_scenario(config, seed, coupling=arm == "coupled")
        runs[arm] = run_pick_and_place(scenario, config.sim_duration_s, config.path_every_s)

    return ObstacleArmRecord(
        cup_xy=scenario.cup_xy,
        coaster_xy=scenario.coaster_xy,
        obstacle_xyz=scenario.obstacle_xyz,
        uncoupled_path_gap_m=gap,
        success={a: r["placed"] for a, r in runs.items()},
        collision_free={a: bool(r["min_ball_gap_m"] > 0.0) for a, r in runs.items()},
        min_ball_gap_m={a: float(r["min_ball_gap_m"]) for a, r in runs.items()},
        min_ball_gap_time_s={a: float(r["min_ball_gap_time_s"]) for a, r in runs.items()},
        cup_to_coaster_m={a: float(r["cup_to_coaster_m"]) for a, r in runs.items()},
        grasp_slip_m={a: float(r["grasp_slip_m"]) for a, r in runs.items()},
        outcome={a: r["outcome"] for a, r in runs.items()},
        failure={a: r["failure"] for a, r in runs.items()},
        path_x={a: [round(float(v), 5) for v in r["path"][:, 0]] for a, r in runs.items()},
        path_y={a: [round(float(v), 5) for v in r["path"][:, 1]] for a, r in runs.items()},
        path_z={a: [round(float(v), 5) for v in r["path"][:, 2]] for a, r in runs.items()},
        sim_time_s=float(runs["coupled"]["duration"]),
        wall_time_s=time.perf_counter() - t0,
        wall_sim_s=float(sum(r["wall"] for r in runs.values())),
    )


def _rate(records: list[ObstacleArmRecord], field: str, arm: str) -> float:
    return float(np.mean([getattr(r, field)[arm] for r in records])) if records else float("nan")


def summarize(
    records: list[ObstacleArmRecord], config: ObstacleArmConfig, out_dir: Path
) -> dict[str, Path]:
    """Top and side views of the tcp paths around the balls; gap histogram; a Markdown table.

    Returns:
        ``{"paths": png, "gaps": png, "results": md}``.
    """
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import Circle, Patch
    from matplotlib.ticker import MaxNLocator

    out_dir = Path(out_dir)
    colors = {"coupled": "tab:green", "uncoupled": "tab:red"}
    fig = Figure(figsize=(12, 7), layout="constrained")
    axes = fig.subplots(2, 2, sharex="all", sharey="row")
    shown = records[:3]
    radius = obstacle_radius()
    fig.suptitle(
        f"tcp paths of the first {len(shown)} episodes (darker = later episode): home -> cup "
        "-> coaster -> retreat,\nwith and without eq. 10 coupling; the same layouts in both "
        "columns"
    )
    for col, arm in enumerate(ARMS):
        top, side = axes[0, col], axes[1, col]
        for k, r in enumerate(shown):
            shade = 0.35 + 0.65 * (k + 1) / len(shown)
            o = r.obstacle_xyz
            top.add_patch(Circle((o[1], o[0]), radius, color="tab:blue", alpha=0.25))
            side.add_patch(Circle((o[1], o[2]), radius, color="tab:blue", alpha=0.25))
            side.plot([o[1], o[1]], [0.75, o[2] - radius], color="tab:gray", lw=1.5)  # its post
            if r.path_x[arm]:
                y, x, z = np.array(r.path_y[arm]), np.array(r.path_x[arm]), np.array(r.path_z[arm])
                top.plot(y, x, color=colors[arm], alpha=shade, lw=1.0)
                side.plot(y, z, color=colors[arm], alpha=shade, lw=1.0)
                side.plot(y, z - 0.052, color=colors[arm], alpha=shade, lw=0.6, ls=":")
            # black: red and green already mean the uncoupled and coupled tcp paths
            top.plot(r.cup_xy[1], r.cup_xy[0], "o", color="k", mfc="none")
            top.plot(r.coaster_xy[1], r.coaster_xy[0], "s", color="k", mfc="none")
        top.set_title(f"{arm}: top view")
        top.tick_params(labelbottom=True)  # shared with the side view, but labelled here too
        top.set_xlabel("y (m)")
        top.set_ylabel("x (m)")
        top.invert_xaxis()
        top.set_aspect("equal")
        side.set_title(f"{arm}: side view (looking along x)")
        side.set_xlabel("y (m)")
        side.set_ylabel("z (m)")
        side.invert_xaxis()
        side.set_aspect("equal")
    # one legend below the panels: inside them it covered the paths' starts
    handles = [
        *(Line2D([], [], color=c, lw=1.0, label=f"tcp, {arm}") for arm, c in colors.items()),
        Line2D([], [], color="0.4", lw=0.6, ls=":", label="cup bottom (tcp - 5.2 cm)"),
        Line2D([], [], ls="", marker="o", color="k", mfc="none", label="cup"),
        Line2D([], [], ls="", marker="s", color="k", mfc="none", label="coaster"),
        Patch(color="tab:blue", alpha=0.25, label=f"ball (radius {radius * 100:g} cm)"),
        Line2D([], [], color="tab:gray", lw=1.5, label="ball's post"),
    ]
    fig.legend(handles=handles, loc="outside lower center", ncols=7, fontsize=8)
    paths = out_dir / "dmp_obstacle_arm_paths.png"
    fig.savefig(paths, dpi=100)

    fig = Figure(figsize=(8, 4), layout="constrained")
    ax = fig.subplots()
    for arm, dx, marker in zip(ARMS, (-0.08, 0.08), ("o", "s"), strict=True):
        g = np.array([r.min_ball_gap_m[arm] for r in records], dtype=float) * 100
        # side by side per episode: drawn on one x, equal gaps hid the coupled point
        ax.scatter(np.arange(len(g)) + dx, g, s=14, marker=marker, color=colors[arm], label=arm)
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.axhline(0.0, color="k", lw=0.8)
    ax.set_xlabel("episode")
    ax.set_ylabel("smallest gap ball - arm/hand/fingers/cup (cm)")
    ax.set_title(
        "smallest signed distance ball - robot per episode (SceneGraph;\n"
        "< 0: they touched; contact pushes back)"
    )
    ax.legend(loc="center left", bbox_to_anchor=(1.0, 0.5))
    gaps = out_dir / "dmp_obstacle_arm_gaps.png"
    fig.savefig(gaps, dpi=110)

    lines = [
        "| figure | coupled | uncoupled |",
        "|---|---|---|",
        f"| episodes | {len(records)} | |",
    ]
    for label, field in (
        ("collision-free (gap > 0)", "collision_free"),
        ("success (cup on coaster within 2 cm)", "success"),
    ):
        lines.append(
            f"| {label} | {_rate(records, field, 'coupled'):.1%} "
            f"| {_rate(records, field, 'uncoupled'):.1%} |"
        )
    for label, fn in (("smallest gap, min [cm]", np.min), ("smallest gap, median [cm]", np.median)):
        vals = []
        for arm in ARMS:
            g = np.array([r.min_ball_gap_m[arm] for r in records], dtype=float)
            g = g[np.isfinite(g)]
            vals.append(f"{fn(g) * 100:.2f}" if g.size else "n/a")
        lines.append(f"| {label} | {vals[0]} | {vals[1]} |")
    stops = [sum(bool(r.failure[a]) for r in records) for a in ARMS]
    lines.append(f"| stopped runs (IK report) | {stops[0]} | {stops[1]} |")
    slips = [sum(r.outcome[a] == "grasp_slip" for r in records) for a in ARMS]
    lines.append(f"| grasp slips (the cup moved > 1 cm in the hand) | {slips[0]} | {slips[1]} |")
    gap0 = np.array([r.uncoupled_path_gap_m for r in records], dtype=float) * 100
    if gap0.size:
        lines.append(
            f"| ball surface to the uncoupled tcp path, min / max [cm] | "
            f"{np.min(gap0):.2f} / {np.max(gap0):.2f} | |"
        )
    table = write_table(out_dir, "dmp_obstacle_arm_results.md", lines)
    return {"paths": paths, "gaps": gaps, "results": table}


register_dmp_study(
    __name__,
    ObstacleArmConfig,
    ObstacleArmRecord,
    description="arm7 + learned DMPs: a ball on the carry path, pick-and-place with vs without "
    "the obstacle coupling term; collision-free and success rates",
    demo_episodes=2,
    # a tiny config for tests: the first 0.2 s of each run
    smoke=dict(sim_duration_s=0.2),
)
