"""Walking controller of the biped: commands -> footsteps -> ZMP -> CoM -> swing feet -> leg IK.

The biped is commanded the way Chestnutt et al. commanded ASIMO: each step is an
*action*, a desired displacement (named in
``repertoire.planning.footstep.actions.ACTIONS``), not a foot location. The
controller turns the commands into footsteps with a stateful rule, then into a
walking pattern that the plant's joint PD tracks:

1. :func:`realize_commands` (wrapped by :class:`CommandStepper`) applies the
   **stepping rule** below to the command sequence and returns the footsteps
   the controller will actually take (:class:`FootstepSequence`).
2. :func:`zmp_reference` puts the ZMP on the stance sole during single support
   and moves it linearly between the soles in double support; Drake's
   ``pydrake.planning.ZmpPlanner`` gives the CoM trajectory
   (:class:`ZmpComPlanner`).
3. :func:`foot_poses_at` interpolates each swing foot (quintic in x, y, yaw;
   a raised-cosine lift) (:class:`SwingFootPlanner`).
4. :func:`whole_body_ik` finds the pelvis position whose whole-body CoM (exact
   mass model of the URDF) is the planned CoM and solves both legs in closed
   form (:class:`WalkingIK`), which feeds the plant's ``desired_state`` input.

Stepping rule (the controller's state, documented as for ASIMO in the paper):
the controller keeps a *walking speed* v, the mean forward command of the two
previous actions (each action has a forward command, ``FORWARD_COMMAND``).
The realized forward displacement of the swing foot is the commanded one
changed by ``s - c``, where ``c`` is the action's forward command and
``s = clip(c, v - max_speed_change, v + max_speed_change)``. So from standing
(v = 0) a long step (c = 0.30 m) is only 0.12 m, a long step after one long
step is 0.27 m, and a ``stop`` after two long steps (v = 0.30) still takes one
more 0.18 m step forward. The step takes ``base_duration +
duration_per_speed_change * |s - v|`` seconds (changing speed takes longer).
The result depends only on (a_{i-2}, a_{i-1}, a_i), as Chestnutt et al. found
for ASIMO, so a table T(a_{i-2}, a_{i-1}, l_i, a_i) measured in simulation can
describe it (plus whatever the physics adds).

Length: one walking pipeline, kept in one file on purpose (DESIGN.md names it as the
example to copy): the five plain functions carry the math and are tested against closed
forms, and each of the thin systems only wraps one of them; splitting them apart would
scatter one controller over several modules.
"""

import dataclasses
import math

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.planning import ZmpPlanner
from pydrake.systems.framework import (
    BasicVector,
    Context,
    DiscreteValues,
    LeafSystem,
)
from pydrake.trajectories import PiecewisePolynomial
from repertoire.models.biped import (
    ANKLE_HEIGHT,
    JOINT_LIMITS,
    LEG_JOINTS,
    com_in_pelvis,
    leg_ik,
    rotation_rpy,
)
from repertoire.planning.footstep.actions import ACTIONS, commanded_displacement
from repertoire.planning.footstep.types import Foot, FootstepPlan, wrap_angle

from repertoire.checks import is_real
from repertoire.errors import RepertoireError

#: Forward command per action [m] (the body's desired forward displacement per step).
FORWARD_COMMAND = {
    "forward_long": 0.30,
    "forward_medium": 0.20,
    "forward_short": 0.10,
    "side_step": 0.0,
    "turn_left": 0.05,
    "turn_right": 0.05,
    "stop": 0.0,
}
GRAVITY = 9.81


