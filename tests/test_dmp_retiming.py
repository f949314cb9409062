"""Re-timing DMPs (``with_tau``) and eq. 10 with the paper's ``v = tau dx/dt`` on the arm's
multi-point coupling: the same path in space at any duration (Pastor et al. eq. 4, 6-10)."""

import dataclasses

import numpy as np
import pytest
from pydrake.systems.analysis import ResetIntegratorFromFlags, Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, VectorLogSink
from repertoire.planning.dmp import DmpParameters, QuaternionDmpParameters, TaskSpaceDmp
from repertoire.planning.dmp_demos import sines_in_motion
from repertoire.planning.dmp_learn import learn_dmp
from repertoire.planning.dmp_math import basis_centres, basis_widths, obstacle_coupling
from repertoire.systems.dmp_sequencer import DmpSequencer
from repertoire.systems.obstacle_coupling import (
    MultiPointObstacleCoupling,
    multi_point_obstacle_coupling,
)

from repertoire.errors import RepertoireError

ALPHA = 4.6


def _dmp(n: int, *, seed: int, tau: float, formulation: str = "new", v0=None) -> DmpParameters:
    """A DMP with seeded weights (no learning: the test is about the equations)."""
    rng = np.random.default_rng(seed)
    c = basis_centres(12, ALPHA)
    K = np.full(n, 100.0)
    return DmpParameters(
        rng.normal(scale=0.3, size=(n, 12)),
        c,
        basis_widths(c, ALPHA),
        K,
        2.0 * np.sqrt(K),
        ALPHA,
        tau,
        rng.normal(size=n),
        rng.normal(size=n),
        formulation,
        v0=v0,
    )


def test_with_tau_of_a_spring_is_its_closed_form():
    # f = 0, old formulation: tau v' = K (g - x) - D v, D = 2 sqrt(K) -> critically damped
    # with omega = sqrt(K) / tau: x(t) = g + (x0 - g)(1 + omega t) exp(-omega t). The exact
    # (first-order-hold) rollout is exact for a constant input.
    base = _dmp(2, seed=1, tau=1.0, formulation="old")
    base = dataclasses.replace(base, weights=np.zeros((2, 12)))
    for tau in (0.25, 1.0, 3.0):
        r = base.with_tau(tau).rollout(dt=tau / 500)
        w = np.sqrt(base.K[0]) / tau
        e = (1.0 + w * r.t) * np.exp(-w * r.t)
        expected = base.goal + (base.x0 - base.goal) * e[:, None]
        np.testing.assert_allclose(r.x, expected, rtol=0, atol=1e-11)  # round-off, 500 steps


@pytest.mark.parametrize("formulation", ["new", "old"])
def test_with_tau_keeps_the_path_and_scales_time_and_v0(formulation):
    v0 = np.array([0.7, -1.3, 0.2])
    dmp = _dmp(3, seed=7, tau=1.2, formulation=formulation, v0=v0)
    ref = dmp.rollout(dt=1e-3)
    for factor in (0.5, 2.0, 3.0):
        tau = factor * dmp.tau
        re = dmp.with_tau(tau)
        assert re.tau == tau and re.v0 == pytest.approx(v0 / factor, rel=1e-15)
        np.testing.assert_array_equal(re.weights, dmp.weights)
        # the same as rolling the original out with that tau, bit for bit
        np.testing.assert_array_equal(re.rollout(dt=1e-3).x, dmp.rollout(tau=tau, dt=1e-3).x)
        # at the same phase t / tau (steps scaled with tau) the same path
        r = re.rollout(dt=factor * 1e-3)
        np.testing.assert_allclose(r.x, ref.x, rtol=0, atol=1e-12)
        np.testing.assert_allclose(r.xd * factor, ref.xd, rtol=0, atol=1e-10)
        np.testing.assert_allclose(r.t, factor * ref.t, rtol=1e-15)


def test_with_tau_on_a_learned_demonstration_in_motion():
    t, x, xd = sines_in_motion(31, n_dims=2, duration=0.8, n=401)
    dmp = learn_dmp(t, x, n_basis=30)
    assert np.linalg.norm(dmp.v0) > 0.5  # it starts in motion
    slow = dmp.with_tau(2.5 * dmp.tau)
    r, ref = slow.rollout(dt=2.5 * 2e-3), dmp.rollout(dt=2e-3)
    np.testing.assert_allclose(r.x, ref.x, rtol=0, atol=1e-11)
    assert r.xd[0] == pytest.approx(dmp.v0 / 2.5, rel=1e-14)  # dx/dt at the start


