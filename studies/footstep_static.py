"""Footstep planning among static flat obstacles (Chestnutt et al., Sec. IV-B, Fig. 3).

Each episode draws a random 3 m x 3 m floor with 2.5 cm cells (long thin strips a biped
may step over and a few larger blocks), plans footsteps from one corner to the opposite
corner with the A* footstep planner, and plans the same trip with a 2-D mobile-robot
planner using the robot's bounding circle, which has to go around every obstacle. It
records success, steps, planning time, nodes expanded and how many steps cross over an
obstacle.

Run it with ``python -m repertoire.studies.footstep_static --help``.
"""

import dataclasses
import math
from pathlib import Path

import numpy as np
from repertoire.studies._footstep_common import (
    load_table,
    markdown_table,
    percentile,
    planner_options,
    planner_rows,
)
from repertoire.studies.engine import register_study

from repertoire.errors import RepertoireError
from repertoire.limits import require_grid_memory


@dataclasses.dataclass
class FootstepStaticConfig:
    """What every episode shares.

    Attributes:
        size_m: side of the square floor.
        resolution_m: grid cell side.
        n_strips: long thin flat obstacles per map.
        n_blocks: larger blocks per map.
        time_limit_s: planner time limit (generous: the node budget binds first).
        max_expansions: deterministic node budget of the planner.
        heuristic_weight: w in g + w h (Dijkstra cost-to-go heuristic).
        body_radius_m: bounding-circle radius of the 2-D planner's robot.
        table_path: action table file (.json/.npz); empty for the nominal table.
        example_figures: number of example plans drawn by the summary.
        swing_clearance_m: the swing foot clears obstacles up to this height (the maps'
            obstacles are 2 cm high, so they are stepped over; taller ones would block).
    """

    size_m: float = 3.0
    resolution_m: float = 0.025
    n_strips: int = 4
    n_blocks: int = 2
    time_limit_s: float = 30.0
    max_expansions: int = 200000
    heuristic_weight: float = 1.5
    body_radius_m: float = 0.30
    table_path: str = ""
    example_figures: int = 4
    swing_clearance_m: float = 0.10

    def validate(self) -> None:
        """Raise RepertoireError if a field is out of range."""
        for name in (
            "size_m",
            "resolution_m",
            "time_limit_s",
            "body_radius_m",
            "swing_clearance_m",
        ):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise RepertoireError(f"FootstepStaticConfig.{name} must be > 0, got {v}")
        if self.size_m < 1.5:
            raise RepertoireError(f"FootstepStaticConfig.size_m must be >= 1.5, got {self.size_m}")
        require_grid_memory(self.size_m, self.resolution_m, f"footstep_static size_m={self.size_m}")
        for name in ("n_strips", "n_blocks", "max_expansions", "example_figures"):
            if getattr(self, name) < 0:
                raise RepertoireError(f"FootstepStaticConfig.{name} must be >= 0")
        if not (math.isfinite(self.heuristic_weight) and self.heuristic_weight >= 0):
            raise RepertoireError("FootstepStaticConfig.heuristic_weight must be >= 0")


@dataclasses.dataclass
class FootstepStaticRecord:
    """One random floor.

    Attributes:
        seed: the episode seed (the map).
        n_obstacles: rectangles on the floor.
        status: planner status (SUCCESS, TIME_LIMIT, UNREACHABLE, NODE_LIMIT).
        success: the footstep plan reaches the goal.
        steps: steps in the (possibly partial) plan.
        cost: plan cost.
        cost_to_go: heuristic cost left at the end of the plan (0 at the goal).
        plan_duration_s: time the robot needs to walk the plan (simulated seconds).
        nodes_expanded: A* expansions.
        nodes_generated: successors evaluated.
        steps_over: steps whose swing foot passes over an obstacle.
        body_path_m: length of the path of the feet midpoints.
        mobile2d_success: the bounding-circle planner found a path.
        mobile2d_length_m: its path length (None when it found none: missing in summaries).
        biped_only: the biped succeeds where the 2-D planner fails.
        wall_plan_time_s: footstep planning wall time (timing field).
        wall_mobile2d_time_s: 2-D planning wall time (timing field).
    """

    seed: int
    n_obstacles: int
    status: str
    success: bool
    steps: int
    cost: float
    cost_to_go: float
    plan_duration_s: float
    nodes_expanded: int
    nodes_generated: int
    steps_over: int
    body_path_m: float
    mobile2d_success: bool
    mobile2d_length_m: float | None
    biped_only: bool
    wall_plan_time_s: float
    wall_mobile2d_time_s: float


