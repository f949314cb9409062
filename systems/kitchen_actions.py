"""Kitchen actions of the diffdrive arm (Stulp & Beetz, section 2): Reach, Grip, Put.

The arm of ``models/diffdrive/diffdrive_arm.urdf`` is a cylindrical manipulator
(lift, yaw, extend) with two parallel fingers; its gripper centre in the chassis
frame is, in closed form (:func:`arm_forward`),

    a = (COLUMN_X + e cos(yaw), e sin(yaw), LIFT_BASE_Z + lift)

and :func:`arm_inverse` inverts it (the target's yaw must be within the joint
range and its horizontal distance from the column within the extend range).

Each action is a LeafSystem with a periodic discrete update, a command output
(joint setpoints for the plant's PD-controlled actuators) and a ``status`` output
(:class:`~repertoire.systems.go_to_pose.ActionStatus`: running, succeeded,
failed, timed out). Motions are straight lines in joint space at limited joint
speeds, all joints arriving together. A target out of the arm's reach, or whose
point or straight joint-space way to it (in the world, given the chassis pose on
``base_state``) enters an obstacle box (a table, the counter), makes the action
fail at once, with no motion; so does a non-finite measurement (joints, fingers or
``base_state``) at any update. The way is checked for the gripper centre and for
both fingers' boxes (:func:`fingers_in_boxes`: 8 cm tall, they reach 4 cm below the
centre, and up to 9 cm to its sides), at the measured finger positions, and for a
held cup's whole bottom disc (:func:`arm_way_hits`, :func:`discs_in_boxes`). (A reach
whose way crossed a table top pushed its fingers against the table and dragged the
standing robot 0.6 m under it, then reported success in the chassis frame. A check of
the centre alone let a way 2 cm above a table's top pass with the fingers 2 cm in it.)

Grip closes the fingers and succeeds when both are blocked by an object (the
fingers stop more than ``block_margin`` short of their closed setpoint: a grasp
by contact, held by friction); closing on nothing fails.
"""

import math

import numpy as np
from pydrake.systems.framework import BasicVector, Context, DiscreteValues, LeafSystem
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
from repertoire.systems.action_status import ActionStatus, ActionSystem

from repertoire.errors import RepertoireError

ARM_JOINTS = ("arm_lift", "arm_yaw", "arm_extend")
FINGER_JOINTS = ("left_finger", "right_finger")
ARM_SPEEDS = (0.15, 0.8, 0.2)  # lift m/s, yaw rad/s, extend m/s
FINGER_SPEED = 0.05  # m/s
FINGER_OPEN = 0.075  # finger centre from the gripper centre when open [m]
FINGER_CLOSED = 0.03  # closed setpoint (the joint's lower limit) [m]
OPEN_TOLERANCE = 0.005  # a finger this close to FINGER_OPEN is measured open [m]
BLOCK_MARGIN = 0.01  # a finger this far short of closed is blocked by an object [m]
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


def joint_step(q_cmd, q_goal, speeds, dt: float) -> np.ndarray:
    """One step of a synchronized straight-line joint motion at limited speeds.

    Every joint moves towards ``q_goal`` along the straight line, scaled so the
    joint that needs the longest time moves at its speed limit; the goal is
    reached exactly on the last step.
    """
    q_cmd, q_goal = np.asarray(q_cmd, float), np.asarray(q_goal, float)
    delta = q_goal - q_cmd
    steps = np.max(np.abs(delta) / (np.asarray(speeds, float) * dt))
    if steps <= 1.0:
        return q_goal.copy()
    return q_cmd + delta / steps


def joint_line(q_from, q_to, spacing: float = 0.01, reach: float = 0.0) -> np.ndarray:
    """Joints ``(n, 3)`` along the straight joint-space line ``q_from -> q_to`` (both ends).

    The line :func:`joint_step` drives. A point carried by the slide at most ``reach``
    (horizontally) from the gripper centre moves at most ``spacing`` between consecutive
    samples: its speed along the line is bounded by ``|d lift| + |d extend| + (max(extend)
    + reach) |d yaw|`` per unit of the line parameter.
    """
    return joint_lines(q_from, q_to, spacing, reach)[0]


