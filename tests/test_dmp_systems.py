"""DMP LeafSystems and diagrams: FixValue expectations, Drake vs NumPy, quaternions."""

import dataclasses
import tracemalloc

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, VectorLogSink
from repertoire.planning.dmp_demos import slerp_minimum_jerk
from repertoire.planning.dmp_discrete import CHUNK_ROWS, DiscreteDmpTables
from repertoire.planning.dmp_learn import learn_dmp, learn_quaternion_dmp, learn_task_space_dmp
from repertoire.planning.dmp_math import (
    forcing_term,
    minimum_jerk_via_points,
    obstacle_coupling,
    transformation_derivatives,
)
from repertoire.planning.dmp_quaternion import (
    manifold_step,
    quat_exp,
    quat_log_error,
    quat_multiply,
    quaternion_rollout,
)
from repertoire.systems.dmp import (
    CanonicalSystem,
    ManifoldQuaternionSystem,
    ObstacleCoupling,
    QuaternionNormalizer,
    TransformationSystem,
)
from repertoire.systems.dmp_compose import DmpSystem, add_dmp
from repertoire.systems.dmp_discrete import DiscreteDmpSystem

from repertoire.errors import RepertoireError


@pytest.fixture(scope="module")
def dmp3():
    t = np.linspace(0, 1.0, 400)
    _, x = minimum_jerk_via_points(np.array([[0, 0, 0], [0.3, 0.5, 0.2], [1, 0.2, -0.4]]), 1.0, 400)
    return learn_dmp(t, x, n_basis=20)


def test_canonical_system_derivative_and_hold():
    cs = CanonicalSystem(tau=2.0, alpha=3.0)
    ctx = cs.CreateDefaultContext()
    cs.set_phase(ctx, 0.4)
    assert cs.EvalTimeDerivatives(ctx).CopyToVector()[0] == pytest.approx(-3.0 * 0.4 / 2.0)
    assert cs.get_phase_output_port().Eval(ctx)[0] == 0.4
    cs.set_start_time(ctx, 1.0)
    assert cs.EvalTimeDerivatives(ctx).CopyToVector()[0] == 0.0
    scaled = CanonicalSystem(tau=2.0, alpha=3.0, time_scaling_input=True)
    c2 = scaled.CreateDefaultContext()
    # Unconnected: the tau parameter, as in TransformationSystem (was Drake's "not connected").
    assert scaled.EvalTimeDerivatives(c2).CopyToVector()[0] == -3.0 * 1.0 / 2.0
    scaled.get_tau_input_port().FixValue(c2, [0.5])
    assert scaled.EvalTimeDerivatives(c2).CopyToVector()[0] == pytest.approx(-6.0)
    scaled.get_tau_input_port().FixValue(c2, [0.0])
    with pytest.raises(RepertoireError, match="tau must be a finite number > 0, got 0.0"):
        scaled.EvalTimeDerivatives(c2)
    with pytest.raises(RepertoireError, match="tau must be a finite number > 0"):
        CanonicalSystem(tau=0.0)


def test_canonical_phase_follows_a_tau_changed_during_the_run():
    from pydrake.systems.analysis import Simulator

    # theta(T) = exp(-alpha (t1 / tau1 + (T - t1) / tau2)) when tau jumps from tau1 to tau2
    cs = CanonicalSystem(tau=1.0, alpha=2.0, time_scaling_input=True)
    sim = Simulator(cs)
    ctx = sim.get_mutable_context()
    sim.get_mutable_integrator().set_target_accuracy(1e-12)
    cs.get_tau_input_port().FixValue(ctx, [0.8])
    sim.AdvanceTo(0.3)
    cs.get_tau_input_port().FixValue(ctx, [2.5])
    sim.AdvanceTo(1.7)
    theta = cs.get_phase_output_port().Eval(ctx)[0]
    assert theta == pytest.approx(np.exp(-2.0 * (0.3 / 0.8 + 1.4 / 2.5)), rel=1e-9)


