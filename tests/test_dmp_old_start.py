"""The DMP LeafSystems start an old-formulation DMP as ``rollout`` and ``with_goal`` do.

Eq. 1 multiplies f by ``g - x0``: a run to another goal is the demonstration scaled per DOF
by ``s = (g - x0) / (learned g - learned x0)``, its start velocity ``s v0`` too. The goal on
the input port at the onset decides that scaling, once; a goal that changes later acts
through eq. 1's terms only (the velocity reached does not jump), as ``rollout`` with one
goal per sample scales ``v0`` by the first. Until session 36 every LeafSystem started from
the learned ``v0`` whatever its goal input: 1.7 % of the range off ``rollout`` on a
sums-of-sines demonstration sent to a new goal.
"""

import dataclasses

import numpy as np
import pytest
from pydrake.systems.analysis import ResetIntegratorFromFlags, Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import VectorLogSink
from repertoire.planning.dmp_chain import chain_rollout, stack_task_space_dmp
from repertoire.planning.dmp_demos import sines_in_motion
from repertoire.planning.dmp_learn import (
    learn_dmp,
    learn_dmp_from_demonstrations,
    learn_task_space_dmp,
)
from repertoire.systems.dmp_compose import DmpSystem
from repertoire.systems.dmp_sequencer import DmpSequencer, task_space_sequencer

from repertoire.errors import RepertoireError

# goals relative to the learned start: scaled, mirrored ("behind the start"), far, the start
GOAL_SCALES = {
    "scaled": np.array([1.7, -0.5, 2.0]),
    "behind": np.array([-1.0, -1.0, -1.0]),
    "far": np.array([25.0, 10.0, -40.0]),
    "start": np.zeros(3),
}


@pytest.fixture(scope="module")
def old3() -> dict:
    """A sums-of-sines demonstration in motion (3 DOF), learned in both formulations."""
    t, x, _ = sines_in_motion(911, 3, 1.2, 601)
    return {f: learn_dmp(t, x, n_basis=40, formulation=f) for f in ("old", "new")}


def _run(dmp, goal, *, time_step, duration, start_time=0.0, goal_later=None, accuracy=None):
    """Simulate a DmpSystem with its goal fixed; returns the logged position and velocity.

    ``goal_later = (time, goal)`` fixes another goal at that time and runs on; then the
    velocity output just after the change is returned too. Continuous (``time_step=None``):
    RK3 at 0.5 ms steps, or error-controlled to ``accuracy`` (a step ending at a delayed
    onset evaluates its last stage there, moving before it by about 1e-4 of the range).
    """
    builder = DiagramBuilder()
    system = builder.AddSystem(DmpSystem(dmp, time_step=time_step))
    logs = []
    for name in ("position", "velocity"):
        log = builder.AddSystem(VectorLogSink(dmp.n_dims, publish_period=1e-3))
        builder.Connect(system.GetOutputPort(name), log.get_input_port())
        logs.append(log)
    diagram = builder.Build()
    sim = Simulator(diagram)
    if time_step is None:
        ResetIntegratorFromFlags(sim, "runge_kutta3", 5e-4)
        if accuracy is None:
            sim.get_mutable_integrator().set_fixed_step_mode(True)
        else:
            sim.get_mutable_integrator().set_target_accuracy(accuracy)
    ctx = sim.get_mutable_context()
    sub = system.GetMyMutableContextFromRoot(ctx)
    system.GetInputPort("goal").FixValue(sub, goal)
    system.set_start_time(sub, start_time)
    after = []
    if goal_later is not None:
        sim.AdvanceTo(goal_later[0])
        system.GetInputPort("goal").FixValue(sub, goal_later[1])
        after = [system.GetOutputPort("velocity").Eval(sub)]
    sim.AdvanceTo(duration)
    return [log.FindLog(ctx).data().T for log in logs] + after


