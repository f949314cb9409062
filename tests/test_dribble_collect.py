"""DribbleBall's collect mode: fetch a ball not held, from behind it, then dribble."""

import math

import numpy as np
import pytest
from pydrake.math import RigidTransform
from pydrake.systems.analysis import Simulator
from repertoire.diagrams.soccer_dribble import (
    BALL_RADIUS,
    DribbleScenario,
    build_soccer_dribble,
    check_dribble,
    dribble_status,
    robot_and_ball,
)
from repertoire.systems.dribble_ball import (
    APPROACH,
    BAD_INPUT,
    BALL_LOST,
    CLOSING,
    COLLECTING,
    DRIBBLE_GAINS,
    DRIBBLING,
    NO_REASON,
    DribbleBall,
    behind_point,
    close_control,
    collect_control,
    collect_phase,
    segment_distance,
    target_aligned,
)
from repertoire.systems.go_to_pose import ActionStatus, pose_control

from repertoire.errors import RepertoireError, ScenarioError

G = dict(DRIBBLE_GAINS)


def test_behind_point_closed_form():
    # ball (1, 1), target along (3, 4): phi = atan2(4, 3), 0.5 m back = (0.3, 0.4) back
    x, y, phi = behind_point([1.0, 1.0], [4.0, 5.0, 0.0, 0.0], 0.5)
    assert (x, y) == pytest.approx((0.7, 0.6)) and phi == pytest.approx(math.atan2(4, 3))
    # target straight down -y: the point is above the ball, facing -pi/2
    assert behind_point([0, 0], [0, -2, 1.0, 0], 0.3) == pytest.approx([0.0, 0.3, -math.pi / 2])


def test_segment_distance_closed_form():
    assert segment_distance([0, 1], [-1, 0], [1, 0]) == pytest.approx(1.0)  # foot inside
    assert segment_distance([3, 4], [-1, 0], [0, 0]) == pytest.approx(5.0)  # nearest end b
    assert segment_distance([-2, 0], [-1, 0], [1, 0]) == pytest.approx(1.0)  # nearest end a
    assert segment_distance([1, 1], [0, 0], [0, 0]) == pytest.approx(math.sqrt(2))  # a = b


def test_collect_control_circles_a_ball_in_the_way():
    # ball at the origin, target along +x: the collect point is (-0.5, 0) facing 0.
    # Robot 0.5 m in front of the ball facing +y: on the circle, tangent anticlockwise
    # (theta = -pi: the +1 side), full speed, no turn.
    v, w, direct = collect_control([0.5, 0.0, math.pi / 2, 0.0], [0, 0], [2, 0, 0, 0], G)
    assert not direct and v == pytest.approx(G["v_max"]) and w == pytest.approx(0.0)
    # facing +x instead: chi - phi = pi/2, no forward speed, turn clipped to omega_max
    v, w, direct = collect_control([0.5, 0.0, 0.0, 0.0], [0, 0], [2, 0, 0, 0], G)
    assert not direct and v == pytest.approx(0.0, abs=1e-12) and w == G["omega_max"]
    # 0.6 m above the ball (outside the 0.5 m circle): chi = pi/2 + pi/2 + atan(0.1 / 0.5)
    # turns in towards the ball; the segment to (-0.5, 0) passes it at 0.384 m < 0.45
    chi = math.pi + math.atan(0.2)
    assert segment_distance([0, 0], [0, 0.6], [-0.5, 0]) < 0.9 * 0.5
    v, w, direct = collect_control([0.0, 0.6, chi, 0.0], [0, 0], [2, 0, 0, 0], G)
    assert not direct and v == pytest.approx(G["v_max"]) and w == pytest.approx(0.0)
    # 0.3 m above (inside the circle), facing +x: chi = pi + atan(-0.4) = 2.76 (turned
    # outwards from the tangent pi), so no forward speed and a left turn at omega_max
    chi = math.pi + math.atan(-0.4)
    v, w, direct = collect_control([0.0, 0.3, 0.0, 0.0], [0, 0], [2, 0, 0, 0], G)
    assert not direct and v == 0.0 and w == G["omega_max"] and G["k_alpha"] * chi > 1.2
    v, w, _ = collect_control([0.0, 0.3, chi, 0.0], [0, 0], [2, 0, 0, 0], G)
    assert v == pytest.approx(G["v_max"]) and w == pytest.approx(0.0)
    # below the line: theta > 0 -> clockwise (side -1): at (0.5, -0.0001) facing -y
    v, w, _ = collect_control([0.5, -1e-4, -math.pi / 2, 0.0], [0, 0], [2, 0, 0, 0], G)
    assert v == pytest.approx(G["v_max"]) and w == pytest.approx(0.0, abs=1e-3)


