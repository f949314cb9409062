"""LittleDog library execution from perturbed starts, with and without the integral controller.

Each episode draws a source terrain (``seed`` modulo the number of terrains), a
start offset uniform in ``+-max_offset_m`` along x and y and a heading offset
uniform in ``+-max_yaw_deg``, and runs the ``littledog_library`` diagram twice
from that start: with the integral foot controller (gain ``gain``) and without it
(gain 0, the ablation). Success: both front feet past the goal line, the body
never lower than 4 cm above the terrain, no fall (tilt over 0.5 rad). The record
holds success and time to cross of both runs, their body position and heading
errors against the step's recorded (ideal) body pose over time, and the
integrator states of the run with the controller.
The summary tabulates success per terrain and condition, plots the body pose
error over time for both conditions and the integrators over one crossing.
Run it with ``python -m repertoire.studies.littledog_execution --help``.
"""

import dataclasses
import math
from pathlib import Path

import numpy as np
from repertoire.studies.engine import register_study

from repertoire.errors import RepertoireError

TRACE_PERIOD_S = 0.2
"""Sampling period of the traces stored in a record (s)."""


@dataclasses.dataclass
class LittleDogExecutionConfig:
    """What every episode shares.

    Attributes:
        terrains: library terrains, chosen by ``seed % len(terrains)``.
        direction_deg: crossing direction.
        max_offset_m: start x and y offsets are uniform in [-max, max] (m).
        max_yaw_deg: start heading offsets are uniform in [-max, max] (degrees).
        gain: integral controller gain of the controlled run.
        duration_s: simulated time of each run (s).
        library: step library file ("" = the cached default library).
    """

    terrains: list[str] = dataclasses.field(default_factory=lambda: ["terrain_a", "terrain_b"])
    direction_deg: float = 0.0
    max_offset_m: float = 0.03
    max_yaw_deg: float = 10.0
    gain: float = 0.05
    duration_s: float = 40.0
    library: str = ""

    def validate(self) -> None:
        """Raises RepertoireError naming a bad field."""
        from repertoire.diagrams.littledog_demos import library_terrain

        if not self.terrains:
            raise RepertoireError("terrains must name at least one library terrain")
        for name in self.terrains:
            library_terrain(name)
        if not (0.0 <= self.max_offset_m <= 0.06 and 0.0 <= self.max_yaw_deg <= 20.0):
            raise RepertoireError(
                f"max_offset_m must be in [0, 0.06] m and max_yaw_deg in [0, 20], got "
                f"{self.max_offset_m}, {self.max_yaw_deg}"
            )
        if not (0.0 < self.gain <= 1.0):
            raise RepertoireError(f"gain must be in (0, 1], got {self.gain}")
        if not (math.isfinite(self.duration_s) and 0.5 <= self.duration_s <= 120.0):
            raise RepertoireError(f"duration_s must be in [0.5, 120] s, got {self.duration_s}")


@dataclasses.dataclass
class LittleDogExecutionRecord:
    """One perturbed start, run with and without the integral controller.

    Attributes:
        terrain: source terrain.
        offset_x_m, offset_y_m, offset_yaw_deg: the start perturbation.
        success: the run with the integral controller crossed (see module doc).
        time_to_cross_s: its time to cross (NaN if it did not).
        fell: it fell.
        steps: steps it started.
        success_ablation, time_to_cross_ablation_s, fell_ablation, steps_ablation: the
            same for the run without the integral controller.
        position_error_m: |body xyz - ideal xyz| every TRACE_PERIOD_S, controlled run.
        heading_error_rad: |body yaw - ideal yaw| every TRACE_PERIOD_S, controlled run.
        position_error_ablation_m, heading_error_ablation_rad: the same without.
        integrators_m: the 12 integrator values every TRACE_PERIOD_S (flattened, T x 12).
        wall_time_s: wall time of both runs (s).
    """

    terrain: str
    offset_x_m: float
    offset_y_m: float
    offset_yaw_deg: float
    success: bool
    time_to_cross_s: float
    fell: bool
    steps: int
    success_ablation: bool
    time_to_cross_ablation_s: float
    fell_ablation: bool
    steps_ablation: int
    position_error_m: list[float]
    heading_error_rad: list[float]
    position_error_ablation_m: list[float]
    heading_error_ablation_rad: list[float]
    integrators_m: list[float]
    wall_time_s: float


