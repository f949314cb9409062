"""Biped model, closed-form leg IK against the plant's FK, standing diagram, bad input."""

from pathlib import Path

import numpy as np
import pytest
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.analysis import Simulator
from repertoire.diagrams.biped import BipedStandScenario, build_biped_stand, check_biped_stand
from repertoire.diagrams.registry import get_diagram_entry
from repertoire.diagrams.scenario import load_scenario
from repertoire.models.biped import (
    JOINT_LIMITS,
    JOINT_NAMES,
    LEG_JOINTS,
    SIDES,
    add_biped,
    leg_fk,
    leg_ik,
    rotation_rpy,
    standing_joint_angles,
)

from repertoire.errors import RepertoireError, ScenarioError

SCENARIOS = Path(__file__).resolve().parents[1] / "diagrams" / "scenarios"


@pytest.fixture(scope="module")
def plant():
    plant = MultibodyPlant(1e-3)
    add_biped(plant, Parser(plant))
    plant.Finalize()
    return plant


def test_model_facts(plant):
    context = plant.CreateDefaultContext()
    assert plant.num_actuators() == 12
    assert plant.num_positions() == 7 + 12
    assert plant.CalcTotalMass(context) == pytest.approx(50.0)
    assert [
        plant.get_joint_actuator(i).joint().name() for i in plant.GetJointActuatorIndices()
    ] == (list(JOINT_NAMES))
    for name in JOINT_NAMES:
        joint = plant.GetJointByName(name)
        lo, hi = JOINT_LIMITS[name.split("_", 1)[1]]
        assert joint.position_lower_limits()[0] == lo and joint.position_upper_limits()[0] == hi
        assert plant.GetJointActuatorByName(name + "_motor").get_controller_gains().p > 0
    # Height with straight legs: sole to the top of the head.
    X_WS = plant.GetFrameByName("left_sole").CalcPoseInWorld(context)
    X_WH = plant.GetBodyByName("head").EvalPoseInWorld(context)
    height = X_WH.translation()[2] + 0.10 - X_WS.translation()[2]
    assert height == pytest.approx(1.25, abs=1e-12)  # straight legs: the link lengths sum to 1.25 m


def test_leg_ik_matches_plant_fk(plant):
    context = plant.CreateDefaultContext()
    rng = np.random.default_rng(7)
    pelvis = plant.GetBodyByName("pelvis").body_frame()
    for trial in range(40):
        q = {}
        for side in SIDES:
            for j in LEG_JOINTS:
                lo, hi = JOINT_LIMITS[j]
                q[f"{side}_{j}"] = rng.uniform(0.6 * lo, 0.6 * hi)
            q[f"{side}_knee"] = rng.uniform(0.1, 2.0)
        for name, value in q.items():
            plant.GetJointByName(name).set_angle(context, value)
        for side in SIDES:
            q_leg = np.array([q[f"{side}_{j}"] for j in LEG_JOINTS])
            X_PS = plant.CalcRelativeTransform(
                context, pelvis, plant.GetFrameByName(f"{side}_sole")
            )
            p, R = leg_fk(q_leg, side)
            np.testing.assert_allclose(p, X_PS.translation(), atol=1e-12)
            np.testing.assert_allclose(R, X_PS.rotation().matrix(), atol=1e-12)
            q_ik = leg_ik(X_PS.translation(), X_PS.rotation().matrix(), side, strict=False)
            np.testing.assert_allclose(q_ik, q_leg, atol=1e-9, err_msg=f"trial {trial} {side}")


def test_leg_ik_closed_forms():
    # Straight leg: zero angles; sole right below the hip at full reach.
    np.testing.assert_allclose(
        leg_ik([0, 0.075, -0.67], np.eye(3), "left"), np.zeros(6), atol=1e-12
    )
    # Symmetric squat: knee = 2 acos(d / 0.6), hip pitch = ankle pitch = -knee / 2.
    q = standing_joint_angles(0.62)
    d = 0.62 - 0.07
    knee = 2 * np.arccos(d / 0.6)
    np.testing.assert_allclose(q[:6], [0, 0, -knee / 2, knee, -knee / 2, 0], atol=1e-12)
    np.testing.assert_allclose(q[6:], q[:6], atol=1e-12)
    # A yawed foot is reached with the hip yaw alone.
    q = leg_ik([0, -0.075, -0.62], rotation_rpy(0, 0, 0.3), "right")
    assert q[0] == pytest.approx(0.3) and q[1] == pytest.approx(0.0, abs=1e-12)


def test_leg_ik_bad_input():
    with pytest.raises(RepertoireError, match="out of reach"):
        leg_ik([0.0, 0.075, -0.8], np.eye(3), "left")
    with pytest.raises(RepertoireError, match="NaN"):
        leg_ik([np.nan, 0.075, -0.6], np.eye(3), "left")
    with pytest.raises(RepertoireError, match="side"):
        leg_ik([0.0, 0.075, -0.6], np.eye(3), "middle")
    with pytest.raises(RepertoireError, match="outside its limits"):
        leg_ik([0.0, 0.075, -0.6], rotation_rpy(0, 0, 1.2), "left")
    with pytest.raises(RepertoireError, match="6 joint angles"):
        leg_fk(np.zeros(5), "left")


def test_biped_stands_one_second():
    scenario = load_scenario(BipedStandScenario, filename=SCENARIOS / "biped_stand.yaml")
    diagram = build_biped_stand(scenario)
    assert diagram.get_name() == "biped_stand"
    simulator = Simulator(diagram)
    simulator.AdvanceTo(1.0)
    context = simulator.get_context()
    assert np.all(np.isfinite(context.get_discrete_state_vector().CopyToVector()))
    figures = check_biped_stand(diagram, context)
    assert abs(figures["height_error_m"]) < 0.005
    assert figures["tilt_rad"] < 0.03
    assert figures["drift_m"] < 0.01
    assert get_diagram_entry("biped_stand").build is build_biped_stand


def test_biped_scenario_bad_input():
    with pytest.raises(ScenarioError, match="unknown_key|Expected keys"):
        load_scenario(BipedStandScenario, data="unknown_key: 1\n")
    with pytest.raises(ScenarioError, match="could not load"):
        load_scenario(BipedStandScenario, data="time_step: [0.001\n")
    with pytest.raises(ScenarioError, match="could not load"):
        load_scenario(BipedStandScenario, data="pelvis_height: high\n")
    with pytest.raises(ScenarioError, match="pelvis_height"):
        load_scenario(BipedStandScenario, data="pelvis_height: 0.70\n")
    with pytest.raises(ScenarioError, match="TAMSI"):
        load_scenario(BipedStandScenario, data="contact_approximation: tamsi\n")
    with pytest.raises(ScenarioError, match="kp must be 6"):
        build_biped_stand(BipedStandScenario(kp=[1.0, 2.0]))
    with pytest.raises(ScenarioError, match="time_step"):
        build_biped_stand(BipedStandScenario(time_step=0.0))
