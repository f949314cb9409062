"""The soccer world with the GoToPose action wired (``soccer_goto_pose``, ``..._run_up``).

Registered twice: ``soccer_goto_pose`` goes to a pose at rest, and
``soccer_goto_pose_run_up`` to a target speed the robot must run up to.

The differential-drive robot on the soccer field (diagrams/diffdrive.py) is
driven by :class:`~repertoire.systems.go_to_pose.GoToPose`: the plant's state
feeds a :class:`DiffDriveStateReader`, whose ``[x, y, phi, v]`` goes to the
action; the action's ``[v, omega]`` command becomes wheel speeds (the ideal
rolling map of ``wheel_speeds_for_twist``) and the wheels' desired state. The
target is a constant source named ``target`` (a plan executor would replace it).
"""

import dataclasses
import math

import numpy as np
from pydrake.math import RollPitchYaw
from pydrake.systems.framework import Context, Diagram, DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, MatrixGain
from repertoire.diagrams.biped import validate_discrete_control_fields
from repertoire.diagrams.diffdrive import (
    TRACK,
    WHEEL_RADIUS,
    add_robot_in_world,
    check_start_clear,
)
from repertoire.diagrams.registry import register_diagram
from repertoire.models.diffdrive import MAX_FORWARD_SPEED, MAX_WHEEL_SPEED
from repertoire.systems.go_to_pose import ActionStatus, DiffDriveStateReader, GoToPose

from repertoire.criteria import Bound
from repertoire.errors import RepertoireError, ScenarioError

BALL_POSITION = (1.0, 0.5)  # the ball's default position in models/diffdrive/soccer.sdf
GOAL_POSTS = ((3.0, 0.75), (3.0, -0.75), (-3.0, 0.75), (-3.0, -0.75))
"""Centres of the goals' posts (radius ``POST_RADIUS``) in models/diffdrive/soccer.sdf [m]."""
POST_RADIUS = 0.05
GOAL_NETS = (3.4, 0.015, 0.75)
"""The nets: boxes at ``x = +-3.4`` of half thickness 0.015 and half width 0.75 [m]."""
FOOTPRINT_RADIUS = 0.32
"""A disc holding the diffdrive base (chassis corners and wheels) [m]."""
FIELD = (-3.0, 3.0, -2.0, 2.0)
"""The field inside its lines, ``(x_min, x_max, y_min, y_max)`` [m] (DribbleBall's workspace)."""


def check_on_field(pose, field: str) -> None:
    """Refuses a pose (a GoToPose target, a start, a refined subgoal) off the field.

    Args:
        pose: ``[x, y, ...]``.
        field: the scenario field (e.g. ``targets[1]``), named in the error.

    Raises:
        ScenarioError: naming the field and its value.
    """
    x_min, x_max, y_min, y_max = FIELD
    if not (x_min <= pose[0] <= x_max and y_min <= pose[1] <= y_max):
        raise ScenarioError(
            f"{field} {list(pose)} lies off the field: x must be in [{x_min}, {x_max}] and "
            f"y in [{y_min}, {y_max}] m"
        )


def clear_of_goals(x, y) -> np.ndarray:
    """True where the robot's footprint disc at ``(x, y)`` touches no goal post or net.

    The robot's start, a dribble's destination or an asserted subgoal there would
    otherwise put it into a goal (the crossbar is above the robot).
    """
    x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
    ok = np.ones(x.shape, dtype=bool)
    for px, py in GOAL_POSTS:
        ok &= np.hypot(x - px, y - py) >= FOOTPRINT_RADIUS + POST_RADIUS
    cx, half_x, half_y = GOAL_NETS
    u = np.maximum(np.abs(np.abs(x) - cx) - half_x, 0.0)
    w = np.maximum(np.abs(y) - half_y, 0.0)
    return ok & (np.hypot(u, w) >= FOOTPRINT_RADIUS)