@pytest.mark.parametrize("mode", ["component", "manifold"])
def test_quaternion_and_task_space_with_tau(mode):
    rng = np.random.default_rng(3)
    c = basis_centres(10, ALPHA)
    q0 = rng.normal(size=4)
    g = rng.normal(size=4)
    q0, g = q0 / np.linalg.norm(q0), g / np.linalg.norm(g)
    g = g if g @ q0 > 0 else -g
    omega0 = np.array([0.4, -0.2, 0.9])
    rows = 4 if mode == "component" else 3
    ori = QuaternionDmpParameters(
        rng.normal(scale=0.1, size=(rows, 10)), c, basis_widths(c, ALPHA), 100.0, 20.0,
        ALPHA, 1.0, q0, g, mode, omega0,
    )  # fmt: skip
    slow = ori.with_tau(2.0)
    assert slow.tau == 2.0 and np.array_equal(slow.omega0, omega0 * 0.5)
    _, q_ref, _ = ori.rollout(dt=1e-3)
    t, q, _ = slow.rollout(dt=2e-3)
    np.testing.assert_allclose(q, q_ref, rtol=0, atol=1e-12)
    assert t[-1] == pytest.approx(2.0)
    pos = _dmp(3, seed=5, tau=1.0, v0=[0.1, 0.2, 0.3])
    fingers = _dmp(2, seed=6, tau=1.0)
    task = TaskSpaceDmp(pos, ori, fingers).with_tau(2.0)
    assert [task.position.tau, task.orientation.tau, task.fingers.tau] == [2.0, 2.0, 2.0]
    np.testing.assert_array_equal(task.position.v0, pos.with_tau(2.0).v0)
    np.testing.assert_array_equal(task.orientation.omega0, slow.omega0)
    assert TaskSpaceDmp(pos, ori).with_tau(2.0).fingers is None


@pytest.mark.parametrize("tau", [0.0, -1.0, float("nan"), float("inf"), "2"])
def test_with_tau_refuses_a_bad_duration(tau):
    dmp = _dmp(1, seed=0, tau=1.0)
    with pytest.raises(RepertoireError, match="tau"):
        dmp.with_tau(tau)


# ----------------------------------------------------------------- eq. 10 at several points
def test_multi_point_coupling_takes_the_scaled_velocity():
    x, xd = np.array([0.5, 0.0, 0.9]), np.array([0.1, 0.4, -0.05])
    o, R = np.array([0.55, 0.12, 0.88]), np.eye(3)
    pts = [[0.0, 0.0, 0.0], [0.0, 0.06, -0.02]]
    kw = dict(obstacle_radius=0.06, length_scale=0.03)
    one = multi_point_obstacle_coupling(x, xd, R, pts, o, 900.0, 4.0, **kw)
    for tau in (0.5, 3.0):
        p = multi_point_obstacle_coupling(x, xd, R, pts, o, 900.0, 4.0, tau=tau, **kw)
        # eq. 10 of v = tau xd: tau times the term of xd (the angles do not change)
        np.testing.assert_allclose(p, tau * one, rtol=1e-14, atol=0)
        # with the single tcp point and no fade: obstacle_coupling with that tau exactly
        single = multi_point_obstacle_coupling(x, xd, R, [[0, 0, 0]], o, 900.0, 4.0, tau=tau)
        np.testing.assert_array_equal(single, obstacle_coupling(x, xd, o, 900.0, 4.0, tau=tau))
    for bad in (0.0, -2.0, float("nan"), "1"):
        with pytest.raises(RepertoireError, match="tau must be a finite number > 0"):
            multi_point_obstacle_coupling(x, xd, R, pts, o, 900.0, 4.0, tau=bad)
    with pytest.raises(RepertoireError, match="tau must be a finite number > 0"):
        MultiPointObstacleCoupling(pts, tau=0.0)


