"""The kitchen with the arm robot running one action (registered as ``kitchen_action``).

The robot of ``models/diffdrive/diffdrive_arm.urdf`` (the diffdrive base with a
lift / yaw / extend arm and two fingers) stands in the kitchen world of
``models/diffdrive/kitchen.sdf`` and runs one of the kitchen actions of Stulp &
Beetz: ``goto_pose`` (:class:`~repertoire.systems.kitchen_drive.KitchenGoToPose`:
GoToPose that stops and fails when its motion would take the base or the held arm into
furniture or a standing cup; its target passed through a :class:`FootprintGuard` so a
pose inside a table fails at once), ``reach``, ``grip`` or ``put``
(:mod:`repertoire.systems.kitchen_actions`). The channels the action does not drive
hold their start values (wheels still, arm and fingers at their initial setpoints).

All actuators are the plant's PD-controlled actuators: the wheels velocity-only
(as in diagrams/diffdrive.py), the arm joints and fingers position-controlled.
The cup is held by contact: the fingers squeeze it (finger setpoint 2 cm inside
the cup's surface, about 8 N each) and friction carries its weight; no weld.
With ``cup_in_gripper`` the cup ``cup_0`` starts between the closed fingers
(for ``put``).
"""

import dataclasses
import functools
import math
import re
from collections.abc import Callable

import numpy as np
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.parsing import Parser
from pydrake.multibody.tree import PdControllerGains
from pydrake.systems.framework import Context, Diagram, DiagramBuilder, EventStatus
from pydrake.systems.primitives import ConstantVectorSource, MatrixGain, Multiplexer
from repertoire.diagrams.biped import add_plant_with_ground, validate_discrete_control_fields
from repertoire.diagrams.diffdrive import WHEEL_RADIUS, WORLDS, check_start_clear
from repertoire.diagrams.registry import register_diagram
from repertoire.diagrams.simulate import SimulatorCache
from repertoire.diagrams.soccer import twist_to_wheel_state_matrix
from repertoire.models import MODELS_DIR, ConfigureParser, package_url
from repertoire.models.diffdrive.generate import CUP_HALF_HEIGHT, CUP_MASS, CUP_RADIUS, MASS
from repertoire.models.diffdrive.generate import KITCHEN_CUPS as _CUP_MODELS
from repertoire.systems.go_to_pose import (
    GOTO_GAINS,
    ActionStatus,
    DiffDriveStateReader,
    GoToPose,
)
from repertoire.systems.kitchen_actions import (
    ARM_JOINTS,
    ARM_SPEEDS,
    FINGER_CLOSED,
    FINGER_JOINTS,
    FINGER_OPEN,
    ArmTracking,
    FootprintGuard,
    Grip,
    Put,
    Reach,
    arm_forward,
    arm_inverse,
    chassis_to_world,
)
from repertoire.systems.kitchen_drive import KitchenGoToPose

from repertoire.criteria import Bound
from repertoire.errors import RepertoireError, ScenarioError

