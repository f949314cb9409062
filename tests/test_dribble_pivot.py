"""DribbleBall's pivot (session 36): the in-place turn kept while it arrives, the reach.

The dribble study's 30 timeouts of seeds 0-999 were slow pivots: the axle law stopped on
the edge of its position tolerance, the in-place turn drifted the ball off the bumper,
closing on it crept the axle out of the tolerance, and the axle law then turned to face
the goal's axle position behind the robot, away from ``phi_g``.
"""

import itertools
import math

import numpy as np
import pytest
from repertoire.systems.dribble_ball import (
    APPROACH,
    DRIBBLE_GAINS,
    PIVOT,
    PIVOT_TURN,
    DribbleBall,
    approach_mode,
    ball_in_robot_frame,
    dribble_control,
    mode_control,
    pivot_turns,
    turn_miss,
)
from repertoire.systems.go_to_pose import ActionStatus

from repertoire.errors import RepertoireError

G = dict(DRIBBLE_GAINS)
H = G["hold_distance"]

# Dribble study seed 112 (default config) at 10.8 s on session 35's law: in PIVOT, the axle
# 0.101 m from the goal's after a close, heading 0.487 rad off, the ball 0.049 m off its
# held spot (controlled). The old axle law turned to face the goal's axle (-0.5 rad/s),
# the heading error grew to 2.5 rad and the dribble ended at 24.0 s.
CREPT_STATE = [-0.999, 1.044, 0.276, 0.0]
CREPT_GOAL = [-1.034, 0.949, 0.763, 0.026]


def _ball_at(state, bx, by):
    """The world ``[x, y]`` of a ball at ``(bx, by)`` in the robot's frame."""
    c, s = math.cos(state[2]), math.sin(state[2])
    return [state[0] + c * bx - s * by, state[1] + s * bx + c * by]


def _spot_distance(state, goal):
    c, s, cg, sg = math.cos(state[2]), math.sin(state[2]), math.cos(goal[2]), math.sin(goal[2])
    return math.hypot(goal[0] + H * cg - state[0] - H * c, goal[1] + H * sg - state[1] - H * s)


def test_turn_miss_closed_forms():
    goal = [0.0, 0.0, 0.0, 0.0]  # the goal's held spot q = (0.31, 0)
    # heading on phi_g: the turn is over, the miss is the axle's distance from the goal's
    assert turn_miss([0.07, 0.0, 0.0, 0.0], goal, G) == pytest.approx(0.07, abs=1e-15)
    assert turn_miss([0.0, 0.06, 0.0, 0.0], goal, G) == pytest.approx(0.06, abs=1e-15)
    # the axle 0.15 m to the side, heading 1.0 off: the nearest spot of the turn's last
    # 0.5 rad is at phi* = atan2(-0.15, 0.31) (error 0.451 rad), | |q - p| - h | away
    miss = turn_miss([0.0, 0.15, -1.0, 0.0], goal, G)
    assert miss == pytest.approx(math.hypot(0.31, 0.15) - 0.31, rel=1e-12)  # 0.0344
    # the same axle turning from the other side (heading +1.0 off, phi* out of the way):
    # its nearest spot is at heading 0, the axle's 0.15 m
    assert turn_miss([0.0, 0.15, 1.0, 0.0], goal, G) == pytest.approx(0.15, rel=1e-12)
    # 0.2 m to the side: phi* = -0.573 lies beyond the 0.5 rad the turn counts
    miss = turn_miss([0.0, 0.2, -1.0, 0.0], goal, G)
    assert miss == pytest.approx(math.hypot(H * math.cos(0.5) - 0.31, -H * math.sin(0.5) + 0.2))
    # the axle 0.12 m past the goal's: turning cannot bring the spot back (0.12 m)
    assert turn_miss([0.12, 0.0, -1.0, 0.0], goal, G) == pytest.approx(0.12, rel=1e-12)


