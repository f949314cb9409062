"""Chaining DMPs: the hand-off math, chain_rollout, the 10-D stacking and the DmpSequencer."""

import dataclasses

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import VectorLogSink
from repertoire.planning.dmp import DmpParameters
from repertoire.planning.dmp_chain import (
    acceleration_matched_start,
    chain_rollout,
    handoff_state,
    stack_task_space_dmp,
)
from repertoire.planning.dmp_learn import learn_dmp, learn_task_space_dmp
from repertoire.planning.dmp_math import (
    basis_centres,
    basis_widths,
    forcing_term,
    minimum_jerk,
    transformation_derivatives,
)
from repertoire.systems.dmp_sequencer import DmpSequencer, task_space_sequencer

from repertoire.errors import RepertoireError


def _flat_dmp(n: int = 2, tau: float = 0.5, K: float = 100.0, D: float = 20.0) -> DmpParameters:
    """A DMP with zero weights (f = 0) and a given tau, K, D."""
    c = basis_centres(5, 3.0)
    return DmpParameters(
        np.zeros((n, 5)), c, basis_widths(c, 3.0), np.full(n, K), np.full(n, D), 3.0, tau,
        np.zeros(n), np.ones(n),
    )  # fmt: skip


@pytest.fixture(scope="module")
def segment():
    t = np.linspace(0, 1, 300)
    return learn_dmp(t, minimum_jerk(np.zeros(2), np.array([1.0, 0]), 1.0, t)[0], n_basis=15)


SQUARE = [np.array(g, float) for g in ([1, 0], [1, 1], [0, 1], [0, 0])]


# ------------------------------------------------------------------ the hand-off math
def test_handoff_state_closed_forms():
    succ = _flat_dmp(tau=0.5)
    x, v, a = np.array([0.2, -0.1]), np.array([0.3, 0.6]), np.array([1.0, -2.0])
    x0, vs = handoff_state(succ, x, v, 2.0, "none")
    np.testing.assert_array_equal(x0, x)
    np.testing.assert_array_equal(vs, [0.0, 0.0])
    x0, vs = handoff_state(succ, x, v, 2.0, "velocity")
    np.testing.assert_array_equal(x0, x)
    np.testing.assert_allclose(vs, v * 0.5 / 2.0, rtol=1e-15)  # same physical velocity
    x0, vs = handoff_state(succ, x, v, 2.0, "acceleration", a)
    xd = v / 2.0
    # f = 0: x0 = x + (tau^2 a + D tau xd) / K
    np.testing.assert_allclose(x0, x + (0.25 * a + 20.0 * 0.5 * xd) / 100.0, rtol=1e-14)
    # the defining property: at theta = 1 the successor starts with acceleration a
    _, vd = transformation_derivatives(x, vs, 1.0, succ.goal, x0, 0.0, succ.K, succ.D, 0.5)
    np.testing.assert_allclose(vd / 0.5, a, rtol=1e-12)


def test_acceleration_matched_start_with_forcing(segment):
    x, xd, a = np.array([0.4, 0.1]), np.array([0.5, -0.2]), np.array([-3.0, 1.0])
    x0 = acceleration_matched_start(segment, x, xd, a)
    f1 = forcing_term(1.0, segment.weights, segment.centres, segment.widths)
    _, vd = transformation_derivatives(
        x, segment.tau * xd, 1.0, SQUARE[1], x0, f1, segment.K, segment.D, segment.tau
    )
    np.testing.assert_allclose(vd / segment.tau, a, atol=1e-9)


def test_handoff_bad_input(segment):
    with pytest.raises(RepertoireError, match="handoff must be one of"):
        handoff_state(segment, np.zeros(2), np.zeros(2), 1.0, "jerk")
    with pytest.raises(RepertoireError, match="needs the predecessor's acceleration"):
        handoff_state(segment, np.zeros(2), np.zeros(2), 1.0, "acceleration")
    old = dataclasses.replace(_flat_dmp(), formulation="old")
    with pytest.raises(RepertoireError, match="needs the new formulation"):
        handoff_state(old, np.zeros(2), np.zeros(2), 1.0, "acceleration", np.zeros(2))
    with pytest.raises(RepertoireError, match="needs the new formulation"):
        DmpSequencer([old, old], [0.0, 1.0], handoff="acceleration")


