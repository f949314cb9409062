"""PlanExecutor: switching rule, FixValue expectations, the soccer plan world, bad input."""

import numpy as np
import pytest
from pydrake.systems.framework import DiscreteValues
from repertoire.systems.go_to_pose import ActionStatus, GoToPose
from repertoire.systems.plan_executor import PlanExecutor, next_plan_state

from repertoire.errors import RepertoireError, ScenarioError

R, S, F, T = (
    ActionStatus.RUNNING,
    ActionStatus.SUCCEEDED,
    ActionStatus.FAILED,
    ActionStatus.TIMED_OUT,
)


def test_next_plan_state_rule():
    assert next_plan_state(0, R, R, 2) == (0, R)
    assert next_plan_state(0, R, S, 2) == (1, R)
    assert next_plan_state(1, R, S, 2) == (2, S)
    assert next_plan_state(1, R, F, 2) == (1, F)
    assert next_plan_state(0, R, T, 2) == (0, T)
    assert next_plan_state(2, S, F, 2) == (2, S)  # a finished plan stays finished


def _fixed(executor, statuses, commands):
    context = executor.CreateDefaultContext()
    for i, (s, c) in enumerate(zip(statuses, commands, strict=True)):
        executor.get_status_input_port(i).FixValue(context, s)
        executor.get_command_input_port(i).FixValue(context, np.asarray(c, dtype=float))
    return context


def _step(executor, context, time):
    context.SetTime(time)
    xd = executor.AllocateDiscreteVariables()
    executor.CalcForcedDiscreteVariableUpdate(context, xd)
    context.SetDiscreteState(xd.get_vector(0).CopyToVector())


def test_executor_routes_targets_and_commands_and_switches():
    targets = [[1.0, 2.0, 0.5, 0.2], [3.0, 0.0, -1.0, 0.0]]
    ex = PlanExecutor(targets, period=0.02)
    context = _fixed(ex, [R, R], [[0.3, 0.1], [0.7, -0.2]])
    np.testing.assert_array_equal(ex.GetOutputPort("target_0").Eval(context), targets[0])
    np.testing.assert_array_equal(ex.GetOutputPort("target_1").Eval(context), targets[1])
    np.testing.assert_array_equal(ex.get_command_output_port().Eval(context), [0.3, 0.1])
    assert ex.get_status_output_port().Eval(context) == R
    assert ex.get_active_action_output_port().Eval(context)[0] == 0
    assert np.isnan(ex.get_finish_times_output_port().Eval(context)).all()

    _step(ex, context, 0.5)  # action 0 still running: nothing changes
    assert ex.get_active_action_output_port().Eval(context)[0] == 0
    assert [ex.GetOutputPort(f"active_{i}").Eval(context)[0] for i in (0, 1)] == [1.0, 0.0]

    ex.get_status_input_port(0).FixValue(context, S)
    _step(ex, context, 1.25)
    assert ex.get_active_action_output_port().Eval(context)[0] == 1
    np.testing.assert_array_equal(ex.get_command_output_port().Eval(context), [0.7, -0.2])
    finish = ex.get_finish_times_output_port().Eval(context)
    assert finish[0] == 1.25 and np.isnan(finish[1])
    assert [ex.GetOutputPort(f"active_{i}").Eval(context)[0] for i in (0, 1)] == [0.0, 1.0]

    ex.get_status_input_port(1).FixValue(context, S)
    _step(ex, context, 3.5)
    assert ex.get_status_output_port().Eval(context) == S
    assert ex.get_active_action_output_port().Eval(context)[0] == 2
    np.testing.assert_array_equal(ex.get_finish_times_output_port().Eval(context), [1.25, 3.5])
    np.testing.assert_array_equal(ex.get_command_output_port().Eval(context), [0.0, 0.0])
    assert [ex.GetOutputPort(f"active_{i}").Eval(context)[0] for i in (0, 1)] == [0.0, 0.0]
    _step(ex, context, 4.0)  # finished: state frozen
    np.testing.assert_array_equal(ex.get_finish_times_output_port().Eval(context), [1.25, 3.5])