def check_target_clear(target, field: str) -> None:
    """Refuses a GoToPose target whose footprint disc touches a goal post or net.

    The robot could never stand there (it would push against the goal until its
    timeout), so such a target is bad input, like a start inside a body.

    Args:
        target: ``[x_g, y_g, ...]``.
        field: the scenario field (e.g. ``targets[1]``), named in the error.

    Raises:
        ScenarioError: naming the field and its value.
    """
    if not clear_of_goals(target[0], target[1]):
        raise ScenarioError(
            f"{field} {list(target)} puts the robot (footprint radius {FOOTPRINT_RADIUS} m) "
            f"into a goal post or net (posts at {GOAL_POSTS}, nets at x = +-{GOAL_NETS[0]}); "
            "place it clear"
        )


def draw_start_xy(rng: np.random.Generator, x_range, y_range, min_ball_clearance: float):
    """A start ``(x, y)`` uniform in the ranges, clear of the ball and the goals.

    At least ``min_ball_clearance`` from the ball (at ``BALL_POSITION``) and
    :func:`clear_of_goals`; other draws are redrawn.

    Raises:
        RepertoireError: no such start in 1000 draws.
    """
    bx, by = BALL_POSITION
    for _ in range(1000):
        x, y = rng.uniform(*x_range), rng.uniform(*y_range)
        if math.hypot(x - bx, y - by) >= min_ball_clearance and clear_of_goals(x, y):
            return x, y
    raise RepertoireError(
        "no start outside min_start_clearance and clear of the goals in the x/y ranges"
    )


@dataclasses.dataclass
class GoToPoseScenario:
    """The robot on the soccer field going to a pose.

    Attributes:
        initial_pose: ``[x, y, yaw]`` of the chassis.
        initial_speed: forward speed at the start [m/s].
        target: ``[x_g, y_g, phi_g, v_g]``.
        time_step: plant step [s].
        control_period: GoToPose update period [s].
        contact_approximation: discrete contact approximation.
        wheel_kd: wheel velocity gain.
        ground_friction: ground friction coefficient.
        gains: overrides of GoToPose's gains (``GOTO_GAINS`` keys).
    """

    initial_pose: list[float] = dataclasses.field(default_factory=lambda: [-1.0, -0.5, 0.0])
    initial_speed: float = 0.0
    target: list[float] = dataclasses.field(default_factory=lambda: [0.6, 0.5, 0.0, 0.0])
    time_step: float = 5e-3
    control_period: float = 0.02
    contact_approximation: str = "lagged"
    wheel_kd: float = 2.0
    ground_friction: float = 1.0
    gains: dict[str, float] = dataclasses.field(default_factory=dict)

    def validate(self) -> None:
        """Raises ScenarioError naming the first bad field."""
        if len(self.initial_pose) != 3 or not np.all(np.isfinite(self.initial_pose)):
            raise ScenarioError(f"initial_pose must be 3 finite values, got {self.initial_pose}")
        if len(self.target) != 4 or not np.all(np.isfinite(self.target)):
            raise ScenarioError(f"target must be 4 finite values, got {self.target}")
        check_initial_speed(self.initial_speed)
        check_on_field(self.initial_pose, "initial_pose")
        check_target_clear(self.target, "target")
        check_on_field(self.target, "target")
        validate_discrete_control_fields(self)


def check_initial_speed(speed: float) -> None:
    """Raises ScenarioError unless ``speed`` [m/s] is finite and within the robot's top speed.

    A start faster than the wheels can turn (their URDF velocity limit) is no state the
    robot can be in: at 1e6 m/s the contact solver failed with a bare "factorization not
    ready", or a plan ran to a chassis 4e10 m away.
    """
    if not (np.isfinite(speed) and abs(speed) <= MAX_FORWARD_SPEED):
        raise ScenarioError(
            f"initial_speed must be finite and within +-{MAX_FORWARD_SPEED:.4g} m/s (wheel "
            f"speed limit {MAX_WHEEL_SPEED:g} rad/s x radius {WHEEL_RADIUS:g} m), got {speed}"
        )