def test_chain_rollout_handoffs(segment):
    times = [0.0, 0.6, 1.2, 1.8]
    vel = chain_rollout([segment] * 4, SQUARE, times, handoff="velocity")
    acc = chain_rollout([segment] * 4, SQUARE, times, handoff="acceleration")
    none = chain_rollout([segment] * 4, SQUARE, times, handoff="none")
    assert vel.switch_steps == [600, 1200, 1800]
    assert max(vel.velocity_jumps) < 1e-12 and max(acc.velocity_jumps) < 1e-12
    assert max(none.velocity_jumps) > 0.1
    assert max(acc.acceleration_jumps) < 1e-9 < max(vel.acceleration_jumps)
    assert len(vel.t) == 2801 and vel.t[-1] == pytest.approx(2.8)  # last switch + tau
    late = chain_rollout([segment] * 4, SQUARE, times, duration=4.0)
    np.testing.assert_allclose(late.x[-1], SQUARE[-1], atol=1e-3)
    with pytest.raises(RepertoireError, match="handoff must be one of"):
        chain_rollout([segment], SQUARE[:1], [0.0], handoff="jerk")
    with pytest.raises(RepertoireError, match="increasing and >= 0"):
        chain_rollout([segment] * 2, SQUARE[:2], [0.5, 0.5])
    with pytest.raises(RepertoireError, match="2 segments need as many goals, got 1"):
        chain_rollout([segment] * 2, SQUARE[:1], [0.0, 0.5])


# ------------------------------------------------------------------ 10-D stacking
def _task_dmp(p0, p1, duration=1.0):
    t = np.linspace(0.0, duration, 300)
    p, _, _ = minimum_jerk(np.asarray(p0, float), np.asarray(p1, float), duration, t)
    q = np.tile([1.0, 0.0, 0.0, 0.0], (len(t), 1))
    f, _, _ = minimum_jerk(np.zeros(3), np.full(3, 0.5), duration, t)
    return learn_task_space_dmp(t, p, q, f, orientation_mode="component", n_basis=20)


def test_stack_task_space_dmp_slices_and_parts():
    dmp = _task_dmp([0.5, 0.0, 0.9], [0.6, -0.1, 0.8])
    stacked = stack_task_space_dmp(dmp)
    assert stacked.slices == {
        "position": slice(0, 3),
        "orientation": slice(3, 7),
        "fingers": slice(7, 10),
    }
    p = stacked.parameters
    np.testing.assert_array_equal(p.weights[:3], dmp.position.weights)
    np.testing.assert_array_equal(p.weights[3:7], dmp.orientation.weights)
    np.testing.assert_array_equal(p.x0[7:], dmp.fingers.x0)
    np.testing.assert_array_equal(p.goal[3:7], dmp.orientation.goal)
    assert p.tau == dmp.tau and p.alpha == dmp.alpha


# ------------------------------------------------------------------ the sequencer
def _run(seq, t_end, n, port="position"):
    builder = DiagramBuilder()
    builder.AddSystem(seq)
    log = builder.AddSystem(VectorLogSink(n, publish_period=1e-3))
    builder.Connect(seq.GetOutputPort(port), log.get_input_port())
    diagram = builder.Build()
    sim = Simulator(diagram)
    return sim, diagram, log


@pytest.mark.parametrize("handoff", ["none", "velocity", "acceleration"])
def test_discrete_sequencer_matches_chain_rollout(segment, handoff):
    times = [0.0, 0.7, 1.4, 2.1]
    seq = DmpSequencer([segment] * 4, times, goals=SQUARE, handoff=handoff)
    sim, _, log = _run(seq, 2.5, 2)
    sim.AdvanceTo(2.5)
    X = log.FindLog(sim.get_context()).data().T
    ref = chain_rollout([segment] * 4, SQUARE, times, handoff=handoff)
    assert np.abs(X - ref.x[: len(X)]).max() < 1e-10
    ctx = seq.GetMyContextFromRoot(sim.get_context())
    assert seq.GetOutputPort("segment").Eval(ctx)[0] == 3


def test_sequencer_per_segment_goal_ports_and_held_start(segment):
    """goal_2 connected overrides the stored goal of segment 2 only; the start is held."""
    times = [0.2, 0.9, 1.6, 2.3]
    moved = np.array([0.2, 1.4])
    seq = DmpSequencer([segment] * 4, times, goals=SQUARE)
    ctx = seq.CreateDefaultContext()
    seq.GetInputPort("goal_2").FixValue(ctx, moved)
    sim = Simulator(seq, ctx)
    sim.AdvanceTo(0.1)
    np.testing.assert_array_equal(seq.GetOutputPort("position").Eval(ctx), segment.x0)
    sim.AdvanceTo(3.0)
    goals = [SQUARE[0], SQUARE[1], moved, SQUARE[3]]
    ref = chain_rollout([segment] * 4, goals, times, duration=3.0)
    np.testing.assert_allclose(seq.GetOutputPort("position").Eval(ctx), ref.x[-1], atol=1e-10)


