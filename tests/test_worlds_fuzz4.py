"""Worlds (fuzz round 4): bad scenario values named, not a Drake assertion or a silent run."""

import re

import numpy as np
import pytest
from repertoire.diagrams.arm_reach import ReachScenario
from repertoire.diagrams.biped_walk import BipedWalkScenario
from repertoire.diagrams.diffdrive import DiffDriveScenario, build_diffdrive_drive
from repertoire.diagrams.kitchen import KitchenScenario, build_kitchen_action
from repertoire.diagrams.simulate import simulate_registered, validate_control_period
from repertoire.diagrams.soccer import GoToPoseScenario, build_soccer_goto_pose
from repertoire.diagrams.soccer_dribble import DribbleScenario, build_soccer_dribble
from repertoire.diagrams.soccer_plan import SoccerPlanScenario, build_soccer_plan

from repertoire.cli import main
from repertoire.errors import RepertoireError, ScenarioError


@pytest.mark.parametrize(
    "build, scenario, shown",
    [
        (build_soccer_goto_pose, GoToPoseScenario(wheel_kd=-2.0), "-2.0"),
        (build_soccer_dribble, DribbleScenario(wheel_kd=float("nan")), "nan"),
        (build_soccer_plan, SoccerPlanScenario(wheel_kd=0.0), "0.0"),
    ],
)
def test_soccer_worlds_name_a_bad_wheel_kd(build, scenario, shown):
    # was RuntimeError "condition 'gains.d >= 0.0' failed" from Drake (or a robot that never moves)
    with pytest.raises(ScenarioError, match=re.escape(f"wheel_kd must be > 0, got {shown}")):
        build(scenario)


@pytest.mark.parametrize(
    "build, scenario, message",
    [
        (
            build_soccer_goto_pose,
            GoToPoseScenario(initial_pose=[3.0, 0.75, 0.0]),
            "initial_pose [3.0, 0.75, 0.0] puts diffdrive::chassis 0.242 m into goal_blue::frame",
        ),
        (
            build_soccer_plan,
            SoccerPlanScenario(initial_pose=[1.0, 0.5, 0.0]),
            "initial_pose [1.0, 0.5, 0.0] puts diffdrive::chassis 0.148 m into ball::ball",
        ),
        (
            build_diffdrive_drive,
            DiffDriveScenario(initial_pose=[3.0, -0.75, 0.0]),
            "initial_pose [3.0, -0.75, 0.0] puts diffdrive::chassis 0.242 m into goal_blue::frame",
        ),
        (
            build_soccer_dribble,
            DribbleScenario(initial_pose=[2.7, 0.75, 0.0]),
            "ball_offset [0.31, 0.0] puts ball::ball 0.150 m into goal_blue::frame",
        ),
        (
            build_kitchen_action,
            KitchenScenario(initial_pose=[-2.0, 2.6, 0.0]),
            "initial_pose [-2.0, 2.6, 0.0] with initial_arm [0.62, 0.0, 0.25] puts "
            "diffdrive_arm::chassis 0.243 m into counter::counter",
        ),
        (
            build_kitchen_action,
            KitchenScenario(cup_positions={"cup_0": [2.0, 1.4, -1.0]}),
            "cup_positions[cup_0] [2.0, 1.4, -1.0] puts cup_0::cup 1.046 m into "
            "WorldModelInstance::ground_collision",
        ),
        (
            build_kitchen_action,
            KitchenScenario(cup_positions={"cup_0": [2.0, 1.4, 0.74]}),
            "cup_positions[cup_0] [2.0, 1.4, 0.74] puts cup_0::cup 0.340 m into table_0::table",
        ),
    ],
)
def test_a_start_inside_another_body_is_refused(build, scenario, message):
    # was accepted: the robot started inside a goal post, the counter or the ball, a cup
    # inside the floor or a table top, and contact threw them apart at t = 0
    with pytest.raises(ScenarioError, match=re.escape(message)):
        build(scenario)


