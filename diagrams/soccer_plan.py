"""The soccer world running a refined plan of GoToPose actions (registered as ``soccer_plan``).

The paper's soccer scenario (Stulp & Beetz, section 6.3.1): go to the ball, then dribble
it. With the actions built so far it is two GoToPose legs: the first to an approach
pose just behind the ball (the refined subgoal: its heading and speed are the plan's free
parameters), the second through the ball's position to the final pose, pushing the
ball. One :class:`~repertoire.systems.go_to_pose.GoToPose` per leg; a
:class:`~repertoire.systems.plan_executor.PlanExecutor` hands each its target and routes
the active one's ``[v, omega]`` to the wheels (the ``soccer_goto_pose`` wiring).
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
from repertoire.systems.go_to_pose import GOTO_GAINS, ActionStatus, GoToPose
from repertoire.systems.plan_executor import PlanExecutor

from repertoire.criteria import Bound
from repertoire.errors import ScenarioError


@dataclasses.dataclass
class SoccerPlanScenario:
    """The robot on the soccer field executing a sequence of GoToPose targets.

    Attributes:
        initial_pose: ``[x, y, yaw]`` of the chassis.
        initial_speed: forward speed at the start [m/s].
        targets: one ``[x_g, y_g, phi_g, v_g]`` per action, in order (the default: behind
            the ball at (1, 0.5) facing +x at 0.2 m/s, then through it to (2, 0.5)).
        time_step: plant step [s].
        control_period: GoToPose and executor period [s].
        contact_approximation: discrete contact approximation.
        wheel_kd: wheel velocity gain.
        ground_friction: ground friction coefficient.
        gains: overrides of GoToPose's gains for every action (``GOTO_GAINS`` keys); the
            ``timeout`` is measured from the plan's start.
        action_gains: empty, or one dict per action of further overrides on top of
            ``gains`` (e.g. a dribble that turns slowly to keep the ball in front).
    """

    initial_pose: list[float] = dataclasses.field(default_factory=lambda: [-1.0, -0.5, 0.0])
    initial_speed: float = 0.0
    targets: list[list[float]] = dataclasses.field(
        default_factory=lambda: [[0.65, 0.5, 0.0, 0.2], [2.0, 0.5, 0.0, 0.0]]
    )
    time_step: float = 1e-2
    control_period: float = 0.02
    contact_approximation: str = "lagged"
    wheel_kd: float = 2.0
    ground_friction: float = 1.0
    gains: dict[str, float] = dataclasses.field(default_factory=dict)
    action_gains: list[dict[str, float]] = dataclasses.field(default_factory=list)

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
        if self.action_gains and len(self.action_gains) != len(self.targets):
            raise ScenarioError(
                f"action_gains must be empty or hold one dict per target: got "
                f"{len(self.action_gains)} for {len(self.targets)} targets"
            )
        for overrides in [self.gains, *self.action_gains]:
            unknown = sorted(set(overrides) - set(GOTO_GAINS))
            if unknown:
                raise ScenarioError(
                    f"unknown GoToPose gains {unknown}; expected {list(GOTO_GAINS)}"
                )


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
    """Builds the soccer world with a PlanExecutor running one GoToPose per target.

    Returns:
        The Diagram ``soccer_plan`` with subsystems ``plant``, ``scene_graph``,
        ``state_reader``, ``action_i`` (GoToPose), ``executor``, ``wheel_desired_state``.
    """
    scenario.validate()
    builder = DiagramBuilder()
    plant, scene_graph, robot, reader = add_soccer_robot(builder, scenario)
    executor = builder.AddSystem(
        PlanExecutor(scenario.targets, command_size=2, period=scenario.control_period)
    )
    executor.set_name("executor")
    for i in range(len(scenario.targets)):
        gains = {**scenario.gains, **(scenario.action_gains[i] if scenario.action_gains else {})}
        action = builder.AddSystem(GoToPose(period=scenario.control_period, gains=gains))
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
    """Figures of a run: success, plan time, final position error and ball displacement.

    Returns ``plan_succeeded`` (1/0), ``still_running`` (1/0: the plan had not ended, a
    longer run may still succeed), ``plan_time_s``, ``position_error_m`` (to the last
    target) and ``ball_moved_m`` (the ball's distance from its start: dribbled or bumped).
    """
    executor = diagram.GetSubsystemByName("executor")
    ec = executor.GetMyContextFromRoot(context)
    goal = executor.target(ec, executor.n_actions - 1)
    s = robot_state(diagram, context)
    times = finish_times(diagram, context)
    return {
        "plan_succeeded": float(plan_status(diagram, context) == ActionStatus.SUCCEEDED),
        "still_running": float(plan_status(diagram, context) == ActionStatus.RUNNING),
        "plan_time_s": float(times[-1]),
        "position_error_m": float(np.hypot(goal[0] - s[0], goal[1] - s[1])),
        "ball_moved_m": ball_moved(diagram, context),
    }


def ball_moved(diagram: Diagram, context: Context) -> float:
    """The ball's horizontal distance from its start position [m]."""
    plant = diagram.GetSubsystemByName("plant")
    pc = plant.GetMyContextFromRoot(context)
    p = plant.EvalBodyPoseInWorld(pc, plant.GetBodyByName("ball")).translation()
    return float(np.hypot(p[0] - BALL_POSITION[0], p[1] - BALL_POSITION[1]))