def test_continuous_sequencer_matches_chain_rollout(segment):
    times = [0.0, 0.7, 1.4]
    seq = DmpSequencer([segment] * 3, times, goals=SQUARE[:3], time_step=None)
    ctx = seq.CreateDefaultContext()
    sim = Simulator(seq, ctx)
    sim.get_mutable_integrator().set_target_accuracy(1e-9)
    sim.AdvanceTo(2.0)
    ref = chain_rollout([segment] * 3, SQUARE[:3], times, duration=2.0, dt=1e-4)
    np.testing.assert_allclose(seq.GetOutputPort("position").Eval(ctx), ref.x[-1], atol=1e-5)
    np.testing.assert_allclose(seq.GetOutputPort("velocity").Eval(ctx), ref.xd[-1], atol=1e-4)
    assert seq.GetOutputPort("segment").Eval(ctx)[0] == 2
    assert seq.GetOutputPort("phase").Eval(ctx)[0] == pytest.approx(
        np.exp(-segment.alpha * 0.6 / segment.tau), rel=1e-6
    )


def test_sequencer_bad_input(segment):
    with pytest.raises(RepertoireError, match="at least one segment"):
        DmpSequencer([], [])
    with pytest.raises(RepertoireError, match="2 segments need as many start times, got 1"):
        DmpSequencer([segment] * 2, [0.0])
    with pytest.raises(RepertoireError, match="increasing and >= 0"):
        DmpSequencer([segment] * 2, [0.0, 0.0])
    with pytest.raises(RepertoireError, match="2 segments need as many goals, got 3"):
        DmpSequencer([segment] * 2, [0.0, 1.0], goals=SQUARE[:3])
    with pytest.raises(RepertoireError, match="handoff must be one of"):
        DmpSequencer([segment], [0.0], handoff="jerk")
    with pytest.raises(RepertoireError, match="segment 1 has 3 DOF, segment 0 has 2"):
        DmpSequencer([segment, _flat_dmp(3)], [0.0, 1.0])
    # segment is 2-D: no room for a quaternion block (the message said "in [0, -2]")
    with pytest.raises(
        RepertoireError, match=r"quaternion_at = 0 needs segments with at least 4 DOF .* have 2"
    ):
        DmpSequencer([segment], [0.0], quaternion_at=0)
    with pytest.raises(RepertoireError, match=r"quaternion_at must be in \[0, 1\] .* got 2"):
        DmpSequencer([_flat_dmp(5)], [0.0], quaternion_at=2)
    with pytest.raises(RepertoireError, match="coupling_dofs must be in"):
        DmpSequencer([segment], [0.0], coupling_dofs=3)
    with pytest.raises(RepertoireError, match="closer than the time step"):
        DmpSequencer([segment] * 2, [0.0, 1e-4])
    with pytest.raises(RepertoireError, match="segment 0 is dict"):
        DmpSequencer([segment.to_dict()], [0.0])
    seq = DmpSequencer([segment], [0.0])
    ctx = seq.CreateDefaultContext()
    # an unconnected goal port stands for the segment's learned goal (as in every DMP
    # system; it raised "segment 0 has no goal" before session 36)
    unwired = seq.GetOutputPort("acceleration").Eval(ctx).copy()
    seq.GetInputPort("goal_0").FixValue(ctx, segment.goal)
    np.testing.assert_array_equal(seq.GetOutputPort("acceleration").Eval(ctx), unwired)
    seq.GetInputPort("goal_0").FixValue(ctx, [np.nan, 0.0])
    with pytest.raises(RepertoireError, match="goal input contains NaN"):
        seq.GetOutputPort("acceleration").Eval(ctx)
    with pytest.raises(RepertoireError, match="x_start must have 2 entries"):
        seq.set_start(ctx, np.zeros(3))


# ------------------------------------------------------------------ the arm's configuration
X_START = np.concatenate([[0.5, 0.0, 0.9], [1, 0, 0, 0], np.zeros(3)])


