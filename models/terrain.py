"""LittleDog-style terrain boards built from boxes, with their exact height function.

Drake has no height-field shape, and a mesh collapses to its convex hull under
point contact, so a board is a list of boxes (each with a yaw about the world
z axis and no roll or pitch). The generator is seeded and returns a typed
:class:`TerrainBoard` that can add itself to a MultibodyPlant, write an SDF
file, and give the exact height ``z(x, y)`` of what it built.

Conventions (world frame W, z up):

- the world ground is z = 0 everywhere (a thin 6 m x 6 m box with its top at z = 0
  when added; a box, not a HalfSpace, so that every query type supports it);
- the board covers ``[-size_x/2, size_x/2] x [-size_y/2, size_y/2]``, centred on
  the origin, LittleDog walking along +x;
- the board's base slab has its top at ``z = base_thickness``; a *gap* is a strip
  of missing slab (full board width), so inside a gap and outside the board the
  height is the ground, 0: the gap depth is ``base_thickness``;
- every other box (rock, step) stands on the ground (its bottom at z = 0), so
  each vertical column is solid from the ground up to ``z(x, y)``;
- a board's extent is what its boxes cover (:meth:`TerrainBoard.bounds`, the
  bounding rectangle of their footprints), not its ``params``: a moved
  (:meth:`TerrainBoard.translated`) or joined (:func:`join_boards`) board keeps
  the parameters it was generated from, but its boxes lie elsewhere.

Kinds: ``flat`` (slab only), ``rocks`` (slab plus yawed boxes of random size
and height), ``steps`` (bands across x at rising and falling heights),
``gaps`` (slab strips separated by gaps across the board), ``mixed`` (the board
cut along x into sections: the first flat, the others rocks/steps/gaps at random).
"""

import dataclasses
import math
from pathlib import Path
from xml.sax.saxutils import escape

import numpy as np

from repertoire.errors import RepertoireError
from repertoire.limits import require_memory

BOARD_KINDS: list[str] = ["flat", "rocks", "steps", "gaps", "mixed"]

_COLORS = {
    "slab": (0.78, 0.70, 0.55, 1.0),
    "rock": (0.50, 0.48, 0.45, 1.0),
    "step": (0.62, 0.52, 0.40, 1.0),
    "ground": (0.85, 0.85, 0.85, 1.0),
}

GROUND_SIZE: list[float] = [6.0, 6.0, 0.2]
"""Size of the ground box (m); its top face is z = 0 and it is centred on the origin."""


def _ground_box() -> "TerrainBox":
    return TerrainBox([0.0, 0.0, -0.5 * GROUND_SIZE[2]], list(GROUND_SIZE), 0.0, "ground")


def _is_count(value) -> bool:
    """True for a non-negative integer (an int or an integral finite float)."""
    try:
        return math.isfinite(value) and int(value) == value and value >= 0
    except (TypeError, ValueError):
        return False


