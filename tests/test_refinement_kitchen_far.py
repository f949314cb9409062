"""The far-side kitchen refinement study (``refinement_kitchen_far``): registered, cheap checks."""

import dataclasses
import math

import numpy as np
from repertoire.studies import _kitchen_plan as kp
from repertoire.studies import refinement_kitchen as rk
from repertoire.studies.registry import get_study, study_names


def test_the_far_side_study_is_the_kitchen_study_on_far_side_cups():
    assert "refinement_kitchen_far" in study_names()
    far, near = get_study("refinement_kitchen_far"), get_study("refinement_kitchen")
    assert far.run_episode is near.run_episode is rk.run_episode  # the same study code
    assert far.config_type is near.config_type is kp.KitchenPlanConfig
    assert far.record_type is near.record_type
    assert far.demo_episodes == 1  # the demo runs its first seed only
    config = far.demo_config()
    config.validate()
    assert config.cup_y_range == [1.4, 1.65]
    assert dataclasses.replace(config, cup_y_range=near.demo_config().cup_y_range) == (
        near.demo_config()
    )
    smoke = far.smoke_config()
    smoke.validate()
    assert smoke == dataclasses.replace(rk.smoke_config(), cup_y_range=[1.4, 1.65])
    # the demo's situation (seed 0) puts cup_0 on table_0's far side
    _, cups, _ = kp.sample_situation(config, np.random.default_rng(0))
    assert 1.4 <= cups[0][1] <= 1.65


def _no_plan_record() -> rk.RefinementKitchenRecord:
    nan = math.nan
    plan = [[0.0] * 9, math.inf, [], nan, "NO_PLAN", []]
    return rk.RefinementKitchenRecord(
        [0.5, 0.0, 0.0, 0.0], [1.6, 1.5, 0.8, 2.5, 1.5, 0.8], [2.2, -1.3, 0.8], *plan, *plan,
        wall_refine_s=0.0, wall_time_s=0.0,
    )  # fmt: skip


def test_the_far_side_summary_writes_its_own_files(tmp_path):
    far = get_study("refinement_kitchen_far")
    paths = far.summarize([_no_plan_record()], far.demo_config(), tmp_path)
    assert paths["tables"] == tmp_path / "refinement_kitchen_far_1_tables.md"
    assert paths["paired"] == tmp_path / "refinement_kitchen_far_1_paired.png"
    assert paths["paired"].is_file() and "cups" not in paths  # nothing executed to draw
    text = paths["tables"].read_text()
    assert "Kitchen (scenario 1, far-side cups)" in text
    assert "with h = 1: {'NO_PLAN': 1}, with h = 2: {'NO_PLAN': 1}" in text
    near = rk.summarize([_no_plan_record()], far.demo_config(), tmp_path)
    assert near["tables"] == tmp_path / "refinement_kitchen_1_tables.md"
    assert "Kitchen (scenario 1)" in near["tables"].read_text()


def test_table_0_steps_are_the_arm_at_work_after_a_drive_to_a_stand():
    assert rk.table_0_steps(1) == [1, 2, 3, 4, 5, 6]
    assert rk.table_0_steps(2) == [1, 2, 3, 4, 5, 6, 12, 13, 14, 15, 16, 17]
    names = kp.action_names(2)
    assert names[11] == names[18] == "goto_pose" and names[10] == "reach"  # the reach up
