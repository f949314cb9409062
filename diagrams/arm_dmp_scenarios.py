"""Typed scenarios of the arm DMP worlds and the goals of their chain segments.

:class:`PickPlaceScenario` (Pastor et al. 2009, Fig. 13) and :class:`ServingScenario`
(Fig. 12) with their checks; :func:`plan_pick_and_place` and :func:`plan_serving` turn a
scenario into one :class:`repertoire.systems.arm_goals.SegmentGoal` per chain segment (the
grasp orientation from the approach direction of the grasp DMP, sec. IV-C); the typed parts
a world is built from (:class:`CoasterMotion`, :class:`BallObstacle`, :class:`BodyPointLog`);
the geometry the scenario checks and the studies use (the uncoupled carry path, the ball's gap
to the arm at home). The wiring is :mod:`repertoire.diagrams.arm_dmp`; running and scoring a
world is :mod:`repertoire.diagrams.arm_dmp_results`.
"""

import dataclasses
import functools

import numpy as np
from pydrake.common.eigen_geometry import Quaternion
from pydrake.math import RotationMatrix
from pydrake.multibody.plant import AddMultibodyPlant, MultibodyPlantConfig
from pydrake.systems.framework import DiagramBuilder
from repertoire.models.arm7 import (
    ARM_JOINTS,
    COASTER_RADIUS,
    CUP_HEIGHT,
    CUP_RADIUS,
    HAND_GRASP_7CM,
    HAND_OPEN,
    OBSTACLE_RADIUS,
    SHOULDER_FRAME,
    TABLE_HEIGHT,
    TCP_FRAME,
    add_arm7,
    arm7_home_configuration,
    make_arm7_control_plant,
)
from repertoire.planning.arm_library import (
    BOTTLE_GRASP_HEIGHT,
    COASTER_TOP,
    CUP_GRASP_HEIGHT,
    PLACE_CLEARANCE,
    R_POUR,
    R_SIDE,
    approach_direction,
    arm_control_plant,
    arm_motion_library,
    home_tcp_pose,
    motion_library,
    pour_tcp_position,
    quaternion_wxyz,
    rotation_from_approach,
)
from repertoire.systems.arm_goals import SegmentGoal
from repertoire.systems.task_space_reach import (
    check_reachable,
    pose_position_residual,
    reach_bound,
)

from repertoire.errors import ScenarioError

GRASP_MODES = ("contact", "grip")
# ----------------------------------------------------------------------------- obstacle
#: Where eq. 10 acts while carrying (tcp frame E; in a side grasp x_E is up, y_E closes the
#: hand across the cup, z_E is the approach): the tcp on the cup's axis, the cup's lower
#: part, the two finger groups, the palm's centre (8.5 cm behind the tcp) and its two ends
#: (+-6.5 cm along y_E; with only the centre the palm's trailing end grazed the ball).
CARRY_CONTROL_POINTS = (
    (0.0, 0.0, 0.0),
    (-0.045, 0.0, 0.0),
    (0.0, 0.06, 0.0),
    (0.0, -0.06, 0.0),
    (0.0, 0.0, -0.085),
    (0.0, 0.065, -0.085),
    (0.0, -0.065, -0.085),
)
#: Gain of eq. 10 on the arm (the paper's gamma: the term turns the scaled velocity ``v = tau
#: dx/dt``, :class:`MultiPointObstacleCoupling` fed the active segment's tau). The ball sits
#: on the carry, the place DMP's path (tau :data:`CARRY_TAU`, the place demonstration's
#: duration); the gain was tuned by hand there (commit fa602e2: 3000 -> 50000) while the term
#: still turned ``dx/dt``, i.e. as the paper's gain times the active tau. The same term on
#: the carry in the paper's units is that gain over the carry's tau, 50000 / 3: the carry
#: is driven exactly as it was tuned, and every segment now gets one gain in phase time
#: (the grasp's term, tau 2.5 s, is 5/6 of what it was, the release's, 1.5 s, half).
CARRY_TAU = 3.0
OBSTACLE_GAMMA = 50000.0 / CARRY_TAU
#: The default ball: 1 cm below the uncoupled carry path of the default layout, 62 % of the
#: way along it (``carry_path_point([0.55, -0.25], [0.54, 0.20], 0.62) - [0, 0, 0.01]``,
#: rounded to mm; nearer the middle it would touch the open hand at home).
DEFAULT_OBSTACLE_XYZ = (0.543, 0.07, 0.971)


