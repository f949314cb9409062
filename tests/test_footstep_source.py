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


def test_plan_phase_at_refuses_a_time_that_is_not_a_number():
    # before: NaN compared false with every step time and fell through to an IndexError
    with pytest.raises(FootstepError, match="plan_phase_at needs a time in seconds, got nan"):
        plan_phase_at(make_plan(), float("nan"))
    with pytest.raises(FootstepError, match="got '1.0'"):
        plan_phase_at(make_plan(), "1.0")
    assert plan_phase_at(make_plan(), float("inf")).step_index == 2  # after the last step
    assert plan_phase_at(make_plan(), float("-inf")).step_index == 0


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


@pytest.mark.parametrize(
    ("field", "value", "match"),
    [
        ("times", [1.0, float("nan"), 2.0], r"plan times must be finite, got \[1.0, nan, 2.0\]"),
        ("times", [1.0, 2.0, float("inf")], r"plan times must be finite"),
        ("times", [1.0, "soon", 2.0], r"plan times must be numbers"),
        ("poses", [[0.0, 0.1, 0.0], [0.3, float("nan"), 0.0], [0.5, 0.1, 0.2]], r"poses must be"),
        ("poses", [[0.0, 0.1], [0.3, -0.1], [0.5, 0.1]], r"finite \[x, y, yaw\] of shape \(3, 3\)"),
        ("initial_swing_pose", [0.0, -0.1], r"initial_swing_pose must be finite .* shape \(3,\)"),
        ("feet", [0, 5, 0], r"plan feet must be 0 \(left\) or 1 \(right\), got 5 at 1"),
        ("feet", [0, 0, 1], r"must alternate from step to step, got 0 then 0 at poses 0 and 1"),
    ],
)
def test_bad_plans_are_refused_where_they_are_made(field, value, match):
    with pytest.raises(FootstepError, match=match):
        FootstepPlan(**{**make_plan().__dict__, field: value})


def test_obstacles_refuse_sizes_and_values_that_paint_nothing_or_fail():
    from repertoire.planning.footstep import MovingRectObstacle, OccupancyGrid, RectObstacle
    from repertoire.planning.footstep.types import GridError

    with pytest.raises(GridError, match=r"RectObstacle size must be > 0 m .* got \[-0.2, 0.2\]"):
        RectObstacle(center=[0.5, 0.5], size=[-0.2, 0.2])
    with pytest.raises(GridError, match=r"RectObstacle center must be 2 finite numbers"):
        RectObstacle(center=[float("nan"), 0.5], size=[0.2, 0.2])
    with pytest.raises(GridError, match=r"RectObstacle height must be finite and >= 0 m"):
        RectObstacle(center=[0.5, 0.5], size=[0.2, 0.2], height=-0.1)
    with pytest.raises(GridError, match=r"MovingRectObstacle velocity must be 2 finite"):
        MovingRectObstacle(center=[0.5, 0.5], size=[0.2, 0.2], velocity=[float("inf"), 0.0])
    with pytest.raises(GridError, match=r"MovingRectObstacle size must be > 0 m"):
        MovingRectObstacle(center=[0.5, 0.5], size=[0.2, 0.0])
    with pytest.raises(GridError, match=r"MovingRectObstacle yaw must be finite, got nan"):
        MovingRectObstacle(center=[0.5, 0.5], size=[0.2, 0.2], yaw=float("nan"))
    grid = OccupancyGrid.from_rectangles((1.0, 1.0), [RectObstacle([0.5, 0.5], [0.2, 0.2])], 0.025)
    assert grid.occupied.sum() == 64  # 8 x 8 cells of 2.5 cm: a valid obstacle still paints


def test_source_keeps_the_plan_it_was_given_and_a_plan_of_no_steps():
    # A plan edited after it was handed over does not reach the outputs: the source and
    # its contexts hold their own copies (checked in session 32, pinned here).
    plan = make_plan()
    src = FootstepPlanSource(plan)
    ctx = src.CreateDefaultContext()
    plan.poses[2][0] = float("nan")
    plan.times[2] = 1.0
    ctx.SetTime(2.55)
    np.testing.assert_array_equal(src.GetOutputPort("swing_target_pose").Eval(ctx), [0.5, 0.1, 0.2])
    assert src.GetOutputPort("swing_phase").Eval(ctx)[0] == pytest.approx(0.75)
    # no steps: at every time the robot stands, the first swing foot's pose as target
    still = FootstepPlan(
        **{**make_plan().__dict__, "poses": [[0.0, 0.1, 0.0]], "feet": [0], "actions": [],
           "times": [1.0]}
    )  # fmt: skip
    src.SetPlan(ctx, still)
    for t in (0.0, 1.0, 50.0):
        ctx.SetTime(t)
        assert src.GetOutputPort("step_index").Eval(ctx)[0] == 0
        assert src.GetOutputPort("swing_phase").Eval(ctx)[0] == 0.0
        assert src.GetOutputPort("swing_foot").Eval(ctx)[0] == 1
        np.testing.assert_array_equal(
            src.GetOutputPort("stance_foot_pose").Eval(ctx), [0.0, 0.1, 0.0]
        )
        np.testing.assert_array_equal(
            src.GetOutputPort("swing_target_pose").Eval(ctx), [0.0, -0.1, 0.0]
        )
