"""DribbleBall: push the ball in front of a differential-drive robot to a target pose.

Stulp & Beetz (section 3, Table 6) parameterise ``dribbleBall`` by the current
state ``[x, y, phi, v]``, the ball ``[x_ball, y_ball]`` and the goal
``[x_g, y_g, phi_g, v_g]``. The robot has no gripper: it keeps the ball in
front of its flat bumper by steering towards it. The command is the GoToPose
pose controller (:func:`~repertoire.systems.go_to_pose.pose_control`) with
slower dribbling limits applied to the held spot (``hold_distance`` ahead of
the axle, where the ball sits) and the goal's held spot, plus a ball-centering
term that lets the pose command act only while the ball is in front. With ``(b_x, b_y)`` the
ball in the robot frame, ``gamma = atan2(b_y, b_x)`` its bearing and
``a = max(0, cos(gamma))^2``:

    v     = max(0, v_pose) * a        (never backing away from the ball)
    omega = a * omega_pose + k_ball * gamma

while that ``v`` is positive; at rest (``v = 0``: turning in place, or the goal behind)
the robot turns by ``a * omega_pose`` alone while the ball is *controlled* (within
``control_distance`` of its held spot, between the guide arms) and otherwise closes on
the ball first (:func:`close_control`), both clipped to the limits, the yaw rate also to
``max(omega_in_place, |v| / min_turn_radius)`` (turning on the spot throws the
ball off), and rate limited like GoToPose. The ball is *lost*
(status FAILED) when it is farther than ``lost_distance`` from its held spot
``(hold_distance, 0)`` in the robot frame, or when its centre lies farther to the
side than ``lost_lateral`` (``|b_y|``; the default 0.155 m is the outer face of the
``soccer_dribble`` world's guide arms: a ball beside an arm's tip is out of the
dribbler); the action succeeds when the held spot is within ``position_tolerance``
of the goal's held spot and the heading within ``heading_tolerance`` of ``phi_g``,
with the ball still held.

Without the lateral test a ball that had slid out past a guide arm's tip could rest
against the arm's outer corner within ``lost_distance`` of its held spot, at (0.43,
+-0.22) m in the robot frame, while the robot turned in place towards a goal behind it:
the ball-centering term then cancelled the pose law's turn, the command was (0, 0), and
the action stood still until its timeout. On the dribble study's sampling, seeds
7000-7239 and 8000-8239, the largest ``|b_y|`` of any succeeded episode was 0.09 m;
every lost ball and every such standstill had passed 0.155 m (4 + 1 of the 6 timeouts;
the other one turned in place within the position tolerance too slowly). Seeds 0-999:
succeeded / lost / timed out 786 / 199 / 15 -> 786 / 208 / 6, every succeeded episode
unchanged; the 9 standstills are lost after 1.5-3.8 s instead of timing out at 15 s.

Rest states (session 35). A law whose forward speed is 0 (turning in place, or the goal
behind) moves the ball only through the guide arms, so ``v = 0, omega = 0`` must mean
arrival. With ``omega = a * omega_pose + k_ball * gamma`` at rest it did not: wherever the
pose law's turn and the ball-centering term cancel, the robot stood still with the ball off
its bumper. The dribble study's seeds 92, 536 and 608 stood so in PIVOT until the timeout
(the axle on the goal's, the heading 0.23-0.27 rad off, the ball flung onto a guide arm's
front end by the in-place turn, at (0.447, +-0.12-0.14) m: 536's terms -0.600 and +0.600
rad/s). At rest the law now closes on a ball off the bumper first (whose only rest is the
ball on the held spot) and turns with a controlled ball by the pose term alone (whose only
rest is ``omega_pose = 0``: the heading reached with the steered point within the
tolerance, which is arrival; ``gamma`` is then bounded by ``control_distance``, and the
arms carry the ball).

The pivot's creep (session 36). The 30 timeouts of the dribble study's seeds 0-999 that
session 35 left were pivots: the axle law stopped on the edge of its position tolerance
(0.095-0.099 m from the goal's axle, 2.2-2.6 rad off ``phi_g`` after its arc), the
in-place turn drifted the ball off the bumper (about 3 cm per rad), and closing on it
crept the axle forward: a centimetre put it outside the tolerance, where the axle law
turned to face the goal's axle position, now behind the robot and 2.2 rad from the
heading, and the heading error grew back to 2.5 rad (seed 112: ended at 24.0 s). Now
:data:`PIVOT` only reaches (:func:`~repertoire.systems.go_to_pose.run_up_control`
without reversing: turn to face the goal's axle position, drive to it, so no arc adds to
the turn) until the in-place turn towards ``phi_g`` arrives with ``control_distance`` to
spare (:func:`turn_miss`, :func:`pivot_turns`), and :data:`PIVOT_TURN` turns while the
turn arrives at all. Its rest (``phi = phi_g``) has the axle within ``position_tolerance``
of the goal's, so it is an arrival.

The spot law's cycle (session 37). Within ``position_tolerance`` of the goal's held spot
the spot law turned in place about the axle, which moves the held spot on a circle of
radius ``hold_distance``. Where no heading of that turn within ``heading_tolerance``
has the spot inside the tolerance (:func:`turn_miss` at least ``position_tolerance``),
the turn swung the spot out, and outside the polar law turned to face the goal's spot,
undoing the turn, and drove back in to the tolerance's edge: the dribble study's seeds
526 and 727 (the spot stopped 0.098 m from the goal's, the heading 0.80 rad off
``phi_g``; the turn's nearest spot 0.135 m away) cycled so until the timeout, and others
for 2-4 s (98: 3.7 s). The swing rule below missed them: it measures the swing from the
goal's spot itself, but the law stops anywhere within the tolerance, mostly on its
edge. The spot law now steers the held spot to ``position_tolerance - control_distance``
(driving on along the heading brings the turn's nearest spot closer: for 526 from 0.135
to 0.077 m at 0.1 m deeper), and the in-place turn is taken only as :data:`PIVOT_TURN`,
where it arrives, and held while it does; one that stops arriving with the spot near
goes back to the spot law, not to the pivot, whose reach turns away to face the goal's
axle (unseen seed 5129 began the turn with its miss 2 mm inside the tolerance, lost it,
and timed out in the pivot). Handing every such turn straight to the pivot instead
(tried first) fixed 526 and 727 but made 104 of 1000 dribbles 3.4 s slower.

Final approach. The paper's dribble goal has a heading (Algorithm 2's example
instantiates ``dribbleBall(..., xg=1, yg=3, phi=2.6, vg=0)``), so arriving at the
spot is not enough. Near the goal with a large heading error the spot law
alone limit-cycles: turning in place swings the held spot (``hold_distance``
ahead of the axle) out of the position tolerance, and driving it back undoes
the turn. The action therefore keeps a mode in its discrete state
(:func:`approach_mode`): when the held spot is near the goal's and turning in
place by the heading error would swing it out of the tolerance, it *pivots*:
the same pose law steers the axle (not the held spot) to the goal's axle
position and then turns in place about it, which brings the held spot onto
the goal's with the heading. (A loop-out to a staging pose behind the goal was
tried first: at ``min_turn_radius`` it orbited the staging pose and timed out
more often than the plain spot law.)

Target speeds. A goal speed ``v_g`` that a stopped robot does not meet
(:func:`needs_loop`: ``v_g >= speed_tolerance(v_g)``, 0.1 m/s) cannot be met by
stopping on the goal, and a dribbling robot cannot back away from the ball for a
run-up as GoToPose does. When the held spot reaches the goal's too slowly, or a
pivot would be needed, the action *loops*: :func:`loop_control` drives a circle of
radius ``LOOP_RADIUS_FACTOR * min_turn_radius`` through the goal position, tangent
to ``phi_g``, on a side :func:`approach_mode` picks, and comes back through the
goal aligned and at speed. Unlike the loop-out to a staging pose above, the law
follows a path, not a point: its guidance heading converges onto the circle and its
speed never drops below ``v_g``, so there is no point to orbit. On 30 episodes of the
dribble study's sampling (seeds 0-29) with ``v_g`` in [0.2, 0.4]: succeeded / ball
lost / timed out 16 / 6 / 8 before, 23 / 5 / 2 with the loop (seeds 30-59: 20 / 7 / 3
and 23 / 7 / 0); goals below 0.1 m/s run exactly as before.

The loop's side (:func:`approach_mode`). Always looping to the side the heading error
turns to, a robot that had reached the goal with a large heading error (0.8-1.3 rad in
the study's full loops) first turned away from its circle, drove ``2 pi + |e|`` of
turning and swung wide of the circle: seed 28 carried the ball into a goal post and
pushed it there until the timeout. The other side takes ``2 pi - |e|``. Same run,
``v_g`` in [0.2, 0.4], succeeded / lost / timed out and mean duration of all
episodes: seeds 0-59 46 / 12 / 2 -> 47 / 12 / 1 (5.65 -> 5.62 s); seeds 100-199
74 / 20 / 6 -> 77 / 20 / 3 (5.88 -> 5.82 s); seeds 200-399 142 / 46 / 12 ->
145 / 46 / 9 (5.89 -> 5.86 s); 13 of the 360 episodes changed, each ended sooner.
A full loop still takes 8-10 s at the dribbling speed, so a loop begun late still
times out
(seed 11: the short loop's circle crosses the goal line where a post stands, and the
long one, taken before, ended at 15.29 s).
"""

