"""GoToPose: drive a differential-drive robot to a pose and speed, reporting its status.

The controller is a smooth pose controller in polar coordinates (the
navigation of Stulp & Beetz, section 3: translational and rotational velocity
commands that turn towards the goal while approaching it and align with the
goal heading on arrival). With ``rho`` the distance to the goal, ``alpha`` the
turn to face it (``angle_to``) and ``beta = -(alpha + angle_at)``:

    v     = clip(max(v_g, k_rho * rho) * cos(alpha), -v_max, v_max)
    omega = clip(k_alpha * alpha + k_beta * beta, -omega_max, omega_max)

and both commands are rate limited by ``a_max`` and ``alpha_max`` in the
discrete update, so the command is continuous. Pure math is in
:func:`pose_control`; the LeafSystem holds the limited command and the status
in its discrete state.

Inside the position tolerance the law stops and turns in place, so a target
speed ``v_g`` that a stopped robot does not meet (``v_g >= 0.1`` m/s, see
:func:`drive_step`) could never be met there: a robot that reached the target
position too slowly, reversing, or facing the wrong way waited for its timeout.
It then runs up instead (:func:`goto_mode`): it drives to the run-up pose, the
target pose moved back along the target heading by :func:`run_up_distance`
(room to reach ``v_g`` at ``a_max``), by turning, driving straight and turning
(:func:`run_up_control`), and approaches again from there, straight and
accelerating.
"""

import dataclasses
import math

import numpy as np
from pydrake.systems.framework import BasicVector, Context, DiscreteValues, LeafSystem
from repertoire.planning.action_models.features import wrap_angle
from repertoire.systems import goto_law
from repertoire.systems.action_status import (
    ActionStatus,
    ActionSystem,
    check_period,
    check_workspace,
    clip,
    merge_gains,
)

from repertoire.errors import RepertoireError

# name -> default, in the order of the numeric parameter vector.
GOTO_GAINS = {
    "v_max": 0.8,  # m/s
    "omega_max": 2.5,  # rad/s
    "a_max": 1.0,  # m/s^2
    "alpha_max": 5.0,  # rad/s^2
    "k_rho": 0.8,
    "k_alpha": 3.0,
    "k_beta": -1.0,
    "position_tolerance": 0.05,  # m
    "heading_tolerance": 0.15,  # rad
    "timeout": 20.0,  # s, from the action's start (DriveAction)
}


def pose_control(state, target, gains: dict[str, float]) -> tuple[float, float, float, float]:
    """Unlimited (v, omega) commands and the remaining (distance, heading error).

    The compiled :func:`~repertoire.systems.goto_law.law` (one math for the LeafSystem
    and the planners' rollouts, :func:`goto_rollout`).

    Args:
        state: ``[x, y, phi, v]``.
        target: ``[x_g, y_g, phi_g, v_g]``.
        gains: the :data:`GOTO_GAINS` keys.

    Returns:
        ``(v_cmd, omega_cmd, rho, heading_error)``.
    """
    x, y, phi = (float(v) for v in state[:3])
    xg, yg, phig, vg = (float(v) for v in target)
    return goto_law.law(x, y, phi, xg, yg, phig, vg, gains_vector(gains))


def gains_vector(gains: dict[str, float]) -> np.ndarray:
    """The gains as a vector in :data:`GOTO_GAINS` order (the compiled law's)."""
    return np.array([float(gains[name]) for name in GOTO_GAINS])


def speed_tolerance(v_g: float) -> float:
    """How close (m/s) the robot's speed must be to the target speed ``v_g`` on arrival."""
    return goto_law.speed_tolerance(float(v_g))


def run_up_distance(v_g: float, gains: dict[str, float]) -> float:
    """Distance (m) of the run-up pose behind the target (see :func:`goto_mode`).

    Twice the distance in which ``a_max`` brings a stopped robot to ``v_g``
    (``v_g^2 / (2 a_max)``; twice: the chassis lags its command), plus the
    position tolerance on either side of the target.
    """
    return v_g * v_g / gains["a_max"] + 2.0 * gains["position_tolerance"]