@pytest.mark.parametrize("formulation", ["old", "new"])
@pytest.mark.parametrize("tau_factor", [1.0, 0.6, 2.5])
@pytest.mark.parametrize("goal_kind", list(GOAL_SCALES))
def test_discrete_system_matches_rollout_to_new_goals_and_taus(
    old3, formulation, tau_factor, goal_kind
):
    dmp = old3[formulation]
    goal = dmp.x0 + GOAL_SCALES[goal_kind] * (dmp.goal - dmp.x0)
    tau = tau_factor * dmp.tau
    x, xd = _run(dmp.with_tau(tau), goal, time_step=1e-3, duration=tau)
    ref = dmp.rollout(goal=goal, tau=tau, dt=1e-3)
    n = min(len(x), len(ref.x))
    scale = max(1.0, np.ptp(ref.x, axis=0).max())
    np.testing.assert_allclose(x[:n], ref.x[:n], rtol=0, atol=1e-11 * scale)
    np.testing.assert_allclose(xd[:n], ref.xd[:n], rtol=0, atol=1e-9 * scale / tau)
    np.testing.assert_allclose(xd[0], dmp.start_velocity(goal, dmp.x0) * dmp.tau / tau, rtol=1e-13)
    if formulation == "old" and goal_kind == "start":  # s = 0: eq. 1 has no input at all
        np.testing.assert_array_equal(x, np.tile(dmp.x0, (len(x), 1)))


@pytest.mark.parametrize("formulation", ["old", "new"])
@pytest.mark.parametrize("tau_factor", [1.0, 0.6])
def test_continuous_system_matches_rollout_to_a_new_goal(old3, formulation, tau_factor):
    dmp = old3[formulation]
    goal = dmp.x0 + GOAL_SCALES["scaled"] * (dmp.goal - dmp.x0)
    tau = tau_factor * dmp.tau
    x, xd = _run(dmp.with_tau(tau), goal, time_step=None, duration=tau)
    ref = dmp.rollout(goal=goal, tau=tau, dt=1e-3)
    n = min(len(x), len(ref.x))
    scale = np.ptp(ref.x, axis=0).max()  # before: 1.7e-2 of it off (old formulation)
    np.testing.assert_allclose(x[:n], ref.x[:n], rtol=0, atol=1e-5 * scale)  # the integrator
    np.testing.assert_allclose(xd[0], dmp.start_velocity(goal, dmp.x0) * dmp.tau / tau, rtol=1e-13)


@pytest.mark.parametrize("time_step", [1e-3, None])
def test_the_goal_at_the_onset_decides_and_a_later_goal_does_not_rescale(old3, time_step):
    dmp = old3["old"]
    g1 = dmp.x0 + GOAL_SCALES["scaled"] * (dmp.goal - dmp.x0)
    g2 = dmp.x0 + GOAL_SCALES["behind"] * (dmp.goal - dmp.x0)
    ref = dmp.rollout(goal=g2, dt=1e-3, n_steps=600)
    # held until 0.2 s; g1 until 0.1 s, then g2: the goal at the onset (g2) scales v0
    x, _, _ = _run(
        dmp,
        g1,
        time_step=time_step,
        duration=0.8,
        start_time=0.2,
        goal_later=(0.1, g2),
        accuracy=1e-9,
    )
    atol = (1e-12 if time_step else 1e-5) * np.ptp(ref.x, axis=0).max()
    np.testing.assert_array_equal(x[:200], np.tile(dmp.x0, (200, 1)))
    np.testing.assert_allclose(x[200:801], ref.x, rtol=0, atol=atol)
    # g1 at the onset, g2 from 0.5 s: the velocity reached does not jump at the change (no
    # rescaling mid-motion); up to the change it is the run to g1
    x, xd, after = _run(dmp, g1, time_step=time_step, duration=0.8, goal_later=(0.5, g2))
    ref1 = dmp.rollout(goal=g1, dt=1e-3, n_steps=500)
    np.testing.assert_allclose(x[:501], ref1.x, rtol=0, atol=atol)
    np.testing.assert_array_equal(after, xd[500])