import math

import numpy as np
from pydrake.systems.framework import Context
from repertoire.systems.action_status import (
    ActionStatus,
    check_period,
    clip,
    merge_gains,
)
from repertoire.systems.go_to_pose import (
    DriveAction,
    drive_step,
    pose_control,
    run_up_control,
    speed_tolerance,
)
from repertoire.systems.goto_law import turn_in_place

from repertoire.errors import RepertoireError

# name -> default, in the order of the numeric parameter vector.
DRIBBLE_GAINS = {
    "v_max": 0.4,  # m/s
    "omega_max": 1.2,  # rad/s
    "a_max": 0.6,  # m/s^2
    "alpha_max": 3.0,  # rad/s^2
    "k_rho": 0.8,
    "k_alpha": 2.0,
    "k_beta": -0.5,
    "k_ball": 2.0,  # yaw rate per rad of ball bearing
    "omega_in_place": 0.5,  # yaw rate limit at standstill [rad/s]
    "min_turn_radius": 0.4,  # yaw rate limit v / radius when faster [m]
    "hold_distance": 0.31,  # ball centre ahead of the axle when held [m]
    "lost_distance": 0.25,  # ball farther than this from its held spot is lost [m]
    "lost_lateral": 0.155,  # ball centre farther to the side is lost (guide arms' faces) [m]
    "position_tolerance": 0.1,  # m
    "heading_tolerance": 0.5,  # rad
    "timeout": 15.0,  # s, from the action's start (DriveAction)
    "collect_distance": 0.5,  # collect mode: axle behind the ball / circling radius [m]
    "collect_angle": 1.0,  # collect mode: target off the heading to drive onto the ball [rad]
    "control_distance": 0.05,  # collect mode: ball this near its held spot is controlled [m]
}


