import numpy as np
import pytest
from repertoire.diagrams.kitchen import KITCHEN_OBSTACLES, ROBOT_RADIUS
from repertoire.studies.actions_kitchen import (
    FEATURE_FUNCS,
    KitchenEpisodesConfig,
    KitchenRecord,
    sample_parameters,
    smoke_config,
    summarize,
)
from repertoire.studies.engine import load_records, run_study
from repertoire.systems.kitchen_actions import arm_inverse, footprint_hits

from repertoire.errors import RepertoireError


def test_sampling_is_seeded_alternating_and_in_range():
    c = KitchenEpisodesConfig()
    assert sample_parameters(c, 5) == sample_parameters(c, 5)
    for seed in range(40):
        action, start, goal = sample_parameters(c, seed)
        assert action == ("goto_pose", "reach")[seed % 2]
        if action == "goto_pose":
            for p in (start, goal):
                assert c.x_range[0] <= p[0] <= c.x_range[1]
                assert footprint_hits(p[:2], KITCHEN_OBSTACLES, ROBOT_RADIUS) == -1
            assert c.v_range[0] <= start[3] <= c.v_range[1]
            assert c.v_g_range[0] <= goal[3] <= c.v_g_range[1]
        else:
            for p in (start, goal):
                lift, yaw, extend = arm_inverse(p)
                assert c.lift_range[0] - 1e-9 <= lift <= c.lift_range[1] + 1e-9
                assert c.yaw_range[0] - 1e-9 <= yaw <= c.yaw_range[1] + 1e-9
                assert c.extend_range[0] - 1e-9 <= extend <= c.extend_range[1] + 1e-9


def test_config_rejects_bad_ranges():
    with pytest.raises(RepertoireError, match="x_range must lie within"):
        KitchenEpisodesConfig(x_range=[-5.0, 0.0]).validate()
    with pytest.raises(RepertoireError, match="lift_range"):
        KitchenEpisodesConfig(lift_range=[0.1, 0.5]).validate()
    # goal speeds up to GoToPose's v_max: a goal reached too slowly costs a run-up
    KitchenEpisodesConfig(v_g_range=[0.2, 0.6]).validate()
    with pytest.raises(RepertoireError, match="v_g_range"):
        KitchenEpisodesConfig(v_g_range=[0.0, 0.9]).validate()
    with pytest.raises(RepertoireError, match="actions"):
        KitchenEpisodesConfig(actions=["fly"]).validate()
    with pytest.raises(RepertoireError, match="cups must be distinct names"):
        KitchenEpisodesConfig(cups=["cup_9"]).validate()


def test_study_smoke_and_load_records(tmp_path):
    result = run_study(
        "actions_kitchen",
        smoke_config(),
        episodes=2,
        executor="inline",
        store=tmp_path / "s.sqlite",
        out_dir=tmp_path,
        fresh=True,
    )
    _, records = load_records(tmp_path / "s.sqlite", "actions_kitchen")
    assert [records[i].action for i in (0, 1)] == ["goto_pose", "reach"]
    for rec in records.values():
        assert rec.duration > 0 and rec.failed == (
            rec.touched_furniture or rec.status != "SUCCEEDED"
        )
        assert len(rec.states) == (4 if rec.action == "goto_pose" else 3) * smoke_config().n_states
    assert records[1].status == "SUCCEEDED"
    # the first kept reach state is the start
    np.testing.assert_allclose(records[1].states[:3], records[1].start, atol=0.01)
    assert "too few" in result.figures["tables"].read_text()


def test_summarize_fits_on_synthetic_records(tmp_path):
    rng = np.random.default_rng(0)
    recs = []
    for i in range(160):
        a = rng.uniform(-1, 1, 3)
        g = rng.uniform(-1, 1, 3)
        d = float(np.linalg.norm(g - a))
        recs.append(KitchenRecord("reach", list(a), list(g), 0.5 + 2 * d, "SUCCEEDED",
                                  False, False, [], 0.0))  # fmt: skip
        s = [*rng.uniform(-2, 2, 2), rng.uniform(-3, 3), 0.0]
        e = [*rng.uniform(-2, 2, 2), rng.uniform(-3, 3), 0.0]
        dist = float(np.hypot(e[0] - s[0], e[1] - s[1]))
        recs.append(KitchenRecord("goto_pose", s, e, 1 + dist / 0.8, "SUCCEEDED", False,
                                  i % 10 == 0, [], 0.0))  # fmt: skip
    paths = summarize(recs, KitchenEpisodesConfig(), tmp_path)
    text = paths["tables"].read_text()
    assert "| goToPose (kitchen) | 160 / 144; 108 | 16 |" in text
    assert "| reach (kitchen) | 160 / 160; 120 | 0 |" in text and "| 2200 | 2.6 | 0.1 |" in text
    assert "| reach (kitchen), + arm features | 160 / 160; 120 | 0 |" in text
    assert "Failure tree of kitchen goToPose" in text and "actual failure" in text
    for action in ("goto_pose", "reach"):
        assert paths[f"learning_curves_{action}"].stat().st_size > 0
    assert set(FEATURE_FUNCS["reach_arm"]) == {*FEATURE_FUNCS["reach"], "turn", "d_radial",
                                               "d_height"}  # fmt: skip
    assert FEATURE_FUNCS["reach"]["dist_xyz"](recs[0]) == pytest.approx(
        np.linalg.norm(np.subtract(recs[0].goal, recs[0].start))
    )
