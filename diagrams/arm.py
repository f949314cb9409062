"""The arm7 world and the arm holding a pose under gravity (registered as ``arm_hold``).

The arm is controlled like the Sarcos arm of the DMP paper (Pastor et al.
2009, sec. IV-D): a feed-forward torque from inverse dynamics plus joint PD
feedback. The feed-forward is Drake's ``InverseDynamics`` evaluated on a
second, control-only plant that holds just the arm (no table, no objects; see
:func:`repertoire.models.arm7.make_arm7_control_plant`) at the measured state
and the reference acceleration. The PD runs inside the simulated plant as the
actuators' PD controllers (``PdControllerGains``, torque units, integrated
implicitly by the ``lagged``/``sap`` solvers, so stiff gains on the light
wrist stay stable); the plant clamps PD + feed-forward at the URDF effort
limits. The three fingers get the same treatment with their own gains, strong
enough to squeeze a cup or a bottle.

:func:`add_arm_station` and :func:`add_arm_controllers` are the reusable
pieces: a task-space controller builds the same station and controllers, then
feeds ``arm_desired_state`` (and, with ``reference_acceleration``,
``arm_desired_acceleration``) from its own systems instead of constants.
"""

import dataclasses

import numpy as np
from pydrake.geometry import SceneGraph
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.plant import AddMultibodyPlant, MultibodyPlant, MultibodyPlantConfig
from pydrake.multibody.tree import ModelInstanceIndex, PdControllerGains
from pydrake.systems.controllers import InverseDynamics
from pydrake.systems.framework import Context, Diagram, DiagramBuilder, InputPort
from pydrake.systems.primitives import ConstantVectorSource, MatrixGain, Multiplexer
from repertoire.diagrams.registry import register_diagram
from repertoire.diagrams.simulate import start_overlaps
from repertoire.models.arm7 import (
    ALL_JOINTS,
    ARM_JOINTS,
    ARM_KD,
    ARM_KP,
    HAND_JOINTS,
    HAND_OPEN,
    ArmWorld,
    add_arm7,
    add_arm_world,
    arm7_home_configuration,
    check_arm_configuration,
    default_arm_world,
    make_arm7_control_plant,
)

from repertoire.criteria import Bound
from repertoire.errors import RepertoireError, ScenarioError

CONTACT_APPROXIMATIONS = ("lagged", "sap", "similar")


@dataclasses.dataclass
class ArmScenario:
    """The arm7 on its base beside a table with objects, holding a configuration.

    Attributes:
        time_step: discrete plant time step [s].
        contact_approximation: discrete contact solver: ``lagged`` (default),
            ``sap`` or ``similar``; TAMSI is refused because it ignores the
            actuators' PD gains.
        base_xyz: position of the arm's base frame (floor under the shoulder) [m].
        base_yaw: rotation of the base about the vertical [rad].
        initial_q: the seven arm joint angles at t = 0, also the held pose [rad].
        initial_fingers: thumb, finger_1, finger_2 angles at t = 0 [rad].
        finger_targets: the hand's commanded finger angles [rad] (close the hand by
            commanding larger angles than ``initial_fingers``).
        kp: joint PD stiffness per arm joint [N m/rad] (7 values).
        kd: joint PD damping per arm joint [N m s/rad] (7 values).
        finger_kp: finger PD stiffness [N m/rad] (3 values); the thumb opposes two
            fingers, so its default is twice theirs and a grasped object stays centred.
        finger_kd: finger PD damping [N m s/rad] (3 values).
        world: the table and the objects on it.
    """

    time_step: float = 1e-3
    contact_approximation: str = "lagged"
    base_xyz: list[float] = dataclasses.field(default_factory=lambda: [0.0, 0.0, 0.0])
    base_yaw: float = 0.0
    initial_q: list[float] = dataclasses.field(
        default_factory=lambda: arm7_home_configuration().tolist()
    )
    initial_fingers: list[float] = dataclasses.field(default_factory=lambda: list(HAND_OPEN))
    finger_targets: list[float] = dataclasses.field(default_factory=lambda: list(HAND_OPEN))
    kp: list[float] = dataclasses.field(default_factory=lambda: list(ARM_KP))
    kd: list[float] = dataclasses.field(default_factory=lambda: list(ARM_KD))
    finger_kp: list[float] = dataclasses.field(default_factory=lambda: [4.0, 2.0, 2.0])
    finger_kd: list[float] = dataclasses.field(default_factory=lambda: [0.04, 0.02, 0.02])
    world: ArmWorld = dataclasses.field(default_factory=default_arm_world)

    def validate(self) -> None:
        """Checks every field; raises ScenarioError saying what is wrong and what is expected."""
        if not (np.isfinite(self.time_step) and 0 < self.time_step <= 0.01):
            raise ScenarioError(f"time_step must be in (0, 0.01] s, got {self.time_step}")
        if self.contact_approximation not in CONTACT_APPROXIMATIONS:
            raise ScenarioError(
                f"contact_approximation '{self.contact_approximation}' unknown; expected one "
                f"of {CONTACT_APPROXIMATIONS}"
            )
        _check_vector("base_xyz", self.base_xyz, 3)
        if not np.isfinite(self.base_yaw):
            raise ScenarioError(f"base_yaw must be finite, got {self.base_yaw}")
        for name, size in (("initial_q", 7), ("initial_fingers", 3), ("finger_targets", 3)):
            try:
                check_arm_configuration(getattr(self, name), name=name, size=size)
            except RepertoireError as e:
                raise ScenarioError(str(e)) from e
        for name, size in (("kp", 7), ("kd", 7), ("finger_kp", 3), ("finger_kd", 3)):
            values = _check_vector(name, getattr(self, name), size)
            if np.any(values < 0):
                raise ScenarioError(f"{name} gains must be >= 0, got {values.tolist()}")
        if not np.all(np.asarray(self.kp) > 0):
            raise ScenarioError(f"kp gains must be > 0 to hold a pose, got {self.kp}")
        self.world.validate()

    def X_WBase(self) -> RigidTransform:
        """The base frame's pose in the world."""
        return RigidTransform(RollPitchYaw(0, 0, self.base_yaw), np.asarray(self.base_xyz))


