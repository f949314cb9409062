"""GoToPose's control law, compiled once for the LeafSystem and for the planners' rollouts.

:class:`~repertoire.systems.go_to_pose.GoToPose` calls :func:`law`, :func:`arrived` and
:func:`rate_limit` at each update; :func:`rollout` closes the same functions around a
kinematic unicycle for many drives at once (a planner's prediction of the path the law
drives: it arcs off the straight line to the goal). One compiled math, so the
prediction cannot drift from the controller. Compiled by numba (``cache=True``: once,
then loaded from ``__pycache__``); everything here is in this one file, so numba's
check of the file's time stamp covers it.

The gains are a vector in :data:`~repertoire.systems.go_to_pose.GOTO_GAINS` order:
``v_max, omega_max, a_max, alpha_max, k_rho, k_alpha, k_beta, position_tolerance,
heading_tolerance, timeout``.
"""

import math

import numba
import numpy as np

V_MAX, OMEGA_MAX, A_MAX, ALPHA_MAX, K_RHO, K_ALPHA, K_BETA, POS_TOL, HEAD_TOL, TIMEOUT = range(10)


@numba.njit(cache=True)
def wrap(a: float) -> float:
    """An angle wrapped to (-pi, pi] (as ``features.wrap_angle``).

    ``pi - (pi - a) % 2 pi``; the modulo is skipped where ``pi - a`` already lies in
    ``[0, 2 pi)`` (there it returns its argument exactly: the same bits, without the call).
    """
    t = math.pi - a
    if 0.0 <= t < 2.0 * math.pi:
        return math.pi - t
    return math.pi - t % (2.0 * math.pi)


@numba.njit(cache=True)
def turn_in_place(heading_error: float, k_alpha: float, omega_max: float) -> float:
    """The pose law's in-place turn: ``clip(k_alpha heading_error, -1, 1) omega_max``."""
    return min(max(k_alpha * heading_error, -1.0), 1.0) * omega_max


@numba.njit(cache=True)
def law(x, y, phi, xg, yg, phig, vg, g):
    """Unlimited ``(v, omega)`` of the polar pose law and ``(rho, heading_error)``.

    ``v = clip(max(v_g, k_rho rho) cos(alpha))``, ``omega = clip(k_alpha alpha + k_beta
    beta)`` (``alpha`` the turn to face the goal, ``beta`` from that direction to the goal
    heading); within the position tolerance ``v = 0`` and the robot turns in place,
    ``omega = clip(k_alpha heading_error, -1, 1) omega_max``.
    """
    dx, dy = xg - x, yg - y
    rho = math.hypot(dx, dy)
    heading_error = wrap(phig - phi)
    if rho < g[POS_TOL]:
        return 0.0, turn_in_place(heading_error, g[K_ALPHA], g[OMEGA_MAX]), rho, heading_error
    direction = math.atan2(dy, dx)
    alpha = wrap(direction - phi)
    beta = wrap(phig - direction)
    v = max(vg, g[K_RHO] * rho) * math.cos(alpha)
    omega = g[K_ALPHA] * alpha + g[K_BETA] * beta
    v = min(max(v, -g[V_MAX]), g[V_MAX])
    omega = min(max(omega, -g[OMEGA_MAX]), g[OMEGA_MAX])
    return v, omega, rho, heading_error


@numba.njit(cache=True)
def speed_tolerance(vg: float) -> float:
    """How close (m/s) the speed must be to the target speed ``vg`` on arrival."""
    return max(0.1, 0.5 * vg)


@numba.njit(cache=True)
def arrived(rho, heading_error, speed, vg, position_tolerance, heading_tolerance) -> bool:
    """Within the position and heading tolerances at about the target speed."""
    return (
        rho < position_tolerance
        and abs(heading_error) < heading_tolerance
        and abs(speed - vg) < speed_tolerance(vg)
    )


@numba.njit(cache=True)
def rate_limit(v, w, v_prev, w_prev, a_max, alpha_max, period):
    """``(v, omega)`` limited to ``a_max`` and ``alpha_max`` from the previous command."""
    dv, dw = a_max * period, alpha_max * period
    return min(max(v, v_prev - dv), v_prev + dv), min(max(w, w_prev - dw), w_prev + dw)