ACTIONS = ("goto_pose", "reach", "grip", "put")
ROBOT_URL_PATH = "diffdrive/diffdrive_arm.urdf"
ROBOT_RADIUS = 0.32  # footprint disc of the base (chassis corners and wheels) [m]
TABLE_TOP = 0.75
#: Obstacle boxes of kitchen.sdf, ``[cx, cy, yaw, half_x, half_y, top_z]`` (world).
KITCHEN_OBSTACLES = np.array(
    [
        [-2.0, 2.6, 0.0, 1.2, 0.3, 0.9],  # counter
        [2.1, 1.3, 0.0, 0.6, 0.4, TABLE_TOP],  # table_0
        [2.0, -1.6, 0.3, 0.6, 0.4, TABLE_TOP],  # table_1
        [0.0, 3.0, 0.0, 4.0, 0.05, 1.2],  # walls
        [0.0, -3.0, 0.0, 4.0, 0.05, 1.2],
        [4.0, 0.0, 0.0, 0.05, 3.0, 1.2],
        [-4.0, 0.0, 0.0, 0.05, 3.0, 1.2],
    ]
)
#: The names of ``KITCHEN_OBSTACLES``' boxes (in failure messages).
KITCHEN_OBSTACLE_NAMES = ("counter", "table_0", "table_1", "wall", "wall", "wall", "wall")
#: The region GoToPose targets may lie in: the room less the robot's radius and the walls.
KITCHEN_WORKSPACE = (-3.6, 3.6, -2.6, 2.6)
#: The free cups of kitchen.sdf (written by models/diffdrive/generate.py).
KITCHEN_CUPS = tuple(_CUP_MODELS)
#: Each cup's centre (world) as placed in kitchen.sdf.
KITCHEN_CUP_POSITIONS = {name: xyz for name, (xyz, _) in _CUP_MODELS.items()}
CUP_0_POSITION = KITCHEN_CUP_POSITIONS["cup_0"]
ARM_TUCKED = (0.62, 0.0, 0.25)  # lift, yaw, extend: fingers above the tables
#: PD gains (kp, kd) of the arm and finger actuators.
ARM_GAINS = {
    "arm_lift": (4000.0, 200.0),
    "arm_yaw": (300.0, 30.0),
    "arm_extend": (2000.0, 100.0),
    "left_finger": (400.0, 10.0),
    "right_finger": (400.0, 10.0),
}
#: How the robot stops when GoToPose's command drops to 0 (the check of KitchenGoToPose):
#: measured 4.5 m/s^2 from 0.8 m/s (8.6 cm) and 41 rad/s^2 from 2.4 rad/s (0.12 rad) on
#: the kitchen floor at the 2 ms step; taken at two thirds and half (a stop still predicted
#: 12 cm and 0.21 rad: a_max and alpha_max, GoToPose's command limits, gave 33 cm, 0.62 rad).
KITCHEN_BRAKING = (3.0, 20.0)
GRAVITY = 9.81  # the plant's (Drake's default) [m/s^2]
#: How the arm's PD joints follow the actions' setpoints (checked ways: ArmTracking):
#: lags kd/kp, and the lift's sag under the lifted links (carriage, turret, slide, two
#: fingers) and under a held cup.
ARM_TRACKING = ArmTracking(
    lags=tuple(ARM_GAINS[j][1] / ARM_GAINS[j][0] for j in ARM_JOINTS),
    speeds=ARM_SPEEDS,
    sag=sum(
        MASS[k] * (2 if k == "finger" else 1) for k in ("carriage", "turret", "slide", "finger")
    )
    * GRAVITY
    / ARM_GAINS["arm_lift"][0],
    cup_sag=CUP_MASS * GRAVITY / ARM_GAINS["arm_lift"][0],
)


