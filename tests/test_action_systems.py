import math

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from repertoire.diagrams.simulate import build_registered
from repertoire.diagrams.soccer import (
    GoToPoseRunUpScenario,
    GoToPoseScenario,
    build_soccer_goto_pose,
    check_goto_pose,
    goto_status,
)
from repertoire.planning.action_models import (
    GOTO_POSE_FEATURES,
    UNMIRRORED_GOTO_POSE_FEATURES,
    fit_duration_tree,
    fit_failure_tree,
)
from repertoire.systems.action_model_predictor import (
    ActionModelPredictor,
    goto_pose_parameter_features,
)
from repertoire.systems.action_status import clip
from repertoire.systems.go_to_pose import (
    APPROACH,
    GOTO_GAINS,
    RUN_UP,
    ActionStatus,
    GoToPose,
    chassis_state,
    goto_mode,
    pose_control,
    run_up_control,
    run_up_distance,
    run_up_pose,
)

from repertoire.errors import RepertoireError, ScenarioError


def test_scalar_clip_matches_numpy():
    for x, lo, hi in ((0.5, -1.0, 1.0), (-3.0, -1.0, 1.0), (2.0, -1.0, 1.0), (1.0, 1.0, 1.0)):
        assert clip(x, lo, hi) == float(np.clip(x, lo, hi))
    assert clip(-3.0, -1.0, 1.0) == -1.0 and clip(2.0, -1.0, 1.0) == 1.0
    assert math.isnan(clip(float("nan"), -1.0, 1.0))


def test_pose_control_by_hand():
    g = dict(GOTO_GAINS)
    # goal straight ahead 1 m, same heading: v = k_rho * rho, no turn
    v, w, rho, he = pose_control([0, 0, 0, 0], [1, 0, 0, 0], g)
    assert (v, w, rho, he) == pytest.approx((0.8, 0.0, 1.0, 0.0))
    # goal to the left (alpha = pi/2): v = 0 (cos), omega saturates at omega_max
    v, w, _, _ = pose_control([0, 0, 0, 0], [0, 1, math.pi / 2, 0], g)
    assert v == pytest.approx(0.0, abs=1e-12) and w == pytest.approx(g["omega_max"])
    # at the goal position: turn in place towards the goal heading
    v, w, _, he = pose_control([0, 0, 0, 0], [0.01, 0, 0.1, 0], g)
    assert v == 0.0 and w == pytest.approx(0.3 * g["omega_max"]) and he == pytest.approx(0.1)


def _goto_context(target, state=(0, 0, 0, 0), time=0.0):
    goto = GoToPose(period=0.1)
    ctx = goto.CreateDefaultContext()
    goto.get_state_input_port().FixValue(ctx, np.array(state, dtype=float))
    goto.get_target_input_port().FixValue(ctx, np.array(target, dtype=float))
    ctx.SetTime(time)
    return goto, ctx


def test_goto_pose_rate_limits_and_status():
    goto, ctx = _goto_context([1, 0, 0, 0])
    xd = goto.EvalUniquePeriodicDiscreteUpdate(ctx).get_vector().get_value()[:-1]
    # v wants 0.8 but a_max * period = 0.1
    np.testing.assert_allclose(xd, [0.1, 0.0, ActionStatus.RUNNING, APPROACH])
    assert goto.get_status_output_port().Eval(ctx) == ActionStatus.RUNNING
    # at the goal: succeeded
    goto, ctx = _goto_context([0.01, 0, 0.05, 0])
    xd = goto.EvalUniquePeriodicDiscreteUpdate(ctx).get_vector().get_value()[:-1]
    assert xd[2] == ActionStatus.SUCCEEDED
    # past the timeout: timed out, zero command
    goto, ctx = _goto_context([1, 0, 0, 0], time=GOTO_GAINS["timeout"])
    xd = goto.EvalUniquePeriodicDiscreteUpdate(ctx).get_vector().get_value()[:-1]
    np.testing.assert_allclose(xd, [0.0, 0.0, ActionStatus.TIMED_OUT, APPROACH])


