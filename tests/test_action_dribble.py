import math

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from repertoire.diagrams.simulate import build_registered
from repertoire.diagrams.soccer_dribble import (
    GUIDE_SIZE,
    GUIDE_Y,
    DribbleLoopScenario,
    DribbleScenario,
    build_soccer_dribble,
    check_dribble,
    dribble_simulator,
    dribble_status,
)
from repertoire.systems.ball import RollingResistance
from repertoire.systems.dribble_ball import (
    APPROACH,
    DRIBBLE_GAINS,
    LOOP_LEFT,
    LOOP_RIGHT,
    PIVOT,
    PIVOT_TURN,
    DribbleBall,
    approach_mode,
    ball_in_robot_frame,
    ball_terms,
    dribble_control,
    loop_control,
    loop_geometry,
    mode_control,
    needs_loop,
)
from repertoire.systems.go_to_pose import ActionStatus

from repertoire.errors import RepertoireError, ScenarioError


def test_ball_in_robot_frame_by_hand():
    # robot at (1, 1) facing +y: a ball at (1, 2) is 1 m ahead, one at (0, 1) 1 m to the left
    assert ball_in_robot_frame([1, 1, math.pi / 2, 0], [1, 2]) == pytest.approx((1.0, 0.0))
    assert ball_in_robot_frame([1, 1, math.pi / 2, 0], [0, 1]) == pytest.approx((0.0, 1.0))


def test_dribble_control_by_hand():
    g = dict(DRIBBLE_GAINS)
    # ball held 5 cm left of centre, goal 2 m straight ahead: full speed scaled by
    # cos^2 of the ball's bearing, turn towards the ball
    v, w, held = dribble_control([0, 0, 0, 0], [0.31, 0.05], [2, 0, 0, 0], g)
    gamma = math.atan2(0.05, 0.31)
    assert held and v == pytest.approx(g["v_max"] * math.cos(gamma) ** 2)
    assert w == pytest.approx(g["k_ball"] * gamma)
    # ball beside the robot: no forward motion, lost, turning at the standstill limit
    v, w, held = dribble_control([0, 0, 0, 0], [0.0, 0.5], [2, 0, 0, 0], g)
    assert not held and v == pytest.approx(0.0, abs=1e-12)
    assert w == pytest.approx(g["omega_in_place"])
    # goal behind: never back away from the ball
    v, _, held = dribble_control([0, 0, 0, 0], [0.31, 0.0], [-2, 0, 0, 0], g)
    assert held and v == 0.0


def _context(target, ball=(0.31, 0.0), state=(0, 0, 0, 0), time=0.0):
    action = DribbleBall(period=0.1)
    ctx = action.CreateDefaultContext()
    action.get_state_input_port().FixValue(ctx, np.array(state, dtype=float))
    action.get_ball_input_port().FixValue(ctx, np.array(ball, dtype=float))
    action.get_target_input_port().FixValue(ctx, np.array(target, dtype=float))
    ctx.SetTime(time)
    return action, ctx


def _update(action, ctx):
    # without the last slot, the timeout's start (tested in test_action_systems)
    return action.EvalUniquePeriodicDiscreteUpdate(ctx).get_vector().get_value()[:-1]


def test_dribble_ball_statuses_exact():
    # goal 1 m ahead: speed wants 0.4, rate limited to a_max * period = 0.06
    action, ctx = _context([1, 0, 0, 0])
    np.testing.assert_allclose(_update(action, ctx), [0.06, 0.0, ActionStatus.RUNNING, APPROACH])
    assert action.get_status_output_port().Eval(ctx) == ActionStatus.RUNNING
    # the ball 0.69 m from its held spot: lost -> failed, zero command
    action, ctx = _context([1, 0, 0, 0], ball=(1.0, 0.0))
    np.testing.assert_allclose(_update(action, ctx), [0.0, 0.0, ActionStatus.FAILED, APPROACH])
    # the ball beside a guide arm's tip, 0.219 m from its held spot (inside lost_distance)
    # but its centre 0.2 m to the side (beyond lost_lateral): lost -> failed
    action, ctx = _context([-1, 0, 0, 0], ball=(0.4, -0.2))
    np.testing.assert_allclose(_update(action, ctx), [0.0, 0.0, ActionStatus.FAILED, APPROACH])
    # 0.15 m to the side, within both: held, still running
    action, ctx = _context([1, 0, 0, 0], ball=(0.4, -0.15))
    assert _update(action, ctx)[2] == ActionStatus.RUNNING
    # held spot 5 cm from the goal's: succeeded
    action, ctx = _context([0.05, 0, 0.1, 0])
    assert _update(action, ctx)[2] == ActionStatus.SUCCEEDED
    # timeout
    action, ctx = _context([1, 0, 0, 0], time=DRIBBLE_GAINS["timeout"])
    np.testing.assert_allclose(_update(action, ctx), [0.0, 0.0, ActionStatus.TIMED_OUT, APPROACH])


