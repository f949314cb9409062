"""The biped standing under joint PD on flat ground (registered as ``biped_stand``).

The plant's actuators carry PD gains, so a constant ``desired_state`` (the
standing joint angles and zero velocities) makes the plant hold the pose;
no controller system is needed. :func:`add_biped_world` is shared with the
walking diagram.
"""

import dataclasses
from typing import Any

import numpy as np
from pydrake.geometry import Box, HalfSpace, SceneGraph
from pydrake.math import RigidTransform
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import (
    AddMultibodyPlant,
    CoulombFriction,
    MultibodyPlant,
    MultibodyPlantConfig,
)
from pydrake.multibody.tree import ModelInstanceIndex
from pydrake.systems.framework import Context, Diagram, DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource
from repertoire.diagrams.registry import register_diagram
from repertoire.diagrams.simulate import validate_control_period
from repertoire.models.biped import (
    JOINT_LIMITS,
    JOINT_NAMES,
    LEG_JOINTS,
    SIDES,
    LegGains,
    add_biped,
    leg_fk,
    standing_joint_angles,
)

from repertoire.criteria import Bound
from repertoire.errors import ScenarioError

CONTACT_APPROXIMATIONS = ("lagged", "sap", "similar")


@dataclasses.dataclass
class BipedStandScenario:
    """The biped standing on flat ground.

    Attributes:
        time_step: discrete plant time step [s].
        contact_approximation: ``lagged`` (default), ``sap`` or ``similar``; TAMSI
            is refused because it ignores the actuators' PD gains.
        pelvis_height: standing height of the pelvis origin (hip points) above the
            ground [m]; below the straight-leg height 0.67 m so the knees bend.
        stance_width: lateral distance between the sole centres [m].
        kp: joint PD proportional gains per leg joint [N m/rad] (6 values).
        kd: joint PD derivative gains per leg joint [N m s/rad] (6 values).
        ground_friction: Coulomb friction of the ground (feet have 1.0).
    """

    time_step: float = 1e-3
    contact_approximation: str = "lagged"
    pelvis_height: float = 0.62
    stance_width: float = 0.15
    kp: list[float] = dataclasses.field(default_factory=lambda: list(LegGains().kp))
    kd: list[float] = dataclasses.field(default_factory=lambda: list(LegGains().kd))
    ground_friction: float = 1.0

    def validate(self) -> None:
        """Raises ScenarioError naming the first bad field."""
        validate_plant_fields(self.time_step, self.contact_approximation, self.ground_friction)
        if not 0.45 <= self.pelvis_height <= 0.665:
            raise ScenarioError(
                "pelvis_height must be in [0.45, 0.665] m (legs reach 0.67 m), "
                f"got {self.pelvis_height}"
            )
        if not 0.10 <= self.stance_width <= 0.40:
            raise ScenarioError(f"stance_width must be in [0.10, 0.40] m, got {self.stance_width}")
        for field in ("kp", "kd"):
            values = getattr(self, field)
            if len(values) != 6 or not all(np.isfinite(v) and v >= 0 for v in values):
                raise ScenarioError(
                    f"{field} must be 6 finite values >= 0 (one per leg joint {LEG_JOINTS}), "
                    f"got {values}"
                )


def validate_plant_fields(time_step: float, contact_approximation: str, friction: float) -> None:
    """Checks the plant settings shared by the biped scenarios.

    Raises:
        ScenarioError: naming the bad value and what is expected.
    """
    if not (np.isfinite(time_step) and 0.0 < time_step <= 0.01):
        raise ScenarioError(f"time_step must be in (0, 0.01] s (a discrete plant), got {time_step}")
    if contact_approximation not in CONTACT_APPROXIMATIONS:
        raise ScenarioError(
            f"contact_approximation must be one of {CONTACT_APPROXIMATIONS} (TAMSI ignores the "
            f"actuators' PD gains), got {contact_approximation!r}"
        )
    if not (np.isfinite(friction) and friction > 0):
        raise ScenarioError(f"ground_friction must be > 0, got {friction}")