@dataclasses.dataclass
class SteppingRule:
    """Parameters of the controller's stateful stepping rule (see the module docstring).

    Attributes:
        max_speed_change: largest change of the forward step from the walking speed [m].
        base_duration: seconds from command to landing at constant speed.
        duration_per_speed_change: extra seconds per metre of speed change.
        double_support: seconds of double support at the start of each step (weight shift).
        swing_height: peak lift of the swing sole [m].
        initial_hold: seconds standing before the first step.
        final_hold: seconds standing after the last landing (CoM settles).
    """

    max_speed_change: float = 0.12
    base_duration: float = 1.0
    duration_per_speed_change: float = 1.0
    double_support: float = 0.4
    swing_height: float = 0.05
    initial_hold: float = 0.4
    final_hold: float = 1.2

    def validate(self) -> None:
        """Raises RepertoireError when a parameter is out of range."""
        for name, value in dataclasses.asdict(self).items():
            if not (isinstance(value, (int, float)) and math.isfinite(value)):
                raise RepertoireError(f"{name} must be a finite number, got {value!r}")
        if not self.max_speed_change >= 0:
            raise RepertoireError(f"max_speed_change must be >= 0, got {self.max_speed_change}")
        if not 0 < self.double_support < self.base_duration:
            raise RepertoireError(
                f"double_support must be in (0, base_duration={self.base_duration}), "
                f"got {self.double_support}"
            )
        if not 0 <= self.swing_height <= 0.15:
            raise RepertoireError(f"swing_height must be in [0, 0.15] m, got {self.swing_height}")
        if self.initial_hold < 0 or self.final_hold < 0 or self.duration_per_speed_change < 0:
            raise RepertoireError(
                "initial_hold, final_hold, duration_per_speed_change must be >= 0"
            )


def _check_action(a: str) -> str:
    if a not in FORWARD_COMMAND:
        raise RepertoireError(f"unknown action {a!r}; expected one of {ACTIONS}")
    return a


def _check_start_time(start_time: float) -> float:
    """``start_time`` as a float; RepertoireError unless finite and >= 0.

    The ZMP reference starts at time 0 (the simulation's start), so a sequence that
    starts earlier (or at NaN) has no valid reference.
    """
    try:
        value = float(start_time)
    except (TypeError, ValueError):
        raise RepertoireError(f"start_time must be a number [s], got {start_time!r}") from None
    if not (math.isfinite(value) and value >= 0.0):
        raise RepertoireError(f"start_time must be finite and >= 0 [s], got {start_time!r}")
    return value


def realize_step(
    a_prev2: str, a_prev1: str, a: str, stance: Foot, rule: SteppingRule
) -> tuple[np.ndarray, float]:
    """The footstep the controller takes for a command, given the two previous commands.

    Args:
        a_prev2: the action commanded two steps before.
        a_prev1: the previous action.
        a: the commanded action.
        stance: the stance foot (the other foot swings).
        rule: the stepping rule.

    Returns:
        ``(d, duration)``: the swing foot's landing pose ``(dx, dy, dyaw)`` in the stance
        sole frame, and the step's duration [s] (command to landing).
    """
    for name in (a_prev2, a_prev1, a):
        _check_action(name)
    d = np.array(commanded_displacement(a, Foot(stance)), dtype=float)
    v = 0.5 * (FORWARD_COMMAND[a_prev1] + FORWARD_COMMAND[a_prev2])
    c = FORWARD_COMMAND[a]
    s = float(np.clip(c, v - rule.max_speed_change, v + rule.max_speed_change))
    d[0] += s - c
    duration = rule.base_duration + rule.duration_per_speed_change * abs(s - v)
    return d, float(duration)


def compose(pose: np.ndarray, d: np.ndarray) -> np.ndarray:
    """World pose (x, y, yaw) of a displacement ``d`` given in the frame of ``pose``."""
    x, y, th = pose
    c, s = math.cos(th), math.sin(th)
    return np.array([x + c * d[0] - s * d[1], y + s * d[0] + c * d[1], wrap_angle(th + d[2])])


def relative(stance: np.ndarray, landed: np.ndarray) -> np.ndarray:
    """Pose ``landed`` (x, y, yaw) expressed in the frame of ``stance`` (inverse of compose)."""
    x, y, th = stance
    c, s = math.cos(th), math.sin(th)
    ex, ey = landed[0] - x, landed[1] - y
    return np.array([c * ex + s * ey, -s * ex + c * ey, wrap_angle(landed[2] - th)])


