"""DMP-driven arm7 worlds of the DMP paper: pick-and-place (Fig. 13) and serving water (Fig. 12).

Pipeline (Pastor et al. 2009, sec. IV, Fig. 7 and 11)::

    DmpSequencer (10-D DMPs: position, quaternion, 3 fingers; grasp -> place -> ...;
      segments run one after another, each started from its predecessor's x and v)
      -> ResolvedMotionRateIK (quaternion feedback, damped least squares, null-space
         joint-limit avoidance; reports targets out of reach)
      -> inverse-dynamics feed-forward + joint PD (diagrams/arm.py controllers)
      -> arm7 MultibodyPlant with the hand, a table and the objects.

The movements are synthesised once as demonstrations (minimum-jerk movements
through via points for the position, minimum-jerk slerps for the orientation,
two minimum-jerk movements for opening and closing the hand, as in sec. IV-B),
learned into DMPs in planning/arm_library.py (``learn_task_space_dmp`` with the paper's component
quaternion DMP) and stored in a ``MotionLibrary`` with semantic labels (grasp,
place, release, pour, retreat); pick-and-place is recalled from it with
``compose("pick_and_place")`` (grasp -> place -> release). Only the learned DMPs drive the arm: each
segment gets its goal from the scene (the cup, the moving coaster, the cups to
pour into), and the grasp orientation is computed from the approach direction
of the grasp DMP rolled out to the new goal (sec. IV-C).

Grasping: by default the hand grasps physically, by finger contact (the
fingers' PD squeezes the object, friction holds it; ``grasp_mode: contact``).
``grasp_mode: grip`` replaces friction by :class:`GraspWrench`, a stiff
spring-damper between palm and object that latches when the commanded fingers
close around an object within 2 cm of the grasp point and lets go when they
open (a physically motivated stand-in, like a suction or magnetic gripper).

Pick-and-place: the coaster rides on two actuated prismatic joints (a small
x-y table under it) and moves ``coaster_move_delay`` seconds after the onset of
the placing movement; the placing DMP's goal input is read from the coaster's
pose in the plant every step, so the movement adapts online (sec. II-B). The
ball-like obstacle (on a post) sits on the carry path by default, where the
carried cup would hit it; it feeds the DMP's coupling term through
:class:`MultiPointObstacleCoupling`: eq. 10 at control points of the hand and
the cup (tcp, cup bottom, fingers, palm), summed, each faded with its distance
to the ball (our extension; eq. 10 alone depends only on the heading angle, and
on the tcp alone it kept the tcp just 6-8 cm from the ball's centre, while the
cup in hand needs about 9.5 cm). ``obstacle_points: [[0, 0, 0]]`` with
``obstacle_length_scale: 0`` is the paper's term on the end-effector. An
:class:`ObstacleClearanceMonitor` records the smallest signed distance between
the ball and the arm, hand, fingers and cup (SceneGraph) for the
``collision_free`` figure.

Size: over 600 lines because it still holds the two scenarios, the world builder and the
scoring of both worlds; the motion library is in planning/arm_library.py and the
LeafSystems in systems/; moving the scoring beside the studies is the next step.
"""

import dataclasses
import functools
import time

