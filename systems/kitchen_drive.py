"""The kitchen's base drive with a run-time check: GoToPose that stops before it hits.

:class:`~repertoire.systems.go_to_pose.GoToPose` drives by its pose law and knows
nothing of the world: in the kitchen a drive across a table, or one that swept the
held-out arm through a standing cup, went on until it pushed the furniture or the cup.
(The refinement checks its plans' drives along the path the law drives, with the
same stopping runs: :func:`~repertoire.studies._kitchen_arm.law_drive_hits`.)
:class:`KitchenGoToPose` checks, at every update before its command, the
motion the base can still make (:func:`stopping_poses`: at the measured speed for the
period the command is held, then braking, and turning likewise at the commanded yaw
rate): the base's footprint disc against the obstacle
boxes (:func:`~repertoire.systems.kitchen_geometry.segment_gaps`, exact) and the arm as
it is held (gripper centre, finger boxes at the measured fingers, a held cup's bottom)
against the boxes and the standing cups
(:func:`~repertoire.systems.kitchen_geometry.arm_pose_hits`), the geometry of the
refinement's checks and of :class:`~repertoire.systems.kitchen_actions.Reach`. Where
that motion would enter an obstacle it stops (command 0) and reports FAILED;
:meth:`KitchenGoToPose.failure` names the obstacle, what would enter it and the poses.
"""

import math

import numpy as np
from pydrake.systems.framework import Context, DiscreteValues
from repertoire.models.diffdrive import WHEEL_RADIUS
from repertoire.systems.action_status import ActionStatus
from repertoire.systems.go_to_pose import GoToPose
from repertoire.systems.kitchen_geometry import (
    FINGER_HALF,
    FINGER_REACH,
    _check_boxes,
    _check_positive,
    arm_forward,
    arm_pose_hits,
    box_gaps,
    chassis_to_world,
    cup_discs,
    first_entry,
    segment_gaps,
)

from repertoire.errors import RepertoireError

#: What entered an obstacle (slot 1 of :class:`KitchenGoToPose`'s failure state).
FAILURE_PARTS = ("", "footprint", "arm")


def stopping_run(v, omega, a_max: float, alpha_max: float, delay: float):
    """``(run, turn)``: how far a base moves and turns if it brakes after ``delay``.

    At speed ``v`` and yaw rate ``omega`` (numbers or arrays), the command held for
    ``delay``, then braking at ``a_max`` and ``alpha_max``: ``v delay + v |v| / (2
    a_max)``, ``omega delay + omega |omega| / (2 alpha_max)``.
    """
    v, omega = np.asarray(v, dtype=float), np.asarray(omega, dtype=float)
    run = v * delay + v * np.abs(v) / (2.0 * a_max)
    return run, omega * delay + omega * np.abs(omega) / (2.0 * alpha_max)


def stopping_poses(state, omega: float, a_max: float, alpha_max: float, delay: float,
                   reach: float, spacing: float = 0.01) -> np.ndarray:  # fmt: skip
    """Poses ``(n, 3)`` from the base's pose to where it stops if it brakes now.

    The command is held for ``delay``, then the speed ``v`` (``state[3]``) and the yaw
    rate ``omega`` fall at ``a_max`` and ``alpha_max``: the base runs ``v delay + v |v| /
    (2 a_max)`` along its heading and turns ``omega delay + omega |omega| / (2
    alpha_max)``. The poses interpolate both (a straight line and a turn: the arc's
    chord, off the arc by run x turn / 8, 3 mm at the kitchen's braking from full speed)
    so that a point ``reach`` from the base's centre moves at most ``spacing`` between
    two poses; the first is the base's pose.

    Args:
        state: ``[x, y, phi, v]``.
        omega: the yaw rate [rad/s].
        a_max, alpha_max: braking [m/s^2, rad/s^2].
        delay: how long the command is held before braking [s].
        reach: the farthest point of the robot from its centre [m].
        spacing: largest motion of that point between poses [m].
    """
    x, y, phi, v = (float(s) for s in state[:4])
    run, turn = (float(r) for r in stopping_run(v, omega, a_max, alpha_max, delay))
    n = max(2, math.ceil((abs(run) + reach * abs(turn)) / spacing) + 1)
    s = np.linspace(0.0, 1.0, n)
    return np.column_stack(
        [x + s * run * math.cos(phi), y + s * run * math.sin(phi), phi + s * turn]
    )