def ball_in_robot_frame(state, ball) -> tuple[float, float]:
    """``(b_x, b_y)``: the ball in the frame of the robot ``[x, y, phi, ...]``."""
    dx, dy = ball[0] - state[0], ball[1] - state[1]
    c, s = math.cos(state[2]), math.sin(state[2])
    return c * dx + s * dy, -s * dx + c * dy


def ball_terms(state, ball, gains: dict[str, float]) -> tuple[bool, float, float]:
    """``(held, gamma, align)``: the ball held, its bearing and ``max(0, cos gamma)^2``.

    Held: within ``lost_distance`` of the held spot and at most ``lost_lateral`` to the
    side.
    """
    bx, by = ball_in_robot_frame(state, ball)
    held = (
        math.hypot(bx - gains["hold_distance"], by) <= gains["lost_distance"]
        and abs(by) <= gains["lost_lateral"]
    )
    gamma = math.atan2(by, bx)
    return held, gamma, max(0.0, math.cos(gamma)) ** 2


def clip_turn(v: float, w: float, gains: dict[str, float]) -> float:
    """``w`` within ``min(omega_max, max(omega_in_place, |v| / min_turn_radius))``."""
    w_max = min(gains["omega_max"], max(gains["omega_in_place"], abs(v) / gains["min_turn_radius"]))
    return clip(w, -w_max, w_max)


def dribble_control(
    state,
    ball,
    target,
    gains: dict[str, float],
    lead: float | None = None,
    turn: bool = False,
) -> tuple[float, float, bool]:
    """Unlimited-rate ``(v, omega)`` commands and whether the ball is held.

    Args:
        state: ``[x, y, phi, v]`` of the robot.
        ball: ``[x_ball, y_ball]``.
        target: ``[x_g, y_g, phi_g, v_g]``.
        gains: the :data:`DRIBBLE_GAINS` keys.
        lead: the steered point's distance ahead of the axle (default
            ``hold_distance``, the held spot; 0 steers the axle, :data:`PIVOT`), to
            within ``position_tolerance - control_distance`` of the goal's (the held
            spot of a target that needs a loop: to ``position_tolerance``).
        turn: turn in place towards ``phi_g`` instead (:data:`PIVOT_TURN`): ``v = 0``,
            ``omega = clip(k_alpha wrap(phi_g - phi), -1, 1) omega_max``, the pose
            law's in-place turn.

    Returns:
        ``(v_cmd, omega_cmd, held)``, commands clipped to ``v_max``/``omega_max``.
    """
    held, gamma, align = ball_terms(state, ball, gains)
    # steer the point lead ahead (the held spot) to the goal's
    h = gains["hold_distance"] if lead is None else lead
    c, s = math.cos(state[2]), math.sin(state[2])
    spot = [state[0] + h * c, state[1] + h * s, state[2], state[3]]
    spot_goal = [
        target[0] + h * math.cos(target[2]),
        target[1] + h * math.sin(target[2]),
        target[2],
        target[3],
    ]
    # deep enough to turn in (approach_mode): one close's creep inside the tolerance
    inner = gains | {"position_tolerance": gains["position_tolerance"] - gains["control_distance"]}
    if turn:
        e = math.remainder(target[2] - state[2], 2.0 * math.pi)
        v, w = 0.0, turn_in_place(e, gains["k_alpha"], gains["omega_max"])
    elif lead == 0.0:  # the pivot's axle: turn, drive
        v, w = run_up_control(state, spot_goal, inner, reverse=False)
    else:  # the held spot (a loop's target: to the tolerance, approach_mode loops there)
        v, w, _, _ = pose_control(spot, spot_goal, gains if needs_loop(target) else inner)
    v = max(0.0, v) * align  # never back away from the ball
    if v > 0.0:
        w = w * align + gains["k_ball"] * gamma
    elif ball_controlled(state, ball, gains):
        w = w * align  # at rest: the arms carry the ball; centring it would cancel the turn
    else:
        v, w = close_control(state, ball, gains)  # at rest: the ball first, the pose after
    v = clip(v, -gains["v_max"], gains["v_max"])
    return v, clip_turn(v, w, gains), held