@dataclasses.dataclass
class FootstepSequence:
    """The footsteps the controller will take (typed artefact on an abstract port).

    Attributes:
        initial_left: ``[x, y, yaw]`` of the left sole at the start.
        initial_right: ``[x, y, yaw]`` of the right sole at the start.
        actions: the commanded action of each step.
        swing_feet: which foot swings in each step (0 left, 1 right).
        poses: landing pose ``[x, y, yaw]`` of each step's swing foot.
        command_times: when each step is commanded (start of its double support) [s].
        land_times: when each step's swing foot lands [s].
        end_time: end of the final hold [s].
        double_support: double-support seconds at the start of each step.
        swing_height: peak lift of the swing sole [m].
    """

    initial_left: list[float]
    initial_right: list[float]
    actions: list[str]
    swing_feet: list[int]
    poses: list[list[float]]
    command_times: list[float]
    land_times: list[float]
    end_time: float
    double_support: float
    swing_height: float

    @property
    def num_steps(self) -> int:
        return len(self.actions)


def realize_commands(
    stance_pose: np.ndarray,
    stance_foot: Foot,
    swing_pose: np.ndarray,
    actions: list[str],
    rule: SteppingRule,
    *,
    history: tuple[str, str] = ("stop", "stop"),
    start_time: float = 0.0,
) -> FootstepSequence:
    """Applies the stepping rule to a command sequence.

    Args:
        stance_pose: ``(x, y, yaw)`` of the first stance sole.
        stance_foot: which foot stands first (the other makes the first step).
        swing_pose: ``(x, y, yaw)`` of the other sole at the start.
        actions: the commanded actions, one per step.
        rule: the stepping rule.
        history: the two actions before the first one (``("stop", "stop")`` when standing).
        start_time: time of the sequence's start [s], finite and >= 0; the first command
            comes ``rule.initial_hold`` later.

    Returns:
        The realized :class:`FootstepSequence`.
    """
    rule.validate()
    start_time = _check_start_time(start_time)
    stance_pose = np.asarray(stance_pose, dtype=float)
    swing_pose = np.asarray(swing_pose, dtype=float)
    if stance_pose.shape != (3,) or swing_pose.shape != (3,):
        raise RepertoireError("stance_pose and swing_pose must be (x, y, yaw)")
    if not (np.all(np.isfinite(stance_pose)) and np.all(np.isfinite(swing_pose))):
        raise RepertoireError("stance_pose and swing_pose must be finite")
    stance_foot = Foot(stance_foot)
    feet = {stance_foot: stance_pose, stance_foot.other(): swing_pose}
    hist = [_check_action(history[0]), _check_action(history[1])]
    t = start_time + rule.initial_hold
    out_actions, swing, poses, t_cmd, t_land = [], [], [], [], []
    stance = stance_foot
    for a in actions:
        d, duration = realize_step(hist[-2], hist[-1], a, stance, rule)
        landed = compose(feet[stance], d)
        out_actions.append(a)
        swing.append(int(stance.other()))
        poses.append(landed.tolist())
        t_cmd.append(t)
        t_land.append(t + duration)
        feet[stance.other()] = landed
        t += duration
        hist.append(a)
        stance = stance.other()
    left0 = stance_pose if stance_foot == Foot.LEFT else swing_pose
    right0 = swing_pose if stance_foot == Foot.LEFT else stance_pose
    return FootstepSequence(
        initial_left=left0.tolist(),
        initial_right=right0.tolist(),
        actions=out_actions,
        swing_feet=swing,
        poses=poses,
        command_times=t_cmd,
        land_times=t_land,
        end_time=t + rule.double_support + rule.final_hold,
        double_support=rule.double_support,
        swing_height=rule.swing_height,
    )


def realize_plan(
    plan: FootstepPlan, rule: SteppingRule, *, start_time: float = 0.0
) -> FootstepSequence:
    """Realizes the commands of a footstep plan from its start poses (see realize_commands).

    Args:
        plan: a footstep plan; only its start poses, first stance foot, history and actions
            are used (the landing poses are what the planner *expects*).
        rule: the stepping rule.
        start_time: time of the start [s].
    """
    history = tuple(plan.initial_history) if plan.initial_history else ("stop", "stop")
    if len(history) != 2:
        raise RepertoireError(f"plan.initial_history must have 2 actions, got {history}")
    return realize_commands(
        np.asarray(plan.poses[0], dtype=float),
        Foot(plan.feet[0]),
        np.asarray(plan.initial_swing_pose, dtype=float),
        list(plan.actions),
        rule,
        history=history,
        start_time=start_time,
    )