@pytest.mark.parametrize("formulation", ["new", "old"])
def test_transformation_system_derivatives_equal_the_math(dmp3, formulation):
    import dataclasses

    dmp = dataclasses.replace(dmp3, formulation=formulation)
    ts = TransformationSystem(dmp, coupling_input=True)
    ctx = ts.CreateDefaultContext()
    x0 = np.array([0.25, -0.5, 2.0])  # the state is the displacement x - x0
    x = np.array([0.125, 0.25, 0.375])
    xd = np.array([-0.5, 0.4, 1.0])
    ts.set_start(ctx, x0, xd)
    ts.set_state(ctx, x, xd)
    np.testing.assert_array_equal(ctx.get_continuous_state_vector().CopyToVector()[:3], x - x0)
    goal, p, theta = np.array([0.9, 0.1, -0.2]), np.array([1.0, -2.0, 3.0]), 0.37
    ts.get_phase_input_port().FixValue(ctx, [theta])
    ts.get_goal_input_port().FixValue(ctx, goal)
    ts.get_coupling_input_port().FixValue(ctx, p)
    f = forcing_term(theta, dmp.weights, dmp.centres, dmp.widths)
    # the equations in the displacement from x0, exactly as the system evaluates them
    exp_xd, exp_vd = transformation_derivatives(
        x - x0,
        dmp.tau * xd,
        theta,
        goal - x0,
        np.zeros(3),
        f,
        dmp.K,
        dmp.D,
        dmp.tau,
        formulation,
        p,
    )
    d = ts.EvalTimeDerivatives(ctx).CopyToVector()
    np.testing.assert_array_equal(d, np.r_[exp_xd, exp_vd])
    # ... which are the absolute-position equations up to rounding
    abs_xd, abs_vd = transformation_derivatives(
        x, dmp.tau * xd, theta, goal, x0, f, dmp.K, dmp.D, dmp.tau, formulation, p
    )
    np.testing.assert_allclose(d, np.r_[abs_xd, abs_vd], rtol=1e-13, atol=1e-12)
    np.testing.assert_array_equal(ts.get_position_output_port().Eval(ctx), x0 + (x - x0))
    np.testing.assert_allclose(ts.get_velocity_output_port().Eval(ctx), xd, rtol=1e-15)
    np.testing.assert_allclose(ts.get_acceleration_output_port().Eval(ctx), exp_vd / dmp.tau)


def test_goal_port_bad_values(dmp3):
    ts = TransformationSystem(dmp3)
    ctx = ts.CreateDefaultContext()
    with pytest.raises(RuntimeError, match="size=3 for input port 'goal'.*size=4"):
        ts.get_goal_input_port().FixValue(ctx, np.ones(4))
    ts.get_phase_input_port().FixValue(ctx, [1.0])
    ts.get_goal_input_port().FixValue(ctx, [np.nan, 0, 0])
    with pytest.raises(RepertoireError, match="goal input contains NaN"):
        ts.EvalTimeDerivatives(ctx)
    with pytest.raises(RepertoireError, match="x0 must have 3 entries, got 2"):
        ts.set_start(ctx, np.zeros(2))
    builder = DiagramBuilder()
    sys = add_dmp(builder, dmp3)
    src = builder.AddSystem(ConstantVectorSource(np.zeros(4)))
    # Drake refuses wrong sizes itself, with a message naming the port and both sizes
    with pytest.raises(
        RuntimeError, match=r"Mismatched vector sizes.*\(size 4\) to input port goal.*\(size 3\)"
    ):
        builder.Connect(src.get_output_port(), sys.GetInputPort("goal"))
    with pytest.raises(RuntimeError, match="size=3 for input port 'goal'.*size=4"):
        sys.GetInputPort("goal").FixValue(sys.CreateDefaultContext(), np.ones(4))


def _simulate(builder_fn, duration):
    builder = DiagramBuilder()
    out = builder_fn(builder)
    diagram = builder.Build()
    sim = Simulator(diagram)
    return sim, out


