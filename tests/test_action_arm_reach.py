import math

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from repertoire.diagrams.arm_reach import (
    ReachScenario,
    build_arm_reach,
    check_reach,
    reach_status,
    set_start_velocity,
)
from repertoire.planning.action_models import arm_reach_features
from repertoire.systems.arm_reach import (
    REACH_GAINS,
    Reach,
    limit_acceleration,
    reach_velocity,
)
from repertoire.systems.go_to_pose import ActionStatus

from repertoire.errors import RepertoireError, ScenarioError


def test_arm_reach_features_by_hand():
    # offset (1, 1): dist sqrt 2, direction 45 deg; velocity along it; goal velocity -y
    f = arm_reach_features([0, 0.5, 0, 0.5], [1, 0, 1, -1])
    np.testing.assert_allclose(f, [math.sqrt(2), 0.0, -3 * math.pi / 4, math.sqrt(0.5), 1.0])
    # offset (0, 2): direction 90 deg; velocity along +a (0 deg) -> angle_1 = 90 deg;
    # zero goal velocity points along a (atan2(0, 0) = 0) -> angle_2 = -90 deg
    f = arm_reach_features([1, 0.3, 0, 0], [1, 0, 2, 0])
    np.testing.assert_allclose(f, [2.0, math.pi / 2, -math.pi / 2, 0.3, 0.0])
    # wrapping: direction 180 deg, velocity -90 deg -> 270 deg wraps to -90 deg
    f = arm_reach_features([0, 0, 0, -1], [-1, 0, 0, 0])
    assert f[1] == pytest.approx(-math.pi / 2)
    batch = arm_reach_features(np.zeros((3, 4)), np.tile([1.0, 0, 0, 0], (3, 1)))
    assert batch.shape == (3, 5)
    with pytest.raises(RepertoireError, match="finite"):
        arm_reach_features([np.nan, 0, 0, 0], [1, 0, 0, 0])
    with pytest.raises(RepertoireError, match="4 values"):
        arm_reach_features([0, 0, 0], [1, 0, 0, 0])


def test_reach_velocity_and_limit_by_hand():
    g = dict(REACH_GAINS)
    # 2 rad away along a: speed k * 2 = 6 clipped to v_max
    np.testing.assert_allclose(reach_velocity([0, 0], [2, 0, 0, 0], g), [g["v_max"], 0])
    # 0.1 rad away along b with goal speed 0.5: max(0.5, k * 0.1 = 0.3) = 0.5
    np.testing.assert_allclose(reach_velocity([0, 0], [0, 0.3, 0.1, 0.4], g), [0, 0.5])
    np.testing.assert_allclose(reach_velocity([1, 1], [1, 0, 1, 0], g), [0, 0])
    np.testing.assert_allclose(limit_acceleration([0, 0], [3, 4], 0.5), [0.3, 0.4])
    np.testing.assert_allclose(limit_acceleration([0, 0], [0.3, 0.4], 0.5), [0.3, 0.4])


def test_reach_velocity_coasts_away_until_there_is_room_to_run_up_to_the_goal_speed():
    g = dict(REACH_GAINS)  # a_max 2: a run-up to s = 1 needs s^2 / (2 a_max) = 0.25 rad
    goal = [1.0, 0.6, 1.0, 0.8]  # goal speed 1.0
    # 0.05 rad past the goal along a, moving away at 0.5: braking now turns it
    # 0.05 + 0.25 / 4 = 0.1125 rad out, too close: it keeps its velocity exactly
    away = np.array([0.5, 0.0])
    np.testing.assert_array_equal(reach_velocity([1.05, 1.0], goal, g, away), away)
    # 0.2 rad past at 0.5: 0.2625 rad >= 0.25, so back towards the goal at v_max
    np.testing.assert_allclose(reach_velocity([1.2, 1.0], goal, g, away), [-1.0, 0.0])
    # moving towards the goal: the old law, whatever the room
    np.testing.assert_allclose(reach_velocity([1.05, 1.0], goal, g, -away), [-1.0, 0.0])
    # a goal faster than v_max runs up to v_max only: 0.2 + 0.0625 >= 1 / 4
    fast = [1.0, 0.9, 1.0, 0.7]
    np.testing.assert_allclose(reach_velocity([1.2, 1.0], fast, g, away), [-1.0, 0.0])
    # a slow goal (0.3 rad/s: 0.0225 rad of run-up) never coasts past 0.05 rad
    slow = [1.0, 0.3, 1.0, 0.0]
    np.testing.assert_allclose(reach_velocity([1.05, 1.0], slow, g, away), [-0.3, 0.0])