def test_ball_held_by_hand():
    g = dict(DRIBBLE_GAINS)
    # the standstill's ball: 0.2506 m from the held spot (0.31, 0), 0.22 m to the side
    assert ball_terms([0, 0, 0, 0], [0.43, -0.22], g)[0] is False
    # 0.219 m from the held spot, but 0.2 m to the side: out of the dribbler
    held, gamma, align = ball_terms([0, 0, 0, 0], [0.4, -0.2], g)
    assert held is False
    assert gamma == pytest.approx(math.atan2(-0.2, 0.4))
    assert align == pytest.approx(0.4**2 / (0.4**2 + 0.2**2))
    # on the lateral limit (robot at (1, 1) facing +y: 0.155 m to its right) is held
    assert ball_terms([1, 1, math.pi / 2, 0], [1.155, 1.31], g)[0] is True
    assert ball_terms([1, 1, math.pi / 2, 0], [1.1551, 1.31], g)[0] is False
    # a narrower dribbler is a gain
    assert ball_terms([0, 0, 0, 0], [0.31, 0.1], g | {"lost_lateral": 0.05})[0] is False


def test_lost_lateral_default_is_the_guide_arms_outer_face():
    assert DRIBBLE_GAINS["lost_lateral"] == pytest.approx(GUIDE_Y + GUIDE_SIZE[1] / 2, abs=1e-12)


def _spot_on_goal(heading_error, offset=0.0):
    """A robot whose held spot is ``offset`` m beyond the goal's (goal [0, 0, 0, 0]) along x."""
    h, phi = DRIBBLE_GAINS["hold_distance"], -heading_error
    return [h + offset - h * math.cos(phi), -h * math.sin(phi), phi, 0.0]


def test_approach_mode_switching_by_hand():
    g, goal = dict(DRIBBLE_GAINS), [0.0, 0.0, 0.0, 0.0]
    # spot on the goal's, heading 1.0 off: an in-place turn of 1.0 - 0.5 swings the spot
    # 2 * 0.31 * sin(0.25) = 0.153 m > 0.1 -> pivot; 0.8 off: 0.093 m, the turn arrives
    # -> the spot law's in-place turn, held as PIVOT_TURN (session 37)
    assert approach_mode(APPROACH, _spot_on_goal(1.0), goal, g) == PIVOT
    assert approach_mode(APPROACH, _spot_on_goal(-1.0), goal, g) == PIVOT
    assert approach_mode(APPROACH, _spot_on_goal(0.8), goal, g) == PIVOT_TURN
    # 0.25 m away (beyond 2 * position_tolerance): not near, keep approaching
    assert approach_mode(APPROACH, _spot_on_goal(1.0, 0.25), goal, g) == APPROACH
    # a pivot goes on within 2 * min_turn_radius = 0.8 m, then approaches again
    assert approach_mode(PIVOT, _spot_on_goal(1.0, 0.5), goal, g) == PIVOT
    assert approach_mode(PIVOT, _spot_on_goal(0.0, 0.9), goal, g) == APPROACH