def test_drake_rollouts_match_numpy(dmp3):
    goal = np.array([0.7, -0.3, 0.5])
    ref = dmp3.rollout(goal=goal, dt=1e-3, n_steps=1000)

    def continuous(builder):
        cs = builder.AddSystem(CanonicalSystem(dmp3.tau, dmp3.alpha))
        ts = builder.AddSystem(TransformationSystem(dmp3))
        src = builder.AddSystem(ConstantVectorSource(goal))
        builder.Connect(cs.get_phase_output_port(), ts.get_phase_input_port())
        builder.Connect(src.get_output_port(), ts.get_goal_input_port())
        return ts

    sim, ts = _simulate(continuous, 1.0)
    sim.get_mutable_integrator().set_target_accuracy(1e-9)
    sim.AdvanceTo(1.0)
    x = ts.get_position_output_port().Eval(ts.GetMyContextFromRoot(sim.get_context()))
    assert np.abs(x - ref.x[-1]).max() < 1e-6

    def discrete(builder):
        ds = builder.AddSystem(DiscreteDmpSystem(dmp3, time_step=1e-3))
        src = builder.AddSystem(ConstantVectorSource(goal))
        builder.Connect(src.get_output_port(), ds.get_goal_input_port())
        log = builder.AddSystem(VectorLogSink(3, publish_period=1e-3))
        builder.Connect(ds.get_position_output_port(), log.get_input_port())
        return ds, log

    sim, (ds, log) = _simulate(discrete, 1.0)
    sim.AdvanceTo(1.0)
    data = log.FindLog(sim.get_context()).data().T
    assert np.abs(data - ref.x).max() < 1e-10
    dctx = ds.GetMyContextFromRoot(sim.get_context())
    assert ds.get_phase_output_port().Eval(dctx)[0] == pytest.approx(ref.theta[-1])
    np.testing.assert_array_equal(ds.get_start(dctx), dmp3.x0)
    fresh = ds.CreateDefaultContext()
    ds.set_start(fresh, [0.1, 0.2, 0.3])
    np.testing.assert_array_equal(ds.get_start(fresh), [0.1, 0.2, 0.3])
    np.testing.assert_allclose(ds.get_velocity_output_port().Eval(dctx), ref.xd[-1], atol=1e-9)
    np.testing.assert_allclose(ds.get_acceleration_output_port().Eval(dctx), ref.xdd[-1], atol=1e-8)


@pytest.mark.parametrize("formulation", ["new", "old"])
def test_discrete_tables_across_blocks_match_the_numpy_rollout(dmp3, formulation):
    # 5000 steps cross two block boundaries (CHUNK_ROWS = 2048); the last block ends the table.
    dmp = dataclasses.replace(dmp3, tau=0.5, formulation=formulation)
    goal = np.array([0.7, -0.3, 0.5])
    tab = DiscreteDmpTables(dmp, 1e-4)
    assert tab.last == int(np.ceil(np.log(1e12) / (dmp.alpha * 1e-4 / 0.5))) + 1
    n_steps = 2 * CHUNK_ROWS + 904
    ref = dmp.rollout(goal=goal, dt=1e-4, n_steps=n_steps)
    z = np.concatenate([dmp.x0, np.zeros(3)])
    xs = [dmp.x0]
    for k in range(n_steps):
        z = tab.step(z, k, goal, dmp.x0)
        xs.append(z[:3])
    assert np.abs(np.array(xs) - ref.x).max() < 1e-10
    for k in (0, CHUNK_ROWS - 1, CHUNK_ROWS, 2 * CHUNK_ROWS + 1, tab.last - 1):
        theta, f = tab.phase_and_f(k)
        assert theta == np.exp(-(dmp.alpha * 1e-4 / 0.5) * k)
        np.testing.assert_allclose(
            f, forcing_term(theta, dmp.weights, dmp.centres, dmp.widths), rtol=1e-12, atol=1e-12
        )
    theta, f = tab.phase_and_f(tab.last)
    assert theta == 0.0 and not f.any()


