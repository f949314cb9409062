"""Plans the walker cannot or should not execute as given: clear errors naming the values.

Probed in session 32 on inputs the other walking tests never use: start soles the biped
cannot stand on, a diagram built for one plan asked to measure another, a plan swapped
into a diagram whose robot stands elsewhere, and a plan of no steps.
"""

import math

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from repertoire.diagrams.biped_walk import (
    build_walk_diagram,
    check_start_stance,
    execute_plan,
    plan_from_actions,
    same_commands,
    start_feet,
)
from repertoire.planning.footstep.actions import nominal_action_table
from repertoire.planning.footstep.types import FootstepPlan

from repertoire.errors import RepertoireError


def _plan(actions, start=(0.0, 0.0, 0.0), stance="left"):
    s, w = start_feet(list(start), stance)
    return plan_from_actions(actions, s, stance, w, nominal_action_table())


def _two_soles(left, right):
    # the first stance is the left sole, the right one makes the first step
    return FootstepPlan.from_commands(
        [list(left), [0.3, right[1], 0.0]], [0, 1], ["forward_long"], [0.0, 1.0],
        list(right), ["stop", "stop"],
    )  # fmt: skip


@pytest.mark.parametrize(
    ("left", "right", "match"),
    [
        # before: all three were built and simulated (the IK stretched or crossed the legs)
        ([0.0, 0.0, 0.0], [0.0, 0.0, 0.0], r"left sole is 0.000 m left of the right one"),
        ([0.0, -0.1, 0.0], [0.0, 0.1, 0.0], r"left sole is -0.200 m left .* needs >= 0.1 m"),
        ([0.0, 0.0, 0.0], [0.0, -3.0, 0.0], r"out of reach \(hip-ankle distance"),
        ([0.0, 0.1, 1.5], [0.0, -0.1, -0.3], r"hip_yaw = .* outside its limits"),
    ],
)
def test_start_soles_the_biped_cannot_stand_on_are_refused(left, right, match):
    plan = _two_soles(left, right)
    soles = rf"left sole \[{left[0]}, {left[1]}, {left[2]}\], right sole \[{right[0]}, "
    with pytest.raises(RepertoireError, match=rf"cannot stand on the start soles \({soles}"):
        build_walk_diagram(plan)
    with pytest.raises(RepertoireError, match=match):
        build_walk_diagram(plan)


def test_start_soles_of_the_study_stances_pass():
    for yaw in (0.0, 2.5, -math.pi):
        for stance in ("left", "right"):
            s, w = start_feet([1.0, -2.0, yaw], stance)
            left, right = (s, w) if stance == "left" else (w, s)
            check_start_stance(left, right, 0.5 * (np.add(s, w)[:2]), 0.6)
    check_start_stance([0.0, 0.05, 0.0], [0.0, -0.05, 0.0], [0.0, 0.0], 0.6)  # soles touching


def test_execute_plan_refuses_a_diagram_that_walks_another_plan():
    walked = _plan(["forward_long", "stop"])
    other = _plan(["forward_short", "stop"])
    diagram = build_walk_diagram(walked)
    # before: the robot walked `walked` and its landings were reported against `other`
    with pytest.raises(RepertoireError, match=r"execute_plan's plan \(2 steps from .*is not the"):
        execute_plan(other, diagram=diagram, max_steps=0)
    assert same_commands(walked, FootstepPlan.from_dict(walked.to_dict()))
    assert not same_commands(walked, other)
    moved = FootstepPlan(**{**walked.__dict__, "times": [0.0, 0.8, 1.7]})
    assert not same_commands(walked, moved)


def test_execute_plan_refuses_a_plan_set_where_the_robot_does_not_stand():
    diagram = build_walk_diagram(_plan(["stop"]))
    simulator = Simulator(diagram)
    source = diagram.GetSubsystemByName("plan_source")
    far = _plan(["stop"], start=(2.0, 1.0, 0.5))
    source.SetPlan(source.GetMyContextFromRoot(simulator.get_context()), far)
    # before: the steps were taken from the old start and measured against the new one
    with pytest.raises(
        RepertoireError,
        match=r"left sole stands at \[0.0, 0.095, 0.0\] but the plan starts it at "
        r"\[1.9545, 1.0834, 0.5\] \(\[x, y, yaw\]; 2.1902 m, 0.5000 rad apart",
    ):
        execute_plan(far, diagram=diagram, simulator=simulator, max_steps=0)
    near = _plan(["stop"], start=(0.003, 0.0, 0.0))  # within the 1 cm tolerance
    source.SetPlan(source.GetMyContextFromRoot(simulator.get_context()), near)
    assert execute_plan(near, diagram=diagram, simulator=simulator, max_steps=0).landed == []