def run_up_pose(target, gains: dict[str, float]) -> list[float]:
    """``[x, y, phi_g, 0]``: the target moved back along its heading by the run-up distance."""
    xg, yg, phig, vg = target
    d = run_up_distance(vg, gains)
    return [xg - d * math.cos(phig), yg - d * math.sin(phig), phig, 0.0]


def run_up_control(
    state, pose, gains: dict[str, float], reverse: bool = True
) -> tuple[float, float]:
    """Unlimited ``(v, omega)`` to a pose by turning, driving straight, turning.

    The polar law of :func:`pose_control` is singular for a pose just behind the
    robot with about its heading (both angles near pi: it spins), which is where a
    run-up pose lies. This law turns in place to face the pose's position (or to
    back onto it when it lies behind: the smaller turn; never with ``reverse``
    False, as for DribbleBall's pivot, which does not back away from its ball),
    drives straight at ``k_rho * rho`` while steering with ``k_alpha``, and within
    the position tolerance turns in place to the pose's heading.
    """
    x, y, phi, _ = state
    xp, yp, php, _ = pose
    g = gains
    dx, dy = xp - x, yp - y
    rho = math.hypot(dx, dy)
    if rho < g["position_tolerance"]:
        heading_error = float(wrap_angle(php - phi))
        return 0.0, clip(g["k_alpha"] * heading_error, -g["omega_max"], g["omega_max"])
    e = float(wrap_angle(math.atan2(dy, dx) - phi))
    sign = 1.0
    if reverse and abs(e) > 0.5 * math.pi:  # back onto it: the smaller turn
        e, sign = float(wrap_angle(e + math.pi)), -1.0
    omega = clip(g["k_alpha"] * e, -g["omega_max"], g["omega_max"])
    if abs(e) > RUN_UP_AIM_RAD:  # face it (or its reverse) first
        return 0.0, omega
    v = clip(sign * g["k_rho"] * rho * math.cos(e), -g["v_max"], g["v_max"])
    return v, omega


RUN_UP_AIM_RAD = 0.2
"""The run-up drives only while its heading is within this of the line to the pose (rad)."""

APPROACH, RUN_UP = 0, 1
"""GoToPose's modes: approach the target, or drive to its run-up pose first."""


def goto_mode(mode: int, state, target, gains: dict[str, float]) -> int:
    """GoToPose's next mode (:data:`APPROACH` or :data:`RUN_UP`).

    RUN_UP when the robot is within the position tolerance of the target at a
    speed off the target speed by :func:`speed_tolerance` or more and the target
    speed is one a stopped robot does not meet (there the law would stop it for
    good); back to APPROACH at the run-up pose (within the position and heading
    tolerances), or at once when the target speed no longer needs a run-up (a
    plan executor changed the target).
    """
    vg = target[3]
    if abs(vg) < speed_tolerance(vg):
        return APPROACH
    g = gains
    if mode == RUN_UP:
        xr, yr, phir, _ = run_up_pose(target, g)
        there = math.hypot(xr - state[0], yr - state[1]) < g["position_tolerance"]
        aligned = abs(float(wrap_angle(phir - state[2]))) < g["heading_tolerance"]
        return APPROACH if there and aligned else RUN_UP
    inside = math.hypot(target[0] - state[0], target[1] - state[1]) < g["position_tolerance"]
    if inside and abs(state[3] - vg) >= speed_tolerance(vg):
        return RUN_UP
    return APPROACH


