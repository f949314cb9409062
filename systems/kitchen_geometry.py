"""The kitchen arm's geometry: forward/inverse kinematics, joint-space ways, obstacle tests.

Plain functions beside the actions of :mod:`repertoire.systems.kitchen_actions` (which
wrap them) and the kitchen refinement's preconditions (which call them too, so plan and
execution check the same geometry). Obstacles are upright *boxes* from the floor to
``top_z``, rows ``[cx, cy, yaw, half_x, half_y, top_z]`` (a table, the counter, a wall),
and upright *discs* (cylinders) from the floor to ``top_z``, rows ``[cx, cy, radius,
top_z]`` (a standing cup: whatever lies below its top under it is a table). An
obstacle index counts the boxes first, then the discs.
"""

import dataclasses
import math

import numpy as np
from repertoire.models.diffdrive import WHEEL_RADIUS
from repertoire.models.diffdrive.generate import (
    COLUMN_X,
    EXTEND_RANGE,
    FINGER_RANGE,
    FINGER_SIZE,
    LIFT_BASE_Z,
    LIFT_RANGE,
    YAW_RANGE,
)

from repertoire.errors import RepertoireError

FINGER_HALF = tuple(0.5 * v for v in FINGER_SIZE)  # a finger box's half sizes (slide frame) [m]
#: Largest horizontal distance of a finger box's point from the gripper centre [m].
FINGER_REACH = math.hypot(FINGER_HALF[0], FINGER_RANGE[1] + FINGER_HALF[1])


def arm_forward(q) -> np.ndarray:
    """Gripper centre ``[ax, ay, az]`` in the chassis frame for joints ``[lift, yaw, extend]``.

    ``q`` may be ``(..., 3)``: one centre per row.
    """
    lift, yaw, extend = np.moveaxis(np.asarray(q, dtype=float), -1, 0)
    return np.stack(
        [COLUMN_X + extend * np.cos(yaw), extend * np.sin(yaw), LIFT_BASE_Z + lift], axis=-1
    )


def arm_inverse(a) -> np.ndarray | None:
    """Joints ``[lift, yaw, extend]`` putting the gripper centre at ``a`` (chassis frame).

    Returns:
        The joints, or None if ``a`` is not finite or out of the arm's reach
        (joint ranges of ``models/diffdrive/generate.py``).
    """
    a = np.asarray(a, dtype=float)
    if a.shape != (3,):
        return None
    q, ok = arm_inverse_rows(a)
    return q[0] if ok[0] else None


def arm_inverse_rows(a) -> tuple[np.ndarray, np.ndarray]:
    """:func:`arm_inverse` per row of ``a`` ``(n, 3)``: joints ``(n, 3)`` and ``(n,)`` in reach."""
    a = np.atleast_2d(np.asarray(a, dtype=float))
    dx, dy = a[:, 0] - COLUMN_X, a[:, 1]
    q = np.stack([a[:, 2] - LIFT_BASE_Z, np.arctan2(dy, dx), np.hypot(dx, dy)], axis=-1)
    ok = np.all(np.isfinite(a), axis=1)
    for j, (lo, hi) in enumerate((LIFT_RANGE, YAW_RANGE, EXTEND_RANGE)):
        ok &= (q[:, j] >= lo - 1e-9) & (q[:, j] <= hi + 1e-9)
    return q, ok


def joint_line(q_from, q_to, spacing: float = 0.01, reach: float = 0.0) -> np.ndarray:
    """Joints ``(n, 3)`` along the straight joint-space line ``q_from -> q_to`` (both ends).

    The line :func:`joint_step` drives. A point carried by the slide at most ``reach``
    (horizontally) from the gripper centre moves at most ``spacing`` between consecutive
    samples: its speed along the line is bounded by ``|d lift| + |d extend| + (max(extend)
    + reach) |d yaw|`` per unit of the line parameter.
    """
    return joint_lines(q_from, q_to, spacing, reach)[0]