def _ball_cylinder_gap(
    centre: np.ndarray, xy: np.ndarray, z0: float, radius: float, height: float
) -> float:
    """Exact distance between a ball of radius OBSTACLE_RADIUS and an upright cylinder.

    Args:
        centre: ball centre (3).
        xy: the cylinder's axis (2).
        z0: the cylinder's bottom height.
        radius: the cylinder's radius.
        height: the cylinder's height.

    Returns:
        Distance between the surfaces [m]; <= 0 when they overlap.
    """
    radial = max(float(np.hypot(centre[0] - xy[0], centre[1] - xy[1])) - radius, 0.0)
    vertical = max(z0 - centre[2], centre[2] - (z0 + height), 0.0)
    return float(np.hypot(radial, vertical)) - OBSTACLE_RADIUS


@functools.lru_cache(maxsize=1)
def _home_arm_query():
    """arm7 alone at home (hand open) with its SceneGraph: (diagram, context, geometry ids)."""
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlant(MultibodyPlantConfig(time_step=0.0), builder)
    arm = add_arm7(plant)
    plant.Finalize()
    plant.SetDefaultPositions(arm, np.concatenate([arm7_home_configuration(), HAND_OPEN]))
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    ids = {
        g
        for i in plant.GetBodyIndices(arm)
        for g in plant.GetCollisionGeometriesForBody(plant.get_body(i))
    }
    return diagram, scene_graph, context, ids


def ball_gap_at_home(centre_W: np.ndarray, radius: float = OBSTACLE_RADIUS) -> float:
    """Signed distance between a ball and arm7 in its home configuration, hand open [m].

    Exact (SceneGraph ``ComputeSignedDistanceToPoint`` from the ball's centre to the
    arm's collision geometries, minus the radius); <= 0 when the ball overlaps the arm
    where every world starts.

    Args:
        centre_W: the ball's centre in W (3).
        radius: the ball's radius.
    """
    diagram, scene_graph, context, ids = _home_arm_query()
    query = scene_graph.get_query_output_port().Eval(scene_graph.GetMyContextFromRoot(context))
    gaps = [
        d.distance
        for d in query.ComputeSignedDistanceToPoint(np.asarray(centre_W, float), 1.0)
        if d.id_G in ids
    ]
    return float(min(gaps, default=1.0)) - radius


def carry_path(cup_xy, coaster_xy, dt: float = 0.005) -> np.ndarray:
    """The tcp path of the learned place DMP without coupling (k x 3), cup to coaster.

    The place DMP rolled out (NumPy) from the cup's grasp point to the place goal
    above ``coaster_xy``: where the arm carries the cup when nothing is in the way.

    Args:
        cup_xy: the cup's position on the table (2).
        coaster_xy: the coaster's position (2).
        dt: rollout step [s].
    """
    cup = np.array([cup_xy[0], cup_xy[1], TABLE_HEIGHT + CUP_GRASP_HEIGHT])
    goal = np.array([coaster_xy[0], coaster_xy[1], COASTER_RAIL_HEIGHT]) + place_offset()
    return motion_library()["place"].position.rollout(goal=goal, x0=cup, dt=dt).x


def carry_path_point(cup_xy, coaster_xy, fraction: float = 0.5) -> np.ndarray:
    """The point at ``fraction`` of the arc length of :func:`carry_path` (3).

    Args:
        cup_xy: the cup's position on the table (2).
        coaster_xy: the coaster's position (2).
        fraction: 0 = the grasp point, 1 = the place goal.
    """
    path = carry_path(cup_xy, coaster_xy)
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
    return np.array([np.interp(fraction * arc[-1], arc, path[:, i]) for i in range(3)])


#: The coaster rides 1 mm above the table top (no rubbing on the table).
COASTER_RAIL_HEIGHT = TABLE_HEIGHT + 0.001


