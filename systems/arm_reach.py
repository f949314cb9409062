"""Reach: move two arm joints to target angles and speeds, reporting a status.

Stulp & Beetz's arm-control ``reach`` (Tables 6-7) drives two joints ``a`` and
``b`` from ``[theta^a, thetadot^a, theta^b, thetadot^b]`` to a goal
``[theta_g^a, thetadot_g^a, theta_g^b, thetadot_g^b]``; the goal velocities let a
sequence of reaches pass through waypoints without stopping. This is a
joint-space controller with velocity and acceleration limits. With
``e = theta_g - theta`` (measured) the commanded joint velocity is

    u = e / |e| * min(v_max, max(|thetadot_g|, k * |e|))

(towards the goal at a speed falling linearly to the goal speed), except while the
reference moves away from the goal too close to it to come back at the goal speed: with
``s = min(|thetadot_g|, v_max)``, braking now would turn it ``|e| + |v_ref|^2 / (2
a_max)`` from the goal, and the run back from there reaches ``s`` only if that is at
least ``s^2 / (2 a_max)``; until it is, ``u = v_ref`` (it coasts on). Without that run-up
a goal passed too slowly was passed again and again at the same speed (the braking and
the run back at ``a_max`` are symmetric), a cycle through the goal that timed out after
10 s (seed 9106 of ``speed_range`` -1.5 to 1.5, and goal speeds down to 0.8 rad/s). The
reference velocity ``v_ref`` follows ``u`` at most ``a_max`` per second (norm);
the reference position integrates it, ``q_ref += v_ref * period``, and the
joints' PD tracks ``[q_ref, v_ref]``. The action succeeds when ``|e| <
position_tolerance`` and the speed is within ``speed_tolerance`` of
``|thetadot_g|``; a target outside the joint limits, one whose speed
``|thetadot_g|`` exceeds ``v_max + speed_tolerance`` (the reference never moves
faster than ``v_max``, so such a goal could only be met by chance while a faster
start slows down; it timed out after 10 s), or a non-finite target or measured
state fails at once.
"""

import math

import numpy as np
from pydrake.systems.framework import BasicVector, Context, DiscreteValues
from repertoire.systems.action_status import ActionStatus, ActionSystem, check_period

from repertoire.errors import RepertoireError

# name -> default, in the order of the numeric parameter vector.
REACH_GAINS = {
    "v_max": 1.0,  # rad/s (joint-space norm)
    "a_max": 2.0,  # rad/s^2 (joint-space norm)
    "k": 3.0,  # 1/s: speed per rad of remaining distance
    "position_tolerance": 0.03,  # rad
    "speed_tolerance": 0.15,  # rad/s
    "timeout": 10.0,  # s
}


def reach_velocity(theta, goal, gains: dict[str, float], v_ref=None) -> np.ndarray:
    """The commanded joint velocity ``u`` (before the acceleration limit).

    Args:
        theta: ``(2,)`` measured angles of joints a and b.
        goal: ``[theta_g^a, thetadot_g^a, theta_g^b, thetadot_g^b]``.
        gains: the :data:`REACH_GAINS` keys.
        v_ref: ``(2,)`` the reference's velocity; while it moves away from the goal with
            too little room to come back at the goal speed, ``u = v_ref`` (module doc).
            None: towards the goal always.
    """
    e = np.array([goal[0] - theta[0], goal[2] - theta[1]], dtype=float)
    dist = float(np.hypot(*e))
    goal_speed = math.hypot(goal[1], goal[3])
    if v_ref is not None:
        v = np.asarray(v_ref, dtype=float)
        s = min(goal_speed, gains["v_max"])
        if float(v @ e) < 0.0 and dist + float(v @ v) / (2 * gains["a_max"]) < s * s / (
            2 * gains["a_max"]
        ):
            return v.copy()
    if dist < 1e-12:
        return np.zeros(2)
    speed = min(gains["v_max"], max(goal_speed, gains["k"] * dist))
    return e / dist * speed


def limit_acceleration(v_prev, u, dv_max: float) -> np.ndarray:
    """``v_prev`` moved towards ``u`` by at most ``dv_max`` (Euclidean norm)."""
    dv = np.asarray(u, dtype=float) - np.asarray(v_prev, dtype=float)
    n = float(np.hypot(*dv))
    return np.asarray(v_prev, dtype=float) + (dv if n <= dv_max else dv * (dv_max / n))


