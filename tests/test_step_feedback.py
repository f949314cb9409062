"""World-frame step feedback of the walker (session 33).

Open loop, the walker took each command's step from where the controller *believed* the
stance sole stood; the stance soles turn and slide a little under load, so long plans
landed up to 0.27 m from their targets. With feedback each step is taken from the
measured stance sole to the plan's world pose.
"""

import math

import numpy as np
import pytest
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.systems.analysis import Simulator
from repertoire.diagrams.biped_walk import (
    BipedWalkScenario,
    build_walk_diagram,
    execute_plan,
    plan_from_actions,
    plan_from_rule,
    start_feet,
)
from repertoire.planning.footstep.actions import nominal_action_table
from repertoire.systems.step_feedback import (
    FootstepFeedback,
    StepReach,
    check_plan_reach,
    check_step_reach,
    open_loop_steps,
    retarget,
    retarget_sequence,
)
from repertoire.systems.walking import SteppingRule, compose, realize_plan, relative

from repertoire.errors import RepertoireError


def _rule_plan(actions, start=(0.0, 0.0, 0.0)):
    s, w = start_feet(list(start), "left")
    return plan_from_rule(actions, s, "left", w, SteppingRule())


def _moved(E, pose):
    """``pose`` (x, y, yaw) moved by the rigid transform E = (x, y, yaw)."""
    return compose(np.asarray(E, float), np.asarray(pose, float))


def test_retarget_closed_form():
    S_c = np.array([1.0, 2.0, 0.3])
    T_c = np.array([1.25, 1.8, 0.5])
    # no drift: the controller's landing is the world target
    np.testing.assert_allclose(retarget(S_c, S_c, T_c), T_c, atol=1e-15)
    # the world is the controller frame moved by E: the world target E.T_c maps back to T_c
    E = np.array([0.03, -0.02, 0.04])
    np.testing.assert_allclose(retarget(S_c, _moved(E, S_c), _moved(E, T_c)), T_c, atol=1e-12)
    # a stance sole turned by 0.01 rad in place: the target turns back about it
    S_w = np.array([1.0, 2.0, 0.31])
    want = compose(S_c, relative(S_w, T_c))
    np.testing.assert_allclose(retarget(S_c, S_w, T_c), want, atol=0)
    assert abs(want[2] - 0.49) < 1e-12


def test_retarget_sequence_moves_the_steps_from_k_on_by_one_transform():
    plan = _rule_plan(["forward_long", "turn_left", "forward_medium", "stop"])
    seq = realize_plan(plan, SteppingRule())
    E = np.array([0.01, 0.02, -0.03])
    stance_c = np.asarray(seq.poses[0], float)  # step 1's stance is step 0's landing
    targets = [list(p) for p in plan.poses[1:]]
    out = retarget_sequence(seq, 1, _moved(E, stance_c), targets)
    assert out.poses[0] == seq.poses[0]
    for j in range(1, 4):
        # the measured stance is E.stance_c, so target j lands where E^-1 puts it
        back = relative(E, np.asarray(targets[j], float))  # E^-1 . target
        np.testing.assert_allclose(out.poses[j], back, atol=1e-12)
    assert out.actions == seq.actions and out.land_times == seq.land_times
    with pytest.raises(RepertoireError, match=r"step 4 is not in 0..3"):
        retarget_sequence(seq, 4, stance_c, targets)
    with pytest.raises(RepertoireError, match=r"3 world targets for a sequence of 4 steps"):
        retarget_sequence(seq, 0, stance_c, targets[:3])


def test_step_reach_bounds_and_stance():
    stance = [0.0, 0.095, 0.0]
    step = [0.27, -0.19, 0.0]
    ok = compose(np.array(stance), np.array([0.30, -0.19, 0.0]))  # 0.03 m further
    check_step_reach(3, "forward_long", 1, stance, ok, step, StepReach(), 0.6)
    far = compose(np.array(stance), np.array([0.32, -0.19, 0.0]))  # 0.05 m further
    with pytest.raises(
        RepertoireError,
        match=r"step 3 \(forward_long, right foot\) to world target \[0.32, -0.095, 0.0\] .*"
        r"0.0500 m and 0.0000 rad from the step the command realizes \(\[0.27, -0.19, 0.0\]\)",
    ):
        check_step_reach(3, "forward_long", 1, stance, far, step, StepReach(), 0.6)
    turned = compose(np.array(stance), np.array([0.27, -0.19, 0.15]))
    with pytest.raises(RepertoireError, match=r"0.0000 m and 0.1500 rad"):
        check_step_reach(3, "forward_long", 1, stance, turned, step, StepReach(), 0.6)
    # within the bounds of a step that crosses under the stance sole: cannot stand on it
    cross = [0.0, -0.09, 0.0]
    with pytest.raises(
        RepertoireError, match=r"cannot stand on the soles of step 3 .*needs >= 0.1"
    ):
        check_step_reach(3, "side_step", 1, stance, [0.0, 0.0, 0.0], cross, StepReach(), 0.6)
    for bad in (0.0, -0.01, math.nan, math.inf):
        with pytest.raises(RepertoireError, match="max_correction_m must be finite and > 0"):
            StepReach(max_correction_m=bad).validate()