def test_discrete_tables_memory_does_not_grow_with_tau_over_dt(dmp3):
    # A whole table for tau = 1000 s at dt = 1e-4 s would be 6e7 rows (~10 GiB kept).
    dmp = dataclasses.replace(dmp3, tau=1000.0)
    tracemalloc.start()
    try:
        tab = DiscreteDmpTables(dmp, 1e-4)
        tab.phase_and_f(tab.last - 1)
        z = tab.step(np.zeros(6), tab.last - 1, np.ones(3), np.zeros(3))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert tab.last == int(np.ceil(np.log(1e12) / (dmp.alpha * 1e-4 / 1000.0))) + 1 > 10**7
    assert np.isfinite(z).all()
    assert peak < 8 * 1024**2


def test_discrete_dmp_with_the_obstacle_on_its_goal_reaches_the_goal(dmp3):
    # Eq. 10 has no distance term: an obstacle on the goal gives no NaN, and p _|_ v does no work.
    builder = DiagramBuilder()
    sys = add_dmp(builder, dmp3, time_step=1e-3, obstacle_avoidance=True)
    for port in ("goal", "obstacle"):
        src = builder.AddSystem(ConstantVectorSource(dmp3.goal))
        builder.Connect(src.get_output_port(), sys.GetInputPort(port))
    sim = Simulator(builder.Build())
    sim.AdvanceTo(5.0)
    x = sys.GetOutputPort("position").Eval(sys.GetMyContextFromRoot(sim.get_context()))
    assert np.linalg.norm(x - dmp3.goal) < 1e-9


def _quat_demo():
    t = np.linspace(0, 1, 300)
    q = slerp_minimum_jerk(
        quat_exp(np.array([0.1, 0.0, 0.2])), quat_exp(np.array([-0.4, 0.5, 0.3])), t
    )
    return t, q


def test_manifold_quaternion_system_unit_norm_and_matches_numpy():
    t, q = _quat_demo()
    dmp = learn_quaternion_dmp(t, q, n_basis=15)
    goal = quat_multiply(quat_exp(np.array([0.3, 0.0, 0.0])), q[-1])

    def build(builder):
        cs = builder.AddSystem(CanonicalSystem(dmp.tau, dmp.alpha))
        ms = builder.AddSystem(ManifoldQuaternionSystem(dmp, time_step=1e-3))
        src = builder.AddSystem(ConstantVectorSource(goal))
        builder.Connect(cs.get_phase_output_port(), ms.get_phase_input_port())
        builder.Connect(src.get_output_port(), ms.get_goal_input_port())
        log = builder.AddSystem(VectorLogSink(4, publish_period=1e-3))
        builder.Connect(ms.get_orientation_output_port(), log.get_input_port())
        return ms, log

    sim, (ms, log) = _simulate(build, 1.5)
    sim.get_mutable_integrator().set_target_accuracy(1e-10)
    sim.AdvanceTo(1.5)
    Q = log.FindLog(sim.get_context()).data().T
    assert np.abs(np.linalg.norm(Q, axis=1) - 1).max() < 1e-12
    _, Qn, _ = quaternion_rollout(
        dmp.weights,
        dmp.centres,
        dmp.widths,
        dmp.K,
        dmp.D,
        dmp.alpha,
        dmp.tau,
        dmp.q0,
        goal,
        n_steps=1500,
    )
    bad = ms.CreateDefaultContext()
    ms.get_phase_input_port().FixValue(bad, [1.0])
    ms.get_goal_input_port().FixValue(bad, 1.1 * goal)
    with pytest.raises(RepertoireError, match="not a unit quaternion: \\|g\\| = 1.1"):
        ms.EvalUniquePeriodicDiscreteUpdate(bad)
    with pytest.raises(RuntimeError, match="size=4 for input port 'goal'.*size=3"):
        ms.get_goal_input_port().FixValue(bad, goal[:3])  # Drake's own clear refusal
    # Same discrete update; Drake's phase comes from the integrated canonical system.
    assert np.abs(Q[-1] - Qn[-1]).max() < 1e-7


