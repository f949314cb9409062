"""LittleDog model, leg kinematics and the littledog_stand diagram."""

import math
import re

import numpy as np
import pytest
from pydrake.geometry import Box, Sphere
from pydrake.math import RigidTransform
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.systems.framework import DiagramBuilder
from repertoire.diagrams.littledog import (
    LittleDogScenario,
    add_littledog_world,
    build_littledog_stand,
    check_littledog_stand,
    desired_state_vector,
    foot_positions,
    standing_pose,
)
from repertoire.diagrams.registry import diagram_names, get_diagram_entry
from repertoire.diagrams.scenario import dump_scenario, load_scenario
from repertoire.diagrams.simulate import SimulationDivergedError, simulate
from repertoire.models import MODELS_DIR, ConfigureParser, package_url
from repertoire.models.littledog import (
    FOOT_FRAMES,
    JOINT_NAMES,
    LEGS,
    STANDING_HEIGHT,
    URDF_PATH,
    leg_fk,
    leg_geometry,
    leg_ik,
    standing_configuration,
)
from repertoire.models.littledog.kinematics import leg_ik_feasible
from repertoire.models.littledog.make_urdf import urdf_text
from repertoire.models.terrain import TerrainParams, generate_board

from repertoire.errors import RepertoireError, ScenarioError

L1, L2, R_FOOT = 0.0751, 0.102, 0.0103
SCENARIO_YAML = MODELS_DIR.parent / "diagrams" / "scenarios" / "littledog_stand.yaml"


@pytest.fixture(scope="module")
def plant_and_instance():
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, 0.001)
    parser = Parser(plant)
    ConfigureParser(parser)
    (instance,) = parser.AddModels(url=package_url(URDF_PATH))
    plant.Finalize()
    return plant, instance, scene_graph


def _set_leg(plant, context, leg, q):
    for name, value in zip(("hip_roll", "hip_pitch", "knee"), q):
        plant.GetJointByName(f"{leg}_{name}").set_angle(context, float(value))


def test_committed_urdf_is_the_generated_one():
    assert (MODELS_DIR / URDF_PATH).read_text() == urdf_text()


def test_model_parses_with_public_facts(plant_and_instance):
    plant, instance, _ = plant_and_instance
    context = plant.CreateDefaultContext()
    assert plant.num_positions() == 7 + 12
    assert plant.num_velocities() == 6 + 12
    assert plant.num_actuators() == 12
    assert plant.CalcTotalMass(context) == pytest.approx(2.75, abs=1e-9)
    assert plant.GetBodyByName("body").default_mass() == pytest.approx(1.8)
    assert plant.GetBodyByName("body").is_floating_base_body()
    limits = {
        "f": {"hip_roll": (-0.6, 0.6), "hip_pitch": (-3.5, 2.4), "knee": (-3.1, 1.0)},
        "h": {"hip_roll": (-0.6, 0.6), "hip_pitch": (-2.4, 3.5), "knee": (-1.0, 3.1)},
    }
    for leg in LEGS:
        for joint_type, (lo, hi) in limits[leg[1]].items():
            joint = plant.GetJointByName(f"{leg}_{joint_type}", instance)
            assert joint.position_lower_limits()[0] == pytest.approx(lo)
            assert joint.position_upper_limits()[0] == pytest.approx(hi)
    for index in plant.GetJointActuatorIndices(instance):
        actuator = plant.get_joint_actuator(index)
        assert actuator.has_controller()
        assert actuator.get_controller_gains().p > 0
        assert actuator.effort_limit() > 0
        assert actuator.joint().name() in JOINT_NAMES
    # Hip roll joints at (+-0.101, +-0.036, 0) in the body frame.
    body = plant.GetFrameByName("body")
    for leg in LEGS:
        joint = plant.GetJointByName(f"{leg}_hip_roll")
        p = joint.frame_on_child().CalcPose(context, body).translation()
        sx = 1 if leg[1] == "f" else -1
        sy = 1 if leg[0] == "l" else -1
        np.testing.assert_allclose(p, [sx * 0.101, sy * 0.036, 0.0], atol=1e-12)