def _table(config: FootstepStaticConfig):
    return load_table(config.table_path)


def _scene(config: FootstepStaticConfig, seed: int):
    from repertoire.planning.footstep.scenes import random_static_scene

    return random_static_scene(
        seed,
        size=config.size_m,
        resolution=config.resolution_m,
        n_strips=config.n_strips,
        n_blocks=config.n_blocks,
    )


def _plan(config: FootstepStaticConfig, scene, table):
    from repertoire.planning.footstep import plan_footsteps, plan_mobile2d

    plan = plan_footsteps(
        scene.grid,
        scene.start,
        scene.start_foot,
        scene.goal,
        table,
        planner_options(config, heuristic="dijkstra"),
    )
    mobile = plan_mobile2d(scene.grid, scene.body_start, scene.goal, config.body_radius_m)
    return plan, mobile


def run_episode(config: FootstepStaticConfig, seed: int) -> FootstepStaticRecord:
    """Plan footsteps and a 2-D path on the seeded random floor.

    Args:
        config: the study config.
        seed: the episode seed (the map).

    Returns:
        The episode's record.
    """
    from repertoire.planning.footstep.metrics import body_path_length, steps_over_obstacles

    config.validate()
    scene = _scene(config, seed)
    plan, mobile = _plan(config, scene, _table(config))
    ok2d = mobile.status == "SUCCESS"
    return FootstepStaticRecord(
        seed=int(seed),
        n_obstacles=len(scene.obstacles),
        status=plan.status.value,
        success=plan.succeeded,
        steps=plan.num_steps,
        cost=float(plan.cost),
        cost_to_go=float(plan.cost_to_go),
        plan_duration_s=float(plan.duration),
        nodes_expanded=plan.nodes_expanded,
        nodes_generated=plan.nodes_generated,
        steps_over=steps_over_obstacles(scene.grid, plan),
        body_path_m=body_path_length(plan),
        mobile2d_success=ok2d,
        mobile2d_length_m=float(mobile.length) if ok2d else None,
        biped_only=bool(plan.succeeded and not ok2d),
        wall_plan_time_s=float(plan.planning_time_s),
        wall_mobile2d_time_s=float(mobile.planning_time_s),
    )


def summary_table(records: list[FootstepStaticRecord]) -> str:
    """Markdown table of the study's headline figures.

    Args:
        records: the episodes.
    """
    n = len(records)
    ok = [r for r in records if r.success]
    rate = [r.nodes_expanded / r.wall_plan_time_s for r in records if r.wall_plan_time_s > 0]
    both = [r for r in ok if r.mobile2d_success]
    ratio = [r.body_path_m / r.mobile2d_length_m for r in both if (r.mobile2d_length_m or 0.0) > 0]
    common = planner_rows(
        records,
        steps_label="steps per successful plan: median [min, max]",
        steps_over_label="steps over obstacles per plan (mean)",
        time_digits=4,
    )
    n2d = sum(r.mobile2d_success for r in records)
    rows = [
        ("maps", f"{n}"),
        common["success"],
        ("2-D bounding-circle planner success", f"{n2d}/{n} ({100 * n2d / max(n, 1):.1f} %)"),
        ("biped succeeds where the 2-D planner fails", f"{sum(r.biped_only for r in records)}"),
        common["steps"],
        ("plans stepping over an obstacle", f"{sum(r.steps_over > 0 for r in ok)}/{len(ok)}"),
        common["steps_over"],
        common["plan_time"],
        common["nodes"],
        (
            "nodes expanded per second of planning time, heuristic included (median)",
            f"{percentile(rate, 50):.0f}",
        ),
        (
            "feet-midpoint path / 2-D path length where both succeed (median)",
            f"{percentile(ratio, 50):.3f} (n = {len(ratio)})",
        ),
    ]
    return markdown_table(rows)