def test_a_clear_start_and_a_held_cup_are_accepted():
    assert build_soccer_goto_pose(GoToPoseScenario(initial_pose=[2.6, 0.0, 0.0])).get_name()
    # the fingers press a held cup by 0.1 mm: within the tolerance
    held = KitchenScenario(action="put", cup_in_gripper=True)
    assert build_kitchen_action(held).get_name() == "kitchen_action"


@pytest.mark.parametrize(
    "fields, message",
    [
        ({"start": [1.0, 1.0, 1.0]}, "start [1.0, 1.0, 1.0] would be ignored"),
        ({"actions": ["stop"]}, "actions ['stop'] would be ignored"),
        ({"first_stance": "right", "map_seed": 3}, "first_stance right would be ignored"),
        (
            {"start": [0.5, 0.0, 0.0], "map_seed": -1, "plan_file": __file__},
            f"start [0.5, 0.0, 0.0] would be ignored: the steps come from plan_file '{__file__}'",
        ),
        ({"map_seed": -2}, "map_seed must be >= 0 (a floor) or -1 (actions), got -2"),
    ],
)
def test_biped_walk_refuses_fields_its_step_source_ignores(fields, message):
    # the default map_seed 0 plans on a random floor: start, actions and first_stance
    # were silently ignored (a map_seed of -2 silently meant -1)
    with pytest.raises(ScenarioError, match=re.escape(message)):
        BipedWalkScenario(**fields).validate()
    BipedWalkScenario(map_seed=-1, start=[1.0, 1.0, 1.0], actions=["stop"]).validate()


def _update(system, fixed: dict[str, list[float]]):
    context = system.CreateDefaultContext()
    for port, value in fixed.items():
        system.GetInputPort(port).FixValue(context, value)
    return system.EvalUniquePeriodicDiscreteUpdate(context).get_vector(0).get_value()


def test_go_to_pose_and_reach_fail_on_a_non_finite_state():
    from repertoire.systems.action_status import ActionStatus
    from repertoire.systems.arm_reach import Reach
    from repertoire.systems.go_to_pose import GoToPose

    # closed form first: one 10 ms step from rest towards a goal 1 m ahead is a_max * period
    goto = GoToPose(period=0.01)
    assert _update(goto, {"state": [0, 0, 0, 0], "target": [1, 0, 0, 0]}).tolist() == [
        0.01,
        0.0,
        ActionStatus.RUNNING,
        0.0,  # mode: approach
        0.0,  # the timeout's start
    ]
    # a NaN measured state commanded NaN while reporting RUNNING; now FAILED, no motion
    out = _update(goto, {"state": [float("nan"), 0, 0, 0], "target": [1, 0, 0, 0]})
    assert out.tolist() == [0.0, 0.0, ActionStatus.FAILED, 0.0, 0.0]
    reach = Reach(period=0.01, initial_state=[0.45, 0.0, 1.45, 0.0])
    out = _update(reach, {"state": [float("inf"), 0, 1.45, 0], "target": [1.2, 0, 0.6, 0]})
    assert out.tolist() == [0.45, 1.45, 0.0, 0.0, ActionStatus.FAILED]


def test_rmrc_ik_names_a_non_finite_desired_input():
    from pydrake.math import RigidTransform
    from repertoire.models.arm7 import make_arm7_control_plant
    from repertoire.systems.task_space import ResolvedMotionRateIK

    plant = make_arm7_control_plant(finger_positions=[0.0, 0.0, 0.0])
    ee = plant.GetFrameByName("hand")
    ik = ResolvedMotionRateIK(plant, ee, list(range(7)))
    context = ik.CreateDefaultContext()
    X: RigidTransform = ee.CalcPoseInWorld(plant.CreateDefaultContext())
    fixed = {
        "position_desired": X.translation(),
        "velocity_desired": [0.0, float("nan"), 0.0],
        "orientation_desired": X.rotation().ToQuaternion().wxyz(),
        "angular_velocity_desired": np.zeros(3),
        "arm_state_measured": np.zeros(14),
    }
    for port, value in fixed.items():
        ik.GetInputPort(port).FixValue(context, value)
    # was a NaN joint reference with status OK
    with pytest.raises(
        RepertoireError, match=r"velocity_desired must be finite, got \[ 0. nan  0.\]"
    ):
        ik.EvalUniquePeriodicDiscreteUpdate(context)