def test_goto_pose_inactive_keeps_running_and_tracks():
    # A plan's later action (active input 0) that is at its target, past its timeout or
    # given an off-field target stays RUNNING; its command is still the rate-limited one.
    cases = (
        ([0.01, 0, 0.05, 0], 0.0, [0.0, 3.0 * 0.05 * 2.5, ActionStatus.RUNNING, APPROACH]),
        ([1, 0, 0, 0], GOTO_GAINS["timeout"], [0.1, 0.0, ActionStatus.RUNNING, APPROACH]),
        ([5.0, 0, 0, 0], 0.0, [0.0, 0.0, ActionStatus.RUNNING, APPROACH]),
    )
    for target, time, expected in cases:
        goto, ctx = _goto_context(target, time=time)
        goto.get_active_input_port().FixValue(ctx, [0.0])
        assert not goto.is_active(ctx)
        xd = goto.EvalUniquePeriodicDiscreteUpdate(ctx).get_vector().get_value()[:-1]
        np.testing.assert_allclose(xd, expected, atol=1e-12)
        goto.get_active_input_port().FixValue(ctx, [1.0])  # started: as when unconnected
        xd = goto.EvalUniquePeriodicDiscreteUpdate(ctx).get_vector().get_value()[:-1]
        assert xd[2] != ActionStatus.RUNNING


def test_drive_actions_time_out_from_their_start():
    # A plan's later leg times out its own timeout after it started, not after the
    # simulation's start: the last state slot is the time of its last inactive update (0
    # for a lone action, which is active from the first update). Before, DribbleBall as a
    # plan's second leg had only what the first leg left of its timeout.
    from repertoire.systems.dribble_ball import DRIBBLE_GAINS, DribbleBall

    for action, timeout in ((GoToPose(period=0.1), GOTO_GAINS["timeout"]),
                            (DribbleBall(period=0.1), DRIBBLE_GAINS["timeout"])):  # fmt: skip
        ctx = action.CreateDefaultContext()
        for name, value in (("state", [0, 0, 0, 0]), ("target", [2, 0, 0, 0])):
            action.GetInputPort(name).FixValue(ctx, np.array(value, dtype=float))
        if isinstance(action, DribbleBall):
            action.get_ball_input_port().FixValue(ctx, [0.31, 0.0])

        def update(time, active, started, ctx=ctx, action=action):
            action.get_active_input_port().FixValue(ctx, [float(active)])
            ctx.SetTime(time)
            xd = ctx.get_mutable_discrete_state(0)
            xd.SetAtIndex(xd.size() - 1, started)
            out = action.EvalUniquePeriodicDiscreteUpdate(ctx).get_vector().get_value()
            return out[2], out[-1]

        assert action.CreateDefaultContext().get_discrete_state(0).get_value()[-1] == 0.0
        # not started: the slot follows the time
        assert update(7.0, 0, 0.0) == (ActionStatus.RUNNING, 7.0)
        # started at 7 s: the slot stays, the timeout falls at 7 s + timeout
        assert update(7.0 + timeout - 0.1, 1, 7.0) == (ActionStatus.RUNNING, 7.0)
        assert update(7.0 + timeout, 1, 7.0) == (ActionStatus.TIMED_OUT, 7.0)
        # a lone action (started at 0): at its timeout after the simulation's start
        assert update(timeout - 0.1, 1, 0.0) == (ActionStatus.RUNNING, 0.0)
        assert update(timeout, 1, 0.0) == (ActionStatus.TIMED_OUT, 0.0)


def test_run_up_geometry_by_hand():
    g = dict(GOTO_GAINS)
    # d = v_g^2 / a_max + 2 position_tolerance = 0.16 + 0.1
    assert run_up_distance(0.4, g) == pytest.approx(0.26)
    pose = run_up_pose([1.0, 2.0, math.pi / 2, 0.4], g)
    np.testing.assert_allclose(pose, [1.0, 1.74, math.pi / 2, 0.0], atol=1e-12)