def summarize(
    records: list[FootstepStaticRecord], config: FootstepStaticConfig, out_dir: Path
) -> dict[str, Path]:
    """Write the headline table, example plans (Fig. 3 style) and distributions.

    Args:
        records: the episodes (sorted by seed; seeds are 0.. in order unless first_seed).
        config: the study config.
        out_dir: output folder.

    Returns:
        ``{label: path}`` of the files written.
    """
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.ticker import FuncFormatter, MaxNLocator
    from repertoire.planning.footstep.plot import (
        action_effects_figure,
        draw_grid,
        draw_plan,
        plan_legend_handles,
    )
    from repertoire.planning.footstep.scenes import maze_grid, random_floor_scene

    out_dir = Path(out_dir)
    out: dict[str, Path] = {}
    md = out_dir / "footstep_static.md"
    md.write_text("# Footstep planning, static obstacles\n\n" + summary_table(records))
    out["table"] = md
    out["action_effects"] = action_effects_figure(
        _table(config),
        out_dir / "footstep_action_effects.png",
        title=f"action table: {config.table_path or 'nominal'} (black: stance foot)",
    )

    out["height_plan"] = _height_plan_figure(config, out_dir / "footstep_height_plan.png")
    out["cut_off"] = _cut_off_figure(config, out_dir / "footstep_cut_off.png")
    floor = random_floor_scene(ANYTIME_FLOOR)
    out["anytime"] = _anytime_figure(
        config, out_dir / "footstep_anytime.png",
        (floor.grid, floor.start, floor.start_foot, floor.goal),
        f"floor {ANYTIME_FLOOR}", ANYTIME_EXPANSIONS,
    )  # fmt: skip
    # a floor where the one-core pipeline ends 17 % above the admissible mode's plan and the
    # second search on the other core (second_search=True) comes within 5 %
    two = random_floor_scene(ANYTIME_TWO_CORES_FLOOR)
    out["anytime_two_cores"] = _anytime_figure(
        config, out_dir / "footstep_anytime_two_cores.png",
        (two.grid, two.start, two.start_foot, two.goal),
        f"floor {ANYTIME_TWO_CORES_FLOOR}", ANYTIME_EXPANSIONS, second_search=True,
    )  # fmt: skip
    # a maze where every Dijkstra-guided search ends early, at 39.1, and the admissible
    # search with the time left finds the admissible mode's 36.95
    out["anytime_maze"] = _anytime_figure(
        config, out_dir / "footstep_anytime_maze.png",
        (maze_grid(ANYTIME_MAZE), (0.6, 0.6, 0.0), "left", (5.4, 5.4)),
        f"6 m maze {ANYTIME_MAZE}", ANYTIME_EXPANSIONS,
    )  # fmt: skip

    # example plans: half where the 2-D planner fails and the biped steps over, half where
    # the 2-D planner has to go around what the biped steps over
    seeds = _seeds_of(records)
    k = config.example_figures
    fails = [i for i, r in enumerate(records) if r.biped_only and r.steps_over > 0]
    around = [i for i, r in enumerate(records) if r.mobile2d_success and r.steps_over > 0]
    pick = fails[: (k + 1) // 2] + around[: k // 2]
    rest = [i for i in range(len(records)) if i not in pick]
    pick = (pick + rest)[:k]
    if pick:
        cols = min(2, len(pick))
        rows = int(math.ceil(len(pick) / cols))
        height = 4.6 * rows + 1.0  # 0.6 in for the legend below, 0.4 in for the title above
        fig = Figure(figsize=(4.6 * cols, height), dpi=110)
        table = _table(config)
        handles = plan_legend_handles()
        for p, i in enumerate(pick):
            scene = _scene(config, seeds[i])
            plan, mobile = _plan(config, scene, table)
            ax = fig.add_subplot(rows, cols, p + 1)
            draw_grid(ax, scene.grid)
            draw_plan(ax, plan)
            if mobile.path:
                mp = np.asarray(mobile.path)
                ax.plot(mp[:, 0], mp[:, 1], "--", color="0.25", lw=1.2)
                if len(handles) == len(plan_legend_handles()):
                    handles.append(
                        Line2D([], [], ls="--", color="0.25", lw=1.2, label="2-D planner")
                    )
            ax.set_xlabel("x (m)", fontsize=7)
            ax.set_ylabel("y (m)", fontsize=7)
            r = records[i]
            ax.set_title(
                f"seed {seeds[i]}: {r.status}, {r.steps} steps, {r.steps_over} over obstacles, "
                f"2-D {'ok' if r.mobile2d_success else 'fails'}",
                fontsize=7,
            )
            ax.tick_params(labelsize=6)
        # one legend below the panels: inside, it covered obstacle cells
        fig.legend(handles=handles, loc="lower center", ncol=4, fontsize=6)
        fig.tight_layout(rect=(0, 0.6 / height, 1, 1 - 0.4 / height))
        # after the layout, in the band it left: laid out with it, rows overlapped
        fig.suptitle(
            "footstep plans on random floors (Fig. 3); dashed: the 2-D planner's path",
            y=1 - 0.15 / height,
            fontsize=9,
        )
        path = out_dir / "footstep_static_examples.png"
        fig.savefig(path)
        out["examples"] = path

    if records:
        fig = Figure(figsize=(11, 3.4), dpi=110)
        ax = fig.add_subplot(1, 3, 1)
        steps_ok = [r.steps for r in records if r.success] or [0]
        ax.hist(steps_ok, bins=np.arange(min(steps_ok) - 0.5, max(steps_ok) + 1.5), color="#1f5fd6")
        ax.set_xlabel("steps per successful plan")
        ax.set_ylabel("maps")
        ax = fig.add_subplot(1, 3, 2)
        ax.scatter(
            [r.steps for r in records],
            [1000 * r.wall_plan_time_s for r in records],
            s=8,
            c=["#1f5fd6" if r.success else "#d6541f" for r in records],
        )
        ax.set_yscale("log")
        # plain numbers (the default labelled a narrow decade 1.35 x 10^0, 1.4 x 10^0, ...)
        ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))

        def minor_label(v, _, ax=ax):
            lo, hi = ax.get_ylim()  # a narrow range labels every minor tick, else 2s and 5s
            return f"{v:g}" if hi < 3 * lo or f"{v:.0e}"[0] in "25" else ""

        ax.yaxis.set_minor_formatter(FuncFormatter(minor_label))
        ax.set_xlabel("steps of the plan")
        ax.set_ylabel("plan time (ms, log scale)")
        outcomes = {bool(r.success) for r in records}
        ax.legend(  # only the outcomes drawn
            handles=[
                Line2D([], [], ls="", marker="o", ms=4, color=c, label=label)
                for ok, c, label in ((True, "#1f5fd6", "success"), (False, "#d6541f", "failed"))
                if ok in outcomes
            ],
            fontsize=7,
        )
        ax.set_title("planning time", fontsize=9)
        fig.axes[0].set_title("plan length", fontsize=9)
        ax = fig.add_subplot(1, 3, 3)
        ax.hist([r.nodes_expanded for r in records], bins=30, color="0.4")
        ax.set_xlabel("nodes expanded")
        ax.set_ylabel("maps")
        ax.set_title("search effort", fontsize=9)
        for a in (fig.axes[0], ax):
            a.yaxis.set_major_locator(MaxNLocator(integer=True))  # counts
        fig.suptitle(
            f"{len(records)} random floors: footstep success "
            f"{100 * np.mean([r.success for r in records]):.0f} %, 2-D planner "
            f"{100 * np.mean([r.mobile2d_success for r in records]):.0f} %",
            fontsize=9,
        )
        fig.tight_layout()
        path = out_dir / "footstep_static_distributions.png"
        fig.savefig(path)
        out["distributions"] = path
    return out


