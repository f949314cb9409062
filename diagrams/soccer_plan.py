"""The soccer world running a refined plan (registered as ``soccer_plan``).

The paper's soccer scenario (Stulp & Beetz, section 6.3.1): go to the ball, then dribble
it to the destination. The first action is a GoToPose to an approach pose behind the ball
(the refined subgoal: its heading and speed are the plan's free parameters); with
``dribble`` the last is a :class:`~repertoire.systems.dribble_ball.DribbleBall` in
collect mode, in the dribbler world (``soccer_dribble``'s guide arms on the chassis,
rolling resistance on the ball): it fetches the ball from where the approach left the
robot (circling it to the point behind it on the ball -> destination line) and succeeds
only with the ball held at the destination (the paper's goal, Fig. 14(b), has the ball
there). Without ``dribble`` every action is a GoToPose (tours, approaches). A
:class:`~repertoire.systems.plan_executor.PlanExecutor` hands each action its target and
routes the active one's ``[v, omega]`` to the wheels (the ``soccer_goto_pose`` wiring).

Before ``dribble`` the dribble leg was a GoToPose through the ball's position, which
succeeded when the robot reached the destination with the ball or without it: in the
refinement models' training episodes 370 of 401 succeeded dribbles ended without the ball
held.
"""

import dataclasses

import numpy as np
from pydrake.systems.framework import Context, Diagram, DiagramBuilder
from repertoire.diagrams.biped import validate_discrete_control_fields
from repertoire.diagrams.registry import register_diagram
from repertoire.diagrams.soccer import (
    BALL_POSITION,
    add_soccer_robot,
    build_driven,
    check_initial_speed,
    check_on_field,
    check_target_clear,
    robot_state,
    set_initial_speed,
)
from repertoire.diagrams.soccer_dribble import add_dribbler_guides
from repertoire.systems.ball import BodyXYReader, RollingResistance
from repertoire.systems.dribble_ball import (
    DRIBBLE_GAINS,
    DribbleBall,
    ball_terms,
)
from repertoire.systems.go_to_pose import GOTO_GAINS, ActionStatus, GoToPose
from repertoire.systems.plan_executor import PlanExecutor

from repertoire.criteria import Bound
from repertoire.errors import ScenarioError


@dataclasses.dataclass
class SoccerPlanScenario:
    """The robot on the soccer field executing a sequence of actions.

    Attributes:
        initial_pose: ``[x, y, yaw]`` of the chassis.
        initial_speed: forward speed at the start [m/s].
        targets: one ``[x_g, y_g, phi_g, v_g]`` per action, in order (the default: 0.5 m
            behind the ball at (1, 0.5) facing +x at 0.05 m/s, then the ball dribbled to
            (2, 0.5)).
        time_step: plant step [s].
        control_period: GoToPose and executor period [s].
        contact_approximation: discrete contact approximation.
        wheel_kd: wheel velocity gain.
        ground_friction: ground friction coefficient.
        gains: overrides of GoToPose's gains for every GoToPose action (``GOTO_GAINS``
            keys); each action's ``timeout`` counts from its own start.
        action_gains: empty, or one dict per GoToPose action of further overrides on
            top of ``gains``.
        dribble: the last action is DribbleBall in collect mode, in the dribbler world
            (see the module); it succeeds only with the ball held at its target.
        dribbler: the dribbler world (guide arms on the chassis, rolling resistance on
            the ball) without a dribble leg: the dribbling robot's approach to its ball
            (always the world with ``dribble``).
        dribble_gains: overrides of DribbleBall's gains (``DRIBBLE_GAINS`` keys) for the
            dribble.
        ball_decel: with ``dribble``, the ball's rolling resistance as the deceleration
            of a freely rolling ball [m/s^2] (``soccer_dribble``'s).
    """

    initial_pose: list[float] = dataclasses.field(default_factory=lambda: [-1.0, -0.5, 0.0])
    initial_speed: float = 0.0
    targets: list[list[float]] = dataclasses.field(
        default_factory=lambda: [[0.5, 0.5, 0.0, 0.05], [2.0, 0.5, 0.0, 0.0]]
    )
    time_step: float = 1e-2
    control_period: float = 0.02
    contact_approximation: str = "lagged"
    wheel_kd: float = 2.0
    ground_friction: float = 1.0
    gains: dict[str, float] = dataclasses.field(default_factory=dict)
    action_gains: list[dict[str, float]] = dataclasses.field(default_factory=list)
    dribble: bool = True
    dribbler: bool = False
    dribble_gains: dict[str, float] = dataclasses.field(default_factory=dict)
    ball_decel: float = 0.8

    def n_goto(self) -> int:
        """The number of GoToPose actions (all but a dribble)."""
        return len(self.targets) - int(self.dribble)

    def validate(self) -> None:
        """Raises ScenarioError naming the first bad field."""
        if len(self.initial_pose) != 3 or not np.all(np.isfinite(self.initial_pose)):
            raise ScenarioError(f"initial_pose must be 3 finite values, got {self.initial_pose}")
        check_initial_speed(self.initial_speed)
        check_on_field(self.initial_pose, "initial_pose")
        if not self.targets:
            raise ScenarioError("targets must hold at least one [x_g, y_g, phi_g, v_g]")
        for i, t in enumerate(self.targets):
            if len(t) != 4 or not np.all(np.isfinite(t)):
                raise ScenarioError(f"targets[{i}] must be 4 finite values, got {t}")
            check_target_clear(t, f"targets[{i}]")
            check_on_field(t, f"targets[{i}]")
        validate_discrete_control_fields(self)
        for name in ("dribble", "dribbler"):
            if not isinstance(getattr(self, name), bool):
                raise ScenarioError(f"{name} must be a bool, got {getattr(self, name)!r}")
        if self.action_gains and len(self.action_gains) != self.n_goto():
            raise ScenarioError(
                f"action_gains must be empty or hold one dict per GoToPose action: got "
                f"{len(self.action_gains)} for {self.n_goto()} (targets {len(self.targets)}, "
                f"dribble {self.dribble})"
            )
        for overrides in [self.gains, *self.action_gains]:
            unknown = sorted(set(overrides) - set(GOTO_GAINS))
            if unknown:
                raise ScenarioError(
                    f"unknown GoToPose gains {unknown}; expected {list(GOTO_GAINS)}"
                )
        unknown = sorted(set(self.dribble_gains) - set(DRIBBLE_GAINS))
        if unknown:
            raise ScenarioError(
                f"unknown DribbleBall gains {unknown}; expected {list(DRIBBLE_GAINS)}"
            )
        if not (np.isfinite(self.ball_decel) and self.ball_decel >= 0):
            raise ScenarioError(f"ball_decel must be finite and >= 0, got {self.ball_decel}")


