"""LittleDog on any terrain at a given start pose (the crawl and library diagrams' world).

``add_littledog_on_terrain`` puts the board(s) and LittleDog (PD actuators) into a
builder with the plant's default state at a given body pose and joint angles;
``build_crawl_playback`` feeds a :class:`~repertoire.planning.littledog_crawl.CrawlPlan`'s
joint commands to the plant's PD and logs the plant state and the feet's contact
flags every ``log_period`` (what the demonstrations record).
"""

import dataclasses

import numpy as np
from pydrake.geometry import SceneGraph
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.plant import (
    AddMultibodyPlant,
    CoulombFriction,
    MultibodyPlant,
    MultibodyPlantConfig,
)
from pydrake.multibody.tree import ModelInstanceIndex
from pydrake.systems.framework import Context, Diagram, DiagramBuilder
from pydrake.systems.primitives import TrajectorySource, VectorLogSink
from pydrake.trajectories import PiecewisePolynomial
from repertoire.diagrams.littledog import BODY_NAME, LittleDogScenario, add_littledog
from repertoire.models.littledog import FOOT_FRAMES, JOINT_NAMES
from repertoire.models.terrain import TerrainBoard
from repertoire.planning.littledog_crawl import CrawlPlan
from repertoire.systems.littledog_sensors import FootContactSensor

from repertoire.errors import RepertoireError


@dataclasses.dataclass
class PlantSettings:
    """Physics settings of a LittleDog world (YAML-loadable).

    Attributes:
        time_step: discrete plant time step (s).
        contact_approximation: ``lagged``, ``sap`` or ``similar``.
        kp: PD proportional gains [hip roll, hip pitch, knee] (N m/rad).
        kd: PD derivative gains [hip roll, hip pitch, knee] (N m s/rad).
        friction: Coulomb friction of the terrain.
    """

    time_step: float = 1e-3
    contact_approximation: str = "lagged"
    kp: list[float] = dataclasses.field(default_factory=lambda: [30.0, 30.0, 30.0])
    kd: list[float] = dataclasses.field(default_factory=lambda: [0.4, 0.4, 0.4])
    friction: float = 1.0

    def validate(self) -> None:
        """Raises ScenarioError naming a bad field (the checks of ``LittleDogScenario``)."""
        LittleDogScenario(
            time_step=self.time_step,
            contact_approximation=self.contact_approximation,
            kp=list(self.kp),
            kd=list(self.kd),
            friction=self.friction,
        ).validate()


def add_littledog_on_terrain(
    builder: DiagramBuilder,
    board: TerrainBoard,
    pose0,
    q0,
    settings: PlantSettings,
) -> tuple[MultibodyPlant, SceneGraph, ModelInstanceIndex]:
    """Adds the terrain and LittleDog (default state: body at ``pose0``, joints at ``q0``).

    Args:
        builder: the diagram builder.
        board: the terrain (one or joined boards).
        pose0: body pose [x, y, z, roll, pitch, yaw].
        q0: 12 joint angles, ``JOINT_NAMES`` order.
        settings: physics settings (validated here).
    """
    settings.validate()
    config = MultibodyPlantConfig(
        time_step=settings.time_step,
        discrete_contact_approximation=settings.contact_approximation,
        contact_model="point",
    )
    plant, scene_graph = AddMultibodyPlant(config, builder)
    board.add_to_plant(plant, friction=CoulombFriction(settings.friction, settings.friction))
    instance = add_littledog(plant, kp=list(settings.kp), kd=list(settings.kd))
    plant.Finalize()
    pose0 = np.asarray(pose0, dtype=float)
    for name, q in zip(JOINT_NAMES, np.asarray(q0, dtype=float)):
        plant.GetJointByName(name, instance).set_default_angle(float(q))
    X_WB = RigidTransform(RollPitchYaw(pose0[3:]), pose0[:3])
    plant.SetDefaultFloatingBaseBodyPose(plant.GetBodyByName(BODY_NAME, instance), X_WB)
    return plant, scene_graph, instance