@dataclasses.dataclass
class TerrainParams:
    """Parameters of the board generator (YAML-loadable: lists, not tuples).

    Attributes:
        kind: one of ``flat``, ``rocks``, ``steps``, ``gaps``, ``mixed``.
        size_x: board length along x (m).
        size_y: board width along y (m).
        base_thickness: height of the slab top above the ground (m); also the gap depth.
        rock_count: number of rocks on a ``rocks`` board (scaled by area in ``mixed``).
        rock_size: [min, max] side length of a rock's footprint (m).
        rock_height: [min, max] height of a rock's top above the slab (m).
        step_count: number of step bands on a ``steps`` board (after a flat start band).
        step_rise: [min, max] height change between neighbouring bands (m); the sign
            is random, heights never go below the slab.
        gap_count: number of gaps on a ``gaps`` board.
        gap_width: [min, max] width of a gap along x (m).
        mixed_sections: number of sections along x of a ``mixed`` board.

    Every combination :meth:`validate` accepts generates boxes of positive size inside
    the board, for every seed. Two limits follow from the geometry:

    - a rock whose yawed footprint would not fit its region (a ``mixed`` section along x,
      or ``size_y`` across: a square rock of side 0.10 m yawed by 45 degrees spans 0.14 m)
      is scaled down, keeping its proportions, to 95 % of the region; ``rock_size`` is
      the size before that scaling, and ``validate`` only asks that its max be smaller
      than the board (an unyawed rock fits);
    - a gap cannot be scaled without changing what was asked, so a board on which a gap
      could leave too little slab is refused: ``gaps`` needs
      ``gap_count * gap_width max < 0.8 * size_x``, ``mixed`` (one gap in a gap section
      of length ``size_x / mixed_sections``) needs
      ``gap_width max < 0.8 * size_x / mixed_sections``.
    """

    kind: str = "flat"
    size_x: float = 0.6
    size_y: float = 0.6
    base_thickness: float = 0.04
    rock_count: int = 14
    rock_size: list[float] = dataclasses.field(default_factory=lambda: [0.04, 0.10])
    rock_height: list[float] = dataclasses.field(default_factory=lambda: [0.01, 0.04])
    step_count: int = 4
    step_rise: list[float] = dataclasses.field(default_factory=lambda: [0.015, 0.035])
    gap_count: int = 2
    gap_width: list[float] = dataclasses.field(default_factory=lambda: [0.03, 0.07])
    mixed_sections: int = 4

    def validate(self) -> None:
        """Checks every field.

        Raises:
            RepertoireError: naming the field, its value and what is expected.
        """
        if self.kind not in BOARD_KINDS:
            raise RepertoireError(
                f"unknown terrain board kind '{self.kind}'; expected one of {BOARD_KINDS}"
            )
        for name in ("size_x", "size_y", "base_thickness"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise RepertoireError(f"terrain {name} must be a positive length, got {value}")
        for name in ("rock_count", "step_count", "gap_count", "mixed_sections"):
            value = getattr(self, name)
            if not _is_count(value):
                raise RepertoireError(f"terrain {name} must be a non-negative integer, got {value}")
        if self.mixed_sections < 1:
            raise RepertoireError(f"terrain mixed_sections must be >= 1, got {self.mixed_sections}")
        for name in ("rock_size", "rock_height", "step_rise", "gap_width"):
            value = list(getattr(self, name))
            if (
                len(value) != 2
                or not all(math.isfinite(v) for v in value)
                or value[0] < 0.0
                or value[0] > value[1]
            ):
                raise RepertoireError(
                    f"terrain {name} must be a range [min, max] with 0 <= min <= max, got {value}"
                )
        if self.rock_size[0] <= 0.0:
            raise RepertoireError(f"terrain rock_size must be positive, got {self.rock_size}")
        if self.gap_width[1] * max(self.gap_count, 1) >= 0.8 * self.size_x:
            raise RepertoireError(
                f"terrain gaps ({self.gap_count} of up to {self.gap_width[1]} m) leave too little "
                f"board along size_x={self.size_x} m; expected gap_count*max width < 0.8*size_x"
            )
        if self.kind == "mixed" and self.mixed_sections >= 2:
            section = self.size_x / self.mixed_sections
            if self.gap_width[1] >= 0.8 * section:
                raise RepertoireError(
                    f"terrain kind 'mixed' with mixed_sections={self.mixed_sections} on "
                    f"size_x={self.size_x} m has sections of {section:.4g} m, too short for a gap "
                    f"of up to gap_width max {self.gap_width[1]} m; expected gap_width max < "
                    f"0.8*size_x/mixed_sections = {0.8 * section:.4g} m (use fewer sections, a "
                    f"longer board or narrower gaps)"
                )
        if self.rock_size[1] >= min(self.size_x, self.size_y):
            raise RepertoireError(
                f"terrain rock_size max {self.rock_size[1]} m must be smaller than the board "
                f"(size_x={self.size_x} m, size_y={self.size_y} m)"
            )


@dataclasses.dataclass
class TerrainBox:
    """One box of a board.

    Attributes:
        center: [x, y, z] of the box centre in the world frame (m).
        size: [sx, sy, sz] full side lengths (m), sx and sy before the yaw.
        yaw: rotation about the world z axis (rad).
        label: ``slab``, ``rock``, ``step`` or ``ground`` (used for colours and names).
    """

    center: list[float]
    size: list[float]
    yaw: float = 0.0
    label: str = "slab"

    @property
    def top(self) -> float:
        """Height of the box's top face (m)."""
        return self.center[2] + 0.5 * self.size[2]

    def contains_xy(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """True where (x, y) lies inside the box's footprint (closed set)."""
        dx, dy = x - self.center[0], y - self.center[1]
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        u = c * dx + s * dy
        v = -s * dx + c * dy
        eps = 1e-12
        return (np.abs(u) <= 0.5 * self.size[0] + eps) & (np.abs(v) <= 0.5 * self.size[1] + eps)

    def footprint_bounds(self) -> tuple[float, float, float, float]:
        """``(x_min, x_max, y_min, y_max)`` of the yawed footprint in the world (m)."""
        c, s = abs(math.cos(self.yaw)), abs(math.sin(self.yaw))
        ex = 0.5 * (c * self.size[0] + s * self.size[1])
        ey = 0.5 * (s * self.size[0] + c * self.size[1])
        return (
            self.center[0] - ex,
            self.center[0] + ex,
            self.center[1] - ey,
            self.center[1] + ey,
        )


@dataclasses.dataclass
class TerrainBoard:
    """A generated board: its boxes and the exact height function.

    Attributes:
        params: the parameters it was generated from.
        seed: the generator seed.
        boxes: the boxes (all welded to the world).
    """

    params: TerrainParams
    seed: int
    boxes: list[TerrainBox]

    @property
    def kind(self) -> str:
        return self.params.kind

    def bounds(self) -> tuple[float, float, float, float]:
        """The board's extent ``(x_min, x_max, y_min, y_max)`` in the world (m).

        The bounding rectangle of its boxes' footprints (a ``ground`` box, if one was
        put in ``boxes``, does not count), so it follows the boxes wherever
        :meth:`translated`, :func:`join_boards`, :func:`tile_boards` or
        :func:`replace_with_rocks` put them; ``params.size_x`` and ``size_y`` give it
        only for a board as generated (``[-size_x/2, size_x/2] x [-size_y/2,
        size_y/2]``, up to the rounding of the boxes' centres and sizes, about 1e-16 m).
        Bare ground between joined boards or in a gap lies inside the extent.

        Raises:
            RepertoireError: the board has no boxes other than ground.
        """
        boxes = [b.footprint_bounds() for b in self.boxes if b.label != "ground"]
        if not boxes:
            raise RepertoireError("terrain board has no boxes: it has no extent")
        lo, hi = np.min(boxes, axis=0), np.max(boxes, axis=0)
        return (float(lo[0]), float(hi[1]), float(lo[2]), float(hi[3]))

    def height(self, x, y) -> np.ndarray:
        """Exact terrain height z(x, y) in m (vectorised; broadcasts x and y).

        The ground (outside the board and inside gaps) has height 0. Each box is tested only
        on the points (sorted by x) within its footprint's x range: exact, and fast on rocks.

        Args:
            x: world x coordinates (m), any shape.
            y: world y coordinates (m), broadcastable with ``x``.
        """
        x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
            raise RepertoireError("terrain height query needs finite x and y")
        order = np.argsort(x, axis=None)  # ties in any order: each point on its own
        xs, ys, z = x.ravel()[order], y.ravel()[order], np.zeros(x.size)
        x0, x1 = (float(xs[0]) - 1e-9, float(xs[-1]) + 1e-9) if x.size else (np.inf, -np.inf)
        y0, y1 = ys.min(initial=np.inf) - 1e-9, ys.max(initial=-np.inf) + 1e-9
        for box in self.boxes:
            b = box.footprint_bounds()
            if b[0] <= x1 and b[1] >= x0 and b[2] <= y1 and b[3] >= y0:
                s = slice(*np.searchsorted(xs, (b[0] - 1e-9, b[1] + 1e-9)))
                z[s] = np.where(box.contains_xy(xs[s], ys[s]), np.maximum(z[s], box.top), z[s])
        out = np.empty(x.size)
        out[order] = z
        return out.reshape(x.shape)

    def height_grid(
        self,
        origin_xy,
        yaw: float = 0.0,
        *,
        length: float = 0.35,
        width: float = 0.20,
        resolution: float = 0.012,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Heights on a regular grid in a local frame L (origin, yaw about world z).

        The grid has ``floor(length / resolution)`` points along L's x axis and
        ``floor(width / resolution)`` along its y axis, spaced by ``resolution`` and
        centred on the origin. The defaults are the 29 x 16 = 464-point profile of
        Stolle et al.'s terrain features (0.35 m x 0.20 m at 0.012 m).

        Args:
            origin_xy: [x, y] of L's origin in the world (m).
            yaw: heading of L's x axis about world z (rad).
            length: grid extent along L's x axis (m).
            width: grid extent along L's y axis (m).
            resolution: grid spacing (m).

        Returns:
            ``(p_W, z)``: world (x, y) of the grid points, shape (n_y, n_x, 2), and
            the heights there, shape (n_y, n_x).

        Raises:
            RepertoireError: non-finite input, under one point per axis, or over memory.
        """
        origin = np.asarray(origin_xy, dtype=float)
        values = [length, width, resolution, yaw]
        if origin.shape != (2,) or not (
            np.all(np.isfinite(origin)) and np.all(np.isfinite(values))
        ):
            raise RepertoireError(
                f"height_grid needs a finite origin [x, y] and finite sizes, got {origin_xy!r}"
            )
        if resolution <= 0.0 or length < resolution or width < resolution:
            raise RepertoireError(
                f"height_grid needs resolution > 0 and length, width >= resolution; got "
                f"length={length}, width={width}, resolution={resolution}"
            )
        n_x, n_y = (int(math.floor(v / resolution + 1e-9)) for v in (length, width))
        require_memory(8.0 * 12 * n_x * n_y, f"a height grid of {n_x} x {n_y} points")  # ~12 arrays
        u = (np.arange(n_x) - 0.5 * (n_x - 1)) * resolution
        v = (np.arange(n_y) - 0.5 * (n_y - 1)) * resolution
        U, V = np.meshgrid(u, v)
        c, s = math.cos(yaw), math.sin(yaw)
        p_W = np.stack([origin[0] + c * U - s * V, origin[1] + s * U + c * V], axis=-1)
        return p_W, self.height(p_W[..., 0], p_W[..., 1])

    def translated(self, dx: float, dy: float) -> "TerrainBoard":
        """A copy with every box moved by ``(dx, dy)`` in the world x-y plane (m).

        The copy keeps ``params`` (what it was generated from); its extent is
        :meth:`bounds`, moved by ``(dx, dy)``.
        """
        if not (math.isfinite(dx) and math.isfinite(dy)):
            raise RepertoireError(f"board translation must be finite, got ({dx}, {dy})")
        boxes = [
            TerrainBox(
                [b.center[0] + dx, b.center[1] + dy, b.center[2]], list(b.size), b.yaw, b.label
            )
            for b in self.boxes
        ]
        return TerrainBoard(params=self.params, seed=self.seed, boxes=boxes)

    def max_height(self) -> float:
        """Highest box top (m)."""
        return max((b.top for b in self.boxes), default=0.0)

    def check_boxes(self) -> None:
        """Checks that every box has a finite centre and yaw and a positive, finite size.

        Drake's ``Box`` aborts the process (a ``SystemExit``, not an exception) on a
        non-positive size; this raises first.

        Raises:
            RepertoireError: naming the first bad box, its index and its size.
        """
        for i, box in enumerate(self.boxes):
            values = [*box.center, *box.size, box.yaw]
            if (
                len(box.center) != 3
                or len(box.size) != 3
                or not all(math.isfinite(v) for v in values)
                or min(box.size) <= 0.0
            ):
                raise RepertoireError(
                    f"terrain box {i} ({box.label}) needs a finite centre and yaw and a "
                    f"positive size, got centre={list(box.center)}, size={list(box.size)}, "
                    f"yaw={box.yaw}"
                )

    def add_to_plant(self, plant, *, name: str = "terrain", friction=None, ground: bool = True):
        """Welds the boxes (collision + visual) to the plant's world body.

        Call before ``plant.Finalize()``; the plant must have a SceneGraph.

        Args:
            plant: a ``MultibodyPlant`` registered with a SceneGraph.
            name: prefix of the geometry names (must be unique in the plant).
            friction: a ``CoulombFriction``; default static = dynamic = 1.0.
            ground: also add the ground box (top face z = 0).

        Returns:
            The list of collision GeometryIds (ground first when added).

        Raises:
            RepertoireError: a box of non-positive or non-finite size (:meth:`check_boxes`).
        """
        from pydrake.geometry import Box
        from pydrake.math import RigidTransform, RotationMatrix
        from pydrake.multibody.plant import CoulombFriction

        self.check_boxes()
        if friction is None:
            friction = CoulombFriction(1.0, 1.0)
        world = plant.world_body()
        ids = []
        if ground:
            X_WG = RigidTransform([0.0, 0.0, -0.5 * GROUND_SIZE[2]])
            shape = Box(*GROUND_SIZE)
            ids.append(
                plant.RegisterCollisionGeometry(world, X_WG, shape, f"{name}_ground", friction)
            )
            plant.RegisterVisualGeometry(
                world, X_WG, shape, f"{name}_ground_visual", np.asarray(_COLORS["ground"])
            )
        for i, box in enumerate(self.boxes):
            X_WB = RigidTransform(RotationMatrix.MakeZRotation(box.yaw), np.asarray(box.center))
            shape = Box(*box.size)
            gname = f"{name}_{box.label}_{i}"
            ids.append(plant.RegisterCollisionGeometry(world, X_WB, shape, gname, friction))
            plant.RegisterVisualGeometry(
                world, X_WB, shape, f"{gname}_visual", np.asarray(_COLORS[box.label])
            )
        return ids

    def sdf_text(self, *, model_name: str = "terrain_board", ground: bool = True) -> str:
        """SDFormat text of a static model with one link holding every box.

        Args:
            model_name: the SDF model name.
            ground: include the ground box (top face z = 0).

        Raises:
            RepertoireError: a box of non-positive or non-finite size (:meth:`check_boxes`).
        """
        self.check_boxes()
        lines = [
            '<?xml version="1.0"?>',
            '<sdf version="1.9" xmlns:drake="http://drake.mit.edu">',
            f'  <model name="{escape(model_name)}">',
            "    <static>true</static>",
            '    <link name="board">',
        ]
        friction = (
            "        <drake:proximity_properties>\n"
            "          <drake:mu_static>1.0</drake:mu_static>\n"
            "          <drake:mu_dynamic>1.0</drake:mu_dynamic>\n"
            "        </drake:proximity_properties>"
        )
        boxes = list(enumerate(self.boxes))
        if ground:
            boxes.insert(0, ("ground", _ground_box()))
        for i, box in boxes:
            pose = " ".join(f"{v:.9g}" for v in [*box.center, 0.0, 0.0, box.yaw])
            geom = "<box><size>" + " ".join(f"{v:.9g}" for v in box.size) + "</size></box>"
            rgba = " ".join(f"{v:g}" for v in _COLORS[box.label])
            gname = f"{box.label}_{i}" if box.label != "ground" else "ground"
            lines += [
                f'      <collision name="{gname}">',
                f"        <pose>{pose}</pose>",
                f"        <geometry>{geom}</geometry>",
                friction,
                "      </collision>",
                f'      <visual name="{gname}_visual">',
                f"        <pose>{pose}</pose>",
                f"        <geometry>{geom}</geometry>",
                f"        <material><diffuse>{rgba}</diffuse></material>",
                "      </visual>",
            ]
        lines += ["    </link>", "  </model>", "</sdf>", ""]
        return "\n".join(lines)

    def write_sdf(self, path: str | Path, **kwargs) -> Path:
        """Writes :meth:`sdf_text` to ``path`` (parent folders created) and returns it."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(self.sdf_text(**kwargs))
        return path


def _slab(x0: float, x1: float, p: TerrainParams) -> TerrainBox:
    t = p.base_thickness
    return TerrainBox([0.5 * (x0 + x1), 0.0, 0.5 * t], [x1 - x0, p.size_y, t], 0.0, "slab")


def _random_rock(x0: float, x1: float, p: TerrainParams, rng) -> TerrainBox:
    """One rock of random size, yaw and height inside ``[x0, x1]`` x the board's width.

    A rock whose yawed footprint does not fit the region (along x: a short ``mixed``
    section; along y: a narrow board, where a rock yawed by 45 degrees spans up to
    sqrt(2) times its side) is scaled down, keeping its proportions, to 95 % of the
    region along the axis it missed (the smaller scale when both).
    """
    sx, sy = rng.uniform(p.rock_size[0], p.rock_size[1], size=2)
    yaw = float(rng.uniform(0.0, math.pi))
    # Half extents of the yawed footprint, so the rock stays inside its region.
    ex = 0.5 * (abs(math.cos(yaw)) * sx + abs(math.sin(yaw)) * sy)
    ey = 0.5 * (abs(math.sin(yaw)) * sx + abs(math.cos(yaw)) * sy)
    scale = 1.0
    if 2.0 * ex >= x1 - x0:
        scale = 0.95 * (x1 - x0) / (2.0 * ex)
    if 2.0 * ey * scale >= p.size_y:
        scale = min(scale, 0.95 * p.size_y / (2.0 * ey))
    if scale != 1.0:
        sx, sy, ex, ey = sx * scale, sy * scale, ex * scale, ey * scale
    half_y = 0.5 * p.size_y
    cx = float(rng.uniform(x0 + ex, x1 - ex))
    cy = float(rng.uniform(-half_y + ey, half_y - ey))
    top = p.base_thickness + float(rng.uniform(p.rock_height[0], p.rock_height[1]))
    return TerrainBox([cx, cy, 0.5 * top], [float(sx), float(sy), top], yaw, "rock")


def _rocks(x0: float, x1: float, count: int, p: TerrainParams, rng) -> list[TerrainBox]:
    return [_slab(x0, x1, p)] + [_random_rock(x0, x1, p, rng) for _ in range(count)]


ROCK_FIELD_COVERAGE: float = 0.8
"""Default fraction of a rock field's slab covered by rocks (:func:`rock_field`)."""

MAX_ROCK_COVERAGE: float = 0.9
"""Highest coverage :func:`rock_field` accepts: rocks stay inside the slab, so its edges fill
ever more slowly (rocks of 4-10 cm on 0.35 m x 0.8 m: about 60 for 0.6, 200 for 0.8, 600 for
0.9, 3000 for 0.95)."""

COVERAGE_CELL: float = 0.005
"""Cell side of the grid on which :func:`rock_field` measures its coverage (m)."""


def rock_coverage(boxes: list[TerrainBox], x0: float, x1: float, size_y: float) -> float:
    """Fraction of ``[x0, x1] x [-size_y/2, size_y/2]`` under a rock of ``boxes``.

    Measured at the centres of a grid of :data:`COVERAGE_CELL` cells (the union of the
    rocks' footprints, overlaps counted once).
    """
    x, y = _coverage_grid(x0, x1, size_y)
    covered = np.zeros(x.shape, dtype=bool)
    for box in boxes:
        if box.label == "rock":
            covered |= box.contains_xy(x, y)
    return float(covered.mean())


def _coverage_grid(x0: float, x1: float, size_y: float) -> tuple[np.ndarray, np.ndarray]:
    nx = max(1, int(round((x1 - x0) / COVERAGE_CELL)))
    ny = max(1, int(round(size_y / COVERAGE_CELL)))
    xs = x0 + (np.arange(nx) + 0.5) * (x1 - x0) / nx
    ys = (np.arange(ny) + 0.5) * size_y / ny - 0.5 * size_y
    return np.meshgrid(xs, ys)


def rock_field(
    x0: float, x1: float, p: TerrainParams, seed: int, coverage: float = ROCK_FIELD_COVERAGE
) -> list[TerrainBox]:
    """A slab over ``[x0, x1]`` densely covered by rocks (a LittleDog rock board).

    Rocks of the sizes and heights of ``p`` (``rock_size``, ``rock_height``, random yaw)
    are dropped at random places on the slab, one after another, until the fraction of
    the slab's area under at least one rock (:func:`rock_coverage`) reaches
    ``coverage``; overlapping rocks make a field of flat tops at different heights, as
    on the rocky boards of Stolle et al.'s LittleDog terrains. The count therefore
    follows from the area, the rock sizes and the seed, and the coverage reached exceeds
    ``coverage`` by at most one rock's footprint over the slab's area.

    Args:
        x0, x1: the slab's extent along x (m), ``x0 < x1``; it spans the board's width.
        p: board parameters (``size_y``, ``base_thickness``, rock sizes and heights).
        seed: seed of ``np.random.default_rng``; the same arguments give the same field.
        coverage: target fraction of the slab under rocks, in
            ``[0, MAX_ROCK_COVERAGE]``; 0 gives the bare slab.

    Returns:
        The slab box followed by the rock boxes.

    Raises:
        RepertoireError: a coverage outside ``[0, MAX_ROCK_COVERAGE]`` or not finite, an
            empty extent, or a non-integer seed.
    """
    if not (math.isfinite(coverage) and 0.0 <= coverage <= MAX_ROCK_COVERAGE):
        raise RepertoireError(
            f"rock field coverage must be a fraction in [0, {MAX_ROCK_COVERAGE}], got {coverage}"
        )
    if not (math.isfinite(x0) and math.isfinite(x1) and x0 < x1):
        raise RepertoireError(f"rock field needs x0 < x1, got [{x0}, {x1}]")
    if not _is_count(seed):
        raise RepertoireError(f"rock field seed must be an integer, got {seed!r} (expected >= 0)")
    p.validate()
    rng = np.random.default_rng(int(seed))
    x, y = _coverage_grid(x0, x1, p.size_y)
    covered = np.zeros(x.shape, dtype=bool)
    boxes = [_slab(x0, x1, p)]
    # A guard, never reached with the board's rock sizes: 50 times the rocks of the
    # smallest size that would tile the slab.
    cap = 50 * int(math.ceil(covered.size * COVERAGE_CELL**2 / p.rock_size[0] ** 2)) + 10
    while covered.mean() < coverage:
        if len(boxes) > cap:
            raise RepertoireError(
                f"rock field: coverage {coverage} not reached with {cap} rocks "
                f"(reached {covered.mean():.3f}); rocks too small for the grid"
            )
        rock = _random_rock(x0, x1, p, rng)
        covered |= rock.contains_xy(x, y)
        boxes.append(rock)
    return boxes


def _steps(x0: float, x1: float, count: int, p: TerrainParams, rng) -> list[TerrainBox]:
    bands = count + 1
    edges = np.linspace(x0, x1, bands + 1)
    boxes = [_slab(edges[0], edges[1], p)]
    height = 0.0
    for i in range(1, bands):
        rise = float(rng.uniform(p.step_rise[0], p.step_rise[1]))
        sign = 1.0 if (height - rise < 0.0 or rng.random() < 0.6) else -1.0
        height = max(0.0, height + sign * rise)
        top = p.base_thickness + height
        boxes.append(
            TerrainBox(
                [0.5 * (edges[i] + edges[i + 1]), 0.0, 0.5 * top],
                [float(edges[i + 1] - edges[i]), p.size_y, top],
                0.0,
                "slab" if height == 0.0 else "step",
            )
        )
    return boxes


def _gaps(x0: float, x1: float, count: int, p: TerrainParams, rng) -> list[TerrainBox]:
    """Slab pieces over ``[x0, x1]`` separated by ``count`` gaps of ``p.gap_width``.

    :meth:`TerrainParams.validate` keeps ``count * gap_width max`` below 80 % of the
    length for every region this is called on, so every piece has a positive length.
    """
    if count == 0:
        return [_slab(x0, x1, p)]
    length = x1 - x0
    widths = rng.uniform(p.gap_width[0], p.gap_width[1], size=count)
    # Split the rest of the length into count + 1 slab pieces of random share.
    solid = length - widths.sum()
    shares = rng.uniform(0.6, 1.4, size=count + 1)
    pieces = solid * shares / shares.sum()
    boxes, x = [], x0
    for i in range(count + 1):
        boxes.append(_slab(x, x + pieces[i], p))
        x += pieces[i] + (widths[i] if i < count else 0.0)
    return boxes


def generate_board(params: TerrainParams | None = None, seed: int = 0) -> TerrainBoard:
    """Generates a board of ``params.kind`` with ``np.random.default_rng(seed)``.

    Args:
        params: generator parameters (validated here); default a flat board.
        seed: the random seed; the same (params, seed) always gives the same board.

    Raises:
        RepertoireError: invalid parameters (unknown kind, negative sizes, bad ranges).
    """
    params = TerrainParams() if params is None else params
    if not isinstance(params, TerrainParams):
        raise RepertoireError(f"generate_board needs TerrainParams, got {type(params).__name__}")
    params.validate()
    if not _is_count(seed):
        raise RepertoireError(f"terrain seed must be an integer, got {seed!r} (expected >= 0)")
    rng = np.random.default_rng(int(seed))
    x0, x1 = -0.5 * params.size_x, 0.5 * params.size_x
    kind = params.kind
    if kind == "flat":
        boxes = [_slab(x0, x1, params)]
    elif kind == "rocks":
        boxes = _rocks(x0, x1, params.rock_count, params, rng)
    elif kind == "steps":
        boxes = _steps(x0, x1, params.step_count, params, rng)
    elif kind == "gaps":
        boxes = _gaps(x0, x1, params.gap_count, params, rng)
    else:  # mixed
        n = params.mixed_sections
        edges = np.linspace(x0, x1, n + 1)
        boxes = [_slab(edges[0], edges[1], params)]
        for i in range(1, n):
            a, b = float(edges[i]), float(edges[i + 1])
            section = ["rocks", "steps", "gaps"][int(rng.integers(3))]
            if section == "rocks":
                count = max(1, round(params.rock_count / n))
                boxes += _rocks(a, b, count, params, rng)
            elif section == "steps":
                boxes += _steps(a, b, max(1, round(params.step_count / n)), params, rng)
            else:
                boxes += _gaps(a, b, 1, params, rng)
    return TerrainBoard(params=params, seed=int(seed), boxes=boxes)


def join_boards(boards: list[TerrainBoard], offsets_xy) -> TerrainBoard:
    """One terrain made of several boards, board ``i`` moved by ``offsets_xy[i]``.

    The result's ``params`` and ``seed`` are those of the first board; its boxes are
    every board's boxes, so ``height`` is the exact height of the whole terrain and
    :meth:`TerrainBoard.bounds` its extent (``params.size_x`` and ``size_y`` are only the
    first board's).

    Args:
        boards: the boards (at least one).
        offsets_xy: one ``[dx, dy]`` per board (m).

    Raises:
        RepertoireError: no boards, or offsets of the wrong shape or not finite.
    """
    offsets = np.asarray(offsets_xy, dtype=float)
    if not boards or offsets.shape != (len(boards), 2) or not np.all(np.isfinite(offsets)):
        raise RepertoireError(
            f"join_boards needs at least one board and one finite [dx, dy] per board, got "
            f"{len(boards)} boards and offsets of shape {offsets.shape}"
        )
    boxes = []
    for board, (dx, dy) in zip(boards, offsets):
        boxes += board.translated(float(dx), float(dy)).boxes
    return TerrainBoard(params=boards[0].params, seed=boards[0].seed, boxes=boxes)


def replace_with_rocks(
    board: TerrainBoard,
    x_from: float,
    seed: int = 0,
    coverage: float = ROCK_FIELD_COVERAGE,
) -> TerrainBoard:
    """A copy of ``board`` whose part at ``x >= x_from`` is replaced by a rock field.

    The board's extent is :meth:`TerrainBoard.bounds` (its boxes, so a joined or moved
    board is handled, not only one centred on the origin). Boxes lying wholly before
    ``x_from`` are kept; boxes reaching past it are cut at ``x_from`` (slabs and steps
    are axis-aligned bands; a yawed rock reaching past it is dropped); the rest of the
    extent, ``[x_from, x_max] x [y_min, y_max]``, becomes :func:`rock_field` of
    ``seed``: a slab with ``coverage`` (default :data:`ROCK_FIELD_COVERAGE`, 0.8) of its
    area under rocks of the board's ``rock_size`` and ``rock_height`` (Stolle et al.,
    Fig. 10: new rocks in place of the terrain's last part). The unchanged part keeps
    exactly its heights, except under a yawed rock that reaches past ``x_from``: it is
    dropped whole (a yawed box cut by a line across x is no longer a box).

    Args:
        board: the source board.
        x_from: start of the replaced part (m), strictly inside the board along x.
        seed: seed of the new rocks.
        coverage: fraction of the replaced part covered by rocks, in
            ``[0, MAX_ROCK_COVERAGE]``.

    Raises:
        RepertoireError: ``x_from`` outside the board or a bad coverage.
    """
    if not isinstance(board, TerrainBoard):
        raise RepertoireError(f"replace_with_rocks needs a TerrainBoard, got {type(board)}")
    x0, x1, y0, y1 = board.bounds()
    if not (math.isfinite(x_from) and x0 < x_from < x1):
        raise RepertoireError(
            f"replace_with_rocks: x_from={x_from} must lie strictly inside the board ({x0}, {x1})"
        )
    # rock_field builds across [-size_y/2, size_y/2]: give it the board's width, then move
    # it to the board's centre line (for a board centred on y = 0 both are what they were).
    field = dataclasses.replace(board.params, kind="rocks", size_y=y1 - y0)
    cy = 0.5 * (y0 + y1)
    new = [
        dataclasses.replace(b, center=[b.center[0], b.center[1] + cy, b.center[2]])
        for b in rock_field(float(x_from), x1, field, seed, coverage)
    ]
    kept: list[TerrainBox] = []
    for box in board.boxes:
        lo = box.center[0] - 0.5 * box.size[0]
        hi = box.center[0] + 0.5 * box.size[0]
        if box.yaw == 0.0:
            if lo >= x_from:
                continue
            if hi > x_from:
                box = dataclasses.replace(
                    box,
                    center=[0.5 * (lo + x_from), box.center[1], box.center[2]],
                    size=[x_from - lo, box.size[1], box.size[2]],
                )
            kept.append(box)
        elif box.footprint_bounds()[1] < x_from:
            kept.append(box)
    params = dataclasses.replace(board.params, kind="mixed")
    return TerrainBoard(params=params, seed=board.seed, boxes=kept + new)


def tile_boards(boards: list[TerrainBoard]) -> TerrainBoard:
    """Boards of equal width placed one after another along +x as one board.

    The result is centred on the origin; the boards' extents (:meth:`TerrainBoard.bounds`:
    where the boxes are, for a moved or joined board too) touch along x, centred on y = 0.
    Its ``params`` are the first board's, ``mixed``, with the summed length and the width.

    Raises:
        RepertoireError: no boards, or boards of different widths.
    """
    if not boards or not all(isinstance(b, TerrainBoard) for b in boards):
        raise RepertoireError("tile_boards needs a non-empty list of TerrainBoard")
    extents = [b.bounds() for b in boards]
    widths = [y1 - y0 for _, _, y0, y1 in extents]
    if any(abs(w - widths[0]) > 1e-9 for w in widths):
        raise RepertoireError(f"tile_boards needs boards of equal size_y, got widths {widths} m")
    total = sum(x1 - x0 for x0, x1, _, _ in extents)
    x = -0.5 * total
    boxes: list[TerrainBox] = []
    for b, (x0, x1, y0, y1) in zip(boards, extents):
        shift, shift_y = x - x0, -0.5 * (y0 + y1)
        for box in b.boxes:
            center = [box.center[0] + shift, box.center[1] + shift_y, box.center[2]]
            boxes.append(dataclasses.replace(box, center=center))
        x += x1 - x0
    params = dataclasses.replace(boards[0].params, kind="mixed", size_x=total, size_y=widths[0])
    return TerrainBoard(params=params, seed=boards[0].seed, boxes=boxes)