def joint_lines(q_from, q_to, spacing: float = 0.01, reach: float = 0.0) -> np.ndarray:
    """:func:`joint_line` per row of ``q_from``, ``q_to`` (``(n, 3)``): ``(n, s, 3)`` joints.

    Every row gets the sample count of the longest (its points at most ``spacing`` apart).
    """
    _check_positive(spacing=spacing)
    q0, q1 = np.atleast_2d(np.asarray(q_from, dtype=float)), np.atleast_2d(q_to).astype(float)
    d = np.abs(q1 - q0)
    length = d[:, 0] + d[:, 2] + (np.maximum(np.abs(q0[:, 2]), np.abs(q1[:, 2])) + reach) * d[:, 1]
    s = np.linspace(0.0, 1.0, max(2, int(math.ceil(np.max(length, initial=0.0) / spacing)) + 1))
    return q0[:, None, :] + s[None, :, None] * (q1 - q0)[:, None, :]


def joint_line_points(q_from, q_to, spacing: float = 0.01) -> np.ndarray:
    """Gripper centres (chassis frame) along :func:`joint_line`, at most ``spacing`` apart."""
    return arm_forward(joint_line(q_from, q_to, spacing))


def fingers_blocked(
    fingers, closed: float = FINGER_CLOSED, block_margin: float = BLOCK_MARGIN
) -> bool:
    """Whether both measured fingers stopped at least ``block_margin`` short of ``closed``."""
    return bool(np.all(np.asarray(fingers, dtype=float) >= closed + block_margin))


def fingers_open(fingers) -> bool:
    """Whether both measured fingers are open (within ``OPEN_TOLERANCE`` of ``FINGER_OPEN``)."""
    return bool(np.all(np.asarray(fingers, dtype=float) >= FINGER_OPEN - OPEN_TOLERANCE))


def holds_object(fingers) -> bool:
    """Whether the measured fingers hold an object (a gripped cup).

    Both are blocked short of closed (:class:`Grip`'s success test,
    :func:`fingers_blocked`) and neither is open (:func:`fingers_open`).
    """
    return fingers_blocked(fingers) and not any(fingers_open([f]) for f in fingers)