def same_commands(a: FootstepPlan, b: FootstepPlan) -> bool:
    """Whether two plans make the walker take the same steps and predict the same landings.

    Compares the start soles, the feet, the actions, the history, the planned poses and
    the times (the search figures, cost and status may differ).
    """
    return (
        list(a.feet) == list(b.feet)
        and list(a.actions) == list(b.actions)
        and list(a.initial_history) == list(b.initial_history)
        and np.array_equal(a.poses_array(), b.poses_array())
        and np.array_equal(np.asarray(a.initial_swing_pose, float), b.initial_swing_pose)
        and np.array_equal(np.asarray(a.times, float), b.times)
    )


def feet_at_step(seq: FootstepSequence, k: int) -> dict[int, np.ndarray]:
    """Both sole poses before step ``k`` (k = 0: the start; k = N: after the last step)."""
    feet = {0: np.asarray(seq.initial_left, float), 1: np.asarray(seq.initial_right, float)}
    for j in range(min(k, seq.num_steps)):
        feet[seq.swing_feet[j]] = np.asarray(seq.poses[j], float)
    return feet


def zmp_reference(seq: FootstepSequence) -> PiecewisePolynomial:
    """Piecewise-linear desired ZMP (x, y) for a footstep sequence.

    The ZMP stays at the midpoint of the soles until the first command, moves to the
    stance sole in each double support, stays there during the swing, and returns
    to the midpoint of the final soles after the last landing.

    Args:
        seq: the footsteps.

    Returns:
        A first-order-hold PiecewisePolynomial with 2 rows.
    """
    feet = feet_at_step(seq, 0)
    mid = 0.5 * (feet[0][:2] + feet[1][:2])
    times, points = [0.0], [mid]
    t0 = seq.command_times[0] if seq.num_steps else seq.end_time - seq.double_support
    if t0 > 1e-9:
        times.append(t0)
        points.append(mid)
    for k in range(seq.num_steps):
        stance = 1 - seq.swing_feet[k]
        p = feet[stance][:2]
        times += [seq.command_times[k] + seq.double_support, seq.land_times[k]]
        points += [p, p]
        feet[seq.swing_feet[k]] = np.asarray(seq.poses[k], float)
    if seq.num_steps:
        mid = 0.5 * (feet[0][:2] + feet[1][:2])
        times.append(seq.land_times[-1] + seq.double_support)
        points.append(mid)
    times.append(max(seq.end_time, times[-1] + 0.1))
    points.append(mid)
    return PiecewisePolynomial.FirstOrderHold(np.array(times), np.array(points).T)


def plan_com(
    seq: FootstepSequence, com_height: float, com0: np.ndarray | None = None
) -> ZmpPlanner:
    """Plans the CoM trajectory for a footstep sequence with Drake's ZmpPlanner (LIPM).

    Args:
        seq: the footsteps.
        com_height: CoM height above the ground [m] (constant in the LIPM).
        com0: initial CoM (x, y); default the midpoint of the initial soles.

    Returns:
        The planned ``ZmpPlanner`` (``get_nominal_com(t)`` etc.).
    """
    zmp = zmp_reference(seq)
    if com0 is None:
        com0 = zmp.value(0.0).ravel()
    planner = ZmpPlanner()
    x0 = np.array([com0[0], com0[1], 0.0, 0.0])
    planner.Plan(zmp, x0, com_height, GRAVITY, np.eye(2), 1e-4 * np.eye(2))
    if not all(np.all(np.isfinite(planner.get_nominal_com(t))) for t in zmp.get_segment_times()):
        raise RepertoireError(
            f"ZmpPlanner's CoM plan is not finite for a {seq.end_time:.1f} s footstep sequence "
            f"({seq.num_steps} steps): the LIPM's unstable mode overflows; use a shorter "
            "base_duration or fewer steps"
        )
    return planner


def _smooth(s: float) -> float:
    """Quintic smoothstep on [0, 1] (zero velocity and acceleration at both ends)."""
    s = min(max(s, 0.0), 1.0)
    return s * s * s * (10.0 + s * (-15.0 + 6.0 * s))