def drive_step(
    control, previous, state, target, gains, time: float, period: float, active: bool = True,
    steer: "tuple[float, float] | None" = None,
) -> list:  # fmt: skip
    """The next discrete state ``[v_cmd, omega_cmd, status]`` of a driving action.

    ``control`` is ``(v, omega, rho, heading_error)`` (as :func:`pose_control`
    returns it). SUCCEEDED (holding the ``previous`` command) within the
    position and heading tolerances at about the target speed
    (:func:`speed_tolerance`), TIMED_OUT once ``time`` (the time since the action
    started, :class:`DriveAction`) reaches the timeout, else RUNNING with
    ``(v, omega)`` (or ``steer``: a command aimed elsewhere, GoToPose's run-up)
    rate limited by ``a_max`` and ``alpha_max`` from ``previous``. An action that
    is not ``active`` (a plan's later action, not started yet) only tracks the
    command and stays RUNNING.
    """
    v, w, rho, heading_error = control
    if steer is not None:
        v, w = steer
    g = gains
    speed, vg = float(state[3]), float(target[3])
    tolerances = (g["position_tolerance"], g["heading_tolerance"])
    if active and goto_law.arrived(rho, heading_error, speed, vg, *tolerances):
        return [previous[0], previous[1], ActionStatus.SUCCEEDED]
    if active and time >= g["timeout"]:
        return [0.0, 0.0, ActionStatus.TIMED_OUT]
    limits = (g["a_max"], g["alpha_max"], period)
    v, w = goto_law.rate_limit(v, w, float(previous[0]), float(previous[1]), *limits)
    return [v, w, ActionStatus.RUNNING]


@dataclasses.dataclass
class GotoRollout:
    """What :func:`goto_rollout` predicts, per row.

    Attributes:
        poses: ``(n, T + 1, 4)`` states ``[x, y, phi, v]`` at every update (a row that
            ended keeps its last state).
        omega: ``(n, T + 1)`` the yaw rate commanded from each state on (0 after the end).
        steps: ``(n,)`` the update at which the row succeeded (its last pose), or -1 (it
            timed out at T).
    """

    poses: np.ndarray
    omega: np.ndarray
    steps: np.ndarray


def goto_rollout(start, target, gains: dict[str, float], period: float) -> GotoRollout:
    """GoToPose's drives predicted on a kinematic unicycle, for many rows at once.

    The compiled law (:func:`~repertoire.systems.goto_law.rollout`: the LeafSystem's own
    functions) closed around the unicycle.

    The update at ``t = i period`` computes the command from the state (as the
    LeafSystem's periodic update, starting from a zero command); the unicycle then moves
    exactly on the arc of that command (speed and yaw rate) for one period and its speed
    is the command's. A real chassis lags its command: a plan checks the rollout with a
    margin. Targets must not need GoToPose's run-up (``|v_g|`` below
    :func:`speed_tolerance`: a drive to a pose at rest, as the kitchen's).

    Args:
        start: ``(n, 4)`` start states ``[x, y, phi, v]`` (``v`` is the measured speed).
        target: ``(n, 4)`` targets ``[x_g, y_g, phi_g, v_g]``.
        gains: all :data:`GOTO_GAINS` keys.
        period: GoToPose's update period [s].

    Returns:
        The rollout (:class:`GotoRollout`), up to the last row's end or the timeout.
    """
    check_period(period)
    s = np.array(np.atleast_2d(start), dtype=float)
    t = np.broadcast_to(np.atleast_2d(np.asarray(target, dtype=float)), s.shape).copy()
    if s.shape[-1] != 4 or not (np.all(np.isfinite(s)) and np.all(np.isfinite(t))):
        raise RepertoireError(f"start and target must be finite rows of 4, got shapes "
                              f"{np.shape(start)}, {np.shape(target)}")  # fmt: skip
    if np.any(np.abs(t[:, 3]) >= np.maximum(0.1, 0.5 * t[:, 3])):
        raise RepertoireError(f"goto_rollout does not model the run-up: target speeds must be "
                              f"below 0.1 m/s, got {t[:, 3].tolist()}")  # fmt: skip
    last = int(math.floor(gains["timeout"] / period + 1e-9))
    poses, omega, steps = goto_law.rollout(s, t, gains_vector(gains), float(period), last)
    return GotoRollout(poses, omega, steps)