# ----------------------------------------------------------------------------- scenarios
def _check_xy(name: str, xy) -> np.ndarray:
    v = np.asarray(xy, dtype=float).reshape(-1)
    if v.size != 2 or not np.all(np.isfinite(v)):
        raise ScenarioError(f"{name} must be 2 finite numbers (x, y) in m, got {xy}")
    return v


#: The discrete contact model of the DMP arm worlds: Drake's SAP. The fingers hold
#: the cup by friction alone; with ``lagged`` (the friction bound from the previous step's
#: normal force, which Drake's docs say "can introduce non-negligible effects ... during
#: strong transients") one 4 ms step with a finger's force dropped released the grasp,
#: the finger snapped in at about 6 rad/s and the cup rolled 2-6 cm deeper into the hand.
#: The same runs with ``sap`` or ``similar`` at 4 ms, or ``lagged`` at 1-2 ms, hold it.
#: Serving (the bottle held the same way) serves as before with it.
DMP_CONTACT_APPROXIMATION = "sap"


def _check_common(s) -> None:
    if not (np.isfinite(s.time_step) and 0 < s.time_step <= 0.005):
        raise ScenarioError(f"time_step must be in (0, 0.005] s, got {s.time_step}")
    if s.contact_approximation not in ("lagged", "sap", "similar"):
        raise ScenarioError(
            f"contact_approximation '{s.contact_approximation}' unknown; expected lagged, sap "
            "or similar"
        )
    if s.grasp_mode not in GRASP_MODES:
        raise ScenarioError(f"grasp_mode '{s.grasp_mode}' unknown; expected one of {GRASP_MODES}")
    if not (np.isfinite(s.settle_time) and 0.0 <= s.settle_time <= 5.0):
        raise ScenarioError(f"settle_time must be in [0, 5] s, got {s.settle_time}")


