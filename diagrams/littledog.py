"""LittleDog standing on a terrain board under joint PD (registered as ``littledog_stand``).

The plant's 12 actuators carry PD gains, so a constant ``desired_state`` (the
standing joint angles and zero velocities) fed into the plant's desired-state
input makes it hold the stance; no controller system is needed. The initial
pose puts every foot sphere on the terrain under it (closed-form leg IK on the
board's exact height function), with the body level at ``standing_height``
above the mean ground height under the feet.
"""

import dataclasses
import math

import numpy as np
from pydrake.geometry import SceneGraph
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import (
    AddMultibodyPlant,
    CoulombFriction,
    MultibodyPlant,
    MultibodyPlantConfig,
)
from pydrake.multibody.tree import JointActuatorIndex, ModelInstanceIndex, PdControllerGains
from pydrake.systems.framework import Context, Diagram, DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource
from repertoire.diagrams.registry import register_diagram
from repertoire.models import ConfigureParser, package_url
from repertoire.models.littledog import (
    FOOT_FRAMES,
    FOOT_RADIUS,
    JOINT_NAMES,
    LEGS,
    STANDING_HEIGHT,
    URDF_PATH,
    nominal_foot_positions,
    standing_configuration,
)
from repertoire.models.terrain import TerrainBoard, TerrainParams, generate_board

from repertoire.criteria import Bound
from repertoire.errors import RepertoireError, ScenarioError

CONTACT_APPROXIMATIONS = ["lagged", "sap", "similar"]
BODY_NAME = "body"


@dataclasses.dataclass
class LittleDogScenario:
    """LittleDog standing on a generated terrain board.

    Attributes:
        terrain: board generator parameters (``terrain.kind`` is the board kind:
            flat, rocks, steps, gaps or mixed).
        board_seed: seed of the board generator.
        time_step: discrete plant time step (s).
        contact_approximation: ``lagged`` (default), ``sap`` or ``similar``; TAMSI is
            refused because it ignores the actuators' PD gains.
        kp: PD proportional gains (N m/rad) for [hip roll, hip pitch, knee], every leg.
        kd: PD derivative gains (N m s/rad) for [hip roll, hip pitch, knee], every leg.
        base_xy: initial [x, y] of the body origin in the world (m).
        base_yaw: initial heading of the body about world z (rad).
        standing_height: body origin height above the mean ground height under the feet (m).
        foot_offset_x: forward shift of every foot from under its hip (m).
        foot_offset_y: outward shift of every foot from under its hip (m).
        friction: Coulomb friction coefficient of the terrain (feet have 1.0).
    """

    terrain: TerrainParams = dataclasses.field(default_factory=TerrainParams)
    board_seed: int = 0
    time_step: float = 1e-3
    contact_approximation: str = "lagged"
    kp: list[float] = dataclasses.field(default_factory=lambda: [20.0, 20.0, 20.0])
    kd: list[float] = dataclasses.field(default_factory=lambda: [0.3, 0.3, 0.3])
    base_xy: list[float] = dataclasses.field(default_factory=lambda: [0.0, 0.0])
    base_yaw: float = 0.0
    standing_height: float = STANDING_HEIGHT
    foot_offset_x: float = 0.0
    foot_offset_y: float = 0.0
    friction: float = 1.0

    def validate(self) -> None:
        """Checks every field (including the terrain parameters).

        Raises:
            ScenarioError: naming the bad field, its value and what is expected.
        """
        try:
            self.terrain.validate()
        except RepertoireError as e:
            raise ScenarioError(f"LittleDogScenario.terrain: {e}") from e
        if int(self.board_seed) != self.board_seed or self.board_seed < 0:
            raise ScenarioError(f"board_seed must be an integer >= 0, got {self.board_seed}")
        if not (math.isfinite(self.time_step) and 0.0 < self.time_step <= 0.01):
            raise ScenarioError(
                f"time_step must be in (0, 0.01] s (a discrete plant), got {self.time_step}"
            )
        if self.contact_approximation not in CONTACT_APPROXIMATIONS:
            raise ScenarioError(
                f"contact_approximation must be one of {CONTACT_APPROXIMATIONS} (TAMSI ignores "
                f"the actuators' PD gains), got {self.contact_approximation!r}"
            )
        for name in ("kp", "kd"):
            values = list(getattr(self, name))
            if len(values) != 3 or not all(math.isfinite(v) and v >= 0.0 for v in values):
                raise ScenarioError(
                    f"{name} must be 3 finite values >= 0 ([hip roll, hip pitch, knee]), "
                    f"got {values}"
                )
        if min(self.kp) <= 0.0:
            raise ScenarioError(f"kp must be > 0 (Drake PD actuators need p > 0), got {self.kp}")
        if len(self.base_xy) != 2 or not all(math.isfinite(v) for v in self.base_xy):
            raise ScenarioError(f"base_xy must be 2 finite numbers [x, y], got {self.base_xy}")
        if not math.isfinite(self.base_yaw):
            raise ScenarioError(f"base_yaw must be finite, got {self.base_yaw}")
        if not (0.08 <= self.standing_height <= 0.18):
            raise ScenarioError(
                f"standing_height must be in [0.08, 0.18] m (legs reach about 0.187 m), "
                f"got {self.standing_height}"
            )
        for name in ("foot_offset_x", "foot_offset_y"):
            value = getattr(self, name)
            if not (math.isfinite(value) and abs(value) <= 0.06):
                raise ScenarioError(f"{name} must be within +-0.06 m, got {value}")
        if not (math.isfinite(self.friction) and self.friction > 0.0):
            raise ScenarioError(f"friction must be > 0, got {self.friction}")


