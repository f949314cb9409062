import math

import numpy as np
import pytest
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from repertoire.models import MODELS_DIR, ConfigureParser, package_url
from repertoire.models.diffdrive.generate import COLUMN_X, LIFT_BASE_Z, MASS, generated_files


def test_generated_files_match_generator():
    for name, text in generated_files().items():
        assert (MODELS_DIR / "diffdrive" / name).read_text() == text, (
            f"models/diffdrive/{name} is stale: run .venv/bin/python models/diffdrive/generate.py"
        )


def _plant():
    plant = MultibodyPlant(0.0)
    parser = Parser(plant)
    ConfigureParser(parser)
    (robot,) = parser.AddModels(url=package_url("diffdrive/diffdrive_arm.urdf"))
    plant.Finalize()
    return plant, robot


def test_arm_robot_structure_and_gripper_kinematics():
    plant, robot = _plant()
    names = [plant.get_joint_actuator(a).name() for a in plant.GetJointActuatorIndices(robot)]
    assert names == [
        "left_wheel_motor",
        "right_wheel_motor",
        "arm_lift_motor",
        "arm_yaw_motor",
        "arm_extend_motor",
        "left_finger_motor",
        "right_finger_motor",
    ]
    # base 7.4 + 2 x 0.8 kg, arm as in generate.MASS (two fingers)
    arm_mass = sum(MASS.values()) + MASS["finger"]
    ctx = plant.CreateDefaultContext()
    assert plant.CalcTotalMass(ctx) == pytest.approx(7.4 + 1.6 + arm_mass)
    # gripper centre = slide origin: (COLUMN_X + e cos yaw, e sin yaw, LIFT_BASE_Z + lift)
    lift, yaw, extend = 0.5, 0.4, 0.6
    plant.GetJointByName("arm_lift").set_translation(ctx, lift)
    plant.GetJointByName("arm_yaw").set_angle(ctx, yaw)
    plant.GetJointByName("arm_extend").set_translation(ctx, extend)
    X = plant.CalcRelativeTransform(
        ctx, plant.GetFrameByName("chassis"), plant.GetFrameByName("arm_slide")
    )
    expected = [COLUMN_X + extend * math.cos(yaw), extend * math.sin(yaw), LIFT_BASE_Z + lift]
    np.testing.assert_allclose(X.translation(), expected, atol=1e-12)


def test_plain_diffdrive_is_unchanged_for_soccer():
    text = (MODELS_DIR / "diffdrive" / "diffdrive.urdf").read_text()
    assert "arm_lift" not in text and 'robot name="diffdrive"' in text