def test_loop_modes_for_a_target_speed_by_hand():
    g = dict(DRIBBLE_GAINS)
    # a stopped robot meets v_g below speed_tolerance (0.1 m/s) only
    assert not needs_loop([0, 0, 0, 0.05]) and needs_loop([0, 0, 0, 0.1])
    assert needs_loop([0, 0, 0, 0.3]) and not needs_loop([0, 0, 0, -0.3])  # never backs up
    goal = [0.0, 0.0, 0.0, 0.3]
    # spot on the goal's at rest, v_g = 0.3 (off by 0.3 >= 0.15): loop, on the side the
    # heading error turns to (phi_g - phi = -0.2: right, +0.2: left) while that turn keeps
    # the spot in: 0.8 off swings it 2 * 0.31 * sin(0.15) = 0.093 m <= 0.1
    assert approach_mode(APPROACH, _spot_on_goal(-0.2), goal, g) == LOOP_RIGHT
    assert approach_mode(APPROACH, _spot_on_goal(0.2), goal, g) == LOOP_LEFT
    assert approach_mode(APPROACH, _spot_on_goal(0.8), goal, g) == LOOP_LEFT
    assert approach_mode(APPROACH, _spot_on_goal(-0.8), goal, g) == LOOP_RIGHT
    # 1.0 off swings it 0.153 m > 0.1, and the robot is past the target on the left loop
    # (5.745 rad to go, see test_loop_geometry_by_hand): the other side, the loop of
    # 2 pi - 1.0 of turning (not 2 pi + 1.0) that the robot already points into
    assert approach_mode(APPROACH, _spot_on_goal(1.0), goal, g) == LOOP_RIGHT
    assert approach_mode(APPROACH, _spot_on_goal(-1.0), goal, g) == LOOP_LEFT
    # 0.15 m short of the target, still short of it on the left loop (0.031 rad to go):
    # the left loop, whose turn towards phi_g may end the action at once
    assert approach_mode(APPROACH, _spot_on_goal(1.0, -0.15), goal, g) == LOOP_LEFT
    assert approach_mode(APPROACH, _spot_on_goal(-1.0, -0.15), goal, g) == LOOP_RIGHT
    # at the target speed already: no loop (drive_step says succeeded)
    fast = [*_spot_on_goal(0.2)[:3], 0.3]
    assert approach_mode(APPROACH, fast, goal, g) == APPROACH
    # 0.15 m out, the turn small: keep approaching; a swing too large: loop, not pivot
    assert approach_mode(APPROACH, _spot_on_goal(0.2, 0.15), goal, g) == APPROACH
    assert approach_mode(APPROACH, _spot_on_goal(1.0, 0.15), goal, g) == LOOP_RIGHT
    # a loop goes on wherever the robot is, whatever its heading; a pivot becomes a loop
    assert approach_mode(LOOP_LEFT, _spot_on_goal(0.0, 2.0), goal, g) == LOOP_LEFT
    assert approach_mode(LOOP_LEFT, _spot_on_goal(1.0), goal, g) == LOOP_LEFT
    assert approach_mode(PIVOT, _spot_on_goal(-1.0, 0.5), goal, g) == LOOP_LEFT
    assert approach_mode(PIVOT, _spot_on_goal(-0.6, 0.5), goal, g) == LOOP_RIGHT
    # the target speed dropped below 0.1 m/s (a plan executor changed it): approach again
    assert approach_mode(LOOP_LEFT, _spot_on_goal(1.0, 2.0), [0, 0, 0, 0.05], g) == APPROACH


def test_loop_control_by_hand():
    g = dict(DRIBBLE_GAINS)
    goal, r = [0.0, 0.0, 0.0, 0.3], 1.25 * g["min_turn_radius"]  # R = 0.5 m
    # on the target, heading phi_g, ball held: on the left loop (centre (0, 0.5)) at its
    # tangent with no angle to go: v = v_g, omega = v / R = 0.6 (< the limit 0.3 / 0.4)
    assert loop_control([0, 0, 0, 0], [0.31, 0], goal, g, 1.0) == (0.3, pytest.approx(0.6), True)
    # half way round (top of the circle, heading pi): pi to go, v = min(v_max, k_rho R pi)
    v, w, held = loop_control([0, 1, math.pi, 0], [-0.31, 1], goal, g, 1.0)
    assert held and v == 0.4 and w == pytest.approx(0.4 / r)
    # the right loop mirrors it: centre (0, -0.5), clockwise
    v, w, held = loop_control([0, -1, math.pi, 0], [-0.31, -1], goal, g, -1.0)
    assert held and v == 0.4 and w == pytest.approx(-0.4 / r)
    # 2 cm outside the left loop: steer in by atan(0.02 / 0.5) on top of v / R
    v, w, _ = loop_control([0, -0.02, 0, 0], [0.31, -0.02], goal, g, 1.0)
    assert v == 0.3 and w == pytest.approx(0.6 + g["k_alpha"] * math.atan(0.02 / r))
    # ball 5 cm left of centre: both terms scaled by cos^2 of its bearing, plus k_ball
    # gamma (0.890), clipped to |v| / min_turn_radius (0.731)
    v, w, _ = loop_control([0, 0, 0, 0], [0.31, 0.05], goal, g, 1.0)
    gamma = math.atan2(0.05, 0.31)
    a = math.cos(gamma) ** 2
    assert v == pytest.approx(0.3 * a) and a * 0.3 * a / r + 2.0 * gamma > v / 0.4
    assert w == pytest.approx(v / 0.4)