@dataclasses.dataclass
class PickPlaceScenario:
    """Pick a cup, place it on a coaster that moves after onset, around a ball (Fig. 13).

    Attributes:
        time_step: discrete plant time step [s].
        contact_approximation: ``sap`` (default: :data:`DMP_CONTACT_APPROXIMATION` says
            why), ``lagged`` or ``similar``.
        grasp_mode: ``contact`` (finger friction) or ``grip`` (GraspWrench latch).
        cup_xy: the cup's position on the table [m].
        coaster_xy: the coaster's position at the start [m].
        coaster_final_xy: where the coaster moves to after the placing onset [m].
        coaster_move_delay: seconds after the placing onset when the coaster starts moving.
        coaster_move_duration: seconds the coaster takes to move.
        obstacle_xyz: centre of the ball-like obstacle (radius 0.06 m) [m]. The
            default sits on the carry path (1 cm below the uncoupled tcp path, 62 % of
            the way, see :func:`carry_path_point`): without coupling the cup hits it.
        obstacle_coupling: whether the obstacle feeds the DMP coupling term (eq. 10).
        obstacle_gamma: gamma of eq. 10.
        obstacle_beta: the angular decay c of eq. 10 (the paper: 20/pi).
        obstacle_points: control points in the tcp frame where eq. 10 is applied and
            summed (:class:`MultiPointObstacleCoupling`): by default the tcp (the
            carried cup's axis), the cup's lower part (x_tcp is up in a side grasp),
            the two finger groups (+-y_tcp) and the palm (-z_tcp; centre and ends).
            ``[[0, 0, 0]]`` is the paper's end-effector-only term.
        obstacle_length_scale: decay length [m] of the distance factor
            ``exp(-max(d - 0.06, 0) / length_scale)`` (our extension); 0 = the paper's
            eq. 10 exactly.
        settle_time: pause after each DMP's tau before the next segment starts [s].
    """

    time_step: float = 0.004
    contact_approximation: str = DMP_CONTACT_APPROXIMATION
    grasp_mode: str = "contact"
    cup_xy: list[float] = dataclasses.field(default_factory=lambda: [0.55, -0.25])
    coaster_xy: list[float] = dataclasses.field(default_factory=lambda: [0.54, 0.20])
    coaster_final_xy: list[float] = dataclasses.field(default_factory=lambda: [0.58, 0.22])
    coaster_move_delay: float = 0.8
    coaster_move_duration: float = 1.0
    obstacle_xyz: list[float] = dataclasses.field(
        default_factory=lambda: list(DEFAULT_OBSTACLE_XYZ)
    )
    obstacle_coupling: bool = True
    obstacle_gamma: float = OBSTACLE_GAMMA
    obstacle_beta: float = 4.0
    obstacle_points: list[list[float]] = dataclasses.field(
        default_factory=lambda: [list(p) for p in CARRY_CONTROL_POINTS]
    )
    obstacle_length_scale: float = 0.03
    settle_time: float = 0.25

    def validate(self) -> None:
        """Raises ScenarioError on the first bad field."""
        _check_common(self)
        _check_xy("cup_xy", self.cup_xy)
        _check_xy("coaster_xy", self.coaster_xy)
        _check_xy("coaster_final_xy", self.coaster_final_xy)
        # The coaster is no ArmWorld object (it rides on its slider), so the world's
        # pairwise overlap check never sees it: the cup must not start on or in it.
        cup = np.asarray(self.cup_xy, float)
        for name in ("coaster_xy", "coaster_final_xy"):
            xy = getattr(self, name)
            dist = float(np.hypot(*(np.asarray(xy, float) - cup)))
            if dist < CUP_RADIUS + COASTER_RADIUS:
                raise ScenarioError(
                    f"cup_xy {list(map(float, cup))} and {name} {list(map(float, xy))} are "
                    f"{dist:.3f} m apart, less than the cup's and the coaster's radii "
                    f"({CUP_RADIUS} + {COASTER_RADIUS} = {CUP_RADIUS + COASTER_RADIUS:.3f} m): "
                    "the cup would start on or inside the coaster; move them apart"
                )
        o = np.asarray(self.obstacle_xyz, dtype=float).reshape(-1)
        if o.size != 3 or not np.all(np.isfinite(o)):
            raise ScenarioError(f"obstacle_xyz must be 3 finite numbers, got {self.obstacle_xyz}")
        if o[2] - OBSTACLE_RADIUS < TABLE_HEIGHT:
            raise ScenarioError(
                f"obstacle_xyz z = {o[2]} m: the ball (radius {OBSTACLE_RADIUS} m) overlaps the "
                f"table (top at {TABLE_HEIGHT} m); its centre must be at least "
                f"{TABLE_HEIGHT + OBSTACLE_RADIUS + 0.05:.2f} m high"
            )
        if o[2] - OBSTACLE_RADIUS < TABLE_HEIGHT + 0.05:
            raise ScenarioError(
                f"obstacle_xyz z = {o[2]} m puts the ball within 5 cm of the table top "
                f"({TABLE_HEIGHT} m); raise it"
            )
        for name in (
            "coaster_move_delay",
            "coaster_move_duration",
            "obstacle_gamma",
            "obstacle_beta",
            "obstacle_length_scale",
        ):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ScenarioError(f"{name} must be finite and >= 0, got {value}")
        pts = np.asarray(self.obstacle_points, dtype=float)
        if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0 or not np.all(np.isfinite(pts)):
            raise ScenarioError(
                "obstacle_points must list one or more [x, y, z] points, got "
                f"{self.obstacle_points}"
            )
        home_gap = ball_gap_at_home(o)
        if home_gap <= 0.0:
            raise ScenarioError(
                f"obstacle_xyz {list(map(float, o))} puts the ball inside the arm at its start "
                f"(home configuration, hand open; overlap {-home_gap * 100:.1f} cm); move it away"
            )
        # The ball must not overlap the cup where it starts or where it is put down.
        bottom = TABLE_HEIGHT
        placed = TABLE_HEIGHT + COASTER_TOP + PLACE_CLEARANCE
        for what, xy, z0 in (
            ("the cup at its start (cup_xy)", self.cup_xy, bottom),
            ("the cup placed on the coaster (coaster_xy)", self.coaster_xy, placed),
            (
                "the cup placed on the moved coaster (coaster_final_xy)",
                self.coaster_final_xy,
                placed,
            ),
        ):
            gap = _ball_cylinder_gap(o, np.asarray(xy, float), z0, CUP_RADIUS, CUP_HEIGHT)
            if gap <= 0.0:
                raise ScenarioError(
                    f"obstacle_xyz {list(map(float, o))} puts the ball inside {what} "
                    f"(overlap {-gap * 100:.1f} cm); the ball must stay clear of the start and "
                    "the goal"
                )