def test_collect_control_drives_directly_when_clear_and_onto_the_ball_when_lined_up():
    # clear (the segment to (-0.5, 0) ends 0.5 m from the ball) but 0.3 m off the line:
    # GoToPose's law to the collect point at rest
    state = [-1.5, 0.3, 0.0, 0.0]
    v, w, direct = collect_control(state, [0, 0], [2, 0, 0, 0], G)
    v0, w0, _, _ = pose_control(state, [-0.5, 0.0, 0.0, 0.0], G)
    assert direct and (v, w) == (v0, w0)
    # lined up (0.6 m behind, 5 cm off the line, heading 0.1): the law to the held pose
    state = [-0.6, 0.05, 0.1, 0.0]
    v, w, direct = collect_control(state, [0, 0], [2, 0, 0, 0], G)
    v0, w0, _, _ = pose_control(state, [-G["hold_distance"], 0.0, 0.0, 0.0], G)
    assert direct and (v, w) == (v0, w0) and v > 0


def test_target_aligned_and_close_control_closed_forms():
    s = [0.0, 0.0, 0.0, 0.0]
    # the ball -> target direction 0.99 / 1.01 rad off the heading (collect_angle 1)
    assert target_aligned(s, [0.5, 0], [0.5 + math.cos(0.99), math.sin(0.99), 0, 0], G)
    assert not target_aligned(s, [0.5, 0], [0.5 + math.cos(1.01), -math.sin(1.01), 0, 0], G)
    # a ball lying 0.5 m ahead: 0.19 m to go, sqrt(2 * 0.6 * 0.19) = 0.477 > v_max 0.4
    assert close_control(s, [0.5, 0.0], G) == (0.4, 0.0)
    # 0.09 m to go, 0.03 m to the left: sqrt(2 a_max 0.09) cos^2(gamma), k_ball gamma
    gamma = math.atan2(0.03, 0.4)
    v, w = close_control(s, [0.4, 0.03], G)
    assert v == pytest.approx(math.sqrt(1.2 * 0.09) * math.cos(gamma) ** 2, abs=1e-12)
    assert w == pytest.approx(2.0 * gamma, abs=1e-12)
    # at (or inside) the held spot: stop; a heading rotated with the frame gives the same
    assert close_control(s, [0.3, 0.0], G) == (0.0, 0.0)
    v2, w2 = close_control(
        [1.0, 2.0, 0.5, 0.0],
        [
            1 + 0.4 * math.cos(0.5) - 0.03 * math.sin(0.5),
            2 + 0.4 * math.sin(0.5) + 0.03 * math.cos(0.5),
        ],
        G,
    )
    assert (v2, w2) == pytest.approx((v, w), abs=1e-12)