def test_loop_geometry_by_hand():
    g, goal = dict(DRIBBLE_GAINS), [0.0, 0.0, 0.0, 0.3]
    h = g["hold_distance"]
    # spot on the goal's, heading -1.0: the axle at (h - h cos 1, h sin 1) = (0.1425, 0.2608)
    x, y = h - h * math.cos(1.0), h * math.sin(1.0)
    # left loop, centre (0, 0.5): the target is at bearing -pi/2, anticlockwise from psi
    r, psi, d, theta = loop_geometry(_spot_on_goal(1.0), goal, g, 1.0)
    assert r == 0.5 and psi == pytest.approx(math.atan2(y - 0.5, x))
    assert d == pytest.approx(math.hypot(x, y - 0.5))
    assert theta == pytest.approx(2 * math.pi - 0.5 * math.pi - psi) and theta > math.pi
    # right loop, centre (0, -0.5): the target at bearing pi/2, clockwise from psi
    r, psi, d, theta = loop_geometry(_spot_on_goal(1.0), goal, g, -1.0)
    assert psi == pytest.approx(math.atan2(y + 0.5, x))
    assert d == pytest.approx(math.hypot(x, y + 0.5))
    assert theta == pytest.approx(2 * math.pi - (0.5 * math.pi - psi))
    # 0.15 m short: the axle at x - 0.15 = -0.0075, just short of the target on the left loop
    _, psi, _, theta = loop_geometry(_spot_on_goal(1.0, -0.15), goal, g, 1.0)
    assert theta == pytest.approx(-0.5 * math.pi - math.atan2(y - 0.5, x - 0.15))
    assert 0.0 < theta < 0.05


def test_dribble_ball_loops_on_the_shorter_side_exact():
    # spot on the goal's at rest, heading 1.0 off, v_g = 0.3: the right loop (centre
    # (0, -0.5)), not the left one the heading error turns to. Its law: d = 0.774,
    # chi = psi - (pi/2 + atan((d - R) / R)), theta ~ 6.10 so v = v_max = 0.4,
    # omega = -v / R + k_alpha * (chi - phi) = -0.173; v rate limited to 0.06
    state = _spot_on_goal(1.0)
    action, ctx = _context([0, 0, 0, 0.3], ball=(0.31, 0.0), state=state)
    x, y, phi = state[:3]
    psi, d = math.atan2(y + 0.5, x), math.hypot(x, y + 0.5)
    chi = psi - (0.5 * math.pi + math.atan((d - 0.5) / 0.5))
    w = -0.4 / 0.5 + 2.0 * (chi - phi)
    assert w == pytest.approx(-0.173, abs=1e-3)
    np.testing.assert_allclose(_update(action, ctx), [0.06, w, ActionStatus.RUNNING, LOOP_RIGHT])
    # 0.15 m short of the target: the left loop (the turn towards phi_g)
    state = _spot_on_goal(1.0, -0.15)
    action, ctx = _context([0, 0, 0, 0.3], ball=(0.16, 0.0), state=state)
    assert _update(action, ctx)[3] == LOOP_LEFT


def test_dribble_ball_loops_when_stopped_short_of_the_target_speed():
    # on the target at rest, v_g = 0.3: the left loop's (0.3, 0.6), rate limited to
    # a_max * period = 0.06 and alpha_max * period = 0.3; the mode is kept
    action, ctx = _context([0, 0, 0, 0.3])
    np.testing.assert_allclose(_update(action, ctx), [0.06, 0.3, ActionStatus.RUNNING, LOOP_LEFT])
    # the same target at 0.05 m/s is met at rest: succeeded, no loop
    action, ctx = _context([0, 0, 0, 0.05])
    np.testing.assert_allclose(_update(action, ctx), [0.0, 0.0, ActionStatus.SUCCEEDED, APPROACH])


