"""Learning the footstep table T from simulated steps; executing plans made with it."""

import itertools
import json

import numpy as np
import pytest
from repertoire.models.biped import LEARNED_TABLE_PATH
from repertoire.planning.footstep.actions import ACTIONS, nominal_action_table
from repertoire.planning.footstep.types import ActionTable, ActionTableError, Foot
from repertoire.planning.footstep_learning import (
    command_sequences,
    covered_keys,
    learn_action_table,
    sequence_for_index,
    step_periods,
    step_samples,
    table_differences,
)
from repertoire.studies.footstep_execution import (
    FootstepExecutionConfig,
    smoke_config,
)
from repertoire.studies.footstep_execution import (
    run_episode as run_execution_episode,
)
from repertoire.studies.footstep_execution import (
    summarize as execution_summarize,
)
from repertoire.studies.footstep_table import (
    FootstepTableConfig,
    rule_table_displacement,
    run_episode,
    samples_of,
    summarize,
)
from repertoire.systems.walking import SteppingRule, compose, realize_step

from repertoire.errors import RepertoireError


def test_sequence_indexing():
    seqs = command_sequences()
    assert len(seqs) == 343
    assert [sequence_for_index(i) for i in range(343)] == seqs
    assert sequence_for_index(0) == ("forward_long",) * 3
    assert sequence_for_index(342) == ("stop",) * 3
    with pytest.raises(RepertoireError, match="out of range"):
        sequence_for_index(343)
    with pytest.raises(RepertoireError, match="length"):
        command_sequences(length=0)


def test_step_samples_closed_form():
    stance = [[0.0, 0.095, 0.0], [0.3, -0.095, 0.1]]
    landed = [[0.3, -0.095, 0.1], [0.5, 0.2, 0.1]]
    samples = step_samples(["forward_long", "stop"], "left", stance, landed, [1.1, 1.0])
    assert samples[0][:4] == ("stop", "stop", "left", "forward_long")
    np.testing.assert_allclose(samples[0][4:], [0.3, -0.19, 0.1, 1.1], atol=1e-12)
    assert samples[1][:4] == ("stop", "forward_long", "right", "stop")
    c, s = np.cos(0.1), np.sin(0.1)
    d = np.array([0.2, 0.295])
    np.testing.assert_allclose(samples[1][4:6], [c * d[0] + s * d[1], -s * d[0] + c * d[1]])
    with pytest.raises(RepertoireError, match="do not match"):
        step_samples(["stop"], "left", stance, landed, [1.0])
    with pytest.raises(RepertoireError, match="non-finite"):
        step_samples(["stop"], "left", [[np.nan, 0, 0]], [[0, 0, 0]], [1.0])


def test_step_periods_closed_form():
    # touch-downs at 0.4 + 1.104, 1.52 + 1.284, 2.64 + 1.232: 1.504, 2.804, 3.872
    periods = step_periods([0.4, 1.52, 2.64], [1.104, 1.284, 1.232])
    np.testing.assert_allclose(periods, [1.104, 1.3, 1.068], atol=1e-12)
    # a plan's times (their sums) are the touch-downs counted from the first command
    np.testing.assert_allclose(np.cumsum(periods), [1.104, 2.404, 3.472], atol=1e-12)
    assert step_periods([0.0], []) == []
    assert np.isnan(step_periods([0.0, 1.0], [1.0, np.nan])[1])  # no touch-down: NaN
    with pytest.raises(RepertoireError, match="2 durations but only 1 command times"):
        step_periods([0.0], [1.0, 1.0])


def _rule_samples(rule: SteppingRule) -> list:
    """Exact samples of the controller's rule for all 343 sequences from standing."""
    samples = []
    for seq in command_sequences():
        poses = {Foot.LEFT: np.array([0.0, 0.095, 0.0]), Foot.RIGHT: np.array([0.0, -0.095, 0.0])}
        stance = Foot.LEFT
        hist = ["stop", "stop"]
        st, ld, du = [], [], []
        for a in seq:
            d, t = realize_step(hist[-2], hist[-1], a, stance, rule)
            landed = compose(poses[stance], d)
            st.append(poses[stance].tolist())
            ld.append(landed.tolist())
            du.append(t)
            poses[stance.other()] = landed
            stance = stance.other()
            hist.append(a)
        samples += step_samples(list(seq), "left", st, ld, du)
    return samples


