"""FootstepPlanSource: exact stance/swing targets at chosen times, plan port, bad plans."""

import numpy as np
import pytest
from pydrake.systems.framework import DiagramBuilder
from repertoire.planning.footstep import FootstepError, FootstepPlan, PlanStatus
from repertoire.systems.footstep_source import FootstepPlanSource, plan_phase_at


def make_plan(times=(1.0, 1.8, 2.8)) -> FootstepPlan:
    return FootstepPlan(
        poses=[[0.0, 0.1, 0.0], [0.3, -0.1, 0.0], [0.5, 0.1, 0.2]],
        feet=[0, 1, 0],
        actions=["forward_long", "forward_medium"],
        times=list(times),
        status=PlanStatus.SUCCESS,
        cost=2.05,
        cost_to_go=0.0,
        nodes_expanded=3,
        nodes_generated=14,
        planning_time_s=0.001,
        initial_swing_pose=[0.0, -0.1, 0.0],
        goal=[0.5, 0.1],
        goal_tolerance=0.15,
        initial_history=["stop", "stop"],
    )


EXPECTED = [
    # t, k, stance, swing start, swing target, phase, swing foot
    (0.5, 0, [0.0, 0.1, 0.0], [0.0, -0.1, 0.0], [0.0, -0.1, 0.0], 0.0, 1),
    (1.0, 1, [0.0, 0.1, 0.0], [0.0, -0.1, 0.0], [0.3, -0.1, 0.0], 0.0, 1),
    (1.2, 1, [0.0, 0.1, 0.0], [0.0, -0.1, 0.0], [0.3, -0.1, 0.0], 0.25, 1),
    (1.8, 2, [0.3, -0.1, 0.0], [0.0, 0.1, 0.0], [0.5, 0.1, 0.2], 0.0, 0),
    (2.55, 2, [0.3, -0.1, 0.0], [0.0, 0.1, 0.0], [0.5, 0.1, 0.2], 0.75, 0),
    (2.8, 2, [0.3, -0.1, 0.0], [0.0, 0.1, 0.0], [0.5, 0.1, 0.2], 1.0, 0),
    (9.0, 2, [0.3, -0.1, 0.0], [0.0, 0.1, 0.0], [0.5, 0.1, 0.2], 1.0, 0),
]


@pytest.mark.parametrize("t, k, stance, start, target, phase, foot", EXPECTED)
def test_plan_phase_at(t, k, stance, start, target, phase, foot):
    p = plan_phase_at(make_plan(), t)
    assert p.step_index == k
    assert p.stance_pose == stance and p.swing_start_pose == start
    assert p.swing_target_pose == target
    assert p.swing_phase == pytest.approx(phase) and p.swing_foot == foot


def test_source_ports_at_chosen_times():
    plan = make_plan()
    src = FootstepPlanSource(plan)
    ctx = src.CreateDefaultContext()
    ports = {
        n: src.GetOutputPort(n)
        for n in (
            "plan",
            "stance_foot_pose",
            "swing_start_pose",
            "swing_target_pose",
            "step_index",
            "swing_phase",
            "swing_foot",
        )
    }
    assert src.num_input_ports() == 0 and src.num_output_ports() == 7
    for t, k, stance, start, target, phase, foot in EXPECTED:
        ctx.SetTime(t)
        np.testing.assert_allclose(ports["stance_foot_pose"].Eval(ctx), stance)
        np.testing.assert_allclose(ports["swing_start_pose"].Eval(ctx), start)
        np.testing.assert_allclose(ports["swing_target_pose"].Eval(ctx), target)
        assert ports["step_index"].Eval(ctx)[0] == k
        assert ports["swing_phase"].Eval(ctx)[0] == pytest.approx(phase)
        assert ports["swing_foot"].Eval(ctx)[0] == foot
    assert ports["plan"].Eval(ctx) == plan
    # a new plan in the context changes every output
    later = make_plan(times=(3.0, 4.0, 5.0))
    src.SetPlan(ctx, later)
    ctx.SetTime(3.5)
    assert ports["plan"].Eval(ctx).times == [3.0, 4.0, 5.0]
    assert ports["step_index"].Eval(ctx)[0] == 1
    assert ports["swing_phase"].Eval(ctx)[0] == pytest.approx(0.5)


def test_source_in_a_diagram_and_bad_plans():
    builder = DiagramBuilder()
    src = builder.AddSystem(FootstepPlanSource(make_plan()))
    builder.ExportOutput(src.GetOutputPort("swing_target_pose"), "target")
    diagram = builder.Build()
    ctx = diagram.CreateDefaultContext()
    ctx.SetTime(2.0)
    np.testing.assert_allclose(diagram.GetOutputPort("target").Eval(ctx), [0.5, 0.1, 0.2])
    with pytest.raises(FootstepError, match="plan times must increase strictly"):
        FootstepPlanSource(make_plan(times=(1.0, 1.0, 2.0)))
    with pytest.raises(FootstepError, match="needs a FootstepPlan"):
        FootstepPlanSource({"poses": []})
    with pytest.raises(FootstepError, match="needs 3 poses"):
        FootstepPlan(**{**make_plan().__dict__, "times": [0.0, 1.0]})