@dataclasses.dataclass
class ServingScenario:
    """Grasp a bottle and pour over three cups (Fig. 12).

    Attributes:
        time_step: discrete plant time step [s].
        contact_approximation: ``sap`` (default, :data:`DMP_CONTACT_APPROXIMATION`), ``lagged``
            or ``similar``.
        grasp_mode: ``contact`` (finger friction) or ``grip`` (GraspWrench latch).
        bottle_xy: the bottle's position on the table [m].
        cup_xys: the three cups' positions [m], poured over in this order.
        settle_time: pause after each DMP's tau before the next segment starts [s].
    """

    time_step: float = 0.004
    contact_approximation: str = DMP_CONTACT_APPROXIMATION
    grasp_mode: str = "contact"
    bottle_xy: list[float] = dataclasses.field(default_factory=lambda: [0.52, -0.28])
    cup_xys: list[list[float]] = dataclasses.field(
        default_factory=lambda: [[0.64, -0.10], [0.68, 0.04], [0.64, 0.18]]
    )
    settle_time: float = 0.2

    def validate(self) -> None:
        """Raises ScenarioError on the first bad field."""
        _check_common(self)
        _check_xy("bottle_xy", self.bottle_xy)
        if len(self.cup_xys) != 3:
            raise ScenarioError(f"cup_xys must list three cups, got {len(self.cup_xys)}")
        for k, xy in enumerate(self.cup_xys):
            _check_xy(f"cup_xys[{k}]", xy)


# ----------------------------------------------------------------------------- world parts
@dataclasses.dataclass
class CoasterMotion:
    """A coaster that slides from ``xy`` to ``final_xy`` between ``t0`` and ``t1`` (Fig. 13).

    Attributes:
        xy: Start position on the table [m].
        final_xy: End position [m].
        t0: Time the move starts [s].
        t1: Time the move ends [s] (> t0).
    """

    xy: list[float]
    final_xy: list[float]
    t0: float
    t1: float


@dataclasses.dataclass
class BallObstacle:
    """The ball obstacle of a world and the DMP coupling term around it (eq. 10).

    Attributes:
        xyz: Centre of the ball [m] (radius ``models.arm7.OBSTACLE_RADIUS``).
        coupling: Add the coupling term to the DMP chain (False: only the monitor).
        gamma: Coupling gain.
        beta: Coupling steering constant.
        points: Control points in the tcp frame E [m] (see CARRY_CONTROL_POINTS).
        length_scale: Distance fade of the coupling [m] (0 = the paper's, no fade).
    """

    xyz: list[float]
    coupling: bool
    gamma: float
    beta: float
    points: list[list[float]]
    length_scale: float


@dataclasses.dataclass
class BodyPointLog:
    """An extra named logger ``<name>_log`` of a body-fixed point and the body's z axis.

    Attributes:
        name: Logger name prefix.
        body: Body name.
        instance: Model instance name.
        p_BQ: The point in the body frame [m].
    """

    name: str
    body: str
    instance: str
    p_BQ: list[float]


def shoulder_and_reach() -> tuple[np.ndarray, float]:
    """Shoulder centre in W and the reach bound of the tcp (joint polyline length)."""
    plant = arm_control_plant()
    context = plant.CreateDefaultContext()
    shoulder = plant.GetFrameByName(SHOULDER_FRAME).CalcPoseInWorld(context).translation()
    points = [shoulder]
    for name in ARM_JOINTS:
        points.append(
            plant.GetJointByName(name).frame_on_child().CalcPoseInWorld(context).translation()
        )
    points.append(plant.GetFrameByName(TCP_FRAME).CalcPoseInWorld(context).translation())
    return shoulder, reach_bound(np.array(points))


#: A goal pose is attainable when the tcp can come this close to its position [m] (the
#: default world ends its place and release segments about 9 mm from their goals) ...
GOAL_POSITION_TOLERANCE = 0.01
#: ... with its orientation within this angle of the goal's [rad] (about 3 degrees; the
#: controller ends the default world's segments within 0.6 degrees of the goal's approach
#: axis, a place near the edge of the workspace within 2.8 degrees).
GOAL_ORIENTATION_TOLERANCE = 0.05