def validate_discrete_control_fields(scenario: Any) -> None:
    """Checks a controlled world's plant fields and its control period.

    Args:
        scenario: has ``time_step``, ``contact_approximation``, ``ground_friction`` and
            ``control_period`` (the period of the world's discrete controller).

    Raises:
        ScenarioError: naming the bad value and what is expected.
    """
    validate_plant_fields(
        scenario.time_step, scenario.contact_approximation, scenario.ground_friction
    )
    validate_control_period(scenario.control_period, scenario.time_step)


def add_ground(plant: MultibodyPlant, friction: float = 1.0, size: float = 12.0) -> None:
    """Registers a flat ground half-space (z = 0) with collision and a grey visual.

    Args:
        plant: an unfinalized plant.
        friction: Coulomb friction of the ground.
        size: side of the square visual floor [m] (collision is the infinite half-space).
    """
    X = RigidTransform()
    plant.RegisterCollisionGeometry(
        plant.world_body(), X, HalfSpace(), "ground_collision", CoulombFriction(friction, friction)
    )
    # Meshcat does not draw half-spaces: the visual is a large thin box whose top is z = 0.
    plant.RegisterVisualGeometry(
        plant.world_body(),
        RigidTransform([0.0, 0.0, -0.005]),
        Box(size, size, 0.01),
        "ground_visual",
        np.array([0.55, 0.57, 0.6, 1.0]),
    )


def add_plant_with_ground(
    builder: DiagramBuilder, time_step: float, contact_approximation: str, ground_friction: float
) -> tuple[MultibodyPlant, SceneGraph]:
    """Adds a discrete point-contact plant and scene graph with the ground (:func:`add_ground`).

    Args:
        builder: the diagram builder.
        time_step: discrete plant time step [s].
        contact_approximation: discrete contact approximation.
        ground_friction: Coulomb friction of the ground.

    Returns:
        ``(plant, scene_graph)``, the plant not finalized.
    """
    config = MultibodyPlantConfig(
        time_step=time_step,
        discrete_contact_approximation=contact_approximation,
        contact_model="point",
    )
    plant, scene_graph = AddMultibodyPlant(config, builder)
    add_ground(plant, ground_friction)
    return plant, scene_graph


def add_biped_world(
    builder: DiagramBuilder,
    *,
    time_step: float,
    contact_approximation: str,
    gains: LegGains,
    ground_friction: float = 1.0,
    q_joints: np.ndarray,
    pelvis_height: float,
    X_WP: RigidTransform | None = None,
    extra=None,
) -> tuple[MultibodyPlant, SceneGraph, ModelInstanceIndex]:
    """Adds plant + scene graph with ground and the biped at a default standing pose.

    Args:
        builder: the diagram builder.
        time_step: discrete plant time step [s].
        contact_approximation: ``lagged``, ``sap`` or ``similar``.
        gains: joint PD gains set on the actuators.
        ground_friction: Coulomb friction of the ground.
        q_joints: (12,) default joint angles in ``JOINT_NAMES`` order.
        pelvis_height: default pelvis height above the ground [m].
        X_WP: optional default pelvis pose (overrides ``pelvis_height``).
        extra: optional ``extra(plant)`` called before ``Finalize`` (adds more geometry).

    Returns:
        ``(plant, scene_graph, biped_instance)`` with the plant finalized.
    """
    plant, scene_graph = add_plant_with_ground(
        builder, time_step, contact_approximation, ground_friction
    )
    instance = add_biped(plant, Parser(plant), gains=gains)
    if extra is not None:
        extra(plant)
    plant.Finalize()
    for name, q in zip(JOINT_NAMES, q_joints):
        plant.GetJointByName(name, instance).set_default_angle(float(q))
    if X_WP is None:
        X_WP = RigidTransform([0.0, 0.0, pelvis_height])
    plant.SetDefaultFloatingBaseBodyPose(plant.GetBodyByName("pelvis", instance), X_WP)
    return plant, scene_graph, instance


