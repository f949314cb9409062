"""Executes library steps: a cubic spline to the step's first angles, then playback.

Stolle et al. (section III): before a chosen step is played back, every joint
moves along a cubic spline from its current angle to the step's first angle,
taking longer the farther the body is from the step's intended start pose;
then the recorded joint angles are played back. The plain functions
:func:`spline_duration`, :func:`cubic_blend`, :func:`blend_pose` and
:func:`interpolate_step` hold the math; :class:`StepExecutor` is the LeafSystem.

The ideal body pose the executor reports (what the integral foot controller of
section IV compares the measured feet against) follows the joints: during the
blend it moves along the same cubic from the body pose MEASURED when the step
was chosen to the step's recorded start pose, then it is the recorded pose.
Reporting the start pose for the whole blend would make the controller read
the distance still to be blended (up to ~9 cm after a skipped placing move) as
foot error and wind its integrators up to their limit within 0.1 s.
"""

import math

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, Context, LeafSystem
from repertoire.models.littledog.pose import wrap_angle
from repertoire.planning.step_library import LibraryStep, StepLibrary
from repertoire.systems.library_policy import StepChoice

from repertoire.errors import RepertoireError


def spline_duration(
    body_pose, start_pose, *, min_time: float, speed: float, turn_rate: float
) -> float:
    """Duration (s) of the blend.

    ``min_time + |dxyz| / speed + max(|droll|, |dpitch|, |dyaw|) / turn_rate``.
    """
    d = np.asarray(body_pose, dtype=float) - np.asarray(start_pose, dtype=float)
    return float(
        min_time + np.linalg.norm(d[:3]) / speed + np.max(np.abs(wrap_angle(d[3:]))) / turn_rate
    )


def cubic_blend(q_from, q_to, s: float) -> np.ndarray:
    """Cubic with zero end velocities from ``q_from`` (s = 0) to ``q_to`` (s = 1)."""
    s = min(max(s, 0.0), 1.0)
    h = s * s * (3.0 - 2.0 * s)
    return np.asarray(q_from) + h * (np.asarray(q_to) - np.asarray(q_from))


def blend_pose(pose_from, pose_to, s: float) -> np.ndarray:
    """Body pose on the cubic of :func:`cubic_blend` from ``pose_from`` to ``pose_to``.

    Roll, pitch and yaw move along the shorter way.
    """
    a = np.asarray(pose_from, dtype=float)
    d = np.asarray(pose_to, dtype=float) - a
    d[3:] = wrap_angle(d[3:])
    return cubic_blend(a, a + d, s)


def interpolate_step(step: LibraryStep, tau: float) -> tuple[np.ndarray, np.ndarray]:
    """Joint angles and recorded body pose of ``step`` at ``tau`` s into its action.

    Linear between samples (yaw, roll, pitch along the shorter way); held at the ends.
    """
    t = step.times
    if tau <= 0.0:
        return step.q[0].copy(), step.body_pose[0].copy()
    if tau >= t[-1]:
        return step.q[-1].copy(), step.body_pose[-1].copy()
    k = int(np.searchsorted(t, tau, side="right")) - 1
    a = (tau - t[k]) / (t[k + 1] - t[k])
    q = step.q[k] + a * (step.q[k + 1] - step.q[k])
    d = step.body_pose[k + 1] - step.body_pose[k]
    d[3:] = wrap_angle(d[3:])
    return q, step.body_pose[k] + a * d