@register_diagram(
    "soccer_plan",
    scenario_type=SoccerPlanScenario,
    description="diffdrive robot running a refined plan (approach the ball, dribble it)",
    duration=12.0,
    check=lambda diagram, context: check_soccer_plan(diagram, context),
    criteria={"plan_succeeded": Bound(1.0, 1.0), "position_error_m": Bound(0.0, 0.1)},
    initialize=lambda diagram, context, scenario: set_initial_speed(
        diagram, context, scenario.initial_speed
    ),
)
def build_soccer_plan(scenario: SoccerPlanScenario, *, meshcat=None) -> Diagram:
    """Builds the soccer world with a PlanExecutor running one action per target.

    Returns:
        The Diagram ``soccer_plan`` with subsystems ``plant``, ``scene_graph``,
        ``state_reader``, ``action_i`` (GoToPose; with ``dribble`` the last one
        DribbleBall), ``executor``, ``wheel_desired_state``, and in the dribbler world
        ``ball_reader`` and ``ball_rolling_resistance``.
    """
    scenario.validate()
    builder = DiagramBuilder()
    dribbler_world = scenario.dribble or scenario.dribbler
    extra = add_dribbler_guides if dribbler_world else None
    plant, scene_graph, robot, reader = add_soccer_robot(builder, scenario, extra=extra)
    executor = builder.AddSystem(
        PlanExecutor(scenario.targets, command_size=2, period=scenario.control_period)
    )
    executor.set_name("executor")
    if dribbler_world:
        ball_reader = builder.AddNamedSystem("ball_reader", BodyXYReader(plant, "ball"))
        builder.Connect(plant.get_state_output_port(), ball_reader.get_input_port())
        drag = builder.AddNamedSystem(
            "ball_rolling_resistance", RollingResistance(plant, "ball", scenario.ball_decel)
        )
        builder.Connect(plant.get_state_output_port(), drag.get_input_port())
        builder.Connect(drag.get_output_port(), plant.get_applied_spatial_force_input_port())
    for i in range(len(scenario.targets)):
        if i < scenario.n_goto():
            extra_gains = scenario.action_gains[i] if scenario.action_gains else {}
            gains = {**scenario.gains, **extra_gains}
            action = builder.AddSystem(GoToPose(period=scenario.control_period, gains=gains))
        else:
            action = builder.AddSystem(
                DribbleBall(
                    period=scenario.control_period, gains=scenario.dribble_gains, collect=True
                )
            )
            builder.Connect(ball_reader.get_output_port(), action.get_ball_input_port())
        action.set_name(f"action_{i}")
        builder.Connect(reader.get_output_port(), action.get_state_input_port())
        builder.Connect(executor.GetOutputPort(f"target_{i}"), action.get_target_input_port())
        builder.Connect(executor.GetOutputPort(f"active_{i}"), action.get_active_input_port())
        builder.Connect(action.get_status_output_port(), executor.get_status_input_port(i))
        builder.Connect(action.get_command_output_port(), executor.get_command_input_port(i))
    return build_driven(
        builder, plant, scene_graph, robot, executor.get_command_output_port(), "soccer_plan",
        meshcat, start_fields={"diffdrive": f"initial_pose {scenario.initial_pose}"},
    )  # fmt: skip