def _check_vector(name: str, values, size: int) -> np.ndarray:
    v = np.asarray(values, dtype=float).reshape(-1)
    if v.size != size or not np.all(np.isfinite(v)):
        raise ScenarioError(f"{name} must be {size} finite numbers, got {list(values)}")
    return v


@dataclasses.dataclass
class ArmStation:
    """What :func:`add_arm_station` added to a builder.

    Attributes:
        plant: the simulated ``MultibodyPlant`` (arm, table, objects).
        scene_graph: its ``SceneGraph``.
        arm: the arm's model instance.
        objects: model instance name -> index for ``table`` and every object.
    """

    plant: MultibodyPlant
    scene_graph: SceneGraph
    arm: ModelInstanceIndex
    objects: dict


@dataclasses.dataclass
class ArmControllers:
    """The controller inputs a builder must connect (see :func:`add_arm_controllers`).

    Attributes:
        control_plant: the arm-only plant (10 DOFs) the feed-forward uses.
        arm_desired_state: input [q_d(7), v_d(7)] of the arm's joint PD.
        arm_desired_acceleration: input vd_d(7) of the feed-forward, or None
            without reference acceleration (then vd_d = 0).
        hand_desired_state: input [q_d(3), v_d(3)] of the fingers' PD.
        feedforward: the ``InverseDynamics`` system.
    """

    control_plant: MultibodyPlant
    arm_desired_state: InputPort
    arm_desired_acceleration: InputPort | None
    hand_desired_state: InputPort
    feedforward: InverseDynamics


def add_arm_station(builder: DiagramBuilder, scenario: ArmScenario) -> ArmStation:
    """Adds the plant (arm7 + table + objects) with PD gains and the initial state as default.

    The actuators get the scenario's PD gains (``kp``/``kd`` for the arm,
    ``finger_kp``/``finger_kd`` for the hand); the plant's default positions are
    ``initial_q`` and ``initial_fingers``, the free objects rest on the table.

    Args:
        builder: the diagram builder.
        scenario: a validated :class:`ArmScenario`.
    """
    config = MultibodyPlantConfig(
        time_step=scenario.time_step, discrete_contact_approximation=scenario.contact_approximation
    )
    plant, scene_graph = AddMultibodyPlant(config, builder)
    arm = add_arm7(plant, X_WBase=scenario.X_WBase())
    objects = add_arm_world(plant, scenario.world)
    kp = list(scenario.kp) + list(scenario.finger_kp)
    kd = list(scenario.kd) + list(scenario.finger_kd)
    for joint, p, d in zip(ALL_JOINTS, kp, kd):
        plant.GetJointActuatorByName(f"{joint}_motor", arm).set_controller_gains(
            PdControllerGains(p=float(p), d=float(d))
        )
    plant.Finalize()
    plant.SetDefaultPositions(arm, np.concatenate([scenario.initial_q, scenario.initial_fingers]))
    return ArmStation(plant, scene_graph, arm, objects)