def test_executor_failure_ends_plan_and_targets_are_parameters():
    ex = PlanExecutor([[0.0, 0.0, 0.0, 0.0]] * 3)
    context = _fixed(ex, [R, T, R], [[1.0, 1.0]] * 3)
    ex.get_status_input_port(0).FixValue(context, S)
    _step(ex, context, 0.4)
    _step(ex, context, 0.42)  # action 1 timed out
    assert ex.get_status_output_port().Eval(context) == T
    assert ex.get_active_action_output_port().Eval(context)[0] == 1
    np.testing.assert_array_equal(ex.get_finish_times_output_port().Eval(context)[:2], [0.4, 0.42])
    np.testing.assert_array_equal(ex.get_command_output_port().Eval(context), [0.0, 0.0])
    ex.set_target(context, 2, [1.0, -1.0, 0.25, 0.0])
    np.testing.assert_array_equal(ex.GetOutputPort("target_2").Eval(context), [1, -1, 0.25, 0])
    assert isinstance(ex.AllocateDiscreteVariables(), DiscreteValues)


def test_executor_bad_input():
    with pytest.raises(RepertoireError, match=r"n >= 1 actions, got shape \(0,\)"):
        PlanExecutor([])
    with pytest.raises(RepertoireError, match=r"targets of actions \[1\] are not finite"):
        PlanExecutor([[0.0, 0.0], [np.nan, 0.0]])
    with pytest.raises(RepertoireError, match=r"one target of t numbers.*sizes \[4, 2\]"):
        PlanExecutor([[1.0, 2.0, 3.0, 4.0], [1.0, 2.0]])
    with pytest.raises(RepertoireError, match="period must be finite and > 0, got 0"):
        PlanExecutor([[0.0]], period=0)
    with pytest.raises(RepertoireError, match="command_size must be an int >= 1, got 0"):
        PlanExecutor([[0.0]], command_size=0)
    ex = PlanExecutor([[0.0, 0.0]])
    context = ex.CreateDefaultContext()
    with pytest.raises(RepertoireError, match="must be 2 finite values"):
        ex.set_target(context, 0, [1.0, np.inf])
    with pytest.raises(RepertoireError, match=r"action index 3 is not in 0..0"):
        ex.set_target(context, 3, [1.0, 2.0])


