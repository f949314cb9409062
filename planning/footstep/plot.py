"""Figures of footstep plans in the style of the paper's Fig. 3 and Fig. 5 (matplotlib)."""

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, Patch, Polygon
from repertoire.planning.footstep.actions import ASIMO_LIKE, BipedGeometry
from repertoire.planning.footstep.environment import DynamicEnvironment, OccupancyGrid
from repertoire.planning.footstep.types import ActionTable, FootstepPlan

LEFT_COLOR = "#1f5fd6"
RIGHT_COLOR = "#d6541f"


def foot_polygon(pose: Sequence[float], geometry: BipedGeometry = ASIMO_LIKE) -> np.ndarray:
    """Corners (4, 2) of the sole rectangle at ``pose``.

    Args:
        pose: ``(x, y, yaw)``.
        geometry: foot size.
    """
    c, s = math.cos(pose[2]), math.sin(pose[2])
    hl, hw = geometry.foot_length / 2, geometry.foot_width / 2
    local = np.array([[hl, hw], [-hl, hw], [-hl, -hw], [hl, -hw]])
    return np.array([pose[0], pose[1]]) + local @ np.array([[c, s], [-s, c]])


def draw_grid(ax: Axes, grid: OccupancyGrid, color: str = "#c0392b", alpha: float = 1.0) -> None:
    """Draw occupied cells as solid squares.

    Args:
        ax: matplotlib axes.
        grid: the grid.
        color: obstacle colour.
        alpha: opacity.
    """
    x0, y0 = grid.origin
    sx, sy = grid.size
    rgba = np.zeros((*grid.shape[::-1], 4))
    from matplotlib.colors import to_rgba

    rgba[grid.occupied.T] = to_rgba(color, alpha)
    ax.imshow(rgba, origin="lower", extent=(x0, x0 + sx, y0, y0 + sy), interpolation="nearest")
    ax.set_xlim(x0, x0 + sx)
    ax.set_ylim(y0, y0 + sy)
    ax.set_aspect("equal")


def draw_plan(
    ax: Axes,
    plan: FootstepPlan,
    geometry: BipedGeometry = ASIMO_LIKE,
    *,
    upto: int | None = None,
    numbers: bool = False,
    alpha: float = 0.9,
) -> None:
    """Draw the footprints of a plan (blue left, red right), start and goal circles.

    Args:
        ax: matplotlib axes.
        plan: the plan.
        geometry: foot size.
        upto: draw only poses 0..upto.
        numbers: label each footprint with its step index.
        alpha: footprint opacity.
    """
    poses = plan.poses_array()
    last = len(poses) if upto is None else min(upto + 1, len(poses))
    other = 1 - plan.feet[0]
    ax.add_patch(
        Polygon(
            foot_polygon(plan.initial_swing_pose, geometry),
            closed=True,
            fc=LEFT_COLOR if other == 0 else RIGHT_COLOR,
            ec="k",
            lw=0.5,
            alpha=0.4,
        )
    )
    for k in range(last):
        color = LEFT_COLOR if plan.feet[k] == 0 else RIGHT_COLOR
        ax.add_patch(
            Polygon(
                foot_polygon(poses[k], geometry), closed=True, fc=color, ec="k", lw=0.5, alpha=alpha
            )
        )
        if numbers:
            ax.text(
                poses[k, 0],
                poses[k, 1],
                str(k),
                fontsize=5,
                ha="center",
                va="center",
                color="white",
            )
    ax.add_patch(Circle(tuple(poses[0, :2]), 0.12, fill=False, ec="k", lw=1.2))
    ax.add_patch(Circle(tuple(plan.goal), plan.goal_tolerance, fill=False, ec="g", lw=1.5))


def plan_legend_handles() -> list:
    """Legend proxies for what :func:`draw_plan` and :func:`draw_grid` draw."""
    return [
        Patch(fc=LEFT_COLOR, ec="k", lw=0.5, label="left foot"),
        Patch(fc=RIGHT_COLOR, ec="k", lw=0.5, label="right foot"),
        Line2D([], [], ls="", marker="o", mfc="none", mec="k", ms=8, label="start"),
        Line2D([], [], ls="", marker="o", mfc="none", mec="g", ms=8, label="goal region"),
        Patch(fc="0.5", ec="k", lw=0.5, alpha=0.4, label="other foot at start (pale)"),
        Patch(fc="#c0392b", label="obstacle cell"),
    ]