@numba.njit(cache=True)
def _drive(s, t, g, period, last, poses, omega):
    """One drive from state ``s`` to target ``t``: ``(arrival update or -1, updates run)``.

    Fills ``poses`` and ``omega`` where given (``poses.shape[0] > 0``).
    """
    x, y, phi, v = s[0], s[1], s[2], s[3]
    vc, wc = 0.0, 0.0
    fill = poses.shape[0] > 0
    for i in range(last + 1):
        if fill:
            poses[i, 0], poses[i, 1], poses[i, 2], poses[i, 3] = x, y, phi, v
        vl, wl, rho, err = law(x, y, phi, t[0], t[1], t[2], t[3], g)
        if arrived(rho, err, v, t[3], g[POS_TOL], g[HEAD_TOL]):
            return i, i
        if i == last:  # TIMED_OUT: the command drops to 0
            return -1, i
        vc, wc = rate_limit(vl, wl, vc, wc, g[A_MAX], g[ALPHA_MAX], period)
        if fill:
            omega[i] = wc
        x, y, phi = unicycle(x, y, phi, vc, wc, period)
        v = vc
    return -1, last


@numba.njit(cache=True)
def unicycle(x, y, phi, v, omega, period):
    """The pose after driving ``period`` on the arc of speed ``v`` and yaw rate ``omega``."""
    turn = omega * period
    half = 0.5 * turn
    chord = v * period * (math.sin(half) / half if half != 0.0 else 1.0)
    heading = phi + half
    return x + chord * math.cos(heading), y + chord * math.sin(heading), phi + turn


@numba.njit(cache=True)
def rollout(start, target, g, period, last):
    """GoToPose's drives from ``start`` to ``target`` ((n, 4) each) on a kinematic unicycle.

    Each update ``i`` (time ``i period``, the first from a zero command) computes the
    command from the state; the unicycle then moves exactly on that command's arc for a
    period, its speed the command's. Ends at arrival (:func:`arrived`) or after ``last``
    updates (the timeout). Target speeds must not need GoToPose's run-up (the caller's
    check).

    Returns:
        ``(poses (n, T + 1, 4), omega (n, T + 1), steps (n,))``: the state at each update
        (a row that ended keeps its last), the yaw rate commanded from it (0 at and after
        the end), and the update each row arrived at (-1: timed out at ``last``).
    """
    n = start.shape[0]
    steps = np.empty(n, dtype=np.int64)
    ran = np.empty(n, dtype=np.int64)
    none_p, none_w = np.empty((0, 4)), np.empty(0)
    for r in range(n):
        steps[r], ran[r] = _drive(start[r], target[r], g, period, last, none_p, none_w)
    size = ran.max() + 1 if n else 1
    poses = np.empty((n, size, 4))
    omega = np.zeros((n, size))
    for r in range(n):
        _drive(start[r], target[r], g, period, last, poses[r], omega[r])
        for i in range(ran[r] + 1, size):
            poses[r, i] = poses[r, ran[r]]
    return poses, omega, steps


@numba.njit(cache=True)
def _rect_gap(u, w, hx, hy):
    return math.hypot(max(abs(u) - hx, 0.0), max(abs(w) - hy, 0.0))