def test_soccer_plan_world_runs_the_plan_and_dribbles_the_ball():
    from repertoire.diagrams.simulate import simulate_registered
    from repertoire.diagrams.soccer_plan import SoccerPlanScenario, build_soccer_plan
    from repertoire.systems.dribble_ball import DribbleBall

    figures = simulate_registered("soccer_plan", duration=12.0)
    assert figures["plan_succeeded"] == 1.0 and figures["still_running"] == 0.0
    assert figures["ball_held"] == 1.0  # delivered: the plan succeeds only so
    # cut short: the plan has not ended, it did not fail
    short = simulate_registered("soccer_plan", duration=1.0)
    assert (short["plan_succeeded"], short["still_running"]) == (0.0, 1.0)
    assert 0.0 < figures["plan_time_s"] < 12.0
    assert figures["position_error_m"] < 0.1
    assert figures["ball_moved_m"] > 0.3  # dribbled along the second leg
    diagram = build_soccer_plan(SoccerPlanScenario())
    names = {diagram.GetSubsystemByName(n).get_name() for n in ("action_0", "action_1")}
    assert names == {"action_0", "action_1"}
    assert isinstance(diagram.GetSubsystemByName("action_1"), DribbleBall)
    assert diagram.GetSubsystemByName("action_1").collect
    assert diagram.HasSubsystemNamed("ball_rolling_resistance")
    goto_only = build_soccer_plan(SoccerPlanScenario(dribble=False))
    assert isinstance(goto_only.GetSubsystemByName("action_1"), GoToPose)
    assert not goto_only.HasSubsystemNamed("ball_reader")
    with pytest.raises(ScenarioError, match=r"targets\[1\] must be 4 finite values"):
        build_soccer_plan(SoccerPlanScenario(targets=[[0, 0, 0, 0], [1, 2, 3]]))
    with pytest.raises(ScenarioError, match="at least one"):
        build_soccer_plan(SoccerPlanScenario(targets=[]))
    # a leg ending with the robot in a goal post (it pushed the post until its timeout)
    with pytest.raises(ScenarioError, match=r"targets\[1\] \[2.8, -0.6, 0.0, 0.0\] puts the robot"):
        build_soccer_plan(SoccerPlanScenario(targets=[[0.65, 0.5, 0, 0.2], [2.8, -0.6, 0.0, 0.0]]))
    # a subgoal or start off the field (the robot drove off it and on, unchecked)
    with pytest.raises(ScenarioError, match=r"targets\[1\] \[1.0, -2.5, 0.0, 0.0\] lies off the"):
        build_soccer_plan(SoccerPlanScenario(targets=[[0.65, 0.5, 0, 0.2], [1.0, -2.5, 0.0, 0.0]]))
    with pytest.raises(ScenarioError, match=r"initial_pose \[-3.5, 0.0, 0.0\] lies off the field"):
        build_soccer_plan(SoccerPlanScenario(initial_pose=[-3.5, 0.0, 0.0]))
    with pytest.raises(ScenarioError, match=r"unknown GoToPose gains \['k_x'\]"):
        build_soccer_plan(SoccerPlanScenario(gains={"k_x": 1.0}))
    with pytest.raises(ScenarioError, match=r"unknown GoToPose gains \['k_y'\]"):
        build_soccer_plan(SoccerPlanScenario(action_gains=[{"k_y": 1.0}]))
    with pytest.raises(ScenarioError, match=r"unknown DribbleBall gains \['k_y'\]"):
        build_soccer_plan(SoccerPlanScenario(dribble_gains={"k_y": 1.0}))
    with pytest.raises(ScenarioError, match=r"one dict per GoToPose action: got 2 for 1 \("):
        build_soccer_plan(SoccerPlanScenario(action_gains=[{}, {}]))
    with pytest.raises(ScenarioError, match="dribble must be a bool, got 1"):
        build_soccer_plan(SoccerPlanScenario(dribble=1))
    with pytest.raises(ScenarioError, match="ball_decel must be finite and >= 0, got -1.0"):
        build_soccer_plan(SoccerPlanScenario(ball_decel=-1.0))
    slow = build_soccer_plan(
        SoccerPlanScenario(action_gains=[{}, {"omega_max": 0.6}], dribble=False)
    )
    context = slow.CreateDefaultContext()
    for name, omega in (("action_0", 2.5), ("action_1", 0.6)):
        action = slow.GetSubsystemByName(name)
        assert action.gains(action.GetMyContextFromRoot(context))["omega_max"] == omega


def test_soccer_plan_later_leg_through_an_earlier_target_is_driven():
    # There and back and there again: the third leg's target is reached by the first
    # leg. The third GoToPose used to latch SUCCEEDED then, so the plan "succeeded"
    # at the end of the second leg, 0.95 m from the last target; now each action only
    # ends once the executor has started it (its active input).
    from repertoire.diagrams.simulate import simulate_registered
    from repertoire.diagrams.soccer_plan import SoccerPlanScenario

    scenario = SoccerPlanScenario(
        initial_pose=[0.0, 0.0, 0.0],
        targets=[[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, np.pi, 0.0], [1.0, 0.0, 0.0, 0.0]],
        gains={"timeout": 40.0},
        dribble=False,
    )
    figures = simulate_registered("soccer_plan", scenario=scenario, duration=20.0)
    assert figures["plan_succeeded"] == 1.0
    assert figures["position_error_m"] < 0.1