def test_goto_mode_by_hand():
    g = dict(GOTO_GAINS)
    target = [0, 0, 0, 0.4]
    # within the position tolerance at rest, a target speed a stopped robot misses: run up
    assert goto_mode(APPROACH, [0.01, 0, 0, 0.0], target, g) == RUN_UP
    assert goto_mode(APPROACH, [0.01, 0, 0, -0.3], target, g) == RUN_UP  # reversing in
    # within it at about the target speed (drive_step succeeds), or outside it: approach
    assert goto_mode(APPROACH, [0.01, 0, 0, 0.35], target, g) == APPROACH
    assert goto_mode(APPROACH, [-0.5, 0, 0, 0.0], target, g) == APPROACH
    # a target speed a stopped robot meets (|v_g| < 0.1 m/s) never needs a run-up
    for mode in (APPROACH, RUN_UP):
        assert goto_mode(mode, [0.01, 0, 0, 0.0], [0, 0, 0, 0.09], g) == APPROACH
    # the run-up lasts until the run-up pose (0.26 m back) is reached, aligned
    assert goto_mode(RUN_UP, [-0.1, 0, 0, 0.0], target, g) == RUN_UP
    assert goto_mode(RUN_UP, [-0.22, 0, 0.1, 0.0], target, g) == APPROACH
    assert goto_mode(RUN_UP, [-0.26, 0, 0.2, 0.0], target, g) == RUN_UP  # heading off > 0.15


def test_run_up_control_by_hand():
    g = dict(GOTO_GAINS)
    # straight behind with the same heading (the polar law's singular case): back onto it
    v, w = run_up_control([0, 0, 0, 0], [-0.5, 0, 0, 0], g)
    assert v == pytest.approx(-0.8 * 0.5) and w == pytest.approx(0.0, abs=1e-12)
    # behind, 0.1 rad off the backward line: back onto it while steering
    v, w = run_up_control([0, 0, 0, 0], [-math.cos(0.1), -math.sin(0.1), 0, 0], g)
    assert (v, w) == pytest.approx((-0.8 * math.cos(0.1), 0.3))
    # ahead, 0.1 rad off: drive while steering
    v, w = run_up_control([0, 0, 0, 0], [math.cos(0.1), math.sin(0.1), 0, 0], g)
    assert (v, w) == pytest.approx((0.8 * math.cos(0.1), 0.3))
    # to the left (more than RUN_UP_AIM_RAD off either way): turn in place first
    assert run_up_control([0, 0, 0, 0], [0, 1, 0, 0], g) == (0.0, g["omega_max"])
    # within the position tolerance: turn in place to the pose's heading
    v, w = run_up_control([0, 0, 0, 0], [0.01, 0, 0.1, 0], g)
    assert v == 0.0 and w == pytest.approx(0.3)
    # without reverse (DribbleBall's pivot): a pose behind is faced, never backed onto
    assert run_up_control([0, 0, 0, 0], [-0.5, 0, 0, 0], g, reverse=False) == (0.0, 2.5)
    v, w = run_up_control([0, 0, 0, 0], [-math.cos(0.1), -math.sin(0.1), 0, 0], g, False)
    assert (v, w) == (0.0, -g["omega_max"])
    # ahead it drives as with reverse
    v, w = run_up_control([0, 0, 0, 0], [math.cos(0.1), math.sin(0.1), 0, 0], g, reverse=False)
    assert (v, w) == pytest.approx((0.8 * math.cos(0.1), 0.3))


def test_goto_pose_runs_up_when_stopped_short_of_the_target_speed():
    # At the target position at rest, target speed 0.4 m/s: the polar law alone holds the
    # robot there (v = 0) until its timeout. It runs up instead: backing onto the run-up
    # pose 0.26 m behind, rate limited (a_max * period = 0.1).
    goto, ctx = _goto_context([0.01, 0, 0, 0.4])
    xd = goto.EvalUniquePeriodicDiscreteUpdate(ctx).get_vector().get_value()[:-1]
    np.testing.assert_allclose(xd, [-0.1, 0.0, ActionStatus.RUNNING, RUN_UP], atol=1e-12)
    # the same target at 0.05 m/s is met at rest: succeeded, no run-up
    goto, ctx = _goto_context([0.01, 0, 0, 0.05])
    xd = goto.EvalUniquePeriodicDiscreteUpdate(ctx).get_vector().get_value()[:-1]
    np.testing.assert_allclose(xd, [0.0, 0.0, ActionStatus.SUCCEEDED, APPROACH])