@numba.njit(cache=True)
def segment_box_gap(ax, ay, bx, by, box):
    """Exact distance of the segment ``a -> b`` from a box ``[cx, cy, yaw, hx, hy, ...]``.

    0 where it enters the footprint; the math of ``kitchen_geometry.segment_gaps``.
    """
    c, s = math.cos(box[2]), math.sin(box[2])
    hx, hy = box[3], box[4]
    dx, dy = ax - box[0], ay - box[1]
    ua, wa = c * dx + s * dy, -s * dx + c * dy
    dx, dy = bx - box[0], by - box[1]
    ub, wb = c * dx + s * dy, -s * dx + c * dy
    gap = min(_rect_gap(ua, wa, hx, hy), _rect_gap(ub, wb, hx, hy))
    du, dw = ub - ua, wb - wa
    t_in, t_out = 0.0, 1.0
    for k in range(2):
        pk, dk, half = (ua, du, hx) if k == 0 else (wa, dw, hy)
        if dk != 0.0:
            t1, t2 = (-half - pk) / dk, (half - pk) / dk
            t_in, t_out = max(t_in, min(t1, t2)), min(t_out, max(t1, t2))
        elif abs(pk) > half:
            t_in = 2.0
    if t_in <= t_out:
        return 0.0
    dd = max(du * du + dw * dw, 1e-300)
    for cu, cw in ((hx, hy), (hx, -hy), (-hx, hy), (-hx, -hy)):
        t = min(max(((cu - ua) * du + (cw - wa) * dw) / dd, 0.0), 1.0)
        gap = min(gap, math.hypot(ua + t * du - cu, wa + t * dw - cw))
    return gap


@numba.njit(cache=True)
def segment_disc_gap(ax, ay, bx, by, disc):
    """Distance of the segment ``a -> b`` from a disc ``[cx, cy, radius, ...]``'s edge."""
    du, dw = bx - ax, by - ay
    t = ((disc[0] - ax) * du + (disc[1] - ay) * dw) / max(du * du + dw * dw, 1e-300)
    t = min(max(t, 0.0), 1.0)
    return math.hypot(ax + t * du - disc[0], ay + t * dw - disc[1]) - disc[2]


@numba.njit(cache=True)
def segment_box_gaps(a, b, boxes):
    """:func:`segment_box_gap` of every segment ``a[i] -> b[i]`` ((n, >= 2)) and box: (n, k)."""
    out = np.empty((a.shape[0], boxes.shape[0]))
    for i in range(a.shape[0]):
        for j in range(boxes.shape[0]):
            out[i, j] = segment_box_gap(a[i, 0], a[i, 1], b[i, 0], b[i, 1], boxes[j])
    return out


@numba.njit(cache=True)
def segment_disc_gaps(a, b, discs):
    """:func:`segment_disc_gap` of every segment ``a[i] -> b[i]`` ((n, >= 2)) and disc: (n, j)."""
    out = np.empty((a.shape[0], discs.shape[0]))
    for i in range(a.shape[0]):
        for j in range(discs.shape[0]):
            out[i, j] = segment_disc_gap(a[i, 0], a[i, 1], b[i, 0], b[i, 1], discs[j])
    return out


@numba.njit(cache=True)
def _segment_hit(ax, ay, bx, by, run, boxes, cos, sin, discs, limits, radius):
    """The obstacle the segment enters (a box by the footprint first), or -1."""
    first = -1
    for j in range(boxes.shape[0]):  # a point's box distance less the run bounds the segment's
        lim = limits[j]
        far = max(lim, radius) + run
        if far > 0.0 and _rect_gap_squared(ax, ay, boxes[j], cos[j], sin[j]) >= far * far:
            continue
        gap = segment_box_gap(ax, ay, bx, by, boxes[j])
        if gap < radius:
            return j
        if gap < lim and first < 0:
            first = j
    if first >= 0:
        return first
    for j in range(discs.shape[0]):
        lim = limits[boxes.shape[0] + j]
        if lim != -np.inf and segment_disc_gap(ax, ay, bx, by, discs[j]) < lim:
            return boxes.shape[0] + j
    return -1


@numba.njit(cache=True)
def _rect_gap_squared(x, y, box, c, s):
    dx, dy = x - box[0], y - box[1]
    mu = max(abs(c * dx + s * dy) - box[3], 0.0)
    mw = max(abs(-s * dx + c * dy) - box[4], 0.0)
    return mu * mu + mw * mw


