"""DMP chaining (Pastor et al., sec. III-C, Fig. 5): a square from one primitive, four goals.

One minimum-jerk primitive (learned from a straight movement (0,0) -> (1,0) m) is
generalised to the four corners of a square and chained with a DmpSequencer (Drake,
1 kHz): each DMP starts before its predecessor has finished, at a switching interval of
``switch`` x tau. With ``scaling="directional"`` (default) each leg uses the learned Y1
shape along the leg's direction (:func:`repertoire.planning.dmp_chain.directional_primitive`);
with ``"none"`` the 2-D primitive is sent to each corner as it is (the new form then
pushes along Y1 on the vertical legs too, since its forcing term is not scaled by g - x0).

Each episode takes one switching interval (cycled over the config's
list by seed) and a seeded square size and rotation, and runs the three handoffs:

* none: the successor restarts from rest at the current position;
* velocity (the paper): position and velocity handed over;
* acceleration: as velocity, plus the equations' x0 shifted so the successor starts with
  its predecessor's acceleration.

It records the largest acceleration and velocity jumps at the switches, how close the path
comes to the corners and the end error, and keeps the chained path, switch points and
|velocity| / |acceleration| traces (thinned within ``trace_tolerance``), which the figure
draws: the squares it shows are the seeded ones the episodes ran. Run
``python -m repertoire.studies.dmp_chaining``.
"""

import dataclasses
import math
import time
from pathlib import Path

import numpy as np
from repertoire.studies._dmp_common import legend_below, register_dmp_study, write_table

from repertoire.checks import is_whole
from repertoire.errors import RepertoireError

HANDOFF_NAMES = ("none", "velocity", "acceleration")


@dataclasses.dataclass
class DmpChainingConfig:
    """What every episode shares.

    Attributes:
        n_basis: basis functions.
        duration_s: primitive duration (tau).
        n_samples: demonstration samples.
        time_step_s: sequencer update period.
        switches: switching intervals as fractions of tau (cycled over seeds).
        side_min_m: smallest square side.
        side_max_m: largest square side.
        settle_factor: simulated time after the last switch, multiple of tau.
        scaling: "directional" or "none" (see the module docstring).
        trace_tolerance: how closely the path and speed/acceleration traces a record keeps
            for the figure follow the run: lines through the kept samples stay within this
            fraction of each trace's largest magnitude (:func:`trace_indices`).
    """

    n_basis: int = 30
    duration_s: float = 1.0
    n_samples: int = 500
    time_step_s: float = 1e-3
    switches: list[float] = dataclasses.field(
        default_factory=lambda: [1.0, 0.9, 0.8, 0.7, 0.6, 0.5]
    )
    side_min_m: float = 0.2
    side_max_m: float = 0.5
    settle_factor: float = 1.5
    scaling: str = "directional"
    trace_tolerance: float = 2e-3

    def validate(self) -> None:
        """Raises RepertoireError if a field is out of range."""
        if not self.switches or any(not 0 < s for s in self.switches):
            raise RepertoireError("DmpChainingConfig.switches must be non-empty and > 0")
        if self.scaling not in ("directional", "none"):
            raise RepertoireError(
                f"DmpChainingConfig.scaling must be 'directional' or 'none', got {self.scaling}"
            )
        for name in (
            "duration_s",
            "time_step_s",
            "side_min_m",
            "side_max_m",
            "settle_factor",
            "trace_tolerance",
        ):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise RepertoireError(f"DmpChainingConfig.{name} must be finite and > 0, got {v}")
        if self.side_max_m < self.side_min_m:
            raise RepertoireError(
                f"DmpChainingConfig needs side_min_m <= side_max_m, got {self.side_min_m} > "
                f"{self.side_max_m}"
            )
        if not (is_whole(self.n_samples) and is_whole(self.n_basis)):
            raise RepertoireError(
                "DmpChainingConfig.n_samples and n_basis must be integers, got "
                f"{self.n_samples}, {self.n_basis}"
            )
        if not 1 <= self.n_basis <= self.n_samples:
            raise RepertoireError(
                "DmpChainingConfig needs 1 <= n_basis <= n_samples, got "
                f"{self.n_basis}, {self.n_samples}"
            )


