"""The soccer world with the DribbleBall action wired (``soccer_dribble``, ``..._loop``).

Registered twice: ``soccer_dribble`` dribbles to a pose at rest, and
``soccer_dribble_loop`` to a goal passed at 0.3 m/s, met through a loop.

The differential-drive robot on the soccer field starts with the ball in front
of its bumper (``ball_offset`` ahead of the axle) and dribbles it to a target
pose with :class:`~repertoire.systems.dribble_ball.DribbleBall`. The plant's
state feeds a :class:`~repertoire.systems.go_to_pose.DiffDriveStateReader`
(robot ``[x, y, phi, v]``) and a :class:`~repertoire.systems.ball.BodyXYReader`
(ball ``[x, y]``); the action's ``[v, omega]`` becomes the wheels' desired state
as in ``soccer_goto_pose``. The target is a constant source named ``target``.
"""

import dataclasses

import numpy as np
from pydrake.geometry import Box
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.plant import CoulombFriction
from pydrake.systems.framework import Context, Diagram, DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource
from repertoire.diagrams.biped import validate_discrete_control_fields
from repertoire.diagrams.diffdrive import WHEEL_RADIUS
from repertoire.diagrams.registry import register_diagram
from repertoire.diagrams.simulate import SimulatorCache
from repertoire.diagrams.soccer import add_soccer_robot, build_driven
from repertoire.systems.ball import BodyXYReader, RollingResistance
from repertoire.systems.dribble_ball import (
    DRIBBLE_GAINS,
    DribbleBall,
)
from repertoire.systems.go_to_pose import ActionStatus

from repertoire.criteria import Bound
from repertoire.errors import ScenarioError

BALL_RADIUS = 0.11  # models/diffdrive/soccer.sdf
BUMPER_X = 0.1975  # front face of the chassis box ahead of the axle [m]
GUIDE_SIZE = (0.14, 0.02, 0.08)  # each guide arm of the dribbler [m]
GUIDE_Y = BALL_RADIUS + 0.025 + GUIDE_SIZE[1] / 2  # lateral centre of a guide arm [m]


def add_dribbler_guides(plant, robot) -> None:
    """Adds the dribbler to the robot's chassis in an unfinalized plant.

    The dribbler is two guide arms (boxes ``GUIDE_SIZE``) on the chassis either
    side of the ball's held spot, as on RoboCup robots: a flat bumper alone lets
    the ball slide off sideways as soon as the robot turns. They leave the ball
    2.5 cm of play each side.
    """
    chassis = plant.GetBodyByName("chassis", robot)
    for side, y in (("left", GUIDE_Y), ("right", -GUIDE_Y)):
        X = RigidTransform([BUMPER_X + GUIDE_SIZE[0] / 2, y, 0.0])
        plant.RegisterCollisionGeometry(
            chassis, X, Box(*GUIDE_SIZE), f"dribbler_{side}", CoulombFriction(0.3, 0.3)
        )
        plant.RegisterVisualGeometry(
            chassis, X, Box(*GUIDE_SIZE), f"dribbler_{side}_visual", [0.2, 0.2, 0.2, 1.0]
        )


def set_dribble_defaults(plant, scenario: "DribbleScenario") -> None:
    """Sets the plant's default poses of the chassis and the ball to the scenario's start."""
    x, y, yaw = scenario.initial_pose
    plant.SetDefaultFloatingBaseBodyPose(
        plant.GetBodyByName("chassis"),
        RigidTransform(RollPitchYaw(0.0, 0.0, yaw), [x, y, WHEEL_RADIUS]),
    )
    bx, by = scenario.ball_xy()
    plant.SetDefaultFloatingBaseBodyPose(
        plant.GetBodyByName("ball"), RigidTransform([bx, by, BALL_RADIUS])
    )