@dataclasses.dataclass
class KitchenScenario:
    """The arm robot in the kitchen running one action.

    Attributes:
        action: ``goto_pose``, ``reach``, ``grip`` or ``put``.
        initial_pose: ``[x, y, yaw]`` of the chassis.
        initial_arm: ``[lift, yaw, extend]`` at the start.
        initial_fingers: both fingers' position at the start [m].
        goto_target: ``[x_g, y_g, phi_g, v_g]`` for ``goto_pose``.
        arm_target: gripper-centre target ``[ax, ay, az]`` in the chassis frame
            for ``reach`` and ``put``.
        cup_in_gripper: ``cup_0`` starts at the gripper centre (for ``put``).
        cups: the cups of ``KITCHEN_CUPS`` in the world (each a free body with
            six velocities and its contact with the table: leaving out the cups an
            episode never touches makes the plant's step about twice as cheap).
        time_step: plant step [s].
        control_period: the actions' update period [s].
        contact_approximation: discrete contact approximation.
        wheel_kd: wheel velocity gain.
        ground_friction: ground friction coefficient.
        gains: overrides of GoToPose's gains (``GOTO_GAINS`` keys), e.g. its timeout.
        cup_positions: world centres ``[x, y, z]`` of cups moved from their
            ``kitchen.sdf`` places (keys: names in ``cups``), e.g. cups displaced on a table.
        drive_check: ``goto_pose`` stops and fails before the base or the held arm would
            enter furniture or a standing cup (:class:`KitchenGoToPose`); False runs the
            bare GoToPose (to see where its law alone goes: into a table's leg).
    """

    action: str = "reach"
    initial_pose: list[float] = dataclasses.field(default_factory=lambda: [2.0, 0.55, math.pi / 2])
    initial_arm: list[float] = dataclasses.field(default_factory=lambda: list(ARM_TUCKED))
    initial_fingers: float = FINGER_OPEN
    goto_target: list[float] = dataclasses.field(default_factory=lambda: [0.0, 0.0, 0.0, 0.0])
    arm_target: list[float] = dataclasses.field(default_factory=lambda: [0.85, 0.0, 0.7036])
    cup_in_gripper: bool = False
    cups: list[str] = dataclasses.field(default_factory=lambda: list(KITCHEN_CUPS))
    time_step: float = 2e-3
    control_period: float = 0.02
    contact_approximation: str = "lagged"
    wheel_kd: float = 2.0
    ground_friction: float = 1.0
    gains: dict[str, float] = dataclasses.field(default_factory=dict)
    cup_positions: dict[str, list[float]] = dataclasses.field(default_factory=dict)
    drive_check: bool = True

    def validate(self) -> None:
        """Raises ScenarioError naming the first bad field."""
        if self.action not in ACTIONS:
            raise ScenarioError(f"unknown action {self.action!r}; expected one of {ACTIONS}")
        for name, size in (("initial_pose", 3), ("goto_target", 4), ("arm_target", 3)):
            value = getattr(self, name)
            if len(value) != size or not np.all(np.isfinite(value)):
                raise ScenarioError(f"{name} must be {size} finite values, got {value}")
        x0, x1, y0, y1 = KITCHEN_WORKSPACE
        if not (x0 <= self.initial_pose[0] <= x1 and y0 <= self.initial_pose[1] <= y1):
            raise ScenarioError(
                f"initial_pose {self.initial_pose} puts the robot outside the kitchen: its "
                f"x, y must lie in [{x0}, {x1}] x [{y0}, {y1}] (the room less its radius)"
            )
        if len(self.initial_arm) != 3 or arm_inverse(arm_forward(self.initial_arm)) is None:
            raise ScenarioError(
                f"initial_arm must be [lift, yaw, extend] within the joint ranges, got "
                f"{self.initial_arm}"
            )
        if not (np.isfinite(self.initial_fingers) and 0.03 <= self.initial_fingers <= 0.08):
            raise ScenarioError(f"initial_fingers must be in [0.03, 0.08] m, got "
                                f"{self.initial_fingers}")  # fmt: skip
        unknown = [c for c in self.cups if c not in KITCHEN_CUPS]
        if unknown or len(set(self.cups)) != len(self.cups):
            raise ScenarioError(f"cups must be distinct names of {KITCHEN_CUPS}, got {self.cups}")
        if self.cup_in_gripper and "cup_0" not in self.cups:
            raise ScenarioError("cup_in_gripper needs cup_0 in cups")
        validate_discrete_control_fields(self)
        if not (np.isfinite(self.wheel_kd) and self.wheel_kd > 0):
            raise ScenarioError(f"wheel_kd must be > 0, got {self.wheel_kd}")
        for name, p in self.cup_positions.items():
            if name not in self.cups or len(p) != 3 or not np.all(np.isfinite(p)):
                raise ScenarioError(f"cup_positions: {name!r} must be one of cups {self.cups} "
                                    f"with 3 finite values, got {p}")  # fmt: skip
        unknown = sorted(set(self.gains) - set(GOTO_GAINS))
        if unknown:
            raise ScenarioError(f"unknown GoToPose gains {unknown}; expected {list(GOTO_GAINS)}")


def add_kitchen_world(parser: Parser, cups) -> None:
    """Adds the models of kitchen.sdf to the parser's plant, of its cups only ``cups``."""
    text = (MODELS_DIR / WORLDS["kitchen"]).read_text()
    dropped = [c for c in KITCHEN_CUPS if c not in cups]
    for cup in dropped:
        text, n = re.subn(rf'\s*<model name="{cup}">.*?</model>', "", text, flags=re.S)
        if n != 1:
            raise ScenarioError(f"kitchen.sdf has no single model {cup!r}")  # the file changed
    parser.AddModelsFromString(text, "sdf")


def joint_state_selector(plant, joints) -> np.ndarray:
    """``(len(joints), nq + nv)`` matrix picking the named joints' positions from the state."""
    n = plant.num_positions() + plant.num_velocities()
    S = np.zeros((len(joints), n))
    for i, name in enumerate(joints):
        S[i, plant.GetJointByName(name).position_start()] = 1.0
    return S