@dataclasses.dataclass
class DmpChainingRecord:
    """One episode (one switching interval, three handoffs).

    Attributes:
        switch: switching interval / tau.
        side_m: square side.
        acc_jump_none: largest |acceleration jump| at a switch (m/s^2), no handoff.
        acc_jump_velocity: same, velocity handoff (the paper).
        acc_jump_acceleration: same, acceleration-matched handoff.
        vel_jump_none: largest |velocity jump| at a switch (m/s), no handoff.
        vel_jump_velocity: same, velocity handoff.
        vel_jump_acceleration: same, acceleration handoff.
        peak_acc_velocity: peak |acceleration| over the run, velocity handoff.
        peak_acc_acceleration: same, acceleration handoff.
        corner_miss_velocity_m: mean distance of the path to the three inner corners.
        corner_miss_acceleration_m: same, acceleration handoff.
        end_error_velocity_m: distance to the last goal at the end.
        end_error_acceleration_m: same, acceleration handoff.
        drake_vs_numpy: max |Drake sequencer - NumPy chain_rollout| (velocity handoff).
        seed: the episode's seed.
        goals_m: the square's four corners, in the order visited (start at the origin).
        switch_times_s: when legs 2-4 start.
        switch_points_m: the path's position at those times (velocity handoff).
        trace_t_s: times of the kept samples (``trace_tolerance``; both sides of every
            switch).
        path_velocity_m: the chained path at ``trace_t_s``, velocity handoff (the paper).
        speed: |velocity| at ``trace_t_s`` per handoff (m/s).
        acc_norm: |acceleration| at ``trace_t_s`` per handoff (m/s^2).
        wall_time_s: episode wall time.
    """

    switch: float
    side_m: float
    acc_jump_none: float
    acc_jump_velocity: float
    acc_jump_acceleration: float
    vel_jump_none: float
    vel_jump_velocity: float
    vel_jump_acceleration: float
    peak_acc_velocity: float
    peak_acc_acceleration: float
    corner_miss_velocity_m: float
    corner_miss_acceleration_m: float
    end_error_velocity_m: float
    end_error_acceleration_m: float
    drake_vs_numpy: float
    seed: int
    goals_m: list[list[float]]
    switch_times_s: list[float]
    switch_points_m: list[list[float]]
    trace_t_s: list[float]
    path_velocity_m: list[list[float]]
    speed: dict[str, list[float]]
    acc_norm: dict[str, list[float]]
    wall_time_s: float


def primitive(config: DmpChainingConfig):
    """The minimum-jerk primitive (0,0) -> (1,0) m, learned once per episode."""
    from repertoire.planning.dmp_learn import learn_dmp
    from repertoire.planning.dmp_math import minimum_jerk

    t = np.linspace(0, config.duration_s, config.n_samples)
    x, _, _ = minimum_jerk(np.zeros(2), np.array([1.0, 0.0]), config.duration_s, t)
    return learn_dmp(t, x, n_basis=config.n_basis)


def square(config: DmpChainingConfig, seed: int) -> tuple[float, float, list[np.ndarray]]:
    """Seeded switching interval, side and the square's four goals (start at the origin).

    Args:
        config: Study config.
        seed: Episode seed.
    """
    rng = np.random.default_rng(seed)
    switch = float(config.switches[seed % len(config.switches)])
    side = float(rng.uniform(config.side_min_m, config.side_max_m))
    a = float(rng.uniform(0, 2 * np.pi))
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    corners = [R @ (side * np.array(c, float)) for c in ((1, 0), (1, 1), (0, 1), (0, 0))]
    return switch, side, corners


def leg_primitives(config: DmpChainingConfig, goals: list[np.ndarray]) -> list:
    """One DMP per leg of the square (start at the origin).

    Args:
        config: Study config.
        goals: The four corners.
    """
    from repertoire.planning.dmp_chain import directional_primitive

    p = primitive(config)
    if config.scaling == "none":
        return [p.with_goal(g, x0=np.zeros(2)) for g in goals]
    starts = [np.zeros(2)] + list(goals[:-1])
    return [directional_primitive(p, s, g) for s, g in zip(starts, goals)]


