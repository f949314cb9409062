"""arm7 model files, kinematics, helper functions and world layout."""

import math

import numpy as np
import pytest
import repertoire.models.arm7 as arm7
from pydrake.math import RigidTransform
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import RevoluteJoint
from repertoire.models import MODELS_DIR, ConfigureParser
from repertoire.models.arm7 import (
    ALL_JOINTS,
    ARM_JOINTS,
    HAND_JOINTS,
    ArmObject,
    ArmWorld,
    add_arm7,
    add_arm_world,
    arm7_effort_limits,
    arm7_home_configuration,
    arm7_joint_limits,
    arm7_velocity_limits,
    check_arm_configuration,
    default_arm_world,
    make_arm7_control_plant,
    side_grasp_rotation,
)
from repertoire.models.arm7.generate import (
    box_inertia,
    combine,
    cylinder_inertia,
    generated_files,
)

from repertoire.errors import RepertoireError, ScenarioError


def _arm_plant(q=None, fingers=(0.0, 0.0, 0.0)):
    plant = MultibodyPlant(0.0)
    arm = add_arm7(plant)
    plant.Finalize()
    context = plant.CreateDefaultContext()
    if q is not None:
        plant.SetPositions(context, arm, np.concatenate([q, fingers]))
    return plant, arm, context


def _X_WF(plant, context, frame):
    return plant.CalcRelativeTransform(context, plant.world_frame(), plant.GetFrameByName(frame))


def test_generated_files_match_generator():
    for name, text in generated_files().items():
        assert (MODELS_DIR / "arm7" / name).read_text() == text, (
            f"models/arm7/{name} is stale: run .venv/bin/python models/arm7/generate.py"
        )


def test_inertia_formulas_closed_form():
    assert cylinder_inertia(2.0, 0.1, 0.3) == pytest.approx(
        (2.0 * (3 * 0.01 + 0.09) / 12, 2.0 * (3 * 0.01 + 0.09) / 12, 0.01)
    )
    assert cylinder_inertia(1.0, 0.1, 0.2, "x")[0] == pytest.approx(0.005)
    assert box_inertia(12.0, (1.0, 2.0, 3.0)) == pytest.approx((13.0, 10.0, 5.0))
    # Two point-like unit masses 1 m apart: COM midway, 0.5 kg m^2 about the transverse axes.
    two = combine([(1.0, (0, 0, 0), (0, 0, 0)), (1.0, (0, 0, 1.0), (0, 0, 0))])
    assert two.com == pytest.approx((0, 0, 0.5))
    assert (two.ixx, two.iyy, two.izz) == pytest.approx((0.5, 0.5, 0.0))


def test_every_model_parses_with_joints_limits_and_mass():
    plant = MultibodyPlant(1e-3)
    parser = Parser(plant)
    ConfigureParser(parser)
    arm = add_arm7(plant, parser)
    for kind in ("table", "cup", "bottle", "coaster", "obstacle"):
        parser.AddModels(url=f"package://repertoire/arm7/{kind}.sdf")
    plant.Finalize()
    assert plant.num_actuators() == 10
    names = [plant.get_joint(j).name() for j in plant.GetJointIndices(arm)]
    assert set(ALL_JOINTS) <= set(names)
    lower, upper = arm7_joint_limits(ALL_JOINTS)
    for k, name in enumerate(ALL_JOINTS):
        joint = plant.GetJointByName(name, arm)
        assert isinstance(joint, RevoluteJoint)
        assert joint.position_lower_limits()[0] == pytest.approx(lower[k])
        assert joint.position_upper_limits()[0] == pytest.approx(upper[k])
        actuator = plant.GetJointActuatorByName(f"{name}_motor", arm)
        assert actuator.effort_limit() == pytest.approx(arm7_effort_limits((name,))[0])
    moving = [b for b in plant.GetBodyIndices(arm) if plant.get_body(b).name() != "base"]
    mass = sum(plant.get_body(b).default_mass() for b in moving)
    assert 10.0 <= mass <= 15.0
    for kind, expected in (("cup", 0.15), ("bottle", 0.5)):
        assert plant.GetBodyByName(kind).default_mass() == pytest.approx(expected)
    assert arm7_velocity_limits().shape == (7,)