def test_task_space_sequencer_single_segment_matches_the_rollout():
    dmp = _task_dmp([0.5, 0.0, 0.9], [0.6, -0.1, 0.8])
    chain = task_space_sequencer([dmp], [0.0], X_START)
    context = chain.CreateDefaultContext()
    goal = np.concatenate([[0.62, -0.05, 0.85], [1, 0, 0, 0], [0.4, 0.4, 0.4]])
    # the same orientation on the other hemisphere: the chain takes the shortest rotation
    flipped = goal.copy()
    flipped[3:7] *= -1.0
    chain.GetInputPort("goal_0").FixValue(context, flipped)
    chain.GetInputPort("coupling").FixValue(context, np.zeros(3))
    simulator = Simulator(chain, context)
    simulator.get_mutable_integrator().set_target_accuracy(1e-9)
    simulator.AdvanceTo(0.6)
    ref = stack_task_space_dmp(dmp).parameters.rollout(goal=goal, x0=X_START, dt=1e-4, n_steps=6000)
    out = {n: chain.GetOutputPort(n).Eval(context) for n in ("tcp_position", "tcp_velocity")}
    np.testing.assert_allclose(out["tcp_position"], ref.x[-1, :3], atol=1e-5)
    np.testing.assert_allclose(out["tcp_velocity"], ref.xd[-1, :3], atol=1e-4)
    np.testing.assert_allclose(
        chain.GetOutputPort("finger_position").Eval(context), ref.x[-1, 7:], atol=1e-5
    )
    np.testing.assert_allclose(
        chain.GetOutputPort("finger_acceleration").Eval(context), ref.xdd[-1, 7:], atol=1e-3
    )
    np.testing.assert_allclose(chain.GetOutputPort("orientation").Eval(context), [1, 0, 0, 0])
    np.testing.assert_allclose(chain.GetOutputPort("angular_velocity").Eval(context), 0.0)


def test_task_space_sequencer_hands_over_position_and_velocity():
    first = _task_dmp([0.5, 0.0, 0.9], [0.6, 0.0, 0.9])
    second = _task_dmp([0.6, 0.0, 0.9], [0.6, 0.1, 0.9], duration=0.8)
    chain = task_space_sequencer([first, second], [0.0, 0.5], X_START, switch_period=0.01)
    context = chain.CreateDefaultContext()
    chain.GetInputPort("goal_0").FixValue(
        context, np.concatenate([[0.6, 0.0, 0.9], [1, 0, 0, 0], [0.5] * 3])
    )
    chain.GetInputPort("goal_1").FixValue(
        context, np.concatenate([[0.6, 0.1, 0.9], [1, 0, 0, 0], [0.5] * 3])
    )
    chain.GetInputPort("coupling").FixValue(context, np.zeros(3))
    simulator = Simulator(chain, context)
    names = ("tcp_position", "tcp_velocity")
    simulator.AdvanceTo(0.5 - 1e-6)
    before = [chain.GetOutputPort(n).Eval(context).copy() for n in names]
    assert chain.GetOutputPort("segment").Eval(context)[0] == 0
    simulator.AdvanceTo(0.5 + 1e-6)
    after = [chain.GetOutputPort(n).Eval(context).copy() for n in names]
    assert chain.GetOutputPort("segment").Eval(context)[0] == 1
    assert chain.GetOutputPort("phase").Eval(context)[0] == pytest.approx(1.0, abs=1e-4)
    np.testing.assert_allclose(after[0], before[0], atol=1e-5)  # x_pred -> x_succ
    np.testing.assert_allclose(after[1], before[1], atol=1e-3)  # v_pred -> v_succ
    simulator.AdvanceTo(2.5)
    np.testing.assert_allclose(
        chain.GetOutputPort("tcp_position").Eval(context), [0.6, 0.1, 0.9], atol=1e-3
    )


def test_task_space_sequencer_bad_input():
    dmp = _task_dmp([0.5, 0.0, 0.9], [0.6, -0.1, 0.8])
    with pytest.raises(RepertoireError, match="at least one segment"):
        task_space_sequencer([], [], X_START)
    with pytest.raises(RepertoireError, match="must start at 0"):
        task_space_sequencer([dmp], [0.5], X_START)
    with pytest.raises(RepertoireError, match="increasing and >= 0"):
        task_space_sequencer([dmp, dmp], [0.0, 0.0], X_START)
    with pytest.raises(RepertoireError, match="x_start must have 10 entries"):
        task_space_sequencer([dmp], [0.0], X_START[:7])
    no_fingers = learn_task_space_dmp(
        np.linspace(0, 1, 50), np.zeros((50, 3)) + np.linspace(0, 1, 50)[:, None],
        np.tile([1.0, 0, 0, 0], (50, 1)), None, orientation_mode="component", n_basis=5,
    )  # fmt: skip
    with pytest.raises(RepertoireError, match="segment 0: the task-space chain runs"):
        task_space_sequencer([no_fingers], [0.0], X_START)


