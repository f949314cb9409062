"""An unconnected DMP goal input stands for the learned goal, in every DMP system."""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource
from repertoire.planning.dmp_demos import slerp_minimum_jerk
from repertoire.planning.dmp_learn import learn_dmp, learn_task_space_dmp
from repertoire.planning.dmp_math import minimum_jerk_via_points
from repertoire.systems.dmp import (
    ManifoldQuaternionSystem,
    QuaternionGoalSign,
    TransformationSystem,
)
from repertoire.systems.dmp_compose import GoalMultiplexer, add_dmp
from repertoire.systems.dmp_discrete import DiscreteDmpSystem

from repertoire.errors import RepertoireError

N = 300
TIMES = np.linspace(0.0, 1.0, N)


@pytest.fixture(scope="module")
def dmp3():
    via = np.array([[0, 0, 0], [0.3, 0.5, 0.2], [1, 0.2, -0.4]])
    _, x = minimum_jerk_via_points(via, 1.0, N)
    return learn_dmp(TIMES, x, n_basis=20)


def _task_space(mode: str, n_basis: int, fingers: bool):
    _, pos = minimum_jerk_via_points(np.array([[0, 0, 0], [0.2, 0.1, 0.3]]), 1.0, N)
    q = slerp_minimum_jerk(
        np.array([1.0, 0, 0, 0]), np.array([np.cos(0.4), 0, np.sin(0.4), 0]), TIMES
    )
    fin = np.c_[np.linspace(0.0, 0.8, N), np.linspace(0.1, 0.0, N)] if fingers else None
    return learn_task_space_dmp(TIMES, pos, q, fin, orientation_mode=mode, n_basis=n_basis)


def test_transformation_system_without_a_goal_uses_the_learned_goal(dmp3):
    ts = TransformationSystem(dmp3)
    wired, unwired = ts.CreateDefaultContext(), ts.CreateDefaultContext()
    for ctx in (wired, unwired):
        ts.set_state(ctx, [0.1, 0.2, 0.3], [1.0 / dmp3.tau, -1.0 / dmp3.tau, 0.0])
        ts.get_phase_input_port().FixValue(ctx, [0.4])
    ts.get_goal_input_port().FixValue(wired, dmp3.goal)
    np.testing.assert_array_equal(
        ts.EvalTimeDerivatives(unwired).CopyToVector(), ts.EvalTimeDerivatives(wired).CopyToVector()
    )
    # another goal moves the derivatives: the fallback is the learned goal, not any goal
    ts.get_goal_input_port().FixValue(wired, dmp3.goal + 0.1)
    assert not np.array_equal(
        ts.EvalTimeDerivatives(unwired).CopyToVector(), ts.EvalTimeDerivatives(wired).CopyToVector()
    )


def test_discrete_dmp_system_without_a_goal_uses_the_learned_goal(dmp3):
    ds = DiscreteDmpSystem(dmp3, time_step=1e-3)
    wired, unwired = ds.CreateDefaultContext(), ds.CreateDefaultContext()
    ds.get_goal_input_port().FixValue(wired, dmp3.goal)
    for ctx in (wired, unwired):
        ds.set_start(ctx, dmp3.x0, np.array([0.5, -0.2, 0.1]))
    a = ds.EvalUniquePeriodicDiscreteUpdate(unwired).get_vector().CopyToVector()
    b = ds.EvalUniquePeriodicDiscreteUpdate(wired).get_vector().CopyToVector()
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(
        ds.get_acceleration_output_port().Eval(unwired),
        ds.get_acceleration_output_port().Eval(wired),
    )


def test_quaternion_systems_without_a_goal_use_the_learned_goal():
    dmp = _task_space("manifold", 20, fingers=False).orientation
    man = ManifoldQuaternionSystem(dmp, time_step=1e-3)
    wired, unwired = man.CreateDefaultContext(), man.CreateDefaultContext()
    man.get_goal_input_port().FixValue(wired, dmp.goal)
    wired_man = wired
    for ctx in (wired, unwired):
        man.get_phase_input_port().FixValue(ctx, [0.7])
    np.testing.assert_array_equal(
        man.EvalUniquePeriodicDiscreteUpdate(unwired).get_vector().CopyToVector(),
        man.EvalUniquePeriodicDiscreteUpdate(wired).get_vector().CopyToVector(),
    )
    comp = _task_space("component", 20, fingers=False).orientation
    sign = QuaternionGoalSign(comp)
    wired, unwired = sign.CreateDefaultContext(), sign.CreateDefaultContext()
    sign.GetInputPort("goal").FixValue(wired, -comp.goal)  # either sign: the learned one out
    out = sign.GetOutputPort("goal").Eval(unwired)
    np.testing.assert_array_equal(out, sign.GetOutputPort("goal").Eval(wired))
    np.testing.assert_array_equal(out, comp.goal)
    # A non-unit goal is refused by both forms (the component form passed 2 g and 0 on).
    for bad, norm in ((2.0 * comp.goal, "2.0"), (np.zeros(4), "0.0")):
        sign.GetInputPort("goal").FixValue(wired, bad)
        with pytest.raises(RepertoireError, match=f"not a unit quaternion: \\|g\\| = {norm}"):
            sign.GetOutputPort("goal").Eval(wired)
        man.get_goal_input_port().FixValue(wired_man, bad)
        with pytest.raises(RepertoireError, match=f"not a unit quaternion: \\|g\\| = {norm}"):
            man.EvalUniquePeriodicDiscreteUpdate(wired_man)