def test_collect_phase_by_hand():
    s = [0.0, 0.0, 0.0, 0.0]
    ahead = [2, 0.5, 0, 0]
    # the ball at its held spot is controlled: dribbling (the robot turns with it), with
    # the target ahead or 1.2 rad off (seen from the ball)
    far = [0.31 + math.cos(1.2), math.sin(1.2), 0, 0]
    for target in (ahead, far):
        assert collect_phase(COLLECTING, True, s, [0.31, 0.0], target, G) == DRIBBLING
    # 0.09 m beyond it held, not controlled: closing with the target 0.8 rad off (was:
    # dribbling at once), collecting 1.2 rad off; closing goes on whatever the alignment
    near = [0.4 + math.cos(0.8), math.sin(0.8), 0, 0]
    far = [0.4 + math.cos(1.2), math.sin(1.2), 0, 0]
    assert collect_phase(COLLECTING, True, s, [0.4, 0.0], near, G) == CLOSING
    assert collect_phase(COLLECTING, True, s, [0.4, 0.0], far, G) == COLLECTING
    assert collect_phase(CLOSING, True, s, [0.4, 0.0], far, G) == CLOSING
    # not held: collecting (also from closing); dribbling is for good
    assert collect_phase(COLLECTING, False, s, [0.31, 0.0], ahead, G) == COLLECTING
    assert collect_phase(CLOSING, False, s, [0.4, 0.0], near, G) == COLLECTING
    assert collect_phase(DRIBBLING, False, s, [0.4, 0.0], far, G) == DRIBBLING
    # control_distance (0.05 m) ahead of the held spot: controlled; 0.06 m: not
    assert collect_phase(CLOSING, True, s, [0.36, 0.0], far, G) == DRIBBLING
    assert collect_phase(CLOSING, True, s, [0.37, 0.0], far, G) == CLOSING


def _context(target, ball, state=(0, 0, 0, 0), time=0.0, phase=COLLECTING):
    action = DribbleBall(period=0.1, collect=True)
    ctx = action.CreateDefaultContext()
    action.get_state_input_port().FixValue(ctx, np.array(state, dtype=float))
    action.get_ball_input_port().FixValue(ctx, np.array(ball, dtype=float))
    action.get_target_input_port().FixValue(ctx, np.array(target, dtype=float))
    ctx.get_mutable_discrete_state(0).SetFromVector([0, 0, 0, APPROACH, phase, NO_REASON, 0])
    ctx.SetTime(time)
    return action, ctx


def _update(action, ctx):
    # without the last slot, the timeout's start (tested in test_action_systems)
    return action.EvalUniquePeriodicDiscreteUpdate(ctx).get_vector().get_value()[:-1]