def _height_plan_figure(config: FootstepStaticConfig, path: Path) -> Path:
    """A plan over a 2.5-D floor (blocks 2-30 cm high) with the study's swing clearance."""
    from repertoire.planning.footstep import plan_footsteps
    from repertoire.planning.footstep.plot import height_plan_figure
    from repertoire.planning.footstep.scenes import random_floor_scene

    sc = random_floor_scene(3, size=4.0, occupancy=0.15, resolution=config.resolution_m)
    opts = planner_options(config)
    plan = plan_footsteps(sc.grid, sc.start, sc.start_foot, sc.goal, _table(config), opts)
    return height_plan_figure(
        sc.grid,
        plan,
        path,
        swing_clearance=config.swing_clearance_m,
        title=f"4 m floor, blocks 2-30 cm: {plan.status.value}, {plan.num_steps} steps "
        f"(swing clearance {100 * config.swing_clearance_m:.0f} cm)",
    )


ANYTIME_FLOOR = 9
"""The 12 m floor (``random_floor_scene`` seed, 30 % occupied) of :func:`_anytime_figure`."""
ANYTIME_TWO_CORES_FLOOR = 616
"""The 12 m floor of the two-core anytime figure (one core 1.172, two 0.978 of the reference)."""
ANYTIME_MAZE = 512
"""The 6 m maze (``maze_grid`` seed) of the second anytime figure."""
ANYTIME_EXPANSIONS = 1_600_000
"""Its anytime run's expansion budget (about 1 s on a fast machine; deterministic plans)."""