def test_learned_table_from_rule_samples_is_the_rule():
    rule = SteppingRule()
    samples = _rule_samples(rule)
    assert len(covered_keys(samples)) == 2 * 343
    table, filled = learn_action_table(samples)
    assert filled == 0
    np.testing.assert_allclose(table.displacement, rule_table_displacement(rule), atol=1e-9)
    assert table.lookup("stop", "stop", "right", "forward_long")[0] == pytest.approx(0.12)
    assert table.lookup("forward_long", "forward_long", "left", "stop")[0] == pytest.approx(0.18)
    diff = table_differences(table)
    assert diff["max_position_diff_m"] == pytest.approx(0.18)
    assert 0.1 < diff["fraction_over_2cm"] < 0.9
    # Without complete coverage the table refuses, unless filled from another table.
    with pytest.raises(ActionTableError, match="missing"):
        learn_action_table(samples[:30])
    _, filled = learn_action_table(samples[:30], fill_from=nominal_action_table())
    assert 0 < filled < 2 * 343


def test_physics_stop_after_fast_walking_takes_one_more_step(tmp_path):
    config = FootstepTableConfig()
    index = list(itertools.product(ACTIONS, repeat=3)).index(
        ("forward_long", "forward_long", "stop")
    )
    record = run_episode(config, index)
    assert not record.fell and record.steps_measured == 3
    # Commanded: 0.30, 0.30, 0.00 forward. Measured: 0.12 (from standing), 0.27, 0.18.
    np.testing.assert_allclose(record.dx, [0.12, 0.27, 0.18], atol=0.01)
    np.testing.assert_allclose(np.abs(record.dy), 0.19, atol=0.01)
    assert max(record.rule_error_m) < 0.01
    out = summarize([record], config, tmp_path)
    summary = json.loads(out["summary"].read_text())
    assert summary["keys_filled_from_nominal"] > 0
    assert summary["physics_vs_rule_measured_max_m"] < 0.01
    assert out["table"].is_file() and out["fig2"].is_file()
    assert samples_of([record], "left")[2][:4] == ("forward_long", "forward_long", "left", "stop")


def test_shipped_learned_table():
    table = ActionTable.load(LEARNED_TABLE_PATH)
    # Measured on the physics biped: from standing a commanded long step is 0.12 m, and a
    # stop after full speed still moves 0.18 m forward.
    assert table.lookup("stop", "stop", "right", "forward_long")[0] == pytest.approx(
        0.12, abs=0.005
    )
    assert table.lookup("forward_long", "forward_long", "left", "stop")[0] == pytest.approx(
        0.18, abs=0.005
    )
    rule = rule_table_displacement(SteppingRule())
    assert np.abs(table.displacement[..., :2] - rule[..., :2]).max() < 0.01


def test_shipped_table_times_are_the_walkers_touch_downs():
    # A plan's times say when each foot lands (what dynamic obstacles are checked
    # against). The table held command-to-touch-down times, but the walker commands each
    # step at the previous one's scheduled landing, 0.1-0.2 s before its touch-down: the
    # plan's clock ran 0.12 s a step slow (8 steps: the last touch-down at 8.78 s where
    # the plan said 9.75 s). Now the times are touch-down to touch-down. What is left
    # (0.06 s here) does not grow: a step's time depends on the step before its key's
    # history (that step's own lag), which the table T(a-2, a-1, l, a) cannot hold.
    from repertoire.diagrams.biped_walk import execute_plan, plan_from_actions, start_feet
    from repertoire.systems.walking import realize_plan

    actions = ["forward_long", "forward_long", "turn_left", "forward_medium", "side_step"]
    actions += ["forward_short", "stop"]
    stance, swing = start_feet([0.0, 0.0, 0.0], "left")
    plan = plan_from_actions(actions, stance, "left", swing, ActionTable.load(LEARNED_TABLE_PATH))
    seq = realize_plan(plan, SteppingRule())
    result = execute_plan(plan)
    assert not result.fell and len(result.landed) == len(actions)
    touch = np.array(seq.command_times) + np.array(result.durations) - seq.command_times[0]
    np.testing.assert_allclose(touch, plan.times[1:], atol=0.1)  # before: 0.76 s at step 7