def twist_to_wheel_state_matrix() -> np.ndarray:
    """``(4, 2)`` map from ``[v, omega]`` to the wheels' desired state ``[q_l, q_r, w_l, w_r]``."""
    r, b = WHEEL_RADIUS, TRACK
    return np.vstack([np.zeros((2, 2)), [[1 / r, -b / (2 * r)], [1 / r, b / (2 * r)]]])


def add_soccer_robot(builder: DiagramBuilder, scenario, extra=None):
    """The diffdrive robot on the soccer field with its ``state_reader`` connected.

    ``scenario`` gives ``initial_pose``, ``time_step``, ``contact_approximation``,
    ``wheel_kd`` and ``ground_friction``; ``extra(plant, robot)``, if given, adds more
    geometry before the plant is finalized.

    Returns:
        ``(plant, scene_graph, robot, reader)``.
    """
    plant, scene_graph, robot = add_robot_in_world(
        builder,
        world="soccer",
        initial_pose=scenario.initial_pose,
        time_step=scenario.time_step,
        contact_approximation=scenario.contact_approximation,
        wheel_kd=scenario.wheel_kd,
        ground_friction=scenario.ground_friction,
        extra=extra,
    )
    reader = builder.AddNamedSystem("state_reader", DiffDriveStateReader(plant))
    builder.Connect(plant.get_state_output_port(), reader.get_input_port())
    return plant, scene_graph, robot, reader


def build_driven(
    builder, plant, scene_graph, robot, command_port, name, meshcat, *, start_fields: dict[str, str]
) -> Diagram:
    """Feeds ``[v, omega]`` from ``command_port`` to the wheels and builds the diagram ``name``.

    Adds ``wheel_desired_state`` (twist to the wheels' desired state) and, when
    ``meshcat`` is given, a MeshcatVisualizer. ``start_fields`` (model instance
    name -> scenario field and value) names what placed a body that overlaps
    another at the start (:func:`~repertoire.diagrams.diffdrive.check_start_clear`).
    """
    to_state = builder.AddNamedSystem(
        "wheel_desired_state", MatrixGain(twist_to_wheel_state_matrix())
    )
    builder.Connect(command_port, to_state.get_input_port())
    builder.Connect(to_state.get_output_port(), plant.get_desired_state_input_port(robot))
    if meshcat is not None:
        from pydrake.geometry import MeshcatVisualizer

        MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat)
    diagram = builder.Build()
    diagram.set_name(name)
    check_start_clear(diagram, start_fields)
    return diagram


# what both GoToPose worlds check, pass on and set up (the initial speed)
_GOTO_WORLD = dict(
    check=lambda diagram, context: check_goto_pose(diagram, context),
    criteria={"status_succeeded": Bound(1.0, 1.0), "position_error_m": Bound(0.0, 0.1)},
    initialize=lambda diagram, context, scenario: set_initial_speed(
        diagram, context, scenario.initial_speed
    ),
)


@register_diagram(
    "soccer_goto_pose",
    scenario_type=GoToPoseScenario,
    description="diffdrive robot on the soccer field running the GoToPose action",
    duration=8.0,
    **_GOTO_WORLD,
)
def build_soccer_goto_pose(
    scenario: GoToPoseScenario, *, meshcat=None, name: str = "soccer_goto_pose"
) -> Diagram:
    """Builds the soccer world with GoToPose driving the robot.

    Returns:
        The Diagram ``name`` with subsystems ``plant``, ``scene_graph``,
        ``state_reader``, ``goto_pose``, ``target``, ``wheel_desired_state``.
    """
    scenario.validate()
    builder = DiagramBuilder()
    plant, scene_graph, robot, reader = add_soccer_robot(builder, scenario)
    goto = builder.AddSystem(GoToPose(period=scenario.control_period, gains=scenario.gains))
    goto.set_name("goto_pose")
    target = builder.AddSystem(ConstantVectorSource(np.asarray(scenario.target, dtype=float)))
    target.set_name("target")
    builder.Connect(reader.get_output_port(), goto.get_state_input_port())
    builder.Connect(target.get_output_port(), goto.get_target_input_port())
    return build_driven(
        builder, plant, scene_graph, robot, goto.get_command_output_port(),
        name, meshcat,
        start_fields={"diffdrive": f"initial_pose {scenario.initial_pose}"},
    )  # fmt: skip


