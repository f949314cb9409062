"""StepExecutor's touchdown: a foot left unloaded after a step is lowered until it touches down.

Seen in physics (execution study, generated 31/32, start 3001 of a +-6 cm, +-20 deg config):
a recorded step put its lf foot on the ground within 1 micrometre, loaded under the contact
sensor's 0.5 N; the policy waited for all four feet down for the 29 s left, and the run
ended without crossing or falling.
"""

import numpy as np
import pytest
from pydrake.common.value import AbstractValue
from repertoire.models.littledog import LEGS, leg_fk, standing_configuration
from repertoire.planning.step_library import LibraryStep, StepLibrary
from repertoire.systems.integral_foot_controller import body_feet
from repertoire.systems.library_policy import StepChoice
from repertoire.systems.step_executor import StepExecutor, lowered_angles

from repertoire.errors import RepertoireError

Q0 = standing_configuration(0.14)


def _library() -> StepLibrary:
    rng = np.random.default_rng(3)
    steps = []
    for i in range(2):
        n = 5
        pose = np.array([0.01 * i, 0.0, 0.14, 0.0, 0.0, 0.0])
        steps.append(
            LibraryStep(
                start_feet=body_feet(Q0) + pose[:3],
                start_pose=pose,
                times=np.arange(n) * 0.01,
                q=np.repeat(Q0[None], n, 0) + rng.normal(0, 0.01, (n, 12)),
                body_pose=np.tile(pose, (n, 1)),
                stance=np.ones((n, 4), bool),
                foot=i,
                terrain="t",
                direction=0.0,
            )
        )
    return StepLibrary(steps)


def test_lowered_angles_move_each_foot_down_the_body_z_axis():
    q = lowered_angles(Q0, [0.01, 0.0, 0.002, 0.0])
    for i, leg in enumerate(LEGS):
        down = {0: 0.01, 2: 0.002}.get(i, 0.0)
        np.testing.assert_allclose(
            leg_fk(leg, q[3 * i : 3 * i + 3]),
            leg_fk(leg, Q0[3 * i : 3 * i + 3]) - [0.0, 0.0, down],
            atol=1e-12,
        )
    assert np.array_equal(q[3:6], Q0[3:6]) and np.array_equal(q[9:], Q0[9:])  # untouched
    assert np.array_equal(lowered_angles(Q0, np.zeros(4)), Q0)
    for bad in ([0.01, 0.0, 0.0], [-0.01, 0.0, 0.0, 0.0], [np.nan, 0.0, 0.0, 0.0]):
        with pytest.raises(RepertoireError, match="reach must be 4 finite lengths >= 0"):
            lowered_angles(Q0, bad)


def _started(executor, library, t0: float):
    """A context whose step 0 started at ``t0`` (blend 0.15 s) and a stale choice."""
    context = executor.CreateDefaultContext()
    step = library[0]
    executor.body_pose_input.FixValue(context, step.start_pose)
    executor.choice_input.FixValue(context, AbstractValue.Make(StepChoice(0, 0.0, t0)))
    context.SetTime(t0)
    context.SetDiscreteState(
        executor.EvalUniquePeriodicDiscreteUpdate(context).get_vector(0).value()
    )
    return context


def test_executor_lowers_an_unloaded_foot_after_the_playback_then_blends_from_there():
    library = _library()
    executor = StepExecutor(library, Q0, min_time=0.15, speed=0.1)
    context = _started(executor, library, 1.0)
    x = context.get_discrete_state(0).value()
    assert x[0] == 0 and x[2] == pytest.approx(0.15) and not x[40:44].any()
    end = 1.0 + 0.15 + library[0].duration  # 1.19 s: the playback ends
    executor.contact_input.FixValue(context, [0.0, 1.0, 1.0, 1.0])  # lf unloaded

    def tick(t):
        context.SetTime(t)
        context.SetDiscreteState(
            executor.EvalUniquePeriodicDiscreteUpdate(context).get_vector(0).value()
        )
        return context.get_discrete_state(0).value().copy()

    x = tick(end + 0.05)  # within the 0.1 s delay: the last angles are held
    assert not x[40:44].any() and np.array_equal(x[21:33], library[0].q[-1])
    x = tick(end + 0.1)  # 1 cm/s for one 10 ms period: lf 0.1 mm lower
    np.testing.assert_allclose(x[40:44], [1e-4, 0.0, 0.0, 0.0], rtol=0, atol=1e-15)
    np.testing.assert_array_equal(x[21:33], lowered_angles(library[0].q[-1], x[40:44]))
    x = tick(end + 0.11)
    np.testing.assert_allclose(x[40:44], [2e-4, 0.0, 0.0, 0.0], rtol=0, atol=1e-15)
    executor.contact_input.FixValue(context, [1.0, 1.0, 1.0, 1.0])  # down: held there
    x = tick(end + 0.12)
    np.testing.assert_allclose(x[40:44], [2e-4, 0.0, 0.0, 0.0], rtol=0, atol=1e-15)
    held = lowered_angles(library[0].q[-1], x[40:44])
    np.testing.assert_array_equal(executor.q_playback_output.Eval(context), held)
    # The policy chooses step 1: its blend starts from the lowered angles, the reach resets.
    t = end + 0.13
    executor.choice_input.FixValue(context, AbstractValue.Make(StepChoice(1, 0.01, t)))
    x = tick(t)
    assert x[0] == 1 and x[1] == t and not x[40:44].any()
    np.testing.assert_array_equal(x[3:15], held)
    np.testing.assert_array_equal(x[21:33], held)  # s = 0 of the new blend


def test_executor_reach_stops_at_its_limit_and_a_limit_of_zero_never_lowers():
    library = _library()
    executor = StepExecutor(library, Q0, touchdown_limit=0.0005, touchdown_speed=0.02)
    context = _started(executor, library, 0.0)
    executor.contact_input.FixValue(context, [0.0, 0.0, 1.0, 1.0])
    end = executor.playback_end(context.get_discrete_state(0).value())
    for k in range(10, 20):
        context.SetTime(end + 0.01 * k)
        context.SetDiscreteState(
            executor.EvalUniquePeriodicDiscreteUpdate(context).get_vector(0).value()
        )
    reach = context.get_discrete_state(0).value()[40:44]
    np.testing.assert_array_equal(reach, [5e-4, 5e-4, 0.0, 0.0])
    never = StepExecutor(library, Q0, touchdown_limit=0.0)
    context = _started(never, library, 0.0)  # contact never connected: never read
    context.SetTime(5.0)
    x = never.EvalUniquePeriodicDiscreteUpdate(context).get_vector(0).value()
    assert not x[40:44].any() and np.array_equal(x[21:33], library[0].q[-1])


def test_executor_names_bad_touchdown_settings_and_contact():
    library = _library()
    for kwargs, match in (
        (dict(touchdown_speed=0.0), "touchdown_speed must be > 0 m/s, got 0.0"),
        (dict(touchdown_delay=-0.1), "touchdown_delay must be >= 0, got -0.1"),
        (dict(touchdown_limit=np.nan), "touchdown_limit must be >= 0, got nan"),
    ):
        with pytest.raises(RepertoireError, match=match):
            StepExecutor(library, Q0, **kwargs)
    executor = StepExecutor(library, Q0)
    context = _started(executor, library, 0.0)
    executor.contact_input.FixValue(context, [np.nan, 1.0, 1.0, 1.0])
    context.SetTime(2.0)
    with pytest.raises(RepertoireError, match="contact flags must be finite"):
        executor.EvalUniquePeriodicDiscreteUpdate(context)
