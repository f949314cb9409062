"""Running an arm DMP world and reading it back: the IK-checked run, named logs, scoring.

:func:`run_arm_world` simulates a world through :func:`repertoire.diagrams.simulate.simulate`
with an IK-status monitor; :func:`tcp_log` and :func:`point_log` read the named loggers by
field; :func:`pick_and_place_figures` and :func:`serving_figures` score a run (they are also
the registry's checks of the two worlds).
"""

import dataclasses
import time
from collections.abc import Callable, Sequence

import numpy as np
from pydrake.systems.framework import Context, Diagram, EventStatus
from repertoire.diagrams.arm_dmp_scenarios import shoulder_and_reach
from repertoire.diagrams.simulate import simulate
from repertoire.models.arm7 import ARM_JOINTS, OBSTACLE_RADIUS, arm7_joint_limits
from repertoire.planning.arm_library import BOTTLE_GRASP_HEIGHT, COASTER_TOP
from repertoire.systems.task_space import (
    STATUS_JOINT_LIMITS,
    STATUS_NAMES,
    STATUS_OK,
    STATUS_TARGET_OUT_OF_REACH,
    STATUS_TRACKING_LOST,
)

from repertoire.errors import RepertoireError


class IkTargetError(RepertoireError):
    """The task-space IK reported a target out of reach or lost tracking during a run."""


def run_arm_world(
    diagram: Diagram, duration: float, *, monitors: Sequence[Callable] = ()
) -> tuple[Context, float]:
    """Simulates an arm DMP world, stopping with a clear error if the IK reports a problem.

    Runs through :func:`repertoire.diagrams.simulate.simulate` (its non-finite-state check)
    with the IK-status monitor added.

    Args:
        diagram: a diagram built by this module.
        duration: simulated seconds.
        monitors: more per-step monitors ``f(root_context) -> EventStatus``, called before
            the IK-status one (so they also see the step where the IK reports), e.g. a
            :class:`JointLimitRecorder`.

    Returns:
        (final root context, wall-clock seconds of the simulation).

    Raises:
        IkTargetError: the active goal left the arm's reach, or the IK reported a
            desired position out of reach or lost tracking (says when, which segment
            and where the goal and the target were).
    """
    rmrc = diagram.GetSubsystemByName("rmrc")
    chain = diagram.GetSubsystemByName("dmp_chain")
    schedule = diagram.GetSubsystemByName("goal_schedule")
    status_port = rmrc.GetOutputPort("status")
    shoulder, reach = shoulder_and_reach()
    problem = {}

    def ik_monitor(context: Context) -> EventStatus:
        rmrc_context = rmrc.GetMyContextFromRoot(context)
        status = int(status_port.Eval(rmrc_context)[0])
        goal = schedule.GetOutputPort("goal").Eval(schedule.GetMyContextFromRoot(context))[:3]
        if status == STATUS_OK and np.linalg.norm(goal - shoulder) > reach:
            status = STATUS_TARGET_OUT_OF_REACH
        if status == STATUS_OK:
            return EventStatus.Succeeded()
        chain_context = chain.GetMyContextFromRoot(context)
        problem.update(
            status=status,
            time=context.get_time(),
            segment=int(chain.GetOutputPort("segment").Eval(chain_context)[0]),
            target=chain.GetOutputPort("tcp_position").Eval(chain_context).copy(),
            goal=goal.copy(),
            error=rmrc.GetOutputPort("task_error").Eval(rmrc_context).copy(),
            held=rmrc.GetOutputPort("joints_at_limits").Eval(rmrc_context).copy(),
        )
        return EventStatus.ReachedTermination(rmrc, STATUS_NAMES[status])

    start = time.perf_counter()
    _, root = simulate(diagram, duration, monitors=[*monitors, ik_monitor])
    wall = time.perf_counter() - start
    if problem:
        distance = float(np.linalg.norm(problem["goal"] - shoulder))
        raise IkTargetError(
            f"{diagram.get_name()}: IK reported '{STATUS_NAMES[problem['status']]}' at "
            f"t = {problem['time']:.3f} s in segment {problem['segment']}: goal "
            f"{np.round(problem['goal'], 3).tolist()} ({distance:.3f} m from"
            f" the shoulder, reach {reach:.3f} m), desired tcp position "
            f"{np.round(problem['target'], 3).tolist()}, tcp error {problem['error'][0]:.3f} m and "
            f"{problem['error'][1]:.3f} rad{joints_at_limits_text(problem['held'])}; "
            "the simulation was stopped there"
        )
    return root, wall


