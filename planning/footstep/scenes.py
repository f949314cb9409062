"""Seeded scenes of the paper's experiments: random static floors and the strings scene.

Static (Sec. IV-B): a 3 m x 3 m floor with 2.5 cm cells, flat obstacles (long thin strips
a biped steps over and a few larger blocks), start and goal in opposite corners.
Dynamic (Sec. IV-C, Fig. 5): two rows of blocks joined by strings pulled sideways (first
row at 0.18 m/s); the strings span the floor, so the start and goal regions are
disconnected for a wheeled robot, and the phases of the rows are random.
"""

import dataclasses
import math

import numpy as np
from repertoire.planning.footstep.environment import (
    DynamicEnvironment,
    MovingRectObstacle,
    OccupancyGrid,
    RectObstacle,
    rect_overlaps_cells,
)
from repertoire.planning.footstep.types import FootstepError, GridError

from repertoire.checks import is_real, is_whole


def _seeded(seed: int) -> np.random.Generator:
    """The generator of a scene's seed: an integer >= 0 (``None`` would not reproduce)."""
    if not is_whole(seed) or seed < 0:
        raise FootstepError(f"a scene seed must be an integer >= 0, got {seed!r}")
    return np.random.default_rng(int(seed))


@dataclasses.dataclass
class StaticScene:
    """A static planning problem.

    Attributes:
        grid: the occupancy grid.
        obstacles: the rectangles that were rasterised.
        start: ``(x, y, yaw)`` of the starting stance foot.
        start_foot: the starting stance foot ("left" or "right").
        goal: ``(x, y)``.
        body_start: ``(x, y)`` of the robot centre at the start (for the 2-D planner).
    """

    grid: OccupancyGrid
    obstacles: list[RectObstacle]
    start: tuple[float, float, float]
    start_foot: str
    goal: tuple[float, float]
    body_start: tuple[float, float]


@dataclasses.dataclass
class DynamicScene:
    """A dynamic planning problem.

    Attributes:
        env: time-indexed grids E(t).
        moving: the moving obstacles (blocks and strings).
        start: ``(x, y, yaw)`` of the starting stance foot.
        start_foot: the starting stance foot.
        goal: ``(x, y)``.
        body_start: ``(x, y)`` of the robot centre at the start.
        rows_y: y of the two rows.
    """

    env: DynamicEnvironment
    moving: list[MovingRectObstacle]
    start: tuple[float, float, float]
    start_foot: str
    goal: tuple[float, float]
    body_start: tuple[float, float]
    rows_y: list[float]


def _disc_clear(rect: RectObstacle, center: tuple[float, float], radius: float) -> bool:
    probe = np.array([[center[0], center[1]]])
    half = (rect.size[0] / 2 + radius, rect.size[1] / 2 + radius)
    return not rect_overlaps_cells(rect.center, half, rect.yaw, probe, 0.0)[0]