def _anytime_figure(
    config: FootstepStaticConfig,
    path: Path,
    scene: tuple,
    name: str,
    budget: int,
    second_search: bool = False,
) -> Path:
    """ARA* with restarts on a large map: the first and best plans, and cost over time.

    The anytime planner (:func:`~repertoire.planning.footstep.plan_footsteps_anytime`, the
    study's table, default options but an expansion budget) against the admissible mode's
    plan (A* with the Euclidean heuristic on 2.5 cm / 72 bins), with the 5 % band.

    Args:
        config: the study config (its action table).
        path: the PNG to write.
        scene: ``(grid, start, start_foot, goal)``.
        name: the map's name in the titles.
        budget: the anytime run's expansion budget.
        second_search: also run it with ``second_search=True`` (a second search on the
            other core) and draw its plans beside the one-core run's.
    """
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from repertoire.planning.footstep import (
        PlannerOptions,
        plan_footsteps,
        plan_footsteps_anytime,
    )
    from repertoire.planning.footstep.plot import draw_grid, draw_plan, plan_legend_handles

    grid = scene[0]
    args = (*scene, _table(config))
    opts = PlannerOptions(time_limit=600.0, max_expansions=budget)
    runs = [r for r in plan_footsteps_anytime(*args, opts) if r.plan.succeeded]
    series = [(runs, "tab:blue", "one core")]
    if second_search:
        two = plan_footsteps_anytime(*args, opts, second_search=True)
        series.append(([r for r in two if r.plan.succeeded], "tab:orange", "two cores"))
        runs = series[1][0]  # the map shows the two-core run's plans
    ref = plan_footsteps(*args, PlannerOptions.admissible(time_limit=60.0, refinements=0))
    fig = Figure(figsize=(12, 5.6), layout="constrained")
    left, right = fig.subplots(1, 2, width_ratios=[1.1, 1])
    draw_grid(left, grid)
    draw_plan(left, runs[-1].plan, alpha=0.9)
    first = runs[0].plan.poses_array()
    left.plot(first[:, 0], first[:, 1], "-", c="0.25", lw=1.2)
    left.set_aspect("equal")
    left.set_xlabel("x (m)")
    left.set_ylabel("y (m)")
    left.set_title(
        f"{name}: best plan {runs[-1].plan.cost:.1f} (footprints), "
        f"first {runs[0].plan.cost:.1f} (grey line)"
    )
    handles = [
        *plan_legend_handles(),
        Line2D(
            [], [], c="0.25", lw=1.2, label=f"first plan's steps (cost {runs[0].plan.cost:.1f})"
        ),
    ]
    # below the map: inside, it covered obstacle cells
    left.legend(
        handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.1), ncols=3, fontsize=7
    )
    marks = {0.05: "o", 0.025: "s"}
    for plans, colour, label in series:
        for r in plans:
            res = r.plan.xy_resolution
            right.plot(r.elapsed_s, r.plan.cost, marks.get(res, "^"), c=colour, ms=7)
            right.annotate(f"w {r.weight:g}", (r.elapsed_s, r.plan.cost), fontsize=7,
                           xytext=(4, 4), textcoords="offset points")  # fmt: skip
        right.step([r.elapsed_s for r in plans], [r.plan.cost for r in plans], where="post",
                   c=colour, label=label if second_search else None)  # fmt: skip
    if ref.succeeded:
        right.axhline(ref.cost, c="k", lw=1.2, label=f"admissible mode's plan {ref.cost:.1f}")
        right.axhspan(ref.cost, 1.05 * ref.cost, color="tab:green", alpha=0.2, label="within 5 %")
    for res, m in marks.items():
        right.plot([], [], m, c="0.4", label=f"plan on {100 * res:g} cm lattice")
    right.set_xlabel("wall time when found (s, this machine)")
    right.set_ylabel("plan cost (location + step costs)")
    right.set_title(
        f"anytime plans, {budget / 1e6:g} M expansions (w: weight)\n"
        + (
            "second_search=True: one more w 1.5 search on 2.5 cm (the map: its plans)"
            if second_search
            else "a last w 1 on 2.5 cm after the restarts: the admissible search"
        ),
        fontsize=10,
    )
    right.grid(alpha=0.3)
    right.legend(fontsize=8)
    fig.savefig(path, dpi=100)
    return path


