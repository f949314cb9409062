"""Helpers shared by the DMP studies.

The studies are goals, obstacles, chaining, and the arm studies (grid, pick-and-place, serving,
obstacle arm). Registration (every DMP study registers the same way), logged paths subsampled
for figures, the default carry control points, the ball's radius, and the statistics and writing
of the results tables.

The diagrams layer is imported inside the functions, as the studies do, so importing a study
module stays cheap.
"""

import copy
import math
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from repertoire.studies.registry import StudyEntry, register_study

from repertoire.errors import RepertoireError


def register_dmp_study(
    module_name: str,
    config_type: type,
    record_type: type,
    *,
    description: str,
    demo_episodes: int,
    smoke: dict,
) -> StudyEntry:
    """Registers the DMP study defined by ``module_name`` and runs it when that is ``__main__``.

    The study is named after the module; its ``run_episode`` and ``summarize`` are the module's
    functions of those names. The demo runs the default config; the smoke config (for tests) is
    the default with the ``smoke`` fields changed.

    Args:
        module_name: The study module's ``__name__`` (``repertoire.studies.<study>``).
        config_type: The study's config dataclass.
        record_type: The study's record dataclass.
        description: One line saying what the study measures.
        demo_episodes: Number of episodes the demo runs.
        smoke: Config fields a tiny test run changes (e.g. ``{"sim_duration_s": 0.3}``).

    Returns:
        The registered entry (when the module was imported, not run).
    """
    module = sys.modules[module_name]
    name = module.__spec__.name.rsplit(".", 1)[-1] if module.__spec__ else module_name
    return register_study(
        name,
        config_type=config_type,
        record_type=record_type,
        run_episode=module.run_episode,
        description=description,
        summarize=module.summarize,
        demo_config=config_type,
        demo_episodes=demo_episodes,
        smoke_config=lambda: config_type(**copy.deepcopy(smoke)),
    ).run_if_main(module_name)


def write_table(out_dir: Path, filename: str, lines: list[str]) -> Path:
    """Writes a Markdown results table (one line per entry) and returns its path.

    Args:
        out_dir: Output directory.
        filename: File name inside ``out_dir``.
        lines: The table's lines, without newlines.
    """
    path = Path(out_dir) / filename
    path.write_text("\n".join(lines) + "\n")
    return path


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


def check_arm_config(config, ranges: Mapping[str, Sequence[float]]) -> None:
    """Checks an arm study config: sampling ranges and the run's timing.

    Args:
        config: The config (named in the messages; has ``sim_duration_s`` and ``path_every_s``).
        ranges: Field name -> its ``[min, max]`` sampling range.

    Raises:
        RepertoireError: A range that is not two finite numbers in order, a negative
            ``sim_duration_s`` or a ``path_every_s`` that is not positive.
    """
    owner = type(config).__name__
    for name, r in ranges.items():
        if len(r) != 2 or not all(math.isfinite(v) for v in r) or r[0] > r[1]:
            raise RepertoireError(f"{owner}.{name} must be [min, max], got {r}")
    if not (config.sim_duration_s >= 0 and config.path_every_s > 0):
        raise RepertoireError("sim_duration_s must be >= 0 and path_every_s > 0")


def timing_rows(records) -> list[str]:
    """The results-table rows of simulated time per episode and wall time per simulation.

    The wall time counts the runs that were not stopped (``failure`` empty).

    Args:
        records: Episode records with ``sim_time_s``, ``wall_sim_s`` and ``failure``.
    """
    ok = [r for r in records if not r.failure]
    walls = np.array([r.wall_sim_s for r in ok]) if ok else np.array([np.nan])
    return [
        f"| simulated time per episode [s] | {np.mean([r.sim_time_s for r in records]):.1f} |",
        f"| wall time per simulation, mean / max [s] | {stat_pair(walls, np.mean, np.max)} |",
    ]