@functools.lru_cache(maxsize=1)
def _goal_ik_plant():
    """arm7's seven arm joints (fingers welded open) and the IK seeds of goal_pose_residual.

    The seeds: the home configuration, then eight fixed draws within the joint limits
    (tried only when the home seed leaves the goal farther than the tolerance).
    """
    plant = make_arm7_control_plant(finger_positions=HAND_OPEN)
    lower, upper = plant.GetPositionLowerLimits(), plant.GetPositionUpperLimits()
    rng = np.random.default_rng(0)
    seeds = [arm7_home_configuration()] + [rng.uniform(lower, upper) for _ in range(8)]
    return plant, plant.GetFrameByName(TCP_FRAME), seeds


def goal_pose_residual(p_W: np.ndarray, quaternion: np.ndarray) -> float:
    """How close arm7's tcp can come to ``p_W`` with the orientation ``quaternion`` [m].

    :func:`repertoire.systems.task_space_reach.pose_position_residual` on arm7 (joint limits,
    orientation within GOAL_ORIENTATION_TOLERANCE), seeded from the home configuration
    (then fixed draws when that leaves more than GOAL_POSITION_TOLERANCE).

    Args:
        p_W: the tcp goal position in W (3).
        quaternion: the tcp goal orientation [w, x, y, z] (unit).
    """
    plant, frame, seeds = _goal_ik_plant()
    q = np.asarray(quaternion, dtype=float)
    R_WE = RotationMatrix(Quaternion(q / np.linalg.norm(q)))
    return pose_position_residual(
        plant,
        frame,
        p_W,
        R_WE,
        seeds,
        orientation_tolerance=GOAL_ORIENTATION_TOLERANCE,
        good_enough=GOAL_POSITION_TOLERANCE,
    )


def _default_layout(scenario_type: type, fields: tuple[str, ...]) -> str:
    """The default values of a scenario's position fields, for an error message."""
    defaults = scenario_type()
    return " and ".join(f"{name} {getattr(defaults, name)}" for name in fields)


def _check_goal_attainable(
    field: str, xy, what: str, p_W: np.ndarray, quaternion, layout: str
) -> None:
    """ScenarioError naming ``field`` when the tcp cannot attain the goal pose ``p_W``.

    ``layout``: the default layout's fields, named in the message as attainable.
    """
    residual = goal_pose_residual(p_W, quaternion)
    if residual > GOAL_POSITION_TOLERANCE:
        closest = "no IK solution" if not np.isfinite(residual) else f"{residual:.3f} m"
        raise ScenarioError(
            f"{field} {[float(v) for v in xy]}: the arm cannot attain the {what} "
            f"{np.round(p_W, 3).tolist()} with the orientation the motion needs (within "
            f"{GOAL_ORIENTATION_TOLERANCE} rad): inverse kinematics within the joint limits "
            f"brings the tcp no closer than {closest} (tolerance {GOAL_POSITION_TOLERANCE} m); "
            f"the goal is inside the arm's reach sphere but not attainable; move it (the default "
            f"layout's {layout} are attainable)"
        )


#: Segments that set the held object down (their goal places the held object,
#: ``SegmentGoal.places_held``: shifted by where the object sits in the hand) ...
PLACING_LABELS = ("place",)
#: ... and the segment after one waits (``DmpSequencer`` ``start_gates``) until the object
#: stands within this distance of its target horizontally (the coaster's centre) ...
#: Pastor et al. start a DMP "after the preceding DMP has been executed completely" (sec.
#: III-C); what has to be complete here is the object's placing, not the DMP's state: at its
#: due time the place DMP is still 1.5-1.9 mm from its goal (eq. 2's ``-K (g - x0) s`` with
#: ``s`` 0.7 % of its start, decaying at ``alpha / tau`` = 1.5 /s: within 1 mm about 0.4 s
#: later), and a goal for the tcp alone put the cup's offset in the hand (up to a few mm:
#: it slides while carried) on the coaster. 1 mm is a twentieth of the 2 cm a placed cup
#: may stand off the coaster's centre.
PLACE_TOLERANCE = 0.001
#: ... and moves slower than this relative to it [m/s] (nearly at rest). The release hands
#: its start velocity on from the place DMP (sec. III-C), so the hand carries the cup on at
#: about that speed until the opening fingers let go of it, about
#: :data:`PLACE_LET_GO_TIME` later; at this speed that carries it half the tolerance.
PLACE_LET_GO_TIME = 0.3
PLACE_REST_SPEED = 0.5 * PLACE_TOLERANCE / PLACE_LET_GO_TIME
#: The longest a segment waits (then it starts anyway and the world reports the object as
#: not settled); the duration of a world includes it, so the last segment still runs to its
#: end.
MAX_SEGMENT_WAIT = 1.0