def run_crossing(config: LittleDogExecutionConfig, terrain: str, offset, yaw: float, gain: float):
    """One run of the library diagram; returns (figures, traces dict)."""
    from repertoire.diagrams.littledog_library import (
        LittleDogLibraryScenario,
        build_littledog_library,
        check_littledog_library,
        crossing_logs,
        load_library,
    )
    from repertoire.diagrams.simulate import simulate
    from repertoire.models.littledog.pose import wrap_angle

    scenario = LittleDogLibraryScenario(
        terrain=terrain,
        direction_deg=config.direction_deg,
        start_offset=[float(offset[0]), float(offset[1])],
        start_yaw_offset=float(yaw),
        library=config.library,
        gain=gain,
    )
    diagram = build_littledog_library(scenario, library=load_library(config.library))
    _, context = simulate(diagram, config.duration_s)
    figures = check_littledog_library(diagram, context)
    logs = crossing_logs(diagram, context)
    every = max(1, round(TRACE_PERIOD_S / 0.01))
    body, ideal = logs["body_log"][::every], logs["ideal_log"][::every]
    traces = {
        "position": np.linalg.norm(body[:, :3] - ideal[:, :3], axis=1),
        "heading": np.abs(wrap_angle(body[:, 5] - ideal[:, 5])),
        "integrators": logs["integrator_log"][::every],
    }
    return figures, traces


def run_episode(config: LittleDogExecutionConfig, seed: int) -> LittleDogExecutionRecord:
    """Draws the start perturbation from ``seed`` and runs both conditions."""
    import time

    config.validate()
    start = time.perf_counter()
    rng = np.random.default_rng(seed)
    terrain = config.terrains[seed % len(config.terrains)]
    offset = rng.uniform(-config.max_offset_m, config.max_offset_m, size=2)
    yaw = math.radians(float(rng.uniform(-config.max_yaw_deg, config.max_yaw_deg)))
    on, on_traces = run_crossing(config, terrain, offset, yaw, config.gain)
    off, off_traces = run_crossing(config, terrain, offset, yaw, 0.0)

    def ok(f):
        return bool(f["crossed"] >= 1.0 and f["fell"] == 0.0)

    return LittleDogExecutionRecord(
        terrain=terrain,
        offset_x_m=float(offset[0]),
        offset_y_m=float(offset[1]),
        offset_yaw_deg=math.degrees(yaw),
        success=ok(on),
        time_to_cross_s=on["time_to_cross_s"],
        fell=bool(on["fell"]),
        steps=int(on["steps_started"]),
        success_ablation=ok(off),
        time_to_cross_ablation_s=off["time_to_cross_s"],
        fell_ablation=bool(off["fell"]),
        steps_ablation=int(off["steps_started"]),
        position_error_m=[float(v) for v in on_traces["position"]],
        heading_error_rad=[float(v) for v in on_traces["heading"]],
        position_error_ablation_m=[float(v) for v in off_traces["position"]],
        heading_error_ablation_rad=[float(v) for v in off_traces["heading"]],
        integrators_m=[float(v) for v in on_traces["integrators"].ravel()],
        wall_time_s=time.perf_counter() - start,
    )


def _until(trace: list[float], t_end: float) -> np.ndarray:
    """The trace with samples after ``t_end`` (the crossing time, if any) set to NaN."""
    a = np.asarray(trace, dtype=float).copy()
    if math.isfinite(t_end):
        a[np.arange(len(a)) * TRACE_PERIOD_S > t_end] = np.nan
    return a


_LEG_NAMES = {"lf": "left-front", "rf": "right-front", "lh": "left-hind", "rh": "right-hind"}