def test_reach_episode_that_cycled_through_its_goal_succeeds():
    """Seed 9106 of speed_range -1.5 to 1.5 (goal speed 1.067 rad/s): it passed its goal
    at 0.6-0.7 rad/s again and again, braking and running back at a_max, and timed out
    after 10 s; with a run-up it succeeds."""
    from repertoire.studies.actions_arm_reach import ReachEpisodesConfig, run_episode

    record = run_episode(ReachEpisodesConfig(speed_range=[-1.5, 1.5]), 9106)
    assert np.hypot(record.thetadot_g_a, record.thetadot_g_b) == pytest.approx(1.067, abs=1e-3)
    assert record.status == "SUCCEEDED" and not record.failed
    assert record.duration < 4.0


def _context(target, state=(0, 0, 0, 0), time=0.0):
    reach = Reach(period=0.1, initial_state=state)
    ctx = reach.CreateDefaultContext()
    reach.get_state_input_port().FixValue(ctx, np.array(state, dtype=float))
    reach.get_target_input_port().FixValue(ctx, np.array(target, dtype=float))
    ctx.SetTime(time)
    return reach, ctx


def _update(reach, ctx):
    return reach.EvalUniquePeriodicDiscreteUpdate(ctx).get_vector().get_value()


def test_reach_exact_updates_and_statuses():
    # 1 rad away along a, from rest at 0.5 rad: v_ref = a_max * period = 0.2, q_ref += 0.02
    reach, ctx = _context([1.5, 0, 0, 0], state=(0.5, 0, 0, 0))
    np.testing.assert_allclose(
        reach.get_desired_state_output_port().Eval(ctx), [0.5, 0.0, 0.0, 0.0]
    )
    np.testing.assert_allclose(_update(reach, ctx), [0.52, 0.0, 0.2, 0.0, ActionStatus.RUNNING])
    assert reach.get_status_output_port().Eval(ctx) == ActionStatus.RUNNING
    # within 0.03 rad and at the goal speed: succeeded
    reach, ctx = _context([0.51, 0.2, 0.01, 0.0], state=(0.5, 0.25, 0, 0))
    assert _update(reach, ctx)[4] == ActionStatus.SUCCEEDED
    # right position, wrong speed: still running
    reach, ctx = _context([0.5, 1.0, 0.0, 0.0], state=(0.5, 0.0, 0, 0))
    assert _update(reach, ctx)[4] == ActionStatus.RUNNING
    reach, ctx = _context([1.5, 0, 0, 0], state=(0.5, 0, 0, 0), time=REACH_GAINS["timeout"])
    np.testing.assert_allclose(_update(reach, ctx), [0.5, 0, 0, 0, ActionStatus.TIMED_OUT])


def test_reach_target_outside_joint_limits_fails_without_motion():
    for target in ([3.0, 0, 1, 0], [0.5, 0, -0.5, 0], [np.nan, 0, 1, 0]):
        reach, ctx = _context(target, state=(0.5, 0, 1.0, 0))
        np.testing.assert_allclose(_update(reach, ctx), [0.5, 1.0, 0, 0, ActionStatus.FAILED])


def test_reach_target_faster_than_it_can_move_fails_without_motion():
    # v_max 1.0 + speed_tolerance 0.15: |thetadot_g| = hypot(0.9, 0.7) = 1.140 runs,
    # hypot(0.9, 0.72) = 1.1526 fails at once (it timed out after 10 s before).
    reach, ctx = _context([1.5, 0.9, 1.0, 0.7], state=(0.5, 0, 1.0, 0))
    assert _update(reach, ctx)[4] == ActionStatus.RUNNING
    reach, ctx = _context([1.5, 0.9, 1.0, 0.72], state=(0.5, 0, 1.0, 0))
    np.testing.assert_allclose(_update(reach, ctx), [0.5, 1.0, 0, 0, ActionStatus.FAILED])