def test_forward_kinematics_closed_form():
    plant, _, context = _arm_plant(np.zeros(7))
    X = _X_WF(plant, context, "tcp")
    # Hanging straight down: tcp = shoulder - (0.30 + 0.30 + 0.08 + 0.085); x_palm=x, z_palm=-z.
    assert X.translation() == pytest.approx([0, 0, 1.10 - 0.765], abs=1e-12)
    assert X.rotation().matrix() == pytest.approx(np.diag([1.0, -1.0, -1.0]), abs=1e-9)
    # Elbow at 90 deg: forearm and hand point forward (+x), approach axis +x, x_palm up.
    q = np.zeros(7)
    q[3] = math.pi / 2
    plant.SetPositions(context, plant.GetModelInstanceByName("arm7"), np.r_[q, 0, 0, 0])
    X = _X_WF(plant, context, "tcp")
    assert X.translation() == pytest.approx([0.465, 0, 0.80], abs=1e-9)
    R = X.rotation().matrix()
    assert R[:, 2] == pytest.approx([1, 0, 0], abs=1e-9)
    assert R[:, 0] == pytest.approx([0, 0, 1], abs=1e-9)
    # Shoulder flexion by 90 deg: the straight arm points forward at shoulder height.
    q = np.zeros(7)
    q[0] = math.pi / 2
    plant.SetPositions(context, plant.GetModelInstanceByName("arm7"), np.r_[q, 0, 0, 0])
    assert _X_WF(plant, context, "tcp").translation() == pytest.approx([0.765, 0, 1.1], abs=1e-9)


def test_home_configuration_hand_above_table_facing_forward():
    q = arm7_home_configuration()
    check_arm_configuration(q)
    plant, _, context = _arm_plant(q)
    X = _X_WF(plant, context, "tcp")
    assert X.translation()[2] > arm7.TABLE_HEIGHT + 0.15
    assert 0.45 < X.translation()[0] < 0.7
    assert X.rotation().matrix()[:, 2] @ [1, 0, 0] > 0.99  # approach axis forward
    assert X.rotation().matrix()[:, 0] @ [0, 0, 1] > 0.98  # finger spread axis up


def test_finger_contact_angle_grips_7cm_cylinder():
    theta = arm7.FINGER_CONTACT_ANGLE_7CM
    plant, arm, context = _arm_plant(np.zeros(7), fingers=(theta, theta, theta))
    X_WT = _X_WF(plant, context, "tcp")
    for link in ("thumb_link", "finger_1_link", "finger_2_link"):
        X_WL = plant.EvalBodyPoseInWorld(context, plant.GetBodyByName(link, arm))
        p_TTip = X_WT.inverse() @ (X_WL @ np.array([0, 0, 0.085]))
        # Fingertip-sphere centre: cylinder radius + tip radius off the tcp's x-z plane,
        # at the tcp's height along the approach axis (to within 5 mm).
        assert abs(p_TTip[1]) == pytest.approx(0.035 + 0.011, abs=1e-9)
        assert p_TTip[2] == pytest.approx(0.085 * math.cos(theta) + 0.005 - 0.085, abs=1e-9)
        assert abs(p_TTip[2]) < 0.005
    assert 0.05 < theta < 0.2


def test_control_plant_gravity_matches_full_arm():
    fingers = np.array([0.4, 0.2, -0.1])
    q = arm7_home_configuration()
    full, arm, context = _arm_plant(q, fingers)
    tau_full = full.CalcGravityGeneralizedForces(context)
    welded = make_arm7_control_plant(finger_positions=fingers)
    assert welded.num_positions() == 7
    wctx = welded.CreateDefaultContext()
    welded.SetPositions(wctx, q)
    tau_welded = welded.CalcGravityGeneralizedForces(wctx)
    for k, name in enumerate(ARM_JOINTS):
        v = full.GetJointByName(name, arm).velocity_start()
        assert tau_welded[welded.GetJointByName(name).velocity_start()] == pytest.approx(
            tau_full[v], abs=1e-9
        )
        assert k < 7
    assert make_arm7_control_plant().num_positions() == 10
    # Tool frames agree between the full arm and the welded control plant.
    X_full = _X_WF(full, context, "tcp")
    X_welded = _X_WF(welded, wctx, "tcp")
    assert X_full.IsNearlyEqualTo(X_welded, 1e-12)


def test_joint_helpers_reject_bad_input():
    with pytest.raises(RepertoireError, match="unknown arm7 joint"):
        arm7_joint_limits(("knee",))
    with pytest.raises(RepertoireError, match="has 6 values; expected 7"):
        check_arm_configuration(np.zeros(6))
    with pytest.raises(RepertoireError, match="NaN"):
        check_arm_configuration([0, 0, 0, np.nan, 0, 0, 0])
    with pytest.raises(RepertoireError, match="outside the joint limits.*elbow"):
        check_arm_configuration([0, 0, 0, 3.0, 0, 0, 0])
    with pytest.raises(RepertoireError, match="finger_positions has 2 values"):
        make_arm7_control_plant(finger_positions=[0.0, 0.0])
    assert check_arm_configuration(np.zeros(3), size=3).shape == (3,)
    assert len(HAND_JOINTS) == 3