@dataclasses.dataclass(frozen=True)
class ArmTracking:
    """How the arm's joints follow the straight setpoint line :func:`joint_step` drives.

    Each joint is a PD servo with a zero desired velocity: following a setpoint that
    ramps at a constant rate it lags by ``kd / kp`` (a first-order lag of that time
    constant), so the joints with different lags leave the straight joint-space line
    (the lift runs ahead of a slower yaw); and the lift, not compensated for gravity,
    hangs ``sag`` below its setpoint (``cup_sag`` more with a cup held). A reach among
    two cups whose checked line passed over a cup's rim with the 5 mm margin pushed the
    cup 49 mm: its fingers ran 4.8 mm below the line (:func:`joint_lines`).

    Attributes:
        lags: ``kd / kp`` of lift, yaw and extend [s] (>= 0).
        speeds: the setpoint's joint speed limits (lift m/s, yaw rad/s, extend m/s).
        sag: the lift's offset below its setpoint under the arm's weight [m] (>= 0).
        cup_sag: the offset a held cup adds [m] (>= 0).
    """

    lags: tuple[float, float, float]
    speeds: tuple[float, float, float]
    sag: float = 0.0
    cup_sag: float = 0.0

    def __post_init__(self) -> None:
        lags, speeds = np.asarray(self.lags, float), np.asarray(self.speeds, float)
        if lags.shape != (3,) or not np.all(np.isfinite(lags) & (lags >= 0)):
            raise RepertoireError(f"lags must be 3 finite values >= 0 s, got {self.lags}")
        if speeds.shape != (3,) or not np.all(np.isfinite(speeds) & (speeds > 0)):
            raise RepertoireError(f"speeds must be 3 finite values > 0, got {self.speeds}")
        for name in ("sag", "cup_sag"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise RepertoireError(f"{name} must be finite and >= 0 m, got {value}")


def joint_lines(
    q_from, q_to, spacing: float = 0.01, reach: float = 0.0, tracking=None, held: bool = False
) -> np.ndarray:
    """:func:`joint_line` per row of ``q_from``, ``q_to`` (``(n, 3)``): ``(n, s, 3)`` joints.

    Each row is sampled as :func:`joint_line` samples it alone (so a row's samples do not
    depend on the other rows); rows with fewer samples than the longest repeat their end.

    With ``tracking`` (:class:`ArmTracking`), the joints the arm reaches instead of the
    setpoints: the setpoint ramps from ``q_from`` to ``q_to`` in ``T = max_j |d_j| /
    speed_j``; a joint lagging by ``tau`` is at the share ``t/T - tau/T (1 - e^(-t/tau))``
    of its way at ``t <= T`` and closes the rest as ``e^(-(t-T)/tau)`` after it; the lift
    sinks by the sag (with ``held``, the cup's too) as ``1 - e^(-t/tau)``, but not below
    the lower of the way's ends (an arm at rest is measured where it rests; a cup lifted
    off a table or put down on it is held up by it there). Sampled on ``[0, T + 4
    max(tau)]`` (no joint moves faster than its setpoint, so a carried point still moves
    at most ``spacing`` between samples), ending at ``q_to``.
    """
    _check_positive(spacing=spacing)
    q0, q1 = np.atleast_2d(np.asarray(q_from, dtype=float)), np.atleast_2d(q_to).astype(float)
    d = np.abs(q1 - q0)
    length = d[:, 0] + d[:, 2] + (np.maximum(np.abs(q0[:, 2]), np.abs(q1[:, 2])) + reach) * d[:, 1]
    if tracking is None:
        count = np.maximum(2, np.ceil(length / spacing).astype(int) + 1)  # per row, as linspace
        j = np.arange(np.max(count, initial=2))[None, :]
        s = np.where(j < count[:, None] - 1, j * (1.0 / (count[:, None] - 1)), 1.0)
        return q0[:, None, :] + s[:, :, None] * (q1 - q0)[:, None, :]
    tau = np.asarray(tracking.lags, dtype=float)
    ramp = np.max(d / np.asarray(tracking.speeds, dtype=float), axis=1)  # T per row
    horizon = ramp + 4.0 * tau.max()
    # the lagged way takes this much longer than the setpoint's (at most its speeds)
    stretch = np.where(ramp > 0, horizon / np.maximum(ramp, 1e-300), 1.0)
    count = np.maximum(2, np.ceil(length * stretch / spacing).astype(int) + 1)
    j = np.arange(np.max(count, initial=2))[None, :]
    s = np.where(j < count[:, None] - 1, j * (1.0 / (count[:, None] - 1)), 1.0)
    t = (s * horizon[:, None])[:, :, None]  # (n, s, 1)
    T = ramp[:, None, None]
    lag = np.where(tau > 0, tau, 1.0)  # (3,); a joint without lag follows its setpoint
    # the share of its way each joint has made at t (n, s, 3)
    within = t / np.maximum(T, 1e-300) - lag / np.maximum(T, 1e-300) * -np.expm1(-t / lag)
    at_ramp = 1.0 - lag / np.maximum(T, 1e-300) * -np.expm1(-T / lag)
    after = 1.0 - (1.0 - at_ramp) * np.exp(-(t - T) / lag)
    share = np.where(t <= T, within, after)
    share = np.where(tau > 0, share, np.minimum(t / np.maximum(T, 1e-300), 1.0))
    share = np.where(T > 0, share, 1.0)  # no way: at its end
    sag = tracking.sag + (tracking.cup_sag if held else 0.0)
    sink = sag * -np.expm1(-t[..., 0] / (tau[0] if tau[0] > 0 else 1e-300))  # (n, s)
    q = q0[:, None, :] + share * (q1 - q0)[:, None, :]
    # the lift sinks while the arm moves, not below the way's lower end: an arm at rest is
    # measured where it rests, a cup lifted off or put down on a table stands on it there
    q[:, :, 0] = np.maximum(q[:, :, 0] - sink, np.minimum(q0[:, 0], q1[:, 0])[:, None])
    q[:, -1] = q1  # settled (on its support, or the sag left to the end's own checks)
    return q


def joint_line_points(q_from, q_to, spacing: float = 0.01) -> np.ndarray:
    """Gripper centres (chassis frame) along :func:`joint_line`, at most ``spacing`` apart."""
    return arm_forward(joint_line(q_from, q_to, spacing))


def finger_boxes(base_state, q, span, centre=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World boxes of the two fingers, each swept over a range of its positions.

    The left finger slides along the slide's +y axis, the right along -y (a finger's
    position is its centre's distance from the gripper centre); a finger moving over
    ``[inner, outer]`` sweeps one box of the finger's x and z size, from ``inner -
    FINGER_HALF[1]`` to ``outer + FINGER_HALF[1]`` along y.

    Args:
        base_state: ``[x, y, phi, ...]`` of the chassis, or one row per joint row.
        q: joints ``(n, 3)`` (or one ``(3,)``) ``[lift, yaw, extend]``.
        span: ``[[inner, outer] of the left finger, [inner, outer] of the right]`` [m].
        centre: the gripper centres (world, ``(n, 3)``) if already at hand.

    Returns:
        ``(centres (n, 2, 3), yaws (n,), halves (2, 3))``: world centres of the left and
        right boxes, their yaw (world, both the slide's) and their half sizes.
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    base = np.atleast_2d(np.asarray(base_state, dtype=float))
    span = np.asarray(span, dtype=float).reshape(2, 2)
    yaw = base[:, 2] + q[:, 1]
    offsets = 0.5 * (span[:, 0] + span[:, 1]) * np.array([1.0, -1.0])  # along the slide's y
    if centre is None:
        centre = chassis_points_to_world(base, arm_forward(q))
    centres = np.repeat(np.asarray(centre, dtype=float)[:, None, :], 2, axis=1)
    centres[:, :, 0] -= np.sin(yaw)[:, None] * offsets
    centres[:, :, 1] += np.cos(yaw)[:, None] * offsets
    halves = np.tile(FINGER_HALF, (2, 1))
    halves[:, 1] += 0.5 * (span[:, 1] - span[:, 0])
    return centres, yaw, halves


def fingers_in_boxes(base_state, q, span, boxes, margin: float = 0.0, discs=None) -> np.ndarray:
    """Per joint sample, the first obstacle a finger box enters, else -1.

    Exact for the boxes: a finger box (upright, yawed with the slide; :func:`finger_boxes`)
    meets an upright obstacle box (floor to ``top_z``, as in :func:`point_in_boxes`, grown
    by ``margin`` horizontally and on top) when their footprint rectangles overlap
    (separating axes: the four edge directions) and the finger's bottom is at most at the
    top; it meets a disc (a standing cup) when the disc's centre is at most its radius
    plus ``margin`` from the finger's footprint rectangle and the finger's bottom is at
    most at its top (plus ``margin``). Touching counts as entering.

    Args:
        base_state: ``[x, y, phi, ...]`` of the chassis, or one row per joint row.
        q: joints ``(n, 3)`` or ``(3,)``.
        span: the fingers' position ranges, as in :func:`finger_boxes`.
        boxes: ``(k, 6)`` rows ``[cx, cy, yaw, half_x, half_y, top_z]``.
        margin: obstacle growth [m].
        discs: ``(j, 4)`` rows ``[cx, cy, radius, top_z]`` (none by default).

    Returns:
        ``(n,)`` obstacle indices (boxes, then discs; -1: none).
    """
    fingers = finger_boxes(base_state, q, span)
    boxes, discs = _check_boxes(boxes), _check_discs(discs)
    hit = _finger_hits(*fingers, boxes, margin)
    on_disc = _finger_disc_hits(*fingers, discs, margin)
    return np.where((hit < 0) & (on_disc >= 0), len(boxes) + on_disc, hit)


def _finger_hits(centres, yaw, halves, boxes, margin: float) -> np.ndarray:
    """:func:`fingers_in_boxes` for finger boxes given as :func:`finger_boxes` returns them."""
    hit, fa, fb = np.full(len(yaw), -1), *_axes(yaw[:, None])  # the finger's axes, (n, 1)
    dx, dy = centres[:, :, 0], centres[:, :, 1]
    bottom = centres[:, :, 2] - halves[:, 2]
    own = {(u, v): _dot_abs(*a, *b) for u, a in enumerate((fa, fb)) for v, b in enumerate((fa, fb))}
    for i, (cx, cy, byaw, hx, hy, top) in enumerate(np.asarray(boxes, float).reshape(-1, 6)):
        ba, bb = _axes(np.array(byaw))
        d = (dx - cx, dy - cy)
        overlap = bottom <= top + margin
        for k, u in enumerate((fa, fb, ba, bb)):  # separated along u if the projections miss
            on_finger = (own[k, 0], own[k, 1]) if k < 2 else (_dot_abs(*u, *fa), _dot_abs(*u, *fb))
            r_finger = halves[:, 0] * on_finger[0] + halves[:, 1] * on_finger[1]
            r_box = (hx + margin) * _dot_abs(*u, *ba) + (hy + margin) * _dot_abs(*u, *bb)
            overlap &= _dot_abs(*u, *d) <= r_finger + r_box
        new = np.any(overlap, axis=1) & (hit < 0)
        hit[new] = i
    return hit


def finger_disc_gaps(base_state, q, span, discs) -> np.ndarray:
    """Per joint sample and disc, how far the finger boxes' footprints stay from the disc.

    The horizontal distance between the disc (a standing cup's cross-section) and the
    nearer of the two finger footprint rectangles (:func:`finger_boxes`), less the disc's
    radius: ``<= 0`` where a footprint overlaps the disc. Heights are not compared (see
    :func:`fingers_in_boxes` for the test with them, where a finger box meets a disc
    grown by ``margin`` exactly when this gap is at most ``margin`` and its bottom is at
    most ``margin`` above the top).

    Args:
        base_state: ``[x, y, phi, ...]`` of the chassis, or one row per joint row.
        q: joints ``(n, 3)`` or ``(3,)``.
        span: the fingers' position ranges, as in :func:`finger_boxes`.
        discs: ``(j, 4)`` rows ``[cx, cy, radius, top_z]``.

    Returns:
        ``(n, j)`` gaps [m].
    """
    centres, yaw, halves = finger_boxes(base_state, q, span)
    discs = _check_discs(discs)
    gaps = [_disc_distances(centres, yaw, halves, cx, cy).min(axis=1) - r
            for cx, cy, r, _ in discs]  # fmt: skip
    return np.column_stack(gaps) if gaps else np.zeros((len(yaw), 0))


def _disc_distances(centres, yaw, halves, cx: float, cy: float) -> np.ndarray:
    """``(n, 2)`` distances of the point ``(cx, cy)`` from each finger's footprint rectangle."""
    fa, fb = _axes(yaw[:, None])  # the finger's axes, (n, 1)
    d = (centres[:, :, 0] - cx, centres[:, :, 1] - cy)  # (n, 2 fingers) each
    u = np.maximum(_dot_abs(*d, *fa) - halves[:, 0], 0.0)
    w = np.maximum(_dot_abs(*d, *fb) - halves[:, 1], 0.0)
    return np.hypot(u, w)


def _finger_disc_hits(centres, yaw, halves, discs, margin: float) -> np.ndarray:
    """:func:`fingers_in_boxes`' test against discs, finger boxes as :func:`finger_boxes` gives."""
    hit = np.full(len(yaw), -1)
    for i, (cx, cy, radius, top) in enumerate(discs):
        overlap = (_disc_distances(centres, yaw, halves, cx, cy) <= radius + margin) & (
            centres[:, :, 2] - halves[:, 2] <= top + margin
        )
        new = np.any(overlap, axis=1) & (hit < 0)
        hit[new] = i
    return hit


def arm_way_hits(
    base_state,
    q_from,
    q_to,
    span,
    boxes,
    margin: float = 0.0,
    cup=None,
    spacing: float = 0.01,
    discs=None,
    finger_discs=None,
    tracking=None,
) -> np.ndarray:
    """Per row, the first obstacle the arm's straight joint-space way enters, else -1.

    The way from joints ``q_from`` to ``q_to`` (:func:`joint_lines`, any finger point at
    most ``spacing`` between samples) of the gripper centre (:func:`points_in_boxes`,
    :func:`points_in_discs`), of the finger boxes swept over ``span``
    (:func:`fingers_in_boxes`) and of a held cup's bottom disc (:func:`discs_in_boxes`,
    :func:`discs_in_discs`). A way starting inside a box (a measurement a millimetre low
    on a table top) is not an entry while it stays in it: the rest of it is checked on
    its own (not so for a disc: that way enters it).

    Args:
        base_state: ``[x, y, phi, ...]`` of the chassis, or ``(n, >= 3)``: one per way.
        q_from, q_to: ``(n, 3)`` (or ``(3,)``) start and end joints ``[lift, yaw, extend]``.
        span, boxes, margin: as in :func:`fingers_in_boxes` (the cup's margin: horizontal).
        cup: ``(drop, radius)``: a held cup's bottom disc lies ``drop`` below the centre.
        spacing: sample spacing [m].
        discs: ``(j, 4)`` upright discs ``[cx, cy, radius, top_z]`` (standing cups).
        finger_discs: ``(f, 4)`` discs only the finger boxes must keep off (a cup the
            way ends in to grip it: the gripper centre ends inside it).
        tracking: an :class:`ArmTracking`: check the way the servoed joints take off the
            straight line (:func:`joint_lines`; a held ``cup`` sags the lift more).

    Returns:
        ``(n,)`` obstacle indices (boxes, then discs, then finger discs; -1: clear).
    """
    q, boxes, discs = (
        joint_lines(q_from, q_to, spacing, FINGER_REACH, tracking, cup is not None),
        _check_boxes(boxes),
        _check_discs(discs),
    )
    n_full, discs = len(discs), np.vstack([discs, _check_discs(finger_discs)])
    (n, s), (drop, radius) = q.shape[:2], cup if cup is not None else (0.0, 0.0)
    base = np.broadcast_to(np.atleast_2d(np.asarray(base_state, dtype=float))[:, :3], (n, 3))
    # rows whose lowest point is above an obstacle or whose farthest is short of it skip it
    ends = q[:, [0, -1]]  # (the extension moves between them; the lift may dip: its sag)
    low = WHEEL_RADIUS + LIFT_BASE_Z + q[:, :, 0].min(axis=1) - max(FINGER_HALF[2], drop)
    far = COLUMN_X + ends[:, :, 2].max(axis=1) + max(FINGER_REACH, radius) + margin
    near = np.zeros((len(boxes) + len(discs), n), dtype=bool)
    for i, (_, u, w, hx, hy, top) in enumerate(_in_box_frames(base.T, boxes)):
        gap = np.hypot(np.maximum(np.abs(u) - hx, 0.0), np.maximum(np.abs(w) - hy, 0.0))
        near[i] = (low <= top + margin) & (gap <= far)
    for i, (cx, cy, r, top) in enumerate(discs, len(boxes)):
        gap = np.maximum(np.hypot(base[:, 0] - cx, base[:, 1] - cy) - r, 0.0)
        near[i] = (low <= top + margin) & (gap <= far)
    rows = np.flatnonzero(near.any(axis=0))  # the ways near any obstacle, sampled
    inside, flat, at_base = np.full((n, s), -1), q[rows].reshape(-1, 3), np.repeat(base[rows], s, 0)
    centre = chassis_points_to_world(at_base, arm_forward(flat))
    fingers = finger_boxes(at_base, flat, span, centre)
    for i in range(len(near)):
        at = np.flatnonzero(near[i, rows])  # positions in rows
        if at.size == 0:
            continue
        k = (at[:, None] * s + np.arange(s)).ravel()  # their samples
        hit = _arm_samples_in(i, centre[k], (fingers[0][k], fingers[1][k], fingers[2]), boxes,
                              discs, n_full, margin, cup)  # fmt: skip
        sub = inside[rows[at]]
        sub[hit.reshape(-1, s) & (sub < 0)] = i  # the first obstacle in order, as one by one
        inside[rows[at]] = sub
    return first_entry(inside, len(boxes))


def first_entry(inside: np.ndarray, n_boxes: int) -> np.ndarray:
    """Per row of samples along a way, the first obstacle it enters, else -1.

    A way starting inside a box (a measurement a millimetre low on a table top) is not an
    entry while it stays in it; the rest of it counts (a disc's start is no excuse: a way
    starting at a standing cup's edge went on through it).

    Args:
        inside: ``(n, s)`` per way and sample the obstacle the sample is in (-1: none);
            boxes are the indices below ``n_boxes``.
        n_boxes: how many of the obstacles are boxes.
    """
    n, s = inside.shape
    start = inside[:, :1]
    staying = (inside == start) & (start >= 0) & (start < n_boxes)
    left = np.where(staying.all(axis=1), s, np.argmin(staying, axis=1))
    entered = (np.arange(s)[None, :] >= left[:, None]) & (inside >= 0)
    first = np.argmax(entered, axis=1)
    return np.where(entered.any(axis=1), inside[np.arange(n), first], -1)


def _arm_samples_in(i: int, centre, fingers, boxes, discs, n_full: int, margin: float, cup):
    """Per arm sample, whether it is in obstacle ``i`` (boxes, then discs, then finger discs).

    The gripper centres ``centre`` (m, 3) and the finger boxes ``fingers`` (as
    :func:`finger_boxes` returns them) for every obstacle; a held cup's bottom disc
    (``cup = (drop, radius)``) for all but the finger discs (index ``n_full`` on among
    the discs), which only the fingers must keep off.
    """
    drop, radius = cup if cup is not None else (0.0, 0.0)
    if i < len(boxes):
        box = boxes[i]
        hit = points_in_boxes(centre, box, margin) >= 0
        hit |= _finger_hits(*fingers, box, margin) >= 0
        if cup is not None:
            hit |= discs_in_boxes(centre - [0.0, 0.0, drop], radius, box, margin) >= 0
        return hit
    disc = discs[i - len(boxes)][None]
    hit = _finger_disc_hits(*fingers, disc, margin) >= 0
    if i - len(boxes) < n_full:  # (a finger disc: the fingers only)
        hit |= points_in_discs(centre, disc, margin) >= 0
        if cup is not None:
            hit |= discs_in_discs(centre - [0.0, 0.0, drop], radius, disc, margin) >= 0
    return hit


def arm_pose_hits(
    base_states, q, span, boxes, margin: float = 0.0, cup=None, discs=None, finger_discs=None
) -> np.ndarray:
    """Per chassis pose, the obstacle the still arm (joints ``q``) is in, else -1.

    The same tests as :func:`arm_way_hits` (gripper centre, finger boxes over ``span``, a
    held cup's bottom disc; the fingers alone against ``finger_discs``), with the joints
    fixed and the base at each row of ``base_states`` (a base that drives or turns with
    the arm held out). Only the obstacles within the arm's reach of some pose and above
    its lowest point are tested.

    Args:
        base_states: ``(n, >= 3)`` chassis poses ``[x, y, phi, ...]``.
        q: the arm's joints ``[lift, yaw, extend]``.
        span, boxes, margin, cup, discs, finger_discs: as in :func:`arm_way_hits`.

    Returns:
        ``(n,)`` obstacle indices (boxes, then discs, then finger discs; -1: clear).
    """
    base = np.atleast_2d(np.asarray(base_states, dtype=float))[:, :3]
    boxes, discs = _check_boxes(boxes), _check_discs(discs)
    n_full, discs = len(discs), np.vstack([discs, _check_discs(finger_discs)])
    (drop, radius), q = cup if cup is not None else (0.0, 0.0), np.asarray(q, dtype=float)
    low = WHEEL_RADIUS + LIFT_BASE_Z + q[0] - max(FINGER_HALF[2], drop)
    far = COLUMN_X + q[2] + max(FINGER_REACH, radius) + margin  # the arm's reach
    hit = np.full(len(base), -1)
    # above an obstacle, or out of every pose's reach: not tested
    to_disc = np.hypot(base[:, :1] - discs[:, 0], base[:, 1:2] - discs[:, 1]) - discs[:, 2]
    gaps = np.concatenate([box_gaps(base, boxes).min(axis=0, initial=np.inf),
                           to_disc.min(axis=0, initial=np.inf)])  # fmt: skip
    tops = np.concatenate([boxes[:, 5], discs[:, 3]])
    near = (low <= tops + margin) & (gaps <= far)
    if not near.any():
        return hit
    centre = chassis_points_to_world(base, np.broadcast_to(arm_forward(q), base.shape))
    fingers = finger_boxes(base, np.broadcast_to(q, base.shape), span, centre)
    for i in np.flatnonzero(near):
        inside = _arm_samples_in(i, centre, fingers, boxes, discs, n_full, margin, cup)
        hit[inside & (hit < 0)] = i
    return hit


def cup_discs(
    cups, points, radius: float, half_height: float, held=(0, 1), grow: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """Standing cups as obstacle discs for an arm way (or a drive) between ``points``.

    A cup whose cylinder (``radius``, ``half_height`` about its centre) contains none of
    the world ``points`` (the gripper centre where the way starts and ends) is an obstacle
    of the whole arm: an upright disc ``[x, y, radius, z + half_height]``
    (:func:`arm_way_hits`). One containing a point whose index is in ``held`` is the cup
    held (or let go with it): none. One containing another point (a cup the reach ends in
    to grip it, or starts in with the fingers open) is an obstacle of the fingers only:
    approached from above the open fingers straddle it, from the side they push it. The
    discs' radius is grown by ``grow``.

    Args:
        cups: the cups' centres ``[x, y, z] * m`` (world).
        points: ``(p, 3)`` world points (or one).
        radius, half_height: a cup's radius and half height [m].
        held: indices of ``points`` where the gripper holds its cup.
        grow: growth of the discs' radius [m].

    Returns:
        ``(discs, finger_discs)``: rows ``[x, y, radius + grow, top_z]``.
    """
    c = np.asarray(cups, dtype=float).reshape(-1, 3)
    p = np.atleast_2d(np.asarray(points, dtype=float))
    inside = (np.hypot(*(p[None, :, :2] - c[:, None, :2]).transpose(2, 0, 1)) <= radius) & (
        np.abs(p[None, :, 2] - c[:, None, 2]) <= half_height
    )
    holding = inside[:, [i for i in range(len(p)) if i in held]].any(axis=1)
    fingers_only = inside.any(axis=1) & ~holding
    discs = np.column_stack([c[:, :2], np.full(len(c), radius + grow), c[:, 2] + half_height])
    return discs[~inside.any(axis=1)], discs[fingers_only]


def _axes(yaw: np.ndarray) -> tuple[tuple, tuple]:
    """Unit x and y axes ``((x, y), (x, y))`` of frames turned by ``yaw`` about z."""
    c, s = np.cos(yaw), np.sin(yaw)
    return (c, s), (-s, c)


def _dot_abs(ux, uy, vx, vy) -> np.ndarray:
    """``|u . v|`` of plane vectors given by their components (arrays broadcast)."""
    return np.abs(ux * vx + uy * vy)


def chassis_to_world(base_state, a) -> np.ndarray:
    """A chassis-frame point ``a`` in the world, for the chassis at ``[x, y, phi, v]``.

    The chassis frame origin is on the wheel axle, ``WHEEL_RADIUS`` above the floor.
    """
    return chassis_points_to_world(np.atleast_2d(base_state), np.atleast_2d(a))[0]


def chassis_points_to_world(base_states, a) -> np.ndarray:
    """World points ``(n, 3)`` of chassis points ``a`` (n, 3) for rows ``[x, y, phi, ...]``."""
    base, a = np.atleast_2d(base_states), np.atleast_2d(a)
    c, s = np.cos(base[:, 2]), np.sin(base[:, 2])
    return np.stack([base[:, 0] + c * a[:, 0] - s * a[:, 1],
                     base[:, 1] + s * a[:, 0] + c * a[:, 1],
                     WHEEL_RADIUS + a[:, 2]], axis=-1)  # fmt: skip


def point_in_boxes(p, boxes, margin: float = 0.0) -> int:
    """Index of the first obstacle box containing the world point ``p``, else -1.

    Args:
        p: ``[x, y, z]``.
        boxes: ``(k, 6)`` rows ``[cx, cy, yaw, half_x, half_y, top_z]``: upright boxes
            from the floor to ``top_z`` (a table, a counter), grown by ``margin`` [m]
            horizontally and on top.
    """
    return int(points_in_boxes(np.atleast_2d(p), boxes, margin)[0])


def points_in_boxes(p, boxes, margin: float = 0.0) -> np.ndarray:
    """Per world point of ``p`` ``(n, 3)`` the first box containing it, else -1.

    Vectorised :func:`point_in_boxes` (the same boxes and ``margin``).
    """
    p = np.atleast_2d(np.asarray(p, dtype=float))
    hit = np.full(len(p), -1)
    for i, u, w, hx, hy, top in _in_box_frames(p.T, boxes):
        new = (np.abs(u) <= hx + margin) & (np.abs(w) <= hy + margin) & (p[:, 2] <= top + margin)
        hit[new & (hit < 0)] = i
    return hit


def discs_in_boxes(p, radius: float, boxes, margin: float = 0.0) -> np.ndarray:
    """Per disc the first box it enters, else -1: a held cup's whole bottom, not its centre.

    A disc of ``radius`` centred at a row of ``p`` ``(n, 3)`` enters an upright box (as in
    :func:`point_in_boxes`) when its centre is at most ``radius + margin`` from the box's
    footprint and at most at its top (``margin``: horizontal only; touching enters).
    """
    p = np.atleast_2d(np.asarray(p, dtype=float))
    b = np.asarray(boxes, dtype=float).reshape(-1, 6)
    if len(b) == 0:
        return np.full(len(p), -1)
    enters = (box_gaps(p, b) <= radius + margin) & (p[:, 2:3] <= b[:, 5])
    return np.where(enters.any(axis=1), np.argmax(enters, axis=1), -1)


def points_in_discs(p, discs, margin: float = 0.0) -> np.ndarray:
    """Per world point of ``p`` ``(n, 3)`` the first upright disc containing it, else -1.

    ``discs`` rows ``[cx, cy, radius, top_z]``: cylinders from the floor to ``top_z``,
    grown by ``margin`` sideways and on top.
    """
    p = np.atleast_2d(np.asarray(p, dtype=float))
    hit = np.full(len(p), -1)
    for i, (cx, cy, r, top) in enumerate(_check_discs(discs)):
        new = (np.hypot(p[:, 0] - cx, p[:, 1] - cy) <= r + margin) & (p[:, 2] <= top + margin)
        hit[new & (hit < 0)] = i
    return hit


def discs_in_discs(p, radius: float, discs, margin: float = 0.0) -> np.ndarray:
    """Per disc of ``radius`` centred at a row of ``p`` the first upright disc it enters, else -1.

    As :func:`discs_in_boxes` (a held cup's bottom; ``margin`` sideways only) for the
    upright discs of :func:`points_in_discs`: centres at most both radii plus ``margin``
    apart, the bottom at most at the top.
    """
    p = np.atleast_2d(np.asarray(p, dtype=float))
    hit = np.full(len(p), -1)
    for i, (cx, cy, r, top) in enumerate(_check_discs(discs)):
        new = (np.hypot(p[:, 0] - cx, p[:, 1] - cy) <= r + radius + margin) & (p[:, 2] <= top)
        hit[new & (hit < 0)] = i
    return hit


def _in_box_frames(p, boxes):
    """Per box ``(index, u, w, half_x, half_y, top_z)``: ``p`` (or ``(3, n)`` columns) in it."""
    for i, (cx, cy, yaw, hx, hy, top) in enumerate(np.asarray(boxes, float).reshape(-1, 6)):
        c, s = math.cos(yaw), math.sin(yaw)
        dx, dy = p[0] - cx, p[1] - cy
        yield i, c * dx + s * dy, -s * dx + c * dy, hx, hy, top


def _box_frames(boxes) -> tuple[np.ndarray, ...]:
    """Per box row ``[cx, cy, yaw, half_x, half_y, top_z]``: ``(cx, cy, cos, sin, hx, hy)``."""
    b = np.asarray(boxes, dtype=float).reshape(-1, 6)
    c = np.array([math.cos(yaw) for yaw in b[:, 2]])
    s = np.array([math.sin(yaw) for yaw in b[:, 2]])
    return b[:, 0], b[:, 1], c, s, b[:, 3], b[:, 4]


def _in_frames(p: np.ndarray, frames) -> tuple[np.ndarray, np.ndarray]:
    """Points ``p`` (n, >= 2) in every box's frame: ``(u, w)``, (n, b) each."""
    cx, cy, c, s, _, _ = frames
    dx, dy = p[:, :1] - cx, p[:, 1:2] - cy
    return c * dx + s * dy, -s * dx + c * dy


def _rectangle_gaps(u: np.ndarray, w: np.ndarray, frames) -> np.ndarray:
    """Distances (n, b) of box-frame points from the boxes' rectangles (0 inside)."""
    hx, hy = frames[4], frames[5]
    return np.hypot(np.maximum(np.abs(u) - hx, 0.0), np.maximum(np.abs(w) - hy, 0.0))


def box_gaps(xy, boxes) -> np.ndarray:
    """Distances ``(n, b)`` of the points ``xy`` (n, >= 2) from the boxes' footprints (0 inside).

    ``boxes`` are rows ``[cx, cy, yaw, half_x, half_y, top_z]`` as in
    :func:`point_in_boxes`.
    """
    p = np.atleast_2d(np.asarray(xy, dtype=float))
    frames = _box_frames(boxes)
    return _rectangle_gaps(*_in_frames(p, frames), frames)


def segment_gaps(a, b, boxes) -> np.ndarray:
    """Exact distances ``(n, k)`` of the segments ``a -> b`` ((n, >= 2) each) from the boxes.

    In a box's frame the distance between a segment and the rectangle is 0 where the
    segment enters it (slab clipping), else the least of the end points' distances to the
    rectangle and the corners' distances to the segment (two convex sets in the plane are
    nearest at a vertex of one of them). One compiled kernel
    (:func:`~repertoire.systems.goto_law.segment_box_gap`) serves this and the planner's
    rollouts of GoToPose's drives.
    """
    from repertoire.systems.goto_law import segment_box_gaps

    a, b = np.broadcast_arrays(np.atleast_2d(a)[:, :2], np.atleast_2d(b)[:, :2])
    a, b = (np.ascontiguousarray(p, dtype=float) for p in (a, b))
    boxes = np.ascontiguousarray(np.asarray(boxes, dtype=float).reshape(-1, 6))
    return segment_box_gaps(a, b, boxes)


def segment_disc_gaps(a, b, discs) -> np.ndarray:
    """Distances ``(n, j)`` of the segments ``a -> b`` ((n, >= 2)) from upright discs' edges.

    Disc rows are ``[cx, cy, radius, ...]``; negative inside (the compiled
    :func:`~repertoire.systems.goto_law.segment_disc_gap`).
    """
    from repertoire.systems.goto_law import segment_disc_gaps as gaps

    a, b = np.broadcast_arrays(np.atleast_2d(a)[:, :2], np.atleast_2d(b)[:, :2])
    a, b = (np.ascontiguousarray(p, dtype=float) for p in (a, b))
    d = np.asarray(discs, dtype=float)
    d = d.reshape(-1, d.shape[-1] if d.ndim == 2 else 4)  # (no discs: (0, 4))
    return gaps(a, b, np.ascontiguousarray(d))


def support_under(p, boxes, radius: float, max_drop: float) -> int:
    """Index of the first obstacle box whose top holds a disc put down at ``p``, else -1.

    The disc (a cup's bottom, centre ``p``) lies wholly within the box's top
    rectangle and at most ``max_drop`` above the top (not below it).

    Args:
        p: ``[x, y, z]`` of the disc's centre (world).
        boxes: ``(k, 6)`` boxes as in :func:`point_in_boxes`.
        radius: the disc's radius [m].
        max_drop: largest height of the disc above the top [m].
    """
    for i, u, w, hx, hy, top in _in_box_frames(p, boxes):
        if abs(u) <= hx - radius and abs(w) <= hy - radius and 0.0 <= p[2] - top <= max_drop:
            return i
    return -1


def _check_boxes(boxes) -> np.ndarray:
    b = np.asarray(boxes if boxes is not None else np.zeros((0, 6)), dtype=float)
    if b.size % 6 or not np.all(np.isfinite(b)):
        raise RepertoireError(f"obstacle boxes must be finite rows of 6 values, got {boxes!r}")
    b = b.reshape(-1, 6)
    if np.any(b[:, 3:5] <= 0):
        raise RepertoireError(f"obstacle box half sizes must be > 0, got {b[:, 3:5].tolist()}")
    return b


def _check_discs(discs) -> np.ndarray:
    d = np.asarray(discs if discs is not None else np.zeros((0, 4)), dtype=float)
    if d.size % 4 or not np.all(np.isfinite(d)):
        raise RepertoireError(f"obstacle discs must be finite rows of 4 values, got {discs!r}")
    d = d.reshape(-1, 4)
    if np.any(d[:, 2] <= 0):
        raise RepertoireError(f"obstacle disc radii must be > 0, got {d[:, 2].tolist()}")
    return d


def _check_positive(**values) -> None:
    for name, v in values.items():
        if not (math.isfinite(v) and v > 0):
            raise RepertoireError(f"{name} must be finite and > 0, got {v}")
