"""Task-space control of an arm: resolved-motion-rate IK with quaternion feedback.

Pastor et al. (2009), section IV-D: the DMP's desired end-effector position,
velocity, orientation (unit quaternion) and angular velocity are turned into
reference joint velocities by a velocity-based inverse kinematics controller;
the reference joint positions and accelerations come from integrating and
differentiating those velocities; orientation is tracked with quaternion
feedback (Yuan 1988). An inverse-dynamics feed-forward plus PD torque
controller (Drake's ``InverseDynamicsController``) then tracks the references.

The math lives in plain functions (:func:`quaternion_error`,
:func:`damped_pseudoinverse`, :func:`joint_limit_potential_gradient` with its parts
:func:`joint_limit_gradient` and :func:`joint_limit_barrier_gradient`,
:func:`null_space_projector`, :func:`speed_bounded_scale`, :func:`joint_velocity_bounds`,
:func:`rmrc_joint_velocity`, :func:`joints_held_at_limits`); :class:`ResolvedMotionRateIK`
only wraps them. The reach sphere and exact pose attainability are in
:mod:`repertoire.systems.task_space_reach`.

Quaternions are ``[w, x, y, z]`` (Drake's order), angular velocities and
Jacobians are expressed in the world frame W.
"""

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import Frame, JacobianWrtVariable
from pydrake.systems.framework import BasicVector, Context, LeafSystem, ValueProducer
from repertoire.systems.task_space_reach import finite_3vector

from repertoire.errors import RepertoireError

#: Status codes of :class:`ResolvedMotionRateIK` (output port ``status``).
STATUS_OK = 0
#: The desired position lies outside the sphere the arm can reach at all.
STATUS_TARGET_OUT_OF_REACH = 1
#: The position or the orientation error stayed above its tolerance longer than the hold
#: time (target inside the sphere but not attainable: joint limits, base, singularity).
STATUS_TRACKING_LOST = 2
#: Tracking was lost while the solve held one or more joints at a position limit: the
#: desired pose lies where the joint limits do not let this IK follow it (the output port
#: ``joints_at_limits`` says which joints, and at which limit).
STATUS_JOINT_LIMITS = 3

STATUS_NAMES = {
    STATUS_OK: "ok",
    STATUS_TARGET_OUT_OF_REACH: "target out of reach",
    STATUS_TRACKING_LOST: "task-space tracking lost",
    STATUS_JOINT_LIMITS: "task-space tracking lost at the joint limits",
}


def quaternion_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a * b`` of quaternions ``[w, x, y, z]``."""
    aw, av = a[0], np.asarray(a[1:])
    bw, bv = b[0], np.asarray(b[1:])
    return np.concatenate([[aw * bw - av @ bv], aw * bv + bw * av + np.cross(av, bv)])


def quaternion_error(q_desired: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Quaternion feedback error (Yuan 1988), the vector part of ``q_d * conj(q)``.

    ``e = eta * eps_d - eta_d * eps - eps_d x eps`` with ``q = [eta, eps]``. It is
    ``sin(theta / 2) * axis`` of the rotation ``R_d R^T`` taking the current to the
    desired orientation, expressed in the world frame; the sign is chosen for the
    shorter way round (``q`` and ``-q`` are the same rotation).

    Args:
        q_desired: desired unit quaternion ``[w, x, y, z]``.
        q: current unit quaternion ``[w, x, y, z]``.

    Returns:
        The 3-vector error; ``w_ref = w_d + K_o * e`` drives ``q`` to ``q_desired``.
    """
    q_desired = np.asarray(q_desired, dtype=float)
    q = np.asarray(q, dtype=float)
    eta_d, eps_d = q_desired[0], q_desired[1:]
    eta, eps = q[0], q[1:]
    scalar = eta_d * eta + eps_d @ eps
    e = eta * eps_d - eta_d * eps - np.cross(eps_d, eps)
    return -e if scalar < 0.0 else e


def damped_pseudoinverse(J: np.ndarray, damping: float) -> np.ndarray:
    """Damped least-squares inverse ``J^T (J J^T + damping^2 I)^-1``.

    Computed from the SVD ``J = U S V^T`` as ``V diag(s / (s^2 + damping^2)) U^T`` over
    the singular values above ``1e-10 s_max`` (so 0 gives the pseudo-inverse ``J^+``,
    also of a rank-deficient ``J``).

    Args:
        J: an ``m x n`` Jacobian.
        damping: the damping factor lambda.
    """
    return _svd_inverse_and_projector(J, damping)[0]