def actuator_order(plant: MultibodyPlant, instance: ModelInstanceIndex) -> np.ndarray:
    """Index into ``JOINT_NAMES`` of each actuator, in the plant's actuator order."""
    names = [
        plant.get_joint_actuator(i).joint().name() for i in plant.GetJointActuatorIndices(instance)
    ]
    return np.array([JOINT_NAMES.index(n) for n in names])


def joint_positions(plant: MultibodyPlant, instance: ModelInstanceIndex, q_plant) -> np.ndarray:
    """The 12 joint angles (``JOINT_NAMES`` order) from plant positions ``q_plant`` (..., nq)."""
    starts = [plant.GetJointByName(n, instance).position_start() for n in JOINT_NAMES]
    return np.asarray(q_plant)[..., starts]


def world_foot_positions(plant: MultibodyPlant, plant_context: Context) -> np.ndarray:
    """World positions (4 x 3, ``LEGS`` order) of the foot centres."""
    return np.array(
        [plant.GetFrameByName(n).CalcPoseInWorld(plant_context).translation() for n in FOOT_FRAMES]
    )


def build_crawl_playback(
    board: TerrainBoard,
    plan: CrawlPlan,
    settings: PlantSettings | None = None,
    *,
    log_period: float = 0.01,
    meshcat=None,
) -> Diagram:
    """LittleDog on ``board`` playing a crawl plan's joint commands into its PD.

    The initial state is the plan's first body pose and joint angles. Subsystems:
    ``plant``, ``scene_graph``, ``commands`` (TrajectorySource of [q, qdot] in actuator
    order), ``contact`` (FootContactSensor), ``state_log``, ``contact_log`` and
    ``slip_log`` (VectorLogSinks of the plant state, contact flags and slip speeds,
    publishing every ``log_period``).

    Args:
        board: the terrain.
        plan: the crawl plan.
        settings: physics settings.
        log_period: logging period (s).
        meshcat: optional Meshcat for a visualizer.
    """
    settings = PlantSettings() if settings is None else settings
    if not (np.isfinite(log_period) and log_period > 0.0):
        raise RepertoireError(f"log_period must be > 0 s, got {log_period}")
    builder = DiagramBuilder()
    plant, scene_graph, instance = add_littledog_on_terrain(
        builder, board, plan.body_pose[0], plan.q[0], settings
    )
    order = actuator_order(plant, instance)
    q = plan.q[:, order]
    traj = PiecewisePolynomial.CubicShapePreserving(
        plan.times, q.T, zero_end_point_derivatives=True
    )
    commands = builder.AddSystem(TrajectorySource(traj, output_derivative_order=1))
    commands.set_name("commands")
    builder.Connect(commands.get_output_port(), plant.get_desired_state_input_port(instance))
    contact = builder.AddSystem(FootContactSensor(plant, instance))
    contact.set_name("contact")
    builder.Connect(plant.get_contact_results_output_port(), contact.contact_results_input)
    state_log = builder.AddSystem(VectorLogSink(plant.num_multibody_states(), log_period))
    state_log.set_name("state_log")
    builder.Connect(plant.get_state_output_port(), state_log.get_input_port())
    contact_log = builder.AddSystem(VectorLogSink(4, log_period))
    contact_log.set_name("contact_log")
    builder.Connect(contact.contact_output, contact_log.get_input_port())
    slip_log = builder.AddSystem(VectorLogSink(4, log_period))
    slip_log.set_name("slip_log")
    builder.Connect(contact.slip_speed_output, slip_log.get_input_port())
    if meshcat is not None:
        from pydrake.geometry import MeshcatVisualizer

        MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat)
    diagram = builder.Build()
    diagram.set_name("littledog_crawl")
    return diagram


__all__ = [
    "PlantSettings",
    "actuator_order",
    "add_littledog_on_terrain",
    "build_crawl_playback",
    "joint_positions",
    "world_foot_positions",
]