def random_static_scene(
    seed: int,
    *,
    size: float = 3.0,
    resolution: float = 0.025,
    n_strips: int = 4,
    n_blocks: int = 2,
    strip_length: tuple[float, float] = (0.6, 1.8),
    strip_width: tuple[float, float] = (0.03, 0.12),
    block_size: tuple[float, float] = (0.2, 0.5),
    corner_margin: float = 0.35,
    clear_radius: float = 0.45,
) -> StaticScene:
    """A random floor of flat obstacles with start and goal in opposite corners.

    The obstacles are 2 cm high: the grid carries their heights (a 2.5-D map), so a
    planner with a swing clearance above 2 cm steps over them.

    Args:
        seed: random seed.
        size: side of the square floor (m).
        resolution: cell side (m).
        n_strips: long thin flat obstacles (a wheeled robot must go around them).
        n_blocks: larger blocks.
        strip_length: range of strip lengths (m).
        strip_width: range of strip widths (m).
        block_size: range of block sides (m).
        corner_margin: distance of the start and goal from the walls (m).
        clear_radius: no obstacle comes closer than this to the start and goal (m).
    """
    rng = _seeded(seed)
    start_xy = (corner_margin, corner_margin)
    goal = (size - corner_margin, size - corner_margin)
    rects: list[RectObstacle] = []
    wanted = [("strip", n_strips), ("block", n_blocks)]
    for kind, count in wanted:
        placed = 0
        tries = 0
        while placed < count and tries < 200 * max(count, 1):
            tries += 1
            if kind == "strip":
                dims = [rng.uniform(*strip_length), rng.uniform(*strip_width)]
            else:
                dims = [rng.uniform(*block_size), rng.uniform(*block_size)]
            rect = RectObstacle(
                center=[float(v) for v in rng.uniform(0.2 * size, 0.8 * size, 2)]
                if kind == "block"
                else [float(v) for v in rng.uniform(0.1 * size, 0.9 * size, 2)],
                size=[float(d) for d in dims],
                yaw=float(rng.uniform(0, math.pi)),
                height=0.02,
            )
            if _disc_clear(rect, start_xy, clear_radius) and _disc_clear(rect, goal, clear_radius):
                rects.append(rect)
                placed += 1
    grid = OccupancyGrid.from_rectangles((size, size), rects, resolution, with_heights=True)
    yaw = math.atan2(goal[1] - start_xy[1], goal[0] - start_xy[0])
    # left foot stands, the right foot beside it; the body centre is between them
    half_w = 0.095
    start = (start_xy[0] - half_w * math.sin(yaw), start_xy[1] + half_w * math.cos(yaw), yaw)
    return StaticScene(grid, rects, start, "left", goal, start_xy)


def strings_scene(
    seed: int,
    *,
    size: float = 3.0,
    resolution: float = 0.025,
    rows_y: tuple[float, float] = (1.1, 1.9),
    speeds: tuple[float, float] = (0.18, 0.12),
    spacings: tuple[float, float] = (0.9, 1.2),
    block_size: tuple[float, float] = (0.30, 0.20),
    string_width: float = 0.02,
    t_end: float = 40.0,
    dt: float = 0.1,
) -> DynamicScene:
    """The paper's Fig. 5 scene with random phases of the two rows.

    The blocks are 2 cm and the strings 5 mm high; every grid of E(t) carries them.

    Args:
        seed: random seed (phases of the rows).
        size: side of the square floor (m).
        resolution: cell side (m).
        rows_y: y of the two rows (m).
        speeds: speeds of the rows along +x (m/s; negative: along -x); the first is the
            paper's 0.18.
        spacings: centre distance between blocks in each row (m).
        block_size: block length (along the row) and depth (m).
        string_width: width of the strings (m); the robot may not step on them.
        t_end: last grid time (s).
        dt: grid time spacing (s).
    """
    if not len(rows_y) == len(speeds) == len(spacings):
        raise GridError(
            f"rows_y, speeds and spacings need one value per row, got {len(rows_y)}, "
            f"{len(speeds)} and {len(spacings)}"
        )
    for k, (v, sp) in enumerate(zip(speeds, spacings)):
        if not (is_real(v) and math.isfinite(v)):
            raise GridError(f"speeds[{k}] must be a finite number (m/s), got {v!r}")
        if not (is_real(sp) and math.isfinite(sp) and sp > 0):
            raise GridError(f"spacings[{k}] must be a positive number (m), got {sp!r}")
    rng = _seeded(seed)
    moving: list[MovingRectObstacle] = []
    for y, v, sp in zip(rows_y, speeds, spacings):
        phase = float(rng.uniform(0.0, sp))
        # blocks from wherever one enters the floor by t_end, whichever way the row moves
        travel = abs(v) * t_end
        x = -(travel if v > 0 else 0.0) - sp + phase
        while x < size + sp + (travel if v < 0 else 0.0):
            moving.append(MovingRectObstacle([x, y], list(block_size), [v, 0.0]))
            x += sp
        # the string: long enough to span the floor over the whole horizon
        length = size + 2 * (travel + 2 * sp)
        moving.append(
            MovingRectObstacle([size / 2.0, y], [length, string_width], [v, 0.0], height=0.005)
        )
    env = DynamicEnvironment.from_moving_obstacles(
        (size, size), moving=moving, t_end=t_end, dt=dt, resolution=resolution, with_heights=True
    )
    body = (size / 2.0, 0.4)
    start = (body[0] - 0.095, body[1], math.pi / 2)  # left foot, facing +y
    goal = (size / 2.0, size - 0.4)
    return DynamicScene(env, moving, start, "left", goal, body, list(rows_y))


