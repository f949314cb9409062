"""Generalisation grid (Pastor et al. 2009, Fig. 10) in the physics simulation.

The grasp and the place DMP, learned once from their demonstrations, are sent
to a grid of new goals: episode ``k`` grasps at grasp-grid cell ``k`` and then
places at place-grid cell ``k`` (no object in the hand: this measures the
movement generation and the task-space control alone). The arm7 runs under
RMRC IK and inverse dynamics + PD in the MultibodyPlant; the figure of the
study is the grid of adapted tcp paths beside the demonstrations. Pass
criterion: the tcp reaches each goal within 5 mm.

Run it with ``python -m repertoire.studies.dmp_grid --help``.
"""

import dataclasses
import time
from pathlib import Path

import numpy as np
from repertoire.studies._dmp_common import (
    check_arm_config,
    finite_max,
    log_stride,
    register_dmp_study,
    write_table,
)

from repertoire.checks import is_whole
from repertoire.errors import RepertoireError

REACH_TOLERANCE_M = 0.005


@dataclasses.dataclass
class GridConfig:
    """The goal grids.

    Attributes:
        grasp_x: [min, max] of the grasp goals' x [m] (``n`` values across).
        grasp_y: [min, max] of the grasp goals' y [m].
        place_x: [min, max] of the place goals' x [m].
        place_y: [min, max] of the place goals' y [m].
        n: grid points per axis (``n * n`` cells; episode k uses cell k mod n^2).
        time_step: plant time step [s].
        sim_duration_s: simulated seconds (0 = grasp and place in full).
        path_every_s: sampling period of the stored tcp path [s].
    """

    grasp_x: list[float] = dataclasses.field(default_factory=lambda: [0.48, 0.60])
    grasp_y: list[float] = dataclasses.field(default_factory=lambda: [-0.32, -0.16])
    place_x: list[float] = dataclasses.field(default_factory=lambda: [0.48, 0.62])
    place_y: list[float] = dataclasses.field(default_factory=lambda: [0.0, 0.18])
    n: int = 3
    time_step: float = 0.004
    sim_duration_s: float = 0.0
    path_every_s: float = 0.05

    def validate(self) -> None:
        """Raises RepertoireError for a bad range or grid size."""
        if not (is_whole(self.n) and self.n >= 1):
            raise RepertoireError(f"GridConfig.n must be an integer >= 1, got {self.n}")
        names = ("grasp_x", "grasp_y", "place_x", "place_y")
        check_arm_config(self, {n: getattr(self, n) for n in names})

    def cell(self, seed: int) -> tuple[np.ndarray, np.ndarray]:
        """(grasp goal, place goal) of the episode with this seed."""
        from repertoire.diagrams.arm_dmp_scenarios import COASTER_RAIL_HEIGHT, place_offset
        from repertoire.models.arm7 import TABLE_HEIGHT
        from repertoire.planning.arm_library import CUP_GRASP_HEIGHT

        k = seed % (self.n * self.n)
        i, j = divmod(k, self.n)

        def grid(r, index):
            return r[0] if self.n == 1 else r[0] + (r[1] - r[0]) * index / (self.n - 1)

        grasp = np.array(
            [grid(self.grasp_x, i), grid(self.grasp_y, j), TABLE_HEIGHT + CUP_GRASP_HEIGHT]
        )
        place = np.array([grid(self.place_x, i), grid(self.place_y, j), COASTER_RAIL_HEIGHT])
        return grasp, place + place_offset()


@dataclasses.dataclass
class GridRecord:
    """One grid episode.

    Attributes:
        cell: the grid cell.
        grasp_goal: the grasp goal [m].
        place_goal: the place goal [m].
        grasp_reach_error_m: |tcp - grasp goal| at the end of the grasp (physics).
        place_reach_error_m: |tcp - place goal| at the end of the place (physics).
        grasp_orientation_error_rad: tcp orientation error at the end of the grasp.
        reached: both errors within 5 mm.
        failure: empty, or why the run stopped (IK report).
        path_x: tcp x every ``path_every_s`` [m].
        path_y: tcp y.
        path_z: tcp z.
        wall_time_s: wall seconds of the episode (timing field).
        wall_sim_s: wall seconds of the simulation (timing field).
    """

    cell: int
    grasp_goal: list[float]
    place_goal: list[float]
    grasp_reach_error_m: float
    place_reach_error_m: float
    grasp_orientation_error_rad: float
    reached: bool
    failure: str
    path_x: list[float]
    path_y: list[float]
    path_z: list[float]
    wall_time_s: float
    wall_sim_s: float