def test_manifold_quaternion_system_step_uses_the_context_tau():
    # One discrete update with the tau parameter doubled in the context is manifold_step
    # with the phase at the step's end theta exp(-alpha dt / tau) of that tau (it used the
    # constructor's tau: 9e-4 rad off the NumPy rollout after 1 s at tau = 2 s).
    t, q = _quat_demo()
    dmp = learn_quaternion_dmp(t, q, n_basis=15)
    ms = ManifoldQuaternionSystem(dmp, time_step=1e-3)
    ctx = ms.CreateDefaultContext()
    tau, theta = 2.0 * dmp.tau, 0.6
    ctx.get_mutable_numeric_parameter(3).SetFromVector([dmp.K, dmp.D, tau])  # [K, D, tau]
    ms.get_phase_input_port().FixValue(ctx, [theta])
    ms.get_goal_input_port().FixValue(ctx, dmp.goal)
    eta = np.array([0.2, -0.1, 0.3])
    ctx.SetDiscreteState(np.r_[dmp.q0, eta])
    got = ms.EvalUniquePeriodicDiscreteUpdate(ctx).get_vector().CopyToVector()
    theta_next = theta * np.exp(-dmp.alpha * 1e-3 / tau)
    f = forcing_term(np.array([theta, theta_next]), dmp.weights, dmp.centres, dmp.widths)
    e0 = quat_log_error(dmp.goal, dmp.q0)
    a = dmp.K * (quat_log_error(dmp.goal, dmp.q0) - e0 * theta + f[0]) / tau
    eta1, q1, _ = manifold_step(
        dmp.q0, eta, a, dmp.goal, e0, theta_next, f[1], dmp.K, dmp.D, tau, 1e-3
    )
    np.testing.assert_allclose(got, np.r_[q1, eta1], rtol=0, atol=1e-15)


def test_quaternion_normalizer_and_obstacle_coupling_systems():
    qn = QuaternionNormalizer()
    ctx = qn.CreateDefaultContext()
    q = np.array([1.0, 0.2, -0.1, 0.3]) * 1.1
    qn.get_quaternion_input_port().FixValue(ctx, q)
    qn.get_quaternion_rate_input_port().FixValue(ctx, np.zeros(4))
    np.testing.assert_allclose(qn.get_orientation_output_port().Eval(ctx), q / np.linalg.norm(q))
    assert qn.GetOutputPort("norm_error").Eval(ctx)[0] == pytest.approx(np.linalg.norm(q) - 1)
    np.testing.assert_array_equal(qn.get_angular_velocity_output_port().Eval(ctx), np.zeros(3))
    oc = ObstacleCoupling(gamma=500.0, beta=2.0)
    c = oc.CreateDefaultContext()
    x, v, o = np.array([0.1, 0, 0]), np.array([1.0, 0.5, 0]), np.array([1.0, 0.6, 0.1])
    for name, val in (("position", x), ("velocity", v), ("obstacle", o)):
        oc.GetInputPort(name).FixValue(c, val)
    np.testing.assert_array_equal(
        oc.GetOutputPort("coupling").Eval(c), obstacle_coupling(x, v, o, 500.0, 2.0)
    )


