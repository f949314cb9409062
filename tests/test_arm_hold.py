"""The arm_hold diagram: holding a pose, closing the hand, controller wiring, bad scenarios."""

import numpy as np
import pytest
from pydrake.math import RotationMatrix
from pydrake.multibody.inverse_kinematics import InverseKinematics
from pydrake.solvers import Solve
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import TrajectorySource
from pydrake.trajectories import PiecewisePolynomial
from repertoire.diagrams.arm import (
    ArmScenario,
    add_arm_controllers,
    add_arm_station,
    build_arm_hold,
    check_arm_hold,
)
from repertoire.diagrams.registry import get_diagram_entry
from repertoire.diagrams.scenario import dump_scenario, load_scenario
from repertoire.models import MODELS_DIR
from repertoire.models.arm7 import (
    ARM_JOINTS,
    HAND_GRASP_7CM,
    HAND_JOINTS,
    HAND_OPEN,
    TABLE_HEIGHT,
    ArmObject,
    ArmWorld,
    arm7_home_configuration,
    make_arm7_control_plant,
    side_grasp_rotation,
)

from repertoire.errors import RepertoireError, ScenarioError

YAML = MODELS_DIR.parent / "diagrams" / "scenarios" / "arm_hold.yaml"


def _simulate(scenario, duration):
    diagram = build_arm_hold(scenario)
    simulator = Simulator(diagram)
    simulator.AdvanceTo(duration)
    return diagram, simulator.get_context()


def test_arm_holds_pose_with_objects_resting_on_the_table():
    scenario = load_scenario(ArmScenario, filename=YAML)
    assert len(scenario.world.objects) == 7
    diagram, context = _simulate(scenario, 1.0)
    assert diagram.get_name() == "arm_hold"
    plant = diagram.GetSubsystemByName("plant")
    plant_context = plant.GetMyContextFromRoot(context)
    assert np.all(np.isfinite(plant.GetPositionsAndVelocities(plant_context)))
    figures = check_arm_hold(diagram, context)
    assert figures["max_joint_error_rad"] < 1e-3
    assert figures["max_finger_error_rad"] < 1e-3
    assert figures["max_object_speed_m_s"] < 1e-3
    for obj in scenario.world.objects:
        if obj.is_free():
            body = plant.GetBodyByName(obj.kind, plant.GetModelInstanceByName(obj.name))
            p = plant.EvalBodyPoseInWorld(plant_context, body).translation()
            assert p[:2] == pytest.approx(obj.xy, abs=1e-4)
            assert p[2] == pytest.approx(TABLE_HEIGHT, abs=1e-3)


def test_hand_closes_under_command_while_arm_holds():
    scenario = ArmScenario()
    scenario.finger_targets = [0.8, 0.7, 0.7]
    diagram, context = _simulate(scenario, 0.5)
    plant = diagram.GetSubsystemByName("plant")
    plant_context = plant.GetMyContextFromRoot(context)
    arm = plant.GetModelInstanceByName("arm7")
    for joint, target in zip(HAND_JOINTS, scenario.finger_targets):
        q = plant.GetJointByName(joint, arm).get_angle(plant_context)
        assert q == pytest.approx(target, abs=0.01)
    assert check_arm_hold(diagram, context)["max_joint_error_rad"] < 1e-3


def test_registered_and_round_trips_yaml():
    entry = get_diagram_entry("arm_hold")
    assert entry.scenario_type is ArmScenario
    scenario = load_scenario(ArmScenario, filename=YAML)
    again = load_scenario(ArmScenario, data=dump_scenario(scenario))
    assert again == scenario
    assert entry.build(scenario).get_name() == "arm_hold"