def _desired_state_map(plant: MultibodyPlant, arm: ModelInstanceIndex) -> np.ndarray:
    """Matrix from [q_arm(7), v_arm(7), q_hand(3), v_hand(3)] to the plant's desired state.

    The plant's per-instance desired state is [q_d, v_d] with entries in
    actuator-index order.
    """
    order = sorted(plant.GetJointActuatorIndices(arm), key=int)
    joint_of = [plant.get_joint_actuator(i).joint().name() for i in order]
    user = [("q", j) for j in ARM_JOINTS] + [("v", j) for j in ARM_JOINTS]
    user += [("q", j) for j in HAND_JOINTS] + [("v", j) for j in HAND_JOINTS]
    target = [("q", j) for j in joint_of] + [("v", j) for j in joint_of]
    P = np.zeros((len(target), len(user)))
    for row, key in enumerate(target):
        P[row, user.index(key)] = 1.0
    return P


def add_arm_controllers(
    builder: DiagramBuilder, station: ArmStation, *, reference_acceleration: bool = False
) -> ArmControllers:
    """Adds the inverse-dynamics feed-forward and wires the PD desired state into the plant.

    The feed-forward torque is ``InverseDynamics`` of the control-only arm plant
    at the measured arm state and the reference acceleration (zero for the
    fingers), mapped to the plant's actuation input; the PD feedback is the
    plant's own actuator PD (gains set by :func:`add_arm_station`; a station
    built by hand must set ``PdControllerGains`` on all ten arm7 actuators
    before ``Finalize``). The desired inputs are left for the caller to connect.

    Args:
        builder: the diagram builder holding ``station``.
        station: from :func:`add_arm_station`.
        reference_acceleration: whether to expose a desired arm acceleration
            input (feed-forward of a reference trajectory); zero otherwise.

    Raises:
        RepertoireError: an arm7 actuator without PD gains.
    """
    plant, arm = station.plant, station.arm
    missing = [
        j
        for j in ALL_JOINTS
        if not plant.GetJointActuatorByName(f"{j}_motor", arm).has_controller()
    ]
    if missing:
        raise RepertoireError(
            f"arm7 actuators {missing} have no PD gains: set PdControllerGains on every arm7 "
            "actuator before plant.Finalize() (add_arm_station does) so the plant runs the PD"
        )
    control_plant = make_arm7_control_plant(X_WBase=_base_pose(plant, arm))
    ff = builder.AddNamedSystem(
        "arm_feedforward",
        InverseDynamics(control_plant, InverseDynamics.InverseDynamicsMode.kInverseDynamics),
    )
    # InverseDynamics keeps only a reference to its plant: tie the plant's lifetime to
    # the system's Python wrapper, which the diagram keeps alive.
    ff._control_plant = control_plant
    builder.Connect(plant.get_state_output_port(arm), ff.get_input_port_estimated_state())
    ctrl_arm = control_plant.GetModelInstanceByName("arm7")
    v_index = {j: control_plant.GetJointByName(j, ctrl_arm).velocity_start() for j in ALL_JOINTS}
    accel_port = None
    if reference_acceleration:
        S = np.zeros((control_plant.num_velocities(), 7))
        for k, j in enumerate(ARM_JOINTS):
            S[v_index[j], k] = 1.0
        accel_map = builder.AddNamedSystem("arm_acceleration_map", MatrixGain(S))
        builder.Connect(accel_map.get_output_port(), ff.get_input_port_desired_acceleration())
        accel_port = accel_map.get_input_port()
    else:
        zero = builder.AddNamedSystem(
            "zero_acceleration", ConstantVectorSource(np.zeros(control_plant.num_velocities()))
        )
        builder.Connect(zero.get_output_port(), ff.get_input_port_desired_acceleration())
    B = control_plant.MakeActuationMatrix()  # v = B u; a permutation for arm7
    to_u = builder.AddNamedSystem("feedforward_to_actuation", MatrixGain(B.T))
    builder.Connect(ff.get_output_port_generalized_force(), to_u.get_input_port())
    builder.Connect(to_u.get_output_port(), plant.get_actuation_input_port(arm))
    mux = builder.AddNamedSystem("arm_hand_desired_state", Multiplexer([14, 6]))
    to_xd = builder.AddNamedSystem("desired_state_map", MatrixGain(_desired_state_map(plant, arm)))
    builder.Connect(mux.get_output_port(), to_xd.get_input_port())
    builder.Connect(to_xd.get_output_port(), plant.get_desired_state_input_port(arm))
    return ArmControllers(
        control_plant=control_plant,
        arm_desired_state=mux.get_input_port(0),
        arm_desired_acceleration=accel_port,
        hand_desired_state=mux.get_input_port(1),
        feedforward=ff,
    )


def _base_pose(plant: MultibodyPlant, arm: ModelInstanceIndex) -> RigidTransform:
    context = plant.CreateDefaultContext()
    return plant.CalcRelativeTransform(
        context, plant.world_frame(), plant.GetFrameByName("base", arm)
    )


