"""DMP-driven arm7 worlds of the DMP paper: pick-and-place (Fig. 13) and serving water (Fig. 12).

Pipeline (Pastor et al. 2009, sec. IV, Fig. 7 and 11)::

    DmpSequencer (10-D DMPs: position, quaternion, 3 fingers; grasp -> place -> ...;
      segments run one after another, each started from its predecessor's x and v)
      -> ResolvedMotionRateIK (quaternion feedback, damped least squares within the
         joint limits, null-space joint-limit avoidance; reports targets out of reach)
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
cup in hand needs about 9.5 cm) and gated off once the ball is farther than the
active goal (fed from the goal schedule), so the DMP comes to rest at its goal.
``obstacle_points: [[0, 0, 0]]`` with
``obstacle_length_scale: 0`` is the paper's term on the end-effector. An
:class:`ObstacleClearanceMonitor` records the smallest signed distance between
the ball and the arm, hand, fingers and cup (SceneGraph) for the
``collision_free`` figure.

This module is the wiring; the typed scenarios and the segment goals are in
:mod:`repertoire.diagrams.arm_dmp_scenarios`, running and scoring a world in
:mod:`repertoire.diagrams.arm_dmp_results`, the motion library in planning/arm_library.py
and the LeafSystems in systems/.
"""

import dataclasses

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
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import (
    ConstantVectorSource,
    Demultiplexer,
    LogVectorOutput,
    MatrixGain,
    Multiplexer,
    TrajectorySource,
)
from pydrake.trajectories import PiecewisePolynomial
from repertoire.diagrams.arm import ArmStation, add_arm_controllers, add_meshcat
from repertoire.diagrams.arm_dmp_results import (
    GRASP_SLIP_TOLERANCE,
    ik_status_figures,
    pick_and_place_figures,
    serving_figures,
)
from repertoire.diagrams.arm_dmp_scenarios import (
    COASTER_RAIL_HEIGHT,
    MAX_SEGMENT_WAIT,
    PICK_PLACE_LABELS,
    PLACE_REST_SPEED,
    PLACE_TOLERANCE,
    BallObstacle,
    BodyPointLog,
    CoasterMotion,
    PickPlaceScenario,
    ServingScenario,
    held_segments,
    plan_pick_and_place,
    plan_serving,
    segment_gates,
    segment_timing,
    shoulder_and_reach,
)
from repertoire.diagrams.registry import register_diagram
from repertoire.models import ConfigureParser, package_url
from repertoire.models.arm7 import (
    ALL_JOINTS,
    ARM_JOINTS,
    ARM_KD,
    ARM_KP,
    HAND_OPEN,
    OBSTACLE_RADIUS,
    TABLE_HEIGHT,
    TCP_FRAME,
    ArmObject,
    ArmWorld,
    add_arm7,
    add_arm_world,
    arm7_home_configuration,
)
from repertoire.planning.arm_library import (
    arm_motion_library,
    home_tcp_pose,
    quaternion_wxyz,
)
from repertoire.systems.arm_goals import GoalSchedule, HeldObjectOffset, SegmentGoal
from repertoire.systems.arm_monitors import (
    BodyPointAndAxis,
    GraspSlipMonitor,
    ObstacleClearanceMonitor,
    PlacementMonitor,
)
from repertoire.systems.dmp_sequencer import task_space_sequencer
from repertoire.systems.grasp import GraspWrench
from repertoire.systems.obstacle_coupling import MultiPointObstacleCoupling
from repertoire.systems.task_space import ResolvedMotionRateIK
from repertoire.systems.task_space_reach import check_reachable

from repertoire.criteria import Bound
from repertoire.errors import RepertoireError


# ----------------------------------------------------------------------------- building
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