def test_dribble_ball_pivot_mode_exact():
    # spot on the goal's, heading 0.8 off: the spot law turns in place towards phi_g
    # (k_alpha * 0.8 * omega_max clipped to omega_in_place, rate limited to alpha_max * 0.1),
    # as PIVOT_TURN since session 37 (the turn arrives)
    state = _spot_on_goal(0.8)
    action, ctx = _context([0, 0, 0, 0], ball=(0.31, 0.0), state=state)
    np.testing.assert_allclose(_update(action, ctx), [0.0, 0.3, ActionStatus.RUNNING, PIVOT_TURN])
    # 1.0 off: pivot; the axle (0.142, 0.261) is driven to (0, 0), turning first to face
    # it: 1.07 rad to the right, omega_in_place (rate limited to -0.3), no forward speed
    state = _spot_on_goal(1.0)
    action, ctx = _context([0, 0, 0, 0], ball=(0.31, 0.0), state=state)
    np.testing.assert_allclose(_update(action, ctx), [0.0, -0.3, ActionStatus.RUNNING, PIVOT])
    assert action.get_status_output_port().Eval(ctx) == ActionStatus.RUNNING
    # the mode is kept in the discrete state: a pivot 0.5 m out goes on, 0.9 m out ends
    for offset, mode in ((0.5, PIVOT), (0.9, APPROACH)):
        state = _spot_on_goal(0.0, offset)
        spot = [state[0] + 0.31, state[1]]
        action, ctx = _context([0, 0, 0, 0], ball=spot, state=state)
        ctx.SetDiscreteState(0, [0.0, 0.0, ActionStatus.RUNNING, PIVOT, 0.0])
        assert _update(action, ctx)[3] == mode


def test_dribble_ball_bad_targets_fail_without_motion():
    for target, ball in (([5.0, 0, 0, 0], (0.31, 0)), ([np.nan, 0, 0, 0], (0.31, 0))):
        action, ctx = _context(target, ball=ball)
        np.testing.assert_allclose(_update(action, ctx), [0.0, 0.0, ActionStatus.FAILED, APPROACH])
    action, ctx = _context([1, 0, 0, 0], ball=(np.nan, 0))
    assert _update(action, ctx)[2] == ActionStatus.FAILED


def test_dribble_ball_bad_construction():
    with pytest.raises(RepertoireError, match="unknown DribbleBall gain 'speed'"):
        DribbleBall(gains={"speed": 1.0})
    with pytest.raises(RepertoireError, match="lost_distance must be > 0"):
        DribbleBall(gains={"lost_distance": 0.0})
    with pytest.raises(RepertoireError, match="lost_lateral must be > 0"):
        DribbleBall(gains={"lost_lateral": -0.1})
    with pytest.raises(RepertoireError, match="period"):
        DribbleBall(period=0.0)
    with pytest.raises(RepertoireError, match="workspace"):
        DribbleBall(workspace=(0, 1, 1, 0))


def test_rolling_resistance_force_and_port():
    diagram = build_soccer_dribble(DribbleScenario())
    drag = diagram.GetSubsystemByName("ball_rolling_resistance")
    plant = diagram.GetSubsystemByName("plant")
    m = plant.GetBodyByName("ball").default_mass()
    np.testing.assert_allclose(drag.force([1.0, 0.0]), [-m * 0.8, 0.0])
    np.testing.assert_allclose(drag.force([0.01, 0.0]), [-m * 0.8 * 0.01 / 0.05, 0.0])
    ctx = drag.CreateDefaultContext()
    x = np.zeros(plant.num_positions() + plant.num_velocities())
    ball = plant.GetBodyByName("ball")
    x[plant.num_positions() + ball.floating_velocities_start_in_v() + 4] = 2.0  # vy
    drag.get_input_port().FixValue(ctx, x)
    (f,) = drag.get_output_port().Eval(ctx)
    assert f.body_index == ball.index()
    np.testing.assert_allclose(f.F_Bq_W.translational(), [0.0, -m * 0.8, 0.0])
    x[plant.num_positions() + ball.floating_velocities_start_in_v() + 3] = -0.03  # vx, slow
    x[plant.num_positions() + ball.floating_velocities_start_in_v() + 4] = 0.0
    drag.get_input_port().FixValue(ctx, x)
    (g,) = drag.get_output_port().Eval(ctx)
    np.testing.assert_allclose(g.F_Bq_W.translational(), [m * 0.8 * 0.03 / 0.05, 0.0, 0.0])
    np.testing.assert_allclose(f.F_Bq_W.translational(), [0.0, -m * 0.8, 0.0])  # unchanged
    with pytest.raises(RepertoireError, match="decel"):
        RollingResistance(plant, decel=-1.0)
    with pytest.raises(RepertoireError, match="not a floating base body"):
        RollingResistance(plant, body_name="left_wheel")