def turn_miss(state, target, gains: dict[str, float]) -> float:
    """How near the held spot comes to the goal's on an in-place turn towards ``phi_g`` [m].

    Counted over the headings of the turn within ``heading_tolerance`` of ``phi_g``
    (heading errors from ``clip(e, -heading_tolerance, heading_tolerance)`` to 0, ``e``
    the current one), where the action can arrive. Turning in place moves the held spot
    on the circle of radius ``h = hold_distance`` about the axle ``p``; with ``q`` the
    goal's held spot, its distance from ``q`` grows with the heading's distance from
    ``phi* = atan2(q - p)``, so the nearest is at ``phi*``'s heading error clipped into
    that range. At ``e = 0`` it is the axle's distance from the goal's. Depends on the
    axle's position and on the heading only through that range.
    """
    h, tol = gains["hold_distance"], gains["heading_tolerance"]
    phi_g = target[2]
    qx = target[0] + h * math.cos(phi_g) - state[0]
    qy = target[1] + h * math.sin(phi_g) - state[1]
    e = math.remainder(phi_g - state[2], 2.0 * math.pi)
    lo, hi = sorted((0.0, clip(e, -tol, tol)))
    e_star = math.remainder(phi_g - math.atan2(qy, qx), 2.0 * math.pi)
    candidates = (lo, hi, e_star) if lo <= e_star <= hi else (lo, hi)
    return min(
        math.hypot(h * math.cos(phi_g - c) - qx, h * math.sin(phi_g - c) - qy) for c in candidates
    )


def pivot_turns(state, target, gains: dict[str, float], margin: float) -> bool:
    """Whether the in-place turn towards ``phi_g`` arrives with ``margin`` [m] to spare.

    :func:`turn_miss` below ``position_tolerance - margin``.
    """
    return turn_miss(state, target, gains) < gains["position_tolerance"] - margin


def mode_control(mode: int, state, ball, target, gains: dict[str, float]):
    """Unlimited-rate ``(v, omega, held)`` of the final-approach ``mode`` (:func:`approach_mode`).

    A loop's :func:`loop_control`; else :func:`dribble_control`: the held spot steered
    (:data:`APPROACH`), the axle (:data:`PIVOT`), or an in-place turn towards ``phi_g``
    (:data:`PIVOT_TURN`).
    """
    if mode in (LOOP_LEFT, LOOP_RIGHT):
        return loop_control(state, ball, target, gains, 1.0 if mode == LOOP_LEFT else -1.0)
    if mode == PIVOT_TURN:
        return dribble_control(state, ball, target, gains, turn=True)
    return dribble_control(state, ball, target, gains, 0.0 if mode == PIVOT else None)


LOOP_RADIUS_FACTOR = 1.25
"""A loop's radius in ``min_turn_radius`` (headroom for the ball-centering term)."""


def loop_geometry(
    state, target, gains: dict[str, float], side: float
) -> tuple[float, float, float, float]:
    """``(R, psi, d, theta)`` of the robot on the loop of ``side`` (see :func:`loop_control`).

    ``R`` the loop's radius, ``psi`` the robot's bearing from the loop's centre, ``d`` its
    distance from it and ``theta`` in ``[0, 2 pi)`` the angle still to go along the loop
    to the target.
    """
    radius = LOOP_RADIUS_FACTOR * gains["min_turn_radius"]
    cx = target[0] - side * radius * math.sin(target[2])
    cy = target[1] + side * radius * math.cos(target[2])
    psi = math.atan2(state[1] - cy, state[0] - cx)
    d = math.hypot(state[0] - cx, state[1] - cy)
    psi_goal = target[2] - side * 0.5 * math.pi
    return radius, psi, d, (side * (psi_goal - psi)) % (2.0 * math.pi)


def circle_heading(psi: float, d: float, radius: float, side: float) -> float:
    """Heading [rad] that follows a circle of ``radius`` about a centre, ``side`` +1 / -1.

    ``psi`` is the bearing from the centre to the robot and ``d`` its distance: the
    tangent ``psi + side pi/2``, turned inwards outside the circle and outwards inside it
    by ``atan((d - radius) / radius)``.
    """
    return psi + side * (0.5 * math.pi + math.atan((d - radius) / radius))


def loop_control(
    state, ball, target, gains: dict[str, float], side: float
) -> tuple[float, float, bool]:
    """Unlimited-rate ``(v, omega)`` and ``held`` on a loop through the target.

    The loop is the circle of radius ``R = LOOP_RADIUS_FACTOR * min_turn_radius``
    through the target position, tangent to the target heading ``phi_g``, with its
    centre on the left (``side = 1``, driven anticlockwise) or right (``side = -1``,
    clockwise): ``c = p_g + side * R * (-sin phi_g, cos phi_g)``. With ``psi`` the
    robot's bearing from ``c`` and ``d`` its distance, the heading to hold is
    ``chi = psi + side * (pi/2 + atan((d - R) / R))`` (the tangent, turned inwards
    outside the circle and outwards inside it), and

        omega_loop = side * v / R + k_alpha * wrap(chi - phi)
        v          = min(v_max, max(v_g, k_rho * R * theta))

    with ``theta`` the angle still to go along the circle to the target; the ball
    terms are those of :func:`dribble_control`.
    """
    g = gains
    held, gamma, align = ball_terms(state, ball, g)
    radius, psi, d, theta = loop_geometry(state, target, g, side)
    chi = circle_heading(psi, d, radius, side)
    v = min(g["v_max"], max(target[3], g["k_rho"] * radius * theta)) * align
    w = side * v / radius + g["k_alpha"] * math.remainder(chi - state[2], 2.0 * math.pi)
    w = align * w + g["k_ball"] * gamma
    return v, clip_turn(v, w, g), held


APPROACH, PIVOT, LOOP_LEFT, LOOP_RIGHT, PIVOT_TURN = 0, 1, 2, 3, 4  # final-approach modes (slot 3)