def _cut_off_figure(config: FootstepStaticConfig, path: Path) -> Path:
    """The best partial plan below a 5 cm platform that ``max_step_up`` = 4 cm forbids.

    The first lattice runs out of states; the relaxed flood fill
    (:func:`~repertoire.planning.footstep.reachability.goal_cut_off`) proves no lattice
    gets up, so the planner answers UNREACHABLE without refining.
    """
    from repertoire.planning.footstep import OccupancyGrid, PlannerOptions, plan_footsteps
    from repertoire.planning.footstep.plot import height_plan_figure

    grid = OccupancyGrid.from_rectangles((3.0, 1.5), [], config.resolution_m, with_heights=True)
    grid.heights[int(round(1.5 / config.resolution_m)) :, :] = 0.05  # the platform, x >= 1.5 m
    opts = PlannerOptions(time_limit=max(config.time_limit_s, 5.0), max_step_up=0.04)
    plan = plan_footsteps(grid, (0.5, 0.75, 0.0), "left", (2.5, 0.75), _table(config), opts)
    first = plan.xy_resolution == opts.xy_resolution and plan.status.value == "UNREACHABLE"
    how = "no lattice gets up (proved), no refinement" if first else "finest lattice tried"
    return height_plan_figure(
        grid,
        plan,
        path,
        title=f"5 cm platform from x = 1.5 m, max_step_up 4 cm: {plan.status.value} on the "
        f"{100 * plan.xy_resolution:g} cm lattice\nin {plan.planning_time_s:.2f} s: {how}\n"
        "(feet: the best partial plan)",
    )


def _seeds_of(records: list) -> list[int]:
    return [int(r.seed) for r in records]


def demo_config() -> FootstepStaticConfig:
    """The demo config (the paper's setting, the default)."""
    return FootstepStaticConfig()


def smoke_config() -> FootstepStaticConfig:
    """A tiny config for tests: a 1.5 m floor, two strips, a node budget of 20,000.

    The budget is a cap: the 1.5 m floors' plans take a few hundred expansions, and the
    4 m height-map figure's plan about 3,300 (with 3,000 it ended in NODE_LIMIT).
    """
    return FootstepStaticConfig(
        size_m=1.5, n_strips=2, n_blocks=0, max_expansions=20000, example_figures=1
    )


register_study(
    "footstep_static",
    config_type=FootstepStaticConfig,
    record_type=FootstepStaticRecord,
    run_episode=run_episode,
    description="A* footstep plans on random 3 m floors of flat obstacles vs a 2-D planner",
    summarize=summarize,
    demo_config=demo_config,
    demo_episodes=8,
    smoke_config=smoke_config,
).run_if_main(__name__)
