"""A quadruped crawl step model for LittleDog on a 2.5-D height map.

A crawl moves one foot at a time, in a fixed order (default ``lh, lf, rh,
rf``). The state is the four footholds (ground contact points p_WF, x y z in
m, on the height map's cell centres) and the index of the foot that moves
next. A successor moves that foot to one of a discretised set of candidate
footholds around its nominal position (the nominal stance of
:func:`repertoire.models.littledog.kinematics.nominal_foot_positions` placed at
the feet's centroid and turned to the body heading; the candidate offsets are in
the body's axes too), and keeps a candidate only if

- the ground there is flat: the height range within ``flat_radius`` of the
  foothold is at most ``max_roughness`` (rejects steep spots and edges);
- the step up or down is at most ``max_step_height``;
- the swing clears the ground: the highest cell under the straight swing line
  is at most ``swing_clearance`` above the higher of the two footholds;
- the executing crawl (:mod:`repertoire.planning.littledog_crawl`, parameters
  ``crawl``) can do the step: every leg's closed-form IK
  (:func:`~repertoire.models.littledog.kinematics.leg_ik`, joint limits checked)
  holds for every foot command of the step (lift delay, swing over the ground,
  settle) with the body at the crawl's own pose for it
  (:func:`~repertoire.planning.littledog_crawl.swing_pose`: over the three stance
  feet, heading from the four feet, lowered to keep the legs within reach), by
  :func:`~repertoire.planning.littledog_crawl.step_reachable` (one definition
  for the planner and the crawl). The swing's ground is ``ground`` (the exact
  board when given, else the map's cell heights);
- the body's shift to that pose, from the pose the crawl held through the last step
  (the state keeps the cell the last moved foot left, so that pose is known), keeps
  every leg within reach at every commanded sample
  (:func:`~repertoire.planning.littledog_crawl.shift_reachable`; before, only its ends
  were checked, and a step down with a turn took a hip past its limit halfway);
- with an exact ``ground``, the foot's landing spot is flat on it too
  (:func:`flat_on_ground`: the map's cell centres miss edges between them), and
  no ground rises above it within ``face_radius`` (:func:`clear_of_faces`: a
  foot that slides against a face jams, and drags the robot down as it lifts);
- during the swing the body projection lies inside the support triangle of the
  three stance feet with ``support_margin``; the body is taken as shifted by
  ``body_shift`` from the four feet's centroid towards the triangle's centroid
  (the body sway of a crawl).

The body heading starts at the start stance's own heading
(:func:`~repertoire.planning.littledog_crawl.heading_of`) and is part of the state
as a whole number of ``turn_step`` turns. Without a goal heading the crawl keeps it
(from a stance heading 0: the footholds of a crawl in world axes). With a goal
heading (``goal_heading``) each step may also turn the body by one ``turn_step``
towards it first, if that brings the body nearer it and leaves it at most
``turn_lead`` turn steps ahead of the feet's heading (the stance follows as its
feet move; the reach check above decides what the legs can do), and the goal
test also needs the feet's heading within ``heading_tolerance`` of it.

The goal test: the feet's centroid within ``goal_radius`` of the goal point (and the
heading, with a goal heading; both front feet past a line, with a front line). Step
cost: ``step_cost`` plus the foot's horizontal travel plus ``height_cost`` times its
height change; the heuristic is the larger of 4 x the centroid's distance beyond the
goal radius (a lower bound: a step moves the centroid by a quarter of the foot's
travel) and the feet's travel a heading change needs, plus ``step_cost`` times the
least number of steps (for the travel, and for the turn: see below). The turning term
is 2 L e (e the heading error beyond the tolerance, L the distance of the hind feet's
midpoint to the front feet's): turning the line between the two midpoints by e at its
length moves its ends along arcs of L e together, and each end is the mean of two
feet. It is a lower bound while the stance keeps its length (the feet lie farther from
the centroid than the midpoints, and travel farther), not in general: a stance could
shrink while it turns. The proven bound, 2 L sin e up to 90 degrees, stays flat
beyond: with it, turns of 135 and 180 degrees on flat ground ran out of 4000
expansions at 20-30 degrees, and with the arc they took 260 and about 1000.

The least number of steps counts the turn too: a step turns the body by at most one
``turn_step`` and the feet's heading follows the body's, so a heading error e beyond
the tolerance takes at least ceil(e / turn_step) minus ``turn_lead`` more steps. This
too is an estimate: the feet's heading was seen up to 3.8 turn steps ahead of the
body's (flat, rock and mixed boards): it may count two steps (0.01 each) too many.
Without it the heuristic priced a 5 degree turn at 2 L e = 0.035 while the crawl pays
about 0.065 for it (plans cost 2.3 for 175 degrees), so g + 3 h fell little along a
turn, and not at all where rocks made the feet detour: from the modified terrain's
start a half turn ended in TIME_LIMIT at 120-129 degrees after 20-30 s, and turns of
135 and 180 degrees on flat ground took 261 and 961 expansions; with it 310, and 181
and 150 (at the start of a half turn the heuristic is 1.56 against plans of 1.9-2.5).
With a goal heading, ``weight`` is therefore no proven bound on a plan's cost.

Use :func:`~repertoire.planning.footstep.height_map.height_map_from_board` to sample a
terrain board, then :func:`plan_crawl`; the plan's steps are typed :class:`CrawlStep` records.
"""

