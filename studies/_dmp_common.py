"""Helpers shared by the arm DMP studies (grid, pick-and-place, serving, obstacle arm).

Logged paths subsampled for figures, the default carry control points, the ball's radius, and
the statistics of the results tables.

The diagrams layer is imported inside the functions, as the studies do, so importing a study
module stays cheap.
"""

import numpy as np


def log_stride(every_s: float) -> int:
    """How many log samples to step to keep one every ``every_s`` seconds (>= 1).

    Args:
        every_s: Wanted spacing of the kept samples [s].
    """
    from repertoire.diagrams.arm_dmp import LOG_PERIOD

    return max(1, int(round(every_s / LOG_PERIOD)))


def tcp_path(diagram, context, every_s: float) -> np.ndarray:
    """The logged tcp positions, one every ``every_s`` seconds, shape (k, 3) [m].

    Args:
        diagram: An arm world after a run.
        context: Its root context.
        every_s: Spacing of the kept samples [s].
    """
    from repertoire.diagrams.arm_dmp_results import tcp_log

    return tcp_log(diagram, context).point[:: log_stride(every_s)]


def carry_control_points() -> list[list[float]]:
    """The default eq.-10 control points while carrying (``CARRY_CONTROL_POINTS``)."""
    from repertoire.diagrams.arm_dmp_scenarios import CARRY_CONTROL_POINTS

    return [list(p) for p in CARRY_CONTROL_POINTS]


def obstacle_radius() -> float:
    """Radius of the ball obstacle [m] (``models.arm7.OBSTACLE_RADIUS``)."""
    from repertoire.models.arm7 import OBSTACLE_RADIUS

    return float(OBSTACLE_RADIUS)


def stat_pair(values, first, second, digits: int = 2) -> str:
    """'first / second' of the finite values (e.g. median / max), or 'n/a' if none.

    Args:
        values: Numbers (NaN and inf are left out).
        first: Statistic printed first (e.g. ``np.median``).
        second: Statistic printed second (e.g. ``np.max``).
        digits: Decimals.
    """
    finite = np.asarray(values, dtype=float)
    finite = finite[np.isfinite(finite)]
    if finite.size == 0:
        return "n/a"
    return f"{first(finite):.{digits}f} / {second(finite):.{digits}f}"


def finite_max(values) -> float:
    """Largest finite value, NaN if there is none.

    Args:
        values: Numbers (NaN and inf are left out).
    """
    finite = np.asarray(values, dtype=float)
    finite = finite[np.isfinite(finite)]
    return float(finite.max()) if finite.size else float("nan")
