"""LittleDog demonstrations: the scripted operator crosses the library terrains in physics.

Episode ``seed`` is crossing number ``seed`` of the configured terrains (terrain by
terrain, direction by direction; the crossings are deterministic, the seed only
picks one). Each episode plans the footholds, plays the crawl into the plant's PD,
records it every 10 ms and segments it into library steps; the record holds the
number of steps, the largest foot slip during stance, the lowest body clearance,
whether the robot fell, the start foot positions of every step and the wall time.
The summary draws the recorded foot positions over each terrain's height map
(like Fig. 6 of Stolle et al.) and tabulates steps per terrain and direction.
Run it with ``python -m repertoire.studies.littledog_demos --help``.
"""

import dataclasses
import math
from pathlib import Path

import numpy as np
from repertoire.studies.engine import register_study

from repertoire.errors import RepertoireError


@dataclasses.dataclass
class LittleDogDemoConfig:
    """Which crossings to record.

    Attributes:
        terrains: library terrain names (see ``LIBRARY_TERRAINS``).
        max_steps: record only the first steps of each crossing (0 = the whole crossing).
    """

    terrains: list[str] = dataclasses.field(default_factory=lambda: ["terrain_a", "terrain_b"])
    max_steps: int = 0

    def validate(self) -> None:
        """Raises RepertoireError for an unknown terrain or a negative step count."""
        from repertoire.diagrams.littledog_demos import library_terrain

        if not self.terrains:
            raise RepertoireError("LittleDogDemoConfig.terrains must name at least one terrain")
        for name in self.terrains:
            library_terrain(name)
        if int(self.max_steps) != self.max_steps or self.max_steps < 0:
            raise RepertoireError(f"max_steps must be an integer >= 0, got {self.max_steps}")


@dataclasses.dataclass
class LittleDogDemoRecord:
    """One recorded crossing.

    Attributes:
        terrain: terrain name.
        direction_deg: crossing direction.
        steps: number of library steps recorded.
        slip_m: largest distance a foot slid during one stance (m).
        min_clearance_m: lowest body height above the terrain under it (m).
        fell: tilt over 0.5 rad or body within 4 cm of the terrain.
        start_feet: start foot positions of every step, flattened (steps x 4 x 3).
        moving_foot: the moving foot of every step (``LEGS`` index).
        sim_time_s: simulated time of the crossing (s).
        wall_time_s: wall time of the simulation (s).
    """

    terrain: str
    direction_deg: float
    steps: int
    slip_m: float
    min_clearance_m: float
    fell: bool
    start_feet: list[float]
    moving_foot: list[int]
    sim_time_s: float
    wall_time_s: float


def crossings(config: LittleDogDemoConfig) -> list[tuple[str, float]]:
    """Every (terrain, direction) the config crosses, in episode order."""
    from repertoire.diagrams.littledog_demos import library_terrain

    return [(n, d) for n in config.terrains for d in library_terrain(n).directions_deg]


def run_episode(config: LittleDogDemoConfig, seed: int) -> LittleDogDemoRecord:
    """Records crossing ``seed`` (modulo the number of crossings)."""
    from repertoire.diagrams.littledog_demos import library_terrain, record_crossing

    config.validate()
    name, direction = crossings(config)[seed % len(crossings(config))]
    rec = record_crossing(library_terrain(name), direction, max_steps=config.max_steps or None)
    return LittleDogDemoRecord(
        terrain=name,
        direction_deg=float(direction),
        steps=len(rec.steps),
        slip_m=rec.slip_m,
        min_clearance_m=rec.min_clearance_m,
        fell=rec.fell,
        start_feet=[float(v) for s in rec.steps for v in s.start_feet.ravel()],
        moving_foot=[int(s.foot) for s in rec.steps],
        sim_time_s=float(rec.times[-1]),
        wall_time_s=rec.wall_s,
    )


_LEG_NAMES = {"lf": "left-front", "rf": "right-front", "lh": "left-hind", "rh": "right-hind"}