@pytest.mark.parametrize("mode", ["manifold", "component"])
def test_task_space_dmp_system_reaches_goals(mode, grasp_demo):
    demo = grasp_demo
    dmp = learn_task_space_dmp(
        demo.t, demo.position, demo.orientation, demo.fingers, orientation_mode=mode, n_basis=20
    )
    goal_p = np.array([0.5, -0.1, 0.15])
    goal_q = quat_multiply(quat_exp(np.array([0, 0, 0.2])), demo.orientation[-1])
    builder = DiagramBuilder()
    sys = add_dmp(builder, dmp, name="grasp", obstacle_avoidance=True)
    assert isinstance(sys, DmpSystem) and sys.get_name() == "grasp"
    for port, val in (
        ("goal_position", goal_p),
        ("goal_orientation", goal_q),
        ("goal_fingers", [0.3] * 3),
        ("obstacle", [5.0, 5.0, 5.0]),
    ):
        src = builder.AddSystem(ConstantVectorSource(np.asarray(val, float)))
        builder.Connect(src.get_output_port(), sys.GetInputPort(port))
    sim = Simulator(builder.Build())
    ctx = sys.GetMyMutableContextFromRoot(sim.get_mutable_context())
    sys.set_start(
        ctx, position=demo.position[0], orientation=demo.orientation[0], fingers=demo.fingers[0]
    )
    sys.set_start_time(ctx, 0.2)
    sim.AdvanceTo(0.15)
    np.testing.assert_allclose(sys.GetOutputPort("position").Eval(ctx), demo.position[0])
    sim.AdvanceTo(2.7)
    assert np.abs(sys.GetOutputPort("position").Eval(ctx) - goal_p).max() < 1e-3
    q = sys.GetOutputPort("orientation").Eval(ctx)
    assert abs(np.linalg.norm(q) - 1) < 1e-12
    assert min(np.abs(q - goal_q).max(), np.abs(q + goal_q).max()) < 1e-3
    np.testing.assert_allclose(sys.GetOutputPort("fingers").Eval(ctx), 0.3, atol=1e-3)
    with pytest.raises(RepertoireError, match="DmpSystem needs DmpParameters or TaskSpaceDmp"):
        DmpSystem("not a dmp")


def test_continuous_dmp_system_with_obstacle_input_matches_euler_reference(dmp3):
    obstacle = np.array([0.5, 0.4, 0.0])
    builder = DiagramBuilder()
    sys = add_dmp(builder, dmp3, time_step=None, obstacle_avoidance=True, gamma=300.0, beta=2.0)
    for port, val in (("goal", dmp3.goal), ("obstacle", obstacle)):
        src = builder.AddSystem(ConstantVectorSource(val))
        builder.Connect(src.get_output_port(), sys.GetInputPort(port))
    sim = Simulator(builder.Build())
    sim.get_mutable_integrator().set_target_accuracy(1e-8)
    sim.AdvanceTo(1.0)
    x = sys.GetOutputPort("position").Eval(sys.GetMyContextFromRoot(sim.get_context()))
    ref = dmp3.rollout(
        dt=1e-4,
        n_steps=10000,
        method="euler",
        coupling=lambda p, v: obstacle_coupling(p, v, obstacle, 300.0, 2.0),
    )
    plain = dmp3.rollout(dt=1e-3, n_steps=1000)
    assert np.abs(x - ref.x[-1]).max() < 2e-3  # Euler at 0.1 ms vs error-controlled RK3
    assert np.abs(x - plain.x[-1]).max() > 1e-2  # the coupling changed the path
    with pytest.raises(RepertoireError, match="obstacle avoidance needs a 2-D or 3-D DMP, got 4-D"):
        DmpSystem(
            learn_dmp(
                np.linspace(0, 1, 50), np.zeros((50, 4)) + np.linspace(0, 1, 50)[:, None], n_basis=5
            ),
            obstacle_avoidance=True,
        )


def test_online_time_scaling_input(dmp3):
    ts = TransformationSystem(dmp3, time_scaling_input=True)
    ctx = ts.CreateDefaultContext()
    ts.get_phase_input_port().FixValue(ctx, [0.5])
    ts.get_goal_input_port().FixValue(ctx, dmp3.goal)
    ts.get_tau_input_port().FixValue(ctx, [2.0 * dmp3.tau])
    # displacement from x0 zero, v = (0.3, -0.2, 0.1)
    ctx.get_mutable_continuous_state_vector().SetFromVector(np.r_[np.zeros(3), 0.3, -0.2, 0.1])
    f = forcing_term(0.5, dmp3.weights, dmp3.centres, dmp3.widths)
    exp_xd, exp_vd = transformation_derivatives(
        dmp3.x0,
        np.array([0.3, -0.2, 0.1]),
        0.5,
        dmp3.goal,
        dmp3.x0,
        f,
        dmp3.K,
        dmp3.D,
        2.0 * dmp3.tau,
    )
    np.testing.assert_allclose(ts.EvalTimeDerivatives(ctx).CopyToVector(), np.r_[exp_xd, exp_vd])
    for bad in (-1.0, 0.0, np.nan, np.inf):  # inf used to freeze the movement silently
        ts.get_tau_input_port().FixValue(ctx, [bad])
        with pytest.raises(RepertoireError, match=f"tau must be a finite number > 0, got {bad}"):
            ts.EvalTimeDerivatives(ctx)
    cs = CanonicalSystem(dmp3.tau, time_scaling_input=True)
    cs_ctx = cs.CreateDefaultContext()
    cs.get_tau_input_port().FixValue(cs_ctx, [np.inf])
    with pytest.raises(RepertoireError, match="tau must be a finite number > 0, got inf"):
        cs.EvalTimeDerivatives(cs_ctx)