def _band(ax, series: list[np.ndarray], colour: str, label: str) -> None:
    """Median and 10-90 percentile band over the episodes still walking at each time.

    Drawn while at least a quarter of the episodes are still before their goal.
    """
    n = min(len(s) for s in series)
    a = np.array([s[:n] for s in series])
    active = np.sum(np.isfinite(a), axis=0) >= max(1, len(series) // 4)
    a = a[:, active]
    t = np.arange(n)[active] * TRACE_PERIOD_S
    ax.plot(t, np.nanmedian(a, axis=0), color=colour, lw=1.6, label=f"{label}: median")
    ax.fill_between(
        t,
        np.nanpercentile(a, 10, axis=0),
        np.nanpercentile(a, 90, axis=0),
        color=colour,
        alpha=0.2,
        label=f"{label}: 10-90 percentile",
    )


def summarize(
    records: list[LittleDogExecutionRecord], config: LittleDogExecutionConfig, out_dir: Path
) -> dict[str, Path]:
    """Success table, body pose error over time, integrators of one crossing.

    The integrators are those of the first successful episode, up to its goal.

    Returns:
        ``{"table": md, "pose_error": png, "integrators": png}``.
    """
    from matplotlib.figure import Figure
    from repertoire.models.littledog import LEGS

    out_dir = Path(out_dir)
    lines = [
        "| terrain | condition | episodes | success | fell | median time to cross (s) |",
        "|---|---|---|---|---|---|",
    ]
    for name in config.terrains:
        rs = [r for r in records if r.terrain == name]
        if not rs:
            continue
        for label, suc, fell, ttc in (
            ("integral controller", "success", "fell", "time_to_cross_s"),
            (
                "no integral controller",
                "success_ablation",
                "fell_ablation",
                "time_to_cross_ablation_s",
            ),
        ):
            times = [getattr(r, ttc) for r in rs if getattr(r, suc)]
            med = f"{np.median(times):.1f}" if times else "-"
            lines.append(
                f"| {name} | {label} | {len(rs)} | {sum(getattr(r, suc) for r in rs)}/{len(rs)} "
                f"| {sum(getattr(r, fell) for r in rs)} | {med} |"
            )
    table = out_dir / "littledog_execution.md"
    table.write_text("\n".join(lines) + "\n")

    fig = Figure(figsize=(9.5, 4.6), layout="constrained")
    for k, (key, key_off, ylabel) in enumerate(
        [
            ("position_error_m", "position_error_ablation_m", "body position error (m)"),
            ("heading_error_rad", "heading_error_ablation_rad", "body heading error (rad)"),
        ]
    ):
        ax = fig.add_subplot(1, 2, k + 1)
        _band(
            ax,
            [_until(getattr(r, key), r.time_to_cross_s) for r in records],
            "tab:blue",
            "with integral controller",
        )
        _band(
            ax,
            [_until(getattr(r, key_off), r.time_to_cross_ablation_s) for r in records],
            "tab:red",
            "without (ablation)",
        )
        ax.set_xlabel("time (s)")
        ax.set_ylabel(ylabel)
        ax.set_ylim(bottom=0.0)
    # one legend under both panels: inside, it covered the ablation's median
    fig.legend(*ax.get_legend_handles_labels(), loc="outside lower center", ncols=4, fontsize=8)
    fig.suptitle(
        f"Body pose vs the step's recorded pose, {len(records)} perturbed starts "
        f"(each run until its front feet pass the goal)"
    )
    pose_png = out_dir / "littledog_pose_error.png"
    fig.savefig(pose_png, dpi=110)

    r0 = next((r for r in records if r.success), records[0])
    integ = np.asarray(r0.integrators_m).reshape(-1, 12)
    if math.isfinite(r0.time_to_cross_s):
        integ = integ[: int(r0.time_to_cross_s / TRACE_PERIOD_S) + 1]
    fig = Figure(figsize=(9.5, 6.3), layout="constrained")
    t = np.arange(len(integ)) * TRACE_PERIOD_S
    for f in range(4):
        ax = fig.add_subplot(2, 2, f + 1)
        for a, c in zip(range(3), ["tab:red", "tab:green", "tab:blue"]):
            ax.plot(t, 1000 * integ[:, 3 * f + a], color=c, label=f"{'xyz'[a]} (body frame)")
        ax.set_title(f"{_LEG_NAMES[LEGS[f]]} foot ({LEGS[f]})")
        ax.set_xlabel("time (s)")
        ax.set_ylabel("integrator (mm, body frame)")
    # one legend for the four panels: inside, it covered a trace in some of them
    fig.legend(*ax.get_legend_handles_labels(), loc="outside lower center", ncols=3, fontsize=8)
    run = "one crossing" if r0.success else "one run that did not reach the goal"
    fig.suptitle(
        f"Integrator states over {run} ({r0.terrain}, start offset "
        f"{100 * r0.offset_x_m:+.1f}, {100 * r0.offset_y_m:+.1f} cm, {r0.offset_yaw_deg:+.1f} deg)"
    )
    integ_png = out_dir / "littledog_integrators.png"
    fig.savefig(integ_png, dpi=110)
    return {"table": table, "pose_error": pose_png, "integrators": integ_png}


def demo_config() -> LittleDogExecutionConfig:
    """Both terrains, full crossings (about 20 s of wall time per episode)."""
    return LittleDogExecutionConfig()


def smoke_config() -> LittleDogExecutionConfig:
    """One terrain, 2 s runs."""
    return LittleDogExecutionConfig(terrains=["terrain_a"], duration_s=2.0)


register_study(
    "littledog_execution",
    config_type=LittleDogExecutionConfig,
    record_type=LittleDogExecutionRecord,
    run_episode=run_episode,
    description="LittleDog step library from perturbed starts: success, time to cross, "
    "with and without the integral foot controller",
    summarize=summarize,
    demo_config=demo_config,
    demo_episodes=2,
    smoke_config=smoke_config,
).run_if_main(__name__)
