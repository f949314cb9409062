"""DribbleBall's spot law near the goal (session 37): its in-place turn only where it arrives.

Within ``position_tolerance`` of the goal's held spot the spot law turns in place about the
axle, which swings the held spot ``hold_distance`` ahead of it. Where that turn cannot bring
the heading within ``heading_tolerance`` with the spot still inside (:func:`turn_miss` at
least ``position_tolerance``), the spot left the tolerance, the polar law outside it turned
to face the goal's spot (undoing the turn) and drove back in: the dribble study's seeds 526
and 727 cycled so on the tolerance's edge until the 15 s timeout. ``approach_mode`` now
hands that in-place turn to PIVOT_TURN where it arrives (held while it does) and to the
pivot's reach where it does not.
"""

import math

import numpy as np
import pytest
from repertoire.systems.dribble_ball import (
    APPROACH,
    DRIBBLE_GAINS,
    LOOP_LEFT,
    PIVOT,
    PIVOT_TURN,
    DribbleBall,
    approach_mode,
    mode_control,
    turn_miss,
)
from repertoire.systems.go_to_pose import ActionStatus

G = dict(DRIBBLE_GAINS)
H = G["hold_distance"]

# Dribble study seed 526 (default config) at 7.1 s on session 36's law: in APPROACH, the
# held spot 0.098 m from the goal's, the heading 0.80 rad off phi_g. Turning in place to
# within heading_tolerance leaves the spot 0.135 m from the goal's; the law cycled there
# until the timeout.
CYCLE_STATE = [-0.890, -0.717, 1.061, 0.0]
CYCLE_GOAL = [-0.616, -0.651, 1.862, 0.078]


def _spot_offset(state, goal):
    """The goal's held spot minus the robot's, and the goal's held spot minus the axle."""
    cg, sg = math.cos(goal[2]), math.sin(goal[2])
    qx, qy = goal[0] + H * cg - state[0], goal[1] + H * sg - state[1]
    return (qx - H * math.cos(state[2]), qy - H * math.sin(state[2])), (qx, qy)


def _held_ball(state):
    """A ball on the held spot of ``state``."""
    return [state[0] + H * math.cos(state[2]), state[1] + H * math.sin(state[2])]


def test_a_spot_turn_that_cannot_arrive_hands_over_to_the_pivot():
    state, goal = CYCLE_STATE, CYCLE_GOAL
    (sx, sy), (qx, qy) = _spot_offset(state, goal)
    e = math.remainder(goal[2] - state[2], 2.0 * math.pi)
    # the spot law's in-place turn region: spot inside, heading outside the tolerances
    assert math.hypot(sx, sy) < G["position_tolerance"]
    assert e == pytest.approx(0.801, abs=1e-12) and e > G["heading_tolerance"]
    # nearest spot of the turn's headings within tolerance: at error 0.5 (phi* = 0.76 off
    # phi_g lies beyond), 0.135 m from the goal's: the turn cannot arrive
    c = goal[2] - G["heading_tolerance"]
    miss = math.hypot(H * math.cos(c) - qx, H * math.sin(c) - qy)
    assert turn_miss(state, goal, G) == pytest.approx(miss, rel=1e-12)
    assert 0.13 < miss < 0.14
    # the swing rule (from the goal's spot) does not see it: 2 h sin(0.30 / 2) = 0.093
    assert 2.0 * H * math.sin((e - G["heading_tolerance"]) / 2.0) < G["position_tolerance"]
    # the pivot (was: APPROACH, whose turn swung the spot out and whose polar law turned back)
    assert approach_mode(APPROACH, state, goal, G) == PIVOT
    # whose reach turns to face the goal's axle, to the right (the spot law turned left)
    ball = _held_ball(state)
    assert mode_control(APPROACH, state, ball, goal, G) == (0.0, 0.5, True)
    assert mode_control(PIVOT, state, ball, goal, G) == (0.0, -0.5, True)


def test_a_spot_turn_that_arrives_is_held_as_the_pivot_turn():
    goal = [0.0, 0.0, 0.0, 0.0]  # the goal's held spot q = (0.31, 0)
    # the held spot on q, heading 0.6 rad off: turning 0.1 rad to the tolerance swings the
    # spot by the chord 2 h sin(0.05) = 0.031 m, inside
    state = [H - H * math.cos(-0.6), -H * math.sin(-0.6), -0.6, 0.0]
    assert math.hypot(*_spot_offset(state, goal)[0]) == pytest.approx(0.0, abs=1e-15)
    assert turn_miss(state, goal, G) == pytest.approx(2.0 * H * math.sin(0.05), rel=1e-12)
    assert approach_mode(APPROACH, state, goal, G) == PIVOT_TURN
    # the same in-place turn the spot law commands there, now kept while it arrives
    ball = _held_ball(state)
    assert mode_control(PIVOT_TURN, state, ball, goal, G) == (0.0, 0.5, True)
    assert mode_control(APPROACH, state, ball, goal, G) == (0.0, 0.5, True)
    # within the heading tolerance it is an arrival, not a mode change
    inside = [H - H * math.cos(-0.4), -H * math.sin(-0.4), -0.4, 0.0]
    assert approach_mode(APPROACH, inside, goal, G) == APPROACH
    # a target speed that needs a loop (0.3 m/s) keeps the loop logic: at that speed no
    # loop yet and no in-place turn (APPROACH), stopped a loop
    moving = [*state[:3], 0.3]
    assert approach_mode(APPROACH, moving, [0.0, 0.0, 0.0, 0.3], G) == APPROACH
    assert approach_mode(APPROACH, state, [0.0, 0.0, 0.0, 0.3], G) == LOOP_LEFT


def test_dribble_ball_leaves_the_cycle_for_the_pivot_exact():
    action = DribbleBall(period=0.1)
    ctx = action.CreateDefaultContext()
    action.get_state_input_port().FixValue(ctx, np.array(CYCLE_STATE))
    action.get_ball_input_port().FixValue(ctx, np.array(_held_ball(CYCLE_STATE)))
    action.get_target_input_port().FixValue(ctx, np.array(CYCLE_GOAL))
    ctx.SetDiscreteState(0, [0.0, 0.0, ActionStatus.RUNNING, APPROACH, 0.0])
    update = action.EvalUniquePeriodicDiscreteUpdate(ctx).get_vector().get_value()[:-1]
    # the reach's -0.5 rad/s rate limited to alpha_max * period = 0.3 (the old law: +0.3)
    np.testing.assert_allclose(update, [0.0, -0.3, ActionStatus.RUNNING, PIVOT], atol=1e-15)


@pytest.mark.parametrize("seed", [526, 727])
def test_dribble_study_spot_cycles_arrive_before_the_timeout(seed):
    """Dribble study (default config) timeouts of session 36; now 11.6 and 7.7 s."""
    from repertoire.studies.actions_dribble import DribbleEpisodesConfig, run_episode

    record = run_episode(DribbleEpisodesConfig(n_states=0), seed)
    assert record.status == "SUCCEEDED" and record.duration < DRIBBLE_GAINS["timeout"]