@numba.njit(cache=True)
def _clear_margin(x, y, boxes, cos, sin, discs, limits, radius):
    """How far the point ``(x, y)`` is from entering any obstacle's limit (or ``radius``).

    The least over the boxes of the distance from the footprint less ``max(radius,
    limits[j])``, and over the discs (``limits`` not ``-inf``) of the distance from the
    edge less the limit: a segment from within this distance of the point enters nothing.
    """
    margin = np.inf
    for j in range(boxes.shape[0]):
        need = max(limits[j], radius)
        margin = min(margin, math.sqrt(_rect_gap_squared(x, y, boxes[j], cos[j], sin[j])) - need)
    for j in range(discs.shape[0]):
        lim = limits[boxes.shape[0] + j]
        if lim != -np.inf:
            d = discs[j]
            margin = min(margin, math.hypot(x - d[0], y - d[1]) - d[2] - lim)
    return margin


#: Rounding allowance [m] of :func:`rollout_hits`' skipped checks.
SKIP_SLACK = 1e-9


@numba.njit(cache=True)
def rollout_hits(start, target, g, period, last, braking, boxes, discs, limits, radius):
    """Per drive, the first obstacle its stopping runs enter along :func:`rollout`'s path.

    At each update up to the arrival (or the timeout) the base's stopping run from the
    state (the command held a period, then braking at ``braking = (a, alpha)``: ``v
    period + v |v| / (2 a)`` along the heading, the run-time check's motion) is a segment;
    it enters box ``j`` where its distance from the footprint is below ``radius`` (the
    base, tested first) or below ``limits[r, j]`` (e.g. the held arm's reach; ``-inf``:
    never), disc ``j`` below ``limits[r, boxes + j]``.

    The updates that cannot enter anything are not tested (the same result): the base
    moves at most ``speed period`` an update (``speed`` the larger of ``v_max`` and the
    start's), and a stopping run is at most ``speed period + speed^2 / (2 a)`` long, so
    after an update whose position lies ``m`` clear of every obstacle's limit
    (:func:`_clear_margin`) the next ``(m - run) / (speed period)`` updates are clear.

    Args:
        start, target: ``(n, 4)`` as for :func:`rollout`. g, period, last: likewise.
        braking: ``(deceleration, angular deceleration)``.
        boxes: ``(k, >= 5)`` ``[cx, cy, yaw, hx, hy, ...]``. discs: ``(j, >= 3)``
            ``[cx, cy, radius, ...]``.
        limits: ``(n, k + j)`` distances below which a segment enters each obstacle.
        radius: the base's footprint radius.

    Returns:
        ``(n,)`` the obstacle index (boxes, then discs), -1 where clear.
    """
    n = start.shape[0]
    hits = np.full(n, -1, dtype=np.int64)
    cos, sin = np.cos(boxes[:, 2]), np.sin(boxes[:, 2])
    for r in range(n):
        s, t = start[r], target[r]
        x, y, phi, v = s[0], s[1], s[2], s[3]
        speed = max(g[V_MAX], abs(v))
        step = speed * period  # the most the base moves in an update
        longest = step + speed * speed / (2.0 * braking[0])  # the longest stopping run
        vc, wc = 0.0, 0.0
        skip = 0  # updates still known to be clear
        for i in range(last + 1):
            if skip > 0:
                skip -= 1
            else:
                run = v * period + v * abs(v) / (2.0 * braking[0])
                hit = _segment_hit(x, y, x + run * math.cos(phi), y + run * math.sin(phi),
                                   abs(run), boxes, cos, sin, discs, limits[r], radius)  # fmt: skip
                if hit >= 0:
                    hits[r] = hit
                    break
                free = _clear_margin(x, y, boxes, cos, sin, discs, limits[r], radius)
                free -= longest + SKIP_SLACK
                if free > step:  # (NaN: no skip; no obstacle: +inf)
                    skip = int(min(free / step, last + 1.0))
            vl, wl, rho, err = law(x, y, phi, t[0], t[1], t[2], t[3], g)
            if arrived(rho, err, v, t[3], g[POS_TOL], g[HEAD_TOL]) or i == last:
                break
            vc, wc = rate_limit(vl, wl, vc, wc, g[A_MAX], g[ALPHA_MAX], period)
            x, y, phi = unicycle(x, y, phi, vc, wc, period)
            v = vc
    return hits
