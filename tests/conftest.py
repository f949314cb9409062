"""Shared test fixtures: a small pendulum world and an isolated diagram registry."""

import dataclasses
import os
import signal
import subprocess
import sys

import numpy as np
import pytest
from pydrake.geometry import Box, MeshcatVisualizer
from pydrake.math import RigidTransform
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.multibody.tree import RevoluteJoint, SpatialInertia
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource


@dataclasses.dataclass
class PendulumScenario:
    """Test-only scenario: a box on a pin joint, released from ``angle``."""

    angle: float = 0.5
    torque: float = 0.0


def build_pendulum(scenario: PendulumScenario, *, meshcat=None):
    """A MultibodyPlant pendulum (1 kg box, 0.5 m arm) with SceneGraph; named "test_pendulum"."""
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=0.002)
    plant.set_name("plant")
    # Body frame B on the pin; the box centre (and centre of mass) 0.5 m below it.
    M_BBcm = SpatialInertia.SolidBoxWithMass(1.0, 0.1, 0.1, 0.1)
    bob = plant.AddRigidBody("bob", M_BBcm.Shift([0.0, 0.0, 0.5]))
    X_BG = RigidTransform([0.0, 0.0, -0.5])
    plant.RegisterVisualGeometry(
        bob, X_BG, Box(0.1, 0.1, 0.1), "bob_visual", np.array([0.8, 0.1, 0.1, 1.0])
    )
    pin = plant.AddJoint(RevoluteJoint("pin", plant.world_frame(), bob.body_frame(), [0, 1, 0]))
    plant.AddJointActuator("pin_motor", pin)
    plant.Finalize()
    pin.set_default_angle(scenario.angle)
    torque = builder.AddNamedSystem("torque_source", ConstantVectorSource([scenario.torque]))
    builder.Connect(torque.get_output_port(), plant.get_actuation_input_port())
    if meshcat is not None:
        MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat)
    diagram = builder.Build()
    diagram.set_name("test_pendulum")
    return diagram


def pendulum_check(diagram, context) -> dict[str, float]:
    """Figures after a run: the pin angle and the total energy."""
    plant = diagram.GetSubsystemByName("plant")
    plant_context = plant.GetMyContextFromRoot(context)
    angle = plant.GetJointByName("pin").get_angle(plant_context)
    energy = plant.CalcKineticEnergy(plant_context) + plant.CalcPotentialEnergy(plant_context)
    return {"angle_rad": angle, "energy_J": energy}


@pytest.fixture
def isolated_registry(monkeypatch):
    """An empty diagram registry holding only "test_pendulum" (restored after the test)."""
    from repertoire.diagrams import registry

    monkeypatch.setattr(registry, "_REGISTRY", {})
    monkeypatch.setattr(registry, "_LOADED", True)
    registry.register_diagram(
        "test_pendulum",
        scenario_type=PendulumScenario,
        description="test-only pendulum",
        duration=0.2,
        check=pendulum_check,
    )(build_pendulum)
    return registry


@pytest.fixture(scope="session")
def grasp_demo():
    """A 1 s task-space grasp demonstration (3 via points, a 90 degree turn, 3 fingers)."""
    from repertoire.planning.dmp_demos import synthesize_demonstration

    return synthesize_demonstration(
        np.array([[0.3, 0.3, 0.4], [0.5, 0.1, 0.25], [0.6, 0.0, 0.1]]),
        (0.0, 1.0),
        np.array([0, 1, 0, 0]),
        np.array([0, 0.7071067811865476, 0.7071067811865476, 0]),
        (0.0, 1.0),
        [(0.0, 0.6, [0.0] * 3, [0.8] * 3), (0.6, 1.0, [0.8] * 3, [0.2] * 3)],
        1.0,
        n_samples=300,
    )


def group_alive(pgid: int) -> bool:
    """Whether any process of process group ``pgid`` is still alive."""
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    return True


def start_pool_study(seeds: int, out, cwd, env=None):
    """``repertoire study pendulum -n seeds -j 2`` started as a terminal would start it.

    In its own process group (Ctrl-C in a terminal signals the whole group) and with
    SIGINT's default action, also when the tests run where SIGINT is ignored (nohup, a
    background job); ``cwd`` should not be a source tree, so the package comes from where
    the tests' does. Pipes for stdout and stderr (text).
    """
    argv = [sys.executable, "-m", "repertoire", "study", "pendulum", "-n", str(seeds), "-j", "2"]
    return subprocess.Popen(
        [*argv, "--out-dir", str(out), "--no-progress"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        cwd=cwd,
        start_new_session=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