def test_soccer_dribble_delivers_the_ball():
    diagram = build_soccer_dribble(DribbleScenario())
    sim = Simulator(diagram)
    ctx = sim.get_mutable_context()
    sim.AdvanceTo(8.0)
    assert dribble_status(diagram, ctx) == ActionStatus.SUCCEEDED
    figures = check_dribble(diagram, ctx)
    assert figures["position_error_m"] < 0.15 and figures["ball_from_held_spot_m"] < 0.1
    assert (figures["status_succeeded"], figures["still_running"]) == (1.0, 0.0)
    # a ball out of reach, or a target off the field: reported failed, nothing crashes
    for scenario in (
        DribbleScenario(ball_offset=[0.6, 0.0]),
        DribbleScenario(target=[3.5, 0.0, 0.0, 0.0]),
    ):
        diagram = build_soccer_dribble(scenario)
        sim = Simulator(diagram)
        sim.AdvanceTo(0.5)
        assert dribble_status(diagram, sim.get_context()) == ActionStatus.FAILED
        figures = check_dribble(diagram, sim.get_context())
        assert (figures["status_succeeded"], figures["still_running"]) == (0.0, 0.0)


def test_soccer_dribble_meets_a_target_speed_through_a_loop():
    """Target heading 1.5 rad at 0.3 m/s: it timed out pivoting at rest before.

    This is the registered world ``soccer_dribble_loop`` that ``make demo`` shows.
    """
    scenario = DribbleLoopScenario()
    assert scenario.target == [0.6, 0.5, 1.5, 0.3]
    diagram = build_registered("soccer_dribble_loop", scenario=scenario)
    assert diagram.get_name() == "soccer_dribble_loop"
    action = diagram.GetSubsystemByName("dribble_ball")
    sim = Simulator(diagram)
    ctx = sim.get_mutable_context()
    t, modes = 0.0, set()
    while dribble_status(diagram, ctx) == ActionStatus.RUNNING and t < 15.0:
        t += 0.1
        sim.AdvanceTo(t)
        modes.add(int(action.GetMyContextFromRoot(ctx).get_discrete_state(0).get_value()[3]))
    assert dribble_status(diagram, ctx) == ActionStatus.SUCCEEDED
    assert LOOP_LEFT in modes and PIVOT not in modes
    assert check_dribble(diagram, ctx)["ball_from_held_spot_m"] < 0.1


def test_dribble_episodes_loop_on_the_shorter_side():
    """The dribble study's sampling with v_g in [0.2, 0.4]: seeds 28 and 274 timed out.

    Both reached the goal with the heading 0.8-1.3 rad off and looped to the side that
    turns towards phi_g: seed 28 swung wide of its circle and pushed the ball into a
    goal post until the timeout. On the other side both succeed (14.3 s and 12.0 s).
    """
    from repertoire.studies.actions_dribble import DribbleEpisodesConfig, run_episode

    config = DribbleEpisodesConfig(v_g_range=[0.2, 0.4], n_states=0)
    for seed in (28, 274):
        assert run_episode(config, seed).status == "SUCCEEDED"


def test_dribble_scenario_rejects_bad_fields():
    with pytest.raises(ScenarioError, match="inside the robot"):
        build_soccer_dribble(DribbleScenario(ball_offset=[0.2, 0.0]))
    with pytest.raises(ScenarioError, match="target"):
        build_soccer_dribble(DribbleScenario(target=[0, 0, 0]))
    with pytest.raises(ScenarioError, match="unknown gains"):
        build_soccer_dribble(DribbleScenario(gains={"nope": 1.0}))
    with pytest.raises(ScenarioError, match="ball_decel"):
        build_soccer_dribble(DribbleScenario(ball_decel=-1.0))