def test_plan_reach_refuses_plans_of_another_table():
    s, w = start_feet([0.0, 0.0, 0.0], "left")
    actions = ["forward_long", "forward_long", "turn_left", "stop"]
    check_plan_reach(_rule_plan(actions), SteppingRule(), StepReach(), 0.6)
    nominal = plan_from_actions(actions, s, "left", w, nominal_action_table())
    # the nominal table's first long step is 0.30 m; from standing the rule makes 0.12 m
    with pytest.raises(RepertoireError, match=r"step 0 \(forward_long.* 0.1800 m and 0.0000 rad"):
        check_plan_reach(nominal, SteppingRule(), StepReach(), 0.6)
    with pytest.raises(RepertoireError, match=r"step 0 \(forward_long.* 0.1800 m"):
        build_walk_diagram(nominal, feedback=True)
    diagram = build_walk_diagram(nominal)  # open loop it walks the commands as before
    # a diagram walks as it was built: asking for the other way is refused
    with pytest.raises(RepertoireError, match=r"feedback=True\) got a diagram built without"):
        execute_plan(nominal, diagram=diagram, feedback=True, max_steps=0)
    assert execute_plan(nominal, diagram=diagram, max_steps=0).landed == []


def test_plan_from_rule_holds_the_rule_steps():
    plan = _rule_plan(["forward_long", "forward_long", "side_step", "stop"])
    seq = realize_plan(plan, SteppingRule())
    np.testing.assert_allclose(plan.poses_array()[1:], np.asarray(seq.poses), atol=0)
    assert list(plan.feet) == [0, 1, 0, 1, 0]
    np.testing.assert_allclose(plan.times, [0.0, 1.12, 2.24, 3.36, 4.48], atol=1e-12)
    np.testing.assert_allclose(open_loop_steps(seq)[0], [0.12, -0.19, 0.0], atol=1e-12)


def test_feedback_system_retargets_at_lift_off():
    plan = _rule_plan(["forward_long", "forward_long", "stop"])
    rule = SteppingRule()
    seq = realize_plan(plan, rule)
    system = FootstepFeedback(plan.num_steps, 0.6)
    context = system.CreateDefaultContext()
    system.GetInputPort("footsteps").FixValue(context, seq)
    system.GetInputPort("plan").FixValue(context, plan)
    E = np.array([0.004, -0.003, 0.01])
    left_w = _moved(E, seq.initial_left)  # the first stance (left) sole, moved by E
    soles = system.GetInputPort("soles").FixValue(context, [*left_w, *seq.initial_right])
    simulator = Simulator(system, context)
    simulator.Initialize()
    out = system.GetOutputPort("footsteps")
    assert out.Eval(context).poses == seq.poses
    lift0 = seq.command_times[0] + seq.double_support  # 0.8 s
    simulator.AdvanceTo(lift0 - 0.001)
    assert out.Eval(context).poses == seq.poses
    simulator.AdvanceTo(lift0 + 0.001)  # the update at 0.8 s has retargeted steps 0..2
    got = np.asarray(out.Eval(context).poses)
    want = [relative(E, np.asarray(p, float)) for p in plan.poses[1:]]
    np.testing.assert_allclose(got, want, atol=1e-12)
    # step 1 lifts with the right sole (step 0's) measured where the plan put it
    soles.GetMutableData().set_value(np.array([*left_w, *plan.poses[1]]))
    simulator.AdvanceTo(seq.command_times[1] + seq.double_support + 0.001)
    got1 = np.asarray(out.Eval(context).poses)
    np.testing.assert_allclose(got1[0], want[0], atol=1e-12)  # step 0 has landed: kept
    for j in (1, 2):
        np.testing.assert_allclose(
            got1[j], retarget(want[0], plan.poses[1], plan.poses[j + 1]), atol=1e-12
        )
    with pytest.raises(RepertoireError, match=r"built for 3 steps; its plan has 1 steps"):
        other = FootstepFeedback(3, 0.6)
        ctx = other.CreateDefaultContext()
        short = _rule_plan(["stop"])
        other.GetInputPort("footsteps").FixValue(ctx, realize_plan(short, rule))
        other.GetInputPort("plan").FixValue(ctx, short)
        other.GetInputPort("soles").FixValue(ctx, np.zeros(6))
        Simulator(other, ctx).Initialize()


def test_scenario_walks_actions_as_the_rule_makes_them():
    scenario = BipedWalkScenario(map_seed=-1)
    assert scenario.feedback is True
    from repertoire.diagrams.biped_walk import build_biped_walk

    diagram = build_biped_walk(scenario)  # the default actions: refused if nominal poses
    assert diagram.HasSubsystemNamed("step_feedback")
    assert not build_biped_walk(BipedWalkScenario(map_seed=-1, feedback=False)).HasSubsystemNamed(
        "step_feedback"
    )