def cup_position_selector(plant, cups) -> np.ndarray:
    """``(3 len(cups), nq + nv)`` matrix picking each named cup's centre ``[x, y, z]``.

    The cups are free bodies: their positions are a quaternion, then the translation.
    """
    n = plant.num_positions() + plant.num_velocities()
    S = np.zeros((3 * len(cups), n))
    for i, name in enumerate(cups):
        body = plant.GetBodyByName("cup", plant.GetModelInstanceByName(name))
        start = body.floating_positions_start() + 4
        S[3 * i : 3 * i + 3, start : start + 3] = np.eye(3)
    return S


def desired_state_matrix() -> np.ndarray:
    """``(14, 7)`` map from ``[v, omega, lift, yaw, extend, left, right]`` to the desired state.

    The desired state is ``[q_d, v_d]`` over the actuators in order (two wheels,
    three arm joints, two fingers): the wheels get velocities only (their kp is
    0), the arm and fingers positions with zero velocity.
    """
    M = np.zeros((14, 7))
    M[7:9, 0:2] = twist_to_wheel_state_matrix()[2:]
    M[2:7, 2:7] = np.eye(5)
    return M


@register_diagram(
    "kitchen_action",
    scenario_type=KitchenScenario,
    description="diffdrive arm robot in the kitchen running GoToPose, Reach, Grip or Put",
    duration=6.0,
    check=lambda diagram, context: check_kitchen_action(diagram, context),
    criteria={"status_succeeded": Bound(1.0, 1.0)},
)
def build_kitchen_action(
    scenario: KitchenScenario, *, meshcat=None, check_start: bool = True
) -> Diagram:
    """Builds the kitchen with the robot running ``scenario.action``.

    ``check_start`` refuses a start where the robot or a cup overlaps another
    body (:func:`~repertoire.diagrams.diffdrive.check_start_clear`); a caller
    that overwrites the whole plant state (a sequence's next step) turns it off.

    Returns:
        The Diagram ``kitchen_action`` with subsystems ``plant``, ``scene_graph``,
        ``state_reader``, ``arm_reader``, ``finger_reader``, ``action`` (the
        running action), ``target`` (its target source, absent for ``grip``),
        ``cup_reader`` (the cups' centres for reach and put, which keep off the standing
        cups; absent without cups) and ``desired_state``.
    """
    scenario.validate()
    builder = DiagramBuilder()
    plant, scene_graph = add_plant_with_ground(
        builder, scenario.time_step, scenario.contact_approximation, scenario.ground_friction
    )
    parser = Parser(plant)
    ConfigureParser(parser)
    (robot,) = parser.AddModels(url=package_url(ROBOT_URL_PATH))
    for side in ("left", "right"):
        plant.GetJointActuatorByName(f"{side}_wheel_motor", robot).set_controller_gains(
            PdControllerGains(p=0.0, d=scenario.wheel_kd)
        )
    for joint, (kp, kd) in ARM_GAINS.items():
        plant.GetJointActuatorByName(f"{joint}_motor", robot).set_controller_gains(
            PdControllerGains(p=kp, d=kd)
        )
    add_kitchen_world(parser, scenario.cups)
    plant.Finalize()
    _set_default_state(plant, scenario)

    reader = builder.AddSystem(DiffDriveStateReader(plant))
    reader.set_name("state_reader")
    arm_reader = builder.AddSystem(MatrixGain(joint_state_selector(plant, ARM_JOINTS)))
    arm_reader.set_name("arm_reader")
    finger_reader = builder.AddSystem(MatrixGain(joint_state_selector(plant, FINGER_JOINTS)))
    finger_reader.set_name("finger_reader")
    for system in (reader, arm_reader, finger_reader):
        builder.Connect(plant.get_state_output_port(), system.get_input_port())
    mux = builder.AddSystem(Multiplexer([2, 3, 2]))
    mux.set_name("command_mux")  # [v, omega], arm joints, fingers
    to_state = builder.AddSystem(MatrixGain(desired_state_matrix()))
    to_state.set_name("desired_state")
    builder.Connect(mux.get_output_port(), to_state.get_input_port())
    builder.Connect(to_state.get_output_port(), plant.get_desired_state_input_port(robot))

    values = source_values(scenario)

    def hold(port_index: int) -> None:
        name = ("hold_wheels", "hold_arm", "hold_fingers")[port_index]
        source = builder.AddSystem(ConstantVectorSource(values[name]))
        source.set_name(name)
        builder.Connect(source.get_output_port(), mux.get_input_port(port_index))

    def target_source():
        source = builder.AddSystem(ConstantVectorSource(values["target"]))
        source.set_name("target")
        return source

    period = scenario.control_period
    cups = len(scenario.cups)  # goto_pose, reach and put keep off the standing cups
    if scenario.action == "goto_pose":
        try:
            names = [*KITCHEN_OBSTACLE_NAMES, *scenario.cups]
            if scenario.drive_check:
                goto = KitchenGoToPose(period, scenario.gains, KITCHEN_WORKSPACE,
                                       obstacles=KITCHEN_OBSTACLES, radius=ROBOT_RADIUS,
                                       names=names, cups=cups, cup_radius=CUP_RADIUS,
                                       cup_half_height=CUP_HALF_HEIGHT,
                                       braking=KITCHEN_BRAKING)  # fmt: skip
            else:
                goto = GoToPose(period, scenario.gains, KITCHEN_WORKSPACE)
        except RepertoireError as e:
            raise ScenarioError(f"gains: {e}") from e
        action = builder.AddSystem(goto)
        guard = builder.AddSystem(FootprintGuard(KITCHEN_OBSTACLES, ROBOT_RADIUS))
        builder.Connect(target_source().get_output_port(), guard.get_input_port())
        builder.Connect(guard.get_output_port(), action.get_target_input_port())
        builder.Connect(reader.get_output_port(), action.get_state_input_port())
        builder.Connect(action.get_command_output_port(), mux.get_input_port(0))
        if scenario.drive_check:  # the arm's measured joints and fingers, the cups
            builder.Connect(arm_reader.get_output_port(), action.get_arm_position_input_port())
        hold(1)
        hold(2)
    else:
        hold(0)
        if scenario.action == "reach":
            reach = Reach(period, obstacles=KITCHEN_OBSTACLES, cup_half_height=CUP_HALF_HEIGHT,
                          cup_radius=CUP_RADIUS, cups=cups, tracking=ARM_TRACKING)  # fmt: skip
            action = builder.AddSystem(reach)
            builder.Connect(action.get_command_output_port(), mux.get_input_port(1))
            hold(2)
        elif scenario.action == "grip":
            action = builder.AddSystem(Grip(period))
            builder.Connect(action.get_command_output_port(), mux.get_input_port(2))
            hold(1)
        else:
            put = Put(period, cup_half_height=CUP_HALF_HEIGHT, cup_radius=CUP_RADIUS,
                      obstacles=KITCHEN_OBSTACLES, cups=cups, tracking=ARM_TRACKING)  # fmt: skip
            action = builder.AddSystem(put)
            demux = builder.AddSystem(MatrixGain(np.eye(5)[:3]))
            demux.set_name("put_arm_command")
            demux_f = builder.AddSystem(MatrixGain(np.eye(5)[3:]))
            demux_f.set_name("put_finger_command")
            for d, i in ((demux, 1), (demux_f, 2)):
                builder.Connect(action.get_command_output_port(), d.get_input_port())
                builder.Connect(d.get_output_port(), mux.get_input_port(i))
        builder.Connect(reader.get_output_port(), action.get_base_state_input_port())
        if scenario.action in ("reach", "put"):
            builder.Connect(arm_reader.get_output_port(), action.get_arm_position_input_port())
            builder.Connect(
                target_source().get_output_port(),
                action.get_target_input_port(),
            )
    checked = scenario.action != "grip" and (scenario.action != "goto_pose" or scenario.drive_check)
    if cups and checked:
        cup_reader = builder.AddSystem(MatrixGain(cup_position_selector(plant, scenario.cups)))
        cup_reader.set_name("cup_reader")
        builder.Connect(plant.get_state_output_port(), cup_reader.get_input_port())
        builder.Connect(cup_reader.get_output_port(), action.get_cup_positions_input_port())
    if scenario.action != "goto_pose" or scenario.drive_check:  # (for the obstacle checks)
        builder.Connect(finger_reader.get_output_port(), action.get_finger_position_input_port())
    action.set_name("action")
    if meshcat is not None:
        from pydrake.geometry import MeshcatVisualizer

        MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat)
    diagram = builder.Build()
    diagram.set_name("kitchen_action")
    if check_start:
        fields = {c: f"cup_positions[{c}] {p}" for c, p in scenario.cup_positions.items()}
        robot = f"initial_pose {scenario.initial_pose} with initial_arm {scenario.initial_arm}"
        check_start_clear(diagram, {"diffdrive_arm": robot, **fields})
    return diagram