def dynamic_plan_figure(
    env: DynamicEnvironment,
    plan: FootstepPlan,
    path: "str | Path",
    *,
    panels: int = 6,
    title: str = "",
    geometry: BipedGeometry = ASIMO_LIKE,
) -> Path:
    """Write a Fig. 5-like PNG: snapshots of the moving obstacles with the steps so far.

    Each panel shows E(t) at the landing time of one step, the footprints up to that step
    (the current one outlined in black) and the steps still to come faded. Steps in place
    and side steps always get a panel.

    Args:
        env: the time-indexed grids.
        plan: the footstep plan.
        path: output PNG.
        panels: number of snapshots.
        title: figure title.
        geometry: foot size.
    """
    n = plan.num_steps
    # every step in place or side step gets a panel (with the step before it), the rest
    # of the panels are spread evenly over the plan
    special = [k for k in range(1, n + 1) if plan.actions[k - 1] in ("stop", "side_step")]
    steps = set()
    for k in special:
        steps.update((k - 1, k))
    for v in np.linspace(0, n, panels):
        if len(steps) >= panels:
            break
        steps.add(int(round(v)))
    steps = sorted(steps)
    cols = min(3, len(steps))
    rows = int(math.ceil(len(steps) / cols))
    fig = Figure(figsize=(3.3 * cols, 3.4 * rows), dpi=120)
    poses = plan.poses_array()
    for p, k in enumerate(steps):
        ax = fig.add_subplot(rows, cols, p + 1)
        t = plan.times[k]
        draw_grid(ax, env.grids[env.nearest_index_unchecked(t)])
        for j in range(k + 1, len(poses)):
            ax.add_patch(
                Polygon(foot_polygon(poses[j], geometry), closed=True, fill=False, ec="0.6", lw=0.4)
            )
        draw_plan(ax, plan, geometry, upto=k, alpha=0.6)
        ax.add_patch(
            Polygon(foot_polygon(poses[k], geometry), closed=True, fill=False, ec="k", lw=1.5)
        )
        action = plan.actions[k - 1] if k > 0 else "start"
        ax.set_title(f"step {k}: {action}, t = {t:.1f} s", fontsize=8)
        ax.set_xlabel("x (m)", fontsize=7)
        ax.set_ylabel("y (m)", fontsize=7)
        ax.tick_params(labelsize=6)
    handles = plan_legend_handles() + [
        Patch(fill=False, ec="k", lw=1.5, label="current step"),
        Patch(fill=False, ec="0.6", lw=0.4, label="steps to come"),
    ]
    fig.legend(handles=handles, loc="lower center", ncol=4, fontsize=7)
    if title:
        fig.suptitle(title, fontsize=9)
    fig.tight_layout(rect=(0, 0.07, 1, 1))
    path = Path(path)
    fig.savefig(path)
    return path


CRAWL_LEG_COLORS = ("#1f5fd6", "#d6541f", "#2ca02c", "#9467bd")