def test_foot_collision_spheres(plant_and_instance):
    plant, _, scene_graph = plant_and_instance
    inspector = scene_graph.model_inspector()
    for leg in LEGS:
        (geometry_id,) = plant.GetCollisionGeometriesForBody(
            plant.GetBodyByName(f"{leg}_lower_leg")
        )
        shape = inspector.GetShape(geometry_id)
        assert isinstance(shape, Sphere)
        assert shape.radius() == pytest.approx(R_FOOT)
        p_LG = inspector.GetPoseInFrame(geometry_id).translation()
        np.testing.assert_allclose(p_LG, [0, 0, -L2], atol=1e-15)
    (body_id,) = plant.GetCollisionGeometriesForBody(plant.GetBodyByName("body"))
    assert isinstance(inspector.GetShape(body_id), Box)


def test_zero_configuration_closed_form():
    for leg in LEGS:
        g = leg_geometry(leg)
        p = leg_fk(leg, [0.0, 0.0, 0.0])
        np.testing.assert_allclose(
            p, [g.p_BH[0], g.p_BH[1] + g.pitch_offset_y, -(L1 + L2)], atol=1e-15
        )
    # Front knee bent by -pi/2: the lower leg points forward.
    p = leg_fk("lf", [0.0, 0.0, -math.pi / 2])
    np.testing.assert_allclose(p, [0.101 + L2, 0.060, -L1], atol=1e-15)
    # Roll by +pi/2 swings the straight leg to +y.
    p = leg_fk("rh", [math.pi / 2, 0.0, 0.0])
    np.testing.assert_allclose(p, [-0.101, -0.036 + (L1 + L2), -0.024], atol=1e-15)


def test_fk_matches_plant_frames(plant_and_instance):
    plant, _, _ = plant_and_instance
    context = plant.CreateDefaultContext()
    body = plant.GetFrameByName("body")
    rng = np.random.default_rng(7)
    for leg in LEGS:
        g = leg_geometry(leg)
        for _ in range(25):
            q = rng.uniform(g.lower, g.upper)
            _set_leg(plant, context, leg, q)
            p_plant = plant.GetFrameByName(f"{leg}_foot").CalcPose(context, body).translation()
            np.testing.assert_allclose(leg_fk(leg, q), p_plant, atol=1e-12)


def test_fk_is_vectorised():
    q = np.random.default_rng(1).uniform(-0.5, 0.5, size=(4, 5, 3))
    p = leg_fk("rf", q)
    assert p.shape == (4, 5, 3)
    np.testing.assert_allclose(p[2, 3], leg_fk("rf", q[2, 3]), atol=0)


def test_ik_inverts_fk_on_its_branch():
    rng = np.random.default_rng(3)
    for leg in LEGS:
        g = leg_geometry(leg)
        knee_range = (-2.8, -0.05) if g.knee_sign < 0 else (0.05, 2.8)
        q = np.column_stack(
            [
                rng.uniform(-0.6, 0.6, 400),
                rng.uniform(-1.2, 1.2, 400),
                rng.uniform(*knee_range, 400),
            ]
        )
        # Keep the configurations with the foot below the hip pitch axis (IK's branch).
        vz = -L1 * np.cos(q[:, 1]) - L2 * np.cos(q[:, 1] + q[:, 2])
        q = q[vz < -0.01]
        p = leg_fk(leg, q)
        q_ik = leg_ik(leg, p)
        np.testing.assert_allclose(q_ik, q, atol=1e-9)
        np.testing.assert_allclose(leg_fk(leg, q_ik), p, atol=1e-12)