def needs_loop(target) -> bool:
    """Whether a stopped robot misses the target speed (``v_g >= 0.1``): only a loop meets it.

    A negative ``v_g`` never needs one: the robot never backs away from its ball, so no
    loop could meet it (the approach stops on the goal, as for ``v_g = 0``).
    """
    return target[3] >= speed_tolerance(target[3])


def approach_mode(mode: int, state, target, gains: dict[str, float]) -> int:
    """The next final-approach mode: APPROACH, PIVOT, PIVOT_TURN or a loop.

    Args:
        mode: the current mode.
        state: ``[x, y, phi, v]`` of the robot.
        target: ``[x_g, y_g, phi_g, v_g]``.
        gains: the :data:`DRIBBLE_GAINS` keys.

    APPROACH -> PIVOT when the held spot is within ``2 * position_tolerance``
    of the goal's and turning in place by the heading error beyond
    ``heading_tolerance`` would swing it by more than ``position_tolerance``
    (``2 * hold_distance * sin(turn / 2)``). With the held spot within
    ``position_tolerance`` and the heading beyond ``heading_tolerance`` (not for a target
    that needs a loop): APPROACH -> PIVOT_TURN where that in-place turn arrives
    (:func:`pivot_turns` without a margin); where it does not, APPROACH goes on driving
    the held spot deeper (:func:`dribble_control` steers it to ``position_tolerance -
    control_distance``), which brings the turn's nearest spot closer, and -> PIVOT once
    the spot is that deep and the turn still does not arrive. A PIVOT_TURN that no longer
    arrives -> APPROACH where APPROACH would not pivot (the held spot within ``2 *
    position_tolerance`` and the swing at most ``position_tolerance``: deeper first),
    else -> PIVOT.

    PIVOT (:func:`dribble_control` with ``lead = 0``: turn to face the goal's axle
    position, drive to it, never backing) -> PIVOT_TURN once the in-place turn towards
    ``phi_g`` arrives with ``control_distance`` to spare (:func:`pivot_turns`);
    PIVOT_TURN (that turn) stays while it arrives at all (no margin), else -> PIVOT.
    The margin is for the creep: turning in place drifts the ball off the bumper, and
    each time it leaves ``control_distance`` the robot drives onto it again, moving its
    axle forward. Either pivot -> APPROACH when the held spot is farther than ``2 *
    min_turn_radius`` from the goal's.

    With a target speed a stopped robot does not meet (:func:`needs_loop`), the
    held spot within ``position_tolerance`` of the goal's at a speed off ``v_g`` by
    :func:`~repertoire.systems.go_to_pose.speed_tolerance` or more, or a pivot, starts
    a loop instead (see :func:`loop_control`); a loop goes on until the action ends,
    or until the target speed no longer needs one (a plan executor changed it).

    The loop's side: the one the heading error turns to (:data:`LOOP_LEFT` for
    ``phi_g - phi >= 0``, else :data:`LOOP_RIGHT`) when that turn in place would keep
    the held spot within ``position_tolerance`` (the swing above), or when the robot
    is still short of the target on that loop (less than ``pi`` to go,
    :func:`loop_geometry`): turning towards ``phi_g`` may then end the action at
    once. Otherwise that loop is a full lap plus the heading error ``|e|`` of turning,
    begun pointing away from its circle, and the other side's, ``2 pi - |e|``, which
    the robot already points into, is taken.
    """
    heading_error = math.remainder(target[2] - state[2], 2 * math.pi)
    h = gains["hold_distance"]
    rho = math.hypot(
        target[0] + h * math.cos(target[2]) - state[0] - h * math.cos(state[2]),
        target[1] + h * math.sin(target[2]) - state[1] - h * math.sin(state[2]),
    )
    turn = max(0.0, abs(heading_error) - gains["heading_tolerance"])
    swing = 2.0 * h * math.sin(min(turn, math.pi) / 2.0)
    if needs_loop(target):
        # the loop turning towards phi_g, unless that takes a lap plus the heading error
        turn_left = heading_error >= 0.0
        theta = loop_geometry(state, target, gains, 1.0 if turn_left else -1.0)[3]
        if swing > gains["position_tolerance"] and theta >= math.pi:
            turn_left = not turn_left
        loop = LOOP_LEFT if turn_left else LOOP_RIGHT
        if mode in (LOOP_LEFT, LOOP_RIGHT):
            return mode
        inside = rho < gains["position_tolerance"]
        slow = abs(state[3] - target[3]) >= speed_tolerance(target[3])
        if (inside and slow) or mode in (PIVOT, PIVOT_TURN):
            return loop
    elif mode in (LOOP_LEFT, LOOP_RIGHT):
        return APPROACH
    if mode == APPROACH:
        near = rho < 2.0 * gains["position_tolerance"]
        if near and swing > gains["position_tolerance"]:
            return loop if needs_loop(target) else PIVOT
        if rho < gains["position_tolerance"] and turn > 0.0 and not needs_loop(target):
            # the in-place turn where it arrives, else deeper; at the inner tolerance: pivot
            if pivot_turns(state, target, gains, 0.0):
                return PIVOT_TURN
            if rho < gains["position_tolerance"] - gains["control_distance"]:
                return PIVOT
        return APPROACH
    if rho > 2.0 * gains["min_turn_radius"]:
        return APPROACH
    # the turn once the axle is deep enough (one close's creep to spare), kept while it arrives
    margin = 0.0 if mode == PIVOT_TURN else gains["control_distance"]
    if pivot_turns(state, target, gains, margin):
        return PIVOT_TURN
    keeps_in = rho < 2.0 * gains["position_tolerance"] and swing <= gains["position_tolerance"]
    if mode == PIVOT_TURN and keeps_in and not needs_loop(target):
        return APPROACH  # the held spot near, a turn that keeps it in: deeper first (above)
    return PIVOT