def test_pivot_turns_with_and_without_the_margin():
    goal = [0.0, 0.0, 0.0, 0.0]
    # the turn arrives (0.07 < 0.1), but not with control_distance (0.05) to spare
    assert pivot_turns([0.07, 0.0, 0.0, 0.0], goal, G, 0.0)
    assert not pivot_turns([0.07, 0.0, 0.0, 0.0], goal, G, G["control_distance"])
    assert pivot_turns([0.04, 0.0, -1.0, 0.0], goal, G, G["control_distance"])
    assert not pivot_turns([0.12, 0.0, -1.0, 0.0], goal, G, 0.0)


def test_the_crept_pivot_keeps_turning_towards_the_goal_heading():
    state, goal = CREPT_STATE, CREPT_GOAL
    assert math.hypot(state[0] - goal[0], state[1] - goal[1]) > G["position_tolerance"]
    # turning on can still arrive: at phi* = atan2(q - p), 0.20 rad from phi_g, the spot
    # misses the goal's by | |q - p| - h | = 0.086 m < 0.1
    qx, qy = goal[0] + H * math.cos(goal[2]) - state[0], goal[1] + H * math.sin(goal[2]) - state[1]
    assert abs(goal[2] - math.atan2(qy, qx)) < G["heading_tolerance"]
    miss = abs(math.hypot(qx, qy) - H)
    assert turn_miss(state, goal, G) == pytest.approx(miss, rel=1e-12)
    assert 0.08 < miss < 0.09
    # so PIVOT_TURN stays; a pivot still reaching does not turn yet (0.086 m leaves no
    # control_distance to spare): the hysteresis
    assert approach_mode(PIVOT_TURN, state, goal, G) == PIVOT_TURN
    assert approach_mode(PIVOT, state, goal, G) == PIVOT
    # the command: in place towards phi_g at omega_in_place (k_alpha e omega_max a = 1.16)
    ball = _ball_at(state, 0.351, -0.026)
    assert ball_in_robot_frame(state, ball) == pytest.approx((0.351, -0.026), abs=1e-12)
    assert mode_control(PIVOT_TURN, state, ball, goal, G) == (0.0, 0.5, True)
    # the pivot's reach from here turns to face the goal's axle, 2.2 rad to the right
    assert mode_control(PIVOT, state, ball, goal, G) == (0.0, -0.5, True)


def test_dribble_ball_turns_on_in_the_crept_pivot_exact():
    action = DribbleBall(period=0.1)
    ctx = action.CreateDefaultContext()
    action.get_state_input_port().FixValue(ctx, np.array(CREPT_STATE))
    action.get_ball_input_port().FixValue(ctx, np.array(_ball_at(CREPT_STATE, 0.351, -0.026)))
    action.get_target_input_port().FixValue(ctx, np.array(CREPT_GOAL))
    ctx.SetDiscreteState(0, [0.0, 0.0, ActionStatus.RUNNING, PIVOT_TURN, 0.0])
    update = action.EvalUniquePeriodicDiscreteUpdate(ctx).get_vector().get_value()[:-1]
    # +0.5 rad/s rate limited to alpha_max * period = 0.3 (the old law: -0.3)
    np.testing.assert_allclose(update, [0.0, 0.3, ActionStatus.RUNNING, PIVOT_TURN])