@pytest.mark.parametrize("time_step", [1e-3, None])
def test_sequencer_outputs_at_the_start_are_the_closed_form(segment, time_step):
    """At theta = 1, x = x0, v = 0: tau^2 xdd = K f(1) + p (new form, eq. 6-7, 9)."""
    seq = DmpSequencer([segment] * 2, [0.0, 1.0], time_step=time_step, coupling_dofs=1)
    ctx = seq.CreateDefaultContext()
    x0 = np.array([0.3, -0.2])
    seq.set_start(ctx, x0)
    seq.GetInputPort("goal_0").FixValue(ctx, [1.0, 2.0])
    seq.GetInputPort("coupling").FixValue(ctx, [5.0])
    f1 = forcing_term(1.0, segment.weights, segment.centres, segment.widths)
    expected = (segment.K * f1 + np.array([5.0, 0.0])) / segment.tau**2
    np.testing.assert_allclose(seq.GetOutputPort("acceleration").Eval(ctx), expected, rtol=1e-12)
    np.testing.assert_array_equal(seq.GetOutputPort("position").Eval(ctx), x0)
    np.testing.assert_array_equal(seq.GetOutputPort("velocity").Eval(ctx), [0.0, 0.0])
    assert seq.GetOutputPort("phase").Eval(ctx)[0] == 1.0
    assert seq.GetOutputPort("segment").Eval(ctx)[0] == 0


def test_sequencer_quaternion_block_is_post_normalised():
    dmp = _flat_dmp(n=5)
    seq = DmpSequencer([dmp], [0.0], time_step=None, quaternion_at=1, goals=[np.ones(5)])
    ctx = seq.CreateDefaultContext()
    seq.set_start(ctx, [7.0, 1.0, 0.0, 0.0, 0.0])  # a start must be unit (session 35)
    z = ctx.get_continuous_state_vector().CopyToVector()  # [theta, x - x0, v]
    z[2] = 1.0  # so the raw block [2, 0, 0, 0] has norm 2
    ctx.SetContinuousState(z)
    np.testing.assert_array_equal(seq.GetOutputPort("orientation").Eval(ctx), [1, 0, 0, 0])
    np.testing.assert_array_equal(seq.GetOutputPort("angular_velocity").Eval(ctx), [0, 0, 0])


def test_post_normalisation_is_written_once_and_refuses_a_zero_state():
    """The sequencer's quaternion block and QuaternionNormalizer share post_normalised.

    Closed form: q = (2, 0, 0, 0) turning about z at 3 rad/s in R^4 (q' = (0, 0, 0, 3)):
    n = (1, 0, 0, 0), n' = (0, 0, 0, 1.5), omega = (0, 0, 3). A zero block (no orientation)
    gave the sequencer NaN outputs; both now refuse it.
    """
    from repertoire.planning.dmp_quaternion import angular_velocity, post_normalised
    from repertoire.systems.dmp import QuaternionNormalizer

    q, qd = post_normalised(np.array([2.0, 0, 0, 0]), np.array([0.0, 0, 0, 3.0]))
    np.testing.assert_array_equal(q, [1, 0, 0, 0])
    np.testing.assert_array_equal(qd, [0, 0, 0, 1.5])
    np.testing.assert_array_equal(angular_velocity(q, qd), [0, 0, 3])
    qn = QuaternionNormalizer()
    ctx = qn.CreateDefaultContext()
    qn.get_quaternion_input_port().FixValue(ctx, [2.0, 0, 0, 0])
    qn.get_quaternion_rate_input_port().FixValue(ctx, [0.0, 0, 0, 3.0])
    np.testing.assert_array_equal(qn.get_angular_velocity_output_port().Eval(ctx), [0, 0, 3])
    qn.get_quaternion_input_port().FixValue(ctx, np.zeros(4))
    with pytest.raises(RepertoireError, match=r"state \[0. 0. 0. 0.\] has \|q\| = 0.0"):
        qn.get_orientation_output_port().Eval(ctx)
    seq = DmpSequencer([_flat_dmp(n=5)], [0.0], time_step=None, quaternion_at=1)
    ctx = seq.CreateDefaultContext()
    seq.set_start(ctx, [7.0, 1.0, 0.0, 0.0, 0.0])
    z = ctx.get_continuous_state_vector().CopyToVector()  # [theta, x - x0, v]
    z[2] = -1.0  # the raw block is 0
    ctx.SetContinuousState(z)
    with pytest.raises(RepertoireError, match=r"has \|q\| = 0.0: cannot normalise"):
        seq.GetOutputPort("orientation").Eval(ctx)