COLLECTING, DRIBBLING, CLOSING = 0, 1, 2  # collect mode's phases (state slot 4)
NO_REASON, BALL_LOST, BAD_INPUT = 0, 1, 2  # why the action failed (state slot 5, collect mode)
FAILURE_REASONS = {NO_REASON: "", BALL_LOST: "ball lost", BAD_INPUT: "bad target or ball"}
CLEAR_FRACTION = 0.9
"""A straight drive to the collect point is clear while it passes the ball at this
fraction of ``collect_distance`` or more (see :func:`collect_control`)."""


def behind_point(ball, target, distance: float) -> list[float]:
    """``[x, y, phi]``: ``distance`` behind the ball on the ball -> target line, facing the target.

    ``phi = atan2(y_g - y_ball, x_g - x_ball)`` and the point is
    ``ball - distance * (cos phi, sin phi)``.
    """
    phi = math.atan2(target[1] - ball[1], target[0] - ball[0])
    return [ball[0] - distance * math.cos(phi), ball[1] - distance * math.sin(phi), phi]


def segment_distance(p, a, b) -> float:
    """The distance of point ``p`` from the segment ``a``-``b`` (all ``[x, y]``)."""
    ax, ay = b[0] - a[0], b[1] - a[1]
    n2 = ax * ax + ay * ay
    t = 0.0 if n2 == 0.0 else clip(((p[0] - a[0]) * ax + (p[1] - a[1]) * ay) / n2, 0.0, 1.0)
    return math.hypot(p[0] - a[0] - t * ax, p[1] - a[1] - t * ay)


def target_aligned(state, ball, target, gains: dict[str, float]) -> bool:
    """Whether the ball -> target direction is within ``collect_angle`` of the heading."""
    phi_d = math.atan2(target[1] - ball[1], target[0] - ball[0])
    return abs(math.remainder(phi_d - state[2], 2.0 * math.pi)) <= gains["collect_angle"]


def close_control(state, ball, gains: dict[str, float]) -> tuple[float, float]:
    """Unlimited-rate ``(v, omega)`` that drive straight onto a ball ahead, up to the bumper.

    With ``(b_x, b_y)`` the ball in the robot frame, ``gamma`` its bearing and
    ``d = max(0, b_x - hold_distance)`` the way left until it lies on the held spot:

        v     = min(v_max, sqrt(2 a_max d)) * max(0, cos gamma)^2
        omega = k_ball * gamma

    (the speed from which ``a_max`` stops the robot with the ball at the bumper; the
    yaw rate only centres the ball, as in :func:`dribble_control`, never turning towards
    the target while the ball is not against the bumper). Both clipped to ``v_max`` and
    ``omega_max``.
    """
    g = gains
    bx, by = ball_in_robot_frame(state, ball)
    gamma = math.atan2(by, bx)
    d = max(0.0, bx - g["hold_distance"])
    v = min(g["v_max"], math.sqrt(2.0 * g["a_max"] * d)) * max(0.0, math.cos(gamma)) ** 2
    return v, clip(g["k_ball"] * gamma, -g["omega_max"], g["omega_max"])


def collect_control(state, ball, target, gains: dict[str, float]) -> tuple[float, float, bool]:
    """Unlimited-rate ``(v, omega)`` towards the collect point, and whether the drive is direct.

    The collect point is :func:`behind_point` at ``c = collect_distance`` (a pose facing
    the target). While the straight segment from the axle to it passes the ball at
    ``CLEAR_FRACTION * c`` or more, the command is GoToPose's
    :func:`~repertoire.systems.go_to_pose.pose_control` to that pose at rest (direct);
    once lined up behind the ball (axle at least ``hold_distance`` behind it along the
    ball -> target line, within ``position_tolerance`` of the line and the heading within
    ``heading_tolerance`` of ``phi_c``) the same law to the held pose, ``hold_distance``
    behind the ball, which drives the ball onto the held spot (also direct).
    Otherwise the robot circles the ball at radius ``c`` the shorter way round: with
    ``psi`` its bearing from the ball, ``d`` its distance and ``theta = wrap(psi - phi_c -
    pi)`` its angle round the ball from the collect point (``phi_c`` its heading), the side
    is ``s = -1`` for ``theta >= 0`` (clockwise) and ``+1`` otherwise, and as in
    :func:`loop_control`

        chi   = psi + s * (pi/2 + atan((d - c) / c))
        v     = v_max * max(0, cos(chi - phi))
        omega = k_alpha * wrap(chi - phi)

    (``chi`` points at the ball from far away, along the circle on it and outwards
    inside it). Both clipped to ``v_max`` and ``omega_max``.
    """
    g = gains
    c = g["collect_distance"]
    px, py, phi_c = behind_point(ball, target, c)
    cos_c, sin_c = math.cos(phi_c), math.sin(phi_c)
    along = (state[0] - ball[0]) * cos_c + (state[1] - ball[1]) * sin_c
    lateral = -(state[0] - ball[0]) * sin_c + (state[1] - ball[1]) * cos_c
    heading_error = math.remainder(phi_c - state[2], 2.0 * math.pi)
    lined_up = (
        along <= -g["hold_distance"]
        and abs(lateral) < g["position_tolerance"]
        and abs(heading_error) < g["heading_tolerance"]
    )
    if lined_up:
        # behind the ball facing the target: drive the ball onto the held spot
        v, w, _, _ = pose_control(state, [*behind_point(ball, target, g["hold_distance"]), 0.0], g)
        direct = True
    elif segment_distance(ball, state, (px, py)) >= CLEAR_FRACTION * c:
        v, w, _, _ = pose_control(state, [px, py, phi_c, 0.0], g)
        direct = True
    else:
        psi = math.atan2(state[1] - ball[1], state[0] - ball[0])
        d = math.hypot(state[0] - ball[0], state[1] - ball[1])
        side = -1.0 if math.remainder(psi - phi_c - math.pi, 2.0 * math.pi) >= 0.0 else 1.0
        chi = circle_heading(psi, d, c, side)
        err = math.remainder(chi - state[2], 2.0 * math.pi)
        v, w = g["v_max"] * max(0.0, math.cos(err)), g["k_alpha"] * err
        direct = False
    return clip(v, -g["v_max"], g["v_max"]), clip(w, -g["omega_max"], g["omega_max"]), direct