@pytest.mark.parametrize("time_step", [1e-3, None])
def test_dmp_system_takes_the_obstacle_velocity(dmp3, time_step):
    # eq. 10's angle is taken to the velocity relative to the obstacle: DmpSystem exports
    # the coupling's optional obstacle_velocity input (unconnected: a static obstacle)
    sys = DmpSystem(dmp3, time_step=time_step, obstacle_avoidance=True, gamma=300.0, beta=2.0)
    ctx = sys.CreateDefaultContext()
    xd0 = np.array([0.4, -0.2, 0.3])
    sys.set_start(ctx, position=dmp3.x0, velocity=xd0)
    o, vo = dmp3.x0 + np.array([0.1, 0.05, 0.0]), np.array([0.0, 0.5, -0.2])
    sys.GetInputPort("obstacle").FixValue(ctx, o)
    coupling = sys.obstacle_coupling.GetOutputPort("coupling")
    sub = sys.obstacle_coupling.GetMyContextFromRoot(ctx)
    x, v = sys.GetOutputPort("position").Eval(ctx), sys.GetOutputPort("velocity").Eval(ctx)
    np.testing.assert_allclose(v, xd0, rtol=1e-12)
    static = coupling.Eval(sub).copy()
    np.testing.assert_array_equal(static, obstacle_coupling(x, v, o, 300.0, 2.0))
    sys.GetInputPort("obstacle_velocity").FixValue(ctx, vo)
    moving = coupling.Eval(sub)
    np.testing.assert_array_equal(moving, obstacle_coupling(x, v, o, 300.0, 2.0, vo))
    assert np.abs(moving - static).max() > 1.0  # the relative velocity changes the push


def test_fused_task_space_dmp_system_takes_the_obstacle_velocity():
    t = np.linspace(0.0, 1.0, 300)
    _, pos = minimum_jerk_via_points(np.array([[0, 0, 0], [0.2, 0.1, 0.3]]), 1.0, 300)
    q = slerp_minimum_jerk(np.array([1.0, 0, 0, 0]), quat_exp(np.array([0.0, 0.3, 0.0])), t)
    dmp = learn_task_space_dmp(t, pos, q, orientation_mode="component", n_basis=20)
    sys = DmpSystem(dmp, obstacle_avoidance=True)
    assert sys._fused is not None  # the 10-D fused path (its own coupling wiring)
    ctx = sys.CreateDefaultContext()
    sys.set_start(ctx, position=pos[0], velocity=[0.3, 0.1, -0.2], orientation=q[0])
    o, vo = pos[0] + np.array([0.05, 0.1, 0.0]), np.array([-0.3, 0.0, 0.4])
    sys.GetInputPort("obstacle").FixValue(ctx, o)
    sys.GetInputPort("obstacle_velocity").FixValue(ctx, vo)
    x, v = sys.GetOutputPort("position").Eval(ctx), sys.GetOutputPort("velocity").Eval(ctx)
    sub = sys.obstacle_coupling.GetMyContextFromRoot(ctx)
    p = sys.obstacle_coupling.GetOutputPort("coupling").Eval(sub)
    np.testing.assert_array_equal(p, obstacle_coupling(x, v, o, 1000.0, 20.0 / np.pi, vo))
    assert np.abs(p).max() > 0.1  # a real push (0.64 here: the start velocity is not zero)


