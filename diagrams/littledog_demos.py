"""Demonstrations for the LittleDog step library: scripted crossings recorded in physics.

The scripted operator (:func:`~repertoire.planning.littledog_crawl.choose_footholds`)
picks footholds across a terrain; the crawl
(:func:`~repertoire.planning.littledog_crawl.plan_crawl`) turns them into joint
commands; :func:`record_crossing` plays them into the plant's PD, records every
10 ms the commanded joint angles, the measured body pose, foot positions and
contact flags, and cuts the recording into steps
(:func:`~repertoire.planning.step_library.segment_recording`).

The library terrains (:data:`LIBRARY_TERRAINS`) follow the paper's set-up: two
terrains of two rough boards each (0.4 m x 0.8 m rocks boards side by side, so an
0.8 m square), one crossed in four directions and one in three.
"""

import dataclasses
import math
import time

import numpy as np
from repertoire.diagrams.littledog import LittleDogScenario, standing_pose
from repertoire.diagrams.littledog_worlds import (
    PlantSettings,
    build_crawl_playback,
    joint_positions,
)
from repertoire.diagrams.simulate import simulate
from repertoire.models.littledog.pose import rpy_from_rotation
from repertoire.models.terrain import TerrainBoard, TerrainParams, generate_board, join_boards
from repertoire.planning.littledog_crawl import (
    CrawlParams,
    choose_footholds,
    foothold_ok,
    plan_crawl,
)
from repertoire.planning.step_library import LibraryStep, StepLibrary, segment_recording
from repertoire.systems.littledog_sensors import body_pose_from_positions, feet_in_world

from repertoire.errors import RepertoireError


@dataclasses.dataclass
class LibraryTerrain:
    """A terrain of boards side by side along x, and the directions it is crossed in.

    Attributes:
        name: terrain name (stored with every step).
        board: generator parameters of each board.
        seeds: one generator seed per board.
        directions_deg: crossing directions (yaw, degrees).
        half_extent: start / goal distance from the centre along the direction (m).
    """

    name: str
    board: TerrainParams
    seeds: list[int]
    directions_deg: list[float]
    half_extent: float = 0.25

    def build(self) -> TerrainBoard:
        """The joined terrain (boards centred along x, touching)."""
        if not self.seeds:
            raise RepertoireError(f"terrain {self.name}: needs at least one board seed")
        n = len(self.seeds)
        xs = (np.arange(n) - 0.5 * (n - 1)) * self.board.size_x
        boards = [generate_board(self.board, int(s)) for s in self.seeds]
        return join_boards(boards, np.column_stack([xs, np.zeros(n)]))


def _rough_board() -> TerrainParams:
    return TerrainParams(kind="rocks", size_x=0.4, size_y=0.8, rock_count=12)


LIBRARY_TERRAINS: dict[str, LibraryTerrain] = {
    "terrain_a": LibraryTerrain("terrain_a", _rough_board(), [11, 12], [0.0, 90.0, 180.0, 270.0]),
    "terrain_b": LibraryTerrain("terrain_b", _rough_board(), [21, 22], [0.0, 90.0, 180.0]),
}
"""The two source terrains of the library (4 + 3 crossings)."""


def library_terrain(name: str) -> LibraryTerrain:
    """A terrain of :data:`LIBRARY_TERRAINS` by name (clear error for an unknown one)."""
    if name not in LIBRARY_TERRAINS:
        raise RepertoireError(
            f"unknown library terrain {name!r}; expected one of {sorted(LIBRARY_TERRAINS)}"
        )
    return LIBRARY_TERRAINS[name]


def crossing_start(
    board: TerrainBoard,
    heading: float,
    half_extent: float,
    standing_height: float,
    offset_xy=(0.0, 0.0),
    yaw_offset: float = 0.0,
):
    """Standing pose at ``-half_extent`` along ``heading`` (plus offsets), as (pose6, feet, q)."""
    d = np.array([math.cos(heading), math.sin(heading)])
    xy = -half_extent * d + np.asarray(offset_xy, dtype=float)
    scenario = LittleDogScenario(
        base_xy=[float(xy[0]), float(xy[1])],
        base_yaw=float(heading + yaw_offset),
        standing_height=standing_height,
    )
    sp = standing_pose(scenario, board)
    pose = np.r_[sp.X_WB.translation(), rpy_from_rotation(sp.X_WB.rotation().matrix())]
    return pose, sp.p_WF, sp.q_joints


def stance_slip(slip_speed: np.ndarray, contact: np.ndarray, dt: float) -> float:
    """Largest distance a foot slides during one stance interval (m).

    The contacts' tangential sliding speed is integrated over each interval with
    the foot down (rolling of the foot sphere is not sliding and is not counted).

    Args:
        slip_speed: sliding speed of each foot's contact (N x 4, m/s).
        contact: contact flags (N x 4).
        dt: sample period (s).
    """
    worst = 0.0
    for f in range(4):
        down = np.concatenate([[0], (np.asarray(contact)[:, f] != 0).astype(int), [0]])
        edges = np.flatnonzero(np.diff(down))
        for a, b in zip(edges[::2], edges[1::2]):
            worst = max(worst, float(np.sum(slip_speed[a:b, f]) * dt))
    return worst