def test_dribble_sampling_is_seeded_and_in_range():
    from repertoire.studies.actions_dribble import DribbleEpisodesConfig, sample_parameters

    c = DribbleEpisodesConfig()
    assert sample_parameters(c, 3) == sample_parameters(c, 3) != sample_parameters(c, 4)
    for seed in range(50):
        start, goal = sample_parameters(c, seed)
        d = math.hypot(goal[0] - start[0], goal[1] - start[1])
        assert c.goal_distance_range[0] - 1e-9 <= d <= c.goal_distance_range[1] + 1e-9
        assert -2.5 <= goal[0] <= 2.5 and -1.5 <= goal[1] <= 1.5
        direction = math.atan2(goal[1] - start[1], goal[0] - start[0])
        assert abs(math.remainder(goal[2] - direction, 2 * math.pi)) <= c.goal_heading_spread
    # starts up to the field's edge: the robot and the ball ahead of it stay out of the goals
    from repertoire.diagrams.soccer import clear_of_goals

    edge = DribbleEpisodesConfig(x_range=[2.6, 3.0], y_range=[-0.9, 0.9])
    edge.validate()
    for seed in range(40):
        (x, y, phi, _), _ = sample_parameters(edge, seed)
        ball = (x + 0.31 * math.cos(phi), y + 0.31 * math.sin(phi))
        assert clear_of_goals(x, y) and clear_of_goals(*ball)
    with pytest.raises(RepertoireError, match="x_range must lie on the field"):
        DribbleEpisodesConfig(x_range=[-4.0, 0.0]).validate()
    with pytest.raises(RepertoireError, match="goal_heading_spread"):
        DribbleEpisodesConfig(goal_heading_spread=4.0).validate()


def test_dribble_study_smoke_and_summary(tmp_path):
    from repertoire.studies.actions_dribble import (
        FEATURE_FUNCS,
        DribbleEpisodesConfig,
        DribbleRecord,
        smoke_config,
        summarize,
    )
    from repertoire.studies.engine import load_records, run_study

    result = run_study(
        "actions_dribble",
        smoke_config(),
        episodes=2,
        executor="inline",
        store=tmp_path / "s.sqlite",
        out_dir=tmp_path,
        fresh=True,
    )
    _, records = load_records(tmp_path / "s.sqlite", "actions_dribble")
    for rec in records.values():
        assert rec.duration > 0 and len(rec.states) == 6 * smoke_config().n_states
        assert rec.failed == (rec.status != "SUCCEEDED")
        assert rec.lost_ball == (rec.status == "FAILED")
        # the ball starts held: 0.31 m ahead of the axle
        assert math.hypot(rec.x_ball - rec.x, rec.y_ball - rec.y) == pytest.approx(0.31)
    assert "at least 27" in result.figures["tables"].read_text()
    # synthetic records with a known duration law: the row, the loss tree and the figures
    rng = np.random.default_rng(0)
    recs = []
    for _ in range(160):
        x, y, phi = rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-3, 3)
        d = math.hypot(x - 1.5, y)
        lost = abs(math.remainder(math.atan2(-y, 1.5 - x) - phi, 2 * math.pi)) > 2.0
        recs.append(
            DribbleRecord(
                x, y, phi, 0.0, x, y, 1.5, 0.0, 0.0, 0.0, 1 + 2 * d,
                "FAILED" if lost else "SUCCEEDED", lost, lost, [], 0.0,
            )
        )  # fmt: skip
    paths = summarize(recs, DribbleEpisodesConfig(), tmp_path)
    text = paths["tables"].read_text()
    assert "| dribbleBall (soccer, sim), paper (Table 1) | 1000 (750) | 7.4 | 0.29 |" in text
    assert "predicted failure" in text
    assert paths["polar"].stat().st_size > 0 and paths["learning_curves"].stat().st_size > 0
    assert FEATURE_FUNCS["dist"](recs[0]) == pytest.approx(math.hypot(recs[0].x - 1.5, recs[0].y))


def test_reused_dribble_simulator_runs_as_a_new_one():
    first = DribbleScenario(initial_pose=[0.0, 0.0, 1.0], target=[1.0, 1.0, 0.0, 0.0])
    diagram, simulator = dribble_simulator(first)
    simulator.Initialize()
    simulator.AdvanceTo(1.0)
    second = DribbleScenario(initial_pose=[-1.0, 0.5, -0.5], target=[0.5, -0.5, 0.0, 0.0])
    reused, simulator = dribble_simulator(second)
    assert reused is diagram
    fresh = Simulator(build_soccer_dribble(second))
    for sim in (simulator, fresh):
        sim.Initialize()
        sim.AdvanceTo(1.0)
    states = [sim.get_context().get_discrete_state() for sim in (simulator, fresh)]
    for group in range(states[0].num_groups()):
        np.testing.assert_array_equal(states[0].value(group), states[1].value(group))
    target = reused.GetSubsystemByName("target")
    np.testing.assert_array_equal(
        target.get_output_port().Eval(target.GetMyContextFromRoot(simulator.get_context())),
        second.target,
    )