def collect_phase(phase: int, held: bool, state, ball, target, gains: dict[str, float]) -> int:
    """The next collect-mode phase: :data:`COLLECTING`, :data:`CLOSING` or :data:`DRIBBLING`.

    -> DRIBBLING (for good) when the ball is held (:func:`ball_terms`) and *controlled*:
    within ``control_distance`` of its held spot, against the bumper between the guide
    arms (the default 0.05 m: the ``soccer_dribble`` arms' tips are 0.0275 m ahead of the
    held spot), where the robot can turn with it as the plain dribble does. Otherwise
    COLLECTING -> CLOSING when the ball is held and the direction from the ball to the
    target is within ``collect_angle`` of the heading (:func:`target_aligned`); CLOSING
    stays while the ball is held (whatever the alignment: closing turns only to centre the
    ball, :func:`close_control`) and falls back to COLLECTING when it is not.

    A ball held but not controlled is not yet in the dribbler: lying 0.5 m ahead of the
    axle (where the soccer plan's approach stops, ``collect_distance``) it is 0.19 m
    beyond the held spot and 0.05 m beyond the arms' tips, and a turn of ``phi`` moves it
    ``0.5 sin(phi)`` to the side (past ``lost_lateral``, 0.155 m, at 0.31 rad) without
    touching it. Session 34 started the dribble at once on a held ball with the target
    within ``collect_angle``: its first turn swept the ball out, which is how each of the
    35 greedy and 32 refined plans of 1000 that failed in Table 3 failed.
    """
    if phase == DRIBBLING:
        return DRIBBLING
    if held and ball_controlled(state, ball, gains):
        return DRIBBLING
    if held and (phase == CLOSING or target_aligned(state, ball, target, gains)):
        return CLOSING
    return COLLECTING


def ball_controlled(state, ball, gains: dict[str, float]) -> bool:
    """Whether the ball lies within ``control_distance`` of its held spot."""
    bx, by = ball_in_robot_frame(state, ball)
    return math.hypot(bx - gains["hold_distance"], by) <= gains["control_distance"]