class DriveAction(ActionSystem):
    """What GoToPose and DribbleBall share: gains, workspace, ports and ``[v, omega, status]``.

    The timeout counts from the action's start: the last slot of the discrete state holds
    the time of the action's last update with its ``active`` input 0 (0 if it was active
    from the first update, as a lone action is), and :func:`drive_step` gets the time
    since then. In a plan the executor starts each action after the previous one ended,
    so each leg has its whole timeout (as the kitchen actions count theirs from their
    first update); a lone action's timeout still counts from the simulation's start.
    """

    def _declare_drive(
        self, period: float, names, merged, workspace, inputs, next_state, extra_slots: int = 0
    ) -> dict:
        """Declares gains, workspace, the ``inputs`` (name, size), state, command and status.

        The discrete state is ``[v_cmd, omega_cmd, status]`` followed by
        ``extra_slots`` zeros the subclass uses (DribbleBall's approach mode) and the
        start time (see the class). Returns the input ports by name.

        Args:
            next_state: ``(context, xd, elapsed) -> list``, the subclass's law: the next
                discrete state without the start time, given the state without its last
                slot and the time since the action started [s] (its timeout's clock).
        """
        self._next_state = next_state
        ws = check_workspace(workspace)
        self.period = period
        self._declare_gains(names, merged)
        self._workspace_index = self.DeclareNumericParameter(BasicVector(ws))
        ports = {name: self.DeclareVectorInputPort(name, size) for name, size in inputs}
        self._state_port, self._target_port = ports["state"], ports["target"]
        self._active_port = self.DeclareVectorInputPort("active", 1)
        self._xd = self.DeclareDiscreteState(3 + extra_slots + 1)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        self._command_port = self.DeclareVectorOutputPort(
            "command", 2, self._calc_command, {self.discrete_state_ticket(self._xd)}
        )
        self._declare_status_port(self._xd, 2)
        return ports

    def _update(self, context: Context, discrete_state: DiscreteValues) -> None:
        xd = context.get_discrete_state(self._xd).get_value()
        t = context.get_time()
        started = float(xd[-1]) if self.is_active(context) else t
        values = self._next_state(context, xd[:-1], t - started)
        discrete_state.get_mutable_vector(self._xd).SetFromVector([*values, started])

    def get_state_input_port(self):
        return self._state_port

    def get_target_input_port(self):
        return self._target_port

    def get_active_input_port(self):
        return self._active_port

    def is_active(self, context: Context) -> bool:
        """False while the ``active`` input (when connected or fixed) is below 0.5.

        A plan executor connects it so that a later action does not succeed, fail or
        time out (a terminal status is kept) before it has started; unconnected, the
        action is active.
        """
        port = self._active_port
        return not port.HasValue(context) or port.Eval(context)[0] >= 0.5

    def get_command_output_port(self):
        return self._command_port

    def _calc_command(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(context.get_discrete_state(self._xd).get_value()[:2])


class GoToPose(DriveAction):
    """Drives a differential-drive robot to a target pose and speed.

    Input ports:
        state: ``[x, y, phi, v]`` of the robot.
        target: ``[x_g, y_g, phi_g, v_g]`` (a plan executor changes it).
        active: optional ``[1]`` (default) or ``[0]``: while 0 the action tracks its
            command but stays RUNNING (a plan's action that has not started yet).

    Output ports:
        command: ``[v, omega]`` rate-limited forward speed and yaw rate.
        status: an :class:`ActionStatus` (abstract).

    Parameters (numeric parameter 0, :data:`GOTO_GAINS` order): speed and
    acceleration limits, gains, tolerances and the timeout. The workspace
    ``[x_min, x_max, y_min, y_max]`` is numeric parameter 1: a target outside
    it (or a non-finite target or state) makes the action fail at once (no motion).

    Discrete state: ``[v_cmd, omega_cmd, status, mode, started]`` (:func:`goto_mode`;
    ``started`` the timeout's start, :class:`DriveAction`),
    updated every ``period`` s.
    """

    def __init__(
        self,
        period: float = 0.01,
        gains: dict[str, float] | None = None,
        workspace: tuple[float, float, float, float] = (-3.0, 3.0, -2.0, 2.0),
    ):
        """Creates the action.

        Args:
            period: update period [s].
            gains: overrides of :data:`GOTO_GAINS` (the limits, tolerances, timeout,
                ``k_rho`` and ``k_alpha`` must be > 0).
            workspace: the allowed target region ``[x_min, x_max, y_min, y_max]``.
        """
        super().__init__()
        check_period(period)
        positive = (
            "v_max",
            "omega_max",
            "a_max",
            "alpha_max",
            "timeout",
            "position_tolerance",
            "heading_tolerance",
            "k_rho",  # <= 0: a robot asked to arrive at rest never moves
            "k_alpha",  # <= 0: it turns away from the goal heading and never aligns
        )
        merged = merge_gains(GOTO_GAINS, gains, "GoToPose", positive)
        inputs = (("state", 4), ("target", 4))
        self._declare_drive(
            period, GOTO_GAINS, merged, workspace, inputs, self._next, extra_slots=1
        )

    def _next(self, context: Context, xd: np.ndarray, elapsed: float) -> list:
        v_prev, w_prev, status, mode = xd
        if status != ActionStatus.RUNNING:
            return [0.0, 0.0, status, mode]
        g = self.gains(context)
        state = self._state_port.Eval(context)
        target = self._target_port.Eval(context)
        ws = context.get_numeric_parameter(self._workspace_index).get_value()
        active = self.is_active(context)
        if (
            not np.all(np.isfinite(target))
            or not np.all(np.isfinite(state))
            or not ws[0] <= target[0] <= ws[1]
            or not ws[2] <= target[1] <= ws[3]
        ):
            failed = ActionStatus.FAILED if active else ActionStatus.RUNNING
            return [0.0, 0.0, failed, mode]
        if active:
            mode = goto_mode(int(mode), state, target, g)
        control = pose_control(state, target, g)
        steer = run_up_control(state, run_up_pose(target, g), g) if mode == RUN_UP else None
        previous = (v_prev, w_prev)
        step = drive_step(control, previous, state, target, g, elapsed, self.period, active, steer)
        return [*step, mode]


class DiffDriveStateReader(LeafSystem):
    """Reads ``[x, y, phi, v]`` of the robot's chassis from the plant's state.

    Input ports:
        plant_state: the MultibodyPlant's full state ``[q, v]``.

    Output ports:
        state: ``[x, y, yaw, forward speed]`` of the chassis.
    """

    def __init__(self, plant, body_name: str = "chassis"):
        """Creates the reader.

        Args:
            plant: the finalized plant (read for indices only).
            body_name: the floating chassis body.
        """
        super().__init__()
        body = plant.GetBodyByName(body_name)
        if not body.is_floating_base_body():
            raise RepertoireError(f"body {body_name!r} is not a floating base body")
        self._q0 = body.floating_positions_start()
        self._v0 = plant.num_positions() + body.floating_velocities_start_in_v()
        self._in = self.DeclareVectorInputPort(
            "plant_state", plant.num_positions() + plant.num_velocities()
        )
        self.DeclareVectorOutputPort("state", 4, self._calc)

    def _calc(self, context: Context, output: BasicVector) -> None:
        x = self._in.Eval(context)
        state = chassis_state(x[self._q0 : self._q0 + 7], x[self._v0 : self._v0 + 6])
        output.SetFromVector(state)


def chassis_state(q_floating, v_floating) -> np.ndarray:
    """``[x, y, yaw, forward speed]`` from floating positions and velocities.

    Args:
        q_floating: ``[qw, qx, qy, qz, x, y, z]``.
        v_floating: ``[wx, wy, wz, vx, vy, vz]`` (world frame).
    """
    qw, qx, qy, qz, x, y, _ = q_floating
    yaw = math.atan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))
    v = v_floating[3] * math.cos(yaw) + v_floating[4] * math.sin(yaw)
    return np.array([x, y, yaw, v])