def joints_at_limits_text(held: np.ndarray) -> str:
    """``", joints held at a limit: wrist_abduction (upper, 0.6 rad)"`` for the IK's report.

    Args:
        held: the IK's ``joints_at_limits`` output over arm7's joints (+1 upper, -1 lower).

    Returns:
        The clause naming each held joint and its limit, or ``""`` when none is held.
    """
    lower, upper = arm7_joint_limits()
    names = [
        f"{joint} ({'upper' if h > 0 else 'lower'}, {(upper if h > 0 else lower)[k]:g} rad)"
        for k, (joint, h) in enumerate(zip(ARM_JOINTS, held, strict=True))
        if h != 0
    ]
    if not names:
        return ""
    return (
        f", joints held at a limit: {', '.join(names)} (the desired pose lies beyond what "
        "the IK attains within arm7's joint limits there)"
    )


class JointLimitRecorder:
    """A per-step monitor recording the IK's joint references and the joints it holds.

    Pass it to :func:`run_arm_world`'s ``monitors``; after the run, :attr:`times`,
    :attr:`q` and :attr:`held` hold, for every simulator step, the time, the RMRC IK's
    reference positions ``q_r`` of arm7's joints and its ``joints_at_limits`` output (+1
    upper, -1 lower, 0 free).
    """

    def __init__(self, diagram: Diagram):
        """Records the ``rmrc`` IK of ``diagram`` (an arm world)."""
        self._rmrc = diagram.GetSubsystemByName("rmrc")
        self._reference = self._rmrc.GetOutputPort("arm_reference_state")
        self._held = self._rmrc.GetOutputPort("joints_at_limits")
        self._rows: list[np.ndarray] = []

    def __call__(self, context: Context) -> EventStatus:
        """Records the step; never stops the run."""
        rmrc_context = self._rmrc.GetMyContextFromRoot(context)
        held = self._held.Eval(rmrc_context)
        q = self._reference.Eval(rmrc_context)[: len(held)]
        self._rows.append(np.concatenate([[context.get_time()], q, held]))
        return EventStatus.Succeeded()

    def _table(self) -> np.ndarray:
        n = self._held.size()
        return np.array(self._rows).reshape(-1, 1 + 2 * n)

    @property
    def times(self) -> np.ndarray:
        """Times of the recorded steps, (k,) [s]."""
        return self._table()[:, 0]

    @property
    def q(self) -> np.ndarray:
        """The IK's reference joint positions, (k, n) [rad]."""
        return self._table()[:, 1 : 1 + self._held.size()]

    @property
    def held(self) -> np.ndarray:
        """The IK's ``joints_at_limits`` at each step, (k, n)."""
        return self._table()[:, 1 + self._held.size() :]


def limit_margins(q, lower, upper) -> np.ndarray:
    """Per joint, the least distance of its positions from either of its limits.

    Args:
        q: joint positions, (k, n) [rad] (k >= 1).
        lower: the joints' lower limits, (n,).
        upper: the joints' upper limits, (n,).

    Returns:
        (n,) ``min over rows of min(q - lower, upper - q)`` (0 on a limit, negative past it).

    Raises:
        RepertoireError: no rows, or shapes that do not match.
    """
    q = np.asarray(q, dtype=float)
    lower, upper = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    if q.ndim != 2 or len(q) == 0 or q.shape[1] != lower.size or lower.shape != upper.shape:
        raise RepertoireError(
            f"limit_margins needs q of shape (k >= 1, n) and n lower and upper limits, got "
            f"{q.shape}, {lower.shape} and {upper.shape}"
        )
    return np.minimum(q - lower, upper - q).min(axis=0)