def test_every_vector_dmp_variant_reports_zero_acceleration_while_held():
    """Before its start time the state is held, so the acceleration output is 0 in all four.

    The discrete systems reported the equations' acceleration at the held start instead
    (K f(1) / tau^2: the demonstration's initial acceleration), the continuous ones 0. At
    the onset every variant gives the NumPy rollout's first acceleration.
    """
    from repertoire.systems.dmp_sequencer import DmpSequencer

    t = np.linspace(0, 1, 201)
    dmp = learn_dmp(t, np.c_[t**2, np.sin(2 * t)], n_basis=20)  # starts accelerating
    onset = dmp.rollout(dt=1e-3).xdd[0]
    assert np.abs(onset).max() > 0.1
    for time_step in (1e-3, None):
        system = DmpSystem(dmp, time_step=time_step)
        sequencer = DmpSequencer([dmp], [0.5], goals=[dmp.goal], time_step=time_step)
        ctx, seq_ctx = system.CreateDefaultContext(), sequencer.CreateDefaultContext()
        system.GetInputPort("goal").FixValue(ctx, dmp.goal)
        system.set_start_time(ctx, 0.5)
        for held, expected in ((0.0, 0.0), (0.3, 0.0), (0.5, onset)):
            ctx.SetTime(held)
            seq_ctx.SetTime(held)
            for out in (
                system.GetOutputPort("acceleration").Eval(ctx),
                sequencer.GetOutputPort("acceleration").Eval(seq_ctx),
            ):
                np.testing.assert_allclose(out, expected, rtol=1e-9, atol=1e-12)
    # discrete: the onset is the start time's rounded step (the update's rule), 0.5 here
    sequencer = DmpSequencer([dmp], [0.5004], goals=[dmp.goal], time_step=1e-3)
    seq_ctx = sequencer.CreateDefaultContext()
    for time, expected in ((0.499, 0.0), (0.5, onset)):
        seq_ctx.SetTime(time)
        out = sequencer.GetOutputPort("acceleration").Eval(seq_ctx)
        np.testing.assert_allclose(out, expected, rtol=1e-12, atol=1e-12)


def _all_state(context) -> np.ndarray:
    """Continuous and discrete state of a diagram context, one vector."""
    parts = [context.get_continuous_state_vector().CopyToVector()]
    parts += [
        context.get_discrete_state(i).CopyToVector()
        for i in range(context.num_discrete_state_groups())
    ]
    return np.concatenate(parts)


@pytest.mark.parametrize("time_step", [1e-3, None])
@pytest.mark.parametrize("kind", ["vector", "component", "manifold"])
def test_set_start_after_a_run_restarts_every_variant_as_a_fresh_context(kind, time_step):
    """DmpSystem.set_start restarts the whole DMP: phase 1, every part at its start.

    After 0.6 s of a 1 s movement the continuous variants kept the decayed phase (0.063:
    the restarted movement ran with its forcing term nearly off), and parts not given ran
    on; the discrete fused variant restarted. Now the state equals a fresh context's.
    """
    t = np.linspace(0, 1, 201)
    s = 10 * t**3 - 15 * t**4 + 6 * t**5
    if kind == "vector":
        dmp = learn_dmp(t, np.c_[s, 0.3 * np.sin(np.pi * t)], n_basis=15)
        start = {"position": np.array([0.1, 0.0])}
    else:
        q = np.c_[np.cos(0.6 * s), 0 * s, 0 * s, np.sin(0.6 * s)]
        dmp = learn_task_space_dmp(
            t, np.c_[s, 0.5 * s, 0 * s], q, np.c_[s], orientation_mode=kind, n_basis=15
        )
        start = {"position": np.array([0.1, 0.0, 0.2])}
    system = DmpSystem(dmp, time_step=time_step)
    sim = Simulator(system)
    sim.AdvanceTo(0.6)
    used = sim.get_mutable_context()
    fresh = system.CreateDefaultContext()
    for context in (used, fresh):
        system.set_start(context, **start)
    assert system.GetOutputPort("phase").Eval(used)[0] == 1.0
    np.testing.assert_array_equal(_all_state(used), _all_state(fresh))