# Where the dribble study's seeds 92, 536 and 608 stood still until their timeout
# (session 33): PIVOT, the axle within position_tolerance of the goal's, the ball on
# a guide arm's front end ((0.447, +-0.12-0.14) m in the robot frame, held but off the
# bumper). The old law's in-place turn a * omega_pose and k_ball * gamma cancelled.
STALLS = {
    92: ([0.1293, -0.6584, 1.3596, 0.0], [0.1079, -0.196], [0.0838, -0.7381, 1.1301, 0.0003]),
    536: ([-0.7196, -1.5887, -1.3065, 0.0], [-0.4694, -1.9838], [-0.7088, -1.4982, -1.5807, 0.085]),
    608: ([-0.2641, 1.3789, 2.8974, 0.0], [-0.6679, 1.6051], [-0.1735, 1.3935, 3.1361, 0.0612]),
}


@pytest.mark.parametrize("seed", sorted(STALLS))
def test_dribble_control_closes_on_a_ball_off_the_bumper_at_rest(seed):
    g = dict(DRIBBLE_GAINS)
    state, ball, goal = STALLS[seed]
    assert approach_mode(PIVOT, state, goal, g) == PIVOT
    bx, by = ball_in_robot_frame(state, ball)
    gamma = math.atan2(by, bx)
    # the old law: (0, a * omega_pose + k_ball * gamma) with the two terms cancelling
    h = g["hold_distance"]
    assert 0.44 < bx < 0.45 and 0.11 < abs(by) < 0.14 and math.hypot(bx - h, by) > 0.05
    # now: at rest with the ball off the bumper the robot closes on it (close_control)
    v, w, held = dribble_control(state, ball, goal, g, 0.0)
    v_close = min(g["v_max"], math.sqrt(2.0 * g["a_max"] * (bx - h))) * math.cos(gamma) ** 2
    assert held
    assert v == pytest.approx(v_close, rel=1e-12) and v > 0.3
    w_max = min(g["omega_max"], max(g["omega_in_place"], v / g["min_turn_radius"]))
    assert w == pytest.approx(min(w_max, max(-w_max, g["k_ball"] * gamma)), rel=1e-12)
    assert abs(w) > 0.2


def test_dribble_control_turns_in_place_with_a_controlled_ball():
    # the axle on the goal's (a pivot turning in place, PIVOT_TURN), heading e off, the ball
    # 2 cm left of the held spot, controlled: the turn is a * omega_pose alone. The old
    # law's k_ball * gamma cancelled it at e* = -k_ball gamma / (a k_alpha omega_max), where
    # the held spot is not the goal's
    g = dict(DRIBBLE_GAINS)
    ball_rf = (g["hold_distance"] + 0.02, 0.02)
    gamma = math.atan2(ball_rf[1], ball_rf[0])
    a = math.cos(gamma) ** 2
    e_star = -g["k_ball"] * gamma / (a * g["k_alpha"] * g["omega_max"])
    phi = -e_star
    state = [0.0, 0.0, phi, 0.0]
    c, s = math.cos(phi), math.sin(phi)
    ball = [c * ball_rf[0] - s * ball_rf[1], s * ball_rf[0] + c * ball_rf[1]]
    goal = [0.0, 0.0, 0.0, 0.0]
    assert approach_mode(PIVOT, state, goal, g) == PIVOT_TURN
    v, w, held = mode_control(PIVOT_TURN, state, ball, goal, g)
    assert held and v == 0.0
    assert w == pytest.approx(a * g["k_alpha"] * e_star * g["omega_max"], rel=1e-12)
    assert w == pytest.approx(-g["k_ball"] * gamma, rel=1e-12)


def test_dribble_ball_leaves_the_standstill_exact():
    # the LeafSystem in PIVOT at seed 536's standstill: forward, rate limited to
    # a_max * 0.1 = 0.06 m/s, turning towards the ball at alpha_max * 0.1 = 0.3 rad/s
    state, ball, goal = STALLS[536]
    action, ctx = _context(goal, ball=ball, state=state)
    ctx.SetDiscreteState(0, [0.0, 0.0, ActionStatus.RUNNING, PIVOT, 0.0])
    np.testing.assert_allclose(_update(action, ctx), [0.06, 0.3, ActionStatus.RUNNING, PIVOT])