def summarize(
    records: list[LittleDogDemoRecord], config: LittleDogDemoConfig, out_dir: Path
) -> dict[str, Path]:
    """Draws the recorded footholds over each terrain's height map and writes a table.

    Returns:
        ``{"footholds": png, "table": md}``.
    """
    from matplotlib.figure import Figure
    from repertoire.diagrams.littledog_demos import library_terrain
    from repertoire.models.littledog import LEGS

    names = [n for n in config.terrains if any(r.terrain == n for r in records)]
    # about as tall as a square map with its title and legend (6.0 floated it in white)
    fig = Figure(figsize=(5.4 * max(len(names), 1), 5.0), layout="constrained")
    markers = ["o", "s", "^", "v"]
    colours = ["tab:red", "tab:orange", "tab:blue", "tab:cyan"]
    for k, name in enumerate(names):
        ax = fig.add_subplot(1, len(names), k + 1)
        board = library_terrain(name).build()
        xs = np.linspace(-0.4, 0.4, 321)
        X, Y = np.meshgrid(xs, xs)
        im = ax.imshow(
            board.height(X, Y), origin="lower", extent=(-0.4, 0.4, -0.4, 0.4), cmap="gray"
        )
        fig.colorbar(im, ax=ax, label="terrain height (m)", shrink=0.8)
        for f in range(4):
            pts = [
                np.asarray(r.start_feet).reshape(-1, 4, 3)[:, f, :2]
                for r in records
                if r.terrain == name and r.steps
            ]
            if pts:
                p = np.concatenate(pts)
                ax.scatter(
                    p[:, 0],
                    p[:, 1],
                    s=9,
                    marker=markers[f],
                    color=colours[f],
                    label=f"{_LEG_NAMES.get(LEGS[f], LEGS[f])} foot at a step start",
                )
        n_steps = sum(r.steps for r in records if r.terrain == name)
        dirs = sorted({r.direction_deg for r in records if r.terrain == name})
        ax.set_title(f"{name}: {n_steps} steps\ncrossed at {', '.join(f'{d:g}°' for d in dirs)}")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.15), ncol=2, fontsize=8)
    fig.suptitle("LittleDog demonstrations: where each foot stood when a step started")
    path = Path(out_dir) / "littledog_demo_footholds.png"
    fig.savefig(path, dpi=110)
    lines = [
        "| terrain | direction (deg) | steps | max slip (mm) | min clearance (cm) | fell |",
        "|---|---|---|---|---|---|",
    ]
    for r in records:
        lines.append(
            f"| {r.terrain} | {r.direction_deg:g} | {r.steps} | {1000 * r.slip_m:.1f} "
            f"| {100 * r.min_clearance_m:.1f} | {r.fell} |"
        )
    lines.append(
        f"| all | | {sum(r.steps for r in records)} | "
        f"{1000 * max((r.slip_m for r in records), default=math.nan):.1f} | | "
        f"{sum(r.fell for r in records)} fell |"
    )
    table = Path(out_dir) / "littledog_demos.md"
    table.write_text("\n".join(lines) + "\n")
    return {"footholds": path, "table": table}


def demo_config() -> LittleDogDemoConfig:
    """All seven crossings (about 170 steps' worth of recording, a minute of wall time)."""
    return LittleDogDemoConfig()


def smoke_config() -> LittleDogDemoConfig:
    """Two steps of the first crossing only."""
    return LittleDogDemoConfig(terrains=["terrain_a"], max_steps=2)


register_study(
    "littledog_demos",
    config_type=LittleDogDemoConfig,
    record_type=LittleDogDemoRecord,
    run_episode=run_episode,
    description="LittleDog scripted demonstrations: steps, slip and falls per terrain crossing",
    summarize=summarize,
    demo_config=demo_config,
    demo_episodes=7,
    smoke_config=smoke_config,
).run_if_main(__name__)