def stepping_stones_grid(
    seed: int,
    gap: float,
    *,
    stone_length: tuple[float, float] = (0.22, 0.30),
    resolution: float = 0.01,
) -> OccupancyGrid:
    """A 2 m x 0.8 m room of stepping stones: floor for x < 0.4 m and x >= 1.6 m.

    Between, stones 0.6 m wide (y in [0.1, 0.7] m) of a random length in
    ``stone_length`` follow each other ``gap`` apart along x; everything else is
    occupied. Start at (0.2, 0.45), goal at (1.8, 0.4) suit it.

    Args:
        seed: seed of the stone lengths.
        gap: free-of-footholds gap between stones along x (m), >= 0.
        stone_length: [min, max] stone length along x (m).
        resolution: cell side (m).

    Raises:
        GridError: negative gap, bad stone lengths or resolution.
    """
    if not (math.isfinite(gap) and gap >= 0.0):
        raise GridError(f"stepping-stone gap must be >= 0 m, got {gap}")
    lo, hi = stone_length
    if not (0.0 < lo <= hi and math.isfinite(hi)):
        raise GridError(f"stone_length must be [min, max] with 0 < min <= max, got {stone_length}")
    if not (math.isfinite(resolution) and 0.0 < resolution <= 0.1):
        raise GridError(f"stepping-stone resolution must be in (0, 0.1] m, got {resolution}")
    rng = _seeded(seed)
    nx, ny = int(round(2.0 / resolution)), int(round(0.8 / resolution))
    occ = np.ones((nx, ny), dtype=bool)
    occ[: int(round(0.4 / resolution)), :] = False
    occ[int(round(1.6 / resolution)) :, :] = False
    y0, y1 = int(round(0.1 / resolution)), int(round(0.7 / resolution))
    x = 0.40
    while x < 1.6:
        w = rng.uniform(lo, hi)
        occ[int(x / resolution) : int((x + w) / resolution), y0:y1] = False
        x += w + gap
    return OccupancyGrid(occ, resolution)


def maze_grid(
    seed: int,
    *,
    size: float = 6.0,
    cells: int = 4,
    door: float = 0.5,
    wall: float = 0.3,
    resolution: float = 0.025,
) -> OccupancyGrid:
    """A seeded maze on a square floor: ``cells`` x ``cells`` rooms, ``door``-wide doorways.

    The rooms form a spanning tree (randomised depth-first search), so every room is
    reachable; each tree edge gets one doorway at a random position along the wall.
    Walls are ``wall`` thick (thicker than a biped's step, so it uses the doorways);
    the outer boundary is walled too. Start near (0.5, 0.5), goal near (size-0.5, size-0.5).

    Args:
        seed: maze seed.
        size: floor side (m).
        cells: rooms per side (>= 2).
        door: doorway width (m), smaller than a room.
        wall: wall thickness (m).
        resolution: cell side of the grid (m).

    Raises:
        GridError: sizes that do not fit (door wider than a room, non-positive values).
    """
    values = (size, door, wall, resolution)
    if not all(math.isfinite(v) and v > 0.0 for v in values):
        raise GridError(f"maze size, door, wall and resolution must be positive, got {values}")
    if int(cells) != cells or cells < 2:
        raise GridError(f"maze cells must be an integer >= 2, got {cells}")
    room = size / cells
    if door + 2.0 * wall >= room:
        raise GridError(f"maze door {door} m plus walls {wall} m do not fit a {room:.2f} m room")
    rng = _seeded(seed)
    n = int(round(size / resolution))
    occ = np.zeros((n, n), dtype=bool)

    def fill(x0: float, x1: float, y0: float, y1: float, value: bool) -> None:
        i0, i1 = max(int(x0 / resolution), 0), min(int(math.ceil(x1 / resolution)), n)
        j0, j1 = max(int(y0 / resolution), 0), min(int(math.ceil(y1 / resolution)), n)
        occ[i0:i1, j0:j1] = value

    h = wall / 2.0
    for k in range(cells + 1):
        c = k * room
        fill(c - h, c + h, 0.0, size, True)  # walls x = c
        fill(0.0, size, c - h, c + h, True)  # walls y = c
    seen = {(0, 0)}
    stack = [(0, 0)]
    while stack:
        i, j = stack[-1]
        nbrs = [
            (i + di, j + dj)
            for di, dj in ((1, 0), (-1, 0), (0, 1), (0, -1))
            if 0 <= i + di < cells and 0 <= j + dj < cells and (i + di, j + dj) not in seen
        ]
        if not nbrs:
            stack.pop()
            continue
        a, b = nbrs[rng.integers(len(nbrs))]
        along = rng.uniform(wall, room - wall - door)
        if a != i:  # door in the wall x = max(i, a) * room
            c = max(i, a) * room
            fill(c - h, c + h, j * room + along, j * room + along + door, False)
        else:  # door in the wall y = max(j, b) * room
            c = max(j, b) * room
            fill(i * room + along, i * room + along + door, c - h, c + h, False)
        seen.add((a, b))
        stack.append((a, b))
    return OccupancyGrid(occ, resolution)