@dataclasses.dataclass
class GoToPoseRunUpScenario(GoToPoseScenario):
    """A target behind the robot to be passed at 0.4 m/s: GoToPose's run-up shown.

    The robot reaches the target position slower than ``v_g`` allows, backs to the
    run-up pose behind it and accelerates through it (``RUN_UP`` mode of
    :func:`~repertoire.systems.go_to_pose.goto_mode`).
    """

    initial_pose: list[float] = dataclasses.field(default_factory=lambda: [0.0, 0.0, 0.0])
    target: list[float] = dataclasses.field(default_factory=lambda: [-1.0, 0.0, 0.0, 0.4])


@register_diagram(
    "soccer_goto_pose_run_up",
    scenario_type=GoToPoseRunUpScenario,
    description="GoToPose to a target to be passed at 0.4 m/s: it runs up to it",
    duration=12.0,
    **_GOTO_WORLD,
)
def build_soccer_goto_pose_run_up(scenario: GoToPoseRunUpScenario, *, meshcat=None) -> Diagram:
    """:func:`build_soccer_goto_pose` named ``soccer_goto_pose_run_up``."""
    return build_soccer_goto_pose(scenario, meshcat=meshcat, name="soccer_goto_pose_run_up")


def set_initial_speed(diagram: Diagram, context: Context, speed: float) -> None:
    """Gives the chassis and wheels a rolling forward speed in ``context``."""
    plant = diagram.GetSubsystemByName("plant")
    pc = plant.GetMyMutableContextFromRoot(context)
    chassis = plant.GetBodyByName("chassis")
    yaw = RollPitchYaw(plant.EvalBodyPoseInWorld(pc, chassis).rotation()).yaw_angle()
    from pydrake.multibody.math import SpatialVelocity

    plant.SetFreeBodySpatialVelocity(
        pc, chassis, SpatialVelocity([0, 0, 0], [speed * np.cos(yaw), speed * np.sin(yaw), 0])
    )
    for side in ("left", "right"):
        plant.GetJointByName(f"{side}_wheel_joint").set_angular_rate(pc, speed / WHEEL_RADIUS)


def goto_status(diagram: Diagram, context: Context) -> ActionStatus:
    """The GoToPose status in a ``soccer_goto_pose`` diagram's context."""
    goto = diagram.GetSubsystemByName("goto_pose")
    return goto.get_status_output_port().Eval(goto.GetMyContextFromRoot(context))


def robot_state(diagram: Diagram, context: Context) -> np.ndarray:
    """``[x, y, phi, v]`` of the robot."""
    reader = diagram.GetSubsystemByName("state_reader")
    return reader.get_output_port().Eval(reader.GetMyContextFromRoot(context))


def check_goto_pose(diagram: Diagram, context: Context) -> dict[str, float]:
    """The world's figures at the end of a run.

    ``status_succeeded`` (1/0), ``still_running`` (1/0: the action had not ended, a
    longer run may still succeed), ``position_error_m``, ``heading_error_rad``.
    """
    target = diagram.GetSubsystemByName("target")
    goal = target.get_output_port().Eval(target.GetMyContextFromRoot(context))
    s = robot_state(diagram, context)
    status = goto_status(diagram, context)
    return {
        "status_succeeded": float(status == ActionStatus.SUCCEEDED),
        "still_running": float(status == ActionStatus.RUNNING),
        "position_error_m": float(np.hypot(goal[0] - s[0], goal[1] - s[1])),
        "heading_error_rad": float(abs(np.angle(np.exp(1j * (goal[2] - s[2]))))),
    }