def test_walking_refuses_non_finite_rules_and_an_overflowing_com_plan():
    from repertoire.diagrams.biped_walk import _scenario_plan
    from repertoire.systems.walking import (
        SteppingRule,
        plan_com,
        realize_plan,
        standing_com_height,
    )

    # base_duration inf was a traceback (PiecewisePolynomial: times must be increasing)
    with pytest.raises(RepertoireError, match="base_duration must be a finite number, got inf"):
        SteppingRule(base_duration=float("inf")).validate()
    with pytest.raises(ScenarioError, match="max_speed_change must be a finite number, got inf"):
        BipedWalkScenario(max_speed_change=float("inf")).validate()
    # 100 s steps: ZmpPlanner's CoM was NaN everywhere, reported as "leg_ik target contains NaN"
    scenario = BipedWalkScenario(map_seed=-1, base_duration=100.0)
    seq = realize_plan(_scenario_plan(scenario)[0], scenario.rule())
    with pytest.raises(RepertoireError, match=r"CoM plan is not finite for a 702.6 s footstep"):
        plan_com(seq, standing_com_height(0.6))
    scenario = BipedWalkScenario(map_seed=-1, base_duration=2.0)
    seq = realize_plan(_scenario_plan(scenario)[0], scenario.rule())
    assert plan_com(seq, standing_com_height(0.6)).get_nominal_com(seq.end_time).shape == (2,)


def test_kitchen_actions_fail_on_a_non_finite_measurement():
    from repertoire.systems.action_status import ActionStatus
    from repertoire.systems.kitchen_actions import (
        ARM_SPEEDS,
        Grip,
        Put,
        Reach,
        arm_inverse,
        joint_step,
    )

    nan, base = float("nan"), [0.0, 0.0, 0.0, 0.0]
    reach = {"arm_position": [0.62, 0.0, 0.25], "target": [0.85, 0.0, 0.7036], "base_state": base,
             "finger_position": [0.075, 0.075]}  # fmt: skip
    # closed form: one 20 ms joint_step from the measured joints towards arm_inverse(target)
    expected = joint_step(reach["arm_position"], arm_inverse(reach["target"]), ARM_SPEEDS, 0.02)
    np.testing.assert_allclose(_update(Reach(), reach)[:4], [*expected, ActionStatus.RUNNING])
    # a NaN measurement was copied into the command (NaN setpoints) while RUNNING
    assert _update(Reach(), {**reach, "arm_position": [nan, 0.0, 0.25]})[3] == ActionStatus.FAILED
    assert _update(Reach(), {**reach, "finger_position": [nan, 0.075]})[3] == ActionStatus.FAILED
    assert _update(Grip(), {"finger_position": [0.075, nan], "base_state": base})[2] == (
        ActionStatus.FAILED
    )
    put = {**reach, "finger_position": [0.05, 0.05], "base_state": [0.0, nan, 0.0, 0.0]}
    assert _update(Put(), put)[5] == ActionStatus.FAILED


def test_wheel_speed_errors_print_plain_numbers():
    # the message read "got [np.float64(12.0001), np.float64(12.0)]"
    with pytest.raises(ScenarioError, match=re.escape("rad/s, got [12.0001, 12.0]")):
        DiffDriveScenario(wheel_speeds=[12.0001, 12.0]).validate()