import numpy as np
from pydrake.math import RigidTransform
from pydrake.multibody.plant import AddMultibodyPlant, MultibodyPlant, MultibodyPlantConfig
from pydrake.multibody.tree import (
    FixedOffsetFrame,
    PdControllerGains,
    PrismaticJoint,
    SpatialInertia,
    UnitInertia,
)
from pydrake.systems.framework import Context, Diagram, DiagramBuilder, EventStatus
from pydrake.systems.primitives import (
    ConstantVectorSource,
    LogVectorOutput,
    MatrixGain,
    Multiplexer,
    TrajectorySource,
)
from pydrake.trajectories import PiecewisePolynomial
from repertoire.diagrams.arm import ArmStation, add_arm_controllers, add_meshcat
from repertoire.diagrams.registry import register_diagram
from repertoire.diagrams.simulate import simulate
from repertoire.models import ConfigureParser, package_url
from repertoire.models.arm7 import (
    ALL_JOINTS,
    ARM_JOINTS,
    CUP_HEIGHT,
    CUP_RADIUS,
    HAND_GRASP_7CM,
    HAND_OPEN,
    OBSTACLE_RADIUS,
    SHOULDER_FRAME,
    TABLE_HEIGHT,
    TCP_FRAME,
    ArmObject,
    ArmWorld,
    add_arm7,
    add_arm_world,
    arm7_home_configuration,
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
from repertoire.systems.arm_goals import GoalSchedule, SegmentGoal
from repertoire.systems.arm_monitors import BodyPointAndAxis, ObstacleClearanceMonitor
from repertoire.systems.dmp_sequencer import task_space_sequencer
from repertoire.systems.grasp import GraspWrench
from repertoire.systems.obstacle_coupling import MultiPointObstacleCoupling
from repertoire.systems.task_space import (
    STATUS_NAMES,
    STATUS_OK,
    STATUS_TARGET_OUT_OF_REACH,
    ResolvedMotionRateIK,
    check_reachable,
    reach_bound,
)

from repertoire.criteria import Bound
from repertoire.errors import RepertoireError, ScenarioError

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
    goal = np.array([coaster_xy[0], coaster_xy[1], COASTER_RAIL_HEIGHT]) + _place_offset()
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


# ----------------------------------------------------------------------------- scenarios
def _check_xy(name: str, xy) -> np.ndarray:
    v = np.asarray(xy, dtype=float).reshape(-1)
    if v.size != 2 or not np.all(np.isfinite(v)):
        raise ScenarioError(f"{name} must be 2 finite numbers (x, y) in m, got {xy}")
    return v


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
        contact_approximation: ``lagged``, ``sap`` or ``similar``.
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
    contact_approximation: str = "lagged"
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
    obstacle_gamma: float = 50000.0
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
        contact_approximation: ``lagged``, ``sap`` or ``similar``.
        grasp_mode: ``contact`` (finger friction) or ``grip`` (GraspWrench latch).
        bottle_xy: the bottle's position on the table [m].
        cup_xys: the three cups' positions [m], poured over in this order.
        settle_time: pause after each DMP's tau before the next segment starts [s].
    """

    time_step: float = 0.004
    contact_approximation: str = "lagged"
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


# ----------------------------------------------------------------------------- building
#: The coaster rides 1 mm above the table top (no rubbing on the table).
COASTER_RAIL_HEIGHT = TABLE_HEIGHT + 0.001


def _coaster_on_slider(plant: MultibodyPlant, xy: np.ndarray):
    """Adds the coaster on two PD-actuated prismatic joints (x, then y) just above the table.

    Returns:
        (model instance, coaster body).
    """
    from pydrake.multibody.parsing import Parser

    parser = Parser(plant)
    ConfigureParser(parser)
    (instance,) = parser.AddModels(url=package_url("arm7/coaster.sdf"))
    coaster = plant.GetBodyByName("coaster", instance)
    slider = plant.AddRigidBody(
        "coaster_slider", instance, SpatialInertia(0.05, np.zeros(3), UnitInertia.SolidSphere(0.01))
    )
    rail = plant.AddFrame(
        FixedOffsetFrame(
            "coaster_rail", plant.world_frame(), RigidTransform([0, 0, COASTER_RAIL_HEIGHT])
        )
    )
    jx = plant.AddJoint(PrismaticJoint("coaster_x", rail, slider.body_frame(), [1, 0, 0]))
    jy = plant.AddJoint(
        PrismaticJoint("coaster_y", slider.body_frame(), coaster.body_frame(), [0, 1, 0])
    )
    for joint in (jx, jy):
        actuator = plant.AddJointActuator(f"{joint.name()}_motor", joint, 50.0)
        actuator.set_controller_gains(PdControllerGains(p=400.0, d=40.0))
    jx.set_default_translation(float(xy[0]))
    jy.set_default_translation(float(xy[1]))
    return instance, coaster


#: Joint PD gains of the arm (diagrams/arm.py defaults) and of the fingers.
ARM_KP = (800.0, 800.0, 400.0, 400.0, 60.0, 60.0, 60.0)
ARM_KD = (40.0, 40.0, 20.0, 20.0, 2.0, 2.0, 2.0)
FINGER_KP = (2.0, 2.0, 2.0)
FINGER_KD = (0.02, 0.02, 0.02)
IK_PERIOD = 0.004
LOG_PERIOD = 0.02
TABLE_CENTER = [0.65, 0.0]


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


def segment_timing(labels: list[str], settle: float) -> tuple[list[float], float]:
    """Start time of each segment of a chain and the total duration [s].

    Args:
        labels: Motion-library labels of the segments, in order.
        settle: Settling time after each segment [s].
    """
    lib = motion_library()
    starts, t = [], 0.0
    for label in labels:
        starts.append(t)
        t += lib[label].tau + settle
    return starts, t


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


def build_arm_world(
    name: str,
    scenario,
    objects: list[ArmObject],
    goals: list[SegmentGoal],
    *,
    graspable: list[str],
    coaster: CoasterMotion | None = None,
    obstacle: BallObstacle | None = None,
    logs: list[BodyPointLog] | None = None,
    meshcat=None,
) -> Diagram:
    """Wires DMP chain -> RMRC IK -> ID + PD -> arm7 plant for one world (see module doc).

    Args:
        name: the Diagram's name.
        scenario: a validated scenario (time_step, contact_approximation,
            grasp_mode, settle_time).
        objects: the table's objects (table and arm are always added).
        goals: one goal per chain segment, in order (labels from the motion library).
        graspable: "instance:body" of the objects the grip may hold (grip mode).
        coaster: optional moving coaster.
        obstacle: optional ball: MultiPointObstacleCoupling (if ``coupling``) and a
            clearance monitor between the ball and the arm and the graspable objects.
        logs: extra named point loggers.
        meshcat: optional Meshcat for a visualizer.

    Raises:
        RepertoireError: a fixed goal out of the arm's reach.
    """
    shoulder, reach = shoulder_and_reach()
    for g in goals:
        if isinstance(g.body, int) and g.body < 0:
            check_reachable(g.position, shoulder, reach, what=f"{g.label} goal")
    builder = DiagramBuilder()
    config = MultibodyPlantConfig(
        time_step=scenario.time_step,
        discrete_contact_approximation=scenario.contact_approximation,
    )
    plant, scene_graph = AddMultibodyPlant(config, builder)
    arm = add_arm7(plant)
    instances = add_arm_world(plant, ArmWorld(table_center=TABLE_CENTER, objects=objects))
    coaster_instance = None
    if coaster is not None:
        coaster_instance, coaster_body = _coaster_on_slider(plant, coaster.xy)
        instances["coaster"] = coaster_instance
    for joint, p, d in zip(ALL_JOINTS, ARM_KP + FINGER_KP, ARM_KD + FINGER_KD):
        plant.GetJointActuatorByName(f"{joint}_motor", arm).set_controller_gains(
            PdControllerGains(p=p, d=d)
        )
    plant.Finalize()
    plant.SetDefaultPositions(arm, np.concatenate([arm7_home_configuration(), HAND_OPEN]))
    station = ArmStation(plant, scene_graph, arm, instances)
    controllers = add_arm_controllers(builder, station, reference_acceleration=True)
    ctrl = controllers.control_plant
    home = home_tcp_pose()
    # Tracked goals (bodies) resolved to body indices of the simulated plant.
    resolved = []
    for g in goals:
        body = g.body
        if isinstance(body, str):  # "instance:body"
            instance_name, body_name = body.split(":")
            body = int(plant.GetBodyByName(body_name, instances[instance_name]).index())
        resolved.append(dataclasses.replace(g, body=body))
    labels = [g.label for g in goals]
    starts, duration = segment_timing(labels, scenario.settle_time)
    library = arm_motion_library()
    chain = builder.AddNamedSystem(
        "dmp_chain",
        task_space_sequencer(
            [library.select(label, robot="arm7").dmp for label in labels],
            starts,
            np.concatenate([home.translation(), quaternion_wxyz(home.rotation()), HAND_OPEN]),
            switch_period=IK_PERIOD,
        ),
    )
    schedule = builder.AddNamedSystem("goal_schedule", GoalSchedule(resolved))
    builder.Connect(plant.get_body_poses_output_port(), schedule.GetInputPort("body_poses"))
    builder.Connect(chain.GetOutputPort("segment"), schedule.GetInputPort("segment"))
    for k in range(len(goals)):
        builder.Connect(schedule.GetOutputPort(f"goal_{k}"), chain.GetInputPort(f"goal_{k}"))
    if obstacle is not None and obstacle.coupling:
        coupling = builder.AddNamedSystem(
            "obstacle_coupling",
            MultiPointObstacleCoupling(
                np.asarray(obstacle.points, float),
                gamma=obstacle.gamma,
                beta=obstacle.beta,
                obstacle_radius=OBSTACLE_RADIUS,
                length_scale=obstacle.length_scale,
            ),
        )
        o_src = builder.AddNamedSystem(
            "obstacle_position", ConstantVectorSource(np.asarray(obstacle.xyz, float))
        )
        builder.Connect(chain.GetOutputPort("tcp_position"), coupling.GetInputPort("position"))
        builder.Connect(chain.GetOutputPort("tcp_velocity"), coupling.GetInputPort("velocity"))
        builder.Connect(chain.GetOutputPort("orientation"), coupling.GetInputPort("orientation"))
        builder.Connect(o_src.get_output_port(), coupling.GetInputPort("obstacle"))
        builder.Connect(coupling.GetOutputPort("coupling"), chain.GetInputPort("coupling"))
    else:
        zero = builder.AddNamedSystem("no_coupling", ConstantVectorSource(np.zeros(3)))
        builder.Connect(zero.get_output_port(), chain.GetInputPort("coupling"))

    arm_v = [ctrl.GetJointByName(j).velocity_start() for j in ARM_JOINTS]
    rmrc = builder.AddNamedSystem(
        "rmrc",
        ResolvedMotionRateIK(
            ctrl,
            ctrl.GetFrameByName(TCP_FRAME),
            arm_v,
            period=IK_PERIOD,
            reach_center=shoulder,
            max_reach=reach,
        ),
    )
    for src, dst in (
        ("tcp_position", "position_desired"),
        ("tcp_velocity", "velocity_desired"),
        ("orientation", "orientation_desired"),
        ("angular_velocity", "angular_velocity_desired"),
    ):
        builder.Connect(chain.GetOutputPort(src), rmrc.GetInputPort(dst))
    selector = builder.AddNamedSystem(
        "arm_state_selector",
        MatrixGain(
            plant.MakeStateSelectorMatrix(
                [plant.GetJointByName(j, arm).index() for j in ARM_JOINTS]
            )
        ),
    )
    builder.Connect(plant.get_state_output_port(), selector.get_input_port())
    builder.Connect(selector.get_output_port(), rmrc.GetInputPort("arm_state_measured"))
    builder.Connect(rmrc.GetOutputPort("arm_reference_state"), controllers.arm_desired_state)
    builder.Connect(
        rmrc.GetOutputPort("arm_reference_acceleration"), controllers.arm_desired_acceleration
    )
    hand_mux = builder.AddNamedSystem("hand_reference", Multiplexer([3, 3]))
    builder.Connect(chain.GetOutputPort("finger_position"), hand_mux.get_input_port(0))
    builder.Connect(chain.GetOutputPort("finger_velocity"), hand_mux.get_input_port(1))
    builder.Connect(hand_mux.get_output_port(), controllers.hand_desired_state)

    hand_body = plant.GetBodyByName("hand", arm)
    X_HTcp = plant.GetFrameByName(TCP_FRAME, arm).GetFixedPoseInBodyFrame()
    if scenario.grasp_mode == "grip":
        bodies = [
            plant.GetBodyByName(n.split(":")[1], instances[n.split(":")[0]]) for n in graspable
        ]
        grip = builder.AddNamedSystem(
            "grip",
            GraspWrench(
                hand_body.index(),
                [b.index() for b in bodies],
                num_fingers=3,
                closure_weights=np.full(3, 1.0 / 3.0),
                close_threshold=0.45,
                open_threshold=0.0,
                palm_point_H=X_HTcp.translation(),
                capture_radius=0.02,
                period=scenario.time_step,
                object_com_offsets=[b.default_com() for b in bodies],
            ),
        )
        builder.Connect(plant.get_body_poses_output_port(), grip.GetInputPort("body_poses"))
        builder.Connect(
            plant.get_body_spatial_velocities_output_port(),
            grip.GetInputPort("body_spatial_velocities"),
        )
        builder.Connect(chain.GetOutputPort("finger_position"), grip.GetInputPort("finger_command"))
        builder.Connect(
            grip.GetOutputPort("spatial_forces"), plant.get_applied_spatial_force_input_port()
        )

    if coaster is not None:
        times = [0.0, coaster.t0, coaster.t1, coaster.t1 + 1.0]
        xy0, xy1 = np.asarray(coaster.xy, float), np.asarray(coaster.final_xy, float)
        knots = np.column_stack([xy0, xy0, xy1, xy1])
        traj = PiecewisePolynomial.CubicWithContinuousSecondDerivatives(
            times, knots, np.zeros(2), np.zeros(2)
        )
        source = builder.AddNamedSystem("coaster_motion", TrajectorySource(traj, 1))
        builder.Connect(
            source.get_output_port(), plant.get_desired_state_input_port(coaster_instance)
        )

    tcp_point = builder.AddNamedSystem("tcp_point", BodyPointAndAxis(hand_body.index(), X_HTcp))
    builder.Connect(plant.get_body_poses_output_port(), tcp_point.GetInputPort("body_poses"))
    log_mux = builder.AddNamedSystem("log_mux", Multiplexer([6, 10, 1]))
    builder.Connect(tcp_point.get_output_port(), log_mux.get_input_port(0))
    builder.Connect(schedule.GetOutputPort("goal"), log_mux.get_input_port(1))
    builder.Connect(chain.GetOutputPort("segment"), log_mux.get_input_port(2))
    sink = LogVectorOutput(log_mux.get_output_port(), builder, LOG_PERIOD)
    sink.set_name("tcp_log")
    for spec in logs or []:
        body = plant.GetBodyByName(spec.body, instances[spec.instance])
        point = builder.AddNamedSystem(
            f"{spec.name}_point", BodyPointAndAxis(body.index(), RigidTransform(spec.p_BQ))
        )
        builder.Connect(plant.get_body_poses_output_port(), point.GetInputPort("body_poses"))
        s = LogVectorOutput(point.get_output_port(), builder, LOG_PERIOD)
        s.set_name(f"{spec.name}_log")
    if obstacle is not None:
        watched = [
            plant.GetBodyByName(n.split(":")[1], instances[n.split(":")[0]]) for n in graspable
        ]
        watched += [plant.get_body(i) for i in plant.GetBodyIndices(arm)]
        ids = [g for b in watched for g in plant.GetCollisionGeometriesForBody(b)]
        monitor = builder.AddNamedSystem(
            "obstacle_clearance",
            ObstacleClearanceMonitor(
                np.asarray(obstacle.xyz, float),
                OBSTACLE_RADIUS,
                ids,
                period=IK_PERIOD,
            ),
        )
        builder.Connect(scene_graph.get_query_output_port(), monitor.GetInputPort("geometry_query"))
    add_meshcat(builder, scene_graph, meshcat)
    diagram = builder.Build()
    diagram.set_name(name)
    return diagram


# ----------------------------------------------------------------------------- the two worlds
PICK_PLACE_LABELS = ["grasp", "place", "release"]
SERVING_LABELS = ["grasp", "pour", "retreat", "pour", "retreat", "pour", "retreat"]


def _place_offset() -> np.ndarray:
    return np.array([0.0, 0.0, COASTER_TOP + CUP_GRASP_HEIGHT + PLACE_CLEARANCE])


RELEASE_OFFSET = np.array([-0.12, 0.0, 0.08])


def plan_pick_and_place(s: PickPlaceScenario) -> tuple[list[SegmentGoal], float]:
    """Goals of grasp -> place -> release for a scenario (sec. IV-C, IV-E).

    The grasp goal is the cup's grasp point, its orientation computed from the
    approach direction of the grasp DMP rolled out to that goal; the place and
    release goals follow the coaster (their orientations are the demonstration's).

    Returns:
        (goals, duration of the whole sequence in s).
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
        SegmentGoal(place_primitive.label, _place_offset(), q_side, grasp, "coaster:coaster"),
        SegmentGoal(
            release_primitive.label,
            _place_offset() + RELEASE_OFFSET,
            q_side,
            open_,
            "coaster:coaster",
        ),
    ]
    shoulder, reach = shoulder_and_reach()
    for xy_name in ("coaster_xy", "coaster_final_xy"):
        xy = getattr(s, xy_name)
        base = np.array([xy[0], xy[1], COASTER_RAIL_HEIGHT])
        check_reachable(base + _place_offset(), shoulder, reach, what=f"place goal ({xy_name})")
        check_reachable(
            base + _place_offset() + RELEASE_OFFSET, shoulder, reach, what=f"release ({xy_name})"
        )
    _, duration = segment_timing(PICK_PLACE_LABELS, s.settle_time)
    return goals, duration


@register_diagram(
    "arm_pick_and_place",
    scenario_type=PickPlaceScenario,
    description="arm7 driven by learned DMPs (RMRC IK + ID/PD): grasp a cup, place it on a "
    "coaster that moves after onset, around a ball obstacle (Pastor et al. Fig. 13)",
    duration=7.75,
    check=lambda diagram, context: pick_and_place_figures(diagram, context),
    criteria={"success": Bound(lo=1.0), "collision_free": Bound(lo=1.0)},
)
def build_pick_and_place(scenario: PickPlaceScenario, *, meshcat=None) -> Diagram:
    """Builds the pick-and-place world.

    Args:
        scenario: a :class:`PickPlaceScenario` (validated here).
        meshcat: optional Meshcat for a visualizer (HTML replay).

    Raises:
        ScenarioError: bad scenario fields.
        RepertoireError: a goal out of the arm's reach.
    """
    scenario.validate()
    goals, _ = plan_pick_and_place(scenario)
    starts, _ = segment_timing(PICK_PLACE_LABELS, scenario.settle_time)
    t0 = starts[1] + scenario.coaster_move_delay
    objects = [
        ArmObject(name="cup_red", kind="cup", xy=list(scenario.cup_xy)),
        ArmObject(
            name="obstacle_blue",
            kind="obstacle",
            xy=list(scenario.obstacle_xyz[:2]),
            z_above_table=float(scenario.obstacle_xyz[2] - OBSTACLE_RADIUS - TABLE_HEIGHT),
            mount="welded",
        ),
    ]
    return build_arm_world(
        "arm_pick_and_place",
        scenario,
        objects,
        goals,
        graspable=["cup_red:cup"],
        coaster=CoasterMotion(
            xy=list(scenario.coaster_xy),
            final_xy=list(scenario.coaster_final_xy),
            t0=t0,
            t1=t0 + max(scenario.coaster_move_duration, 1e-3),
        ),
        obstacle=BallObstacle(
            xyz=list(scenario.obstacle_xyz),
            coupling=scenario.obstacle_coupling,
            gamma=scenario.obstacle_gamma,
            beta=scenario.obstacle_beta,
            points=scenario.obstacle_points,
            length_scale=scenario.obstacle_length_scale,
        ),
        meshcat=meshcat,
    )


def plan_serving(s: ServingScenario) -> tuple[list[SegmentGoal], float]:
    """Goals of grasp(bottle) -> (pour -> retreat) x 3 cups (sec. IV-E, Fig. 12).

    Returns:
        (goals, duration of the whole sequence in s).
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
    _, duration = segment_timing(SERVING_LABELS, s.settle_time)
    return goals, duration


@register_diagram(
    "arm_serving_water",
    scenario_type=ServingScenario,
    description="arm7 driven by learned DMPs: grasp a bottle and pour over three cups "
    "(Pastor et al. Fig. 12)",
    duration=14.1,
    check=lambda diagram, context: serving_figures(diagram, context),
    criteria={"success": Bound(lo=1.0), "cups_served": Bound(lo=3.0)},
)
def build_serving_water(scenario: ServingScenario, *, meshcat=None) -> Diagram:
    """Builds the serving-water world.

    Args:
        scenario: a :class:`ServingScenario` (validated here).
        meshcat: optional Meshcat for a visualizer.

    Raises:
        ScenarioError: bad scenario fields.
        RepertoireError: a goal out of the arm's reach.
    """
    scenario.validate()
    goals, _ = plan_serving(scenario)
    objects = [ArmObject(name="bottle", kind="bottle", xy=list(scenario.bottle_xy))]
    objects += [
        ArmObject(name=f"cup_{k + 1}", kind="cup", xy=list(xy))
        for k, xy in enumerate(scenario.cup_xys)
    ]
    return build_arm_world(
        "arm_serving_water",
        scenario,
        objects,
        goals,
        graspable=["bottle:bottle"],
        logs=[BodyPointLog(name="tip", body="bottle", instance="bottle", p_BQ=[0.0, 0.0, 0.25])],
        meshcat=meshcat,
    )


# ----------------------------------------------------------------------------- running
class IkTargetError(RepertoireError):
    """The task-space IK reported a target out of reach or lost tracking during a run."""


def run_arm_world(diagram: Diagram, duration: float) -> tuple[Context, float]:
    """Simulates an arm DMP world, stopping with a clear error if the IK reports a problem.

    Runs through :func:`repertoire.diagrams.simulate.simulate` (its non-finite-state check)
    with the IK-status monitor added.

    Args:
        diagram: a diagram built by this module.
        duration: simulated seconds.

    Returns:
        (final root context, wall-clock seconds of the simulation).

    Raises:
        IkTargetError: the active goal left the arm's reach, or the IK reported a
            desired position out of reach or lost tracking (says when, which segment
            and where the goal and the target were).
    """
    rmrc = diagram.GetSubsystemByName("rmrc")
    chain = diagram.GetSubsystemByName("dmp_chain")
    schedule = diagram.GetSubsystemByName("goal_schedule")
    status_port = rmrc.GetOutputPort("status")
    shoulder, reach = shoulder_and_reach()
    problem = {}

    def ik_monitor(context: Context) -> EventStatus:
        rmrc_context = rmrc.GetMyContextFromRoot(context)
        status = int(status_port.Eval(rmrc_context)[0])
        goal = schedule.GetOutputPort("goal").Eval(schedule.GetMyContextFromRoot(context))[:3]
        if status == STATUS_OK and np.linalg.norm(goal - shoulder) > reach:
            status = STATUS_TARGET_OUT_OF_REACH
        if status == STATUS_OK:
            return EventStatus.Succeeded()
        chain_context = chain.GetMyContextFromRoot(context)
        problem.update(
            status=status,
            time=context.get_time(),
            segment=int(chain.GetOutputPort("segment").Eval(chain_context)[0]),
            target=chain.GetOutputPort("tcp_position").Eval(chain_context).copy(),
            goal=goal.copy(),
            error=rmrc.GetOutputPort("task_error").Eval(rmrc_context).copy(),
        )
        return EventStatus.ReachedTermination(rmrc, STATUS_NAMES[status])

    start = time.perf_counter()
    _, root = simulate(diagram, duration, monitors=[ik_monitor])
    wall = time.perf_counter() - start
    if problem:
        distance = float(np.linalg.norm(problem["goal"] - shoulder))
        raise IkTargetError(
            f"{diagram.get_name()}: IK reported '{STATUS_NAMES[problem['status']]}' at "
            f"t = {problem['time']:.3f} s in segment {problem['segment']}: goal "
            f"{np.round(problem['goal'], 3).tolist()} ({distance:.3f} m from"
            f" the shoulder, reach {reach:.3f} m), desired tcp position "
            f"{np.round(problem['target'], 3).tolist()}, tcp error {problem['error'][0]:.3f} m; "
            "the simulation was stopped there"
        )
    return root, wall


@dataclasses.dataclass
class PointLog:
    """A logged body point and axis (``BodyPointAndAxis``), by field.

    Attributes:
        t: Sample times, shape (N,) [s].
        point: The point in world, shape (N, 3) [m].
        axis: The body's z axis in world, shape (N, 3).
    """

    t: np.ndarray
    point: np.ndarray
    axis: np.ndarray


@dataclasses.dataclass
class TcpLog(PointLog):
    """The ``tcp_log`` of an arm world, by field (``point`` is the tcp, ``axis`` the palm z).

    Attributes:
        goal: The current segment's goal (position 3, quaternion 4, fingers 3), (N, 10).
        segment: Index of the running chain segment, shape (N,).
    """

    goal: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 10)))
    segment: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0, dtype=int))


def point_log(diagram: Diagram, context: Context, name: str) -> PointLog:
    """The samples of a point logger (``"tip_log"``, ...) of an arm world.

    Args:
        diagram: The arm world.
        context: Its root context after a run.
        name: The logger's name.
    """
    log = diagram.GetSubsystemByName(name).FindLog(context)
    data = log.data().T
    return PointLog(log.sample_times().copy(), data[:, 0:3], data[:, 3:6])


def tcp_log(diagram: Diagram, context: Context) -> TcpLog:
    """The arm world's ``tcp_log``: tcp, palm axis, segment goal and segment index.

    Args:
        diagram: The arm world.
        context: Its root context after a run.
    """
    log = diagram.GetSubsystemByName("tcp_log").FindLog(context)
    data = log.data().T
    return TcpLog(
        log.sample_times().copy(),
        data[:, 0:3],
        data[:, 3:6],
        data[:, 6:16],
        data[:, 16].astype(int),
    )


def segment_reach_errors(diagram: Diagram, context: Context) -> list[float]:
    """|tcp - goal| at the end of each segment (the last log sample of the segment) [m]."""
    log = tcp_log(diagram, context)
    errors = []
    for k in range(int(log.segment.max()) + 1):
        rows = np.nonzero(log.segment == k)[0]
        if len(rows):
            last = rows[-1]
            errors.append(float(np.linalg.norm(log.point[last] - log.goal[last, :3])))
    return errors


def pick_and_place_figures(diagram: Diagram, context: Context) -> dict[str, float]:
    """Figures of a pick-and-place run (also the registry's check).

    Returns:
        ``cup_to_coaster_m`` (horizontal), ``cup_height_above_coaster_m`` (cup bottom
        above the coaster top), ``cup_tilt_rad``, ``min_obstacle_clearance_m`` (tcp
        to the ball's surface), ``grasp_reach_error_m``, ``place_reach_error_m``,
        ``success`` (1 if the cup stands on the coaster within 2 cm of its centre),
        ``min_ball_gap_m`` (smallest signed distance between the ball and any collision
        geometry of the arm, the hand, the fingers or the cup over the run, from
        SceneGraph every 4 ms; negative = they touched), ``min_ball_gap_time_s``
        (when) and ``collision_free`` (1 if ``min_ball_gap_m > 0``).
    """
    plant = diagram.GetSubsystemByName("plant")
    pc = plant.GetMyContextFromRoot(context)
    X_cup = plant.GetBodyByName("cup", plant.GetModelInstanceByName("cup_red")).EvalPoseInWorld(pc)
    X_coaster = plant.GetBodyByName(
        "coaster", plant.GetModelInstanceByName("coaster")
    ).EvalPoseInWorld(pc)
    d_xy = float(np.linalg.norm(X_cup.translation()[:2] - X_coaster.translation()[:2]))
    height = float(X_cup.translation()[2] - (X_coaster.translation()[2] + COASTER_TOP))
    tilt = float(np.arccos(np.clip(X_cup.rotation().matrix()[2, 2], -1, 1)))
    obstacle = plant.GetBodyByName(
        "obstacle", plant.GetModelInstanceByName("obstacle_blue")
    ).EvalPoseInWorld(pc)
    tcp = tcp_log(diagram, context).point
    clearance = float(
        np.min(np.linalg.norm(tcp - obstacle.translation(), axis=1)) - OBSTACLE_RADIUS
    )
    monitor = diagram.GetSubsystemByName("obstacle_clearance")
    gap, gap_time = monitor.get_output_port().Eval(monitor.GetMyContextFromRoot(context))
    errors = segment_reach_errors(diagram, context) + [np.nan] * 3
    success = d_xy < 0.02 and abs(height) < 0.01 and tilt < 0.2
    return {
        "cup_to_coaster_m": d_xy,
        "cup_height_above_coaster_m": height,
        "cup_tilt_rad": tilt,
        "min_obstacle_clearance_m": clearance,
        "grasp_reach_error_m": errors[0],
        "place_reach_error_m": errors[1],
        "success": float(success),
        "min_ball_gap_m": float(gap),
        "min_ball_gap_time_s": float(gap_time),
        "collision_free": float(gap > 0.0),
    }


#: The tip must come within this horizontal distance of a cup's axis (inside the rim).
POUR_RADIUS = 0.03
#: Tilt of the bottle above which it counts as pouring [rad].
POUR_MIN_TILT = np.pi / 3


def serving_figures(diagram: Diagram, context: Context) -> dict[str, float]:
    """Figures of a serving run (also the registry's check).

    Returns:
        ``tip_to_cup_k_m`` (k = 1..3): closest horizontal distance of the bottle tip to
        cup k while the bottle is tilted past 60 degrees during that cup's pour;
        ``cups_served`` (how many within 3 cm), ``max_cup_displacement_m`` (how far
        the bottle or the hand pushed a cup), ``bottle_in_hand_m`` (bottle grasp
        point to tcp at the end), ``grasp_reach_error_m``, ``pour_reach_error_m``
        (largest over the pours), ``success`` (1 if all three cups were served and
        none was pushed by more than 1 cm).
    """
    plant = diagram.GetSubsystemByName("plant")
    pc = plant.GetMyContextFromRoot(context)
    tip = point_log(diagram, context, "tip_log")  # the bottle tip and the bottle's z axis
    tcp = tcp_log(diagram, context)
    n = min(len(tip.t), len(tcp.t))
    tip_xy, segments = tip.point[:n, :2], tcp.segment[:n]
    tilt = np.arccos(np.clip(tip.axis[:n, 2], -1.0, 1.0))
    figures = {}
    served = 0
    knocked = 0.0
    for k in range(3):
        cup = plant.GetBodyByName("cup", plant.GetModelInstanceByName(f"cup_{k + 1}"))
        p_cup = plant.GetDefaultFloatingBaseBodyPose(cup).translation()
        knocked = max(knocked, float(np.linalg.norm(cup.EvalPoseInWorld(pc).translation() - p_cup)))
        rows = ((segments == 1 + 2 * k) | (segments == 2 + 2 * k)) & (tilt > POUR_MIN_TILT)
        d = np.linalg.norm(tip_xy[rows] - p_cup[:2], axis=1) if rows.any() else [np.inf]
        figures[f"tip_to_cup_{k + 1}_m"] = float(np.min(d))
        served += int(np.min(d) < POUR_RADIUS)
    bottle = plant.GetBodyByName("bottle", plant.GetModelInstanceByName("bottle"))
    X_B = bottle.EvalPoseInWorld(pc)
    grasp_point = X_B @ np.array([0, 0, BOTTLE_GRASP_HEIGHT])
    errors = segment_reach_errors(diagram, context)
    figures.update(
        cups_served=float(served),
        max_cup_displacement_m=knocked,
        bottle_in_hand_m=float(np.linalg.norm(grasp_point - tcp.point[n - 1])),
        grasp_reach_error_m=errors[0],
        pour_reach_error_m=float(max(errors[1::2][:3])) if len(errors) > 1 else np.nan,
        success=float(served == 3 and knocked < 0.01),
    )
    return figures
