"""The integral foot controller of Stolle et al. (section IV).

Every foot f has a 3-D integrator I_f. The played-back joint angles j_f give the
body-relative foot position x_f = FK_f(j_f); the leg is commanded to
x_f' = x_f + I_f through inverse kinematics. The integrators are updated from
the measured state: the measured feet X_f = POSE(FK_f(j_f measured)) are
expressed in the ideal body frame (the body pose recorded with the step),
xd_f = POSE_d^-1(X_f), and I_f += k (xd_f - x_f) for feet on the ground, where
x_f is the measured body-relative foot position; a foot in flight has its
integrator decayed towards zero, so that it steps where it was recorded.

:func:`integrator_update` and :func:`corrected_angles` are the math;
:class:`IntegralFootController` is the LeafSystem (discrete state, periodic update).
"""

import math

import numpy as np
from pydrake.systems.framework import BasicVector, Context, LeafSystem
from repertoire.models.littledog import LEGS, leg_fk, leg_ik
from repertoire.models.littledog.kinematics import foot_above_pitch_axis, leg_ik_feasible
from repertoire.models.littledog.pose import body_to_world, world_to_body

from repertoire.errors import RepertoireError


def body_feet(q_joints) -> np.ndarray:
    """Body-frame foot centres (4 x 3) from 12 joint angles."""
    q = np.asarray(q_joints, dtype=float)
    if q.shape != (12,):
        raise RepertoireError(
            f"joint angles must be a 12-vector (JOINT_NAMES order), got {q.shape}"
        )
    return np.stack([leg_fk(leg, q[3 * i : 3 * i + 3]) for i, leg in enumerate(LEGS)])


def _check_integrators(integrators) -> np.ndarray:
    integrators = np.asarray(integrators, dtype=float)
    if integrators.shape != (4, 3) or not np.all(np.isfinite(integrators)):
        raise RepertoireError(
            f"integrators must be a finite 4 x 3 array (m), got shape {integrators.shape}: "
            f"{integrators!r}"
        )
    return integrators


def integrator_update(
    integrators,
    q_measured,
    body_pose,
    ideal_pose,
    contact,
    *,
    gain: float,
    decay: float,
    limit: float,
) -> np.ndarray:
    """One update of the four integrators (4 x 3).

    Args:
        integrators: current I (4 x 3, m).
        q_measured: measured joint angles (12).
        body_pose: measured body pose (6).
        ideal_pose: the recorded (ideal) body pose (6).
        contact: 4 contact flags (nonzero = down).
        gain: k, the fraction of the error added per update.
        decay: factor multiplying the integrator of a foot in flight per update, in [0, 1).
        limit: each integrator's length is saturated to this (m) (the commanded foot is
            further held inside the leg's workspace by :func:`corrected_angles`).
    """
    integrators = _check_integrators(integrators)
    contact = np.asarray(contact, dtype=float)
    if contact.shape != (4,) or not np.all(np.isfinite(contact)):
        raise RepertoireError(f"contact must be 4 finite flags, got {contact!r}")
    if not (0.0 <= gain <= 1.0 and 0.0 <= decay < 1.0):
        raise RepertoireError(f"gain must be in [0, 1] and decay in [0, 1), got {gain}, {decay}")
    if not (math.isfinite(limit) and limit > 0.0):
        raise RepertoireError(f"limit must be > 0 m, got {limit}")
    x = body_feet(q_measured)
    X = body_to_world(body_pose, x)
    xd = world_to_body(ideal_pose, X)
    down = contact != 0
    new = np.where(down[:, None], integrators + gain * (xd - x), decay * integrators)
    norm = np.linalg.norm(new, axis=1, keepdims=True)
    return np.where(norm > limit, new * (limit / np.maximum(norm, 1e-12)), new)


_SATURATION_SAMPLES = 64
"""Samples per level (two levels) of the search for a leg's reachable correction."""


def _reachable_fraction(leg: str, foot, correction, knee_sign, above) -> float:
    """The largest t in [0, 1] with ``foot + s * correction`` reachable for every s <= t.

    Resolved to 1 / 64**2 of the correction; 0 if the played-back foot itself is not.
    """
    if leg_ik_feasible(leg, foot + correction, knee_sign=knee_sign, foot_above=above):
        return 1.0
    lo, hi = 0.0, 1.0
    for _ in range(2):
        t = np.linspace(lo, hi, _SATURATION_SAMPLES + 1)
        ok = leg_ik_feasible(
            leg, foot + t[:, None] * correction, knee_sign=knee_sign, foot_above=above
        )
        if not ok[0]:
            return lo
        k = int(np.argmin(ok)) if not ok.all() else len(t) - 1
        lo, hi = float(t[k - 1]), float(t[k])
    return lo