class Reach(ActionSystem):
    """Moves two joints to target angles and speeds with velocity and acceleration limits.

    Input ports:
        state: ``[theta^a, thetadot^a, theta^b, thetadot^b]`` measured (Table 6 order).
        target: ``[theta_g^a, thetadot_g^a, theta_g^b, thetadot_g^b]``.

    Output ports:
        desired_state: ``[q_ref^a, q_ref^b, v_ref^a, v_ref^b]`` for the joints' PD.
        status: an :class:`~repertoire.systems.go_to_pose.ActionStatus` (abstract).

    Parameters: numeric parameter 0 holds :data:`REACH_GAINS` (in order),
    numeric parameter 1 the joint limits ``[a_min, a_max, b_min, b_max]``.

    Discrete state: ``[q_ref(2), v_ref(2), status]``; call :meth:`start_at`
    to set the reference to the measured start.
    """

    def __init__(
        self,
        period: float = 0.01,
        gains: dict[str, float] | None = None,
        joint_limits: tuple[float, float, float, float] = (-0.9, 2.8, 0.0, 2.6),
        initial_state=(0.0, 0.0, 0.0, 0.0),
    ):
        """Creates the action.

        Args:
            period: update period [s].
            gains: overrides of :data:`REACH_GAINS`.
            joint_limits: ``[a_min, a_max, b_min, b_max]`` [rad] (arm7's
                shoulder_flexion and elbow by default).
            initial_state: the default start ``[theta^a, thetadot^a, theta^b,
                thetadot^b]``, where the reference begins (see :meth:`start_at`).
        """
        super().__init__()
        check_period(period)
        merged = dict(REACH_GAINS)
        for k, v in (gains or {}).items():
            if k not in REACH_GAINS:
                raise RepertoireError(f"unknown Reach gain {k!r}; expected {list(REACH_GAINS)}")
            if not (math.isfinite(v) and v > 0):
                raise RepertoireError(f"Reach gain {k} must be finite and > 0, got {v}")
            merged[k] = float(v)
        lim = np.asarray(joint_limits, dtype=float)
        if (
            lim.shape != (4,)
            or not np.all(np.isfinite(lim))
            or lim[0] >= lim[1]
            or lim[2] >= lim[3]
        ):
            raise RepertoireError(
                f"joint_limits must be finite [a_min, a_max, b_min, b_max] with min < max, got "
                f"{joint_limits}"
            )
        self.period = period
        self._declare_gains(REACH_GAINS, merged)
        self._limits_index = self.DeclareNumericParameter(BasicVector(lim))
        self._state_port = self.DeclareVectorInputPort("state", 4)
        self._target_port = self.DeclareVectorInputPort("target", 4)
        x0 = np.asarray(initial_state, dtype=float)
        if x0.shape != (4,) or not np.all(np.isfinite(x0)):
            raise RepertoireError(f"initial_state must be 4 finite values, got {initial_state}")
        self._xd = self.DeclareDiscreteState(
            np.array([x0[0], x0[2], x0[1], x0[3], float(ActionStatus.RUNNING)])
        )
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        self._desired_port = self.DeclareVectorOutputPort(
            "desired_state", 4, self._calc_desired, {self.discrete_state_ticket(self._xd)}
        )
        self._declare_status_port(self._xd, 4)

    def get_state_input_port(self):
        return self._state_port

    def get_target_input_port(self):
        return self._target_port

    def get_desired_state_output_port(self):
        return self._desired_port

    def start_at(self, context: Context, theta, thetadot=(0.0, 0.0)) -> None:
        """Sets the reference to the start angles and velocities, status RUNNING."""
        context.get_mutable_discrete_state(self._xd).SetFromVector(
            [theta[0], theta[1], thetadot[0], thetadot[1], ActionStatus.RUNNING]
        )

    def _update(self, context: Context, discrete_state: DiscreteValues) -> None:
        xd = context.get_discrete_state(self._xd).get_value()
        q_ref, v_ref, status = xd[:2], xd[2:4], xd[4]
        out = discrete_state.get_mutable_vector(self._xd)
        if status != ActionStatus.RUNNING:
            # hold where the reference is; a finished reach keeps its last velocity at zero
            out.SetFromVector([*q_ref, 0.0, 0.0, status])
            return
        g = self.gains(context)
        s = self._state_port.Eval(context)
        target = self._target_port.Eval(context)
        lim = context.get_numeric_parameter(self._limits_index).get_value()
        if (
            not np.all(np.isfinite(target))
            or not np.all(np.isfinite(s))
            or not lim[0] <= target[0] <= lim[1]
            or not lim[2] <= target[2] <= lim[3]
            or math.hypot(target[1], target[3]) > g["v_max"] + g["speed_tolerance"]
        ):
            out.SetFromVector([*q_ref, 0.0, 0.0, ActionStatus.FAILED])
            return
        theta = np.array([s[0], s[2]])
        dist = float(np.hypot(target[0] - s[0], target[2] - s[2]))
        speed_error = abs(math.hypot(s[1], s[3]) - math.hypot(target[1], target[3]))
        if dist < g["position_tolerance"] and speed_error < g["speed_tolerance"]:
            out.SetFromVector([*q_ref, *v_ref, ActionStatus.SUCCEEDED])
            return
        if context.get_time() >= g["timeout"]:
            out.SetFromVector([*q_ref, 0.0, 0.0, ActionStatus.TIMED_OUT])
            return
        v_new = limit_acceleration(
            v_ref, reach_velocity(theta, target, g, v_ref), g["a_max"] * self.period
        )
        out.SetFromVector([*(q_ref + v_new * self.period), *v_new, ActionStatus.RUNNING])

    def _calc_desired(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(context.get_discrete_state(self._xd).get_value()[:4])