def segment_gates(labels: list[str]) -> list[bool]:
    """Per segment, whether it waits for the object its predecessor placed to settle.

    Args:
        labels: Motion-library labels of the segments, in order.
    """
    return [False] + [labels[k - 1] in PLACING_LABELS for k in range(1, len(labels))]


def segment_timing(labels: list[str], settle: float) -> tuple[list[float], float]:
    """Earliest start time of each segment of a chain and the total duration [s].

    A segment that waits for a placed object (:func:`segment_gates`) may start up to
    :data:`MAX_SEGMENT_WAIT` later (and so every segment after it); the duration includes
    those waits.

    Args:
        labels: Motion-library labels of the segments, in order.
        settle: Settling time after each segment [s].
    """
    lib = motion_library()
    starts, t = [], 0.0
    for label in labels:
        starts.append(t)
        t += lib[label].tau + settle
    waits = sum(segment_gates(labels))
    return starts, t + waits * MAX_SEGMENT_WAIT


def held_segments(labels: list[str]) -> list[int]:
    """Indices of the segments during which the hand holds the grasped object.

    The segments after the first ``grasp`` up to the first ``release`` after it (to the
    end without one); none without a ``grasp``.

    Args:
        labels: Motion-library labels of the segments, in order.
    """
    if "grasp" not in labels:
        return []
    first = labels.index("grasp") + 1
    rest = labels[first:]
    end = first + (rest.index("release") if "release" in rest else len(rest))
    return list(range(first, end))


# ----------------------------------------------------------------------------- segment goals
PICK_PLACE_LABELS = ["grasp", "place", "release"]
SERVING_LABELS = ["grasp", "pour", "retreat", "pour", "retreat", "pour", "retreat"]


def place_offset() -> np.ndarray:
    """The tcp above the coaster's origin when the cup stands on it [m] (3)."""
    return np.array([0.0, 0.0, COASTER_TOP + CUP_GRASP_HEIGHT + PLACE_CLEARANCE])


RELEASE_OFFSET = np.array([-0.12, 0.0, 0.08])