def test_collect_mode_leaf_system_exact():
    running, failed = ActionStatus.RUNNING, ActionStatus.FAILED
    # a free ball 1 m ahead on the line to the target (without collect mode: FAILED):
    # lined up, the held-pose law wants 0.4, rate limited to a_max * period = 0.06
    action, ctx = _context([2, 0, 0, 0], ball=(1.0, 0.0))
    np.testing.assert_allclose(_update(action, ctx), [0.06, 0, running, APPROACH, COLLECTING, 0])
    # held 0.09 m beyond its spot (not controlled), target behind: circle round (omega
    # wants -1.2, rate limited to 0.3), no speed
    action, ctx = _context([-1, 0, math.pi, 0], ball=(0.4, 0.0))
    np.testing.assert_allclose(
        _update(action, ctx), [0.0, -0.3, running, APPROACH, COLLECTING, 0], atol=1e-12
    )
    # held 0.19 m beyond its spot, the target 0.8 rad off: closing, straight onto the ball
    # (wants v_max, rate limited to 0.06), no turn (was: dribbling at once); from CLOSING
    # with the target 1.2 rad off: the same
    for phi, phase in ((0.8, COLLECTING), (1.2, CLOSING)):
        target = [0.5 + math.cos(phi), math.sin(phi), phi, 0]
        action, ctx = _context(target, ball=(0.5, 0.0), phase=phase)
        np.testing.assert_allclose(_update(action, ctx), [0.06, 0, running, APPROACH, CLOSING, 0])
    # controlled and the target ahead or behind: dribbling at once,
    # the same command as without collect mode
    for target in ([1, 0, 0, 0], [-1, 0, math.pi, 0]):
        action, ctx = _context(target, ball=(0.31, 0.0))
        plain = DribbleBall(period=0.1)
        plain_ctx = plain.CreateDefaultContext()
        for port, value in (("state", [0, 0, 0, 0]), ("ball", [0.31, 0]), ("target", target)):
            plain.GetInputPort(port).FixValue(plain_ctx, np.array(value, dtype=float))
        expected = [*_update(plain, plain_ctx), DRIBBLING, NO_REASON]
        np.testing.assert_allclose(_update(action, ctx), expected)
    np.testing.assert_allclose(expected[:4], [0.0, 0.3, running, APPROACH], atol=1e-12)
    # at the target pose without the ball: collecting never succeeds
    action, ctx = _context([0.05, 0, 0.1, 0], ball=(0.0, 1.0))
    assert _update(action, ctx)[2] == running
    # the ball lost after it was held: FAILED, reason "ball lost"
    action, ctx = _context([1, 0, 0, 0], ball=(1.0, 0.0), phase=DRIBBLING)
    xd = _update(action, ctx)
    np.testing.assert_allclose(xd, [0, 0, failed, APPROACH, DRIBBLING, BALL_LOST])
    ctx.get_mutable_discrete_state(0).SetFromVector([*xd, 0.0])
    assert action.failure_reason(ctx) == "ball lost"
    assert action.get_status_output_port().Eval(ctx) == failed
    # a bad target: FAILED, its reason
    action, ctx = _context([np.nan, 0, 0, 0], ball=(1.0, 0.0))
    xd = _update(action, ctx)
    np.testing.assert_allclose(xd, [0, 0, failed, APPROACH, COLLECTING, BAD_INPUT])
    ctx.get_mutable_discrete_state(0).SetFromVector([*xd, 0.0])
    assert action.failure_reason(ctx) == "bad target or ball"
    # the timeout while collecting
    action, ctx = _context([2, 0, 0, 0], ball=(1.0, 0.0), time=DRIBBLE_GAINS["timeout"])
    np.testing.assert_allclose(
        _update(action, ctx), [0, 0, ActionStatus.TIMED_OUT, APPROACH, COLLECTING, 0]
    )
    # a later plan action (active 0) keeps collecting and stays RUNNING
    action, ctx = _context([1, 0, 0, 0], ball=(0.31, 0.0))
    action.get_active_input_port().FixValue(ctx, [0.0])
    np.testing.assert_allclose(_update(action, ctx)[2:], [running, APPROACH, COLLECTING, 0])


def test_collect_mode_off_by_default_and_bad_values():
    action = DribbleBall()
    assert not action.collect
    assert action.CreateDefaultContext().get_discrete_state(0).size() == 5
    with pytest.raises(RepertoireError, match="collect mode"):
        action.failure_reason(action.CreateDefaultContext())
    with pytest.raises(RepertoireError, match="collect must be a bool, got 'yes'"):
        DribbleBall(collect="yes")
    with pytest.raises(RepertoireError, match="collect_distance must be > 0"):
        DribbleBall(collect=True, gains={"collect_distance": 0.0})
    with pytest.raises(ScenarioError, match="collect must be a bool"):
        DribbleScenario(collect=1).validate()


def test_soccer_dribble_collects_a_ball_beside_the_robot_and_delivers_it():
    # the ball 0.5 m ahead and 0.5 m left, the target 1 m behind the robot: without
    # collect mode the action fails at once (ball not held); with it the robot circles
    # the ball, comes in behind it and dribbles it to the target
    kwargs = dict(initial_pose=[0.0, 0.0, 0.0], ball_offset=[0.5, 0.5], target=[-1.0, 0.8, 3.0, 0])
    diagram = build_soccer_dribble(DribbleScenario(**kwargs))
    sim = Simulator(diagram)
    sim.AdvanceTo(0.1)
    assert dribble_status(diagram, sim.get_context()) == ActionStatus.FAILED
    diagram = build_soccer_dribble(DribbleScenario(collect=True, **kwargs))
    sim = Simulator(diagram)
    sim.AdvanceTo(15.0)
    ctx = sim.get_context()
    assert dribble_status(diagram, ctx) == ActionStatus.SUCCEEDED
    figures = check_dribble(diagram, ctx)
    assert figures["position_error_m"] < 0.15 and figures["ball_from_held_spot_m"] < 0.1
    _, ball = robot_and_ball(diagram, ctx)
    # the ball held in front of the goal pose's held spot
    spot = np.array([-1.0 + 0.31 * math.cos(3.0), 0.8 + 0.31 * math.sin(3.0)])
    assert np.hypot(*(ball - spot)) < 0.2


