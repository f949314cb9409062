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

A step ends when all four feet are down (the policy then chooses the next one). A
foot that the played-back angles put on the ground without loading it (the PD legs
press a foot with about 3 N per mm it is commanded into the ground, so a foot
commanded within 0.2 mm of the surface stays under the contact sensor's 0.5 N) would
keep the robot waiting for ever: once a step's playback has been over for
``touchdown_delay`` with no new step chosen, every foot without contact is lowered
along the body's -z at ``touchdown_speed`` (:func:`lowered_angles`) until it touches
down, at most ``touchdown_limit``.
"""

import math

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, Context, LeafSystem
from repertoire.models.littledog.pose import wrap_angle
from repertoire.planning.step_library import LibraryStep, StepLibrary
from repertoire.systems.integral_foot_controller import corrected_angles
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


def lowered_angles(q, reach) -> np.ndarray:
    """Joint angles ``q`` (12) with each foot moved ``reach[f]`` (m) along the body's -z.

    The legs' own knee and roll branches, and as far as each leg reaches
    (:func:`~repertoire.systems.integral_foot_controller.corrected_angles` with the
    offset ``[0, 0, -reach[f]]`` as its correction); a leg with ``reach`` 0 keeps its
    angles exactly.
    """
    reach = np.asarray(reach, dtype=float)
    if reach.shape != (4,) or not np.all(np.isfinite(reach)) or np.any(reach < 0.0):
        raise RepertoireError(f"reach must be 4 finite lengths >= 0 (m), got {reach!r}")
    offsets = np.zeros((4, 3))
    offsets[:, 2] = -reach
    return corrected_angles(q, offsets)[0]


class StepExecutor(LeafSystem):
    """Plays back the steps the policy chooses.

    Discrete state ``[step index, start time, blend duration, q_from (12), pose_from (6),
    q (12), ideal pose (6), ideal pose set, reach (4)]``, updated every ``period`` (the
    commands are held between updates, as a 100 Hz controller's would be): when the
    current step's playback is over and the policy's choice is fresh (made at most
    ``1.5 period`` ago, i.e. with all four feet down after the step), the chosen step
    starts: a cubic blend of :func:`spline_duration` from the last played angles to its
    first angles, the ideal pose blended alike from the measured body pose
    (``pose_from``) to the step's start pose, then its recorded angles and poses. When
    the playback has been over for ``touchdown_delay`` and no step is chosen, each foot
    whose ``contact`` flag is 0 has its ``reach`` grown by ``touchdown_speed * period``
    (up to ``touchdown_limit``) and the held angles are :func:`lowered_angles` by it
    (see the module doc); a new step blends from those angles and resets the reach.

    Input ports:
        choice: the policy's :class:`StepChoice` (abstract).
        body_pose: measured body pose [x, y, z, roll, pitch, yaw].
        contact: 4 foot contact flags (nonzero = down), read only while waiting for a
            touchdown.

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
        touchdown_delay: float = 0.1,
        touchdown_speed: float = 0.01,
        touchdown_limit: float = 0.03,
    ) -> None:
        """Creates the system.

        Args:
        library: the step library.
        q_initial: joint angles played before the first step (12).
        period: update period (s).
        min_time: shortest blend (s).
        speed: body distance per blend second (m/s), > 0.
        turn_rate: body rotation per blend second (rad/s), > 0.
        touchdown_delay: how long after a playback ends, with no step chosen, the feet
            without contact start to be lowered (s), >= 0.
        touchdown_speed: how fast they are lowered (m/s), > 0.
        touchdown_limit: how far at most (m), >= 0 (0: never).
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
        for name, v in (
            ("min_time", min_time),
            ("touchdown_delay", touchdown_delay),
            ("touchdown_limit", touchdown_limit),
        ):
            if not (math.isfinite(v) and v >= 0.0):
                raise RepertoireError(f"{name} must be >= 0, got {v}")
        if not (math.isfinite(touchdown_speed) and touchdown_speed > 0.0):
            raise RepertoireError(f"touchdown_speed must be > 0 m/s, got {touchdown_speed}")
        self._library = library
        self._period = float(period)
        self._blend = dict(min_time=min_time, speed=speed, turn_rate=turn_rate)
        self._touchdown = (float(touchdown_delay), float(touchdown_speed), float(touchdown_limit))
        self.choice_input = self.DeclareAbstractInputPort(
            "choice", AbstractValue.Make(StepChoice())
        )
        self.body_pose_input = self.DeclareVectorInputPort("body_pose", 6)
        self.contact_input = self.DeclareVectorInputPort("contact", 4)
        self._state = self.DeclareDiscreteState(
            np.concatenate([[-1.0, 0.0, 0.0], q0, np.zeros(6), q0, np.zeros(6), [0.0], np.zeros(4)])
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
        """``(q, ideal pose or None, finished)`` for discrete state ``x`` at time ``t``.

        ``x`` is the whole state; once the playback is over the angles held are
        :func:`lowered_angles` by the state's reach.
        """
        i = int(x[0])
        reach = x[40:44]
        if i < 0:
            q = x[3:15].copy()
            return (lowered_angles(q, reach) if reach.any() else q), None, True
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
        finished = tau - x[2] >= step.duration
        if finished and reach.any():
            q = lowered_angles(q, reach)
        return q, pose, finished

    def playback_end(self, x: np.ndarray) -> float:
        """When the playback of state ``x`` is (or was) over (s); 0 before the first step."""
        i = int(x[0])
        return 0.0 if i < 0 else float(x[1] + x[2] + self._library[i].duration)

    def _grow_reach(self, context: Context, x: np.ndarray, t: float) -> None:
        """Lowers the feet without contact once the playback has waited ``touchdown_delay``."""
        delay, speed, limit = self._touchdown
        if limit == 0.0 or t < self.playback_end(x) + delay - 1e-9:
            return
        contact = self.contact_input.Eval(context)
        if not np.all(np.isfinite(contact)):
            raise RepertoireError(f"StepExecutor contact flags must be finite, got {contact}")
        reach = x[40:44]
        up = (contact == 0) & (reach < limit)
        x[40:44] = np.where(up, np.minimum(reach + speed * self._period, limit), reach)

    def _update(self, context: Context, discrete_state) -> None:
        x = context.get_discrete_state(self._state).value().copy()
        t = context.get_time()
        q, _, finished = self.playback(x, t)
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
            x[40:44] = 0.0
        elif finished:
            self._grow_reach(context, x, t)
        q, pose, _ = self.playback(x, t)
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


__all__ = [
    "StepExecutor",
    "blend_pose",
    "cubic_blend",
    "interpolate_step",
    "lowered_angles",
    "spline_duration",
]