def test_physics_feedback_lands_on_the_plan_where_open_loop_drifts():
    # 24 steps with turns both ways; the same plan open loop and with feedback
    actions = ["forward_long"] * 4 + ["turn_left"] * 4 + ["forward_long"] * 4
    actions += ["turn_right"] * 2 + ["side_step"] * 2 + ["forward_medium"] * 6 + ["stop"] * 2
    plan = _rule_plan(actions, start=(0.2, -0.1, 0.4))
    planned = plan.poses_array()[1:, :2]
    opened = execute_plan(plan)
    assert not opened.fell and len(opened.landed) == plan.num_steps
    # open loop the stance soles' small turns add up: 14.3 mm at step 22 (session 33)
    assert np.linalg.norm(np.asarray(opened.landed)[:, :2] - planned, axis=1).max() > 0.01
    closed = execute_plan(plan, feedback=True)
    assert not closed.fell and len(closed.landed) == plan.num_steps
    pos = np.linalg.norm(np.asarray(closed.landed)[:, :2] - planned, axis=1)
    assert pos.max() < 0.003  # measured 1.07 mm here, 1.1 mm at most over 102 steps
    yaw = np.abs(np.asarray(closed.landed)[:, 2] - plan.poses_array()[1:, 2])
    assert yaw.max() < math.radians(0.5)


def test_sole_pose_sensor_reads_the_sole_frames():
    diagram = build_walk_diagram(_rule_plan(["stop"]), feedback=True)
    plant = diagram.GetSubsystemByName("plant")
    sensor = diagram.GetSubsystemByName("sole_sensor")
    poses = plant.get_body_poses_output_port().Allocate()
    X = [RigidTransform()] * plant.num_bodies()
    left = plant.GetBodyByName("left_foot").index()
    right = plant.GetBodyByName("right_foot").index()
    # the sole frames are 0.07 m below the foot bodies' origins
    X[int(left)] = RigidTransform(RotationMatrix.MakeZRotation(0.3), [1.0, 2.0, 0.07])
    X[int(right)] = RigidTransform(RotationMatrix.MakeZRotation(-2.0), [-1.0, 0.5, 0.17])
    poses.set_value(X)
    context = sensor.CreateDefaultContext()
    sensor.GetInputPort("body_poses").FixValue(context, poses)
    got = sensor.GetOutputPort("soles").Eval(context)
    np.testing.assert_allclose(got, [1.0, 2.0, 0.3, -1.0, 0.5, -2.0], atol=1e-15)


def test_a_plan_set_before_the_start_is_walked_with_feedback():
    first = _rule_plan(["forward_long", "forward_long", "stop"])
    diagram = build_walk_diagram(first, feedback=True)
    simulator = Simulator(diagram)
    context = simulator.get_context()
    source = diagram.GetSubsystemByName("plan_source")
    feedback = diagram.GetSubsystemByName("step_feedback")
    other = _rule_plan(["forward_short", "forward_medium", "stop"])  # the same start soles
    simulator.Initialize()
    simulator.AdvanceTo(0.2)  # the first command is at 0.4 s: the CommandStepper allows it
    source.SetPlan(source.GetMyContextFromRoot(context), other)
    # before: the feedback kept the first plan's steps until the first lift-off
    walked = feedback.GetOutputPort("footsteps").Eval(feedback.GetMyContextFromRoot(context))
    assert walked.poses == realize_plan(other, SteppingRule()).poses
    shorter = _rule_plan(["forward_short", "stop"])
    source.SetPlan(source.GetMyContextFromRoot(context), shorter)
    with pytest.raises(RepertoireError, match=r"built for 3 steps; its plan has 2 steps"):
        simulator.Initialize()


def test_feedback_refuses_a_target_out_of_reach_of_the_measured_stance():
    plan = _rule_plan(["forward_long", "forward_long", "stop"])
    seq = realize_plan(plan, SteppingRule())
    system = FootstepFeedback(plan.num_steps, 0.6)
    context = system.CreateDefaultContext()
    system.GetInputPort("footsteps").FixValue(context, seq)
    system.GetInputPort("plan").FixValue(context, plan)
    # the stance (left) sole measured 5 cm behind where it stood: the first step would be
    # 0.17 m where the command makes 0.12 m
    left_w = np.asarray(seq.initial_left) - [0.05, 0.0, 0.0]
    system.GetInputPort("soles").FixValue(context, [*left_w, *seq.initial_right])
    simulator = Simulator(system, context)
    simulator.AdvanceTo(0.79)
    with pytest.raises(
        RepertoireError,
        match=r"step 0 \(forward_long, right foot\) to world target \[0.12, -0.095, 0.0\] from "
        r"the stance sole at \[-0.05, 0.095, 0.0\] is out of the step model's reach: .* "
        r"0.0500 m and 0.0000 rad from the step the command realizes",
    ):
        simulator.AdvanceTo(0.81)