def finger_boxes(base_state, q, span) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World boxes of the two fingers, each swept over a range of its positions.

    The left finger slides along the slide's +y axis, the right along -y (a finger's
    position is its centre's distance from the gripper centre); a finger moving over
    ``[inner, outer]`` sweeps one box of the finger's x and z size, from ``inner -
    FINGER_HALF[1]`` to ``outer + FINGER_HALF[1]`` along y.

    Args:
        base_state: ``[x, y, phi, ...]`` of the chassis, or one row per joint row.
        q: joints ``(n, 3)`` (or one ``(3,)``) ``[lift, yaw, extend]``.
        span: ``[[inner, outer] of the left finger, [inner, outer] of the right]`` [m].

    Returns:
        ``(centres (n, 2, 3), yaws (n,), halves (2, 3))``: world centres of the left and
        right boxes, their yaw (world, both the slide's) and their half sizes.
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    base = np.atleast_2d(np.asarray(base_state, dtype=float))
    span = np.asarray(span, dtype=float).reshape(2, 2)
    yaw = base[:, 2] + q[:, 1]
    offsets = 0.5 * (span[:, 0] + span[:, 1]) * np.array([1.0, -1.0])  # along the slide's y
    centres = np.repeat(chassis_points_to_world(base, arm_forward(q))[:, None, :], 2, axis=1)
    centres[:, :, 0] -= np.sin(yaw)[:, None] * offsets
    centres[:, :, 1] += np.cos(yaw)[:, None] * offsets
    halves = np.tile(FINGER_HALF, (2, 1))
    halves[:, 1] += 0.5 * (span[:, 1] - span[:, 0])
    return centres, yaw, halves


def fingers_in_boxes(base_state, q, span, boxes, margin: float = 0.0) -> np.ndarray:
    """Per joint sample, the first obstacle box a finger box enters, else -1.

    Exact for the boxes: a finger box (upright, yawed with the slide; :func:`finger_boxes`)
    meets an upright obstacle box (floor to ``top_z``, as in :func:`point_in_boxes`, grown
    by ``margin`` horizontally and on top) when their footprint rectangles overlap
    (separating axes: the four edge directions) and the finger's bottom is at most at the
    top. Touching counts as entering.

    Args:
        base_state: ``[x, y, phi, ...]`` of the chassis, or one row per joint row.
        q: joints ``(n, 3)`` or ``(3,)``.
        span: the fingers' position ranges, as in :func:`finger_boxes`.
        boxes: ``(k, 6)`` rows ``[cx, cy, yaw, half_x, half_y, top_z]``.
        margin: obstacle growth [m].

    Returns:
        ``(n,)`` box indices (-1: no box).
    """
    return _finger_hits(*finger_boxes(base_state, q, span), boxes, margin)


def _finger_hits(centres, yaw, halves, boxes, margin: float) -> np.ndarray:
    """:func:`fingers_in_boxes` for finger boxes given as :func:`finger_boxes` returns them."""
    hit, (fa, fb) = np.full(len(yaw), -1), _axes(yaw[:, None])  # the finger's axes (n, 1, 2)
    for i, (cx, cy, byaw, hx, hy, top) in enumerate(np.asarray(boxes, float).reshape(-1, 6)):
        ba, bb = _axes(np.array(byaw))
        d = centres[:, :, :2] - [cx, cy]
        overlap = centres[:, :, 2] - halves[:, 2] <= top + margin
        for u in (fa, fb, ba, bb):  # separated along u if the projections do not meet
            r_finger = halves[:, 0] * _dot_abs(u, fa) + halves[:, 1] * _dot_abs(u, fb)
            r_box = (hx + margin) * _dot_abs(u, ba) + (hy + margin) * _dot_abs(u, bb)
            overlap &= _dot_abs(u, d) <= r_finger + r_box
        new = np.any(overlap, axis=1) & (hit < 0)
        hit[new] = i
    return hit


def arm_way_hits(
    base_state, q_from, q_to, span, boxes, margin: float = 0.0, cup=None, spacing: float = 0.01
) -> np.ndarray:
    """Per row, the first obstacle box the arm's straight joint-space way enters, else -1.

    The way from joints ``q_from`` to ``q_to`` (:func:`joint_lines`, any finger point at
    most ``spacing`` between samples) of the gripper centre (:func:`points_in_boxes`),
    of the finger boxes swept over ``span`` (:func:`fingers_in_boxes`) and of a held
    cup's bottom disc (:func:`discs_in_boxes`). A way starting inside a box (a
    measurement a millimetre low on a table top) is not an entry while it stays in that
    box: the rest of it is checked on its own.

    Args:
        base_state: ``[x, y, phi, ...]`` of the chassis, or ``(n, >= 3)``: one per way.
        q_from, q_to: ``(n, 3)`` (or ``(3,)``) start and end joints ``[lift, yaw, extend]``.
        span, boxes, margin: as in :func:`fingers_in_boxes` (the cup's margin: horizontal).
        cup: ``(drop, radius)``: a held cup's bottom disc lies ``drop`` below the centre.
        spacing: sample spacing [m].

    Returns:
        ``(n,)`` box indices (-1: the way is clear).
    """
    q, boxes = joint_lines(q_from, q_to, spacing, FINGER_REACH), _check_boxes(boxes)
    (n, s), (drop, radius) = q.shape[:2], cup if cup is not None else (0.0, 0.0)
    base = np.broadcast_to(np.atleast_2d(np.asarray(base_state, dtype=float))[:, :3], (n, 3))
    # rows whose lowest point is above a box or whose farthest is short of it skip it
    ends = q[:, [0, -1]]
    low = WHEEL_RADIUS + LIFT_BASE_Z + ends[:, :, 0].min(axis=1) - max(FINGER_HALF[2], drop)
    far = COLUMN_X + ends[:, :, 2].max(axis=1) + max(FINGER_REACH, radius) + margin
    near = np.zeros((len(boxes), n), dtype=bool)
    for i, (_, u, w, hx, hy, top) in enumerate(_in_box_frames(base.T, boxes)):
        gap = np.hypot(np.maximum(np.abs(u) - hx, 0.0), np.maximum(np.abs(w) - hy, 0.0))
        near[i] = (low <= top + margin) & (gap <= far)
    rows = np.flatnonzero(near.any(axis=0))  # the ways near any box, sampled
    inside, flat, at_base = np.full((n, s), -1), q[rows].reshape(-1, 3), np.repeat(base[rows], s, 0)
    centre = chassis_points_to_world(at_base, arm_forward(flat))
    fingers = finger_boxes(at_base, flat, span)
    for i, box in enumerate(boxes):
        at = np.flatnonzero(near[i, rows])  # positions in rows
        if at.size == 0:
            continue
        k = (at[:, None] * s + np.arange(s)).ravel()  # their samples
        hit = points_in_boxes(centre[k], box, margin) >= 0
        hit |= _finger_hits(fingers[0][k], fingers[1][k], fingers[2], box, margin) >= 0
        if cup is not None:
            hit |= discs_in_boxes(centre[k] - [0.0, 0.0, drop], radius, box, margin) >= 0
        sub = inside[rows[at]]
        sub[hit.reshape(-1, s) & (sub < 0)] = i  # the first box in order, as one by one
        inside[rows[at]] = sub
    staying = (inside == inside[:, :1]) & (inside[:, :1] >= 0)  # still in its start box
    left = np.where(staying.all(axis=1), s, np.argmin(staying, axis=1))
    entered = (np.arange(s)[None, :] >= left[:, None]) & (inside >= 0)
    first = np.argmax(entered, axis=1)
    return np.where(entered.any(axis=1), inside[np.arange(n), first], -1)


def _axes(yaw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit x and y axes (``(..., 2)`` each) of frames turned by ``yaw`` about z."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.stack([c, s], axis=-1), np.stack([-s, c], axis=-1)


def _dot_abs(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.abs(np.sum(u * v, axis=-1))


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
    hit = np.full(len(p), -1)
    for i, u, w, hx, hy, top in _in_box_frames(p.T, boxes):
        gap = np.hypot(np.maximum(np.abs(u) - hx, 0.0), np.maximum(np.abs(w) - hy, 0.0))
        new = (gap <= radius + margin) & (p[:, 2] <= top)
        hit[new & (hit < 0)] = i
    return hit


def _in_box_frames(p, boxes):
    """Per box ``(index, u, w, half_x, half_y, top_z)``: ``p`` (or ``(3, n)`` columns) in it."""
    for i, (cx, cy, yaw, hx, hy, top) in enumerate(np.asarray(boxes, float).reshape(-1, 6)):
        c, s = math.cos(yaw), math.sin(yaw)
        dx, dy = p[0] - cx, p[1] - cy
        yield i, c * dx + s * dy, -s * dx + c * dy, hx, hy, top


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


def _check_positive(**values) -> None:
    for name, v in values.items():
        if not (math.isfinite(v) and v > 0):
            raise RepertoireError(f"{name} must be finite and > 0, got {v}")


class _Action(ActionSystem):
    """Shared ports and state of the kitchen actions (not registered on its own)."""

    def __init__(self, period: float, timeout: float, n_command: int, boxes, margin: float):
        super().__init__()
        _check_positive(period=period, timeout=timeout)
        if not (math.isfinite(margin) and margin >= 0):
            raise RepertoireError(f"margin must be finite and >= 0, got {margin}")
        self.period, self.timeout, self.margin = period, timeout, margin
        self._n = n_command
        self._boxes = _check_boxes(boxes)
        # state: [command (n), status, started, t0, phase, t_phase]
        self._xd = self.DeclareDiscreteState(n_command + 5)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        self._base_port = self.DeclareVectorInputPort("base_state", 4)
        self._finger_port = self.DeclareVectorInputPort("finger_position", 2)
        self._declare_status_port(self._xd, n_command)

    def get_base_state_input_port(self):
        return self._base_port

    def get_finger_position_input_port(self):
        return self._finger_port

    def inside_obstacle(self, context: Context, a_chassis) -> int:
        """Index of the obstacle box containing the chassis-frame point, else -1."""
        base = self._base_port.Eval(context)
        return point_in_boxes(chassis_to_world(base, a_chassis), self._boxes, self.margin)

    def path_enters_obstacle(self, context: Context, q_from, q_to, span, cup=None) -> int:
        """Index of the first obstacle box the straight joint-space way enters, else -1.

        :func:`arm_way_hits` for the chassis on ``base_state``: the gripper centre, the
        finger boxes swept over ``span`` and, with ``cup = (drop, radius)``, a held cup's
        bottom disc.
        """
        base = self._base_port.Eval(context)
        return int(arm_way_hits(base, q_from, q_to, span, self._boxes, self.margin, cup)[0])

    def _calc_command(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(context.get_discrete_state(self._xd).get_value()[: self._n])

    def _update(self, context: Context, discrete_state: DiscreteValues) -> None:
        xd = context.get_discrete_state(self._xd).get_value().copy()
        n = self._n
        status, started = int(xd[n]), bool(xd[n + 1])
        out = discrete_state.get_mutable_vector(self._xd)
        if status != ActionStatus.RUNNING:
            out.SetFromVector(xd)
            return
        t = context.get_time()
        measured = self.measured(context)
        finite = (np.all(np.isfinite(measured))
                  and np.all(np.isfinite(self._base_port.Eval(context)))
                  and np.all(np.isfinite(self._finger_port.Eval(context))))  # fmt: skip
        if not started:
            xd[:n] = measured if finite else xd[:n]
            xd[n + 1], xd[n + 2], xd[n + 3], xd[n + 4] = 1.0, t, 0.0, t
        if not finite or (not started and not self.target_ok(context)):
            xd[n] = ActionStatus.FAILED  # a non-finite measurement, or a bad target
            out.SetFromVector(xd)
            return
        if t - xd[n + 2] >= self.timeout:
            xd[n] = ActionStatus.TIMED_OUT
            out.SetFromVector(xd)
            return
        command, status, phase = self.step(context, xd[:n], int(xd[n + 3]), t - xd[n + 4])
        xd[:n], xd[n] = command, status
        if phase != xd[n + 3]:
            xd[n + 3], xd[n + 4] = phase, t
        out.SetFromVector(xd)

    # Each action defines: measured(context) -> the command's measured start,
    # target_ok(context) -> bool (checked on the first update), and
    # step(context, command, phase, time_in_phase) -> (command, status, phase).


class Reach(_Action):
    """Moves the gripper centre to a target point in the chassis frame.

    Input ports:
        arm_position: measured ``[lift, yaw, extend]``.
        target: ``[ax_g, ay_g, az_g]`` gripper-centre target in the chassis frame.
        base_state: ``[x, y, phi, v]`` of the chassis (for the obstacle check).
        finger_position: measured ``[left, right]`` (held; for the obstacle check).

    Output ports:
        arm_command: ``[lift, yaw, extend]`` setpoints.
        status: an :class:`ActionStatus`.

    Succeeds when the measured gripper centre is within ``tolerance`` of the
    target; fails at once if the target is out of reach or it, or the straight
    joint-space way to it from the measured joints of the gripper centre or of a
    finger (at its measured position), is inside an obstacle box; times out
    ``timeout`` s after its first update. When the measured fingers hold an object
    (:func:`holds_object`: a grip blocked on a cup), the way of the cup's bottom disc
    (``cup_half_height`` below the gripper centre, of ``cup_radius``, as :class:`Put`
    checks it: :func:`discs_in_boxes`) must stay out of the boxes too (a reach carrying
    a cup level 4.5 cm over table_0's top, its fingers clear, caught the cup on the
    table's side, turned the robot 0.66 rad and reported SUCCEEDED in the chassis
    frame; the point under its centre alone missed a rim over the table's edge).
    """

    def __init__(
        self,
        period: float = 0.02,
        *,
        speeds=ARM_SPEEDS,
        tolerance: float = 0.01,
        timeout: float = 10.0,
        obstacles=None,
        margin: float = 0.0,
        cup_half_height: float = 0.05,
        cup_radius: float = 0.04,
    ):
        """Creates the action.

        Args:
            period: update period [s].
            speeds: joint speed limits (lift m/s, yaw rad/s, extend m/s).
            tolerance: success distance of the gripper centre [m].
            timeout: time limit from the first update [s].
            obstacles: ``(k, 6)`` boxes ``[cx, cy, yaw, half_x, half_y, top_z]`` (world).
            margin: obstacle growth [m].
            cup_half_height: a held cup's bottom lies this far below the gripper centre [m].
            cup_radius: a held cup's radius: its whole bottom disc is checked [m].
        """
        super().__init__(period, timeout, 3, obstacles, margin)
        _check_positive(cup_half_height=cup_half_height, cup_radius=cup_radius)
        self.cup_half_height, self.cup_radius = cup_half_height, cup_radius
        self.speeds = np.asarray(speeds, dtype=float)
        if self.speeds.shape != (3,) or not np.all(np.isfinite(self.speeds) & (self.speeds > 0)):
            raise RepertoireError(f"speeds must be 3 finite values > 0, got {speeds}")
        _check_positive(tolerance=tolerance)
        self.tolerance = tolerance
        self._arm_port = self.DeclareVectorInputPort("arm_position", 3)
        self._target_port = self.DeclareVectorInputPort("target", 3)
        self._command_port = self.DeclareVectorOutputPort(
            "arm_command", 3, self._calc_command, {self.discrete_state_ticket(self._xd)}
        )

    def get_arm_position_input_port(self):
        return self._arm_port

    def get_target_input_port(self):
        return self._target_port

    def get_command_output_port(self):
        return self._command_port

    def measured(self, context):
        return self._arm_port.Eval(context)

    def target_ok(self, context) -> bool:
        target = self._target_port.Eval(context)
        goal = arm_inverse(target)
        if goal is None or self.inside_obstacle(context, target) >= 0:
            return False
        fingers = self._finger_port.Eval(context)
        span = [[fingers[0]] * 2, [fingers[1]] * 2]  # held where they are
        q = self._arm_port.Eval(context)
        # a held cup hangs below the fingers: its bottom's way too
        cup = (self.cup_half_height, self.cup_radius) if holds_object(fingers) else None
        return self.path_enters_obstacle(context, q, goal, span, cup) < 0

    def step(self, context, command, phase, time_in_phase):
        target = self._target_port.Eval(context)
        goal = arm_inverse(target)
        if goal is None:
            return command, ActionStatus.FAILED, phase
        error = np.linalg.norm(arm_forward(self._arm_port.Eval(context)) - target)
        if error < self.tolerance:
            return command, ActionStatus.SUCCEEDED, phase
        return joint_step(command, goal, self.speeds, self.period), ActionStatus.RUNNING, 0


class Grip(_Action):
    """Closes the two fingers on an object; succeeds when both are blocked by it.

    Input ports:
        finger_position: measured ``[left, right]`` finger positions [m].
        base_state: ``[x, y, phi, v]`` (unused by the check; kept for a uniform wiring).

    Output ports:
        finger_command: ``[left, right]`` setpoints.
        status: an :class:`ActionStatus`.

    The setpoints close at ``speed`` to ``closed``; once there and ``settle``
    s later, the grip succeeded if both fingers stopped at least
    ``block_margin`` short of ``closed`` (an object between them), else failed.
    """

    def __init__(
        self,
        period: float = 0.02,
        *,
        speed: float = FINGER_SPEED,
        closed: float = FINGER_CLOSED,
        block_margin: float = BLOCK_MARGIN,
        settle: float = 0.2,
        timeout: float = 5.0,
    ):
        """Creates the action (arguments as in the class docstring)."""
        super().__init__(period, timeout, 2, None, 0.0)
        _check_positive(speed=speed, block_margin=block_margin, settle=settle)
        if not FINGER_RANGE[0] <= closed <= FINGER_RANGE[1]:
            raise RepertoireError(f"closed must be within the finger range {FINGER_RANGE}")
        self.speed, self.closed = speed, closed
        self.block_margin, self.settle = block_margin, settle
        self._command_port = self.DeclareVectorOutputPort(
            "finger_command", 2, self._calc_command, {self.discrete_state_ticket(self._xd)}
        )

    def get_command_output_port(self):
        return self._command_port

    def measured(self, context):
        return self._finger_port.Eval(context)

    def target_ok(self, context) -> bool:
        return True

    def step(self, context, command, phase, time_in_phase):
        goal = np.full(2, self.closed)
        if phase == 0:
            command = joint_step(command, goal, (self.speed, self.speed), self.period)
            return command, ActionStatus.RUNNING, int(np.allclose(command, goal))
        if time_in_phase < self.settle:
            return command, ActionStatus.RUNNING, 1
        blocked = fingers_blocked(self._finger_port.Eval(context), self.closed, self.block_margin)
        return command, ActionStatus.SUCCEEDED if blocked else ActionStatus.FAILED, 1


class Put(_Action):
    """Carries a held cup to a target, lowers it and opens the fingers.

    Input ports:
        arm_position: measured ``[lift, yaw, extend]``.
        finger_position: measured ``[left, right]``.
        target: ``[ax_g, ay_g, az_g]``: where the gripper centre (the cup's
            centre) ends, chassis frame.
        base_state: ``[x, y, phi, v]`` of the chassis (for the obstacle check).

    Output ports:
        command: ``[lift, yaw, extend, left, right]`` setpoints.
        status: an :class:`ActionStatus`.

    Phases: 0 move to ``clearance`` above the target holding the fingers
    closed, 1 lower to the target, 2 open the fingers; succeeds when both are
    measured open. Fails at once if the target or the point above it is out of
    reach, or the cup's bottom disc (``cup_half_height`` below the gripper centre, of
    ``cup_radius``) or a finger (swept from its measured position to closed) would enter
    an obstacle box on the way (straight in joint space to the point above, then down to the target;
    grown by ``margin`` horizontally), or a finger opening at the target would. With
    obstacles given, it
    also fails at once unless the cup would stand on one of them: its bottom
    (a disc of ``cup_radius``) wholly on a box's top and at most ``max_drop``
    above it (:func:`support_under`); a cup let go in the air falls to the floor
    (measured: a cup let go beside a table, or with its bottom 1.1 cm over the
    table's edge, fell to the floor while the fingers opened as commanded).
    """

    def __init__(
        self,
        period: float = 0.02,
        *,
        speeds=ARM_SPEEDS,
        clearance: float = 0.05,
        cup_half_height: float = 0.05,
        cup_radius: float = 0.04,
        max_drop: float = 0.02,
        tolerance: float = 0.01,
        timeout: float = 15.0,
        obstacles=None,
        margin: float = 0.0,
    ):
        """Creates the action (arguments as in the class docstring and :class:`Reach`)."""
        super().__init__(period, timeout, 5, obstacles, margin)
        _check_positive(cup_radius=cup_radius, max_drop=max_drop)
        self.cup_radius, self.max_drop = cup_radius, max_drop
        self.speeds = np.asarray(speeds, dtype=float)
        if self.speeds.shape != (3,) or not np.all(np.isfinite(self.speeds) & (self.speeds > 0)):
            raise RepertoireError(f"speeds must be 3 finite values > 0, got {speeds}")
        _check_positive(clearance=clearance, cup_half_height=cup_half_height, tolerance=tolerance)
        self.clearance, self.cup_half_height, self.tolerance = clearance, cup_half_height, tolerance
        self._arm_port = self.DeclareVectorInputPort("arm_position", 3)
        self._target_port = self.DeclareVectorInputPort("target", 3)
        self._command_port = self.DeclareVectorOutputPort(
            "command", 5, self._calc_command, {self.discrete_state_ticket(self._xd)}
        )

    def get_arm_position_input_port(self):
        return self._arm_port

    def get_target_input_port(self):
        return self._target_port

    def get_command_output_port(self):
        return self._command_port

    def measured(self, context):
        # hold the fingers closed on the cup while carrying it
        return np.concatenate([self._arm_port.Eval(context), [FINGER_CLOSED, FINGER_CLOSED]])

    def _waypoints(self, context):
        target = np.asarray(self._target_port.Eval(context), dtype=float)
        return target + [0.0, 0.0, self.clearance], target

    def target_ok(self, context) -> bool:
        above, target = self._waypoints(context)
        if arm_inverse(above) is None or arm_inverse(target) is None:
            return False
        bottom = target - [0.0, 0.0, self.cup_half_height]
        base = self._base_port.Eval(context)
        cup = (self.cup_half_height, self.cup_radius)
        if discs_in_boxes(chassis_to_world(base, bottom), self.cup_radius, self._boxes,
                          self.margin)[0] >= 0:  # fmt: skip
            return False
        q, q_above, q_target = self._arm_port.Eval(context), arm_inverse(above), arm_inverse(target)
        # the fingers close from where they are (on a cup they stop at it) while carrying
        # it, then open at the target
        carry = [sorted([f, FINGER_CLOSED]) for f in self._finger_port.Eval(context)]
        release = [[FINGER_CLOSED, max(f, FINGER_OPEN)] for f in self._finger_port.Eval(context)]
        opened = fingers_in_boxes(base, q_target, release, self._boxes, self.margin)[0]
        if (self.path_enters_obstacle(context, q, q_above, carry, cup) >= 0
                or self.path_enters_obstacle(context, q_above, q_target, carry, cup) >= 0
                or opened >= 0):  # fmt: skip
            return False
        if len(self._boxes) == 0:
            return True  # no world given: nothing to stand on is known
        p = chassis_to_world(base, bottom)
        return support_under(p, self._boxes, self.cup_radius, self.max_drop) >= 0

    def step(self, context, command, phase, time_in_phase):
        above, target = self._waypoints(context)
        measured = arm_forward(self._arm_port.Eval(context))
        arm, fingers = command[:3], command[3:]
        if phase in (0, 1):
            point = above if phase == 0 else target
            goal = arm_inverse(point)
            if goal is None:
                return command, ActionStatus.FAILED, phase
            arm = joint_step(arm, goal, self.speeds, self.period)
            done = np.linalg.norm(measured - point) < self.tolerance
            return np.concatenate([arm, fingers]), ActionStatus.RUNNING, phase + int(done)
        fingers = joint_step(fingers, [FINGER_OPEN] * 2, (FINGER_SPEED,) * 2, self.period)
        opened = fingers_open(self._finger_port.Eval(context))
        status = ActionStatus.SUCCEEDED if opened else ActionStatus.RUNNING
        return np.concatenate([arm, fingers]), status, 2


def footprint_hits(xy, boxes, radius: float) -> int:
    """Index of the first obstacle box a robot disc at ``xy`` overlaps, else -1.

    Args:
        xy: ``[x, y]`` of the robot's centre.
        boxes: ``(k, 6)`` boxes as in :func:`point_in_boxes`.
        radius: the robot's footprint radius [m].
    """
    for i, u, w, hx, hy, _ in _in_box_frames(xy, boxes):  # the disc centre's distance:
        if math.hypot(max(abs(u) - hx, 0.0), max(abs(w) - hy, 0.0)) < radius:
            return i
    return -1


class FootprintGuard(LeafSystem):
    """Passes a GoToPose target through, or NaN if the robot would stand inside an obstacle.

    GoToPose fails at once on a non-finite target, so a pose inside a table
    (the robot's footprint disc overlapping an obstacle box) is reported as
    FAILED with no motion.

    Input ports:
        target: ``[x_g, y_g, phi_g, v_g]``.

    Output ports:
        target: the same, or all NaN.
    """

    def __init__(self, boxes, radius: float):
        """Creates the guard.

        Args:
            boxes: ``(k, 6)`` obstacle boxes ``[cx, cy, yaw, half_x, half_y, top_z]``.
            radius: the robot's footprint radius [m].
        """
        super().__init__()
        _check_positive(radius=radius)
        self._boxes, self.radius = _check_boxes(boxes), radius
        self._in = self.DeclareVectorInputPort("target", 4)
        self.DeclareVectorOutputPort("target", 4, self._calc)
        self._last = (None, False)  # (x, y) of the last target checked, and its answer

    def _calc(self, context: Context, output: BasicVector) -> None:
        target = self._in.Eval(context)
        # a pure function of the target's x, y: the last answer is reused while it holds
        # (a constant-source target is re-read on every update of GoToPose)
        xy = (float(target[0]), float(target[1]))
        if xy != self._last[0]:
            self._last = (xy, footprint_hits(xy, self._boxes, self.radius) >= 0)
        output.SetFromVector(np.full(4, np.nan) if self._last[1] else target)