def test_a_plan_switched_mid_walk_is_refused_and_one_switched_before_the_start_is_walked():
    first = _plan(["forward_long", "forward_long", "stop"])
    diagram = build_walk_diagram(first)
    simulator = Simulator(diagram)
    context = simulator.get_context()
    source = diagram.GetSubsystemByName("plan_source")
    stepper = diagram.GetSubsystemByName("command_stepper")
    shorter = _plan(["forward_short", "stop"])  # the same start soles
    source.SetPlan(source.GetMyContextFromRoot(context), shorter)  # before the start: allowed
    simulator.Initialize()
    assert stepper.GetOutputPort("footsteps").Eval(
        stepper.GetMyContextFromRoot(context)
    ).actions == ["forward_short", "stop"]
    simulator.AdvanceTo(1.5)  # the first command was at 0.4 s
    source.SetPlan(source.GetMyContextFromRoot(context), shorter)  # the same plan again
    simulator.AdvanceTo(1.6)
    # before: the feet targets jumped to the new plan's steps at that time and the biped
    # fell (a switch at 3 s: 0.35 m and 0.7 rad, fell 1.2 s later)
    source.SetPlan(source.GetMyContextFromRoot(context), first)
    with pytest.raises(
        RepertoireError,
        match=r"CommandStepper got a new plan \(3 steps from .*\) at t = 1.600 s, after its "
        r"first step was commanded at 0.400 s; it walks the plan it started with \(2 steps",
    ):
        simulator.AdvanceTo(1.7)


def test_a_plan_of_no_steps_stands_and_counts_as_reached_from_inside_the_goal():
    from repertoire.planning.footstep.environment import OccupancyGrid
    from repertoire.studies.footstep_execution import evaluate_execution

    plan = _plan([])
    result = execute_plan(plan)
    assert result.landed == [] and not result.fell
    assert result.final_time == pytest.approx(0.4 + 0.4 + 1.2)  # holds and double support
    np.testing.assert_allclose(result.final_soles, [[0, 0.095, 0], [0, -0.095, 0]], atol=2e-3)
    grid = OccupancyGrid(np.zeros((40, 40), bool), 0.05, (-1.0, -1.0))
    stats = evaluate_execution(plan, result, grid)
    # before: only landings counted, so standing on the goal was "not reached"
    assert stats["reached"] and stats["steps"] == 0 and stats["within_frac"] == 0.0
    away = FootstepPlan(**{**plan.__dict__, "goal": [1.0, 0.0]})
    assert not evaluate_execution(away, result, grid)["reached"]


def test_command_stepper_guard_with_fixed_inputs():
    from repertoire.systems.walking import CommandStepper, SteppingRule, realize_plan

    rule = SteppingRule(initial_hold=0.5)
    stepper = CommandStepper(rule, start_time=1.0)  # first command at 1.5 s
    ctx = stepper.CreateDefaultContext()
    first, other = _plan(["forward_long"]), _plan(["stop"])
    port = stepper.GetInputPort("plan")
    out = stepper.GetOutputPort("footsteps")
    ctx.SetTime(9.0)
    port.FixValue(ctx, other)  # no plan seen at initialization: nothing to compare with
    assert out.Eval(ctx).poses == realize_plan(other, rule, start_time=1.0).poses
    ctx.get_mutable_abstract_state(0).set_value(first)
    for t in (0.0, 1.5):  # up to the first command a new plan is taken
        ctx.SetTime(t)
        port.FixValue(ctx, other)
        assert out.Eval(ctx).actions == ["stop"]
        assert out.Eval(ctx).command_times == [1.5]
    ctx.SetTime(1.5 + 1e-6)
    port.FixValue(ctx, first)  # the plan it started with
    assert out.Eval(ctx).actions == ["forward_long"]
    port.FixValue(ctx, other)
    with pytest.raises(RepertoireError, match=r"got a new plan \(1 steps from \[0.0, 0.095, 0.0\]"):
        out.Eval(ctx)