def test_goal_multiplexer_joins_connected_inputs_and_defaults():
    mux = GoalMultiplexer([np.array([1.0, 2.0, 3.0]), np.array([4.0]), np.array([5.0, 6.0])])
    ctx = mux.CreateDefaultContext()
    np.testing.assert_array_equal(mux.get_output_port().Eval(ctx), [1, 2, 3, 4, 5, 6])
    mux.get_input_port(1).FixValue(ctx, [-4.0])
    mux.get_input_port(2).FixValue(ctx, [7.0, 8.0])
    np.testing.assert_array_equal(mux.get_output_port().Eval(ctx), [1, 2, 3, -4, 7, 8])
    mux.get_input_port(0).FixValue(ctx, [0.0, np.inf, 0.0])
    with pytest.raises(RepertoireError, match="goal input contains NaN or inf"):
        mux.get_output_port().Eval(ctx)
    with pytest.raises(RepertoireError, match="one non-empty default per input"):
        GoalMultiplexer([np.zeros(3), np.zeros(0)])
    with pytest.raises(RepertoireError, match="one non-empty default per input"):
        GoalMultiplexer([])


def _run(dmp, wire: bool, time_step, seconds: float = 0.6, fused: "bool | None" = None) -> dict:
    builder = DiagramBuilder()
    sys = add_dmp(builder, dmp, name="dmp", time_step=time_step)
    if wire:
        goals = {"goal": getattr(dmp, "goal", None)}
        if not hasattr(dmp, "goal"):
            goals = {"goal_position": dmp.position.goal, "goal_orientation": dmp.orientation.goal}
            if dmp.fingers is not None:
                goals["goal_fingers"] = dmp.fingers.goal
        for port, value in goals.items():
            src = builder.AddSystem(ConstantVectorSource(np.asarray(value, float)))
            builder.Connect(src.get_output_port(), sys.GetInputPort(port))
    if fused is not None:
        assert (sys._fused is not None) == fused
    sim = Simulator(builder.Build())
    sim.AdvanceTo(seconds)
    ctx = sys.GetMyContextFromRoot(sim.get_context())
    names = [sys.get_output_port(i).get_name() for i in range(sys.num_output_ports())]
    return {n: sys.GetOutputPort(n).Eval(ctx).copy() for n in names}


@pytest.mark.parametrize("time_step", [1e-3, None])
def test_unwired_vector_dmp_system_reproduces_the_wired_learned_goal(dmp3, time_step):
    unwired, wired = _run(dmp3, False, time_step), _run(dmp3, True, time_step)
    for name, value in wired.items():
        np.testing.assert_array_equal(unwired[name], value, err_msg=name)


@pytest.mark.parametrize(
    "mode, n_basis, fingers, time_step, fused",
    [
        ("component", 20, True, 1e-3, True),  # one fused 10-D system behind a GoalMultiplexer
        ("manifold", 20, True, 1e-3, True),
        ("component", 20, False, None, False),  # continuous parts, one system each
    ],
)
def test_unwired_task_space_dmp_system_reproduces_the_wired_learned_goals(
    mode, n_basis, fingers, time_step, fused
):
    dmp = _task_space(mode, n_basis, fingers)
    unwired = _run(dmp, False, time_step, fused=fused)
    wired = _run(dmp, True, time_step, fused=fused)
    assert set(unwired) == set(wired)
    for name, value in wired.items():
        np.testing.assert_array_equal(unwired[name], value, err_msg=name)
    # the movement went somewhere: not a system that ignores its goals altogether
    assert np.linalg.norm(unwired["position"] - dmp.position.x0) > 0.05