def ik_status_figures(diagram: Diagram, context: Context) -> dict[str, float]:
    """The RMRC IK's status at the end of a run, as flags (1 = it was reported).

    The status latches (:class:`~repertoire.systems.task_space.ResolvedMotionRateIK`), so a
    flag says the IK reported it at some time of the run. :func:`run_arm_world` stops a
    run there with the details; a run simulated to its end (``repertoire simulate``) shows
    it with these figures, e.g. a place goal the arm approached with a joint at its limit.

    Returns:
        ``ik_target_out_of_reach``, ``ik_tracking_lost`` (the task-space error stayed
        above the IK's tolerance longer than its hold time) and ``ik_joint_limits`` (the
        same, with joints held at a position limit then), each 0 or 1.
    """
    rmrc = diagram.GetSubsystemByName("rmrc")
    status = int(rmrc.GetOutputPort("status").Eval(rmrc.GetMyContextFromRoot(context))[0])
    return {
        "ik_target_out_of_reach": float(status == STATUS_TARGET_OUT_OF_REACH),
        "ik_tracking_lost": float(status == STATUS_TRACKING_LOST),
        "ik_joint_limits": float(status == STATUS_JOINT_LIMITS),
    }


@dataclasses.dataclass
class PointLog:
    """A logged body point and axis (``BodyPointAndAxis``), by field.

    Attributes:
        t: Sample times, shape (N,) [s].
        point: The point in world, shape (N, 3) [m].
        axis: The body's z axis in world, shape (N, 3).
    """

    t: np.ndarray
    point: np.ndarray
    axis: np.ndarray


@dataclasses.dataclass
class TcpLog(PointLog):
    """The ``tcp_log`` of an arm world, by field (``point`` is the tcp, ``axis`` the palm z).

    Attributes:
        goal: The current segment's goal (position 3, quaternion 4, fingers 3), (N, 10).
        segment: Index of the running chain segment, shape (N,).
    """

    goal: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 10)))
    segment: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0, dtype=int))


def point_log(diagram: Diagram, context: Context, name: str) -> PointLog:
    """The samples of a point logger (``"tip_log"``, ...) of an arm world.

    Args:
        diagram: The arm world.
        context: Its root context after a run.
        name: The logger's name.
    """
    log = diagram.GetSubsystemByName(name).FindLog(context)
    data = log.data().T
    return PointLog(log.sample_times().copy(), data[:, 0:3], data[:, 3:6])


def tcp_log(diagram: Diagram, context: Context) -> TcpLog:
    """The arm world's ``tcp_log``: tcp, palm axis, segment goal and segment index.

    Args:
        diagram: The arm world.
        context: Its root context after a run.
    """
    log = diagram.GetSubsystemByName("tcp_log").FindLog(context)
    data = log.data().T
    return TcpLog(
        log.sample_times().copy(),
        data[:, 0:3],
        data[:, 3:6],
        data[:, 6:16],
        data[:, 16].astype(int),
    )


def segment_reach_errors(diagram: Diagram, context: Context) -> list[float]:
    """|tcp - goal| at the end of each segment (the last log sample of the segment) [m]."""
    log = tcp_log(diagram, context)
    errors = []
    for k in range(int(log.segment.max()) + 1):
        rows = np.nonzero(log.segment == k)[0]
        if len(rows):
            last = rows[-1]
            errors.append(float(np.linalg.norm(log.point[last] - log.goal[last, :3])))
    return errors


#: A held object that moved more than this in the hand is a grasp slip [m]: half the 2 cm
#: within which a placed cup must stand on the coaster's centre.
GRASP_SLIP_TOLERANCE = 0.01


def grasp_slip_figures(diagram: Diagram, context: Context) -> dict[str, float]:
    """How far the held object moved in the hand over a run (:class:`GraspSlipMonitor`).

    Returns:
        ``grasp_slip_m`` (the largest distance of the object's origin, in the tcp frame,
        from where it sat when the hold began), ``grasp_slip_time_s`` (when) and
        ``held_offset_m``: how far the object's axis (its origin and the tcp's x axis,
        which is upright in a side grasp) was from the tcp's x axis when the hold began.
    """
    monitor = diagram.GetSubsystemByName("grasp_slip")
    monitor_context = monitor.GetMyContextFromRoot(context)
    slip, when = monitor.GetOutputPort("slip").Eval(monitor_context)
    p_TO = monitor.GetOutputPort("hold_reference").Eval(monitor_context)
    return {
        "grasp_slip_m": float(slip),
        "grasp_slip_time_s": float(when),
        "held_offset_m": float(np.hypot(p_TO[1], p_TO[2])),
    }


