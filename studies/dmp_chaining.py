"""DMP chaining (Pastor et al., sec. III-C, Fig. 5): a square from one primitive, four goals.

One minimum-jerk primitive (learned from a straight movement (0,0) -> (1,0) m) is
generalised to the four corners of a square and chained with a DmpSequencer (Drake,
1 kHz): each DMP starts before its predecessor has finished, at a switching interval of
``switch`` x tau. With ``scaling="directional"`` (default) each leg uses the learned Y1
shape along the leg's direction (:func:`repertoire.planning.dmp.directional_primitive`);
with ``"none"`` the 2-D primitive is sent to each corner as it is (the new form then
pushes along Y1 on the vertical legs too, since its forcing term is not scaled by g - x0).

Each episode takes one switching interval (cycled over the config's
list by seed) and a seeded square size and rotation, and runs the three handoffs:

* none: the successor restarts from rest at the current position;
* velocity (the paper): position and velocity handed over;
* acceleration: as velocity, plus the equations' x0 shifted so the successor starts with
  its predecessor's acceleration.

It records the largest acceleration and velocity jumps at the switches, how close the path
comes to the corners and the end error. Run ``python -m repertoire.studies.dmp_chaining``.
"""

import dataclasses
import math
import time
from pathlib import Path

import numpy as np
from repertoire.studies._dmp_common import register_dmp_study, write_table

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

    def validate(self) -> None:
        """Raises RepertoireError if a field is out of range."""
        if not self.switches or any(not 0 < s for s in self.switches):
            raise RepertoireError("DmpChainingConfig.switches must be non-empty and > 0")
        if self.scaling not in ("directional", "none"):
            raise RepertoireError(
                f"DmpChainingConfig.scaling must be 'directional' or 'none', got {self.scaling}"
            )
        for name in ("duration_s", "time_step_s", "side_min_m", "side_max_m", "settle_factor"):
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
    from repertoire.planning.dmp import directional_primitive

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


def run_episode(config: DmpChainingConfig, seed: int) -> DmpChainingRecord:
    """Run the square with the seeded switching interval and the three handoffs."""
    from repertoire.planning.dmp_chain import chain_rollout

    t0 = time.perf_counter()
    config.validate()
    switch, side, goals = square(config, seed)
    out: dict = {"switch": switch, "side_m": side}
    for h in HANDOFF_NAMES:
        t, x, xd, xdd, steps, segs, times = run_chain(config, switch, goals, h)
        ref = chain_rollout(
            segs, goals, times, x0=np.zeros(2), handoff=h, dt=config.time_step_s, duration=t[-1]
        )
        out[f"acc_jump_{h}"] = max(ref.acceleration_jumps)
        out[f"vel_jump_{h}"] = max(ref.velocity_jumps)
        if h == "velocity":
            out["drake_vs_numpy"] = float(np.abs(x - ref.x[: len(x)]).max())
        if h != "none":
            out[f"peak_acc_{h}"] = float(np.abs(xdd).max())
            miss = [float(np.min(np.linalg.norm(x - c, axis=1))) for c in goals[:3]]
            out[f"corner_miss_{h}_m"] = float(np.mean(miss))
            out[f"end_error_{h}_m"] = float(np.linalg.norm(x[-1] - goals[-1]))
    return DmpChainingRecord(**out, wall_time_s=time.perf_counter() - t0)


def summarize(records: list[DmpChainingRecord], config: DmpChainingConfig, out_dir: Path):
    """Fig. 5-like squares for every switching interval, acceleration traces, a table."""
    from matplotlib import colormaps
    from matplotlib.figure import Figure

    out_dir = Path(out_dir)
    goals = [np.array(c, float) for c in ((1, 0), (1, 1), (0, 1), (0, 0))]
    fig = Figure(figsize=(17, 4.5), layout="constrained")
    axes = fig.subplots(1, 4)
    sw = sorted(set(config.switches), reverse=True)
    cmap = colormaps["Blues"]
    for i, s in enumerate(sw):
        t, x, _, xdd, steps, _, _ = run_chain(config, s, goals, "velocity")
        col = cmap(0.95 - 0.6 * i / max(len(sw) - 1, 1))
        if i == 0:
            # Fig. 5a: alternate solid / dashed per segment.
            bounds = [0] + steps + [len(x)]
            for k in range(4):
                seg = x[bounds[k] : bounds[k + 1] + 1]
                axes[0].plot(
                    seg[:, 0],
                    seg[:, 1],
                    "-" if k % 2 == 0 else "--",
                    c="tab:blue" if k % 2 == 0 else "tab:red",
                    lw=2,
                    label=("segments 1, 3", "segments 2, 4")[k % 2] if k < 2 else None,
                )
        axes[1].plot(x[:, 0], x[:, 1], c=col, lw=1.5, label=f"switch {s:g} tau")
        if s == min(sw):
            for h, c in (
                ("none", "tab:gray"),
                ("velocity", "tab:red"),
                ("acceleration", "tab:blue"),
            ):
                th, xh, vh, ah, st, _, _ = run_chain(config, s, goals, h)
                ls = "--" if h == "none" else "-"
                axes[2].plot(th, np.linalg.norm(ah, axis=1), ls, c=c, lw=1.2, label=f"handoff {h}")
                axes[3].plot(th, np.linalg.norm(vh, axis=1), ls, c=c, lw=1.2, label=f"handoff {h}")
            for k in st:
                for ax in axes[2:]:
                    ax.axvline(
                        th[k], color="k", ls=":", lw=0.8, label="switch" if k == st[0] else None
                    )
    for ax in axes[:2]:
        ax.plot(*np.array(goals).T, "ko", ms=6, label="goals (in order from (1, 0))")
        ax.plot(0, 0, "k^", ms=6, label="start")
        ax.set_aspect("equal")
        ax.set_xlabel("Y1 (m)")
        ax.set_ylabel("Y2 (m)")
        ax.grid(alpha=0.3)
    axes[0].set_title(f"(a) one primitive, four goals (switch {sw[0]:g} tau)")
    axes[0].legend(fontsize=7)
    axes[1].set_title("(b) switching times (lighter = earlier)")
    axes[1].legend(fontsize=7)
    axes[2].set_title(f"|acceleration|, switch {min(sw):g} tau")
    axes[2].set_xlabel("t (s)")
    axes[2].set_ylabel("|acceleration| (m/s^2)")
    axes[2].legend(fontsize=8)
    axes[3].set_title(f"|velocity|, switch {min(sw):g} tau")
    axes[3].set_xlabel("t (s)")
    axes[3].set_ylabel("|velocity| (m/s)")
    axes[3].set_ylim(top=1.3 * axes[3].get_ylim()[1])  # headroom: the legend clears the dips
    axes[3].legend(fontsize=8, loc="upper center", ncols=2)
    p1 = out_dir / "dmp_chaining_fig5.png"
    fig.savefig(p1, dpi=100)

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