def test_reach_bad_construction():
    with pytest.raises(RepertoireError, match="unknown Reach gain 'speed'"):
        Reach(gains={"speed": 1.0})
    with pytest.raises(RepertoireError, match="v_max must be finite and > 0"):
        Reach(gains={"v_max": 0.0})
    with pytest.raises(RepertoireError, match="joint_limits"):
        Reach(joint_limits=(1, 0, 0, 1))
    with pytest.raises(RepertoireError, match="initial_state"):
        Reach(initial_state=(0, 0, 0))


def test_arm_reach_world_reaches_and_reports():
    diagram = build_arm_reach(ReachScenario(time_step=5e-3))
    sim = Simulator(diagram)
    ctx = sim.get_mutable_context()
    set_start_velocity(diagram, ctx, 0.2, -0.2)
    sim.AdvanceTo(2.5)
    assert reach_status(diagram, ctx) == ActionStatus.SUCCEEDED
    assert check_reach(diagram, ctx)["joint_error_rad"] < 0.05
    # a target beyond the elbow's limit: reported failed, nothing crashes
    diagram = build_arm_reach(ReachScenario(target=[1.0, 0, 3.0, 0], time_step=5e-3))
    sim = Simulator(diagram)
    sim.AdvanceTo(0.1)
    assert reach_status(diagram, sim.get_context()) == ActionStatus.FAILED
    with pytest.raises(ScenarioError, match="start angles"):
        build_arm_reach(ReachScenario(start=[3.5, 0, 1, 0]))
    with pytest.raises(ScenarioError, match="unknown gains"):
        build_arm_reach(ReachScenario(gains={"nope": 1.0}))


def test_reach_study_sampling_smoke_and_summary(tmp_path):
    from repertoire.studies.actions_arm_reach import (
        FEATURE_FUNCS,
        ReachEpisodesConfig,
        ReachRecord,
        sample_parameters,
        smoke_config,
        summarize,
    )
    from repertoire.studies.engine import load_records, run_study

    c = ReachEpisodesConfig()
    assert sample_parameters(c, 5) == sample_parameters(c, 5) != sample_parameters(c, 6)
    for seed in range(30):
        for p in sample_parameters(c, seed):
            assert c.theta_a_range[0] <= p[0] <= c.theta_a_range[1]
            assert c.theta_b_range[0] <= p[2] <= c.theta_b_range[1]
            assert c.speed_range[0] <= p[1] <= c.speed_range[1]
    with pytest.raises(RepertoireError, match="joint limits"):
        ReachEpisodesConfig(theta_b_range=[-0.5, 1.0]).validate()
    result = run_study(
        "actions_arm_reach",
        smoke_config(),
        episodes=2,
        executor="inline",
        store=tmp_path / "s.sqlite",
        out_dir=tmp_path,
        fresh=True,
    )
    _, records = load_records(tmp_path / "s.sqlite", "actions_arm_reach")
    for rec in records.values():
        assert rec.status == "SUCCEEDED" and not rec.failed and 0 < rec.duration < 2.0
        # at most n_states, fewer when the reach ends first (every state_period s)
        assert len(rec.states) == 4 * min(5, math.floor(rec.duration / 0.2 + 1e-9) + 1)
        assert rec.states[:4] == pytest.approx([rec.theta_a, 0.0, rec.theta_b, 0.0], abs=1e-6)
    assert "at least 27" in result.figures["tables"].read_text()
    # synthetic records whose duration is linear in dist: the tree finds it
    rng = np.random.default_rng(1)
    recs = []
    for _ in range(120):
        a, b, ga, gb = rng.uniform(0, 2, 4)
        recs.append(
            ReachRecord(a, 0, b, 0, ga, 0, gb, 0, 0.5 + math.hypot(ga - a, gb - b), "SUCCEEDED",
                        False, [], 0.0)
        )  # fmt: skip
    paths = summarize(recs, c, tmp_path)
    text = paths["tables"].read_text()
    assert "| reach (arm control, 2 joints), paper (Table 1) | 1466 (1100) | 2.9 | 0.21 |" in text
    assert "no failure tree (one class)" in text
    assert float(text.split("| reach (arm control, 2 joints), ours |")[1].split("|")[2]) < 0.05
    assert FEATURE_FUNCS["dist"](recs[0]) == pytest.approx(recs[0].duration - 0.5)
