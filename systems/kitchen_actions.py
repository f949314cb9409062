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
Built with ``cups`` > 0, Reach and Put read the cups' centres (``cup_positions``) and
keep off the standing ones the same way, each an upright disc of the cup's radius up
to its rim (:meth:`_Action.standing_cups`: all but a cup the way starts or ends in, the
one gripped, held or let go); unchecked, a level swing across a standing cup pushed it
168 mm and reported SUCCEEDED. The geometry lives in
:mod:`repertoire.systems.kitchen_geometry` (re-exported here).

Grip closes the fingers and succeeds when both are blocked by an object (the
fingers stop more than ``block_margin`` short of their closed setpoint: a grasp
by contact, held by friction); closing on nothing fails.
"""

import math

import numpy as np
from pydrake.systems.framework import BasicVector, Context, DiscreteValues, LeafSystem
from repertoire.models.diffdrive.generate import FINGER_RANGE
from repertoire.systems.action_status import ActionStatus, ActionSystem
from repertoire.systems.kitchen_geometry import (
    FINGER_HALF,
    FINGER_REACH,
    ArmTracking,
    _check_boxes,
    _check_positive,
    arm_forward,
    arm_inverse,
    arm_inverse_rows,
    arm_way_hits,
    box_gaps,
    chassis_points_to_world,
    chassis_to_world,
    cup_discs,
    discs_in_boxes,
    discs_in_discs,
    finger_boxes,
    fingers_in_boxes,
    joint_line,
    joint_line_points,
    joint_lines,
    point_in_boxes,
    points_in_boxes,
    points_in_discs,
    support_under,
)

from repertoire.errors import RepertoireError

#: The actions and their constants, and the geometry of systems/kitchen_geometry.py
#: (re-exported: the actions' callers import it from here).
__all__ = [
    "ARM_JOINTS",
    "ARM_SPEEDS",
    "ArmTracking",
    "BLOCK_MARGIN",
    "FINGER_CLOSED",
    "FINGER_HALF",
    "FINGER_JOINTS",
    "FINGER_OPEN",
    "FINGER_REACH",
    "FINGER_SPEED",
    "OPEN_TOLERANCE",
    "CUP_MARGIN",
    "arm_forward",
    "arm_inverse",
    "arm_inverse_rows",
    "arm_way_hits",
    "chassis_points_to_world",
    "chassis_to_world",
    "cup_discs",
    "discs_in_boxes",
    "discs_in_discs",
    "finger_boxes",
    "fingers_blocked",
    "fingers_in_boxes",
    "fingers_open",
    "footprint_hits",
    "FootprintGuard",
    "Grip",
    "holds_object",
    "joint_line",
    "joint_line_points",
    "joint_lines",
    "joint_step",
    "point_in_boxes",
    "points_in_boxes",
    "points_in_discs",
    "Put",
    "Reach",
    "support_under",
]

ARM_JOINTS = ("arm_lift", "arm_yaw", "arm_extend")
FINGER_JOINTS = ("left_finger", "right_finger")
ARM_SPEEDS = (0.15, 0.8, 0.2)  # lift m/s, yaw rad/s, extend m/s
FINGER_SPEED = 0.05  # m/s
FINGER_OPEN = 0.075  # finger centre from the gripper centre when open [m]
#: Reach's and Put's growth of the standing cups [m]: half the ways' 1 cm samples.
CUP_MARGIN = 0.005
FINGER_CLOSED = 0.03  # closed setpoint (the joint's lower limit) [m]
OPEN_TOLERANCE = 0.005  # a finger this close to FINGER_OPEN is measured open [m]
BLOCK_MARGIN = 0.01  # a finger this far short of closed is blocked by an object [m]


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


def _check_nonnegative(**values) -> None:
    """Each value finite and >= 0 (as :func:`_check_positive`), or an error naming it."""
    for name, v in values.items():
        if not (math.isfinite(v) and v >= 0):
            raise RepertoireError(f"{name} must be finite and >= 0, got {v}")


class _Action(ActionSystem):
    """Shared ports and state of the kitchen actions (not registered on its own)."""

    def __init__(
        self,
        period: float,
        timeout: float,
        n_command: int,
        boxes,
        margin: float,
        cups: int = 0,
        tracking: ArmTracking | None = None,
    ):
        super().__init__()
        if tracking is not None and not isinstance(tracking, ArmTracking):
            raise RepertoireError(f"tracking must be an ArmTracking or None, got {tracking!r}")
        self.tracking = tracking
        _check_positive(period=period, timeout=timeout)
        _check_nonnegative(margin=margin)
        if not (isinstance(cups, int) and not isinstance(cups, bool) and cups >= 0):
            raise RepertoireError(f"cups must be a whole number >= 0, got {cups!r}")
        self.period, self.timeout, self.margin = period, timeout, margin
        self._n, self.cups = n_command, cups
        self._boxes = _check_boxes(boxes)
        # state: [command (n), status, started, t0, phase, t_phase]
        self._xd = self.DeclareDiscreteState(n_command + 5)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        self._base_port = self.DeclareVectorInputPort("base_state", 4)
        self._finger_port = self.DeclareVectorInputPort("finger_position", 2)
        self._declare_status_port(self._xd, n_command)
        self._cups_port = self.DeclareVectorInputPort("cup_positions", 3 * cups) if cups else None

    def get_base_state_input_port(self):
        return self._base_port

    def get_cup_positions_input_port(self):
        """The cups' centres ``[x, y, z] * cups`` (world; only with ``cups`` > 0)."""
        if self._cups_port is None:
            raise RepertoireError("this action was built with cups=0: no cup_positions port")
        return self._cups_port

    def standing_cups(
        self,
        context: Context,
        points,
        radius: float,
        half_height: float,
        held=(0, 1),
        grow: float = 0.0,
    ) -> tuple[np.ndarray, np.ndarray]:
        """The cups on ``cup_positions`` as obstacle discs, for a way between ``points``.

        :func:`cup_discs` of the cups' centres (none without the port).

        Returns:
            ``(discs, finger_discs)``.
        """
        if self._cups_port is None:
            return np.zeros((0, 4)), np.zeros((0, 4))
        cups = self._cups_port.Eval(context)
        return cup_discs(cups, points, radius, half_height, held, grow)

    def get_finger_position_input_port(self):
        return self._finger_port

    def inside_obstacle(self, context: Context, a_chassis) -> int:
        """Index of the obstacle box containing the chassis-frame point, else -1."""
        base = self._base_port.Eval(context)
        return point_in_boxes(chassis_to_world(base, a_chassis), self._boxes, self.margin)

    def path_enters_obstacle(
        self,
        context: Context,
        q_from,
        q_to,
        span,
        cup=None,
        discs=None,
        finger_discs=None,
    ) -> int:
        """Index of the first obstacle the straight joint-space way enters, else -1.

        :func:`arm_way_hits` for the chassis on ``base_state``: the gripper centre, the
        finger boxes swept over ``span`` and, with ``cup = (drop, radius)``, a held cup's
        bottom disc, against the boxes and ``discs`` (standing cups), and the fingers
        against ``finger_discs``; with the action's ``tracking``, along the way the
        servoed joints take (:class:`ArmTracking`), else the straight line.
        """
        base = self._base_port.Eval(context)
        hit = arm_way_hits(base, q_from, q_to, span, self._boxes, self.margin, cup, discs=discs,
                           finger_discs=finger_discs, tracking=self.tracking)  # fmt: skip
        return int(hit[0])

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
        cup_positions: the cups' centres ``[x, y, z] * cups`` (world; only with ``cups``
            > 0): the standing cups are obstacles too (:meth:`_Action.standing_cups`).

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
        cups: int = 0,
        cup_margin: float = CUP_MARGIN,
        tracking: ArmTracking | None = None,
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
            cups: how many cups' centres the ``cup_positions`` input carries (0: no port).
            cup_margin: the standing cups' growth [m]: half the way's 1 cm samples, so no
                finger passes a cup's edge between two samples.
            tracking: how the plant's servoed joints follow the setpoints
                (:class:`ArmTracking`): the way checked is the one they take; None: the
                straight joint-space line.
        """
        super().__init__(period, timeout, 3, obstacles, margin, cups, tracking)
        _check_nonnegative(cup_margin=cup_margin)
        self.cup_margin = cup_margin
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
        base = self._base_port.Eval(context)
        ends = chassis_points_to_world(np.vstack([base, base]), arm_forward([q, goal]))
        held = (0,) if cup is not None else ()  # a held cup starts at the gripper
        discs, fingers_only = self.standing_cups(
            context, ends, self.cup_radius, self.cup_half_height, held, self.cup_margin
        )
        return self.path_enters_obstacle(context, q, goal, span, cup, discs, fingers_only) < 0

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
        cup_positions: as in :class:`Reach` (only with ``cups`` > 0).

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
        cups: int = 0,
        cup_margin: float = CUP_MARGIN,
        tracking: ArmTracking | None = None,
    ):
        """Creates the action (arguments as in the class docstring and :class:`Reach`)."""
        super().__init__(period, timeout, 5, obstacles, margin, cups, tracking)
        _check_nonnegative(cup_margin=cup_margin)
        self.cup_margin = cup_margin
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
        # the held cup (at the gripper) and the cup let go at the target are not obstacles
        ends = chassis_points_to_world(np.vstack([base, base]), [arm_forward(q), target])
        discs = self.standing_cups(
            context, ends, self.cup_radius, self.cup_half_height, grow=self.cup_margin
        )[0]
        opened = fingers_in_boxes(base, q_target, release, self._boxes, self.margin, discs)[0]
        if (self.path_enters_obstacle(context, q, q_above, carry, cup, discs) >= 0
                or self.path_enters_obstacle(context, q_above, q_target, carry, cup, discs) >= 0
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
    hits = np.flatnonzero(box_gaps(np.asarray(xy, dtype=float)[:2], boxes)[0] < radius)
    return int(hits[0]) if hits.size else -1


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