def test_feedforward_is_inverse_dynamics_of_the_arm():
    """With v = 0, the plant's actuation input is M(q) vd_d - tau_g(q) (closed form)."""
    scenario = ArmScenario()
    builder = DiagramBuilder()
    station = add_arm_station(builder, scenario)
    ctrl = add_arm_controllers(builder, station, reference_acceleration=True)
    builder.ExportInput(ctrl.arm_desired_state, "arm_desired_state")
    builder.ExportInput(ctrl.hand_desired_state, "hand_desired_state")
    builder.ExportInput(ctrl.arm_desired_acceleration, "arm_desired_acceleration")
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    vd = np.array([0.5, -0.2, 0.3, 1.0, -0.4, 0.2, 0.1])
    diagram.GetInputPort("arm_desired_acceleration").FixValue(context, vd)
    diagram.GetInputPort("arm_desired_state").FixValue(context, np.r_[scenario.initial_q, [0] * 7])
    diagram.GetInputPort("hand_desired_state").FixValue(
        context, np.r_[scenario.initial_fingers, [0] * 3]
    )
    plant, arm = station.plant, station.arm
    plant_context = plant.GetMyContextFromRoot(context)
    u = plant.get_actuation_input_port(arm).Eval(plant_context)
    cp = ctrl.control_plant
    cctx = cp.CreateDefaultContext()
    cp.SetPositions(cctx, np.r_[scenario.initial_q, scenario.initial_fingers])
    vd_full = np.zeros(10)
    for k, name in enumerate(ARM_JOINTS):
        vd_full[cp.GetJointByName(name).velocity_start()] = vd[k]
    expected = cp.CalcMassMatrix(cctx) @ vd_full - cp.CalcGravityGeneralizedForces(cctx)
    for name in ARM_JOINTS + HAND_JOINTS:
        actuator = plant.GetJointActuatorByName(f"{name}_motor", arm)
        k = list(plant.GetJointActuatorIndices(arm)).index(actuator.index())
        assert u[k] == pytest.approx(expected[cp.GetJointByName(name).velocity_start()], abs=1e-9)


@pytest.mark.parametrize(
    "text, match",
    [
        ("bogus_key: 1", "bogus_key"),
        ("kp: fast", "could not load ArmScenario"),
        ("world: {objects: [{name: c, kind: cup, colour: red}]}", "colour"),
        ("initial_q: [0.1, 0.2, 0.3]", "initial_q has 3 values; expected 7"),
        ("initial_q: [0, 0, 0, 2.9, 0, 0, 0]", "outside the joint limits.*elbow"),
        ("finger_targets: [0.0, 0.0, 0.0, 0.0]", "finger_targets has 4 values"),
        ("kp: [1, 1, 1, 1, 1, 1]", "kp must be 7 finite numbers"),
        ("kd: [-1, 1, 1, 1, 1, 1, 1]", "kd gains must be >= 0"),
        ("time_step: 0.0", "time_step must be in"),
        ("contact_approximation: tamsi", "contact_approximation 'tamsi' unknown"),
        ("world: {objects: [{name: c, kind: cup, xy: [5.0, 0.0]}]}", "not fully over the table"),
    ],
)
def test_bad_scenarios_are_refused(text, match):
    with pytest.raises(ScenarioError, match=match):
        load_scenario(ArmScenario, data=text)


def test_build_validates_a_hand_made_scenario():
    scenario = ArmScenario()
    scenario.world.objects.append(ArmObject(name="cup_red", kind="cup", xy=[0.3, 0.5]))
    with pytest.raises(ScenarioError, match="repeated: \\['cup_red'\\]"):
        build_arm_hold(scenario)


def _side_grasp_ik(control_plant, p_WT, q_guess):
    """Joint angles putting tcp at p_WT with approach +x_W and finger spread +z_W."""
    R_WT = side_grasp_rotation(0.0)
    ik = InverseKinematics(control_plant)
    tcp = control_plant.GetFrameByName("tcp")
    world = control_plant.world_frame()
    ik.AddPositionConstraint(tcp, [0, 0, 0], world, p_WT - 1e-4, p_WT + 1e-4)
    ik.AddOrientationConstraint(tcp, RotationMatrix(), world, R_WT, 1e-3)
    prog = ik.get_mutable_prog()
    prog.AddQuadraticErrorCost(np.eye(7), q_guess, ik.q())
    prog.SetInitialGuess(ik.q(), q_guess)
    result = Solve(prog)
    assert result.is_success()
    return result.GetSolution(ik.q())