import dataclasses
import math

import numpy as np
from repertoire.models.littledog.kinematics import FOOT_RADIUS, LEGS, nominal_foot_positions
from repertoire.planning.footstep.height_map import HeightMap
from repertoire.planning.footstep.search import SearchResult, anytime_search, search
from repertoire.planning.footstep.types import FootstepError, PlanStatus
from repertoire.planning.littledog_crawl import CrawlParams as ExecutionParams
from repertoire.planning.littledog_crawl import (
    foothold_range,
    heading_of,
    joint_angles,
    shift_reachable,
    step_reachable,
    swing_pose,
)

from repertoire.checks import is_real, is_whole
from repertoire.errors import RepertoireError
from repertoire.limits import require_memory


@dataclasses.dataclass
class CrawlParams:
    """Parameters of the crawl step model (YAML-loadable).

    Attributes:
        order: leg indices (into LEGS = lf, rf, lh, rh) in crawl order.
        offsets_x: candidate foothold offsets from the nominal position along the body
            heading (m; x for heading 0).
        offsets_y: candidate foothold offsets to the body's left (m).
        flat_radius: radius of the flatness check around a foothold (m).
        max_roughness: largest height range allowed within ``flat_radius`` (m).
        max_step_height: largest height change of one foot (m); by default the crawl's
            reach: every leg reaches 9 cm up from a level stance, none 9.5 cm.
        swing_clearance: highest ground along a swing above the higher foothold (m).
        support_margin: distance the body projection keeps inside the support triangle (m).
        face_radius: with an exact ground, no ground within this distance of a landing
            spot's centre rises more than ``max_roughness`` above it (m;
            :func:`clear_of_faces`). The foot's radius plus 1 cm: in physics the stance
            feet stand up to about 1 cm from their planned footholds (median 4 mm); the
            scripted operator's footholds keep the same 2 cm (its ``edge_radius``).
        body_shift: fraction of the way the body sways towards the triangle's centroid.
        goal_radius: goal region radius around the goal point (m).
        step_cost: fixed cost per step.
        height_cost: cost per metre of height change.
        turn_step: body heading change of one turning step (rad, in (0, pi]), used with a goal
            heading.
        heading_tolerance: largest feet's heading error from a goal heading (rad, in (0, pi]).
        turn_lead: how many ``turn_step`` the body heading may run ahead of the feet's
            heading (an integer >= 1): a step turns the body only while the feet keep up,
            so the legs never reach for footholds turned far beyond the stance they stand
            on (with no limit, a half turn left the body 60 degrees ahead of the feet and
            the search stalled). The lead angle is ``turn_lead * turn_step`` (10 degrees by
            default): keep it when changing ``turn_step``. With ``turn_step`` 2 degrees and
            ``turn_lead`` 2 (a 4 degree lead, less than the feet's heading varies with the
            candidate offsets) a 90 degree turn on flat ground ran out of 3000 expansions;
            with ``turn_lead`` 5 it took 130, and a half turn 536.
    """

    order: list[int] = dataclasses.field(default_factory=lambda: [2, 0, 3, 1])
    offsets_x: list[float] = dataclasses.field(
        default_factory=lambda: [-0.02, 0.0, 0.02, 0.04, 0.06]
    )
    offsets_y: list[float] = dataclasses.field(default_factory=lambda: [-0.02, 0.0, 0.02])
    flat_radius: float = 0.012
    max_roughness: float = 0.006
    max_step_height: float = 0.09
    swing_clearance: float = 0.05
    support_margin: float = 0.005
    face_radius: float = 0.02
    body_shift: float = 0.5
    goal_radius: float = 0.03
    step_cost: float = 0.01
    height_cost: float = 1.0
    turn_step: float = math.radians(5.0)
    heading_tolerance: float = math.radians(5.0)
    turn_lead: int = 2

    def validate(self) -> None:
        """Raises FootstepError naming the first bad field."""
        if not (_numbers(self.order, is_whole) and sorted(self.order) == [0, 1, 2, 3]):
            raise FootstepError(f"crawl order must be a permutation of 0..3, got {self.order!r}")
        if not self.offsets_x or not self.offsets_y:
            raise FootstepError(
                f"crawl candidate offsets are empty (offsets_x={self.offsets_x}, "
                f"offsets_y={self.offsets_y}): the step model would have no successors"
            )
        for name in ("offsets_x", "offsets_y"):
            values = getattr(self, name)
            if not _numbers(values, lambda v: is_real(v) and math.isfinite(v)):
                raise FootstepError(f"crawl {name} must be finite numbers, got {values!r}")
        for f in dataclasses.fields(self):
            if f.name not in ("order", "offsets_x", "offsets_y", "turn_lead"):
                if not is_real(value := getattr(self, f.name)):
                    raise FootstepError(f"crawl {f.name} must be a number, got {value!r}")
        for name in (
            "flat_radius",
            "max_step_height",
            "swing_clearance",
            "goal_radius",
            "step_cost",
            "turn_step",
            "heading_tolerance",
        ):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise FootstepError(f"crawl {name} must be positive, got {value}")
        for name in ("max_roughness", "support_margin", "face_radius", "height_cost"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise FootstepError(f"crawl {name} must be >= 0, got {value}")
        for name in ("turn_step", "heading_tolerance"):
            # Angles beyond a half turn wrap: a turn of 4 rad is one of 4 - 2 pi the
            # other way, and a tolerance over pi admits every heading.
            value = getattr(self, name)
            if value > math.pi:
                raise FootstepError(f"crawl {name} must be at most pi rad, got {value}")
        if not (is_whole(self.turn_lead) and self.turn_lead >= 1):
            raise FootstepError(f"crawl turn_lead must be an integer >= 1, got {self.turn_lead!r}")
        if not (0.0 <= self.body_shift <= 1.0):
            raise FootstepError(f"crawl body_shift must be in [0, 1], got {self.body_shift}")


def _numbers(values, ok) -> bool:
    """True when ``values`` is a list (or tuple, array) whose every element passes ``ok``."""
    if isinstance(values, np.ndarray):
        values = values.tolist() if values.ndim == 1 else None
    return isinstance(values, (list, tuple)) and all(ok(v) for v in values)


@dataclasses.dataclass(frozen=True)
class CrawlState:
    """A search state: foothold cells, the next crawl phase and the body's turns.

    ``cells``: 4 x (row, col); ``turns``: whole ``turn_step`` from the start heading;
    ``left``: the cell the last moved foot left (None at the start). The body's pose
    during the last step depends on it, and the next step's shift starts from that pose,
    so arrivals from different cells are different states.
    """

    cells: tuple[tuple[int, int], ...]
    phase: int
    turns: int = 0
    left: tuple[int, int] | None = None


@dataclasses.dataclass(frozen=True)
class CrawlStep:
    """One step of a crawl plan.

    Attributes:
        foot: leg index into LEGS (lf, rf, lh, rh).
        leg: leg name.
        p_WF: the new foothold (ground contact point, world frame, m).
        stance: the four footholds after the step, shape (4, 3), LEGS order.
    """

    foot: int
    leg: str
    p_WF: np.ndarray
    stance: np.ndarray


@dataclasses.dataclass
class CrawlPlan:
    """A crawl plan.

    Attributes:
        status: SUCCESS, UNREACHABLE, NODE_LIMIT or TIME_LIMIT (see search.py).
        start_stance: the four start footholds, shape (4, 3).
        steps: the steps in order (a best partial plan unless SUCCESS).
        cost: summed step costs.
        weight: suboptimality bound of the plan (1 = optimal on the lattice).
        resolution: lattice resolution (the height map's cell side, m).
        expansions: states expanded (all searches).
        seconds: planning wall time.
        bounds: (cost, weight) of every plan the anytime search found, in order.
    """

    status: PlanStatus
    start_stance: np.ndarray
    steps: list[CrawlStep]
    cost: float
    weight: float
    resolution: float
    expansions: int
    seconds: float
    bounds: list[tuple[float, float]] = dataclasses.field(default_factory=list)


def _point_in_triangle_margin(p: np.ndarray, tri: np.ndarray) -> float:
    """Signed distance of p inside triangle tri (3 x 2): min over edges, > 0 inside."""
    area = (tri[1, 0] - tri[0, 0]) * (tri[2, 1] - tri[0, 1]) - (tri[1, 1] - tri[0, 1]) * (
        tri[2, 0] - tri[0, 0]
    )
    sign = 1.0 if area > 0.0 else -1.0
    d = math.inf
    for i in range(3):
        a, b = tri[i], tri[(i + 1) % 3]
        e = b - a
        n = math.hypot(e[0], e[1])
        if n == 0.0:
            return -math.inf
        cross = e[0] * (p[1] - a[1]) - e[1] * (p[0] - a[0])
        d = min(d, sign * cross / n)
    return d


def swing_support_margin(feet, leg: int, params: CrawlParams) -> float:
    """How far inside the three stance feet's support triangle the swaying body stays (m).

    The body is taken ``body_shift`` of the way from the four feet's centroid towards
    the triangle's centroid; the step is statically stable if this is at least
    ``support_margin`` (negative outside).

    Args:
        feet: the four footholds before the step (4 x 2 or 4 x 3).
        leg: the swing foot.
        params: model parameters.
    """
    xy = np.asarray(feet, dtype=float)[:, :2]
    tri = xy[[i for i in range(4) if i != leg]]
    sway = (1.0 - params.body_shift) * xy.mean(axis=0) + params.body_shift * tri.mean(axis=0)
    return _point_in_triangle_margin(sway, tri)


def flat_on_ground(ground, xy, params: CrawlParams) -> np.ndarray:
    """True where a foot at each point of ``xy`` (M x 2 or more columns) stands on flat ground.

    The height spread of ``ground`` (an exact height function, e.g. the board the map
    was sampled from) under the foot, within its radius ``FOOT_RADIUS`` (centre and
    two rings, :func:`~repertoire.planning.littledog_crawl.foothold_range`), at most
    ``max_roughness``: the map's cell centres miss edges between them, and a foot
    landing on an edge slides off.
    """
    rule = ExecutionParams(edge_radius=FOOT_RADIUS)
    return foothold_range(ground, np.asarray(xy, dtype=float)[:, :2], rule) <= params.max_roughness


def clear_of_faces(ground, xy, params: CrawlParams) -> np.ndarray:
    """True where no ground within ``face_radius`` of each point of ``xy`` rises above it.

    A foot standing at a point is clear when the exact ``ground`` on rings of radius
    ``FOOT_RADIUS``, halfway and ``face_radius`` around it (24 points each, at most
    5.2 mm apart on the outer ring for the default 2 cm) lies at most
    ``max_roughness`` above the ground at the point. Ground that falls away is not
    checked here (the foot's own footprint is :func:`flat_on_ground`'s).

    Why: a standing foot slides up to about 1 cm from its planned foothold as the body
    shifts over it; a face rising to the foot sphere's centre pushes back on it
    horizontally, and when the foot lifts, its friction drags that corner of the robot
    down. Planned footholds 1.1 and 1.5 cm from a 1.4 and a 2.5 cm face made the
    robot tip over that way in physics (the diagonally opposite front foot unloaded).

    Args:
        ground: terrain with an exact ``height(x, y)``.
        xy: foot centres' (x, y), (M, 2) or more columns.
        params: model parameters (``face_radius``, ``max_roughness``).

    Returns:
        Boolean mask (M,).
    """
    xy = np.asarray(xy, dtype=float)[:, :2]
    if params.face_radius <= FOOT_RADIUS or len(xy) == 0:
        return np.ones(len(xy), dtype=bool)
    angles = np.linspace(0.0, 2.0 * np.pi, 24, endpoint=False)
    radii = [FOOT_RADIUS, 0.5 * (FOOT_RADIUS + params.face_radius), params.face_radius]
    ring = np.concatenate([r * np.column_stack([np.cos(angles), np.sin(angles)]) for r in radii])
    pts = xy[:, None, :] + ring[None]
    around = np.asarray(ground.height(pts[..., 0], pts[..., 1]), dtype=float)
    here = np.asarray(ground.height(xy[:, 0], xy[:, 1]), dtype=float)
    return around.max(axis=1) - here <= params.max_roughness


_FEET_KEPT = 200_000
"""Foothold arrays a :class:`CrawlModel` keeps per foothold cells (then it starts over)."""


def _line(a: float, b: float, n: int) -> np.ndarray:
    """``np.linspace(a, b, n + 1)`` by its own arithmetic (the same values), n >= 1."""
    y = np.arange(n + 1) * ((b - a) / n) + a
    y[-1] = b
    return y


def swing_line_cells(r0: int, c0: int, r1: int, c1: int) -> tuple[np.ndarray, np.ndarray]:
    """Rows and columns of the cells on the straight swing line from one cell to another."""
    n = max(abs(r1 - r0), abs(c1 - c0)) + 1
    return np.rint(_line(r0, r1, n)).astype(int), np.rint(_line(c0, c1, n)).astype(int)


def _rotate(v: np.ndarray, psi: float) -> np.ndarray:
    """Planar vectors (..., 2) turned by ``psi`` (rad); exactly ``v`` for psi = 0."""
    c, s = math.cos(psi), math.sin(psi)
    return np.stack([c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1]], axis=-1)