def test_soccer_goto_pose_reaches_a_target_speed_behind_it():
    """Target 1 m behind, facing away, 0.4 m/s: it timed out at rest on the target before.

    This is the registered world ``soccer_goto_pose_run_up`` that ``make demo`` shows.
    """
    scenario = GoToPoseRunUpScenario()
    assert scenario.initial_pose == [0.0, 0.0, 0.0] and scenario.target == [-1.0, 0.0, 0.0, 0.4]
    diagram = build_registered("soccer_goto_pose_run_up", scenario=scenario)
    assert diagram.get_name() == "soccer_goto_pose_run_up"
    sim = Simulator(diagram)
    ctx = sim.get_mutable_context()
    t = 0.0
    while goto_status(diagram, ctx) == ActionStatus.RUNNING and t < 12.0:
        t += 0.05
        sim.AdvanceTo(t)
    assert goto_status(diagram, ctx) == ActionStatus.SUCCEEDED
    figures = check_goto_pose(diagram, ctx)
    assert figures["position_error_m"] < 0.1 and figures["heading_error_rad"] < 0.2
    assert (figures["status_succeeded"], figures["still_running"]) == (1.0, 0.0)
    # at the start the action has not ended: still running, not (yet) succeeded
    figures = check_goto_pose(diagram, diagram.CreateDefaultContext())
    assert (figures["status_succeeded"], figures["still_running"]) == (0.0, 1.0)


def test_goto_pose_target_off_field_fails_without_motion():
    goto, ctx = _goto_context([5.0, 0, 0, 0])
    xd = goto.EvalUniquePeriodicDiscreteUpdate(ctx).get_vector().get_value()[:-1]
    np.testing.assert_allclose(xd, [0.0, 0.0, ActionStatus.FAILED, APPROACH])
    goto, ctx = _goto_context([np.nan, 0, 0, 0])
    xd = goto.EvalUniquePeriodicDiscreteUpdate(ctx).get_vector().get_value()[:-1]
    assert xd[2] == ActionStatus.FAILED


def test_goto_pose_bad_construction():
    with pytest.raises(RepertoireError, match="unknown GoToPose gain"):
        GoToPose(gains={"speed": 1.0})
    with pytest.raises(RepertoireError, match="v_max must be > 0"):
        GoToPose(gains={"v_max": 0.0})
    with pytest.raises(RepertoireError, match="workspace"):
        GoToPose(workspace=(1, 0, 0, 1))
    # A heading tolerance <= 0 could never be met (|error| < tol): the action ran to its
    # timeout instead of refusing the gain, as DribbleBall already did.
    for bad in (-0.1, 0.0):
        with pytest.raises(RepertoireError, match=f"heading_tolerance must be > 0, got {bad}"):
            GoToPose(gains={"heading_tolerance": bad})
    # k_rho <= 0: a robot asked to arrive at rest never moved (timed out at 20 s);
    # k_alpha <= 0: it arrived and turned away from the goal heading until its timeout
    for name in ("k_rho", "k_alpha"):
        with pytest.raises(RepertoireError, match=f"GoToPose gain {name} must be > 0, got -1.0"):
            GoToPose(gains={name: -1.0})
    with pytest.raises(RepertoireError, match="k_rho must be > 0, got 0.0"):
        build_soccer_goto_pose(GoToPoseScenario(gains={"k_rho": 0.0}))


def test_chassis_state_by_hand():
    yaw = 0.7
    q = [math.cos(yaw / 2), 0, 0, math.sin(yaw / 2), 1.0, 2.0, 0.1]
    v = [0, 0, 0.3, 0.5 * math.cos(yaw), 0.5 * math.sin(yaw), 0]
    np.testing.assert_allclose(chassis_state(q, v), [1.0, 2.0, yaw, 0.5])