def test_missing_model_files_give_clear_errors(monkeypatch):
    monkeypatch.setattr(arm7, "MODEL_RELATIVE_PATH", "arm7/missing_arm.urdf")
    with pytest.raises(RepertoireError, match="model file 'arm7/missing_arm.urdf' not found"):
        add_arm7(MultibodyPlant(0.0))
    monkeypatch.setattr(arm7, "_OBJECT_FILES", {**arm7._OBJECT_FILES, "cup": "arm7/gone.sdf"})
    world = ArmWorld(objects=[ArmObject(name="c", kind="cup", xy=[0.5, 0.0])])
    with pytest.raises(RepertoireError, match="model file 'arm7/gone.sdf' not found"):
        add_arm_world(MultibodyPlant(0.0), world)


def test_world_places_objects_on_the_table():
    plant = MultibodyPlant(1e-3)
    add_arm7(plant, X_WBase=RigidTransform([0.0, 0.0, 0.0]))
    world = default_arm_world()
    instances = add_arm_world(plant, world)
    plant.Finalize()
    context = plant.CreateDefaultContext()
    assert set(instances) == {"table"} | {o.name for o in world.objects}
    for obj in world.objects:
        body = plant.GetBodyByName(obj.kind, instances[obj.name])
        p = plant.EvalBodyPoseInWorld(context, body).translation()
        assert p[:2] == pytest.approx(obj.xy)
        bottom = p[2] - (arm7.OBSTACLE_RADIUS if obj.kind == "obstacle" else 0.0)
        assert bottom == pytest.approx(arm7.TABLE_HEIGHT)
        assert body.is_floating_base_body() == (obj.kind in ("cup", "bottle"))
    top = plant.GetFrameByName("top_center", instances["table"])
    assert top.CalcPoseInWorld(context).translation()[2] == pytest.approx(0.75)


@pytest.mark.parametrize(
    "objects, match",
    [
        ([ArmObject(name="a", kind="mug")], "unknown kind 'mug'"),
        ([ArmObject(name="a", mount="glued")], "unknown mount 'glued'"),
        ([ArmObject(name="a", xy=[2.0, 0.0])], "not fully over the table"),
        ([ArmObject(name="a", xy=[0.5, 0.0, 0.1])], "xy must be 2 finite numbers"),
        ([ArmObject(name="a"), ArmObject(name="a", xy=[0.6, 0.3])], "repeated: \\['a'\\]"),
        ([ArmObject(name="a"), ArmObject(name="b", xy=[0.52, 0.0])], "overlap"),
        ([ArmObject(name="a", z_above_table=0.1)], "free object must rest on the table"),
        ([ArmObject(name="arm7")], "name must be non-empty"),
    ],
)
def test_world_validation_errors(objects, match):
    with pytest.raises(ScenarioError, match=match):
        ArmWorld(objects=objects).validate()


def test_welded_cup_in_the_air_is_allowed():
    world = ArmWorld(objects=[ArmObject(name="a", z_above_table=0.1, mount="welded")])
    world.validate()
    plant = MultibodyPlant(0.0)
    instances = arm7.add_arm_world(plant, world)
    plant.Finalize()
    cup = plant.GetBodyByName("cup", instances["a"])
    X_WC = cup.EvalPoseInWorld(plant.CreateDefaultContext())
    assert X_WC.translation() == pytest.approx([0.5, 0.0, arm7.TABLE_HEIGHT + 0.1], abs=1e-15)
    assert plant.num_positions() == 0  # welded: no free-body coordinates


def test_side_grasp_rotation_closed_form():
    R = side_grasp_rotation(0.0).matrix()
    assert R == pytest.approx(np.column_stack([[0, 0, 1], [0, -1, 0], [1, 0, 0]]))
    R = side_grasp_rotation(math.pi / 2).matrix()
    assert R[:, 2] == pytest.approx([0, 1, 0], abs=1e-12)  # approach towards +y
    assert R[:, 0] == pytest.approx([0, 0, 1], abs=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    # The elbow-at-90-degrees pose (forearm forward) is exactly the yaw-0 side grasp.
    q = np.zeros(7)
    q[3] = math.pi / 2
    plant, _, context = _arm_plant(q)
    R_tcp = _X_WF(plant, context, "tcp").rotation().matrix()
    assert R_tcp == pytest.approx(side_grasp_rotation(0.0).matrix(), abs=1e-9)