def check_initial_clearance(
    diagram: Diagram, plant: MultibodyPlant, *, tolerance: float = 1e-3
) -> None:
    """Refuses a default state in which the arm penetrates the table, an object or itself.

    Args:
        diagram: the built diagram holding ``plant`` (and its SceneGraph).
        plant: the simulated plant.
        tolerance: penetration depth allowed [m] (resting contacts are ~1e-6 m).

    Raises:
        ScenarioError: naming the colliding bodies and the depth.
    """
    for a, b, depth in start_overlaps(diagram, plant, tolerance):
        if "arm7" in (a[0], b[0]):
            raise ScenarioError(
                f"initial configuration in collision: {a[0]}::{a[1]} penetrates {b[0]}::{b[1]} "
                f"by {depth * 1000:.1f} mm; choose initial_q / initial_fingers / base pose / "
                "object positions that keep the arm clear"
            )


def add_meshcat(builder: DiagramBuilder, scene_graph: SceneGraph, meshcat) -> None:
    """Adds a MeshcatVisualizer when ``meshcat`` is not None."""
    if meshcat is not None:
        from pydrake.geometry import MeshcatVisualizer

        MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat)


def check_arm_hold(diagram: Diagram, context: Context) -> dict[str, float]:
    """Figures after an ``arm_hold`` simulation.

    Returns:
        ``max_joint_error_rad``: largest |q - q_held| over the seven arm joints;
        ``max_finger_error_rad``: largest |q - q_target| over the fingers;
        ``max_object_speed_m_s``: fastest free object (0 when resting).
    """
    plant = diagram.GetSubsystemByName("plant")
    plant_context = plant.GetMyContextFromRoot(context)
    arm = plant.GetModelInstanceByName("arm7")
    arm_src = diagram.GetSubsystemByName("arm_desired_state")
    hand_src = diagram.GetSubsystemByName("hand_desired_state")
    q_arm_d = arm_src.get_source_value(arm_src.GetMyContextFromRoot(context)).value()[:7]
    q_hand_d = hand_src.get_source_value(hand_src.GetMyContextFromRoot(context)).value()[:3]
    q_by_joint = {j: plant.GetJointByName(j, arm).get_angle(plant_context) for j in ALL_JOINTS}
    arm_err = max(abs(q_by_joint[j] - q_arm_d[k]) for k, j in enumerate(ARM_JOINTS))
    hand_err = max(abs(q_by_joint[j] - q_hand_d[k]) for k, j in enumerate(HAND_JOINTS))
    speed = 0.0
    for body_index in plant.GetFloatingBaseBodies():
        body = plant.get_body(body_index)
        v = body.EvalSpatialVelocityInWorld(plant_context).translational()
        speed = max(speed, float(np.linalg.norm(v)))
    return {
        "max_joint_error_rad": float(arm_err),
        "max_finger_error_rad": float(hand_err),
        "max_object_speed_m_s": speed,
    }


@register_diagram(
    "arm_hold",
    scenario_type=ArmScenario,
    description="7-DOF arm7 with a 3-finger hand holding a pose under gravity (inverse "
    "dynamics + PD) beside a table with cups, a bottle, a coaster and a ball",
    duration=1.0,
    check=check_arm_hold,
    criteria={
        "max_joint_error_rad": Bound(hi=0.01),
        "max_object_speed_m_s": Bound(hi=0.01),
    },
)
def build_arm_hold(scenario: ArmScenario, *, meshcat=None) -> Diagram:
    """Builds the arm holding ``scenario.initial_q`` and commanding ``finger_targets``.

    Args:
        scenario: the :class:`ArmScenario` (validated here).
        meshcat: optional Meshcat instance for a visualizer.

    Returns:
        The Diagram named ``arm_hold``; its default context starts at the
        scenario's initial state with the objects resting on the table.

    Raises:
        ScenarioError: an invalid scenario, or an initial arm pose that
            penetrates the table, an object or the arm itself.
    """
    scenario.validate()
    builder = DiagramBuilder()
    station = add_arm_station(builder, scenario)
    controllers = add_arm_controllers(builder, station)
    arm_src = builder.AddNamedSystem(
        "arm_desired_state", ConstantVectorSource(np.concatenate([scenario.initial_q, np.zeros(7)]))
    )
    hand_src = builder.AddNamedSystem(
        "hand_desired_state",
        ConstantVectorSource(np.concatenate([scenario.finger_targets, np.zeros(3)])),
    )
    builder.Connect(arm_src.get_output_port(), controllers.arm_desired_state)
    builder.Connect(hand_src.get_output_port(), controllers.hand_desired_state)
    add_meshcat(builder, station.scene_graph, meshcat)
    diagram = builder.Build()
    diagram.set_name("arm_hold")
    check_initial_clearance(diagram, station.plant)
    return diagram