@pytest.mark.parametrize("time_step", [1e-3, None])
def test_the_sequencer_and_chain_rollout_scale_the_first_segment_alike(old3, time_step):
    dmp = old3["old"]
    second = dmp.with_goal(dmp.goal + 0.3, x0=dmp.goal)
    g0 = dmp.x0 + GOAL_SCALES["behind"] * (dmp.goal - dmp.x0)
    goals, times = [g0, second.goal], [0.2, 0.7]
    ref = chain_rollout([dmp, second], goals, times, duration=1.6)
    own = dmp.rollout(goal=g0, dt=1e-3, n_steps=500)  # the first segment is its rollout
    np.testing.assert_allclose(ref.x[200:701], own.x, rtol=0, atol=1e-12)
    seq = DmpSequencer([dmp, second], times, time_step=time_step)
    sim = Simulator(seq)
    if time_step is None:
        ResetIntegratorFromFlags(sim, "runge_kutta3", 1e-3)
        sim.get_mutable_integrator().set_target_accuracy(1e-9)
    ctx = sim.get_mutable_context()
    seq.GetInputPort("goal_0").FixValue(ctx, g0)
    seq.GetInputPort("goal_1").FixValue(ctx, second.goal)
    atol = (1e-12 if time_step else 1e-5) * np.ptp(ref.x, axis=0).max()
    for k in (100, 200, 201, 450, 700, 1100, 1600):
        sim.AdvanceTo(k * 1e-3)
        np.testing.assert_allclose(seq.GetOutputPort("position").Eval(ctx), ref.x[k], atol=atol)
        np.testing.assert_allclose(
            seq.GetOutputPort("velocity").Eval(ctx), ref.xd[k], atol=1e3 * atol
        )
    seq.set_start(ctx, dmp.x0, dmp.v0)  # an explicit start velocity is not rescaled
    ctx.SetTime(0.3)
    np.testing.assert_allclose(seq.GetOutputPort("velocity").Eval(ctx), dmp.v0, rtol=1e-15)


def test_an_explicit_start_velocity_is_kept_and_set_start_restores_the_scaling(old3):
    dmp = old3["old"]
    goal = dmp.x0 + GOAL_SCALES["scaled"] * (dmp.goal - dmp.x0)
    for time_step in (1e-3, None):
        system = DmpSystem(dmp, time_step=time_step)
        ctx = system.CreateDefaultContext()
        system.GetInputPort("goal").FixValue(ctx, goal)
        velocity = system.GetOutputPort("velocity")
        np.testing.assert_allclose(velocity.Eval(ctx), dmp.start_velocity(goal, dmp.x0))
        system.set_start(ctx, dmp.x0, velocity=dmp.v0)
        np.testing.assert_allclose(velocity.Eval(ctx), dmp.v0, rtol=1e-15)
        system.set_start(ctx, dmp.x0 + 0.1)  # the learned start again: scaled from x0 + 0.1
        np.testing.assert_allclose(velocity.Eval(ctx), dmp.start_velocity(goal, dmp.x0 + 0.1))


def test_an_old_form_task_space_dmp_is_not_stacked_with_a_component_orientation():
    t, x, _ = sines_in_motion(912, 3, 1.0, 501)
    q = np.tile([1.0, 0.0, 0.0, 0.0], (t.size, 1))
    fingers = np.c_[0.2 + 0.1 * t, 0.3 - 0.1 * t]
    dmp = learn_task_space_dmp(t, x, q, fingers, orientation_mode="component", n_basis=30)
    old = dataclasses.replace(dmp, position=learn_dmp(t, x, n_basis=30, formulation="old"))
    with pytest.raises(RepertoireError, match="orientation DMP is in the 'new' formulation"):
        stack_task_space_dmp(old)
    with pytest.raises(RepertoireError, match="cannot be stacked"):
        task_space_sequencer([old], [0.0], np.r_[old.position.x0, q[0], fingers[0]])
    # DmpSystem runs the parts as separate systems: the position is its own old-form rollout
    goal = old.position.x0 + 2.0 * (old.position.goal - old.position.x0)
    system = DmpSystem(old, time_step=1e-3)
    sim = Simulator(system)
    system.GetInputPort("goal_position").FixValue(sim.get_mutable_context(), goal)
    sim.AdvanceTo(0.5)
    ref = old.position.rollout(goal=goal, dt=1e-3, n_steps=500).x[-1]
    out = system.GetOutputPort("position").Eval(sim.get_context())
    np.testing.assert_allclose(out, ref, rtol=0, atol=1e-12)