class CrawlModel:
    """The crawl step model for :func:`repertoire.planning.footstep.search.search`.

    Args:
        height_map: the terrain.
        start_xy: the four start footholds' (x, y), shape (4, 2), LEGS order, or
            (x, y, z) ground contact points (4, 3) (default z: the map's); each foot
            stays there exactly until it moves, then it steps onto cell centres.
        goal_xy: goal point for the feet's centroid (m).
        params: model parameters (validated).
        crawl: parameters of the crawl that executes the plan (its reach decides).
        ground: terrain with ``height(x, y)`` the swings clear (default: the map).
        goal_heading: goal heading of the stance (rad, :func:`heading_of` of the
            feet), or None: any heading, and the body keeps its start heading.
        front_line: ``(nx, ny, d)``: the goal test also needs both front feet (lf, rf)
            on the line's far side, ``n . p >= d`` with ``n`` normalised (e.g. ``(1, 0,
            x)``: past the line x along +x), or None. The heuristic also takes the larger
            of its value and the front feet's travel to the line (plus a step each).

    Raises:
        FootstepError: bad parameters, a start foothold off the map or on ground
            too steep, a start stance out of reach or unstable, a goal off the map,
            a goal heading not a finite number, a front line not finite or with n = 0.
        ResourceLimitError: a map whose planning arrays would not fit in memory (the
            figure in the message), checked before allocating them.
    """

    def __init__(
        self,
        height_map: HeightMap,
        start_xy,
        goal_xy,
        params: CrawlParams,
        crawl: ExecutionParams | None = None,
        ground=None,
        goal_heading: float | None = None,
        front_line=None,
    ) -> None:
        crawl = ExecutionParams() if crawl is None else crawl
        for name, value, kind in (
            ("height_map", height_map, HeightMap),
            ("params", params, CrawlParams),
            ("crawl", crawl, ExecutionParams),
        ):
            if not isinstance(value, kind):
                raise FootstepError(f"crawl {name} must be a {kind.__name__}, got {value!r:.80}")
        params.validate()
        self.map = height_map
        self.params = params
        self.crawl = crawl
        self.crawl.validate()
        self.ground = height_map if ground is None else ground
        if not callable(getattr(self.ground, "height", None)):
            raise FootstepError(
                f"crawl ground must have a height(x, y) method (e.g. a TerrainBoard), got "
                f"{ground!r:.80}"
            )
        n_y, n_x = height_map.shape
        require_memory(  # the roughness filter's arrays (max, min, range), before allocating
            24.0 * n_x * n_y,
            f"crawl planning (roughness) of a {n_x} x {n_y} height map at "
            f"{height_map.resolution} m",
        )
        self._rough = height_map.roughness(params.flat_radius)
        self._nominal = nominal_foot_positions()[:, :2]
        try:
            goal = np.asarray(goal_xy, dtype=float)
        except (TypeError, ValueError):  # a string, ragged rows: refused by the shape test
            goal = np.zeros(0)
        if goal.shape != (2,) or not np.all(np.isfinite(goal)):
            raise FootstepError(f"crawl goal must be a finite (x, y), got {goal_xy!r}")
        if not bool(height_map.inside(*height_map.cell(goal[0], goal[1]))):
            raise FootstepError(f"crawl goal {goal.tolist()} is outside the height map")
        self.goal = goal
        self.goal_heading = None
        if goal_heading is not None:
            if not (is_real(goal_heading) and math.isfinite(goal_heading)):
                raise FootstepError(
                    f"crawl goal_heading must be a finite angle (rad) or None, got {goal_heading!r}"
                )
            value = float(goal_heading)
            self.goal_heading = math.atan2(math.sin(value), math.cos(value))
        self.front_line = None
        if front_line is not None:
            try:
                line = np.asarray(front_line, dtype=float)
            except (TypeError, ValueError):
                line = np.zeros(0)  # refused below
            if line.shape != (3,) or not np.all(np.isfinite(line)) or not np.hypot(*line[:2]) > 0:
                raise FootstepError(
                    f"crawl front_line must be a finite (nx, ny, d) with n != 0, got {front_line!r}"
                )
            self.front_line = line / np.hypot(*line[:2])
        try:
            start = np.asarray(start_xy, dtype=float)
        except (TypeError, ValueError):  # a string, a dict, ragged rows: refused below
            start = np.zeros(0)
        if start.shape not in ((4, 2), (4, 3)) or not np.all(np.isfinite(start)):
            raise FootstepError(
                f"crawl start footholds must be finite, shape (4, 2) or (4, 3); "
                f"got {start_xy!r:.200}"
            )
        rows, cols = height_map.cell(start[:, 0], start[:, 1])
        if not np.all(height_map.inside(rows, cols)):
            raise FootstepError(f"crawl start footholds {start.tolist()} leave the height map")
        # A foot keeps its exact start foothold until it moves (the crawl does not snap it).
        z0 = start[:, 2] if start.shape[1] == 3 else height_map.heights[rows, cols]
        self._start_feet = np.column_stack([start[:, :2], z0])
        self._feet_of: dict[tuple, np.ndarray] = {}
        # An exact ground judges the exact start footholds (the map, the cells holding them).
        exact = None if self.ground is height_map else flat_on_ground(self.ground, start, params)
        for i in range(4):
            if exact is not None and not exact[i]:
                rule = ExecutionParams(edge_radius=FOOT_RADIUS)
                spread = float(foothold_range(self.ground, start[i : i + 1, :2], rule)[0])
                raise FootstepError(
                    f"crawl start foothold of {LEGS[i]} at {start[i].tolist()} is on ground too "
                    f"steep: height range {spread:.4f} m within {FOOT_RADIUS} m on the exact "
                    f"ground > max_roughness {params.max_roughness} m"
                )
            if exact is None and self._rough[rows[i], cols[i]] > params.max_roughness:
                raise FootstepError(
                    f"crawl start foothold of {LEGS[i]} at {start[i].tolist()} is on ground too "
                    f"steep: height range {self._rough[rows[i], cols[i]]:.4f} m within "
                    f"{params.flat_radius} m > max_roughness {params.max_roughness} m"
                )
        self._start = CrawlState(
            cells=tuple((int(r), int(c)) for r, c in zip(rows, cols, strict=True)), phase=0
        )
        # The body heading: the start stance's own, turned by whole turn steps.
        self._heading0 = heading_of(self._start_feet)
        feet = self.footholds(self._start)
        # The crawl starts level over the four feet at its standing height.
        centres = feet + np.array([0.0, 0.0, FOOT_RADIUS])
        c = centres.mean(axis=0)
        level = [c[0], c[1], feet[:, 2].mean() + self.crawl.standing_height]
        self._pose0 = np.array([*level, 0.0, 0.0, heading_of(centres)])
        try:
            joint_angles(
                self._pose0,
                centres - np.array([0.0, 0.0, self.crawl.press]),
                "crawl start stance",
            )
        except RepertoireError as e:
            raise FootstepError(
                f"crawl start stance {feet.tolist()} is out of the legs' reach: {e}"
            ) from e
        self._max_travel = (
            math.hypot(
                max(abs(v) for v in params.offsets_x) + 0.5 * height_map.resolution,
                max(abs(v) for v in params.offsets_y) + 0.5 * height_map.resolution,
            )
            + self._max_nominal_drift()
        )
        dx, dy = np.meshgrid(params.offsets_x, params.offsets_y)
        self._offsets = np.stack([dx.ravel(), dy.ravel()], axis=-1)

    def _max_nominal_drift(self) -> float:
        # Bound on how far a foot's nominal position lies from the foot itself: the
        # reach region of a leg lies within the leg lengths of its hip.
        return 0.0751 + 0.102 + 0.036

    def _turn_error(self, turns: int) -> float:
        """|goal heading - the body heading after ``turns`` turn steps| (0 without one)."""
        if self.goal_heading is None:
            return 0.0
        e = self.goal_heading - self._heading0 - turns * self.params.turn_step
        return abs(math.atan2(math.sin(e), math.cos(e)))

    def _lead(self, turns: int, feet) -> float:
        """|body heading after ``turns`` turn steps - the feet's heading| (rad, wrapped)."""
        e = self._heading0 + turns * self.params.turn_step - heading_of(feet)
        return abs(math.atan2(math.sin(e), math.cos(e)))

    def footholds(self, state: CrawlState) -> np.ndarray:
        """The four footholds (4 x 3, ground contact points) of a state (a new array).

        Cell centres, except a foot in its start cell: its exact start foothold.
        """
        return self._feet(state).copy()

    def _feet(self, state: CrawlState) -> np.ndarray:
        """:meth:`footholds`, kept per foothold cells (read-only: the search's own use)."""
        feet = self._feet_of.get(state.cells)
        if feet is None:
            if len(self._feet_of) >= _FEET_KEPT:
                self._feet_of.clear()
            feet = self._feet_of[state.cells] = self._compute_feet(state)
        return feet

    def _compute_feet(self, state: CrawlState) -> np.ndarray:
        rows = np.array([c[0] for c in state.cells])
        cols = np.array([c[1] for c in state.cells])
        x, y = self.map.center(rows, cols)
        feet = np.stack([x, y, self.map.heights[rows, cols]], axis=-1)
        at_start = [c == s for c, s in zip(state.cells, self._start.cells, strict=True)]
        feet[at_start] = self._start_feet[at_start]
        return feet

    # --- the StepModel protocol ---
    def start(self) -> CrawlState:
        return self._start

    def key(self, state: CrawlState) -> CrawlState:
        return state

    def heading_error(self, feet) -> float:
        """|goal heading - the feet's heading| (rad, wrapped to [0, pi]); 0 without one."""
        if self.goal_heading is None:
            return 0.0
        e = self.goal_heading - heading_of(feet)
        return abs(math.atan2(math.sin(e), math.cos(e)))

    def is_goal(self, state: CrawlState) -> bool:
        feet = self._feet(state)
        c = feet[:, :2].mean(axis=0)
        if math.hypot(*(c - self.goal)) > self.params.goal_radius:
            return False
        line = self.front_line
        if line is not None and min(feet[:2, :2] @ line[:2]) < line[2]:
            return False
        return self.heading_error(feet) <= self.params.heading_tolerance

    def heuristic(self, state: CrawlState) -> float:
        h = self._centroid_heuristic(state)
        if self.front_line is None:
            return h
        # each front foot behind the line travels at least its distance to it, in a step
        behind = self.front_line[2] - self._feet(state)[:2, :2] @ self.front_line[:2]
        behind = behind[behind > 0.0]
        return max(h, float(behind.sum()) + self.params.step_cost * behind.size)

    def _centroid_heuristic(self, state: CrawlState) -> float:
        p = self.params
        feet = self._feet(state)
        d = float(np.hypot(*(feet[:, :2].mean(axis=0) - self.goal))) - p.goal_radius
        e = self.heading_error(feet) - p.heading_tolerance
        turn, turn_steps = 0.0, 0
        if e > 0.0:
            # The midpoints' line (length L) turns by e: at its length, its ends travel an
            # arc of L e together, each the mean of two feet (see the module docstring).
            mid = 0.5 * (feet[0, :2] + feet[1, :2]) - 0.5 * (feet[2, :2] + feet[3, :2])
            turn = 2.0 * float(np.hypot(*mid)) * e
            # A step turns the body by one turn step at most and the feet follow it within
            # about turn_lead turn steps (see the module docstring).
            turn_steps = math.ceil(e / p.turn_step - 1e-9) - p.turn_lead
        if turn > 4.0 * max(d, 0.0):
            steps = max(math.ceil(turn / self._max_travel - 1e-9), turn_steps)
            return turn + p.step_cost * steps
        if d <= 0.0:
            return p.step_cost * max(turn_steps, 0)
        min_steps = max(math.ceil(d / (self._max_travel / 4.0) - 1e-9), turn_steps)
        return 4.0 * d + p.step_cost * min_steps

    def successors(self, state: CrawlState) -> list[tuple[CrawlState, float]]:
        p = self.params
        m = self.map
        leg = p.order[state.phase]
        feet = self._feet(state)
        centroid = feet[:, :2].mean(axis=0)
        # Candidates around the nominal foothold turned to the body heading after the
        # step's turn (none, or one turn step towards the goal heading if that brings the
        # body nearer it); a cell reached both ways keeps the turn.
        found: dict[tuple[int, int], int] = {}
        error = self._turn_error(state.turns)
        turns = [
            t
            for t in (-1, 1)
            if self._turn_error(state.turns + t) < error - 1e-12
            and self._lead(state.turns + t, feet) <= p.turn_lead * p.turn_step + 1e-9
        ]
        for dt in [*turns, 0]:
            psi = self._heading0 + (state.turns + dt) * p.turn_step
            targets = centroid + _rotate(self._nominal[leg], psi) + _rotate(self._offsets, psi)
            rows, cols = m.cell(targets[:, 0], targets[:, 1])
            ok = m.inside(rows, cols)
            for r, col in zip(rows[ok].tolist(), cols[ok].tolist(), strict=True):
                found.setdefault((r, col), state.turns + dt)
        old = state.cells[leg]
        found.pop(tuple(old), None)  # skip "no move"
        if not found:
            return []
        # Unique cells (offsets may snap to the same cell), in row, col order.
        cells = np.array(sorted(found), dtype=int)
        rows, cols = cells[:, 0], cells[:, 1]
        z_new = m.heights[rows, cols]
        z_old = feet[leg, 2]
        keep = (self._rough[rows, cols] <= p.max_roughness) & (
            np.abs(z_new - z_old) <= p.max_step_height
        )
        # Swing clearance along the straight line old -> new.
        for k in np.flatnonzero(keep):
            rr, cc = swing_line_cells(old[0], old[1], rows[k], cols[k])
            if m.heights[rr, cc].max() > max(z_new[k], z_old) + p.swing_clearance:
                keep[k] = False
        # Support triangle of the three stance feet during the swing.
        if swing_support_margin(feet, leg, p) < p.support_margin:
            return []
        idx = np.flatnonzero(keep)
        if len(idx) and self.ground is not self.map:
            x_new, y_new = m.center(rows[idx], cols[idx])
            spots = np.column_stack([x_new, y_new])
            idx = idx[flat_on_ground(self.ground, spots, p) & clear_of_faces(self.ground, spots, p)]
        if len(idx) == 0:
            return []
        x_new, y_new = m.center(rows[idx], cols[idx])
        p_new = np.stack([x_new, y_new, z_new[idx]], axis=-1)  # K x 3
        # The crawl's leg IK for the whole step at its own body pose (foot centres).
        lift = np.array([0.0, 0.0, FOOT_RADIUS])
        reach = step_reachable(feet + lift, leg, p_new + lift, self.crawl, self.ground)
        # ... and the body's shift there from where the last step held it
        ok = np.flatnonzero(reach)
        targets = swing_pose(feet + lift, leg, p_new[ok] + lift, self.crawl)
        ok = ok[shift_reachable(feet + lift, self._held_pose(state, feet), targets, self.crawl)]
        out = []
        next_phase = (state.phase + 1) % 4
        for j in ok:
            cells_new = list(state.cells)
            cells_new[leg] = (int(rows[idx[j]]), int(cols[idx[j]]))
            travel = math.hypot(p_new[j, 0] - feet[leg, 0], p_new[j, 1] - feet[leg, 1])
            cost = p.step_cost + travel + p.height_cost * abs(p_new[j, 2] - z_old)
            turns = found[cells_new[leg]]
            out.append((CrawlState(tuple(cells_new), next_phase, turns, old), cost))
        return out

    def _held_pose(self, state: CrawlState, feet: np.ndarray) -> np.ndarray:
        """The body pose the crawl holds as ``state`` is reached (the next shift's start).

        The start: level over the feet at the standing height (as the start check);
        else the last step's :func:`~repertoire.planning.littledog_crawl.swing_pose`, from
        the feet before it (its foot in ``state.left``).
        """
        if state.left is None:
            return self._pose0
        last = self.params.order[(state.phase - 1) % 4]
        before = list(state.cells)
        before[last] = state.left
        lift = np.array([0.0, 0.0, FOOT_RADIUS])
        prior = self._feet(CrawlState(tuple(before), 0)) + lift
        return swing_pose(prior, last, feet[last] + lift, self.crawl)