class StepExecutor(LeafSystem):
    """Plays back the steps the policy chooses.

    Discrete state ``[step index, start time, blend duration, q_from (12), pose_from (6),
    q (12), ideal pose (6), ideal pose set]``, updated every ``period`` (the commands are
    held between updates, as a 100 Hz controller's would be): when the current step's
    playback is over and the policy's choice is fresh (made at most ``1.5 period`` ago,
    i.e. with all four feet down after the step), the chosen step starts: a cubic blend
    of :func:`spline_duration` from the last played angles to its first angles, the
    ideal pose blended alike from the measured body pose (``pose_from``) to the step's
    start pose, then its recorded angles and poses.

    Input ports:
        choice: the policy's :class:`StepChoice` (abstract).
        body_pose: measured body pose [x, y, z, roll, pitch, yaw].

    Output ports:
        q_playback: the played-back joint angles (12, ``JOINT_NAMES`` order).
        ideal_pose: the step's recorded body pose now (during the blend, on the cubic from
            the body pose measured when the step started to the step's start pose).
        step_index: index of the step being executed (-1 before the first).
    """

    def __init__(
        self,
        library: StepLibrary,
        q_initial,
        *,
        period: float = 0.01,
        min_time: float = 0.15,
        speed: float = 0.1,
        turn_rate: float = 1.0,
    ) -> None:
        """Creates the system.

        Args:
        library: the step library.
        q_initial: joint angles played before the first step (12).
        period: update period (s).
        min_time: shortest blend (s).
        speed: body distance per blend second (m/s), > 0.
        turn_rate: body rotation per blend second (rad/s), > 0.
        """
        super().__init__()
        if not isinstance(library, StepLibrary):
            raise RepertoireError(f"StepExecutor needs a StepLibrary, got {type(library)}")
        q0 = np.asarray(q_initial, dtype=float)
        if q0.shape != (12,) or not np.all(np.isfinite(q0)):
            raise RepertoireError(f"q_initial must be 12 finite angles, got {q_initial!r}")
        for name, v in (("period", period), ("speed", speed), ("turn_rate", turn_rate)):
            if not (math.isfinite(v) and v > 0.0):
                raise RepertoireError(f"{name} must be > 0, got {v}")
        if not (math.isfinite(min_time) and min_time >= 0.0):
            raise RepertoireError(f"min_time must be >= 0 s, got {min_time}")
        self._library = library
        self._period = float(period)
        self._blend = dict(min_time=min_time, speed=speed, turn_rate=turn_rate)
        self.choice_input = self.DeclareAbstractInputPort(
            "choice", AbstractValue.Make(StepChoice())
        )
        self.body_pose_input = self.DeclareVectorInputPort("body_pose", 6)
        self._state = self.DeclareDiscreteState(
            np.concatenate([[-1.0, 0.0, 0.0], q0, np.zeros(6), q0, np.zeros(6), [0.0]])
        )
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        ticket = {self.xd_ticket()}
        self.q_playback_output = self.DeclareVectorOutputPort(
            "q_playback", 12, self._calc_q, prerequisites_of_calc=ticket
        )
        self.ideal_pose_output = self.DeclareVectorOutputPort(
            "ideal_pose", 6, self._calc_pose, prerequisites_of_calc=ticket
        )
        self.step_index_output = self.DeclareVectorOutputPort(
            "step_index", 1, self._calc_index, prerequisites_of_calc=ticket
        )

    def playback(self, x: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray | None, bool]:
        """``(q, ideal pose or None, finished)`` for discrete state ``x`` at time ``t``."""
        i = int(x[0])
        if i < 0:
            return x[3:15].copy(), None, True
        step = self._library[i]
        tau = t - x[1]
        if tau < x[2]:
            s = tau / x[2]
            return (
                cubic_blend(x[3:15], step.q[0], s),
                blend_pose(x[15:21], step.start_pose, s),
                False,
            )
        q, pose = interpolate_step(step, tau - x[2])
        return q, pose, tau - x[2] >= step.duration

    def _update(self, context: Context, discrete_state) -> None:
        x = context.get_discrete_state(self._state).value().copy()
        t = context.get_time()
        q, _, finished = self.playback(x[:21], t)
        choice = self.choice_input.Eval(context)
        body = self.body_pose_input.Eval(context)
        if not np.all(np.isfinite(body)):
            raise RepertoireError(f"StepExecutor body_pose must be finite, got {body}")
        if not choice.index < len(self._library):
            raise RepertoireError(
                f"StepExecutor: the policy chose step {choice.index} of a library of "
                f"{len(self._library)} steps (policy and executor need the same library)"
            )
        if finished and choice.index >= 0 and choice.time >= t - 1.5 * self._period:
            step = self._library[choice.index]
            T = max(spline_duration(body, step.start_pose, **self._blend), 1e-3)
            x[:21] = np.concatenate([[choice.index, t, T], q, body])
        q, pose, _ = self.playback(x[:21], t)
        x[21:33] = q
        x[33:39] = body if pose is None else pose
        x[39] = 1.0
        discrete_state.get_mutable_vector(self._state).SetFromVector(x)

    def _calc_q(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(context.get_discrete_state(self._state).value()[21:33])

    def _calc_pose(self, context: Context, output: BasicVector) -> None:
        x = context.get_discrete_state(self._state).value()
        # Before the first update the ideal pose is the measured one.
        output.SetFromVector(x[33:39] if x[39] else self.body_pose_input.Eval(context))

    def _calc_index(self, context: Context, output: BasicVector) -> None:
        output.SetAtIndex(0, context.get_discrete_state(self._state).value()[0])


__all__ = ["StepExecutor", "blend_pose", "cubic_blend", "interpolate_step", "spline_duration"]