def joint_limit_gradient(q: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """Gradient of ``H(q) = sum(((q - q_mid) / (upper - lower))^2)``.

    ``H`` grows toward the joint limits; it is the mid-range part of
    :func:`joint_limit_potential_gradient`.

    Args:
        q: joint positions.
        lower: lower joint limits (finite).
        upper: upper joint limits (finite).
    """
    span = upper - lower
    return 2.0 * (q - 0.5 * (lower + upper)) / span**2


def joint_limit_barrier_gradient(
    q: np.ndarray, lower: np.ndarray, upper: np.ndarray, band: float
) -> np.ndarray:
    """Gradient of a joint-limit barrier that is zero away from the limits.

    ``B(q) = sum_i b_i(q_i)`` with ``d_i = band * (upper_i - lower_i)`` and

    ``b_i = ((q_i - upper_i + d_i) / d_i)^2`` above ``upper_i - d_i``,
    ``b_i = ((lower_i + d_i - q_i) / d_i)^2`` below ``lower_i + d_i``, 0 between:

    each term rises from 0 at the band's inner edge to 1 at the limit (C^1 there), so
    ``-grad B`` pushes only the joints inside a band of their limits back toward the
    middle, by ``2 / d_i`` per unit gain at the limit itself.

    Args:
        q: joint positions (n).
        lower: lower joint limits (n, finite).
        upper: upper joint limits (n, finite, above ``lower``).
        band: width of the active band as a fraction of each joint's range, in (0, 0.5].

    Raises:
        RepertoireError: a band outside (0, 0.5].
    """
    if not (np.isfinite(band) and 0.0 < band <= 0.5):
        raise RepertoireError(f"the joint-limit band must be in (0, 0.5] of the range, got {band}")
    q = np.asarray(q, dtype=float)
    d = band * (upper - lower)
    above = np.maximum(q - (upper - d), 0.0)
    below = np.maximum((lower + d) - q, 0.0)
    return 2.0 * (above - below) / d**2


def joint_limit_potential_gradient(
    q: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    *,
    mid_gain: float,
    barrier_gain: float,
    band: float,
) -> np.ndarray:
    """Gradient of the IK's secondary objective ``P = mid_gain H + barrier_gain B``.

    ``H`` prefers the middle of each joint's range everywhere
    (:func:`joint_limit_gradient`), ``B`` acts only within ``band`` of a limit
    (:func:`joint_limit_barrier_gradient`). ``-grad P`` is the joint velocity the task's
    null space follows in :func:`rmrc_joint_velocity`.

    Args:
        q: joint positions (n).
        lower: lower joint limits (n, finite).
        upper: upper joint limits (n, finite).
        mid_gain: weight of ``H`` [rad^2/s] (>= 0).
        barrier_gain: weight of ``B`` [rad^2/s] (>= 0).
        band: the barrier's band as a fraction of each joint's range, in (0, 0.5].

    Raises:
        RepertoireError: a negative or non-finite gain, or a bad band.
    """
    for name, gain in (("mid_gain", mid_gain), ("barrier_gain", barrier_gain)):
        if not (np.isfinite(gain) and gain >= 0.0):
            raise RepertoireError(f"{name} must be finite and >= 0, got {gain}")
    grad = mid_gain * joint_limit_gradient(np.asarray(q, dtype=float), lower, upper)
    if barrier_gain > 0.0:
        grad = grad + barrier_gain * joint_limit_barrier_gradient(q, lower, upper, band)
    return grad


def _svd_inverse_and_projector(
    J: np.ndarray, damping: float, rcond: float = 1e-10
) -> tuple[np.ndarray, np.ndarray]:
    """``(J#, N)`` from one SVD: damped inverse and exact null-space projector."""
    n = J.shape[1]
    U, s, Vt = np.linalg.svd(J)
    rank = int(np.sum(s > rcond * s[0])) if s.size and s[0] > 0.0 else 0
    k = np.arange(s.size) < rank
    gain = np.where(k, s / np.where(k, s**2 + damping**2, 1.0), 0.0)
    J_pinv = (Vt[: s.size].T * gain) @ U[:, : s.size].T
    V = Vt[:rank]
    return J_pinv, np.eye(n) - V.T @ V


def null_space_projector(J: np.ndarray, rcond: float = 1e-10) -> np.ndarray:
    """Orthogonal projector ``N = I - J^+ J`` onto the null space of ``J``.

    From the SVD ``J = U S V^T``: ``N = I - V_r V_r^T`` over the singular values above
    ``rcond * s_max`` (all of them when ``J`` is zero: ``N = I``). ``J N x`` is at most
    ``rcond * s_max * |x|`` for any ``x``: motion along ``N x`` changes no task velocity
    (the undamped projector; ``I - J# J`` with a damped ``J#`` leaks
    ``damping^2 (J J^T + damping^2 I)^-1 J x`` into the task).

    Args:
        J: an ``m x n`` Jacobian.
        rcond: relative singular-value cut-off of the task's range.
    """
    return _svd_inverse_and_projector(J, 0.0, rcond)[1]


def speed_bounded_scale(
    qdot_task: np.ndarray,
    qdot_null: np.ndarray,
    velocity_limits: np.ndarray,
    *,
    negligible: float = 0.0,
) -> float:
    """Largest ``a`` in [0, 1] with ``|qdot_task + a qdot_null| <= max(v_max, |qdot_task|)``.

    Per joint, the null-space motion may use the speed the task leaves below the
    velocity limit (and never adds speed to a joint the task already drives past it):
    ``a <= (c_i - t_i) / n_i`` for ``n_i > 0`` and ``a <= (c_i + t_i) / -n_i`` for
    ``n_i < 0``, with ``c_i = max(v_max_i, |t_i|)``. A joint with ``|n_i| <= negligible``
    bounds nothing (it gains at most ``negligible`` of speed): a projection's round-off
    (``n_i = +-1e-17`` at a joint the null space cannot move) must not decide ``a``.

    Args:
        qdot_task: the task's joint velocity ``t`` (n).
        qdot_null: the null-space joint velocity ``n`` (n).
        velocity_limits: ``v_max`` (n, > 0; inf for no limit).
        negligible: null-space speeds up to this are round-off [rad/s] (>= 0).
    """
    if not negligible >= 0.0:
        raise RepertoireError(f"negligible must be >= 0 rad/s, got {negligible}")
    t = np.asarray(qdot_task, dtype=float)
    v = np.asarray(qdot_null, dtype=float)
    v = np.where(np.abs(v) > negligible, v, 0.0)
    c = np.maximum(velocity_limits, np.abs(t))
    with np.errstate(divide="ignore", invalid="ignore"):
        room = np.where(v > 0.0, (c - t) / v, np.where(v < 0.0, (c + t) / -v, np.inf))
    return float(min(1.0, np.min(room))) if room.size else 1.0


def joint_velocity_bounds(
    q: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    velocity_limits: np.ndarray,
    period: float,
    deceleration: float,
) -> tuple[np.ndarray, np.ndarray]:
    """The joint-velocity box ``[lo, hi]`` of one step (as in Flacco et al. 2015).

    ``hi = min(v_max, (upper - q) / period, sqrt(2 a_max (upper - q)))`` and
    ``lo = -min(v_max, (q - lower) / period, sqrt(2 a_max (q - lower)))``: a joint that
    keeps within the box stays inside its position limits, at most ``v_max`` fast, and
    can always brake to rest at a limit with deceleration ``a_max``.

    Args:
        q: joint positions (n, within the limits).
        lower: lower joint limits (n).
        upper: upper joint limits (n).
        velocity_limits: ``v_max`` (n, > 0).
        period: the step [s] (> 0).
        deceleration: ``a_max`` [rad/s^2] (> 0; inf: no braking term).

    Returns:
        ``(lo, hi)``, ``lo <= 0 <= hi`` per joint.
    """
    up = np.maximum(upper - q, 0.0)
    down = np.maximum(q - lower, 0.0)
    hi = np.minimum(velocity_limits, up / period)
    lo = np.minimum(velocity_limits, down / period)
    if np.isfinite(deceleration):  # (inf * 0 at a joint on its limit would be NaN)
        hi = np.minimum(hi, np.sqrt(2.0 * deceleration * up))
        lo = np.minimum(lo, np.sqrt(2.0 * deceleration * down))
    return -lo, hi


def rmrc_joint_velocity(
    J: np.ndarray,
    xdot_ref: np.ndarray,
    q: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    damping: float,
    null_gain: float,
    *,
    limit_gain: float = 0.0,
    limit_band: float = 0.1,
    velocity_limits: np.ndarray | None = None,
    velocity_bounds: tuple[np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """Resolved-motion-rate joint velocity: the task within the joint bounds, then ``-grad P``.

    Without ``velocity_bounds``:
    ``qdot = J# xdot_ref + a N (-grad P(q))`` with the damped least-squares inverse ``J#``,
    the exact null-space projector ``N`` of ``J`` (:func:`null_space_projector`), the
    secondary objective ``P`` of :func:`joint_limit_potential_gradient` (``mid_gain =
    null_gain``, ``barrier_gain = limit_gain``, ``band = limit_band``) and ``a`` in [0, 1]
    from :func:`speed_bounded_scale` against ``velocity_limits`` (1 when None). ``J qdot =
    J J# xdot_ref``: the secondary motion changes no task velocity.

    With ``velocity_bounds = (lo, hi)`` (:func:`joint_velocity_bounds`) the joint limits
    are constraints of the solve (saturation in the null space, as in Flacco, De Luca and
    Khatib, IEEE T-RO 2015, without their task scaling): while the solution leaves the
    box, the joint farthest outside it is fixed at the bound it crossed (``z_j``), its
    column dropped from ``J`` (``J_W = J W``) and the law re-solved over the other joints,
    ``qdot = z + J_W# (xdot_ref - J z) + a N_W W (-grad P)``, with ``N_W`` the exact
    projector of ``J_W``. The free joints thus take the saturated joints' share of the task
    (exactly while ``J_W`` keeps the task's rank and ``damping`` is 0); when too few are
    left, ``J_W#`` gives the least-squares compromise (scale the rows of ``J`` and
    ``xdot_ref`` to weigh the task's components). At most n joints are saturated; the
    result lies in the box up to round-off (clipped to it if every joint saturated).

    Args:
        J: ``6 x n`` spatial-velocity Jacobian ``[angular; translational]`` (rows may be
            weighted, with ``xdot_ref`` weighted alike).
        xdot_ref: reference spatial velocity ``[w_ref; v_ref]`` (6).
        q: joint positions (n).
        lower: lower joint limits (n).
        upper: upper joint limits (n).
        damping: damped least-squares factor.
        null_gain: weight of the mid-range preference ``H`` in ``P`` [rad^2/s].
        limit_gain: weight of the barrier ``B`` near the limits in ``P`` [rad^2/s].
        limit_band: the barrier's band as a fraction of each joint's range.
        velocity_limits: speed bounds of the secondary motion (n; None: none).
        velocity_bounds: the hard joint-velocity box ``(lo, hi)``, ``lo <= 0 <= hi``
            (None: unbounded).
    """
    n = J.shape[1]
    qdot_0 = -joint_limit_potential_gradient(
        q, lower, upper, mid_gain=null_gain, barrier_gain=limit_gain, band=limit_band
    )
    free = np.ones(n, dtype=bool)
    z = np.zeros(n)
    for _ in range(n):
        J_pinv, N = _svd_inverse_and_projector(J * free, damping)
        # (the saturated joints' rows of J_W# and N_W are zero up to round-off: made exact)
        qdot = z + free * (J_pinv @ (xdot_ref - J @ z))
        qdot_null = free * (N @ (free * qdot_0))
        if np.any(qdot_null):
            if velocity_limits is not None:
                # (N x is exact to about 1e-16 |x|: smaller components are round-off)
                negligible = 1e-12 * np.max(np.abs(qdot_0[free]))
                qdot_null *= speed_bounded_scale(
                    qdot, qdot_null, velocity_limits, negligible=negligible
                )
            qdot = qdot + qdot_null
        if velocity_bounds is None:
            return qdot
        lo, hi = velocity_bounds
        excess = np.maximum(qdot - hi, lo - qdot)
        j = int(np.argmax(excess))
        if excess[j] <= 1e-12 * (1.0 + abs(qdot[j])):
            return qdot
        free[j] = False
        z[j] = hi[j] if qdot[j] > hi[j] else lo[j]
    return np.clip(z, *velocity_bounds)


def joints_held_at_limits(
    qdot: np.ndarray,
    velocity_bounds: tuple[np.ndarray, np.ndarray],
    velocity_limits: np.ndarray,
) -> np.ndarray:
    """Which joints a step of :func:`rmrc_joint_velocity` holds at a position limit.

    A joint is held at its upper limit (+1) when ``qdot`` is at the box's upper bound
    ``hi`` and that bound is below ``v_max``, i.e. it comes from the position limit (one
    period ahead or braking to rest there, :func:`joint_velocity_bounds`), not from the
    speed limit; likewise at its lower limit (-1). A saturated joint is set exactly at its
    bound by the solve, so the test is exact.

    Args:
        qdot: the step's joint velocity (n).
        velocity_bounds: the box ``(lo, hi)`` it was solved in.
        velocity_limits: ``v_max`` (n).

    Returns:
        Per joint +1 (held at the upper limit), -1 (at the lower) or 0, as floats (n).
    """
    lo, hi = velocity_bounds
    upper = (qdot >= hi) & (hi < velocity_limits)
    lower = (qdot <= lo) & (-lo < velocity_limits)
    return upper.astype(float) - lower.astype(float)


class ResolvedMotionRateIK(LeafSystem):
    """Resolved-motion-rate IK with quaternion feedback (Pastor et al. 2009, IV-D).

    Every ``period`` seconds the reference joint positions ``q_r`` (discrete
    state) are advanced by ``period * qdot_r`` with

    ``qdot_r = J# xdot_ref + a N (-grad P(q_r))``,
    ``xdot_ref = [w_d + K_o e_o; v_d + K_p (p_d - p(q_r))]``

    where ``J`` is the end-effector Jacobian at ``q_r`` (evaluated in a plant
    Context held in a cache entry), ``J#`` its damped least-squares inverse, ``e_o``
    the quaternion error, ``N`` the exact null-space projector of ``J`` and ``P =
    null_gain H + limit_gain B`` one secondary objective (:func:`joint_limit_potential_gradient`:
    mid-range preference everywhere plus a barrier within ``limit_band`` of a limit),
    its motion scaled by ``a`` in [0, 1] to keep within ``limit_speed_fraction`` of the
    velocity limits. The joint limits are constraints of this solve, not only of the
    secondary objective: ``qdot_r`` must lie in the box of :func:`joint_velocity_bounds`
    (velocity limits, position limits one period ahead, braking to a limit at
    ``limit_deceleration``), and a joint that would leave it is saturated and the task
    re-solved over the others (saturation in the null space, :func:`rmrc_joint_velocity`);
    the rows of ``J`` and ``xdot_ref`` are weighted by the monitor's tolerances
    (``orientation_tolerance / error_tolerance`` on the position rows, 1 on the
    orientation rows), so when the joints left cannot do the whole task, position and
    orientation give way in proportion to what the monitor allows (least squares).
    ``qdd_r`` is the backward difference of ``qdot_r``. ``q_r`` starts at the
    measured joint positions (initialisation event). The kinematic loop is closed on
    ``q_r`` (as in the paper's Fig. 11); the torque controller closes the loop on
    the measured state.

    Target monitoring: ``status`` is :data:`STATUS_TARGET_OUT_OF_REACH` as soon as
    the desired position is farther than ``max_reach`` from ``reach_center``, and
    :data:`STATUS_TRACKING_LOST` when the position error stayed above
    ``error_tolerance`` or the orientation error above ``orientation_tolerance`` for
    longer than ``error_hold_time`` (an orientation the joint limits do not allow at an
    attainable position is reported too, not followed silently);
    :data:`STATUS_JOINT_LIMITS` instead when, at that moment, the solve held one or more
    joints at a position limit (:func:`joints_held_at_limits`; the desired pose lies
    where the joint limits stop this IK, e.g. the hand's orientation beyond the wrist's
    range). The status latches.

    Input ports:
        position_desired: p_d, 3.
        velocity_desired: v_d, 3.
        orientation_desired: q_d, unit quaternion [w, x, y, z], 4.
        angular_velocity_desired: w_d in W, 3.
        arm_state_measured: [q; v] of the n arm joints, 2n.

    Output ports:
        arm_reference_state: [q_r; qdot_r], 2n.
        arm_reference_acceleration: qdd_r, n.
        status: [status code], 1 (see ``STATUS_NAMES``).
        task_error: [|p_d - p(q_r)| in m, orientation error angle in rad], 2.
        joints_at_limits: per joint +1 / -1 when the latest step held it at its upper /
            lower position limit, else 0, n (:func:`joints_held_at_limits`).

    Numeric parameter (index ``gains_parameter_index``): ``[K_p, K_o, damping,
    null_gain, limit_gain]``.
    """

    def __init__(
        self,
        plant: MultibodyPlant,
        frame_E: Frame,
        arm_velocity_indices: list[int],
        *,
        period: float = 0.004,
        position_gain: float = 20.0,
        orientation_gain: float = 20.0,
        damping: float = 0.02,
        null_gain: float = 0.5,
        limit_gain: float = 0.0,
        limit_band: float = 0.1,
        limit_speed_fraction: float = 0.5,
        limit_deceleration: float = 10.0,
        reach_center: np.ndarray | None = None,
        max_reach: float = np.inf,
        error_tolerance: float = 0.03,
        orientation_tolerance: float = 0.3,
        error_hold_time: float = 0.5,
    ):
        """Builds the IK system for a finalized control plant.

        Args:
            plant: finalized control plant (positions equal velocities for the arm
                joints). Positions not in ``arm_velocity_indices`` stay at defaults.
            frame_E: end-effector frame of ``plant``; its origin is the controlled point.
            arm_velocity_indices: indices of the n arm joints in the plant's
                position (= velocity) vector, in the order of ``arm_state_measured``.
            period: update period of the discrete reference in seconds.
            position_gain: K_p in 1/s.
            orientation_gain: K_o in 1/s.
            damping: damped least-squares factor.
            null_gain: weight of the mid-range preference in the secondary objective
                [rad^2/s] (see :func:`joint_limit_potential_gradient`).
            limit_gain: weight of the barrier that acts only within ``limit_band`` of a
                joint limit in the secondary objective [rad^2/s] (0: off).
            limit_band: the barrier's band as a fraction of each joint's range.
            limit_speed_fraction: the secondary objective's motion keeps every joint
                within this fraction of its velocity limit (or the task's own speed, if
                higher).
            limit_deceleration: the deceleration at which a joint can always brake to
                rest at its position limit [rad/s^2] (:func:`joint_velocity_bounds`).
            reach_center: shoulder point in W for the reach check.
            max_reach: reach radius in m (see
                :func:`repertoire.systems.task_space_reach.reach_bound`); inf disables.
            error_tolerance: position error in m above which tracking counts as lost.
            orientation_tolerance: orientation error angle in rad above which tracking
                counts as lost.
            error_hold_time: seconds the errors may stay above their tolerances.

        Raises:
            RepertoireError: bad period, gains, tolerances, reach sphere, indices or
                unfinalized plant.
        """
        super().__init__()
        if not plant.is_finalized():
            raise RepertoireError("ResolvedMotionRateIK needs a finalized control plant")
        if not period > 0.0:
            raise RepertoireError(f"period must be > 0 s, got {period}")
        for name, value in (
            ("position_gain", position_gain),
            ("orientation_gain", orientation_gain),
            ("damping", damping),
            ("null_gain", null_gain),
            ("limit_gain", limit_gain),
        ):
            if not (np.isfinite(value) and value >= 0.0):
                raise RepertoireError(f"{name} must be finite and >= 0, got {value}")
        for name, value in (
            ("error_tolerance", error_tolerance),
            ("orientation_tolerance", orientation_tolerance),
            ("error_hold_time", error_hold_time),
        ):
            if not (np.isfinite(value) and value > 0.0):
                raise RepertoireError(f"{name} must be finite and > 0, got {value}")
        if not (np.isfinite(limit_band) and 0.0 < limit_band <= 0.5):
            raise RepertoireError(f"limit_band must be in (0, 0.5], got {limit_band}")
        if not limit_deceleration > 0.0:
            raise RepertoireError(
                f"limit_deceleration must be > 0 rad/s^2 (inf: no braking bound), "
                f"got {limit_deceleration}"
            )
        if not (np.isfinite(limit_speed_fraction) and limit_speed_fraction > 0.0):
            raise RepertoireError(
                f"limit_speed_fraction must be finite and > 0, got {limit_speed_fraction}"
            )
        if not max_reach > 0.0:
            raise RepertoireError(f"max_reach must be > 0 m (inf disables it), got {max_reach}")
        center = np.zeros(3)
        if reach_center is not None:
            center = finite_3vector("reach_center", reach_center)
        idx = np.asarray(arm_velocity_indices, dtype=int)
        if (
            idx.ndim != 1
            or len(idx) == 0
            or len(set(idx.tolist())) != len(idx)
            or idx.min() < 0
            or idx.max() >= plant.num_velocities()
        ):
            raise RepertoireError(
                f"arm_velocity_indices must be distinct indices below {plant.num_velocities()}, "
                f"got {arm_velocity_indices}"
            )
        if plant.num_positions() != plant.num_velocities():
            raise RepertoireError("the control plant must have as many positions as velocities")
        self._plant = plant
        self._frame_E = frame_E
        self._idx = idx
        n = len(idx)
        self._n = n
        self._period = float(period)
        lower = plant.GetPositionLowerLimits()[idx]
        upper = plant.GetPositionUpperLimits()[idx]
        if not (np.all(np.isfinite(lower)) and np.all(np.isfinite(upper))):
            raise RepertoireError("every arm joint needs finite position limits")
        self._lower, self._upper = lower, upper
        v_max = plant.GetVelocityUpperLimits()[idx]
        if not np.all(v_max > 0.0):
            raise RepertoireError(f"every arm joint needs a velocity limit > 0, got {v_max}")
        self._limit_band = float(limit_band)
        self._limit_speeds = float(limit_speed_fraction) * v_max
        self._v_max = v_max
        self._deceleration = float(limit_deceleration)
        self._center = center
        self._max_reach = float(max_reach)
        self._tol = float(error_tolerance)
        self._ori_tol = float(orientation_tolerance)
        # Task rows normalised by their tolerances (1 rad of orientation error weighs as
        # much as orientation_tolerance / error_tolerance m of position error).
        self._task_weights = np.repeat([1.0, self._ori_tol / self._tol], 3)
        self._hold = float(error_hold_time)

        self._p_d = self.DeclareVectorInputPort("position_desired", 3)
        self._v_d = self.DeclareVectorInputPort("velocity_desired", 3)
        self._q_d = self.DeclareVectorInputPort("orientation_desired", 4)
        self._w_d = self.DeclareVectorInputPort("angular_velocity_desired", 3)
        self._x_meas = self.DeclareVectorInputPort("arm_state_measured", 2 * n)

        self.gains_parameter_index = self.DeclareNumericParameter(
            BasicVector([position_gain, orientation_gain, damping, null_gain, limit_gain])
        )
        # Group 0: [q_r, qdot_r, qdd_r]; group 1: [status, seconds above tolerance,
        # position error, orientation error, joints held at a limit (n)].
        self._ref_group = self.DeclareDiscreteState(3 * n)
        self._monitor_group = self.DeclareDiscreteState(4 + n)
        self.DeclarePeriodicDiscreteUpdateEvent(self._period, 0.0, self._update)
        self.DeclareInitializationDiscreteUpdateEvent(self._initialize)

        self._plant_context = self.DeclareCacheEntry(
            "control plant context at q_r",
            ValueProducer(
                allocate=lambda: AbstractValue.Make(plant.CreateDefaultContext()),
                calc=self._calc_plant_context,
            ),
            prerequisites_of_calc={self.discrete_state_ticket(self._ref_group)},
        )

        self.DeclareVectorOutputPort(
            "arm_reference_state",
            2 * n,
            lambda c, o: o.SetFromVector(c.get_discrete_state(self._ref_group).value()[: 2 * n]),
            prerequisites_of_calc={self.discrete_state_ticket(self._ref_group)},
        )
        self.DeclareVectorOutputPort(
            "arm_reference_acceleration",
            n,
            lambda c, o: o.SetFromVector(c.get_discrete_state(self._ref_group).value()[2 * n :]),
            prerequisites_of_calc={self.discrete_state_ticket(self._ref_group)},
        )
        self.DeclareVectorOutputPort(
            "status",
            1,
            lambda c, o: o.SetFromVector(c.get_discrete_state(self._monitor_group).value()[:1]),
            prerequisites_of_calc={self.discrete_state_ticket(self._monitor_group)},
        )
        self.DeclareVectorOutputPort(
            "task_error",
            2,
            lambda c, o: o.SetFromVector(c.get_discrete_state(self._monitor_group).value()[2:4]),
            prerequisites_of_calc={self.discrete_state_ticket(self._monitor_group)},
        )
        self.DeclareVectorOutputPort(
            "joints_at_limits",
            n,
            lambda c, o: o.SetFromVector(c.get_discrete_state(self._monitor_group).value()[4:]),
            prerequisites_of_calc={self.discrete_state_ticket(self._monitor_group)},
        )

    def _calc_plant_context(self, context: Context, value: AbstractValue) -> None:
        plant_context = value.get_mutable_value()
        q = self._plant.GetPositions(plant_context).copy()
        q[self._idx] = context.get_discrete_state(self._ref_group).value()[: self._n]
        self._plant.SetPositions(plant_context, q)

    @staticmethod
    def _finite_input(port, context: Context) -> np.ndarray:
        """The port's value, or a RepertoireError naming the port and the value."""
        value = port.Eval(context)
        if not np.all(np.isfinite(value)):
            raise RepertoireError(f"{port.get_name()} must be finite, got {value}")
        return value

    def _initialize(self, context: Context, discrete_state) -> None:
        n = self._n
        q_meas = self._finite_input(self._x_meas, context)[:n]
        x = np.zeros(3 * n)
        x[:n] = np.clip(q_meas, self._lower, self._upper)
        discrete_state.get_mutable_vector(self._ref_group).SetFromVector(x)
        discrete_state.get_mutable_vector(self._monitor_group).SetFromVector(np.zeros(4 + n))

    def _update(self, context: Context, discrete_state) -> None:
        n = self._n
        h = self._period
        kp, ko, damping, null_gain, limit_gain = context.get_numeric_parameter(
            self.gains_parameter_index
        ).value()
        ref = context.get_discrete_state(self._ref_group).value()
        q_r, qd_prev = ref[:n], ref[n : 2 * n]
        plant_context = self._plant_context.Eval(context)
        X_WE = self._frame_E.CalcPoseInWorld(plant_context)
        J = self._plant.CalcJacobianSpatialVelocity(
            plant_context,
            JacobianWrtVariable.kV,
            self._frame_E,
            np.zeros(3),
            self._plant.world_frame(),
            self._plant.world_frame(),
        )[:, self._idx]
        p_d, v_d, w_d = (
            self._finite_input(port, context) for port in (self._p_d, self._v_d, self._w_d)
        )
        q_d = np.asarray(self._q_d.Eval(context), dtype=float)
        norm = np.linalg.norm(q_d)
        if not (np.isfinite(norm) and abs(norm - 1.0) < 1e-3):
            raise RepertoireError(
                f"orientation_desired must be a unit quaternion [w, x, y, z], got {q_d} "
                f"(norm {norm})"
            )
        e_p = p_d - X_WE.translation()
        e_o = quaternion_error(q_d / norm, X_WE.rotation().ToQuaternion().wxyz())
        xdot_ref = np.concatenate([w_d + ko * e_o, v_d + kp * e_p])
        bounds = joint_velocity_bounds(
            q_r, self._lower, self._upper, self._v_max, h, self._deceleration
        )
        qd = rmrc_joint_velocity(
            self._task_weights[:, None] * J,
            self._task_weights * xdot_ref,
            q_r,
            self._lower,
            self._upper,
            damping,
            null_gain,
            limit_gain=limit_gain,
            limit_band=self._limit_band,
            velocity_limits=self._limit_speeds,
            velocity_bounds=bounds,
        )
        held = joints_held_at_limits(qd, bounds, self._v_max)
        q_new = np.clip(q_r + h * qd, self._lower, self._upper)
        qd = (q_new - q_r) / h
        discrete_state.get_mutable_vector(self._ref_group).SetFromVector(
            np.concatenate([q_new, qd, (qd - qd_prev) / h])
        )

        monitor = context.get_discrete_state(self._monitor_group).value()
        status, above = int(monitor[0]), monitor[1]
        pos_err = float(np.linalg.norm(e_p))
        ori_err = float(2.0 * np.arcsin(min(1.0, np.linalg.norm(e_o))))
        above = above + h if (pos_err > self._tol or ori_err > self._ori_tol) else 0.0
        if status == STATUS_OK:
            if np.linalg.norm(p_d - self._center) > self._max_reach:
                status = STATUS_TARGET_OUT_OF_REACH
            elif above > self._hold:
                status = STATUS_JOINT_LIMITS if np.any(held) else STATUS_TRACKING_LOST
        discrete_state.get_mutable_vector(self._monitor_group).SetFromVector(
            np.concatenate([[status, above, pos_err, ori_err], held])
        )