def test_soccer_plan_success_needs_the_ball_held_at_the_end():
    # a plan whose actions all succeeded counts as succeeded only with the ball held when
    # its last action is a DribbleBall (the GoToPose "dribble" once succeeded without it)
    from pydrake.math import RigidTransform
    from repertoire.diagrams.soccer_plan import (
        SoccerPlanScenario,
        ball_held,
        build_soccer_plan,
        plan_succeeded,
    )

    for dribble in (True, False):
        diagram = build_soccer_plan(SoccerPlanScenario(dribble=dribble))
        context = diagram.CreateDefaultContext()
        executor = diagram.GetSubsystemByName("executor")
        executor.GetMyMutableContextFromRoot(context).SetDiscreteState(
            [2.0, float(ActionStatus.SUCCEEDED), 3.0, 9.0]
        )
        plant = diagram.GetSubsystemByName("plant")
        pc = plant.GetMyMutableContextFromRoot(context)
        chassis, ball = plant.GetBodyByName("chassis"), plant.GetBodyByName("ball")
        plant.SetFreeBodyPose(pc, chassis, RigidTransform([0.0, 0.0, 0.05]))
        for ball_x, held in ((0.31, True), (0.7, False)):  # on the held spot / 0.39 m beyond
            plant.SetFreeBodyPose(pc, ball, RigidTransform([ball_x, 0.0, 0.11]))
            assert ball_held(diagram, context) == held
            assert plan_succeeded(diagram, context) == (held or not dribble)


def test_soccer_plan_dribble_starts_closing_on_the_ball():
    # refinement_explore's seed 113: the approach stops 0.54 m behind the ball, the
    # destination 0.23 rad off. The waiting dribble used to track collect mode's circling
    # turn and hand it to the robot: it turned away from the ball, lost it beside a guide
    # arm, circled it and delivered it after 8.68 s. Now it tracks closing's command: it
    # closes on the ball and dribbles it (no collecting), in 5.78 s.
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import EventStatus
    from repertoire.diagrams.soccer_plan import (
        SoccerPlanScenario,
        build_soccer_plan,
        finish_times,
        plan_status,
    )
    from repertoire.studies._refinement_common import approach_target, sample_situation
    from repertoire.studies.refinement_explore import demo_config
    from repertoire.systems.dribble_ball import CLOSING, COLLECTING, DRIBBLING

    config = demo_config()
    rng = np.random.default_rng(113)
    start, dest = sample_situation(config, rng)
    phi_a, v_a = rng.uniform(-np.pi, np.pi), rng.uniform(0.0, config.approach_v_max)
    scenario = SoccerPlanScenario(
        initial_pose=[float(s) for s in start[:3]],
        initial_speed=float(start[3]),
        targets=[[float(x) for x in approach_target(phi_a, v_a, 0.5)], [float(x) for x in dest]],
        gains={**config.gains, "timeout": config.timeout},
        dribble=True,
    )
    diagram = build_soccer_plan(scenario)
    dribble = diagram.GetSubsystemByName("action_1")
    executor = diagram.GetSubsystemByName("executor")
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    phases = []

    def monitor(root):
        ex = executor.GetMyContextFromRoot(root)
        if executor.get_active_action_output_port().Eval(ex)[0] == 1:
            phase = int(dribble.GetMyContextFromRoot(root).get_discrete_state(0).get_value()[4])
            if not phases or phases[-1] != phase:
                phases.append(phase)
        if plan_status(diagram, root) != ActionStatus.RUNNING:
            return EventStatus.ReachedTermination(None, "plan ended")
        return EventStatus.Succeeded()

    simulator.set_monitor(monitor)
    simulator.AdvanceTo(30.0)
    assert plan_status(diagram, context) == ActionStatus.SUCCEEDED
    # the first entry is the slot it waited with (none kept), then its own phases
    assert phases == [COLLECTING, CLOSING, DRIBBLING]
    t_approach, t_end = finish_times(diagram, context)
    assert t_end - t_approach < 6.0