def run_chain(config: DmpChainingConfig, switch: float, goals: list[np.ndarray], handoff: str):
    """Run the DmpSequencer in a Drake diagram; returns (t, x, xd, xdd, switch_steps).

    Args:
        config: Study config.
        switch: Switching interval / tau.
        goals: Four goals.
        handoff: "none", "velocity" or "acceleration".
    """
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.primitives import VectorLogSink
    from repertoire.systems.dmp_sequencer import DmpSequencer

    segments = leg_primitives(config, goals)
    dt = config.time_step_s
    times = [i * switch * config.duration_s for i in range(4)]
    builder = DiagramBuilder()
    seq = builder.AddSystem(
        DmpSequencer(segments, times, goals=goals, time_step=dt, handoff=handoff)
    )
    logs = {}
    for name in ("position", "velocity", "acceleration"):
        logs[name] = builder.AddSystem(VectorLogSink(2, publish_period=dt))
        builder.Connect(seq.GetOutputPort(name), logs[name].get_input_port())
    sim = Simulator(builder.Build())
    sim.AdvanceTo(times[-1] + config.settle_factor * config.duration_s)
    ctx = sim.get_context()
    data = {k: v.FindLog(ctx) for k, v in logs.items()}
    steps = [int(round(s / dt)) for s in times[1:]]
    return (
        data["position"].sample_times(),
        data["position"].data().T,
        data["velocity"].data().T,
        data["acceleration"].data().T,
        steps,
        segments,
        times,
    )


def trace_indices(t: np.ndarray, signals: list[np.ndarray], steps: list[int], rel_tol: float):
    """The samples a record keeps: each signal, drawn through them, stays within tolerance.

    Ramer-Douglas-Peucker on all signals at once: a stretch between kept samples is split
    at its worst sample until every signal is within ``rel_tol`` of its largest magnitude
    of the chord through the kept samples (thinning each signal apart and keeping the
    union of the samples would not do: a chord to another signal's sample can leave a
    signal's band).

    Args:
        t: Sample times, shape (N,).
        signals: Time series, each shape (N,).
        steps: The switch steps (the first samples of legs 2-4): they and the samples
            before them are always kept (a jump stays a jump).
        rel_tol: Largest gap between a signal and its chords, as a fraction of the
            signal's largest magnitude.
    """
    y = np.stack(signals, axis=1)
    tol = rel_tol * np.maximum(np.max(np.abs(y), axis=0), 1e-300)
    n = len(t)
    keep = {0, n - 1} | {k + d for k in steps for d in (-1, 0) if 0 <= k + d < n}
    ordered = sorted(keep)
    stack = list(zip(ordered[:-1], ordered[1:]))
    while stack:
        i, j = stack.pop()
        if j <= i + 1:
            continue
        s = ((t[i + 1 : j] - t[i]) / (t[j] - t[i]))[:, None]
        excess = np.max(np.abs(y[i + 1 : j] - (y[i] + (y[j] - y[i]) * s)) / tol, axis=1)
        m = int(np.argmax(excess))
        if excess[m] > 1.0:
            keep.add(i + 1 + m)
            stack += [(i, i + 1 + m), (i + 1 + m, j)]
    return np.array(sorted(keep))


def run_episode(config: DmpChainingConfig, seed: int) -> DmpChainingRecord:
    """Run the square with the seeded switching interval and the three handoffs."""
    from repertoire.planning.dmp_chain import chain_rollout

    t0 = time.perf_counter()
    config.validate()
    switch, side, goals = square(config, seed)
    out: dict = {"switch": switch, "side_m": side, "seed": int(seed), "speed": {}, "acc_norm": {}}
    out["goals_m"] = [g.tolist() for g in goals]
    runs = {h: run_chain(config, switch, goals, h) for h in HANDOFF_NAMES}
    t, steps = runs["velocity"][0], runs["velocity"][4]  # the same for every handoff
    signals = [runs["velocity"][1][:, 0], runs["velocity"][1][:, 1]]
    for _, _, xd, xdd, *_ in runs.values():
        signals += [np.linalg.norm(xd, axis=1), np.linalg.norm(xdd, axis=1)]
    keep = trace_indices(t, signals, steps, config.trace_tolerance)
    for h in HANDOFF_NAMES:
        t, x, xd, xdd, steps, segs, times = runs[h]
        ref = chain_rollout(
            segs, goals, times, x0=np.zeros(2), handoff=h, dt=config.time_step_s, duration=t[-1]
        )
        out[f"acc_jump_{h}"] = max(ref.acceleration_jumps)
        out[f"vel_jump_{h}"] = max(ref.velocity_jumps)
        # to 1e-6 (m, m/s, m/s^2, s): far inside trace_tolerance, a third of the JSON
        out["speed"][h] = np.round(np.linalg.norm(xd[keep], axis=1), 6).tolist()
        out["acc_norm"][h] = np.round(np.linalg.norm(xdd[keep], axis=1), 6).tolist()
        if h == "velocity":
            out["drake_vs_numpy"] = float(np.abs(x - ref.x[: len(x)]).max())
            out["trace_t_s"] = np.round(t[keep], 6).tolist()
            out["path_velocity_m"] = np.round(x[keep], 6).tolist()
            out["switch_times_s"] = np.round(t[steps], 6).tolist()  # as in trace_t_s
            out["switch_points_m"] = np.round(x[steps], 6).tolist()
        if h != "none":
            out[f"peak_acc_{h}"] = float(np.abs(xdd).max())
            miss = [float(np.min(np.linalg.norm(x - c, axis=1))) for c in goals[:3]]
            out[f"corner_miss_{h}_m"] = float(np.mean(miss))
            out[f"end_error_{h}_m"] = float(np.linalg.norm(x[-1] - goals[-1]))
    return DmpChainingRecord(**out, wall_time_s=time.perf_counter() - t0)