def height_plan_figure(
    grid: OccupancyGrid,
    plan: FootstepPlan,
    path: "str | Path",
    *,
    swing_clearance: float = math.inf,
    title: str = "",
    geometry: BipedGeometry = ASIMO_LIKE,
) -> Path:
    """Write a PNG of a biped plan over a 2.5-D map: obstacle cells coloured by height.

    Obstacles higher than ``swing_clearance`` above level 0 (no swing from the floor clears
    them; the planner measures the clearance from the ground the feet stand on) are
    outlined; free ground is white (shaded by its height when it has any).

    Args:
        grid: the grid with ``heights``.
        plan: the footstep plan.
        path: output PNG.
        swing_clearance: the planner's swing clearance (m), to mark the taller obstacles.
        title: axes title.
        geometry: foot size.

    Raises:
        ValueError: a grid without heights.
    """
    if grid.heights is None:
        raise ValueError("height_plan_figure needs a grid with heights")
    nx, ny = grid.shape
    # as tall as the map needs (a 3 x 1.5 m strip in a square figure floated in white)
    fig = Figure(figsize=(6.4, float(np.clip(4.2 * ny / nx + 1.8, 3.0, 8.0))), dpi=130)
    ax = fig.add_subplot(1, 1, 1)
    x0, y0 = grid.origin
    res = grid.resolution
    extent = (x0, x0 + nx * res, y0, y0 + ny * res)
    h_cm = np.where(grid.occupied, 100.0 * grid.heights, np.nan)
    ground = np.where(grid.occupied, np.nan, 100.0 * grid.heights)
    shaded = np.nanmax(np.abs(ground), initial=0.0) > 0
    if shaded:
        gi = ax.imshow(
            ground.T, origin="lower", extent=extent, cmap="Greys", alpha=0.35,
            interpolation="nearest", vmin=0.0,
        )  # fmt: skip
    handles = plan_legend_handles()[:5]
    if grid.occupied.any():
        im = ax.imshow(
            h_cm.T, origin="lower", extent=extent, cmap="viridis", interpolation="nearest",
            vmin=0.0,
        )  # fmt: skip
        fig.colorbar(im, ax=ax, label="obstacle height (cm)", shrink=0.8)
        handles.append(Patch(fc=im.cmap(0.1), label="obstacle (colour: height)"))
    elif shaded:
        fig.colorbar(gi, ax=ax, label="ground height (cm)", shrink=0.8)
    if shaded:
        handles.append(Patch(fc="0.55", alpha=0.35, label="free ground (grey: higher)"))
    if math.isfinite(swing_clearance):
        tall = grid.occupied & (grid.heights > swing_clearance)
        if tall.any():
            ax.contour(
                (np.arange(nx) + 0.5) * res + x0, (np.arange(ny) + 0.5) * res + y0,
                tall.T.astype(float), levels=[0.5], colors="r", linewidths=0.8,
            )  # fmt: skip
            handles.append(
                Line2D([], [], color="r", lw=0.8, label=f"over the swing clearance "
                       f"{100 * swing_clearance:.0f} cm (no step over from the floor)")
            )  # fmt: skip
    draw_plan(ax, plan, geometry)
    fig.legend(handles=handles, loc="lower center", ncol=3, fontsize=6, framealpha=0.9)
    ax.set_title(title or f"plan: {plan.status.value}, {plan.num_steps} steps", fontsize=8)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_aspect("equal")
    fig.tight_layout(rect=(0.0, 0.1, 1.0, 1.0))
    path = Path(path)
    fig.savefig(path)
    return path


def crawl_plan_figure(height_map, plan, path: "str | Path", *, goal=None, title: str = "") -> Path:
    """Write a PNG of a crawl plan over the height map (heights as a colour bar).

    Args:
        height_map: a :class:`repertoire.planning.footstep.height_map.HeightMap`.
        plan: a :class:`repertoire.planning.footstep.quadruped.CrawlPlan`.
        path: output PNG.
        goal: the goal point and radius ``(x, y, r)`` to draw, if given.
        title: axes title.
    """
    from repertoire.models.littledog.kinematics import LEGS

    fig = Figure(figsize=(7.0, 5.4), dpi=130)
    ax = fig.add_subplot(1, 1, 1)
    h = height_map.heights
    res = height_map.resolution
    x0, y0 = height_map.origin
    extent = (
        x0 - res / 2,
        x0 + (h.shape[1] - 0.5) * res,
        y0 - res / 2,
        y0 + (h.shape[0] - 0.5) * res,
    )
    im = ax.imshow(100.0 * h, origin="lower", extent=extent, cmap="Greys", interpolation="nearest")
    fig.colorbar(im, ax=ax, label="ground height (cm)", shrink=0.8)
    handles = []
    for leg in range(4):
        pts = [plan.start_stance[leg]] + [s.p_WF for s in plan.steps if s.foot == leg]
        pts = np.asarray(pts)
        ax.plot(pts[:, 0], pts[:, 1], "-", color=CRAWL_LEG_COLORS[leg], lw=0.8)
        ax.plot(pts[0, 0], pts[0, 1], "s", color=CRAWL_LEG_COLORS[leg], ms=5, mfc="none")
        ax.plot(pts[1:, 0], pts[1:, 1], "o", color=CRAWL_LEG_COLORS[leg], ms=3.5)
        handles.append(
            Line2D(
                [],
                [],
                color=CRAWL_LEG_COLORS[leg],
                marker="o",
                ms=3.5,
                label=f"{LEGS[leg]} footholds",
            )
        )
    handles.append(
        Line2D([], [], ls="", marker="s", mfc="none", mec="k", ms=5, label="start foothold")
    )
    # The start and final stances as quadrilaterals (lf, rf, rh, lh): their turn shows.
    final = plan.steps[-1].stance if plan.steps else plan.start_stance
    stances = ((plan.start_stance, ":", "start stance"), (final, "-", "final stance"))
    for stance, ls, label in stances:
        quad = np.asarray(stance)[[0, 1, 3, 2, 0], :2]
        ax.plot(quad[:, 0], quad[:, 1], ls, color="k", lw=1.0)
        handles.append(Line2D([], [], ls=ls, color="k", lw=1.0, label=label))
    if goal is not None:
        ax.add_patch(Circle((goal[0], goal[1]), goal[2], fill=False, ec="g", lw=1.5))
        handles.append(
            Line2D(
                [], [], ls="", marker="o", mfc="none", mec="g", ms=8, label="goal (feet centroid)"
            )
        )
    # below the map: in its upper left it covered terrain blocks
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncols=4, fontsize=6)
    ax.set_title(title or f"crawl plan: {plan.status.value}, {len(plan.steps)} steps", fontsize=8)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_aspect("equal")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path)
    return path