def random_floor_scene(
    seed: int,
    *,
    size: float = 12.0,
    occupancy: float = 0.30,
    resolution: float = 0.025,
    block_size: tuple[float, float] = (0.1, 0.6),
    height: tuple[float, float] = (0.02, 0.30),
    clear_radius: float = 0.5,
) -> StaticScene:
    """A large floor covered to ``occupancy`` by axis-aligned blocks of random heights.

    Blocks of side in ``block_size`` and height in ``height`` (a 2.5-D map: low ones can be
    stepped over, tall ones need a way around when the planner has a swing clearance) are
    dropped until the occupied fraction reaches ``occupancy``, keeping discs of
    ``clear_radius`` around the start (0.6 m from the low corner) and the goal (0.6 m from
    the far edge, at a random y), 9-12 m apart on the default floor.

    Args:
        seed: random seed.
        size: side of the square floor (m).
        occupancy: occupied fraction to reach, in [0, 0.6].
        resolution: cell side (m).
        block_size: range of block sides (m).
        height: range of block heights (m).
        clear_radius: obstacle-free radius around start and goal (m).

    Raises:
        GridError: an occupancy outside [0, 0.6] or a floor too small for its margins.
    """
    if not (math.isfinite(occupancy) and 0.0 <= occupancy <= 0.6):
        raise GridError(f"floor occupancy must be in [0, 0.6], got {occupancy}")
    if not (math.isfinite(size) and size >= 4.0 * clear_radius + 1.2):
        raise GridError(f"floor size {size} m is too small for clear_radius {clear_radius} m")
    rng = _seeded(seed)
    n = int(round(size / resolution))
    occ = np.zeros((n, n), dtype=bool)
    heights = np.zeros((n, n))
    start_xy = (0.6, 0.6)
    goal = (size - 0.6, float(rng.uniform(0.25 * size, size - 0.6)))
    centers = (np.arange(n) + 0.5) * resolution
    keep = np.zeros((n, n), dtype=bool)
    for px, py in (start_xy, goal):
        keep |= np.hypot(centers[:, None] - px, centers[None, :] - py) <= clear_radius
    target = occupancy * n * n
    while occ.sum() < target:
        w, h = (rng.uniform(*block_size, 2) / resolution).astype(int) + 1
        i, j = rng.integers(0, n - w), rng.integers(0, n - h)
        if keep[i : i + w, j : j + h].any():
            continue
        occ[i : i + w, j : j + h] = True
        heights[i : i + w, j : j + h] = rng.uniform(*height)
    grid = OccupancyGrid(occ, resolution, (0.0, 0.0), heights)
    yaw = math.atan2(goal[1] - start_xy[1], goal[0] - start_xy[0])
    half_w = 0.095
    start = (start_xy[0] - half_w * math.sin(yaw), start_xy[1] + half_w * math.cos(yaw), yaw)
    return StaticScene(grid, [], start, "left", goal, start_xy)