def flat_start(board: TerrainBoard, heading: float, half_extent: float, params: CrawlParams):
    """The start offset (within 6 cm, nearest first) that puts all four feet on flat spots."""
    g = np.arange(-6, 7) * 0.01
    offsets = sorted(((x, y) for x in g for y in g), key=lambda o: o[0] ** 2 + o[1] ** 2)
    for off in offsets:
        _, feet, _ = crossing_start(board, heading, half_extent, params.standing_height, off)
        if np.all(foothold_ok(board, feet[:, :2], params)):
            return np.array(off)
    raise RepertoireError(
        f"no flat start within 6 cm of {-half_extent} m along heading {heading:.2f} rad"
    )


@dataclasses.dataclass
class CrossingRecord:
    """One recorded crossing.

    Attributes:
        steps: the segmented library steps.
        times, body_pose, feet, contact: the recording (N, N x 6, N x 4 x 3, N x 4).
        slip_m: largest stance slip (m).
        min_clearance_m: lowest body height above the terrain under it (m).
        fell: True if the body tilted over 0.5 rad or came within 4 cm of the terrain.
        wall_s: wall time of the simulation (s).
    """

    steps: list[LibraryStep]
    times: np.ndarray
    body_pose: np.ndarray
    feet: np.ndarray
    contact: np.ndarray
    slip_m: float
    min_clearance_m: float
    fell: bool
    wall_s: float


def record_crossing(
    terrain: LibraryTerrain,
    direction_deg: float,
    params: CrawlParams | None = None,
    settings: PlantSettings | None = None,
    *,
    max_steps: int | None = None,
) -> CrossingRecord:
    """Crosses ``terrain`` along ``direction_deg`` in physics and records the steps.

    Args:
        terrain: the library terrain.
        direction_deg: crossing direction (degrees).
        params: crawl parameters.
        settings: physics settings.
        max_steps: keep only the first steps of the crossing (a short recording for tests).

    Raises:
        RepertoireError: no crossable path (from the foothold choice), or a recording
            without a complete step.
    """
    params = CrawlParams() if params is None else params
    board = terrain.build()
    heading = math.radians(direction_deg)
    offset = flat_start(board, heading, terrain.half_extent, params)
    pose0, feet0, _ = crossing_start(
        board, heading, terrain.half_extent, params.standing_height, offset
    )
    steps = choose_footholds(board, feet0, heading, terrain.half_extent - 0.02, params)
    if max_steps is not None:
        steps = steps[:max_steps]
    plan = plan_crawl(feet0, pose0, steps, board, params)
    diagram = build_crawl_playback(board, plan, settings)
    start = time.perf_counter()
    _, context = simulate(diagram, plan.duration + 0.3)
    wall = time.perf_counter() - start
    plant = diagram.GetSubsystemByName("plant")
    log = diagram.GetSubsystemByName("state_log").FindLog(context)
    clog = diagram.GetSubsystemByName("contact_log").FindLog(context)
    n = min(log.num_samples(), clog.num_samples())
    X = log.data().T[:n]
    times = log.sample_times()[:n]
    body = body_pose_from_positions(X[:, :7])
    q_meas = joint_positions(
        plant, plant.GetModelInstanceByName("littledog"), X[:, : plant.num_positions()]
    )
    feet = np.stack([feet_in_world(p, q) for p, q in zip(body, q_meas)])
    contact = clog.data().T[:n]
    slip_speed = diagram.GetSubsystemByName("slip_log").FindLog(context).data().T[:n]
    k = np.minimum(np.round(times / params.dt).astype(int), len(plan.q) - 1)
    q_cmd = plan.q[k]
    lib_steps = segment_recording(
        times, q_cmd, body, feet, contact, terrain=terrain.name, direction=heading
    )
    ground = board.height(body[:, 0], body[:, 1])
    clearance = float(np.min(body[:, 2] - ground))
    tilt = float(np.max(np.abs(body[:, 3:5])))
    return CrossingRecord(
        steps=lib_steps,
        times=times,
        body_pose=body,
        feet=feet,
        contact=contact,
        slip_m=stance_slip(slip_speed, contact, 0.01),
        min_clearance_m=clearance,
        fell=bool(tilt > 0.5 or clearance < 0.04),
        wall_s=wall,
    )


def library_crossings(names: list[str] | None = None) -> list[tuple[str, float]]:
    """``(terrain, direction_deg)`` of every crossing of the named terrains (default all)."""
    return [
        (name, direction)
        for name in names or sorted(LIBRARY_TERRAINS)
        for direction in library_terrain(name).directions_deg
    ]


def record_library(names: list[str] | None = None, **kwargs) -> tuple[StepLibrary, list[dict]]:
    """Records every crossing of the named terrains (default all) into one library.

    Returns:
        ``(library, summaries)``: one summary dict per crossing (terrain, direction,
        steps, slip, fell, wall time).
    """
    steps, summaries = [], []
    for name, direction in library_crossings(names):
        rec = record_crossing(library_terrain(name), direction, **kwargs)
        steps += rec.steps
        summaries.append(
            dict(
                terrain=name,
                direction_deg=direction,
                steps=len(rec.steps),
                slip_m=rec.slip_m,
                fell=rec.fell,
                wall_s=rec.wall_s,
            )
        )
    return StepLibrary(steps), summaries


__all__ = [
    "LIBRARY_TERRAINS",
    "CrossingRecord",
    "LibraryTerrain",
    "crossing_start",
    "library_crossings",
    "library_terrain",
    "record_crossing",
    "record_library",
    "stance_slip",
]