@dataclasses.dataclass
class StandingPose:
    """The initial standing state computed for a scenario.

    Attributes:
        X_WB: world pose of the body.
        q_joints: 12 joint angles in ``JOINT_NAMES`` order (rad).
        p_WF: 4 x 3 world positions of the foot centres (``LEGS`` order).
        ground_heights: terrain height under each foot (m).
    """

    X_WB: RigidTransform
    q_joints: np.ndarray
    p_WF: np.ndarray
    ground_heights: np.ndarray


def standing_pose(scenario: LittleDogScenario, board: TerrainBoard) -> StandingPose:
    """Body pose and joint angles with every foot on the board's surface.

    Args:
        scenario: the scenario (base xy, yaw, standing height, foot offsets).
        board: the terrain board (its exact height function is used).

    Raises:
        RepertoireError: when the feet cannot reach the terrain within the joint limits.
    """
    p_BF = nominal_foot_positions(
        scenario.standing_height,
        offset_x=scenario.foot_offset_x,
        offset_y=scenario.foot_offset_y,
    )
    R_WB = RotationMatrix.MakeZRotation(scenario.base_yaw)
    xy_WF = np.asarray(scenario.base_xy) + (R_WB.matrix()[:2, :2] @ p_BF[:, :2].T).T
    heights = board.height(xy_WF[:, 0], xy_WF[:, 1])
    ground = float(np.mean(heights))
    try:
        q = standing_configuration(
            scenario.standing_height,
            heights - ground,
            offset_x=scenario.foot_offset_x,
            offset_y=scenario.foot_offset_y,
        )
    except RepertoireError as e:
        raise RepertoireError(
            f"LittleDog cannot stand at base_xy={scenario.base_xy} on this board (ground "
            f"heights under the feet {np.round(heights, 4).tolist()} m): {e}"
        ) from e
    z = ground + scenario.standing_height
    X_WB = RigidTransform(R_WB, [scenario.base_xy[0], scenario.base_xy[1], z])
    p_WF = np.column_stack([xy_WF, heights + FOOT_RADIUS])
    return StandingPose(X_WB=X_WB, q_joints=q, p_WF=p_WF, ground_heights=heights)