def grasp_slip_text(slip_m: float, time_s: float, what: str) -> str:
    """The report of a grasp slip, e.g. ``"grasp slip: the cup moved 31.1 mm in the hand ..."``.

    Args:
        slip_m: the largest distance the object moved in the hand [m].
        time_s: when [s].
        what: the held object's name.
    """
    return (
        f"grasp slip: the {what} moved {slip_m * 1000:.1f} mm in the hand (largest at "
        f"t = {time_s:.2f} s; tolerance {GRASP_SLIP_TOLERANCE * 1000:g} mm)"
    )


def pick_and_place_figures(diagram: Diagram, context: Context) -> dict[str, float]:
    """Figures of a pick-and-place run (also the registry's check).

    Returns:
        ``cup_to_coaster_m`` (horizontal), ``cup_height_above_coaster_m`` (cup bottom
        above the coaster top), ``cup_tilt_rad``, ``min_obstacle_clearance_m`` (tcp
        to the ball's surface), ``grasp_reach_error_m``, ``place_reach_error_m``,
        ``success`` (1 if the cup stands on the coaster within 2 cm of its centre),
        ``min_ball_gap_m`` (smallest signed distance between the ball and any collision
        geometry of the arm, the hand, the fingers or the cup over the run, from
        SceneGraph every 4 ms; negative = they touched), ``min_ball_gap_time_s``
        (when), ``collision_free`` (1 if ``min_ball_gap_m > 0``), the cup's
        :func:`grasp_slip_figures` while it is carried and ``grasp_slipped`` (1 if it
        moved more than :data:`GRASP_SLIP_TOLERANCE` in the hand), ``start_delay_s``
        (how long after its due time the release began: it waits, at most
        ``MAX_SEGMENT_WAIT``, for the placed cup to settle) and the
        :func:`placement_figures` at the release.
    """
    plant = diagram.GetSubsystemByName("plant")
    pc = plant.GetMyContextFromRoot(context)
    X_cup = plant.GetBodyByName("cup", plant.GetModelInstanceByName("cup_red")).EvalPoseInWorld(pc)
    X_coaster = plant.GetBodyByName(
        "coaster", plant.GetModelInstanceByName("coaster")
    ).EvalPoseInWorld(pc)
    d_xy = float(np.linalg.norm(X_cup.translation()[:2] - X_coaster.translation()[:2]))
    height = float(X_cup.translation()[2] - (X_coaster.translation()[2] + COASTER_TOP))
    tilt = float(np.arccos(np.clip(X_cup.rotation().matrix()[2, 2], -1, 1)))
    obstacle = plant.GetBodyByName(
        "obstacle", plant.GetModelInstanceByName("obstacle_blue")
    ).EvalPoseInWorld(pc)
    tcp = tcp_log(diagram, context).point
    clearance = float(
        np.min(np.linalg.norm(tcp - obstacle.translation(), axis=1)) - OBSTACLE_RADIUS
    )
    monitor = diagram.GetSubsystemByName("obstacle_clearance")
    gap, gap_time = monitor.get_output_port().Eval(monitor.GetMyContextFromRoot(context))
    errors = segment_reach_errors(diagram, context) + [np.nan] * 3
    success = d_xy < 0.02 and abs(height) < 0.01 and tilt < 0.2
    slip = grasp_slip_figures(diagram, context)
    chain = diagram.GetSubsystemByName("dmp_chain")
    delay = chain.GetOutputPort("start_delay").Eval(chain.GetMyContextFromRoot(context))[0]
    return {
        "cup_to_coaster_m": d_xy,
        "cup_height_above_coaster_m": height,
        "cup_tilt_rad": tilt,
        "min_obstacle_clearance_m": clearance,
        "grasp_reach_error_m": errors[0],
        "place_reach_error_m": errors[1],
        "success": float(success),
        "min_ball_gap_m": float(gap),
        "min_ball_gap_time_s": float(gap_time),
        "collision_free": float(gap > 0.0),
        **slip,
        "grasp_slipped": float(slip["grasp_slip_m"] > GRASP_SLIP_TOLERANCE),
        "start_delay_s": float(delay),
        **placement_figures(diagram, context),
    }