def source_values(scenario: KitchenScenario) -> dict[str, np.ndarray]:
    """Values of the constant sources of ``scenario``'s diagram, by subsystem name.

    ``target`` (goto_pose: ``goto_target``; reach, put: ``arm_target``; absent for
    grip) and the hold values of the channels the action does not drive:
    ``hold_wheels`` ``[v, omega] = 0``, ``hold_arm`` the start joints,
    ``hold_fingers`` the start fingers (closed with ``cup_in_gripper``).
    """
    fingers = FINGER_CLOSED if scenario.cup_in_gripper else scenario.initial_fingers
    held = {
        "hold_wheels": [0.0, 0.0],
        "hold_arm": scenario.initial_arm,
        "hold_fingers": [fingers] * 2,
    }
    driven = {"goto_pose": "hold_wheels", "reach": "hold_arm", "grip": "hold_fingers"}
    if scenario.action == "put":
        del held["hold_arm"], held["hold_fingers"]
    else:
        del held[driven[scenario.action]]
    if scenario.action == "goto_pose":
        held["target"] = scenario.goto_target
    elif scenario.action in ("reach", "put"):
        held["target"] = scenario.arm_target
    return {name: np.asarray(v, dtype=float) for name, v in held.items()}


def _structure(scenario: KitchenScenario) -> tuple:
    """The fields that shape the diagram (the others are start values and targets)."""
    s = scenario
    return (s.action, s.cup_in_gripper, tuple(s.cups), s.time_step, s.control_period,
            s.contact_approximation, s.wheel_kd, s.ground_friction,
            tuple(sorted(s.gains.items())), s.drive_check)  # fmt: skip