@dataclasses.dataclass
class DribbleScenario:
    """The robot on the soccer field dribbling the ball to a pose.

    Attributes:
        initial_pose: ``[x, y, yaw]`` of the chassis.
        ball_offset: ``[forward, left]`` of the ball centre from the axle midpoint
            in the robot frame at the start [m] (the bumper is 0.1975 m ahead).
        target: ``[x_g, y_g, phi_g, v_g]`` of the robot.
        time_step: plant step [s].
        control_period: DribbleBall update period [s].
        contact_approximation: discrete contact approximation.
        wheel_kd: wheel velocity gain.
        ground_friction: ground friction coefficient.
        gains: overrides of DribbleBall's gains (``DRIBBLE_GAINS`` keys).
        ball_decel: rolling resistance of the ball on grass as the deceleration of
            a freely rolling ball [m/s^2] (point contact has no rolling friction).
        collect: DribbleBall's collect mode (fetch a ball not held first).
    """

    initial_pose: list[float] = dataclasses.field(default_factory=lambda: [-1.0, 0.0, 0.0])
    ball_offset: list[float] = dataclasses.field(default_factory=lambda: [0.31, 0.0])
    target: list[float] = dataclasses.field(default_factory=lambda: [0.5, 0.5, 0.5, 0.0])
    time_step: float = 1e-2
    control_period: float = 0.02
    contact_approximation: str = "lagged"
    wheel_kd: float = 2.0
    ground_friction: float = 1.0
    gains: dict[str, float] = dataclasses.field(default_factory=dict)
    ball_decel: float = 0.8
    collect: bool = False

    def validate(self) -> None:
        """Raises ScenarioError naming the first bad field."""
        if len(self.initial_pose) != 3 or not np.all(np.isfinite(self.initial_pose)):
            raise ScenarioError(f"initial_pose must be 3 finite values, got {self.initial_pose}")
        if len(self.ball_offset) != 2 or not np.all(np.isfinite(self.ball_offset)):
            raise ScenarioError(f"ball_offset must be 2 finite values, got {self.ball_offset}")
        f, left = self.ball_offset
        if f < BUMPER_X + BALL_RADIUS - 1e-3 or (
            f < BUMPER_X + GUIDE_SIZE[0] + BALL_RADIUS and abs(left) > GUIDE_Y - 0.01 - BALL_RADIUS
        ):
            raise ScenarioError(
                f"ball_offset {self.ball_offset} puts the ball inside the robot or its dribbler "
                f"(the bumper is {BUMPER_X} m ahead, the guides at +-{GUIDE_Y:.3f} m; the ball "
                f"radius is {BALL_RADIUS} m)"
            )
        if len(self.target) != 4 or not np.all(np.isfinite(self.target)):
            raise ScenarioError(f"target must be 4 finite values, got {self.target}")
        unknown = set(self.gains) - set(DRIBBLE_GAINS)
        if unknown:
            raise ScenarioError(f"unknown gains {sorted(unknown)}; expected {list(DRIBBLE_GAINS)}")
        if not (np.isfinite(self.ball_decel) and self.ball_decel >= 0):
            raise ScenarioError(f"ball_decel must be finite and >= 0, got {self.ball_decel}")
        if not isinstance(self.collect, bool):
            raise ScenarioError(f"collect must be a bool, got {self.collect!r}")
        validate_discrete_control_fields(self)

    def ball_xy(self) -> np.ndarray:
        """The ball's initial world ``[x, y]``."""
        x, y, yaw = self.initial_pose
        f, left = self.ball_offset
        return np.array(
            [x + f * np.cos(yaw) - left * np.sin(yaw), y + f * np.sin(yaw) + left * np.cos(yaw)]
        )


def _dribble_world(position_bound: float) -> dict:
    """The check and criteria of a dribble world (the axle within ``position_bound`` m)."""
    return dict(
        check=lambda diagram, context: check_dribble(diagram, context),
        criteria={
            "status_succeeded": Bound(1.0, 1.0),
            "position_error_m": Bound(0.0, position_bound),
            "ball_from_held_spot_m": Bound(0.0, 0.25),
        },
    )


@register_diagram(
    "soccer_dribble",
    scenario_type=DribbleScenario,
    description="diffdrive robot on the soccer field dribbling the ball with DribbleBall",
    duration=12.0,
    **_dribble_world(position_bound=0.15),
)
def build_soccer_dribble(
    scenario: DribbleScenario, *, meshcat=None, name: str = "soccer_dribble"
) -> Diagram:
    """Builds the soccer world with DribbleBall pushing the ball.

    Returns:
        The Diagram ``name`` with subsystems ``plant``, ``scene_graph``,
        ``state_reader``, ``ball_reader``, ``dribble_ball``, ``target``,
        ``wheel_desired_state``.
    """
    scenario.validate()
    builder = DiagramBuilder()
    plant, scene_graph, robot, reader = add_soccer_robot(
        builder, scenario, extra=add_dribbler_guides
    )
    set_dribble_defaults(plant, scenario)
    ball_reader = builder.AddNamedSystem("ball_reader", BodyXYReader(plant, "ball"))
    action = builder.AddNamedSystem(
        "dribble_ball",
        DribbleBall(period=scenario.control_period, gains=scenario.gains, collect=scenario.collect),
    )
    target = builder.AddNamedSystem(
        "target", ConstantVectorSource(np.asarray(scenario.target, dtype=float))
    )
    builder.Connect(plant.get_state_output_port(), ball_reader.get_input_port())
    drag = builder.AddNamedSystem(
        "ball_rolling_resistance", RollingResistance(plant, "ball", scenario.ball_decel)
    )
    builder.Connect(plant.get_state_output_port(), drag.get_input_port())
    builder.Connect(drag.get_output_port(), plant.get_applied_spatial_force_input_port())
    builder.Connect(reader.get_output_port(), action.get_state_input_port())
    builder.Connect(ball_reader.get_output_port(), action.get_ball_input_port())
    builder.Connect(target.get_output_port(), action.get_target_input_port())
    return build_driven(
        builder, plant, scene_graph, robot, action.get_command_output_port(), name,
        meshcat, start_fields={"diffdrive": f"initial_pose {scenario.initial_pose}",
                               "ball": f"ball_offset {scenario.ball_offset}"},
    )  # fmt: skip