def placement_figures(diagram: Diagram, context: Context) -> dict[str, float]:
    """Where the placed object stood when the release began (:class:`PlacementMonitor`).

    Returns:
        ``release_object_error_m`` (the object's horizontal distance from its target),
        ``release_object_speed_mps`` (its horizontal speed relative to the target) and
        ``release_settled`` (1 if it was within both of the monitor's tolerances: the
        release found it settled; 0 if the release began because the wait ran out), NaN
        when the release never began.
    """
    monitor = diagram.GetSubsystemByName("placement")
    at = monitor.GetOutputPort("at_release").Eval(monitor.GetMyContextFromRoot(context))
    return {
        "release_object_error_m": float(at[0]),
        "release_object_speed_mps": float(at[1]),
        "release_settled": float(at[2]),
    }


def placement_text(error_m: float, speed_mps: float, wait_s: float, what: str) -> str:
    """The report of a release that began before the placed object settled.

    Args:
        error_m: the object's horizontal distance from its target at the release [m].
        speed_mps: its horizontal speed relative to the target then [m/s].
        wait_s: how long the release had waited [s].
        what: the placed object's name.
    """
    from repertoire.diagrams.arm_dmp_scenarios import PLACE_REST_SPEED, PLACE_TOLERANCE

    return (
        f"not settled: the release began after waiting {wait_s:.2f} s with the {what} "
        f"{error_m * 1000:.2f} mm from its target, moving {speed_mps * 1000:.1f} mm/s "
        f"(settled: within {PLACE_TOLERANCE * 1000:g} mm and {PLACE_REST_SPEED * 1000:g} mm/s)"
    )


#: The tip must come within this horizontal distance of a cup's axis (inside the rim).
POUR_RADIUS = 0.03
#: Tilt of the bottle above which it counts as pouring [rad].
POUR_MIN_TILT = np.pi / 3


def serving_figures(diagram: Diagram, context: Context) -> dict[str, float]:
    """Figures of a serving run (also the registry's check).

    Returns:
        ``tip_to_cup_k_m`` (k = 1..3): closest horizontal distance of the bottle tip to
        cup k while the bottle is tilted past 60 degrees during that cup's pour;
        ``cups_served`` (how many within 3 cm), ``max_cup_displacement_m`` (how far
        the bottle or the hand pushed a cup), ``bottle_in_hand_m`` (bottle grasp
        point to tcp at the end), ``grasp_reach_error_m``, ``pour_reach_error_m``
        (largest over the pours), ``success`` (1 if all three cups were served and
        none was pushed by more than 1 cm) and the bottle's :func:`grasp_slip_figures`
        from the grasp to the end.
    """
    plant = diagram.GetSubsystemByName("plant")
    pc = plant.GetMyContextFromRoot(context)
    tip = point_log(diagram, context, "tip_log")  # the bottle tip and the bottle's z axis
    tcp = tcp_log(diagram, context)
    n = min(len(tip.t), len(tcp.t))
    tip_xy, segments = tip.point[:n, :2], tcp.segment[:n]
    tilt = np.arccos(np.clip(tip.axis[:n, 2], -1.0, 1.0))
    figures = {}
    served = 0
    knocked = 0.0
    for k in range(3):
        cup = plant.GetBodyByName("cup", plant.GetModelInstanceByName(f"cup_{k + 1}"))
        p_cup = plant.GetDefaultFloatingBaseBodyPose(cup).translation()
        knocked = max(knocked, float(np.linalg.norm(cup.EvalPoseInWorld(pc).translation() - p_cup)))
        rows = ((segments == 1 + 2 * k) | (segments == 2 + 2 * k)) & (tilt > POUR_MIN_TILT)
        d = np.linalg.norm(tip_xy[rows] - p_cup[:2], axis=1) if rows.any() else [np.inf]
        figures[f"tip_to_cup_{k + 1}_m"] = float(np.min(d))
        served += int(np.min(d) < POUR_RADIUS)
    bottle = plant.GetBodyByName("bottle", plant.GetModelInstanceByName("bottle"))
    X_B = bottle.EvalPoseInWorld(pc)
    grasp_point = X_B @ np.array([0, 0, BOTTLE_GRASP_HEIGHT])
    errors = segment_reach_errors(diagram, context)
    figures.update(
        cups_served=float(served),
        max_cup_displacement_m=knocked,
        bottle_in_hand_m=float(np.linalg.norm(grasp_point - tcp.point[n - 1])),
        grasp_reach_error_m=errors[0],
        pour_reach_error_m=float(max(errors[1::2][:3])) if len(errors) > 1 else np.nan,
        success=float(served == 3 and knocked < 0.01),
        **grasp_slip_figures(diagram, context),
    )
    return figures