def test_a_learned_mask_of_the_wrong_size_is_named(old3):
    system = DmpSystem(old3["old"], time_step=1e-3)
    ctx = system.CreateDefaultContext()
    discrete = system.GetSubsystemByName("dmp")
    sub = system.GetMutableSubsystemContext(discrete, ctx)
    with pytest.raises(RepertoireError, match=r"learned must be one bool or one per DOF \(3\)"):
        discrete.set_start(sub, np.zeros(3), np.zeros(3), learned=[True, False])
    discrete.set_start(sub, np.zeros(3), old3["old"].v0, learned=[True, False, True])
    goal = np.array([2.0, -1.0, 0.5])
    system.GetInputPort("goal").FixValue(ctx, goal)
    scale = old3["old"].start_scale(goal, np.zeros(3))
    expected = old3["old"].v0 * np.array([scale[0], 1.0, scale[2]])
    np.testing.assert_allclose(system.GetOutputPort("velocity").Eval(ctx), expected, rtol=1e-14)


def test_start_scale_closed_form():
    # s = (g - x0) / (learned g - learned x0) per DOF in the old form; 1 where the learned
    # displacement is 0 (eq. 1 cannot scale it) and everywhere in the new form
    dmp = learn_dmp(np.linspace(0, 1, 5), np.zeros((5, 1)), n_basis=2)  # shapes only
    old = dataclasses.replace(
        dmp,
        weights=np.zeros((3, 2)),
        K=np.full(3, 100.0),
        D=np.full(3, 20.0),
        x0=np.array([1.0, 0.0, 2.0]),
        goal=np.array([3.0, 0.0, 1.0]),
        v0=np.array([0.5, 1.0, 0.0]),
        formulation="old",
    )
    goal, x0 = np.array([-3.0, 5.0, 7.0]), np.array([1.0, 1.0, 1.0])
    np.testing.assert_array_equal(old.start_scale(goal, x0), [-2.0, 1.0, -6.0])
    np.testing.assert_array_equal(old.start_velocity(goal, x0), [-1.0, 1.0, 0.0])
    assert old.scales_start_velocity()  # v0 = 0.5 in the moved DOF 0
    assert not dataclasses.replace(old, v0=np.array([0.0, 1.0, 0.0])).scales_start_velocity()
    new = dataclasses.replace(old, formulation="new")
    np.testing.assert_array_equal(new.start_scale(goal, x0), np.ones(3))
    assert not new.scales_start_velocity()
    with pytest.raises(RepertoireError, match="goal must have 3 entries"):
        old.start_scale(np.zeros(2), x0)


def test_old_form_learning_from_several_demonstrations_ignores_their_amplitudes():
    # Eq. 5 learns each demonstration divided by its g - x0, so two demonstrations and their
    # copies rescaled (about their starts) to the mean displacement learn one DMP. The start
    # velocity was the mean of the raw ones: v0 (0.72, -0.51) against (1.94, 0.73), rollouts
    # 2.5 % of the range apart. It is now averaged divided by g - x0 too.
    tA, xA, _ = sines_in_motion(995, 2, 1.0, 501)
    tB, xB, _ = sines_in_motion(996, 2, 1.0, 501)
    target = 0.5 * ((xA[-1] - xA[0]) + (xB[-1] - xB[0]))
    rescaled = [xA[0] + (xA - xA[0]) * target / (xA[-1] - xA[0])]
    rescaled.append(xB[0] + (xB - xB[0]) * target / (xB[-1] - xB[0]))
    one = learn_dmp_from_demonstrations([(tA, xA), (tB, xB)], n_basis=30, formulation="old")
    two = learn_dmp_from_demonstrations(
        [(tA, rescaled[0]), (tB, rescaled[1])], n_basis=30, formulation="old"
    )
    np.testing.assert_allclose(one.v0, two.v0, rtol=1e-12)
    r1, r2 = one.rollout(dt=1e-3), two.rollout(dt=1e-3)
    np.testing.assert_allclose(r1.x, r2.x, rtol=0, atol=1e-10 * np.ptp(r1.x, axis=0).max())
    # one demonstration: the same v0 as learn_dmp (v0 / (g - x0) (g - x0))
    single = learn_dmp_from_demonstrations([(tA, xA)], n_basis=30, formulation="old")
    np.testing.assert_allclose(single.v0, learn_dmp(tA, xA, n_basis=30, formulation="old").v0)