def add_littledog(
    plant: MultibodyPlant, *, kp: list[float] | None = None, kd: list[float] | None = None
) -> ModelInstanceIndex:
    """Parses the LittleDog URDF into ``plant`` (not finalized) and sets its PD gains.

    Args:
        plant: a MultibodyPlant with a SceneGraph, before Finalize().
        kp: [hip roll, hip pitch, knee] proportional gains; default the URDF's.
        kd: [hip roll, hip pitch, knee] derivative gains; default the URDF's.

    Returns:
        The LittleDog model instance.
    """
    parser = Parser(plant)
    ConfigureParser(parser)
    (instance,) = parser.AddModels(url=package_url(URDF_PATH))
    if kp is not None or kd is not None:
        # GetJointActuatorIndices(instance) is empty before Finalize(): scan all actuators.
        for k in range(plant.num_actuators()):
            actuator = plant.get_joint_actuator(JointActuatorIndex(k))
            if actuator.model_instance() != instance:
                continue
            k = [s in actuator.joint().name() for s in ("hip_roll", "hip_pitch", "knee")].index(
                True
            )
            old = actuator.get_controller_gains()
            actuator.set_controller_gains(
                PdControllerGains(
                    p=float(kp[k]) if kp is not None else old.p,
                    d=float(kd[k]) if kd is not None else old.d,
                )
            )
    return instance


def desired_state_vector(
    plant: MultibodyPlant, instance: ModelInstanceIndex, q_joints: np.ndarray
) -> np.ndarray:
    """The plant's desired-state input [qd, vd] (actuator order) for joint angles.

    Args:
        plant: the finalized plant.
        instance: the LittleDog model instance.
        q_joints: 12 joint angles in ``JOINT_NAMES`` order (rad).
    """
    by_name = dict(zip(JOINT_NAMES, np.asarray(q_joints, dtype=float)))
    indices = plant.GetJointActuatorIndices(instance)
    qd = [by_name[plant.get_joint_actuator(i).joint().name()] for i in indices]
    return np.concatenate([qd, np.zeros(len(qd))])


def add_littledog_world(
    builder: DiagramBuilder, scenario: LittleDogScenario
) -> tuple[MultibodyPlant, SceneGraph, ModelInstanceIndex, TerrainBoard, StandingPose]:
    """Adds plant + scene graph with the board and LittleDog at its standing pose.

    Args:
        builder: the diagram builder.
        scenario: a validated scenario.

    Returns:
        ``(plant, scene_graph, instance, board, pose)`` with the plant finalized and
        its default state set to the standing pose.
    """
    config = MultibodyPlantConfig(
        time_step=scenario.time_step,
        discrete_contact_approximation=scenario.contact_approximation,
        contact_model="point",
    )
    plant, scene_graph = AddMultibodyPlant(config, builder)
    board = generate_board(scenario.terrain, scenario.board_seed)
    board.add_to_plant(plant, friction=CoulombFriction(scenario.friction, scenario.friction))
    instance = add_littledog(plant, kp=list(scenario.kp), kd=list(scenario.kd))
    plant.Finalize()
    pose = standing_pose(scenario, board)
    for name, q in zip(JOINT_NAMES, pose.q_joints):
        plant.GetJointByName(name, instance).set_default_angle(float(q))
    plant.SetDefaultFloatingBaseBodyPose(plant.GetBodyByName(BODY_NAME, instance), pose.X_WB)
    return plant, scene_graph, instance, board, pose