def square_frame(goals: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Points in the square's own frame, in side lengths: goal 1 at (1, 0), goal 3 at (0, 1).

    Args:
        goals: The four corners (:func:`square`), shape (4, 2); the start is the origin.
        points: Points in the plane, shape (N, 2).
    """
    goals = np.asarray(goals, dtype=float)
    u, v = goals[0], goals[2]  # side x the square's axes
    return np.asarray(points, dtype=float) @ np.stack([u, v]).T / float(u @ u)


def _episode_label(r: DmpChainingRecord) -> str:
    return f"seed {r.seed}: switch {r.switch:g} tau, side {r.side_m:.2f} m"


def fig5(records: list[DmpChainingRecord]):
    """Fig. 5 drawn from the episodes run: their chained paths, switch points and traces.

    (a) the episode with the longest switching interval as it ran (metres); (b) every
    episode in its own square's frame (side lengths), so squares of any size and rotation
    compare; (c)/(d) |acceleration| and |velocity| of the episode with the shortest
    switching interval, for the three handoffs.

    Args:
        records: The episodes (at least one).

    Returns:
        The matplotlib Figure.
    """
    from matplotlib import colormaps
    from matplotlib.figure import Figure

    if not records:
        raise RepertoireError("the dmp_chaining figure needs at least one record")
    fig = Figure(figsize=(18, 5), layout="constrained")
    axes = fig.subplots(1, 4)
    sw = sorted({r.switch for r in records}, reverse=True)
    first = min(records, key=lambda r: (-r.switch, r.seed))  # longest interval
    last = min(records, key=lambda r: (r.switch, r.seed))  # shortest interval
    # (a) one episode's chained path, leg by leg (Fig. 5a: alternate solid / dashed)
    t, x = np.array(first.trace_t_s), np.array(first.path_velocity_m)
    bounds = [0] + [int(np.searchsorted(t, s)) for s in first.switch_times_s] + [len(t) - 1]
    for k in range(4):
        seg = x[bounds[k] : bounds[k + 1] + 1]
        axes[0].plot(
            seg[:, 0],
            seg[:, 1],
            "-" if k % 2 == 0 else "--",
            c="tab:blue" if k % 2 == 0 else "tab:red",
            lw=2,
            label=("legs 1, 3 (velocity handoff)", "legs 2, 4")[k % 2] if k < 2 else None,
        )
    goals = np.array(first.goals_m)
    # hollow marks: a switch at a goal (switch 1 tau) and the start at goal 4 stay visible
    axes[0].plot(*goals.T, "o", c="k", mfc="none", ms=11, label="goals 1-4 (in order)")
    for k, g in enumerate(goals):
        axes[0].annotate(str(k + 1), g, xytext=(7, 7), textcoords="offset points")
    axes[0].plot(0, 0, "^", c="tab:green", ms=7, label="start (= goal 4)")
    axes[0].plot(*np.array(first.switch_points_m).T, "kx", ms=7, mew=2, label="switch")
    axes[0].set_xlabel("x (m)")
    axes[0].set_ylabel("y (m)")
    axes[0].set_title(f"(a) one primitive, four goals\n{_episode_label(first)}")
    # (b) every episode in its square's frame, coloured by switching interval
    cmap = colormaps["Blues"]
    for i, s in enumerate(sw):
        col = cmap(0.95 - 0.6 * i / max(len(sw) - 1, 1))
        rs = [r for r in records if r.switch == s]
        for r in rs:
            axes[1].plot(*square_frame(r.goals_m, r.path_velocity_m).T, c=col, lw=1.2)
            axes[1].plot(*square_frame(r.goals_m, r.switch_points_m).T, "x", c=col, ms=6)
        axes[1].plot([], [], c=col, lw=1.2, label=f"switch {s:g} tau ({len(rs)} episodes)")
    unit = np.array([(1, 0), (1, 1), (0, 1), (0, 0)], float)
    axes[1].plot(*unit.T, "o", c="k", mfc="none", ms=11, label="goals")
    axes[1].plot(0, 0, "^", c="tab:green", ms=7, label="start (= goal 4)")
    axes[1].plot([], [], "x", c="0.4", ms=6, label="switches")
    axes[1].set_xlabel("along leg 1 (side lengths)")
    axes[1].set_ylabel("along leg 2 (side lengths)")
    axes[1].set_title(
        f"(b) all {len(records)} episodes in their square's frame\n(lighter = earlier switch)"
    )
    for ax in axes[:2]:
        ax.set_aspect("equal")
        ax.grid(alpha=0.3)
        # below the axes: inside, the legend covered the paths of the earliest switches
        legend_below(ax, ax.get_legend_handles_labels()[0], ncols=2, fontsize=7)
    # (c), (d) the shortest switching interval's traces, three handoffs
    t = np.array(last.trace_t_s)
    for h, c in (("none", "tab:gray"), ("velocity", "tab:red"), ("acceleration", "tab:blue")):
        ls = "--" if h == "none" else "-"
        axes[2].plot(t, last.acc_norm[h], ls, c=c, lw=1.2, label=f"handoff {h}")
        axes[3].plot(t, last.speed[h], ls, c=c, lw=1.2, label=f"handoff {h}")
    for ax in axes[2:]:
        for k, ts in enumerate(last.switch_times_s):
            ax.axvline(ts, color="k", ls=":", lw=0.8, label="switch" if k == 0 else None)
        ax.set_xlabel("t (s)")
    axes[2].set_title(f"(c) |acceleration|\n{_episode_label(last)}")
    axes[2].set_ylabel("|acceleration| (m/s^2)")
    axes[2].legend(fontsize=8)
    axes[3].set_title(f"(d) |velocity|\n{_episode_label(last)}")
    axes[3].set_ylabel("|velocity| (m/s)")
    axes[3].set_ylim(top=1.3 * axes[3].get_ylim()[1])  # headroom: the legend clears the dips
    axes[3].legend(fontsize=8, loc="upper center", ncols=2)
    return fig


def summarize(records: list[DmpChainingRecord], config: DmpChainingConfig, out_dir: Path):
    """The Fig. 5 panels of the episodes run (:func:`fig5`) and the table per interval."""
    out_dir = Path(out_dir)
    p1 = out_dir / "dmp_chaining_fig5.png"
    fig5(records).savefig(p1, dpi=100)
    sw = sorted({r.switch for r in records}, reverse=True)

    lines = [
        f"# DMP chaining, Fig. 5 square ({len(records)} episodes; jumps are max over the "
        "three switches, m/s^2 and m/s)",
        "",
        "| switch / tau | episodes | acc jump none | acc jump velocity (paper) | "
        "acc jump acceleration | vel jump none | vel jump velocity | corner miss velocity (m) |"
        " end error (m) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for s in sw:
        rs = [r for r in records if r.switch == s]
        if not rs:
            continue

        def mx(key, rs=rs):
            return max(getattr(r, key) for r in rs)

        lines.append(
            f"| {s:g} | {len(rs)} | {mx('acc_jump_none'):.3g} | {mx('acc_jump_velocity'):.3g} | "
            f"{mx('acc_jump_acceleration'):.2g} | {mx('vel_jump_none'):.3g} | "
            f"{mx('vel_jump_velocity'):.2g} | "
            f"{np.mean([r.corner_miss_velocity_m for r in rs]):.3f} | "
            f"{mx('end_error_velocity_m'):.2g} |"
        )
    lines.append("")
    lines.append(
        f"Drake DmpSequencer vs NumPy chain_rollout: max difference "
        f"{max(r.drake_vs_numpy for r in records):.2g} m."
    )
    p2 = write_table(out_dir, "dmp_chaining_table.md", lines)
    return {"fig5": p1, "table": p2}


register_dmp_study(
    __name__,
    DmpChainingConfig,
    DmpChainingRecord,
    description="DMP chaining (Fig. 5 square): acceleration/velocity jumps at switches",
    demo_episodes=12,
    # a tiny config for tests: one switching interval, a short settle
    smoke=dict(n_basis=10, n_samples=100, time_step_s=2e-3, switches=[0.7], settle_factor=0.3),
)