def swing_pose(p0: np.ndarray, p1: np.ndarray, phase: float, height: float) -> np.ndarray:
    """Swing sole pose (x, y, z, yaw) at a phase in [0, 1] of the swing.

    The sole lifts with a raised cosine (peak ``height`` at phase 0.5, zero vertical
    speed at lift-off and touch-down) and moves horizontally between phases 0.15
    and 0.85 with a quintic smoothstep.

    Args:
        p0: (x, y, yaw) lift-off pose.
        p1: (x, y, yaw) landing pose.
        phase: fraction of the swing time elapsed.
        height: peak lift [m].
    """
    phase = min(max(phase, 0.0), 1.0)
    s = _smooth((phase - 0.15) / 0.7)
    xy = p0[:2] + s * (p1[:2] - p0[:2])
    yaw = p0[2] + s * wrap_angle(p1[2] - p0[2])
    z = height * 0.5 * (1.0 - math.cos(2.0 * math.pi * phase))
    return np.array([xy[0], xy[1], z, yaw])


def foot_poses_at(seq: FootstepSequence, t: float) -> tuple[np.ndarray, np.ndarray, int]:
    """Both soles' poses (x, y, z, yaw) at time ``t`` and the current support.

    Returns:
        ``(left, right, support)`` with support 0 = double support, 1 = left stance
        (right swings), 2 = right stance (left swings).
    """
    feet = feet_at_step(seq, 0)
    support = 0
    for k in range(seq.num_steps):
        t_lift = seq.command_times[k] + seq.double_support
        if t < t_lift:
            break
        swing = seq.swing_feet[k]
        target = np.asarray(seq.poses[k], float)
        if t < seq.land_times[k]:
            phase = (t - t_lift) / (seq.land_times[k] - t_lift)
            out = {f: np.array([*feet[f][:2], 0.0, feet[f][2]]) for f in (0, 1)}
            out[swing] = swing_pose(feet[swing], target, phase, seq.swing_height)
            return out[0], out[1], 2 - swing
        feet[swing] = target
    left = np.array([*feet[0][:2], 0.0, feet[0][2]])
    right = np.array([*feet[1][:2], 0.0, feet[1][2]])
    return left, right, support