#: ``kitchen_action`` simulators by diagram structure (see :func:`kitchen_simulator`).
KITCHEN_SIMULATORS = SimulatorCache(build_kitchen_action)


def kitchen_simulator(scenario: KitchenScenario, *, reuse: bool = True):
    """A Simulator of the ``kitchen_action`` diagram at time 0 in ``scenario``'s start.

    The diagram is built the first time its structure (action, cups, plant
    settings, gains) is asked for in this process and reset afterwards
    (:class:`~repertoire.diagrams.simulate.SimulatorCache`: a reset diagram
    runs bit for bit as a new one). Change the context as needed, then call
    ``simulator.Initialize()`` before advancing.

    Args:
        scenario: the world, action and start.
        reuse: False builds a new diagram (and forgets the one kept for this structure).

    Returns:
        ``(diagram, simulator)``.
    """
    scenario.validate()
    return KITCHEN_SIMULATORS.get(
        _structure(scenario),
        scenario,
        lambda plant: _set_default_state(plant, scenario),
        source_values(scenario),
        reuse=reuse,
    )


def _set_default_state(plant, scenario: KitchenScenario) -> None:
    """Default positions: chassis pose, arm, fingers and (optionally) the cup in the gripper."""
    x, y, yaw = scenario.initial_pose
    plant.SetDefaultFloatingBaseBodyPose(
        plant.GetBodyByName("chassis"),
        RigidTransform(RollPitchYaw(0.0, 0.0, yaw), [x, y, WHEEL_RADIUS]),
    )
    for name, value in zip(ARM_JOINTS, scenario.initial_arm):
        plant.GetJointByName(name).set_default_positions([value])
    for name in scenario.cups:  # every cup, as a reset diagram keeps the last defaults
        plant.SetDefaultFloatingBaseBodyPose(
            plant.GetBodyByName("cup", plant.GetModelInstanceByName(name)),
            RigidTransform(scenario.cup_positions.get(name, KITCHEN_CUP_POSITIONS[name])),
        )
    fingers = scenario.initial_fingers
    if scenario.cup_in_gripper:
        fingers = CUP_RADIUS + 0.01 - 1e-4  # the fingers' inner faces on the cup
        cup = chassis_to_world([x, y, yaw], arm_forward(scenario.initial_arm))
        plant.SetDefaultFloatingBaseBodyPose(
            plant.GetBodyByName("cup", plant.GetModelInstanceByName("cup_0")),
            RigidTransform(RollPitchYaw(0.0, 0.0, yaw), cup),
        )
    for name in FINGER_JOINTS:
        plant.GetJointByName(name).set_default_positions([fingers])