def test_multi_point_coupling_system_reads_tau_from_its_input_else_its_parameter():
    pts = [[0.0, 0.0, 0.0]]
    system = MultiPointObstacleCoupling(pts, gamma=800.0, beta=3.0, tau=2.0)
    ctx = system.CreateDefaultContext()
    x, xd, o = np.zeros(3), np.array([0.3, 0.1, 0.0]), np.array([1.0, 0.2, 0.1])
    for name, value in (("position", x), ("velocity", xd), ("obstacle", o)):
        system.GetInputPort(name).FixValue(ctx, value)
    system.GetInputPort("orientation").FixValue(ctx, [1.0, 0.0, 0.0, 0.0])
    out = system.GetOutputPort("coupling")
    np.testing.assert_array_equal(out.Eval(ctx), obstacle_coupling(x, xd, o, 800.0, 3.0, tau=2.0))
    system.GetInputPort("tau").FixValue(ctx, [3.5])  # connected: the input wins
    np.testing.assert_array_equal(out.Eval(ctx), obstacle_coupling(x, xd, o, 800.0, 3.0, tau=3.5))
    system.GetInputPort("tau").FixValue(ctx, [-1.0])
    with pytest.raises(RepertoireError, match="tau must be a finite number > 0"):
        out.Eval(ctx)


def test_sequencer_reports_the_active_segments_tau():
    a, b = _dmp(3, seed=1, tau=0.3), _dmp(3, seed=2, tau=0.7)
    seq = DmpSequencer([a, b], [0.0, 0.2], time_step=1e-3)
    sim = Simulator(seq)
    ctx = sim.get_mutable_context()
    tau = seq.GetOutputPort("tau")
    assert tau.Eval(ctx)[0] == 0.3
    sim.AdvanceTo(0.1)
    assert tau.Eval(ctx)[0] == 0.3 and seq.GetOutputPort("segment").Eval(ctx)[0] == 0
    sim.AdvanceTo(0.25)
    assert tau.Eval(ctx)[0] == 0.7 and seq.GetOutputPort("segment").Eval(ctx)[0] == 1


def _coupled_sequencer_path(dmp: DmpParameters, obstacle: np.ndarray, samples: int):
    """tcp path of a one-segment continuous DmpSequencer under MultiPointObstacleCoupling
    fed the sequencer's tau (as the arm worlds wire it), sampled at phase steps."""
    builder = DiagramBuilder()
    seq = builder.AddSystem(
        DmpSequencer([dmp], [0.0], time_step=None, switch_period=dmp.tau / 50, coupling_dofs=3)
    )
    pts = [[0.0, 0.0, 0.0], [0.0, 0.0, -0.05]]
    coupling = builder.AddSystem(
        MultiPointObstacleCoupling(pts, gamma=300.0, beta=2.0, obstacle_radius=0.05,
                                   length_scale=0.1)
    )  # fmt: skip
    for src, dst in (("position", "position"), ("velocity", "velocity"), ("tau", "tau")):
        builder.Connect(seq.GetOutputPort(src), coupling.GetInputPort(dst))
    for name, value in (("orientation", [1.0, 0.0, 0.0, 0.0]), ("obstacle", obstacle)):
        src = builder.AddSystem(ConstantVectorSource(np.asarray(value, float)))
        builder.Connect(src.get_output_port(), coupling.GetInputPort(name))
    builder.Connect(coupling.GetOutputPort("coupling"), seq.GetInputPort("coupling"))
    log = builder.AddSystem(VectorLogSink(3, publish_period=dmp.tau / samples))
    builder.Connect(seq.GetOutputPort("position"), log.get_input_port())
    diagram = builder.Build()
    sim = Simulator(diagram)
    # fixed steps scaled with tau: in the phase time t / tau the runs take the same steps
    ResetIntegratorFromFlags(sim, "runge_kutta2", dmp.tau / 500)
    sim.get_mutable_integrator().set_fixed_step_mode(True)
    sim.AdvanceTo(1.2 * dmp.tau)
    return log.FindLog(sim.get_context()).data().T


def test_arm_style_coupled_chain_takes_the_same_path_at_any_tau():
    dmp = _dmp(3, seed=11, tau=1.0)
    free = dmp.rollout(dt=1e-3).x
    obstacle = free[len(free) // 2] + np.array([0.0, 0.0, 0.02])
    ref = _coupled_sequencer_path(dmp, obstacle, 60)
    # the coupling bends the path: some sample is > 5 mm from every point of the free one
    off = np.linalg.norm(ref[:, None, :] - free[None, :, :], axis=2).min(axis=1)
    assert off.max() > 0.005
    for factor in (0.5, 3.0):
        path = _coupled_sequencer_path(dmp.with_tau(factor), obstacle, 60)
        n = min(len(path), len(ref))
        # before session 36 the term took dx/dt: 1 / tau of the paper's, another path
        np.testing.assert_allclose(path[:n], ref[:n], rtol=0, atol=1e-12)