class KitchenGoToPose(GoToPose):
    """GoToPose with the kitchen's run-time check: it stops before the base or arm hits.

    Input ports (besides GoToPose's ``state``, ``target``, ``active``):
        arm_position: measured ``[lift, yaw, extend]`` (held while driving).
        finger_position: measured ``[left, right]``.
        cup_positions: the cups' centres ``[x, y, z] * cups`` (world; only with ``cups``
            > 0): the standing cups are obstacles of the arm, all but one around the
            gripper centre (:func:`~repertoire.systems.kitchen_geometry.cup_discs`): held
            when neither finger is open (its bottom then hangs below the gripper and is
            checked too), else an obstacle of the fingers.

    Output ports: GoToPose's ``command`` and ``status``.

    At each update while running and active, :func:`stopping_poses` (the command held for
    one period, then braking at ``braking``) are checked: the
    footprint disc of ``radius`` along them against ``obstacles`` (a base already
    overlapping a box may move away from it, not further in), and the still arm with
    :func:`~repertoire.systems.kitchen_geometry.arm_pose_hits` against the boxes and the
    standing cups (a way starting in a box may leave it, as a reach's). On an entry the
    status is FAILED and the command 0; the failure state (a second discrete group: part,
    obstacle index, the base's pose and the pose where it would enter) is read by
    :meth:`failure`.
    """

    def __init__(
        self,
        period: float = 0.01,
        gains: dict[str, float] | None = None,
        workspace: tuple[float, float, float, float] = (-3.0, 3.0, -2.0, 2.0),
        *,
        obstacles,
        radius: float,
        names=(),
        cups: int = 0,
        cup_radius: float = 0.04,
        cup_half_height: float = 0.05,
        cup_margin: float = 0.005,
        braking: tuple[float, float] | None = None,
    ):
        """Creates the action.

        Args:
            period, gains, workspace: as for :class:`GoToPose`.
            obstacles: ``(k, 6)`` boxes ``[cx, cy, yaw, half_x, half_y, top_z]`` (world).
            radius: the base's footprint radius [m].
            names: the boxes' names, then the cups' (for :meth:`failure`); default
                ``box i`` / ``cup j``.
            cups: how many cups' centres the ``cup_positions`` input carries (0: no port).
            cup_radius, cup_half_height: a cup's size (a held cup's bottom hangs
                ``cup_half_height`` below the gripper centre) [m].
            cup_margin: the standing cups' growth [m] (as :class:`Reach`'s).
            braking: ``(deceleration [m/s^2], angular deceleration [rad/s^2])`` of the
                base when its command drops to 0 (a property of the plant's wheels);
                None: the gains' ``a_max`` and ``alpha_max`` (the command's own limits,
                far gentler than a stop: the predicted stops reach farther).
        """
        super().__init__(period, gains, workspace)
        _check_positive(radius=radius, cup_radius=cup_radius, cup_half_height=cup_half_height)
        if not (math.isfinite(cup_margin) and cup_margin >= 0):
            raise RepertoireError(f"cup_margin must be finite and >= 0, got {cup_margin}")
        if not (isinstance(cups, int) and not isinstance(cups, bool) and cups >= 0):
            raise RepertoireError(f"cups must be a whole number >= 0, got {cups!r}")
        self._boxes, self.radius, self.cups = _check_boxes(obstacles), radius, cups
        self.cup_radius, self.cup_half_height = cup_radius, cup_half_height
        self.cup_margin = cup_margin
        if braking is not None:
            b = np.asarray(braking, dtype=float)
            if b.shape != (2,) or not np.all(np.isfinite(b) & (b > 0)):
                raise RepertoireError(f"braking must be 2 finite values > 0, got {braking}")
        self.braking = None if braking is None else (float(braking[0]), float(braking[1]))
        n = len(self._boxes) + cups
        self.names = list(names) or [f"box {i}" for i in range(len(self._boxes))]
        self.names += [f"cup {j}" for j in range(n - len(self.names))]
        if len(self.names) != n:
            raise RepertoireError(f"names must name the {len(self._boxes)} boxes, then the "
                                  f"{cups} cups; got {list(names)}")  # fmt: skip
        self._arm_port = self.DeclareVectorInputPort("arm_position", 3)
        self._finger_port = self.DeclareVectorInputPort("finger_position", 2)
        self._cups_port = self.DeclareVectorInputPort("cup_positions", 3 * cups) if cups else None
        # [part (FAILURE_PARTS index), obstacle, x, y, phi, x_hit, y_hit, phi_hit]
        self._failure_xd = self.DeclareDiscreteState(8)

    def get_arm_position_input_port(self):
        return self._arm_port

    def get_finger_position_input_port(self):
        return self._finger_port

    def get_cup_positions_input_port(self):
        """The cups' centres ``[x, y, z] * cups`` (world; only with ``cups`` > 0)."""
        if self._cups_port is None:
            raise RepertoireError("this action was built with cups=0: no cup_positions port")
        return self._cups_port

    def way_hit(self, context: Context) -> tuple[int, int, np.ndarray] | None:
        """What the base's stopping motion enters: ``(part, obstacle, pose)``, or None.

        ``part`` indexes :data:`FAILURE_PARTS`; ``pose`` ``[x, y, phi]`` is the first
        pose of :func:`stopping_poses` in the obstacle.
        """
        from repertoire.systems.kitchen_actions import fingers_open

        state = np.asarray(self._state_port.Eval(context), dtype=float)
        q = np.asarray(self._arm_port.Eval(context), dtype=float)
        fingers = np.asarray(self._finger_port.Eval(context), dtype=float)
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(fingers))):
            return None  # GoToPose fails on a non-finite state; the arm is not measured
        g = self.gains(context)
        omega = float(context.get_discrete_state(self._xd).get_value()[1])
        a = arm_forward(q)
        reach = max(self.radius, math.hypot(a[0], a[1]) + FINGER_REACH)
        brake = self.braking or (g["a_max"], g["alpha_max"])
        poses = stopping_poses(state, omega, *brake, self.period, reach)
        # boxes farther than the base can move (plus the footprint, or the arm's reach
        # where the arm is not above them) are not tested
        start = box_gaps(poses[:1], self._boxes)[0]
        clear = start - math.hypot(*(poses[-1, :2] - poses[0, :2]))
        # the footprint: the stopping segment (exact), a base already too close may leave
        if np.any(clear < self.radius):
            gaps = segment_gaps(poses[:1], poses[-1:], self._boxes)[0]
            end = box_gaps(poses[-1:], self._boxes)[0]
            into = (gaps < self.radius) & ((start >= self.radius) | (end < start))
            if into.any():
                i = int(np.argmax(into))
                on_way = np.flatnonzero(box_gaps(poses, self._boxes)[:, i] < self.radius)
                return 1, i, poses[on_way[0] if on_way.size else -1]
        # fingers not open hold the cup they are around (a squeezed cup sways in the
        # grip while the base turns: a finger then reads below holds_object's 1 cm)
        held = not any(fingers_open([f]) for f in fingers)
        discs, finger_discs = np.zeros((0, 4)), np.zeros((0, 4))
        if self._cups_port is not None:
            centre = chassis_to_world(state, a)
            discs, finger_discs = cup_discs(self._cups_port.Eval(context), centre,
                                            self.cup_radius, self.cup_half_height,
                                            (0,) if held else (), self.cup_margin)  # fmt: skip
        cup = (self.cup_half_height, self.cup_radius) if held else None
        low = WHEEL_RADIUS + a[2] - max(FINGER_HALF[2], self.cup_half_height if held else 0.0)
        arm_reach = math.hypot(a[0], a[1]) + max(FINGER_REACH, self.cup_radius) + self.cup_margin
        both = np.vstack([discs, finger_discs])
        to_cups = np.hypot(both[:, 0] - state[0], both[:, 1] - state[1]) - both[:, 2]
        moved = math.hypot(*(poses[-1, :2] - poses[0, :2]))
        if not (np.any((clear <= arm_reach) & (low <= self._boxes[:, 5]))
                or np.any((to_cups - moved <= arm_reach) & (low <= both[:, 3]))):  # fmt: skip
            return None  # nothing within the arm's reach below it
        span = [[f, f] for f in fingers]
        inside = arm_pose_hits(poses, q, span, self._boxes, 0.0, cup, discs, finger_discs)
        hit = int(first_entry(inside[None, :], len(self._boxes))[0])
        if hit < 0:
            return None
        # the obstacle's name: the finger discs are cups too, after the standing ones
        cups = np.asarray(self._cups_port.Eval(context)).reshape(-1, 3) if self.cups else None
        index = hit
        if hit >= len(self._boxes):
            disc = np.vstack([discs, finger_discs])[hit - len(self._boxes)]
            j = int(np.argmin(np.hypot(cups[:, 0] - disc[0], cups[:, 1] - disc[1])))
            index = len(self._boxes) + j
        at = int(np.argmax(inside == hit))
        return 2, index, poses[at]

    def failure(self, context: Context) -> str:
        """Why the drive stopped (``""`` unless its run-time check stopped it)."""
        part, index, *poses = context.get_discrete_state(self._failure_xd).get_value()
        if part <= 0:
            return ""
        now, at = np.round(poses[:3], 3).tolist(), np.round(poses[3:], 3).tolist()
        return (f"stopped at [x, y, phi] = {now}: the {FAILURE_PARTS[int(part)]} would enter "
                f"{self.names[int(index)]} at {at}")  # fmt: skip

    def _update(self, context: Context, discrete_state: DiscreteValues) -> None:
        xd = context.get_discrete_state(self._xd).get_value()
        failure = discrete_state.get_mutable_vector(self._failure_xd)
        failure.SetFromVector(context.get_discrete_state(self._failure_xd).get_value())
        finite = np.all(np.isfinite(self._state_port.Eval(context)))
        if xd[2] == ActionStatus.RUNNING and finite and self.is_active(context):
            hit = self.way_hit(context)
            if hit is not None:
                part, index, pose = hit
                state = self._state_port.Eval(context)
                failure.SetFromVector([part, index, *state[:3], *pose])
                discrete_state.get_mutable_vector(self._xd).SetFromVector(
                    [0.0, 0.0, ActionStatus.FAILED, *xd[3:]]  # the mode, the start
                )
                return
        super()._update(context, discrete_state)