def plan_crawl(
    height_map: HeightMap,
    start_xy,
    goal_xy,
    params: CrawlParams | None = None,
    *,
    time_limit: float = 2.0,
    max_expansions: int = 50_000,
    anytime: bool = False,
    weight: float = 3.0,
    crawl: ExecutionParams | None = None,
    ground=None,
    goal_heading: float | None = None,
    front_line=None,
) -> CrawlPlan:
    """Plans a LittleDog crawl on a height map.

    Args:
        height_map: the terrain (e.g. from
            :func:`~repertoire.planning.footstep.height_map.height_map_from_board`).
        start_xy: the four start footholds' (x, y), shape (4, 2), LEGS order (lf, rf, lh, rh),
            or their ground contact points (4, 3) (see :class:`CrawlModel`).
        goal_xy: goal point for the feet's centroid.
        params: crawl model parameters; default :class:`CrawlParams`.
        time_limit: wall-time budget (s).
        max_expansions: expansion budget (per search).
        anytime: if True, weighted A* with weights 3, 2, 1.5, 1.2, 1 while time
            remains; the returned plan is the cheapest success.
        weight: heuristic weight of the single search when ``anytime`` is False (the
            plan costs at most ``weight`` times the lattice optimum without a goal
            heading, see the module docstring; 1 = optimal, slow).
        crawl: parameters of the executing crawl (default
            :class:`repertoire.planning.littledog_crawl.CrawlParams`).
        ground: terrain with ``height(x, y)`` for the swings' clearance in the reach
            check, e.g. the exact board the map was sampled from (default: the map).
        goal_heading: goal heading of the stance (rad, within ``heading_tolerance``);
            None: any heading, and the body keeps the start stance's heading.
        front_line: ``(nx, ny, d)`` or None, see :class:`CrawlModel`.

    Raises:
        FootstepError: see :class:`CrawlModel` and the search's budget checks.
        ResourceLimitError: see :class:`CrawlModel`.
    """
    p = CrawlParams() if params is None else params
    if not isinstance(anytime, (bool, np.bool_)):
        raise FootstepError(f"plan_crawl anytime must be True or False, got {anytime!r}")
    model = CrawlModel(height_map, start_xy, goal_xy, p, crawl, ground, goal_heading, front_line)
    if anytime:
        results = anytime_search(model, max_expansions=max_expansions, time_limit=time_limit)
    else:
        results = [
            search(model, weight=weight, max_expansions=max_expansions, time_limit=time_limit)
        ]
    successes = [r for r in results if r.status is PlanStatus.SUCCESS]
    best: SearchResult = min(successes, key=lambda r: r.cost) if successes else results[-1]
    if not successes and any(r.status is PlanStatus.UNREACHABLE for r in results):
        best = next(r for r in results if r.status is PlanStatus.UNREACHABLE)
    steps = []
    prev = best.path[0]
    for st in best.path[1:]:
        leg = model.params.order[prev.phase]
        stance = model.footholds(st)
        steps.append(CrawlStep(foot=leg, leg=LEGS[leg], p_WF=stance[leg].copy(), stance=stance))
        prev = st
    return CrawlPlan(
        status=best.status,
        start_stance=model.footholds(best.path[0]),
        steps=steps,
        cost=best.cost,
        weight=best.weight,
        resolution=height_map.resolution,
        expansions=sum(r.expansions for r in results),
        seconds=sum(r.seconds for r in results),
        bounds=[(r.cost, r.weight) for r in successes],
    )