def test_ik_inverts_fk_everywhere_within_the_joint_limits():
    # Joint angles drawn uniformly within the limits (knee branch given by the sample's
    # knee): IK(FK(q)) lands on FK(q) within the limits for every sample. Before, the IK
    # took the foot below the hip pitch axis always, and refused 46-47 % of them (a folded
    # leg, pitch beyond +-pi/2), naming a hip roll of 1-3 rad outside [-0.6, 0.6].
    rng = np.random.default_rng(11)
    for leg in LEGS:
        g = leg_geometry(leg)
        q = rng.uniform(g.lower, g.upper, size=(5000, 3))
        sign = np.where(q[:, 2] >= 0.0, 1.0, -1.0)
        vz = -L1 * np.cos(q[:, 1]) - L2 * np.cos(q[:, 1] + q[:, 2])
        assert 0.3 < np.mean(vz > 0.0) < 0.6  # half of them fold the foot above the hip
        p = leg_fk(leg, q)
        q_ik = leg_ik(leg, p, knee_sign=sign)
        np.testing.assert_allclose(leg_fk(leg, q_ik), p, atol=1e-12)
        assert np.all(q_ik >= np.asarray(g.lower) - 1e-9)
        assert np.all(q_ik <= np.asarray(g.upper) + 1e-9)
        assert np.all(leg_ik_feasible(leg, p, knee_sign=sign))
        # the foot below the pitch axis: the IK's usual branch, the same angles
        below = vz < -0.01
        np.testing.assert_allclose(q_ik[below], q[below], atol=1e-9)
    # One folded leg: the only solution within the limits is the angles themselves.
    q = np.array([0.219, -3.182, -2.197])
    np.testing.assert_allclose(leg_ik("lf", leg_fk("lf", q)), q, atol=1e-9)
    # Refusals stay: beyond the leg's length, and within it but beyond the limits.
    with pytest.raises(RepertoireError, match=r"leg lf: foot target out of reach .* missed by"):
        leg_ik("lf", leg_fk("lf", q) + [0.0, 0.0, -0.3])
    with pytest.raises(RepertoireError, match=r"leg lf: IK solution hip_roll=.* outside the joint"):
        leg_ik("lf", [0.101, 0.16, -0.05])


def test_standing_configuration_gives_standing_height(plant_and_instance):
    q = standing_configuration()
    assert q.shape == (12,)
    for i, leg in enumerate(LEGS):
        g = leg_geometry(leg)
        p = leg_fk(leg, q[3 * i : 3 * i + 3])
        np.testing.assert_allclose(
            p, [g.p_BH[0], g.p_BH[1] + g.pitch_offset_y, R_FOOT - STANDING_HEIGHT], atol=1e-12
        )
        assert np.all(q[3 * i : 3 * i + 3] >= np.asarray(g.lower))
        assert np.all(q[3 * i : 3 * i + 3] <= np.asarray(g.upper))
    # Closed-form knee angle of the planar 2-link leg with the foot under the hip.
    d = STANDING_HEIGHT - R_FOOT
    knee = math.acos((d * d - L1 * L1 - L2 * L2) / (2 * L1 * L2))
    np.testing.assert_allclose(q[2::3], [-knee, -knee, knee, knee], atol=1e-12)
    # In the plant: body at 0.146 m, feet spheres touch z = 0.
    plant, instance, _ = plant_and_instance
    context = plant.CreateDefaultContext()
    plant.SetFreeBodyPose(context, plant.GetBodyByName("body"), RigidTransform([0, 0, 0.146]))
    for name, value in zip(JOINT_NAMES, q):
        plant.GetJointByName(name).set_angle(context, value)
    feet = foot_positions(plant, context)
    np.testing.assert_allclose(feet[:, 2], R_FOOT, atol=1e-12)


def test_ik_bad_input():
    with pytest.raises(RepertoireError, match="out of reach"):
        leg_ik("lf", [0.101, 0.06, -0.5])
    with pytest.raises(RepertoireError, match="out of reach"):
        leg_ik("lf", [0.101, 0.036, 0.0])
    with pytest.raises(RepertoireError, match="outside the joint limits"):
        leg_ik("lf", [0.101, 0.06 + 0.12, -0.06])  # needs a roll beyond 0.6 rad
    with pytest.raises(RepertoireError, match="unknown LittleDog leg"):
        leg_fk("xx", [0, 0, 0])
    with pytest.raises(RepertoireError, match="shape"):
        leg_fk("lf", [0, 0])
    with pytest.raises(RepertoireError, match="NaN"):
        leg_ik("lf", [np.nan, 0, -0.1])
    with pytest.raises(RepertoireError, match="foot_heights"):
        standing_configuration(0.146, [0.0, 0.0])