def world_to_chassis(base_state, p) -> np.ndarray:
    """A world point in the chassis frame of the robot at ``[x, y, phi, ...]``."""
    x, y, phi = base_state[0], base_state[1], base_state[2]
    c, s = math.cos(phi), math.sin(phi)
    dx, dy = p[0] - x, p[1] - y
    return np.array([c * dx + s * dy, -s * dx + c * dy, p[2] - WHEEL_RADIUS])


def action_status(diagram: Diagram, context: Context) -> ActionStatus:
    """The running action's status in a ``kitchen_action`` diagram's context."""
    action = diagram.GetSubsystemByName("action")
    return action.get_status_output_port().Eval(action.GetMyContextFromRoot(context))


def cup_position(diagram: Diagram, context: Context, name: str = "cup_0") -> np.ndarray:
    """World position of a cup's centre."""
    plant = diagram.GetSubsystemByName("plant")
    body = plant.GetBodyByName("cup", plant.GetModelInstanceByName(name))
    return plant.EvalBodyPoseInWorld(plant.GetMyContextFromRoot(context), body).translation()


def gripper_position(diagram: Diagram, context: Context) -> np.ndarray:
    """World position of the gripper centre."""
    plant = diagram.GetSubsystemByName("plant")
    body = plant.GetBodyByName("arm_slide")
    return plant.EvalBodyPoseInWorld(plant.GetMyContextFromRoot(context), body).translation()


def furniture_and_robot_bodies(plant) -> tuple[set, set]:
    """Body indices of the kitchen's furniture (room walls, counter, tables) and of the robot."""
    furniture = {plant.GetBodyByName(name).index() for name in ("room", "counter")}
    furniture |= {
        plant.GetBodyByName("table", plant.GetModelInstanceByName(t)).index()
        for t in ("table_0", "table_1")
    }
    robot = set(plant.GetBodyIndices(plant.GetModelInstanceByName("diffdrive_arm")))
    return furniture, robot


def touches(contact_results, bodies_a: set, bodies_b: set) -> bool:
    """True if a point contact of ``contact_results`` joins a body of each set."""
    for i in range(contact_results.num_point_pair_contacts()):
        info = contact_results.point_pair_contact_info(i)
        a, b = info.bodyA_index(), info.bodyB_index()
        if (a in bodies_a and b in bodies_b) or (b in bodies_a and a in bodies_b):
            return True
    return False


def check_kitchen_action(diagram: Diagram, context: Context) -> dict[str, float]:
    """The world's figures at the end of a run.

    ``status_succeeded`` (1/0), ``still_running`` (1/0: the action had not ended, a
    longer run may still succeed), ``touching_furniture`` (1/0: the robot touches a
    table, the counter or a wall, e.g. GoToPose pushing against a table leg) and
    ``gripper_to_cup_m`` (cup_0 from the gripper centre; only if cup_0 is in the world).
    """
    status = action_status(diagram, context)
    plant = diagram.GetSubsystemByName("plant")
    contacts = plant.get_contact_results_output_port().Eval(plant.GetMyContextFromRoot(context))
    figures = {
        "status_succeeded": float(status == ActionStatus.SUCCEEDED),
        "still_running": float(status == ActionStatus.RUNNING),
        "touching_furniture": float(touches(contacts, *furniture_and_robot_bodies(plant))),
    }
    if diagram.GetSubsystemByName("plant").HasModelInstanceNamed("cup_0"):
        gap = cup_position(diagram, context) - gripper_position(diagram, context)
        figures["gripper_to_cup_m"] = float(np.linalg.norm(gap))
    return figures


@dataclasses.dataclass
class StepResult:
    """One executed step of :func:`run_kitchen_sequence`.

    Attributes:
        action: the action name.
        status: the final ActionStatus name (``TIMED_OUT`` also when the step was
            still running at the sequence's ``step_limit``).
        duration: simulated time the step took [s].
        reason: why the step failed, where its action says (``goto_pose``'s run-time
            check: :meth:`~repertoire.systems.kitchen_drive.KitchenGoToPose.failure`),
            else ``""``.
    """

    action: str
    status: str
    duration: float
    reason: str = ""