def test_soccer_dribble_drives_onto_a_ball_ahead_before_turning():
    # the ball lying 0.5 m ahead of the axle (where soccer_plan's approach stops, not yet
    # touching the guide arms), the target 1.5 m beyond it 0.95 rad to the left: the
    # robot used to dribble at once, and its first turn swept the ball out past the right
    # arm (ball lost after 1.25 s); now it drives onto the ball first and delivers it
    target = [0.5 + 1.5 * math.cos(0.95), 1.5 * math.sin(0.95), 0.95, 0.0]
    scenario = DribbleScenario(
        collect=True, initial_pose=[0.0, 0.0, 0.0], ball_offset=[0.5, 0.0], target=target
    )
    diagram = build_soccer_dribble(scenario)
    sim = Simulator(diagram)
    sim.AdvanceTo(10.0)
    ctx = sim.get_context()
    assert dribble_status(diagram, ctx) == ActionStatus.SUCCEEDED
    figures = check_dribble(diagram, ctx)
    assert figures["position_error_m"] < 0.15 and figures["ball_from_held_spot_m"] < 0.1


def test_soccer_dribble_collects_a_ball_behind_the_robot_and_delivers_it():
    # the robot faces away from the ball (0.7 m behind it; set in the context: a
    # scenario's ball_offset is ahead of the bumper) and the target lies beyond the ball
    target = [-1.8, 0.6, 2.5, 0.0]
    statuses = []
    for collect in (False, True):
        scenario = DribbleScenario(collect=collect, initial_pose=[0.0, 0.0, 0.0], target=target)
        diagram = build_soccer_dribble(scenario)
        sim = Simulator(diagram)
        ctx = sim.get_mutable_context()
        plant = diagram.GetSubsystemByName("plant")
        ball_pose = RigidTransform([-0.7, 0.1, BALL_RADIUS])
        plant.SetFreeBodyPose(
            plant.GetMyMutableContextFromRoot(ctx), plant.GetBodyByName("ball"), ball_pose
        )
        sim.Initialize()
        sim.AdvanceTo(15.0)
        statuses.append(dribble_status(diagram, ctx))
    assert statuses == [ActionStatus.FAILED, ActionStatus.SUCCEEDED]
    figures = check_dribble(diagram, ctx)
    assert figures["position_error_m"] < 0.15 and figures["ball_from_held_spot_m"] < 0.1


def test_collect_mode_waiting_tracks_the_phase_it_would_start_in():
    # A plan's dribble (active input 0) tracks the command it would give: with the ball
    # held 0.54 m ahead and the target 0.4 rad off, that is closing's (straight onto the
    # ball: v_max wanted, rate limited to 0.06; omega = k_ball * gamma = -0.148), and no phase is
    # kept while it waits. It used to track COLLECTING's law, whose circling turn it then
    # handed to the robot (explore seed 113: a robot at rest turned away from its ball).
    running = ActionStatus.RUNNING
    ball = (0.54, -0.04)
    gamma = math.atan2(ball[1], ball[0])
    target = [0.54 + 2.0 * math.cos(0.4), 2.0 * math.sin(0.4), 0.4, 0.0]
    for active in (0.0, 1.0):
        action, ctx = _context(target, ball=ball)
        action.get_active_input_port().FixValue(ctx, [active])
        kept = CLOSING if active else COLLECTING
        expected = [0.06, G["k_ball"] * gamma, running, APPROACH, kept, 0]
        np.testing.assert_allclose(_update(action, ctx), expected, atol=1e-12)
    # a controlled ball while waiting: the dribble's command, still no phase kept
    action, ctx = _context([1.0, 0.0, 0.0, 0.0], ball=(0.31, 0.0))
    action.get_active_input_port().FixValue(ctx, [0.0])
    np.testing.assert_allclose(_update(action, ctx), [0.06, 0.0, running, APPROACH, COLLECTING, 0])
