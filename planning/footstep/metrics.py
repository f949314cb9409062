"""Figures of merit of footstep plans: steps over obstacles, action counts, path length."""

import math

import numpy as np
from repertoire.planning.footstep.environment import DynamicEnvironment, OccupancyGrid
from repertoire.planning.footstep.types import FootstepPlan


def swing_segments(plan: FootstepPlan) -> list[tuple[list[float], list[float]]]:
    """``(lift-off pose, landing pose)`` of the swing foot of every step.

    Args:
        plan: the plan.
    """
    out = []
    for k in range(1, plan.num_steps + 1):
        start = plan.initial_swing_pose if k == 1 else plan.poses[k - 2]
        out.append((list(start), list(plan.poses[k])))
    return out


def steps_over_obstacles(world: "OccupancyGrid | DynamicEnvironment", plan: FootstepPlan) -> int:
    """How many steps carry the swing foot's centre over an occupied cell.

    The straight segment from lift-off to landing is sampled every half cell against the
    grid at the middle of the step (for dynamic worlds).

    Args:
        world: the grid or the time-indexed grids.
        plan: the plan.
    """
    count = 0
    for k, (a, b) in enumerate(swing_segments(plan), start=1):
        if isinstance(world, DynamicEnvironment):
            t_mid = 0.5 * (plan.times[k - 1] + plan.times[k])
            grid = world.grids[world.nearest_index_unchecked(t_mid)]
        else:
            grid = world
        length = math.hypot(b[0] - a[0], b[1] - a[1])
        m = max(2, int(math.ceil(length / (grid.resolution / 2))) + 1)
        crossed = False
        for s in np.linspace(0.0, 1.0, m):
            x = a[0] + s * (b[0] - a[0])
            y = a[1] + s * (b[1] - a[1])
            ix, iy = grid.cell_of(x, y)
            if 0 <= ix < grid.shape[0] and 0 <= iy < grid.shape[1] and grid.occupied[ix, iy]:
                crossed = True
                break
        count += int(crossed)
    return count


def action_counts(plan: FootstepPlan) -> dict[str, int]:
    """Number of times each action is commanded.

    Args:
        plan: the plan.
    """
    out: dict[str, int] = {}
    for a in plan.actions:
        out[a] = out.get(a, 0) + 1
    return out


def body_path_length(plan: FootstepPlan) -> float:
    """Length (m) of the polyline through the midpoints of consecutive stance feet.

    Args:
        plan: the plan.
    """
    feet = [plan.initial_swing_pose] + [list(p) for p in plan.poses]
    mids = np.array([[(p[0] + q[0]) / 2, (p[1] + q[1]) / 2] for p, q in zip(feet[:-1], feet[1:])])
    if len(mids) < 2:
        return 0.0
    return float(np.sum(np.hypot(*np.diff(mids, axis=0).T)))