def _sample(on_sample, diagram: Diagram, step: int, context: Context) -> EventStatus:
    """A simulator monitor handing the state to ``on_sample``; it never stops the run."""
    on_sample(diagram, context, step)
    return EventStatus.Succeeded()


def run_kitchen_sequence(
    steps: list[tuple[str, list[float]]],
    scenario: KitchenScenario | None = None,
    *,
    step_limit: float = 30.0,
    on_sample: Callable[[Diagram, Context, int], None] | None = None,
) -> tuple[list[StepResult], Diagram, Context]:
    """Runs kitchen actions one after the other in physics, carrying the plant state over.

    Each step builds a ``kitchen_action`` diagram for its action (the plant is the
    same every time), copies the previous step's plant state into it and holds
    the channels the action does not drive at the previous step's setpoints (so
    a gripped cup stays squeezed while the robot drives). The sequence stops at
    the first step that does not succeed.

    Args:
        steps: ``(action, target)`` pairs: ``goto_pose`` with ``[x_g, y_g, phi_g,
            v_g]``, ``reach`` and ``put`` with a gripper-centre point ``[x, y, z]``
            in the *world* (converted to the chassis frame at the step's start),
            ``grip`` with ``[]``.
        scenario: the start (pose, arm, fingers) and plant settings.
        step_limit: simulated seconds allowed per step; a step still running then
            ends the sequence as ``TIMED_OUT``.
        on_sample: optional ``f(diagram, context, step)`` called after every simulator
            step (a monitor: it sees the state and changes nothing) with the running
            step's diagram, its context (time from the step's start) and its index.

    Returns:
        ``(results, diagram, context)`` of the executed steps and the last step.
    """
    from pydrake.systems.analysis import Simulator
    from repertoire.diagrams.soccer import robot_state

    if not (math.isfinite(step_limit) and step_limit > 0):
        raise ScenarioError(f"step_limit must be finite and > 0 s, got {step_limit}")
    base = dataclasses.replace(scenario or KitchenScenario())
    results: list[StepResult] = []
    x = None
    diagram = context = None
    for action, target in steps:
        if action not in ACTIONS:
            raise ScenarioError(f"unknown action {action!r} in the sequence; expected {ACTIONS}")
        step = dataclasses.replace(base, action=action, cup_in_gripper=False)
        if x is not None:
            step.initial_pose = list(robot_state(diagram, context)[:3])
        if action == "goto_pose":
            step.goto_target = list(target)
        elif action in ("reach", "put"):
            pose = robot_state(diagram, context) if x is not None else [*step.initial_pose, 0.0]
            step.arm_target = list(world_to_chassis(pose, target))
        diagram = build_kitchen_action(step, check_start=x is None)  # x: the whole state
        simulator = Simulator(diagram)
        context = simulator.get_mutable_context()
        plant = diagram.GetSubsystemByName("plant")
        if x is not None:
            plant.SetPositionsAndVelocities(plant.GetMyMutableContextFromRoot(context), x)
        if on_sample is not None:
            simulator.set_monitor(functools.partial(_sample, on_sample, diagram, len(results)))
        t = 0.0
        while t < step_limit and action_status(diagram, context) == ActionStatus.RUNNING:
            t += 0.1
            simulator.AdvanceTo(t)
        status = action_status(diagram, context)
        if status == ActionStatus.RUNNING:  # cut off at step_limit: the sequence timed out
            status = ActionStatus.TIMED_OUT
        system = diagram.GetSubsystemByName("action")
        reason = ""
        if status == ActionStatus.FAILED and hasattr(system, "failure"):
            reason = system.failure(system.GetMyContextFromRoot(context))
        results.append(StepResult(action, status.name, float(context.get_time()), reason))
        x = plant.GetPositionsAndVelocities(plant.GetMyContextFromRoot(context)).copy()
        # the next step holds what this one commanded
        command = diagram.GetSubsystemByName("command_mux").get_output_port()
        held = command.Eval(diagram.GetSubsystemByName("command_mux").GetMyContextFromRoot(context))
        base.initial_arm, base.initial_fingers = list(held[2:5]), float(held[5])
        if status != ActionStatus.SUCCEEDED:
            break
    return results, diagram, context