def test_missing_model_file_is_a_clear_error():
    with pytest.raises(RepertoireError, match="not found"):
        package_url("littledog/no_such_dog.urdf")


def test_desired_state_follows_actuator_order(plant_and_instance):
    plant, instance, _ = plant_and_instance
    q = np.arange(12) * 0.01
    xd = desired_state_vector(plant, instance, q)
    assert xd.shape == (24,)
    for k, index in enumerate(plant.GetJointActuatorIndices(instance)):
        name = plant.get_joint_actuator(index).joint().name()
        assert xd[k] == q[JOINT_NAMES.index(name)]
    np.testing.assert_array_equal(xd[12:], 0.0)


def test_scenario_yaml_and_registry():
    assert "littledog_stand" in diagram_names()
    entry = get_diagram_entry("littledog_stand")
    assert entry.scenario_type is LittleDogScenario
    scenario = load_scenario(LittleDogScenario, filename=SCENARIO_YAML)
    assert scenario.terrain.kind == "mixed"
    assert scenario.time_step == 1e-3


@pytest.mark.parametrize(
    "text, match",
    [
        ("board_seed: 1\nwings: 2\n", "wings"),
        ("terrain: {kind: lava}\n", "unknown terrain board kind 'lava'"),
        ("terrain: {size_x: -0.6}\n", "size_x must be a positive length"),
        ("contact_approximation: tamsi\n", "TAMSI"),
        ("kp: [1.0, 2.0]\n", "kp must be 3 finite values"),
        ("standing_height: 0.30\n", "standing_height"),
        ("time_step: [oops\n", "could not load"),
    ],
)
def test_bad_scenarios(text, match):
    with pytest.raises(ScenarioError, match=match):
        load_scenario(LittleDogScenario, data=text)


def test_builder_refuses_a_foreign_scenario():
    with pytest.raises(ScenarioError, match="LittleDogScenario"):
        build_littledog_stand(TerrainParams())


def test_standing_pose_on_uneven_ground_touches_the_terrain():
    scenario = LittleDogScenario(terrain=TerrainParams(kind="rocks"), board_seed=4)
    board = generate_board(scenario.terrain, scenario.board_seed)
    pose = standing_pose(scenario, board)
    builder = DiagramBuilder()
    plant, _, _, _, _ = add_littledog_world(builder, scenario)
    context = plant.CreateDefaultContext()
    feet = foot_positions(plant, context)
    np.testing.assert_allclose(feet, pose.p_WF, atol=1e-12)
    np.testing.assert_allclose(
        feet[:, 2] - R_FOOT, board.height(feet[:, 0], feet[:, 1]), atol=1e-12
    )
    assert pose.X_WB.translation()[2] == pytest.approx(np.mean(pose.ground_heights) + 0.146)


@pytest.mark.parametrize("approximation", ["lagged", "sap"])
def test_stands_one_second_on_a_flat_board(approximation):
    scenario = LittleDogScenario(contact_approximation=approximation)
    diagram = build_littledog_stand(scenario)
    assert diagram.get_name() == "littledog_stand"
    _, context = simulate(diagram, 1.0)
    figures = check_littledog_stand(diagram, context)
    assert sorted(figures) == [
        "drift_m", "height_error_m", "max_foot_slip_m", "max_joint_error_rad", "tilt_rad"
    ]  # fmt: skip
    assert abs(figures["height_error_m"]) < 0.01
    plant = diagram.GetSubsystemByName("plant")
    plant_context = plant.GetMyContextFromRoot(context)
    z = plant.GetFreeBodyPose(plant_context, plant.GetBodyByName("body")).translation()[2]
    board_top = scenario.terrain.base_thickness
    assert abs(z - board_top - STANDING_HEIGHT) < 0.01
    assert figures["tilt_rad"] < 0.01
    assert figures["max_foot_slip_m"] < 0.002
    state = plant.GetPositionsAndVelocities(plant_context)
    assert np.all(np.isfinite(state))
    for name in FOOT_FRAMES:
        assert plant.HasFrameNamed(name)