def test_execution_smoke_with_learned_table(tmp_path):
    record = run_execution_episode(smoke_config(), 0)
    assert not record.learned_fell
    assert record.learned_steps > 0 and record.learned_executed == record.learned_steps
    assert record.learned_within_frac >= 0.8
    assert record.learned_max_err_m < 0.05
    out = execution_summarize([record], smoke_config(), tmp_path)
    rows = json.loads(out["execution_summary"].read_text())
    assert rows["learned"]["runs"] == 1 and rows["learned"]["steps"] == record.learned_steps
    assert out["example"].is_file() and out["landing_error_hist"].is_file()


def test_execution_config_bad_input(tmp_path):
    with pytest.raises(RepertoireError, match="not found"):
        FootstepExecutionConfig(table_path=str(tmp_path / "none.json")).validate()
    with pytest.raises(RepertoireError, match="size_m"):
        FootstepExecutionConfig(size_m=0.5).validate()
    # the walk's settings are checked before any map is planned (a negative time_step
    # reached Drake's MultibodyPlant, which aborted the process)
    with pytest.raises(RepertoireError, match="time_step must be in .* got -0.002"):
        FootstepExecutionConfig(time_step=-0.002).validate()
    with pytest.raises(RepertoireError, match=r"pelvis_height must be in \[0.5, 0.64\] m, got 0.9"):
        FootstepExecutionConfig(pelvis_height=0.9).validate()
    with pytest.raises(RepertoireError, match="contact_approximation .* got 'tamsi'"):
        FootstepExecutionConfig(contact_approximation="tamsi").validate()
    with pytest.raises(RepertoireError, match="heuristic_weight must be finite and >= 1 .*nan"):
        FootstepExecutionConfig(heuristic_weight=float("nan")).validate()
    with pytest.raises(RepertoireError, match="table_file"):
        FootstepTableConfig(table_file="t.txt").validate()


def test_long_walk_actions_repeat_the_cycle_then_stop():
    from repertoire.studies.footstep_execution import long_walk_actions

    assert long_walk_actions(3) == ["forward_long", "stop", "stop"]
    assert long_walk_actions(7) == [
        "forward_long",
        "turn_left",
        "forward_medium",
        "turn_right",
        "forward_long",
        "stop",
        "stop",
    ]
    # the 102-step plan of docs/results/footstep.md: the cycle 25 times, then two stops
    cycle = ["forward_long", "turn_left", "forward_medium", "turn_right"]
    assert long_walk_actions(102) == cycle * 25 + ["stop", "stop"]
    for bad in (2, 0, -1, 4.5, True):
        with pytest.raises(RepertoireError, match="whole number >= 3 of steps, got"):
            long_walk_actions(bad)


def test_feedback_walk_steps_is_checked():
    for bad in (1, 2, -3, 7.5):
        with pytest.raises(RepertoireError, match=f"feedback_walk_steps must be 0 .* got {bad}"):
            FootstepExecutionConfig(feedback_walk_steps=bad).validate()
    FootstepExecutionConfig(feedback_walk_steps=0).validate()


def test_feedback_walk_figure_is_written(tmp_path):
    from repertoire.studies.footstep_execution import draw_feedback_walk, feedback_walk

    plan, results = feedback_walk(smoke_config(), 4)
    assert plan.num_steps == 4 and set(results) == {False, True}
    for result in results.values():
        assert not result.fell and len(result.landed) == 4
    out = draw_feedback_walk(plan, results, tmp_path / "walk.png")
    assert out.is_file() and out.stat().st_size > 10_000


def test_a_long_walk_the_feedback_refuses_is_noted_not_drawn(tmp_path):
    # the nominal table's first long step is 0.18 m from the controller's: out of reach
    table = tmp_path / "nominal.json"
    nominal_action_table().save(table)
    config = FootstepExecutionConfig(
        **{**smoke_config().__dict__, "table_path": str(table), "feedback_walk_steps": 3}
    )
    record = run_execution_episode(config, 0)
    out = execution_summarize([record], config, tmp_path)
    assert "feedback_walk" not in out
    assert out["feedback_walk_refused"].read_text().startswith("the long walk was not drawn: ")