def test_simulate_starts_from_the_scenarios_start_velocities():
    """Velocities are no Diagram default: the registered ``initialize`` sets them."""
    from repertoire.diagrams.arm_reach import ReachScenario, joint_state
    from repertoire.diagrams.registry import get_diagram_entry
    from repertoire.diagrams.simulate import build_registered, start_context
    from repertoire.diagrams.soccer import robot_state

    for name, scenario in (
        ("soccer_goto_pose", GoToPoseScenario(initial_speed=0.5)),
        ("soccer_plan", SoccerPlanScenario(initial_speed=-0.25)),
    ):
        diagram = build_registered(name, scenario=scenario)
        context = start_context(get_diagram_entry(name), diagram, scenario)
        assert robot_state(diagram, context)[3] == pytest.approx(scenario.initial_speed)
    scenario = ReachScenario(start=[0.45, 0.3, 1.45, -0.2])
    diagram = build_registered("arm_reach", scenario=scenario)
    context = start_context(get_diagram_entry("arm_reach"), diagram, scenario)
    assert joint_state(diagram, context)[[1, 3]] == pytest.approx([0.3, -0.2])


@pytest.mark.parametrize(
    "scenario_type",
    [ReachScenario, KitchenScenario, GoToPoseScenario, DribbleScenario, SoccerPlanScenario],
)
def test_every_world_refuses_a_control_period_no_run_reaches(scenario_type):
    # was accepted: a 1e6 s period never updates the controller after t = 0 in any run
    # (simulate runs at most MAX_DURATION_S = 3600 s per call)
    step = scenario_type().time_step
    message = (
        f"control_period must be in [time_step, 3600] s = [{step:g}, 3600] s (a longer "
        "period never updates the controller after t = 0 within a run of at most 3600 s), "
        "got 1e+06"
    )
    with pytest.raises(ScenarioError, match=re.escape(message)):
        scenario_type(control_period=1e6).validate()
    with pytest.raises(ScenarioError, match=re.escape(f"got {step / 2:g}")):
        scenario_type(control_period=step / 2).validate()
    with pytest.raises(ScenarioError, match=re.escape("got nan")):
        scenario_type(control_period=float("nan")).validate()
    scenario_type(control_period=3600.0).validate()  # the bound itself is allowed
    scenario_type(control_period=step).validate()


def test_validate_control_period_bounds():
    validate_control_period(0.5, 0.01, 0.5)
    validate_control_period(0.01, 0.01, 0.5)
    with pytest.raises(ScenarioError, match=re.escape("= [0.01, 0.5] s") + ".*got 0.6"):
        validate_control_period(0.6, 0.01, 0.5)
    with pytest.raises(ScenarioError, match=re.escape("got inf")):
        validate_control_period(float("inf"), 0.01, 0.5)


def test_simulate_registered_refuses_a_control_period_longer_than_the_run():
    # a 2 s period in a 1 s run holds the first command throughout; refused before building
    message = (
        "control_period must be in [time_step, 1] s = [0.002, 1] s (a longer period never "
        "updates the controller after t = 0 within a run of at most 1 s), got 2"
    )
    with pytest.raises(ScenarioError, match=re.escape(message)):
        simulate_registered("arm_reach", scenario=ReachScenario(control_period=2.0), duration=1.0)


@pytest.mark.parametrize("replay", [False, True])
def test_the_cli_refuses_a_run_shorter_than_the_control_period(tmp_path, capsys, replay):
    # arm_reach's default period is 0.01 s; a 0.005 s run never sees a second update
    argv = ["simulate", "arm_reach", "--duration", "0.005"]
    argv += ["--replay", "--out", str(tmp_path / "out")] if replay else []
    assert main(argv) == 2
    assert capsys.readouterr().err.endswith(
        "error: control_period must be in [time_step, 0.005] s = [0.002, 0.005] s (a longer "
        "period never updates the controller after t = 0 within a run of at most 0.005 s), "
        "got 0.01\n"
    )
    assert not (tmp_path / "out").exists()