@register_diagram(
    "littledog_stand",
    scenario_type=LittleDogScenario,
    description="LittleDog quadruped (12 joints, floating base) standing on a terrain board "
    "under joint PD",
    duration=1.0,
    check=lambda diagram, context: check_littledog_stand(diagram, context),
    criteria={
        "height_error_m": Bound(-0.01, 0.01),
        "tilt_rad": Bound(hi=0.05),
    },
)
def build_littledog_stand(scenario: LittleDogScenario, *, meshcat=None) -> Diagram:
    """Builds LittleDog standing on a terrain board.

    Args:
        scenario: a :class:`LittleDogScenario` (validated here).
        meshcat: optional Meshcat instance for a visualizer.

    Returns:
        The Diagram ``littledog_stand`` with subsystems ``plant``, ``scene_graph`` and
        ``desired_state`` (the constant standing state fed to the plant's PD).
    """
    if not isinstance(scenario, LittleDogScenario):
        raise ScenarioError(
            f"littledog_stand takes a LittleDogScenario, got {type(scenario).__name__}"
        )
    scenario.validate()
    builder = DiagramBuilder()
    plant, scene_graph, instance, _, pose = add_littledog_world(builder, scenario)
    desired = builder.AddSystem(
        ConstantVectorSource(desired_state_vector(plant, instance, pose.q_joints))
    )
    desired.set_name("desired_state")
    builder.Connect(desired.get_output_port(), plant.get_desired_state_input_port(instance))
    if meshcat is not None:
        from pydrake.geometry import MeshcatVisualizer

        MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat)
    diagram = builder.Build()
    diagram.set_name("littledog_stand")
    return diagram


def foot_positions(plant: MultibodyPlant, plant_context: Context) -> np.ndarray:
    """World positions (4 x 3, ``LEGS`` order) of the foot centres."""
    return np.array(
        [
            plant.GetFrameByName(name).CalcPoseInWorld(plant_context).translation()
            for name in FOOT_FRAMES
        ]
    )


def check_littledog_stand(diagram: Diagram, context: Context) -> dict[str, float]:
    """Figures after a standing simulation, relative to the initial standing pose.

    Returns:
        ``height_error_m`` (body height minus its initial standing height),
        ``tilt_rad`` (angle of the body z axis from vertical), ``drift_m`` (horizontal
        body displacement), ``max_joint_error_rad`` (largest |q - q_desired|)
        and ``max_foot_slip_m`` (largest horizontal foot displacement). No figure says
        whether the state is finite: ``simulate`` raises ``SimulationDivergedError`` the
        step a state turns NaN or infinite, so it never returns such a context.
    """
    plant = diagram.GetSubsystemByName("plant")
    plant_context = plant.GetMyContextFromRoot(context)
    body = plant.GetBodyByName(BODY_NAME)
    default_context = plant.CreateDefaultContext()
    X0 = plant.EvalBodyPoseInWorld(default_context, body)
    X = plant.EvalBodyPoseInWorld(plant_context, body)
    desired = diagram.GetSubsystemByName("desired_state")
    xd = desired.get_output_port().Eval(desired.GetMyContextFromRoot(context))
    q_actuated = np.array(
        [
            plant.get_joint_actuator(i).joint().GetOnePosition(plant_context)
            for i in plant.GetJointActuatorIndices(body.model_instance())
        ]
    )
    feet0 = foot_positions(plant, default_context)
    feet = foot_positions(plant, plant_context)
    return {
        "height_error_m": float(X.translation()[2] - X0.translation()[2]),
        "tilt_rad": float(np.arccos(np.clip(X.rotation().matrix()[2, 2], -1.0, 1.0))),
        "drift_m": float(np.linalg.norm(X.translation()[:2] - X0.translation()[:2])),
        "max_joint_error_rad": float(np.max(np.abs(q_actuated - xd[: len(q_actuated)]))),
        "max_foot_slip_m": float(np.max(np.linalg.norm(feet[:, :2] - feet0[:, :2], axis=1))),
    }


__all__ = [
    "CONTACT_APPROXIMATIONS",
    "LEGS",
    "LittleDogScenario",
    "StandingPose",
    "add_littledog",
    "add_littledog_world",
    "build_littledog_stand",
    "check_littledog_stand",
    "desired_state_vector",
    "foot_positions",
    "standing_pose",
]