class DribbleBall(DriveAction):
    """Dribbles the ball in front of a differential-drive robot to a target pose.

    Input ports:
        state: ``[x, y, phi, v]`` of the robot.
        ball: ``[x_ball, y_ball]``.
        target: ``[x_g, y_g, phi_g, v_g]``.
        active: optional ``[1]`` (default) or ``[0]``: while 0 the action tracks its
            command but stays RUNNING (a plan's action that has not started yet).

    Output ports:
        command: ``[v, omega]`` rate-limited forward speed and yaw rate.
        status: an :class:`~repertoire.systems.go_to_pose.ActionStatus` (abstract):
            FAILED when the ball is lost or the target is off the workspace.

    Parameters: numeric parameter 0 holds :data:`DRIBBLE_GAINS` (in order),
    numeric parameter 1 the workspace ``[x_min, x_max, y_min, y_max]``.

    Discrete state: ``[v_cmd, omega_cmd, status, mode]`` (then collect mode's slots,
    then the timeout's start, :class:`~repertoire.systems.go_to_pose.DriveAction`),
    updated every ``period`` s; ``mode`` is :data:`APPROACH`, :data:`PIVOT`, :data:`LOOP_LEFT` or
    :data:`LOOP_RIGHT` (see :func:`approach_mode`).

    Collect mode (``collect=True``; off by default, which is the behaviour above):
    the action starts with a ball that need not be held. While :func:`collect_phase`
    says :data:`COLLECTING`, the command is :func:`collect_control`'s, to
    :func:`behind_point` facing the target round the ball; while it says :data:`CLOSING`
    (a held ball with the target ahead, not yet against the bumper),
    :func:`close_control`'s, straight onto the ball; both rate limited and timed out
    like the dribble (it never succeeds while collecting); from :data:`DRIBBLING` on
    (for good) the action dribbles as above, and a ball no longer held is FAILED with
    reason :data:`BALL_LOST`. The discrete state gains ``[phase, reason]`` (slots 4
    and 5); :meth:`failure_reason` reads the reason. While not ``active`` (a plan's dribble
    waiting for the approach) it tracks the command of the phase it would start in and
    keeps none (it used to track COLLECTING's, and handed its circling turn to the robot).
    """

    def __init__(
        self,
        period: float = 0.02,
        gains: dict[str, float] | None = None,
        workspace: tuple[float, float, float, float] = (-3.0, 3.0, -2.0, 2.0),
        collect: bool = False,
    ):
        """Creates the action.

        Args:
            period: update period [s].
            gains: overrides of :data:`DRIBBLE_GAINS`.
            workspace: the allowed target region ``[x_min, x_max, y_min, y_max]``.
            collect: collect mode: fetch a ball not held first (see the class).
        """
        super().__init__()
        check_period(period)
        positive = (
            "v_max",
            "omega_max",
            "omega_in_place",
            "min_turn_radius",
            "a_max",
            "alpha_max",
            "timeout",
            "position_tolerance",
        )
        positive = (*positive, "hold_distance", "lost_distance", "lost_lateral")
        positive = (*positive, "heading_tolerance", "collect_distance", "collect_angle")
        positive = (*positive, "control_distance")
        merged = merge_gains(DRIBBLE_GAINS, gains, "DribbleBall", positive)
        if merged["control_distance"] >= merged["position_tolerance"]:
            raise RepertoireError(
                f"DribbleBall gain control_distance ({merged['control_distance']}) must be "
                f"below position_tolerance ({merged['position_tolerance']}): a pivot turns in "
                "place once its held spot arrives with control_distance to spare"
            )
        if not isinstance(collect, bool):
            raise RepertoireError(f"collect must be a bool, got {collect!r}")
        self.collect = collect
        inputs = (("state", 4), ("ball", 2), ("target", 4))
        slots = 3 if collect else 1
        ports = self._declare_drive(
            period, DRIBBLE_GAINS, merged, workspace, inputs, self._next, slots
        )
        self._ball_port = ports["ball"]

    def failure_reason(self, context: Context) -> str:
        """Why a collect-mode action failed (``"ball lost"``, ...), ``""`` otherwise."""
        if not self.collect:
            raise RepertoireError("failure_reason needs collect mode (DribbleBall(collect=True))")
        xd = context.get_discrete_state(self._xd).get_value()
        return FAILURE_REASONS[int(xd[5])]

    def get_ball_input_port(self):
        return self._ball_port

    def _next(self, context: Context, xd: np.ndarray, elapsed: float) -> list:
        status, mode = xd[2], xd[3]
        extra = list(xd[4:])  # collect mode's [phase, reason]
        if status != ActionStatus.RUNNING:
            return [0.0, 0.0, status, mode, *extra]
        g = self.gains(context)
        state = self._state_port.Eval(context)
        ball = self._ball_port.Eval(context)
        target = self._target_port.Eval(context)
        ws = context.get_numeric_parameter(self._workspace_index).get_value()
        active = self.is_active(context)
        if (
            not np.all(np.isfinite(target))
            or not np.all(np.isfinite(ball))
            or not ws[0] <= target[0] <= ws[1]
            or not ws[2] <= target[1] <= ws[3]
        ):
            failed = ActionStatus.FAILED if active else ActionStatus.RUNNING
            if self.collect and active:
                extra[1] = BAD_INPUT
            return [0.0, 0.0, failed, mode, *extra]
        if self.collect and extra[0] != DRIBBLING:
            held = ball_terms(state, ball, g)[0]
            phase = collect_phase(int(extra[0]), held, state, ball, target, g)
            # waiting (not active): the command of the phase it would start in, none kept
            kept = phase if active else COLLECTING
            if phase == DRIBBLING and not active:
                waiting = approach_mode(APPROACH, state, target, g)
                step = self._dribble_step(
                    waiting, extra, state, ball, target, g, xd, elapsed, active
                )
                return [*step[:3], mode, kept, NO_REASON]
            if phase != DRIBBLING:
                if phase == CLOSING:
                    v, w = close_control(state, ball, g)
                else:
                    v, w, _ = collect_control(state, ball, target, g)
                control = (v, w, math.inf, math.pi)  # never succeeds while collecting
                step = drive_step(control, xd[:2], state, target, g, elapsed, self.period, active)
                return [*step, mode, kept, NO_REASON]
            extra[0] = DRIBBLING
        mode = approach_mode(int(mode), state, target, g)
        return self._dribble_step(mode, extra, state, ball, target, g, xd, elapsed, active)

    def _dribble_step(self, mode, extra, state, ball, target, g, xd, elapsed, active) -> list:
        """The next state while dribbling in approach ``mode``."""
        v, w, held = mode_control(mode, state, ball, target, g)
        if not held and active:
            if self.collect:
                extra[1] = BALL_LOST
            return [0.0, 0.0, ActionStatus.FAILED, mode, *extra]
        h = g["hold_distance"]
        rho = math.hypot(
            target[0] + h * math.cos(target[2]) - state[0] - h * math.cos(state[2]),
            target[1] + h * math.sin(target[2]) - state[1] - h * math.sin(state[2]),
        )
        heading_error = math.remainder(target[2] - state[2], 2 * math.pi)
        control = (v, w, rho, heading_error)
        step = drive_step(control, xd[:2], state, target, g, elapsed, self.period, active)
        return [*step, mode, *extra]
