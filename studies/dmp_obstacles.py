"""DMP obstacle avoidance with the coupling term of eq. 10 (Pastor et al., sec. II-C).

Each episode draws a 3-D point-to-point demonstration (minimum jerk with a small seeded
via-point detour), learns a DMP, places a spherical obstacle of radius r on the path
(centre at a seeded fraction of the way, offset sideways by less than r, so the learned
path passes through the sphere) and runs the DMP in a Drake diagram (DmpSystem with
ObstacleCoupling, 1 kHz) with and without coupling. Success: the clearance (closest
distance of the path to the obstacle centre) stays above r. Also records the goal error
and the peak acceleration. Run ``python -m repertoire.studies.dmp_obstacles --help``.
"""

import dataclasses
import math
import time
from pathlib import Path

import numpy as np
from repertoire.studies._dmp_common import register_dmp_study, write_table
from repertoire.studies.dmp_goals import simulate_dmp

from repertoire.checks import is_whole
from repertoire.errors import RepertoireError


@dataclasses.dataclass
class DmpObstaclesConfig:
    """What every episode shares.

    Attributes:
        n_basis: basis functions per DOF.
        duration_s: demonstration duration (tau).
        n_samples: demonstration samples.
        time_step_s: DmpSystem update period.
        sim_factor: simulated time as a multiple of tau.
        length_min_m: shortest start-goal distance.
        length_max_m: longest start-goal distance.
        radius_m: obstacle radius r.
        offset_max: largest sideways offset of the centre from the path, fraction of r.
        along_min: obstacle centre at least this fraction of the way along the path.
        along_max: at most this fraction.
        gamma: coupling gain of eq. 10.
        beta: coupling decay (the paper's c).
    """

    n_basis: int = 30
    duration_s: float = 1.0
    n_samples: int = 500
    time_step_s: float = 1e-3
    sim_factor: float = 1.5
    length_min_m: float = 0.3
    length_max_m: float = 0.6
    radius_m: float = 0.05
    offset_max: float = 0.8
    along_min: float = 0.3
    along_max: float = 0.7
    gamma: float = 1000.0
    beta: float = 20.0 / math.pi

    def validate(self) -> None:
        """Raises RepertoireError if a field is out of range."""
        for name in ("duration_s", "time_step_s", "sim_factor", "radius_m", "length_min_m"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise RepertoireError(f"DmpObstaclesConfig.{name} must be > 0, got {v}")
        if not (math.isfinite(self.length_max_m) and self.length_min_m <= self.length_max_m):
            raise RepertoireError(
                "DmpObstaclesConfig needs finite length_min_m <= length_max_m, got "
                f"{self.length_min_m}, {self.length_max_m}"
            )
        if not 0 <= self.along_min <= self.along_max <= 1:
            raise RepertoireError("DmpObstaclesConfig needs 0 <= along_min <= along_max <= 1")
        if not (math.isfinite(self.offset_max) and self.offset_max >= 0):
            raise RepertoireError(
                f"DmpObstaclesConfig.offset_max must be finite and >= 0, got {self.offset_max}"
            )
        if not (0 <= self.gamma < math.inf and 0 <= self.beta < math.inf):
            raise RepertoireError(
                f"DmpObstaclesConfig needs finite gamma, beta >= 0, got {self.gamma}, {self.beta}"
            )
        if not (is_whole(self.n_samples) and is_whole(self.n_basis)) or not (
            3 <= self.n_samples and 1 <= self.n_basis <= self.n_samples
        ):
            raise RepertoireError(
                "DmpObstaclesConfig needs n_samples >= 3 and 1 <= n_basis <= n_samples, got "
                f"{self.n_samples}, {self.n_basis}"
            )


@dataclasses.dataclass
class DmpObstaclesRecord:
    """One episode.

    Attributes:
        length_m: start-goal distance.
        along: where the obstacle sits along the path (fraction).
        offset_m: sideways offset of the obstacle centre from the learned path.
        clearance_without_m: min distance path - centre without coupling.
        clearance_with_m: same with coupling.
        success_without: clearance_without_m > radius.
        success_with: clearance_with_m > radius.
        goal_error_with_m: |x(T_sim) - g| with coupling.
        peak_acc_without: peak |acceleration| without coupling (m/s^2).
        peak_acc_with: same with coupling.
        wall_time_s: episode wall time.
    """

    length_m: float
    along: float
    offset_m: float
    clearance_without_m: float
    clearance_with_m: float
    success_without: bool
    success_with: bool
    goal_error_with_m: float
    peak_acc_without: float
    peak_acc_with: float
    wall_time_s: float


def scene(config: DmpObstaclesConfig, seed: int) -> dict:
    """Seeded demonstration and obstacle.

    Args:
        config: Study config.
        seed: Episode seed.

    Returns:
        dict with t, Y (demo), obstacle, length, along, offset.
    """
    from repertoire.planning.dmp_math import minimum_jerk_via_points

    rng = np.random.default_rng(seed)
    start = rng.uniform([0.3, -0.3, 0.1], [0.5, 0.3, 0.4])
    direction = rng.normal(size=3)
    direction /= np.linalg.norm(direction)
    length = float(rng.uniform(config.length_min_m, config.length_max_m))
    goal = start + length * direction
    side = np.cross(direction, rng.normal(size=3))
    side /= np.linalg.norm(side)
    via = 0.5 * (start + goal) + 0.05 * length * side
    t, Y = minimum_jerk_via_points(
        np.stack([start, via, goal]), config.duration_s, config.n_samples
    )
    along = float(rng.uniform(config.along_min, config.along_max))
    k = int(round(along * (len(Y) - 1)))
    # Offset perpendicular to the path's tangent at that point.
    tangent = Y[min(k + 1, len(Y) - 1)] - Y[max(k - 1, 0)]
    tangent /= np.linalg.norm(tangent)
    perp = np.cross(tangent, rng.normal(size=3))
    perp /= np.linalg.norm(perp)
    offset = float(rng.uniform(0, config.offset_max)) * config.radius_m
    obstacle = Y[k] + offset * perp
    return {
        "t": t,
        "Y": Y,
        "obstacle": obstacle,
        "length": length,
        "along": along,
        "offset": offset,
    }


def _clearance(x: np.ndarray, o: np.ndarray) -> float:
    return float(np.min(np.linalg.norm(x - o, axis=1)))


def straight_case(config: DmpObstaclesConfig, start: np.ndarray, goal: np.ndarray) -> dict:
    """Eq. 10's degenerate case: an obstacle exactly on a straight demonstration.

    The velocity points straight at the obstacle (``phi = 0``) all along, where eq. 10 is
    0; :func:`repertoire.planning.dmp_obstacle.obstacle_coupling` breaks the symmetry
    (before, the path went through the obstacle's centre).

    Args:
        config: Study config (duration, samples, basis, gains, time step).
        start: Start of the straight demonstration.
        goal: Its goal.

    Returns:
        dict with Y (demo), obstacle (the midpoint), x_without, x_with (DmpSystem paths).
    """
    from repertoire.planning.dmp_learn import learn_dmp
    from repertoire.planning.dmp_math import minimum_jerk_via_points

    t, Y = minimum_jerk_via_points(np.stack([start, goal]), config.duration_s, config.n_samples)
    dmp = learn_dmp(t, Y, n_basis=config.n_basis)
    o = 0.5 * (np.asarray(start, float) + np.asarray(goal, float))
    dur = config.sim_factor * config.duration_s
    runs = [
        simulate_dmp(
            dmp,
            [0.0],
            [dmp.goal],
            dur,
            time_step=config.time_step_s,
            obstacle=obstacle,
            gamma=config.gamma,
            beta=config.beta,
        )[1]
        for obstacle in (None, o)
    ]
    return {"Y": Y, "obstacle": o, "x_without": runs[0], "x_with": runs[1]}


def run_episode(config: DmpObstaclesConfig, seed: int) -> DmpObstaclesRecord:
    """Learns the seeded demonstration and runs it with and without coupling."""
    from repertoire.planning.dmp_learn import learn_dmp

    t0 = time.perf_counter()
    config.validate()
    sc = scene(config, seed)
    dmp = learn_dmp(sc["t"], sc["Y"], n_basis=config.n_basis)
    g = dmp.goal
    dur = config.sim_factor * config.duration_s
    _, x0, _, a0 = simulate_dmp(dmp, [0.0], [g], dur, time_step=config.time_step_s)
    _, x1, _, a1 = simulate_dmp(
        dmp,
        [0.0],
        [g],
        dur,
        time_step=config.time_step_s,
        obstacle=sc["obstacle"],
        gamma=config.gamma,
        beta=config.beta,
    )
    c0, c1 = _clearance(x0, sc["obstacle"]), _clearance(x1, sc["obstacle"])
    return DmpObstaclesRecord(
        length_m=sc["length"],
        along=sc["along"],
        offset_m=sc["offset"],
        clearance_without_m=c0,
        clearance_with_m=c1,
        success_without=bool(c0 > config.radius_m),
        success_with=bool(c1 > config.radius_m),
        goal_error_with_m=float(np.linalg.norm(x1[-1] - g)),
        peak_acc_without=float(np.abs(a0).max()),
        peak_acc_with=float(np.abs(a1).max()),
        wall_time_s=time.perf_counter() - t0,
    )


def summarize(records: list[DmpObstaclesRecord], config: DmpObstaclesConfig, out_dir: Path):
    """Seed-0 paths around the obstacle, a clearance histogram and a Markdown table."""
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator
    from repertoire.planning.dmp_learn import learn_dmp

    out_dir = Path(out_dir)
    sc = scene(config, 0)
    dmp = learn_dmp(sc["t"], sc["Y"], n_basis=config.n_basis)
    dur = config.sim_factor * config.duration_s
    _, x0, _, _ = simulate_dmp(dmp, [0.0], [dmp.goal], dur, time_step=config.time_step_s)
    _, x1, _, _ = simulate_dmp(
        dmp,
        [0.0],
        [dmp.goal],
        dur,
        time_step=config.time_step_s,
        obstacle=sc["obstacle"],
        gamma=config.gamma,
        beta=config.beta,
    )
    # Project on the plane spanned by the path direction and the detour of the coupled path.
    e1 = (dmp.goal - dmp.x0) / np.linalg.norm(dmp.goal - dmp.x0)
    dev = x1 - x0
    k = np.argmax(np.linalg.norm(dev, axis=1))
    e2 = dev[k] - (dev[k] @ e1) * e1
    e2 = e2 / np.linalg.norm(e2) if np.linalg.norm(e2) > 1e-9 else np.cross(e1, [0, 0, 1])
    fig = Figure(figsize=(16, 4.6), layout="constrained")
    ax, ax3, ax2 = fig.subplots(1, 3)
    P = lambda p: ((p - dmp.x0) @ e1, (p - dmp.x0) @ e2)  # noqa: E731
    ax.plot(*P(sc["Y"]), "k-", lw=2.5, label="demonstration")
    ax.plot(*P(x0), "--", c="tab:red", label="DMP without coupling")
    ax.plot(*P(x1), "-", c="tab:blue", label="DMP with eq. 10 coupling")
    o = P(sc["obstacle"])
    ax.add_patch(
        __import__("matplotlib.patches").patches.Circle(
            o,
            config.radius_m,
            color="tab:gray",
            alpha=0.5,
            label=f"obstacle (radius r = {config.radius_m * 100:g} cm)",
        )
    )
    ax.set_aspect("equal")
    ax.set_xlabel("along start-goal (m)")
    ax.set_ylabel("detour direction (m)")
    ax.set_title("seed 0, projected on the start-goal / detour plane")
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.35), ncol=2)
    # the straight-line case: the same start and goal, no via point, obstacle on the line
    st = straight_case(config, dmp.x0, dmp.goal)
    e2s = st["x_with"] - st["obstacle"]
    e2s = e2s[np.argmin(np.linalg.norm(e2s, axis=1))]
    e2s = e2s - (e2s @ e1) * e1
    e2s = e2s / np.linalg.norm(e2s) if np.linalg.norm(e2s) > 1e-12 else e2
    Ps = lambda p: ((p - dmp.x0) @ e1, (p - dmp.x0) @ e2s)  # noqa: E731
    c_without = _clearance(st["x_without"], st["obstacle"])
    c_with = _clearance(st["x_with"], st["obstacle"])
    ax3.plot(*Ps(st["Y"]), "k-", lw=2.5, label="straight demonstration")
    ax3.plot(
        *Ps(st["x_without"]),
        "--",
        c="tab:red",
        label=f"DMP without coupling (clearance {c_without * 1e3:.2f} mm)",
    )
    ax3.plot(
        *Ps(st["x_with"]),
        "-",
        c="tab:blue",
        label=f"DMP with eq. 10 coupling (clearance {c_with * 1e3:.1f} mm)",
    )
    ax3.add_patch(
        __import__("matplotlib.patches").patches.Circle(
            Ps(st["obstacle"]),
            config.radius_m,
            color="tab:gray",
            alpha=0.5,
            label="obstacle centred on the line (phi = 0)",
        )
    )
    ax3.plot(*Ps(st["obstacle"]), "x", c="k", label="obstacle centre")
    ax3.set_aspect("equal")
    ax3.set_xlabel("along start-goal (m)")
    ax3.set_ylabel("detour direction (m)")
    ax3.set_title("seed 0's ends, straight: heading at the obstacle (phi = 0)")
    ax3.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.42), ncol=1)
    # every episode in a bin: the clearances without coupling too (the coupling may lower one)
    largest = max(max(r.clearance_with_m, r.clearance_without_m) for r in records)
    bins = np.linspace(0, max(largest, 2 * config.radius_m), 30)
    # side by side in each bin: overlaid translucent bars mixed into a colour of neither
    counts, _, _ = ax2.hist(
        [[getattr(r, f"clearance_{key}_m") for r in records] for key in ("without", "with")],
        bins=bins,
        color=["tab:red", "tab:blue"],
        label=["without coupling", "with coupling"],
    )
    ax2.axvline(config.radius_m, color="k", ls="--", label="obstacle radius")
    ax2.set_xlabel("clearance to obstacle centre (m)")
    ax2.set_ylabel("episodes")
    ax2.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax2.set_title(f"closest approach, {len(records)} obstacles placed on the path")
    fig.suptitle(
        f"DMP obstacle avoidance (eq. 10, gamma = {config.gamma:g}, beta = {config.beta:.3g})"
    )
    ax2.set_ylim(top=1.35 * np.max(counts))  # headroom: the legend clears the tallest bar
    ax2.legend(fontsize=8, loc="upper right")
    p1 = out_dir / "dmp_obstacles.png"
    fig.savefig(p1, dpi=100)
    sw = np.mean([r.success_with for r in records])
    so = np.mean([r.success_without for r in records])
    lines = [
        f"# DMP obstacle avoidance ({len(records)} episodes, r = {config.radius_m} m, "
        f"gamma = {config.gamma:g}, beta = {config.beta:.3g})",
        "",
        "| | without coupling | with coupling |",
        "|---|---|---|",
        f"| fraction with clearance > r | {so:.2f} | {sw:.2f} |",
        f"| median clearance (m) | {np.median([r.clearance_without_m for r in records]):.3f} "
        f"| {np.median([r.clearance_with_m for r in records]):.3f} |",
        f"| min clearance (m) | {min(r.clearance_without_m for r in records):.3f} "
        f"| {min(r.clearance_with_m for r in records):.3f} |",
        f"| median peak acceleration (m/s^2) | "
        f"{np.median([r.peak_acc_without for r in records]):.2f} | "
        f"{np.median([r.peak_acc_with for r in records]):.2f} |",
        f"| max goal error at {config.sim_factor:g} tau (m) | | "
        f"{max(r.goal_error_with_m for r in records):.2e} |",
        f"| straight path, obstacle centred on it (seed 0's ends): clearance (m) | "
        f"{c_without:.4f} | {c_with:.4f} |",
    ]
    p2 = write_table(out_dir, "dmp_obstacles_table.md", lines)
    return {"paths_and_clearance": p1, "table": p2}


register_dmp_study(
    __name__,
    DmpObstaclesConfig,
    DmpObstaclesRecord,
    description="DMP obstacle avoidance (eq. 10): clearance above the radius with/without",
    demo_episodes=40,
    # a tiny config for tests: fewer samples and basis functions
    smoke=dict(n_basis=10, n_samples=100, time_step_s=2e-3, sim_factor=1.1),
)