def action_effects_figure(
    table: ActionTable,
    path: "str | Path",
    *,
    histories: Sequence[Sequence[str]] | None = None,
    stance_foot: int = 1,
    geometry: BipedGeometry = ASIMO_LIKE,
    title: str = "",
) -> Path:
    """Write a Fig. 2-like PNG: where the swing foot lands for every action, per history.

    The stance foot (black) stands at the origin facing +x; each outline is the landing
    pose of the other foot for one action, labelled with the action's name.

    Args:
        table: the action table.
        path: output PNG.
        histories: ``(a_prev2, a_prev1)`` per panel; default standing still and full-speed
            walking (the longest forward action twice).
        stance_foot: 0 left, 1 right.
        geometry: foot size.
        title: figure title.
    """
    if histories is None:
        fwd = max(range(table.n), key=lambda a: table.displacement[0, 0, stance_foot, a, 0])
        histories = [
            (table.rest_action, table.rest_action),
            (table.actions[fwd], table.actions[fwd]),
        ]
    fig = Figure(figsize=(3.6 * len(histories), 3.8), dpi=120)
    colors = [
        "#1f77b4",
        "#ff7f0e",
        "#2ca02c",
        "#d62728",
        "#9467bd",
        "#8c564b",
        "#e377c2",
        "#7f7f7f",
        "#bcbd22",
        "#17becf",
    ]
    for p, (h2, h1) in enumerate(histories):
        ax = fig.add_subplot(1, len(histories), p + 1)
        ax.add_patch(Polygon(foot_polygon((0, 0, 0), geometry), closed=True, fc="k"))
        for a, name in enumerate(table.actions):
            dx, dy, dth, dur = table.lookup(h2, h1, stance_foot, name)
            c = colors[a % len(colors)]
            ax.add_patch(
                Polygon(
                    foot_polygon((dx, dy, dth), geometry),
                    closed=True,
                    fill=False,
                    ec=c,
                    lw=1.3,
                    label=f"{name} ({dur:.2f} s)",
                )
            )
        ax.set_xlim(-0.25, 0.45)
        lo = -0.15 if stance_foot == 1 else -0.45
        ax.set_ylim(lo, lo + 0.6)
        ax.set_aspect("equal")
        ax.set_title(f"after {h2}, {h1}", fontsize=8)
        side = "left" if stance_foot == 0 else "right"
        ax.set_xlabel(f"x in the {side}-sole (stance) frame (m)", fontsize=7)
        ax.set_ylabel("y (m)", fontsize=7)
        ax.tick_params(labelsize=6)
        ax.legend(fontsize=5.5, loc="upper left" if stance_foot == 0 else "lower right")
    if title:
        fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path)
    return path