def run_episode(config: GridConfig, seed: int) -> GridRecord:
    """Grasp at one grid cell, then place at the matching place cell.

    Args:
        config: the study config.
        seed: the episode seed (selects the cell).
    """
    from pydrake.common.eigen_geometry import Quaternion
    from repertoire.diagrams.arm_dmp import build_arm_world
    from repertoire.diagrams.arm_dmp_results import (
        IkTargetError,
        run_arm_world,
        segment_reach_errors,
        tcp_log,
    )
    from repertoire.diagrams.arm_dmp_scenarios import PickPlaceScenario, segment_timing
    from repertoire.models.arm7 import HAND_GRASP_7CM
    from repertoire.planning.arm_library import (
        R_SIDE,
        approach_direction,
        home_tcp_pose,
        motion_library,
        quaternion_wxyz,
        rotation_from_approach,
    )
    from repertoire.systems.arm_goals import SegmentGoal

    t0 = time.perf_counter()
    config.validate()
    grasp, place = config.cell(seed)
    lib = motion_library()
    R_grasp = rotation_from_approach(
        approach_direction(lib["grasp"], home_tcp_pose().translation(), grasp)
    )
    fingers = np.array(HAND_GRASP_7CM)
    goals = [
        SegmentGoal("grasp", grasp, quaternion_wxyz(R_grasp), fingers),
        SegmentGoal("place", place, quaternion_wxyz(R_SIDE), fingers),
    ]
    scenario = PickPlaceScenario(time_step=config.time_step)
    starts, duration = segment_timing(["grasp", "place"], scenario.settle_time)
    if config.sim_duration_s > 0:
        duration = min(duration, config.sim_duration_s)
    nan = float("nan")
    errors, ori_error, failure, path, wall_sim = [nan, nan], nan, "", np.zeros((0, 3)), 0.0
    try:
        diagram = build_arm_world("dmp_grid", scenario, [], goals, graspable=[])
        context, wall_sim = run_arm_world(diagram, duration)
        errors = (segment_reach_errors(diagram, context) + [nan, nan])[:2]
        log = tcp_log(diagram, context)
        path = log.point[:: log_stride(config.path_every_s)]
        # Orientation error at the end of the grasp: from the logged palm z axis.
        rows = np.nonzero(log.segment == 0)[0]
        z_axis = log.axis[rows[-1]]
        z_goal = Quaternion(goals[0].orientation).rotation()[:, 2]
        ori_error = float(np.arccos(np.clip(z_axis @ z_goal, -1.0, 1.0)))
    except (IkTargetError, RepertoireError) as e:
        failure = str(e)
    del starts
    reached = not failure and max(errors) < REACH_TOLERANCE_M
    return GridRecord(
        cell=int(seed % (config.n * config.n)),
        grasp_goal=[float(v) for v in grasp],
        place_goal=[float(v) for v in place],
        grasp_reach_error_m=float(errors[0]),
        place_reach_error_m=float(errors[1]),
        grasp_orientation_error_rad=ori_error,
        reached=bool(reached),
        failure=failure,
        path_x=[round(float(v), 5) for v in path[:, 0]],
        path_y=[round(float(v), 5) for v in path[:, 1]],
        path_z=[round(float(v), 5) for v in path[:, 2]],
        wall_time_s=time.perf_counter() - t0,
        wall_sim_s=float(wall_sim),
    )


def results_lines(records: list[GridRecord]) -> list[str]:
    """The results table (one row per cell) and its summary line, in Markdown.

    An error is ``n/a`` where the run stopped (or its simulated time ended) before that
    segment; the summary explains ``n/a`` only when the table shows one.

    Args:
        records: The grid episodes.
    """
    g = np.array([r.grasp_reach_error_m for r in records], dtype=float) * 1000
    p = np.array([r.place_reach_error_m for r in records], dtype=float) * 1000
    o = np.degrees(np.array([r.grasp_orientation_error_rad for r in records], dtype=float))
    lines = [
        "| cell | grasp goal [m] | place goal [m] | grasp error [mm] | place error [mm] | "
        "approach-axis error [deg] | within 5 mm |",
        "|---|---|---|---|---|---|---|",
    ]

    def mm(value: float) -> str:  # NaN: the run stopped (or ended) before that segment
        return f"{value:.2f}" if np.isfinite(value) else "n/a"

    for r, ge, pe, oe in zip(records, g, p, o):
        # a miss without a failure is an error above 5 mm (or a run too short): the
        # error columns say by how much; "no: error" read as if the episode had raised
        verdict = "yes" if r.reached else f"no: {r.failure[:80]}" if r.failure else "no"
        lines.append(
            f"| {r.cell} | {np.round(r.grasp_goal, 3).tolist()} | "
            f"{np.round(r.place_goal, 3).tolist()} | {mm(ge)} | {mm(pe)} | {mm(oe)} | "
            f"{verdict} |"
        )
    legend = ""
    if not np.all(np.isfinite(np.concatenate([g, p, o]))):
        legend = (
            " n/a: the run stopped (or its simulated time ended) before that segment; "
            "a max is n/a when no run got that far."
        )
    lines.append(
        f"\n{sum(r.reached for r in records)} of {len(records)} cells reached within 5 mm; "
        f"max grasp error {mm(finite_max(g))} mm, max place error {mm(finite_max(p))} mm." + legend
    )
    return lines


