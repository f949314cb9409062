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


def test_kitchen_cups_stand_on_four_feet():
    from pydrake.geometry import Cylinder, Role, Sphere
    from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
    from pydrake.systems.framework import DiagramBuilder
    from repertoire.diagrams.kitchen import add_kitchen_world
    from repertoire.models.diffdrive.generate import (
        CUP_FOOT_RADIUS,
        CUP_HALF_HEIGHT,
        CUP_RADIUS,
        KITCHEN_CUPS,
        cup_feet,
    )

    # closed form: four spheres of 4 mm, centres 3.6 cm from the axis at 90 deg, their
    # lowest points on the cup's bottom plane; the cylinder ends at their centres
    np.testing.assert_allclose(
        cup_feet(),
        [[0.036, 0, -0.046], [0, 0.036, -0.046], [-0.036, 0, -0.046], [0, -0.036, -0.046]],
        atol=1e-15,
    )
    plant, scene_graph = AddMultibodyPlantSceneGraph(DiagramBuilder(), 0.0)
    parser = Parser(plant)
    ConfigureParser(parser)
    add_kitchen_world(parser, list(KITCHEN_CUPS))
    plant.Finalize()
    inspector = scene_graph.model_inspector()
    for name in KITCHEN_CUPS:
        body = plant.GetBodyByName("cup", plant.GetModelInstanceByName(name))
        ids = inspector.GetGeometries(plant.GetBodyFrameIdOrThrow(body.index()), Role.kProximity)
        shapes = {inspector.GetName(g).split("::")[-1]: g for g in ids}
        assert sorted(shapes) == ["cup_collision", "foot_0", "foot_1", "foot_2", "foot_3"]
        side = shapes.pop("cup_collision")
        cyl = inspector.GetShape(side)
        assert isinstance(cyl, Cylinder) and cyl.radius() == CUP_RADIUS
        z = inspector.GetPoseInFrame(side).translation()[2] - cyl.length() / 2
        assert z == pytest.approx(CUP_FOOT_RADIUS - CUP_HALF_HEIGHT, abs=1e-15)  # cylinder bottom
        for k, g in enumerate(sorted(shapes)):
            sphere = inspector.GetShape(shapes[g])
            assert isinstance(sphere, Sphere) and sphere.radius() == CUP_FOOT_RADIUS
            p = inspector.GetPoseInFrame(shapes[g]).translation()
            np.testing.assert_allclose(p, cup_feet()[k], atol=1e-15)
            assert p[2] - sphere.radius() == pytest.approx(-CUP_HALF_HEIGHT, abs=1e-15)


def test_fingers_touch_with_two_sphere_pads_on_their_inner_faces():
    from pydrake.geometry import Box, Role, Sphere
    from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
    from pydrake.systems.framework import DiagramBuilder
    from repertoire.models.diffdrive.generate import (
        FINGER_PAD_RADIUS,
        FINGER_PAD_RECESS,
        FINGER_SIZE,
        finger_pads,
    )

    # closed form: 5 mm spheres 2.5 cm above and below the finger's centre, their tips on
    # the inner face of the 3 x 2 x 8 cm finger (y = -+1 cm: left, right); the collision
    # box ends 2 mm behind them, so only the pads touch a cup between the fingers
    np.testing.assert_allclose(finger_pads(-1.0), [[0, -0.005, 0.025], [0, -0.005, -0.025]])
    np.testing.assert_allclose(finger_pads(1.0), [[0, 0.005, 0.025], [0, 0.005, -0.025]])
    plant, scene_graph = AddMultibodyPlantSceneGraph(DiagramBuilder(), 0.0)
    parser = Parser(plant)
    ConfigureParser(parser)
    parser.AddModels(url=package_url("diffdrive/diffdrive_arm.urdf"))
    plant.Finalize()
    inspector = scene_graph.model_inspector()
    for side, inward in (("left", -1.0), ("right", 1.0)):
        frame = plant.GetBodyFrameIdOrThrow(plant.GetBodyByName(f"{side}_finger").index())
        shapes = {inspector.GetName(g).split("::")[-1]: g
                  for g in inspector.GetGeometries(frame, Role.kProximity)}  # fmt: skip
        assert sorted(shapes) == [f"{side}_finger_collision", f"{side}_finger_pad_0",
                                  f"{side}_finger_pad_1"]  # fmt: skip
        box = shapes[f"{side}_finger_collision"]
        size = [inspector.GetShape(box).width(), inspector.GetShape(box).depth(),
                inspector.GetShape(box).height()]  # fmt: skip
        assert isinstance(inspector.GetShape(box), Box)
        np.testing.assert_allclose(size, [0.03, 0.018, 0.08], atol=1e-15)
        inner = inspector.GetPoseInFrame(box).translation()[1] + inward * size[1] / 2
        assert inner == pytest.approx(inward * (FINGER_SIZE[1] / 2 - FINGER_PAD_RECESS))
        for k in range(2):
            pad = shapes[f"{side}_finger_pad_{k}"]
            assert isinstance(inspector.GetShape(pad), Sphere)
            assert inspector.GetShape(pad).radius() == FINGER_PAD_RADIUS
            p = inspector.GetPoseInFrame(pad).translation()
            np.testing.assert_allclose(p, finger_pads(inward)[k], atol=1e-15)
            assert p[1] + inward * FINGER_PAD_RADIUS == pytest.approx(inward * 0.01)  # the face
            # soft pads: the grip's 4 N a pad compresses one 1 mm; the box keeps the default
            props = inspector.GetProximityProperties(pad)
            assert props.GetProperty("material", "point_contact_stiffness") == 4000.0
        props = inspector.GetProximityProperties(box)
        assert not props.HasProperty("material", "point_contact_stiffness")