def corrected_angles(q_playback, integrators) -> tuple[np.ndarray, int]:
    """IK(FK(q_playback) + I) per leg, on the played-back knee and roll branches.

    The branches are the played-back leg's (its knee's sign, its foot above or below the
    hip pitch axis: :func:`~repertoire.models.littledog.kinematics.foot_above_pitch_axis`),
    so a small correction never flips the leg to another solution of the IK (the IK's
    own roll-branch choice did for 962 of 80000 folded legs drawn within the limits).

    A leg with a zero integrator keeps its played-back angles exactly. A leg whose
    corrected target is out of reach (or needs a joint beyond its limits) is moved as
    far along its correction as it can go: to ``FK + t I`` with the largest t in
    [0, 1] such that every target on the way is reachable, so the correction
    saturates at the leg's workspace instead of being dropped.

    Returns:
        ``(q, saturated)``: the 12 desired angles and how many legs had their
        correction shortened.
    """
    q_playback = np.asarray(q_playback, dtype=float)
    feet = body_feet(q_playback)
    integrators = _check_integrators(integrators)
    q = q_playback.copy()
    saturated = 0
    for i, leg in enumerate(LEGS):
        if not integrators[i].any():
            continue
        knee = q_playback[3 * i + 2]
        sign = None if knee == 0.0 else float(np.sign(knee))
        above = bool(foot_above_pitch_axis(q_playback[3 * i : 3 * i + 3]))
        t = _reachable_fraction(leg, feet[i], integrators[i], sign, above)
        if t < 1.0:
            saturated += 1
        if t > 0.0:
            q[3 * i : 3 * i + 3] = leg_ik(
                leg, feet[i] + t * integrators[i], knee_sign=sign, foot_above=above
            )
    return q, saturated


class IntegralFootController(LeafSystem):
    """Corrects played-back joint angles with per-foot integrators (section IV).

    Discrete state: the 12 integrator values (I_f, ``LEGS`` order), updated every
    ``period`` by :func:`integrator_update`. Numeric parameters: ``[gain, decay]``
    (change them in a context to run an ablation, e.g. gain 0).

    Input ports:
        q_playback: played-back joint angles (12).
        ideal_pose: the recorded body pose of the step now (6).
        body_pose: measured body pose (6).
        joint_angles: measured joint angles (12).
        contact: 4 contact flags.

    Output ports:
        q_desired: corrected joint angles (12, ``JOINT_NAMES`` order).
        integrators: I_f, 12 values (m).
    """

    def __init__(
        self,
        *,
        gain: float = 0.05,
        decay: float = 0.9,
        limit: float = 0.04,
        period: float = 0.01,
    ) -> None:
        """Creates the system.

        Args:
        gain: k in [0, 1] (0 turns the controller off).
        decay: per-update factor of a flying foot's integrator, in [0, 1).
        limit: saturation of each integrator's length (m), > 0.
        period: update period (s), > 0.
        """
        super().__init__()
        if not (math.isfinite(gain) and 0.0 <= gain <= 1.0):
            raise RepertoireError(f"gain must be in [0, 1], got {gain}")
        if not (math.isfinite(decay) and 0.0 <= decay < 1.0):
            raise RepertoireError(f"decay must be in [0, 1), got {decay}")
        if not (math.isfinite(limit) and limit > 0.0):
            raise RepertoireError(f"limit must be > 0 m, got {limit}")
        if not (math.isfinite(period) and period > 0.0):
            raise RepertoireError(f"period must be > 0 s, got {period}")
        self._limit = float(limit)
        self.q_playback_input = self.DeclareVectorInputPort("q_playback", 12)
        self.ideal_pose_input = self.DeclareVectorInputPort("ideal_pose", 6)
        self.body_pose_input = self.DeclareVectorInputPort("body_pose", 6)
        self.joint_angles_input = self.DeclareVectorInputPort("joint_angles", 12)
        self.contact_input = self.DeclareVectorInputPort("contact", 4)
        self._gains = self.DeclareNumericParameter(BasicVector([gain, decay]))
        self._state = self.DeclareDiscreteState(12)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        self.q_desired_output = self.DeclareVectorOutputPort(
            "q_desired",
            12,
            self._calc_q,
            prerequisites_of_calc={self.xd_ticket(), self.q_playback_input.ticket()},
        )
        self.integrators_output = self.DeclareStateOutputPort("integrators", self._state)

    def set_gains(self, context: Context, gain: float, decay: float) -> None:
        """Sets ``[gain, decay]`` in this system's ``context``."""
        if not (0.0 <= gain <= 1.0 and 0.0 <= decay < 1.0):
            raise RepertoireError(
                f"gain must be in [0, 1] and decay in [0, 1), got {gain}, {decay}"
            )
        context.get_mutable_numeric_parameter(int(self._gains)).SetFromVector([gain, decay])

    def _update(self, context: Context, discrete_state) -> None:
        gain, decay = context.get_numeric_parameter(int(self._gains)).value()
        integrators = context.get_discrete_state(self._state).value().reshape(4, 3)
        new = integrator_update(
            integrators,
            self.joint_angles_input.Eval(context),
            self.body_pose_input.Eval(context),
            self.ideal_pose_input.Eval(context),
            self.contact_input.Eval(context),
            gain=gain,
            decay=decay,
            limit=self._limit,
        )
        discrete_state.get_mutable_vector(self._state).SetFromVector(new.reshape(12))

    def _calc_q(self, context: Context, output: BasicVector) -> None:
        integrators = context.get_discrete_state(self._state).value().reshape(4, 3)
        q, _ = corrected_angles(self.q_playback_input.Eval(context), integrators)
        output.SetFromVector(q)


__all__ = ["IntegralFootController", "body_feet", "corrected_angles", "integrator_update"]