def summarize(records: list[GridRecord], config: GridConfig, out_dir: Path) -> dict:
    """Fig. 10: demonstrated paths (blue) and the adapted physical tcp paths (red).

    Returns:
        ``{"grid": png, "results": md}``.
    """
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator, MultipleLocator
    from repertoire.planning.arm_library import synthetic_demonstrations

    out_dir = Path(out_dir)
    demos = synthetic_demonstrations()
    fig = Figure(figsize=(12, 5.2), layout="constrained")
    ax3 = fig.add_subplot(1, 2, 1, projection="3d")
    ax = fig.add_subplot(1, 2, 2)
    for label, style in (("grasp", "-"), ("place", "--")):
        p = demos[label].position
        ax3.plot(p[:, 0], p[:, 1], p[:, 2], color="tab:blue", lw=2.5, ls=style, zorder=5)
        ax.plot(
            p[:, 1],
            p[:, 0],
            color="tab:blue",
            lw=2.5,
            ls=style,
            zorder=5,
            label=f"demonstrated {label}",
        )
    for r in records:
        color = "tab:red" if r.reached else "0.3"
        # above the demonstrations, which a short (quick) path would hide under
        ax3.plot(r.path_x, r.path_y, r.path_z, color=color, lw=1.2, zorder=6)
        ax.plot(r.path_y, r.path_x, color=color, lw=1.2, zorder=6)
        for g in (r.grasp_goal, r.place_goal):
            ax3.scatter(*g, color="tab:green", marker="+", s=40)  # as in the top view
            ax.plot(g[1], g[0], "+", color="tab:green", ms=8)
    ax3.set_xlabel("x (m)")
    ax3.set_ylabel("y (m)", labelpad=10)
    ax3.set_zlabel("z (m)", labelpad=10)
    ax3.set_aspect("equal")  # metres on all three axes
    for axis in (ax3.xaxis, ax3.zaxis):
        axis.set_major_locator(MaxNLocator(4))  # at equal aspect, more ticks overlap
    ax3.yaxis.set_major_locator(MultipleLocator(0.2))
    ax3.set_title("3-D view")
    ax.set_xlabel("y (m, left)")
    ax.set_ylabel("x (m, forward)")
    ax.invert_xaxis()
    ax.set_aspect("equal")
    ax.plot([], [], color="tab:red", lw=1.2, label="physical tcp path (goal reached)")
    if not all(r.reached for r in records):
        ax.plot([], [], color="0.3", lw=1.2, label="physical tcp path (goal missed)")
    ax.plot([], [], "+", color="tab:green", ms=8, ls="", label="new goals")
    # one legend below both panels (inside, it covered the place goals at the lower left)
    fig.legend(handles=ax.get_legend_handles_labels()[0], loc="outside lower center", ncols=5)
    ax.set_title("top view: grasp grid (right), place grid (left)")
    fig.suptitle(
        f"Fig. 10: learned grasp and place DMPs on arm7 sent to {len(records)} new goal pairs"
    )
    grid = out_dir / "dmp_grid_paths.png"
    fig.savefig(grid, dpi=110)
    table = write_table(out_dir, "dmp_grid_results.md", results_lines(records))
    return {"grid": grid, "results": table}


register_dmp_study(
    __name__,
    GridConfig,
    GridRecord,
    description="arm7 + learned grasp/place DMPs sent to a grid of new goals (Fig. 10): "
    "physical reach error per goal",
    demo_episodes=9,
    # a tiny config for tests: one cell, the first 0.3 s
    smoke=dict(n=1, sim_duration_s=0.3),
)