@dataclasses.dataclass
class DribbleLoopScenario(DribbleScenario):
    """A goal 1.5 rad off the start heading, to be passed at 0.3 m/s: DribbleBall's loop.

    The held spot reaches the goal's too slowly to meet the speed, and the robot cannot
    back away from its ball, so it loops (``LOOP_LEFT``, see
    :func:`~repertoire.systems.dribble_ball.approach_mode`) and passes through the goal
    at speed.
    """

    target: list[float] = dataclasses.field(default_factory=lambda: [0.6, 0.5, 1.5, 0.3])


@register_diagram(
    "soccer_dribble_loop",
    scenario_type=DribbleLoopScenario,
    description="DribbleBall to a goal passed at 0.3 m/s, met through a loop",
    duration=8.0,
    # The action succeeds with the held spot within position_tolerance (0.1 m) and the
    # heading within heading_tolerance (0.5 rad): the axle is then within
    # 0.1 + 2 * 0.31 * sin(0.25) = 0.253 m of the goal.
    **_dribble_world(position_bound=0.26),
)
def build_soccer_dribble_loop(scenario: DribbleLoopScenario, *, meshcat=None) -> Diagram:
    """:func:`build_soccer_dribble` named ``soccer_dribble_loop``."""
    return build_soccer_dribble(scenario, meshcat=meshcat, name="soccer_dribble_loop")


#: ``soccer_dribble`` simulators by diagram structure (see :func:`dribble_simulator`).
DRIBBLE_SIMULATORS = SimulatorCache(build_soccer_dribble)


def dribble_simulator(scenario: DribbleScenario, *, reuse: bool = True):
    """A Simulator of ``soccer_dribble`` at time 0 in ``scenario``'s start.

    Built once per structure (every field but ``initial_pose``, ``ball_offset``
    and ``target``) in this process and reset afterwards
    (:class:`~repertoire.diagrams.simulate.SimulatorCache`). Change the context
    as needed, then call ``simulator.Initialize()`` before advancing.

    Returns:
        ``(diagram, simulator)``.
    """
    scenario.validate()
    s = scenario
    key = (s.time_step, s.control_period, s.contact_approximation, s.wheel_kd,
           s.ground_friction, tuple(sorted(s.gains.items())), s.ball_decel, s.collect)  # fmt: skip
    return DRIBBLE_SIMULATORS.get(
        key,
        scenario,
        lambda plant: set_dribble_defaults(plant, scenario),
        {"target": scenario.target},
        reuse=reuse,
    )


def dribble_status(diagram: Diagram, context: Context) -> ActionStatus:
    """The DribbleBall status in a ``soccer_dribble`` diagram's context."""
    action = diagram.GetSubsystemByName("dribble_ball")
    return action.get_status_output_port().Eval(action.GetMyContextFromRoot(context))


def robot_and_ball(diagram: Diagram, context: Context) -> tuple[np.ndarray, np.ndarray]:
    """``[x, y, phi, v]`` of the robot and ``[x, y]`` of the ball."""
    reader = diagram.GetSubsystemByName("state_reader")
    ball = diagram.GetSubsystemByName("ball_reader")
    return (
        reader.get_output_port().Eval(reader.GetMyContextFromRoot(context)),
        ball.get_output_port().Eval(ball.GetMyContextFromRoot(context)),
    )


def check_dribble(diagram: Diagram, context: Context) -> dict[str, float]:
    """The world's figures.

    ``status_succeeded`` (1/0), ``still_running`` (1/0: the action had not ended, a
    longer run may still succeed), ``position_error_m``, ``heading_error_rad`` and
    ``ball_from_held_spot_m`` (the ball's distance from its held spot).
    """
    from repertoire.systems.dribble_ball import ball_in_robot_frame

    target = diagram.GetSubsystemByName("target")
    goal = target.get_output_port().Eval(target.GetMyContextFromRoot(context))
    action = diagram.GetSubsystemByName("dribble_ball")
    hold = action.gains(action.GetMyContextFromRoot(context))["hold_distance"]
    s, ball = robot_and_ball(diagram, context)
    bx, by = ball_in_robot_frame(s, ball)
    return {
        "status_succeeded": float(dribble_status(diagram, context) == ActionStatus.SUCCEEDED),
        "still_running": float(dribble_status(diagram, context) == ActionStatus.RUNNING),
        "position_error_m": float(np.hypot(goal[0] - s[0], goal[1] - s[1])),
        "heading_error_rad": float(abs(np.angle(np.exp(1j * (goal[2] - s[2]))))),
        "ball_from_held_spot_m": float(np.hypot(bx - hold, by)),
    }