def plan_status(diagram: Diagram, context: Context) -> ActionStatus:
    """The plan's status in a ``soccer_plan`` diagram's context."""
    executor = diagram.GetSubsystemByName("executor")
    return executor.get_status_output_port().Eval(executor.GetMyContextFromRoot(context))


def finish_times(diagram: Diagram, context: Context) -> np.ndarray:
    """Time each action ended (NaN while running or not started)."""
    executor = diagram.GetSubsystemByName("executor")
    return executor.get_finish_times_output_port().Eval(executor.GetMyContextFromRoot(context))


def check_soccer_plan(diagram: Diagram, context: Context) -> dict[str, float]:
    """Figures of a run: success, plan time, final position error and the ball.

    Returns ``plan_succeeded`` (1/0: every action succeeded and, in a dribbling plan, the
    ball ends held, :func:`ball_held`), ``still_running`` (1/0: the plan had not ended, a
    longer run may still succeed), ``plan_time_s``, ``position_error_m`` (to the last
    target), ``ball_moved_m`` (the ball's distance from its start: dribbled or bumped) and
    ``ball_held`` (1/0).
    """
    executor = diagram.GetSubsystemByName("executor")
    ec = executor.GetMyContextFromRoot(context)
    goal = executor.target(ec, executor.n_actions - 1)
    s = robot_state(diagram, context)
    times = finish_times(diagram, context)
    return {
        "plan_succeeded": float(plan_succeeded(diagram, context)),
        "still_running": float(plan_status(diagram, context) == ActionStatus.RUNNING),
        "plan_time_s": float(times[-1]),
        "position_error_m": float(np.hypot(goal[0] - s[0], goal[1] - s[1])),
        "ball_moved_m": ball_moved(diagram, context),
        "ball_held": float(ball_held(diagram, context)),
    }


def plan_succeeded(diagram: Diagram, context: Context) -> bool:
    """Every action succeeded and, when the last one is a DribbleBall, the ball ends held.

    A DribbleBall succeeds only with the ball held; checked again here because a plan's
    success means the ball was delivered (:func:`ball_held`).
    """
    executor = diagram.GetSubsystemByName("executor")
    last = diagram.GetSubsystemByName(f"action_{executor.n_actions - 1}")
    if plan_status(diagram, context) != ActionStatus.SUCCEEDED:
        return False
    return ball_held(diagram, context) or not isinstance(last, DribbleBall)


def ball_xy(diagram: Diagram, context: Context) -> np.ndarray:
    """The ball's world ``[x, y]``."""
    plant = diagram.GetSubsystemByName("plant")
    pc = plant.GetMyContextFromRoot(context)
    return plant.EvalBodyPoseInWorld(pc, plant.GetBodyByName("ball")).translation()[:2]


def ball_moved(diagram: Diagram, context: Context) -> float:
    """The ball's horizontal distance from its start position [m]."""
    p = ball_xy(diagram, context)
    return float(np.hypot(p[0] - BALL_POSITION[0], p[1] - BALL_POSITION[1]))


def ball_held(diagram: Diagram, context: Context) -> bool:
    """Whether the robot holds the ball by DribbleBall's test (:func:`ball_terms`).

    With the gains of the plan's last action when it is a DribbleBall, else
    ``DRIBBLE_GAINS``: the ball within ``lost_distance`` of the spot ``hold_distance``
    ahead of the axle and at most ``lost_lateral`` to the side.
    """
    executor = diagram.GetSubsystemByName("executor")
    last = diagram.GetSubsystemByName(f"action_{executor.n_actions - 1}")
    gains = (
        last.gains(last.GetMyContextFromRoot(context))
        if isinstance(last, DribbleBall)
        else DRIBBLE_GAINS
    )
    return ball_terms(robot_state(diagram, context), ball_xy(diagram, context), gains)[0]