def test_the_pivot_reach_turns_drives_and_never_backs():
    goal = [0.0, 0.0, 0.0, 0.0]
    # facing the goal's axle 0.3 m ahead: drive at k_rho * rho, no turn
    state = [-0.3, 0.0, 0.0, 0.0]
    v, w, held = dribble_control(state, _ball_at(state, H, 0.0), goal, G, 0.0)
    assert held and v == pytest.approx(G["k_rho"] * 0.3, rel=1e-12) and w == 0.0
    # 0.1 rad off it (within go_to_pose.RUN_UP_AIM_RAD): drive and steer with k_alpha
    state = [-0.3, 0.0, 0.1, 0.0]
    v, w, _ = dribble_control(state, _ball_at(state, H, 0.0), goal, G, 0.0)
    assert v == pytest.approx(G["k_rho"] * 0.3 * math.cos(0.1), rel=1e-12)
    assert w == pytest.approx(-G["k_alpha"] * 0.1, rel=1e-12)
    # the goal's axle 0.3 m behind: turn in place to face it, never back onto it
    state = [0.3, 0.0, 0.0, 0.0]
    v, w, _ = dribble_control(state, _ball_at(state, H, 0.0), goal, G, 0.0)
    assert (v, w) == (0.0, G["omega_in_place"])
    # within position_tolerance - control_distance of it: turn towards phi_g in place
    state = [0.03, 0.0, -0.3, 0.0]
    v, w, _ = dribble_control(state, _ball_at(state, H, 0.0), goal, G, 0.0)
    assert (v, w) == (0.0, G["omega_in_place"])


def _rest_roots(mode, dx, ball_rf):
    """Heading errors e in [-1, 1] where the law's yaw rate crosses 0 at rest (bisected).

    The law of the mode that ``approach_mode`` gives from ``mode`` at each heading.
    """
    goal = [0.0, 0.0, 0.0, 0.0]

    def law(e):
        state = [dx, 0.02, -e, 0.0]
        ball = _ball_at(state, *ball_rf)
        return mode_control(approach_mode(mode, state, goal, G), state, ball, goal, G)

    grid = np.linspace(-1.0, 1.0, 81)
    for lo, hi in zip(grid[:-1], grid[1:]):
        (v_lo, w_lo, _), (v_hi, w_hi, _) = law(lo), law(hi)
        if v_lo != 0.0 or v_hi != 0.0 or w_lo * w_hi > 0.0:
            continue
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if law(mid)[1] * w_lo > 0.0 else (lo, mid)
        v, w, held = law(0.5 * (lo + hi))
        if held and v == 0.0 and abs(w) < 1e-6:  # a rest, not a jump of the law
            yield 0.5 * (lo + hi)


def test_every_rest_of_the_modes_is_an_arrival():
    # every rest (v = 0, the yaw rate crossing 0 as the heading error e varies) of the law
    # in the mode approach_mode gives from APPROACH, PIVOT or PIVOT_TURN, with a held ball
    # ahead of the bumper and the axle near the goal's, has the held spot within
    # position_tolerance of the goal's and e within heading_tolerance: an arrival
    rests = 0
    for mode in (APPROACH, PIVOT, PIVOT_TURN):
        for dx in np.linspace(-0.15, 0.15, 7):
            for ball_rf in itertools.product((0.3075, 0.33, 0.38, 0.447), (-0.13, -0.02, 0.03)):
                for e in _rest_roots(mode, dx, ball_rf):
                    rests += 1
                    spot = _spot_distance([dx, 0.02, -e, 0.0], [0.0, 0.0, 0.0, 0.0])
                    assert spot < G["position_tolerance"], (mode, dx, ball_rf, e)
                    assert abs(e) < G["heading_tolerance"], (mode, dx, ball_rf, e)
    assert rests > 0


def test_control_distance_must_leave_a_margin():
    with pytest.raises(RepertoireError, match="control_distance .*position_tolerance"):
        DribbleBall(gains={"control_distance": 0.1})
    DribbleBall(gains={"control_distance": 0.08})


@pytest.mark.parametrize("seed", [28, 112])
def test_dribble_study_pivots_arrive_before_the_timeout(seed):
    """Dribble study (default config) timeouts on session 35's law: crept pivots that
    ended at 27.4 and 24.0 s with a 30 s timeout; now 10.9 and 9.0 s."""
    from repertoire.studies.actions_dribble import DribbleEpisodesConfig, run_episode

    record = run_episode(DribbleEpisodesConfig(n_states=0), seed)
    assert record.status == "SUCCEEDED" and record.duration < DRIBBLE_GAINS["timeout"]