def test_soccer_goto_pose_reaches_its_pose():
    diagram = build_soccer_goto_pose(GoToPoseScenario(time_step=1e-2))
    sim = Simulator(diagram)
    ctx = sim.get_mutable_context()
    sim.AdvanceTo(7.0)
    figures = check_goto_pose(diagram, ctx)
    assert goto_status(diagram, ctx) == ActionStatus.SUCCEEDED
    assert figures["position_error_m"] < 0.1
    with pytest.raises(ScenarioError, match="target"):
        build_soccer_goto_pose(GoToPoseScenario(target=[0, 0, 0]))
    # the footprint disc (0.32 m) on a post (radius 0.05 m) or a net: refused, named
    for target in ([3.0, 0.75, 0.0, 0.0], [2.75, 0.5, 0.0, 0.0], [-3.1, 0.0, 0.0, 0.0]):
        with pytest.raises(ScenarioError, match=r"target \[.*\] puts the robot .* goal post"):
            build_soccer_goto_pose(GoToPoseScenario(target=target))
    # 0.37 m from the post's centre is clear
    build_soccer_goto_pose(GoToPoseScenario(target=[3.0, 0.75 - 0.371, 0.0, 0.0]))
    with pytest.raises(ScenarioError, match=r"target \[0.0, 2.2, 0.0, 0.0\] lies off the field"):
        build_soccer_goto_pose(GoToPoseScenario(target=[0.0, 2.2, 0.0, 0.0]))


def test_predictor_exact_outputs():
    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 1, (200, 2))
    dur = fit_duration_tree(X, 2 + X[:, 0], ["a", "b"])
    fail = fit_failure_tree(X, X[:, 1] > 0.5, ["a", "b"])
    p = ActionModelPredictor(dur, fail, 2)
    ctx = p.CreateDefaultContext()
    p.get_input_port().FixValue(ctx, [0.5, 0.9])
    assert p.GetOutputPort("duration").Eval(ctx)[0] == pytest.approx(2.5, abs=1e-6)
    assert p.GetOutputPort("success").Eval(ctx)[0] == 0.0
    assert p.GetOutputPort("out_of_range").Eval(ctx)[0] == 0.0
    p.get_input_port().FixValue(ctx, [1.5, -0.9])
    # beyond the data the leaf's hyperplane (3.5) is clamped to its episodes' longest
    # duration, 2 + the largest a among them, and out_of_range says so
    leaf = dur.leaves[dur.leaf_index([[1.5, -0.9]])[0]]
    in_leaf = dur.leaf_index(X) == dur.leaf_index([[1.5, -0.9]])[0]
    assert leaf.target_max == pytest.approx(2 + X[in_leaf, 0].max(), abs=1e-12)
    assert leaf.target_max < 3.5
    assert p.GetOutputPort("duration").Eval(ctx)[0] == leaf.target_max
    assert p.GetOutputPort("success").Eval(ctx)[0] == 1.0
    assert p.GetOutputPort("out_of_range").Eval(ctx)[0] == 1.0
    with pytest.raises(RepertoireError, match="duration tree and a failure tree"):
        ActionModelPredictor(fail, dur, 2)
    with pytest.raises(RepertoireError, match="num_parameters"):
        ActionModelPredictor(dur, fail, 3)


def test_goto_parameter_features():
    f = goto_pose_parameter_features(np.array([0, 0, 0, 0.2, 3, 4, 0, 0.1]))
    assert f[0] == pytest.approx(5.0) and f[3] == 0.2 and f[4] == 0.1
    with pytest.raises(RepertoireError, match="8 values"):
        goto_pose_parameter_features(np.zeros(7))


def test_predictor_refuses_a_feature_function_named_for_other_features():
    """The mirrored Table 7 features fed to models fitted on the un-mirrored columns."""
    rng = np.random.default_rng(1)
    X = rng.uniform(-1, 1, (60, 5))
    for names, ok in ((GOTO_POSE_FEATURES, True), (UNMIRRORED_GOTO_POSE_FEATURES, False)):
        dur = fit_duration_tree(X, 2 + X[:, 0], list(names))
        fail = fit_failure_tree(X, X[:, 1] > 0.5, list(names))
        if ok:
            p = ActionModelPredictor(dur, fail, 8, goto_pose_parameter_features)
            ctx = p.CreateDefaultContext()
            p.get_input_port().FixValue(ctx, [0, 0, 0, 0.2, 0.3, 0.4, 0, 0.1])
            want = dur.predict(goto_pose_parameter_features(np.array(
                [0, 0, 0, 0.2, 0.3, 0.4, 0, 0.1]))[None, :])[0]  # fmt: skip
            assert p.GetOutputPort("duration").Eval(ctx)[0] == want
        else:
            with pytest.raises(RepertoireError, match="angle_to_unmirrored"):
                ActionModelPredictor(dur, fail, 8, goto_pose_parameter_features)