#: Finger PD gains of the DMP worlds (the arm's are ``models.arm7.ARM_KP``/``ARM_KD``), softer
#: than ``ArmScenario.finger_kp``: [thumb, finger_1, finger_2]. The thumb closes alone against
#: the two fingers (``HAND_GRASP_7CM`` commands all three 0.49 rad past contact), so it gets
#: twice their gains: the squeeze balances with equal deflections, the object on the tcp's
#: axis. With equal gains (2, 2, 2) the thumb had to deflect twice as far as each finger,
#: which put the object L e / 3 = 14 mm towards the thumb (L = 0.085 m, e = 0.49 rad;
#: measured 13.3 mm) and the placed cup that far off the coaster's centre. The fingers' gain
#: 4/3 keeps the squeeze of before (thumb 2 x 4e/3 = 8/3 x e, each finger 2 x 2e/3 = 4/3 x e).
FINGER_KP = (8.0 / 3.0, 4.0 / 3.0, 4.0 / 3.0)
FINGER_KD = (0.08 / 3.0, 0.04 / 3.0, 0.04 / 3.0)
IK_PERIOD = 0.004
#: The barrier part of the IK's secondary objective (``ResolvedMotionRateIK`` ``limit_gain``,
#: ``limit_band``): within a quarter of its range from a limit a joint is pushed back
#: through the task's null space, at most half its velocity limit. arm7's wrist reaches its
#: limit lifting a cup over the ball left of the torso; the swivel that relieves it barely
#: moves the wrist (about 0.1 of the null direction), so it starts early. (The limits
#: themselves are constraints of the IK's solve: a saturated joint's share goes to the
#: others.)
IK_LIMIT_GAIN = 3.0
IK_LIMIT_BAND = 0.25
LOG_PERIOD = 0.02
TABLE_CENTER = [0.65, 0.0]


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
        graspable: "instance:body" of the objects the grip may hold (grip mode); a
            :class:`GraspSlipMonitor` (``grasp_slip``) watches the first in the hand
            during the segments that hold it (:func:`held_segments`).
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
            max_wait=MAX_SEGMENT_WAIT,
            start_gates=segment_gates(labels),
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
        builder.Connect(chain.GetOutputPort("tau"), coupling.GetInputPort("tau"))
        builder.Connect(o_src.get_output_port(), coupling.GetInputPort("obstacle"))
        # the active goal's position gates the term (off once the ball is past the goal)
        goal_split = builder.AddNamedSystem("coupling_goal", Demultiplexer([3, 7]))
        builder.Connect(schedule.GetOutputPort("goal"), goal_split.get_input_port(0))
        builder.Connect(goal_split.get_output_port(0), coupling.GetInputPort("goal"))
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
            limit_gain=IK_LIMIT_GAIN,
            limit_band=IK_LIMIT_BAND,
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

    held = held_segments(labels)
    if held and graspable:
        instance_name, body_name = graspable[0].split(":")
        slip = builder.AddNamedSystem(
            "grasp_slip",
            GraspSlipMonitor(
                hand_body.index(),
                plant.GetBodyByName(body_name, instances[instance_name]).index(),
                X_HTcp,
                held,
                period=IK_PERIOD,
            ),
        )
        builder.Connect(plant.get_body_poses_output_port(), slip.GetInputPort("body_poses"))
        builder.Connect(chain.GetOutputPort("segment"), slip.GetInputPort("segment"))
        object_index = plant.GetBodyByName(body_name, instances[instance_name]).index()
        _add_placement(builder, plant, chain, schedule, resolved, int(object_index))
    elif any(g.places_held for g in goals) or any(segment_gates(labels)):
        raise RepertoireError(
            f"{name}: a goal that places the held object needs a grasp before it and a "
            "graspable object (its place in the hand is measured during the hold)"
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


def _add_placement(
    builder: DiagramBuilder,
    plant: MultibodyPlant,
    chain,
    schedule: GoalSchedule,
    goals: list[SegmentGoal],
    held_object: int,
) -> None:
    """Places the held object: the goal shift and the release's start gate.

    The goals that place the held object subtract its horizontal offset from the commanded
    tcp (:class:`HeldObjectOffset`, ``held_object_offset``, sampled while it is held: the
    cup slides up to a few mm in the hand while carried, more than the grasp put it off the
    tcp's axis at the lift, and the tcp sits about 0.5 mm off the command; at most
    ``GRASP_SLIP_TOLERANCE``: farther is a grasp slip, reported as such); the segment
    after the placing one (:func:`segment_gates`) starts once a :class:`PlacementMonitor`
    (``placement``) finds the object within :data:`PLACE_TOLERANCE` of the placing goal's
    target, moving slower than :data:`PLACE_REST_SPEED` (at most :data:`MAX_SEGMENT_WAIT`
    late).

    Raises:
        RepertoireError: more than one placing segment (one start gate per chain).
    """
    if any(g.places_held for g in goals):
        offset = builder.AddNamedSystem(
            "held_object_offset",
            HeldObjectOffset(
                held_object,
                held_segments([g.label for g in goals]),
                period=IK_PERIOD,
                max_offset=GRASP_SLIP_TOLERANCE,
            ),
        )
        builder.Connect(plant.get_body_poses_output_port(), offset.GetInputPort("body_poses"))
        builder.Connect(chain.GetOutputPort("tcp_position"), offset.GetInputPort("tcp_desired"))
        builder.Connect(chain.GetOutputPort("segment"), offset.GetInputPort("segment"))
        builder.Connect(offset.GetOutputPort("offset"), schedule.GetInputPort("held_object_offset"))
    gated = [k for k, gate in enumerate(segment_gates([g.label for g in goals])) if gate]
    if not gated:
        return
    if len(gated) > 1:
        raise RepertoireError(
            f"one placing segment per chain is supported, segments {[k - 1 for k in gated]} "
            "place the held object"
        )
    target = goals[gated[0] - 1]
    placement = builder.AddNamedSystem(
        "placement",
        PlacementMonitor(
            held_object,
            target.body,
            np.asarray(target.position, float),
            tolerance=PLACE_TOLERANCE,
            speed_tolerance=PLACE_REST_SPEED,
            release_segment=gated[0],
            period=IK_PERIOD,
        ),
    )
    builder.Connect(plant.get_body_poses_output_port(), placement.GetInputPort("body_poses"))
    builder.Connect(
        plant.get_body_spatial_velocities_output_port(),
        placement.GetInputPort("body_spatial_velocities"),
    )
    builder.Connect(chain.GetOutputPort("segment"), placement.GetInputPort("segment"))
    builder.Connect(placement.GetOutputPort("settled"), chain.GetInputPort("start_gate"))


# ----------------------------------------------------------------------------- the two worlds
@register_diagram(
    "arm_pick_and_place",
    scenario_type=PickPlaceScenario,
    description="arm7 driven by learned DMPs (RMRC IK + ID/PD): grasp a cup, place it on a "
    "coaster that moves after onset, around a ball obstacle (Pastor et al. Fig. 13)",
    duration=8.75,
    check=lambda diagram, context: {
        **pick_and_place_figures(diagram, context),
        **ik_status_figures(diagram, context),
    },
    criteria={
        "success": Bound(lo=1.0),
        "collision_free": Bound(lo=1.0),
        "grasp_slipped": Bound(hi=0.0),
    },
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


@register_diagram(
    "arm_serving_water",
    scenario_type=ServingScenario,
    description="arm7 driven by learned DMPs: grasp a bottle and pour over three cups "
    "(Pastor et al. Fig. 12)",
    duration=14.1,
    check=lambda diagram, context: {
        **serving_figures(diagram, context),
        **ik_status_figures(diagram, context),
    },
    criteria={"success": Bound(lo=1.0), "cups_served": Bound(lo=3.0)},
)
def build_serving_water(scenario: ServingScenario, *, meshcat=None) -> Diagram:
    """Builds the serving-water world from a :class:`ServingScenario`.

    Arguments and errors as :func:`build_pick_and_place`.
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