def plan_pick_and_place(s: PickPlaceScenario) -> tuple[list[SegmentGoal], float]:
    """Goals of grasp -> place -> release for a scenario (sec. IV-C, IV-E).

    The grasp goal is the cup's grasp point, its orientation computed from the
    approach direction of the grasp DMP rolled out to that goal; the place and
    release goals follow the coaster (their orientations are the demonstration's); the
    place goal places the held cup (``places_held``: shifted by the cup's offset from the
    tcp's axis in the hand, so the cup, not the tcp, lands on the coaster's centre).

    Returns:
        (goals, duration of the whole sequence in s).

    Raises:
        RepertoireError: a goal outside the arm's reach sphere (:func:`check_reachable`).
        ScenarioError: a goal pose inside it that the arm cannot attain
            (:func:`goal_pose_residual` above GOAL_POSITION_TOLERANCE), naming the field
            (cup_xy, coaster_xy or coaster_final_xy) and the residual.
    """
    grasp_primitive, place_primitive, release_primitive = arm_motion_library().compose(
        "pick_and_place", robot="arm7"
    )
    home = home_tcp_pose()
    cup = np.array([*s.cup_xy, TABLE_HEIGHT + CUP_GRASP_HEIGHT])
    R_grasp = rotation_from_approach(
        approach_direction(grasp_primitive.dmp, home.translation(), cup)
    )
    grasp, open_ = np.array(HAND_GRASP_7CM), np.array(HAND_OPEN)
    q_side = quaternion_wxyz(R_SIDE)
    goals = [
        SegmentGoal(grasp_primitive.label, cup, quaternion_wxyz(R_grasp), grasp),
        SegmentGoal(
            place_primitive.label,
            place_offset(),
            q_side,
            grasp,
            "coaster:coaster",
            places_held=place_primitive.label in PLACING_LABELS,
        ),
        SegmentGoal(
            release_primitive.label,
            place_offset() + RELEASE_OFFSET,
            q_side,
            open_,
            "coaster:coaster",
        ),
    ]
    # The reach sphere first (cheap, and its message says by how much), then inverse
    # kinematics of each goal pose: a pose inside the sphere may still be unattainable
    # (joint limits, the side grasp's orientation), and the run would then end far from it.
    shoulder, reach = shoulder_and_reach()
    check_reachable(cup, shoulder, reach, what="grasp goal")
    layout = _default_layout(PickPlaceScenario, ("cup_xy", "coaster_xy"))
    _check_goal_attainable("cup_xy", s.cup_xy, "grasp goal", cup, goals[0].orientation, layout)
    for xy_name in ("coaster_xy", "coaster_final_xy"):
        xy = getattr(s, xy_name)
        base = np.array([xy[0], xy[1], COASTER_RAIL_HEIGHT])
        check_reachable(base + place_offset(), shoulder, reach, what=f"place goal ({xy_name})")
        check_reachable(
            base + place_offset() + RELEASE_OFFSET, shoulder, reach, what=f"release ({xy_name})"
        )
    for xy_name in ("coaster_xy", "coaster_final_xy"):
        xy = getattr(s, xy_name)
        base = np.array([xy[0], xy[1], COASTER_RAIL_HEIGHT])
        for goal in goals[1:]:
            _check_goal_attainable(
                xy_name, xy, f"{goal.label} goal", base + goal.position, goal.orientation, layout
            )
    _, duration = segment_timing(PICK_PLACE_LABELS, s.settle_time)
    return goals, duration


def plan_serving(s: ServingScenario) -> tuple[list[SegmentGoal], float]:
    """Goals of grasp(bottle) -> (pour -> retreat) x 3 cups (sec. IV-E, Fig. 12).

    Returns:
        (goals, duration of the whole sequence in s).

    Raises:
        RepertoireError: a goal outside the arm's reach sphere (:func:`check_reachable`).
        ScenarioError: a goal pose inside it that the arm cannot attain
            (:func:`goal_pose_residual` above GOAL_POSITION_TOLERANCE), naming the field
            (bottle_xy or cup_xys[k]) and the residual.
    """
    lib = motion_library()
    home = home_tcp_pose()
    bottle = np.array([*s.bottle_xy, TABLE_HEIGHT + BOTTLE_GRASP_HEIGHT])
    R_grasp = rotation_from_approach(approach_direction(lib["grasp"], home.translation(), bottle))
    grasp = np.array(HAND_GRASP_7CM)
    goals = [SegmentGoal("grasp", bottle, quaternion_wxyz(R_grasp), grasp)]
    for xy in s.cup_xys:
        pour = pour_tcp_position(xy, R_POUR)
        goals.append(SegmentGoal("pour", pour, quaternion_wxyz(R_POUR), grasp))
        goals.append(
            SegmentGoal("retreat", pour + [0.0, 0.0, 0.06], quaternion_wxyz(R_SIDE), grasp)
        )
    # As plan_pick_and_place: the reach sphere, then inverse kinematics of each goal pose
    # (a pour over a cup near the torso column or the arm's side needs a wrist pose the
    # joint limits may not allow).
    shoulder, reach = shoulder_and_reach()
    fields = ["bottle_xy"] + [f"cup_xys[{k}]" for k in range(len(s.cup_xys)) for _ in range(2)]
    xys = [s.bottle_xy] + [xy for xy in s.cup_xys for _ in range(2)]
    layout = _default_layout(ServingScenario, ("bottle_xy", "cup_xys"))
    for field, xy, goal in zip(fields, xys, goals, strict=True):
        what = f"{goal.label} goal"
        check_reachable(goal.position, shoulder, reach, what=f"{what} ({field})")
        _check_goal_attainable(field, xy, what, goal.position, goal.orientation, layout)
    _, duration = segment_timing(SERVING_LABELS, s.settle_time)
    return goals, duration