def test_hand_grasps_and_lifts_a_cup():
    """Side grasp of a free cup: approach, close the hand, lift 12 cm; the cup comes along."""

    xy = [0.55, -0.10]
    z_grasp = TABLE_HEIGHT + 0.055
    control = make_arm7_control_plant(finger_positions=HAND_OPEN)
    q_pre = _side_grasp_ik(
        control, np.array([xy[0] - 0.10, xy[1], z_grasp + 0.02]), arm7_home_configuration()
    )
    q_grasp = _side_grasp_ik(control, np.array([xy[0], xy[1], z_grasp]), q_pre)
    q_lift = _side_grasp_ik(control, np.array([xy[0], xy[1], z_grasp + 0.12]), q_grasp)
    scenario = ArmScenario()
    scenario.initial_q = q_pre.tolist()
    scenario.world = ArmWorld(objects=[ArmObject(name="cup_red", kind="cup", xy=xy)])
    builder = DiagramBuilder()
    station = add_arm_station(builder, scenario)
    ctrl = add_arm_controllers(builder, station)
    times = [0.0, 1.0, 1.3, 1.9, 2.9]
    arm_q = np.column_stack([q_pre, q_grasp, q_grasp, q_grasp, q_lift])
    hand_q = np.column_stack([HAND_OPEN] * 3 + [HAND_GRASP_7CM] * 2)
    arm_src = builder.AddSystem(
        TrajectorySource(
            PiecewisePolynomial.CubicShapePreserving(times, arm_q, True), output_derivative_order=1
        )
    )
    hand_src = builder.AddSystem(
        TrajectorySource(
            PiecewisePolynomial.FirstOrderHold(times, hand_q), output_derivative_order=1
        )
    )
    builder.Connect(arm_src.get_output_port(), ctrl.arm_desired_state)
    builder.Connect(hand_src.get_output_port(), ctrl.hand_desired_state)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.AdvanceTo(3.2)
    plant = station.plant
    plant_context = plant.GetMyContextFromRoot(simulator.get_context())
    X_WC = plant.EvalBodyPoseInWorld(plant_context, plant.GetBodyByName("cup"))
    assert X_WC.translation()[2] == pytest.approx(TABLE_HEIGHT + 0.12, abs=0.01)
    assert X_WC.translation()[:2] == pytest.approx(xy, abs=0.005)
    assert X_WC.rotation().matrix()[2, 2] > np.cos(np.radians(3))  # still upright


def test_initial_pose_in_collision_is_refused():
    scenario = ArmScenario()
    scenario.initial_q = [0.9, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]  # straight arm into the table
    with pytest.raises(ScenarioError, match="forearm penetrates table::table"):
        build_arm_hold(scenario)
    scenario = ArmScenario()
    ball = next(o for o in scenario.world.objects if o.kind == "obstacle")
    ball.xy, ball.z_above_table = [0.52, -0.06], 0.12  # the ball where the hand is
    with pytest.raises(ScenarioError, match="initial configuration in collision.*obstacle_blue"):
        build_arm_hold(scenario)


def test_controllers_need_pd_gains_on_the_plant():
    from pydrake.multibody.plant import AddMultibodyPlant, MultibodyPlantConfig
    from repertoire.diagrams.arm import ArmStation
    from repertoire.models.arm7 import add_arm7

    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlant(MultibodyPlantConfig(time_step=1e-3), builder)
    arm = add_arm7(plant)
    plant.Finalize()
    with pytest.raises(RepertoireError, match="have no PD gains"):
        add_arm_controllers(builder, ArmStation(plant, scene_graph, arm, {}))