def _add_meshcat(builder: DiagramBuilder, scene_graph: SceneGraph, meshcat) -> None:
    if meshcat is not None:
        from pydrake.geometry import MeshcatVisualizer

        MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat)


@register_diagram(
    "biped_stand",
    scenario_type=BipedStandScenario,
    description="ASIMO-like biped (12 leg joints, floating base) standing under joint PD",
    duration=1.0,
    check=lambda diagram, context: check_biped_stand(diagram, context),
    criteria={"height_error_m": Bound(-0.02, 0.02), "tilt_rad": Bound(hi=0.05)},
)
def build_biped_stand(scenario: BipedStandScenario, *, meshcat=None) -> Diagram:
    """Builds the standing biped.

    Args:
        scenario: a validated :class:`BipedStandScenario`.
        meshcat: optional Meshcat instance for a visualizer.

    Returns:
        The Diagram ``biped_stand`` with subsystems ``plant``, ``scene_graph`` and
        ``desired_state`` (the constant standing state fed to the plant's PD).
    """
    scenario.validate()
    builder = DiagramBuilder()
    q_stand = standing_joint_angles(scenario.pelvis_height, scenario.stance_width)
    plant, scene_graph, instance = add_biped_world(
        builder,
        time_step=scenario.time_step,
        contact_approximation=scenario.contact_approximation,
        gains=LegGains(kp=list(scenario.kp), kd=list(scenario.kd)),
        ground_friction=scenario.ground_friction,
        q_joints=q_stand,
        pelvis_height=scenario.pelvis_height,
    )
    desired = builder.AddSystem(ConstantVectorSource(np.concatenate([q_stand, np.zeros(12)])))
    desired.set_name("desired_state")
    builder.Connect(desired.get_output_port(), plant.get_desired_state_input_port(instance))
    _add_meshcat(builder, scene_graph, meshcat)
    diagram = builder.Build()
    diagram.set_name("biped_stand")
    return diagram


def pelvis_pose(diagram: Diagram, context: Context) -> RigidTransform:
    """World pose of the biped's pelvis in a diagram that has a subsystem ``plant``."""
    plant = diagram.GetSubsystemByName("plant")
    plant_context = plant.GetMyContextFromRoot(context)
    return plant.EvalBodyPoseInWorld(plant_context, plant.GetBodyByName("pelvis"))


def check_biped_stand(diagram: Diagram, context: Context) -> dict[str, float]:
    """Figures after a standing simulation.

    Returns:
        ``height_error_m`` (pelvis height minus the commanded standing height, the
        latter from the desired joint angles' forward kinematics), ``tilt_rad`` (angle
        of the pelvis z axis from vertical), ``drift_m`` (horizontal pelvis
        displacement from the origin), ``max_joint_error_rad``.
    """
    plant = diagram.GetSubsystemByName("plant")
    desired = diagram.GetSubsystemByName("desired_state")
    q_des = desired.get_output_port().Eval(desired.GetMyContextFromRoot(context))[:12]
    p_left, _ = leg_fk(q_des[:6], "left")
    target_height = -p_left[2]
    X = pelvis_pose(diagram, context)
    plant_context = plant.GetMyContextFromRoot(context)
    q_joints = np.array([plant.GetJointByName(n).get_angle(plant_context) for n in JOINT_NAMES])
    tilt = float(np.arccos(np.clip(X.rotation().matrix()[2, 2], -1.0, 1.0)))
    return {
        "height_error_m": float(X.translation()[2] - target_height),
        "tilt_rad": tilt,
        "drift_m": float(np.linalg.norm(X.translation()[:2])),
        "max_joint_error_rad": float(np.max(np.abs(q_joints - q_des))),
    }


__all__ = [
    "BipedStandScenario",
    "JOINT_LIMITS",
    "SIDES",
    "add_biped_world",
    "add_ground",
    "build_biped_stand",
    "check_biped_stand",
    "pelvis_pose",
]