def whole_body_ik(
    com: np.ndarray,
    left: np.ndarray,
    right: np.ndarray,
    pelvis_height: float,
    *,
    iterations: int = 4,
    offset_guess: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Joint angles that put the whole-body CoM at ``com`` (x, y) with the soles at their poses.

    The pelvis is kept upright at ``pelvis_height`` with the mean yaw of the soles; its
    horizontal position is found by fixed-point iteration on the exact CoM model.

    Args:
        com: desired CoM (x, y) in the world [m].
        left: left sole pose (x, y, z, yaw).
        right: right sole pose (x, y, z, yaw).
        pelvis_height: pelvis origin height above the ground [m].
        iterations: fixed-point iterations (the CoM error shrinks ~10x per iteration).
        offset_guess: initial pelvis-minus-CoM horizontal offset (e.g. the previous
            solution's); default zero.

    Returns:
        ``(q, pelvis)``: (12,) joint angles and the pelvis pose (x, y, z, yaw).
    """
    yaw = math.atan2(math.sin(left[3]) + math.sin(right[3]), math.cos(left[3]) + math.cos(right[3]))
    R_WP = rotation_rpy(0.0, 0.0, yaw)
    p = np.array([com[0], com[1], pelvis_height], dtype=float)
    if offset_guess is not None:
        p[:2] += np.asarray(offset_guess, dtype=float)[:2]
    q = np.zeros(12)
    for k in range(max(iterations, 1)):
        for i, (foot, side) in enumerate(((left, "left"), (right, "right"))):
            p_PS = R_WP.T @ (np.array([foot[0], foot[1], foot[2]]) - p)
            R_PS = R_WP.T @ rotation_rpy(0.0, 0.0, foot[3])
            q[6 * i : 6 * i + 6] = leg_ik(p_PS, R_PS, side, strict=False)
        if k == iterations - 1:
            break  # q is the IK of this pelvis position: return them together
        c = p + R_WP @ com_in_pelvis(q)
        p[:2] += np.asarray(com[:2]) - c[:2]
    return q, np.array([p[0], p[1], p[2], yaw])


def clip_to_limits(q: np.ndarray) -> np.ndarray:
    """Clips (12,) leg joint angles to the URDF limits."""
    lo = np.array([JOINT_LIMITS[j][0] for j in LEG_JOINTS] * 2)
    hi = np.array([JOINT_LIMITS[j][1] for j in LEG_JOINTS] * 2)
    return np.clip(q, lo, hi)


def standing_com_height(pelvis_height: float) -> float:
    """CoM height above the ground of the upright biped with the pelvis at ``pelvis_height``."""
    left = np.array([0.0, 0.095, 0.0, 0.0])
    right = np.array([0.0, -0.095, 0.0, 0.0])
    q, pelvis = whole_body_ik(np.zeros(2), left, right, pelvis_height)
    return float(pelvis_height + com_in_pelvis(q)[2])


# ---------------------------------------------------------------------------------------
# LeafSystems
# ---------------------------------------------------------------------------------------


class CommandStepper(LeafSystem):
    """Turns a footstep plan's commands into the footsteps the controller takes.

    Applies the stateful stepping rule (:func:`realize_plan`) to the actions of the plan
    on its input (typically ``FootstepPlanSource``'s ``plan`` port, which is cached on
    its parameters, so the footsteps are computed once per plan).

    The footsteps are realized from the plan's start at ``start_time``, so the plan cannot
    change once the walk is under way: a plan that differs (:func:`same_commands`) from
    the one held at initialization, arriving after the first command, raises instead of
    making the feet jump to where the new plan would have them at that time (session 32:
    a switch at 3 s moved a sole target by 0.35 m and 0.7 rad and the biped fell 1.2 s
    later). Setting another plan before the first command is allowed.

    Input ports:
        plan: abstract ``FootstepPlan`` (the commands to execute).

    Output ports:
        footsteps: abstract :class:`FootstepSequence`.

    State: abstract, the plan seen at initialization (None before it).
    """

    def __init__(self, rule: SteppingRule | None = None, *, start_time: float = 0.0):
        super().__init__()
        self._rule = rule or SteppingRule()
        self._rule.validate()
        self._start_time = _check_start_time(start_time)
        self._plan = self.DeclareAbstractInputPort("plan", AbstractValue.Make(_empty_plan()))
        self._started = self.DeclareAbstractState(AbstractValue.Make(_NoPlan()))
        self.DeclareInitializationUnrestrictedUpdateEvent(self._initialize)
        self.DeclareAbstractOutputPort(
            "footsteps",
            lambda: AbstractValue.Make(realize_plan(_empty_plan(), self._rule)),
            self._calc_footsteps,
            prerequisites_of_calc={
                self.input_port_ticket(self._plan.get_index()),
                self.abstract_state_ticket(self._started),
            },
        )

    def _initialize(self, context: Context, state) -> None:
        state.get_mutable_abstract_state(self._started).set_value(self._plan.Eval(context))

    @property
    def rule(self) -> SteppingRule:
        return self._rule

    def _calc_footsteps(self, context: Context, output: AbstractValue) -> None:
        plan = self._plan.Eval(context)
        if not isinstance(plan, FootstepPlan):
            raise RepertoireError(
                f"CommandStepper's plan input needs a FootstepPlan, got {type(plan).__name__}"
            )
        started = context.get_abstract_state(self._started).get_value()
        first_command = self._start_time + self._rule.initial_hold
        t = context.get_time()
        if isinstance(started, FootstepPlan) and t > first_command:
            if not same_commands(started, plan):
                raise RepertoireError(
                    f"CommandStepper got a new plan ({plan.num_steps} steps from "
                    f"{_rounded(plan.poses[0])}) at t = {t:.3f} s, after its first step was "
                    f"commanded at {first_command:.3f} s; it walks the plan it started with "
                    f"({started.num_steps} steps from {_rounded(started.poses[0])}) and "
                    "cannot switch "
                    "plans mid-walk (the feet would jump to the new plan's steps at that "
                    "time); build a new diagram that starts where the robot stands"
                )
        output.set_value(realize_plan(plan, self._rule, start_time=self._start_time))


def _rounded(pose) -> list[float]:
    return [round(float(v), 4) + 0.0 for v in pose]


class _NoPlan:
    """The CommandStepper's state before initialization (no plan seen yet)."""


def _empty_plan() -> FootstepPlan:
    return FootstepPlan.from_commands(
        [[0.0, 0.095, 0.0]], [0], [], [0.0], [0.0, -0.095, 0.0], ["stop", "stop"], goal=[0.0, 0.0]
    )


@dataclasses.dataclass
class _ComPlan:
    """ZmpComPlanner's cached CoM plan and the footsteps it was made for."""

    footsteps: FootstepSequence | None = None
    planner: ZmpPlanner = dataclasses.field(default_factory=ZmpPlanner)


class ZmpComPlanner(LeafSystem):
    """Desired ZMP and the LIPM-optimal CoM trajectory (Drake ``ZmpPlanner``) for footsteps.

    Input ports:
        footsteps: abstract :class:`FootstepSequence`.

    Output ports:
        com: (4,) planned CoM [x, y, xdot, ydot] at the context time.
        zmp_reference: (2,) desired ZMP [x, y] at the context time.
    """

    def __init__(self, com_height: float):
        super().__init__()
        if not 0.3 < com_height < 1.2:
            raise RepertoireError(f"com_height must be in (0.3, 1.2) m, got {com_height}")
        self._com_height = com_height
        self._footsteps = self.DeclareAbstractInputPort(
            "footsteps", AbstractValue.Make(realize_plan(_empty_plan(), SteppingRule()))
        )
        ticket = {self.input_port_ticket(self._footsteps.get_index())}
        self._planner = self.DeclareAbstractOutputPort(
            "zmp_planner",
            lambda: AbstractValue.Make(_ComPlan()),
            self._calc_planner,
            prerequisites_of_calc=ticket,
        )
        self._com = self.DeclareVectorOutputPort("com", 4, self._calc_com)
        self._zmp = self.DeclareVectorOutputPort("zmp_reference", 2, self._calc_zmp)

    def _calc_planner(self, context: Context, output: AbstractValue) -> None:
        # cached on the footsteps input: checked once per new sequence, not per step
        footsteps = self._footsteps.Eval(context)
        if not isinstance(footsteps, FootstepSequence):
            raise RepertoireError(
                "ZmpComPlanner's footsteps input needs a FootstepSequence, "
                f"got {type(footsteps).__name__}"
            )
        # An upstream state update (e.g. FootstepFeedback's) invalidates this entry every
        # period; the same footsteps keep the plan they have (one Plan per change).
        if output.get_value().footsteps != footsteps:
            output.set_value(_ComPlan(footsteps, plan_com(footsteps, self._com_height)))

    def _calc_com(self, context: Context, output: BasicVector) -> None:
        planner = self._planner.Eval(context).planner
        t = context.get_time()
        output.SetFromVector(
            np.concatenate(
                [planner.get_nominal_com(t).ravel(), planner.get_nominal_comd(t).ravel()]
            )
        )

    def _calc_zmp(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(
            self._planner.Eval(context).planner.get_desired_zmp(context.get_time()).ravel()
        )


class SwingFootPlanner(LeafSystem):
    """Sole poses of both feet over time (stance feet fixed, swing foot lifted and moved).

    Input ports:
        footsteps: abstract :class:`FootstepSequence`.

    Output ports:
        left_foot: (4,) left sole [x, y, z, yaw] at the context time.
        right_foot: (4,) right sole [x, y, z, yaw].
        support: (1,) 0 double support, 1 left stance, 2 right stance.
    """

    def __init__(self):
        super().__init__()
        self._footsteps = self.DeclareAbstractInputPort(
            "footsteps", AbstractValue.Make(realize_plan(_empty_plan(), SteppingRule()))
        )
        self._left = self.DeclareVectorOutputPort("left_foot", 4, self._calc(0))
        self._right = self.DeclareVectorOutputPort("right_foot", 4, self._calc(1))
        self._support = self.DeclareVectorOutputPort("support", 1, self._calc(2))

    def _calc(self, which: int):
        def calc(context: Context, output: BasicVector) -> None:
            result = foot_poses_at(self._footsteps.Eval(context), context.get_time())
            output.SetFromVector(np.atleast_1d(np.asarray(result[which], dtype=float)))

        return calc


class WalkingIK(LeafSystem):
    """Whole-body IK of the walking pattern -> desired joint state for the plant's PD.

    Every ``period`` seconds it solves :func:`whole_body_ik` for the inputs and stores
    the joint angles; the desired velocity is their finite difference.

    Input ports:
        com: (4,) desired CoM [x, y, xdot, ydot] (only x, y are used).
        left_foot: (4,) left sole [x, y, z, yaw].
        right_foot: (4,) right sole [x, y, z, yaw].
        measured_com: with ``com_gain`` > 0, (3,) the robot's CoM; the IK then aims the CoM
            at ``com + com_gain (com - measured_com)`` (x, y), a proportional CoM feedback.

    Output ports:
        desired_state: (24,) [q (12), v (12)] in ``JOINT_NAMES`` order.
        pelvis_reference: (4,) pelvis [x, y, z, yaw] of the last solve.

    Parameters: pelvis height (numeric parameter, index 0).
    """

    def __init__(self, pelvis_height: float, *, period: float = 0.005, com_gain: float = 0.0):
        super().__init__()
        if not period > 0:
            raise RepertoireError(f"period must be > 0, got {period}")
        if not (is_real(com_gain) and math.isfinite(com_gain) and com_gain >= 0.0):
            raise RepertoireError(f"com_gain must be a finite number >= 0, got {com_gain!r}")
        self._period, self._com_gain = period, float(com_gain)
        self._com = self.DeclareVectorInputPort("com", 4)
        self._left = self.DeclareVectorInputPort("left_foot", 4)
        self._right = self.DeclareVectorInputPort("right_foot", 4)
        if com_gain > 0.0:
            self._measured = self.DeclareVectorInputPort("measured_com", 3)
        self._height_index = self.DeclareNumericParameter(BasicVector([pelvis_height]))
        # [q (12), v (12), pelvis x, y, z, yaw, pelvis-minus-CoM offset x, y]
        self._state = self.DeclareDiscreteState(24 + 4 + 2)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        self.DeclareInitializationDiscreteUpdateEvent(self._initialize)
        self.DeclareVectorOutputPort(
            "desired_state", 24, self._calc_desired, prerequisites_of_calc={self.xd_ticket()}
        )
        self.DeclareVectorOutputPort(
            "pelvis_reference", 4, self._calc_pelvis, prerequisites_of_calc={self.xd_ticket()}
        )

    def _solve(
        self, context: Context, offset: np.ndarray | None, iterations: int
    ) -> tuple[np.ndarray, np.ndarray]:
        height = context.get_numeric_parameter(self._height_index).GetAtIndex(0)
        left, right = self._left.Eval(context), self._right.Eval(context)
        com = self._aim(context)
        return whole_body_ik(com, left, right, height, iterations=iterations, offset_guess=offset)

    def _aim(self, context: Context) -> np.ndarray:
        """The (x, y) the IK puts the CoM at (the planned CoM, with the CoM feedback)."""
        com = np.array(self._com.Eval(context)[:2])
        if self._com_gain > 0.0:
            com += self._com_gain * (com - self._measured.Eval(context)[:2])
        return com

    def _initialize(self, context: Context, discrete_state: DiscreteValues) -> None:
        q, pelvis = self._solve(context, None, 6)
        offset = pelvis[:2] - self._aim(context)
        discrete_state.set_value(self._state, np.concatenate([q, np.zeros(12), pelvis, offset]))

    def _update(self, context: Context, discrete_state: DiscreteValues) -> None:
        old = context.get_discrete_state(self._state).get_value()
        # Warm start from the previous pelvis-minus-CoM offset: two iterations suffice.
        q, pelvis = self._solve(context, old[28:30], 2)
        v = (q - old[:12]) / self._period
        offset = pelvis[:2] - self._aim(context)
        discrete_state.set_value(self._state, np.concatenate([q, v, pelvis, offset]))

    def _calc_desired(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(context.get_discrete_state(self._state).get_value()[:24])

    def _calc_pelvis(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(context.get_discrete_state(self._state).get_value()[24:28])


__all__ = [
    "ANKLE_HEIGHT",
    "FORWARD_COMMAND",
    "CommandStepper",
    "FootstepSequence",
    "SteppingRule",
    "SwingFootPlanner",
    "WalkingIK",
    "ZmpComPlanner",
    "clip_to_limits",
    "compose",
    "foot_poses_at",
    "plan_com",
    "realize_commands",
    "realize_plan",
    "realize_step",
    "relative",
    "same_commands",
    "standing_com_height",
    "swing_pose",
    "whole_body_ik",
    "zmp_reference",
]