def test_stands_on_the_yaml_mixed_board():
    scenario = load_scenario(LittleDogScenario, filename=SCENARIO_YAML)
    diagram = build_littledog_stand(scenario)
    _, context = simulate(diagram, 1.0)
    figures = check_littledog_stand(diagram, context)
    assert abs(figures["height_error_m"]) < 0.01
    assert figures["tilt_rad"] < 0.02


@pytest.mark.parametrize("kind", ["rocks", "steps", "gaps"])
def test_stands_on_rough_boards(kind):
    for seed in range(2):
        scenario = LittleDogScenario(terrain=TerrainParams(kind=kind), board_seed=seed)
        diagram = build_littledog_stand(scenario)
        _, context = simulate(diagram, 0.5)
        figures = check_littledog_stand(diagram, context)
        assert abs(figures["height_error_m"]) < 0.01, (kind, seed, figures)
        assert figures["tilt_rad"] < 0.05, (kind, seed, figures)


def test_scenario_gains_reach_the_actuators():
    scenario = LittleDogScenario(kp=[5.0, 6.0, 7.0], kd=[0.1, 0.2, 0.3])
    diagram = build_littledog_stand(scenario)
    plant = diagram.GetSubsystemByName("plant")
    for name in JOINT_NAMES:
        actuator = plant.GetJointActuatorByName(f"{name}_motor")
        k = ["hip_roll", "hip_pitch", "knee"].index(name[3:])
        gains = actuator.get_controller_gains()
        assert (gains.p, gains.d) == (scenario.kp[k], scenario.kd[k])


def test_scenario_round_trips_through_yaml():
    scenario = LittleDogScenario(terrain=TerrainParams(kind="steps", step_count=3), board_seed=7)
    text = dump_scenario(scenario)
    assert load_scenario(LittleDogScenario, data=text) == scenario


def test_leg_ik_on_either_knee_branch():
    from repertoire.models.littledog.kinematics import leg_ik_feasible

    for leg, q in (("lf", [0.1, -0.3, 0.3]), ("rh", [-0.1, 0.3, -0.3])):
        p = leg_fk(leg, q)
        assert np.allclose(leg_ik(leg, p, knee_sign=np.sign(q[2])), q)
        assert np.allclose(leg_fk(leg, leg_ik(leg, p)), p)  # the leg's own branch
        assert leg_ik(leg, p)[2] * q[2] < 0.0
        assert leg_ik_feasible(leg, p, knee_sign=np.sign(q[2]))
    with pytest.raises(RepertoireError, match="knee_sign must be"):
        leg_ik("lf", leg_fk("lf", [0.0, 0.0, -0.5]), knee_sign=0.0)


def test_a_non_finite_stand_raises_instead_of_reporting_a_figure():
    # littledog_stand's old "finite" figure could only be 1: simulate never returns a
    # non-finite state, it stops the run and names the system
    diagram = build_littledog_stand(LittleDogScenario())
    context = diagram.CreateDefaultContext()
    plant = diagram.GetSubsystemByName("plant")
    state = plant.GetMyMutableContextFromRoot(context).get_mutable_discrete_state_vector()
    state.SetAtIndex(plant.num_positions(), np.nan)  # the body's first velocity
    message = "the state of ::littledog_stand::plant became non-finite (NaN/inf) at t = 0 s"
    with pytest.raises(SimulationDivergedError, match=re.escape(message)):
        simulate(diagram, 0.2, context=context)
    assert "finite" not in get_diagram_entry("littledog_stand").criteria
