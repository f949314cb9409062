"""A kitchen stand must let a drop drive leave it (studies/_kitchen_arm.exit_clear)."""

import math

import numpy as np
from repertoire.models.diffdrive import WHEEL_RADIUS
from repertoire.studies import _kitchen_arm as ka
from repertoire.studies import _kitchen_plan as kp
from repertoire.studies.refinement_kitchen import refine_kitchen

FAR = {"cup_y_range": [1.4, 1.65]}
# seed 38109 (far-side cups): the stand h = 2 chose before the fix (behind table_0, at its
# footprint's clearance from the table's far edge, facing 0.25 rad towards the table), and
# the one h = 1 chose, 0.02 m to the right, facing along the table
STAND_H2_OLD = [-0.2544623162032942, -0.6425193456214952, 0.7938286169710754]
STAND_H1_OLD = [-0.004181390426066703, -0.9214069297444015, 0.7920855060356022]


def test_the_least_carry_is_the_carry_ranges_shortest_highest_arm():
    config = kp.KitchenPlanConfig()
    arm = ka.least_carry(config)
    z = 1.0 - WHEEL_RADIUS  # carry_z_range's top in the chassis frame
    np.testing.assert_allclose(arm, kp.arm_point(-1.2, 0.3, z), rtol=0, atol=1e-15)
    reach, lowest = ka.arm_reach(arm[None], config.arm_clearance, True)
    lo, hi, _ = kp.parameter_bounds(config)
    rows = np.random.default_rng(0).uniform(lo[3:6], hi[3:6], (2000, 3))
    others = kp.arm_point(rows[:, 0], rows[:, 1], kp.to_chassis_z(rows[:, 2]))
    reaches, lowests = ka.arm_reach(others, config.arm_clearance, True)
    assert np.all(reach[0] <= reaches) and np.all(lowest[0] >= lowests)
    # a yaw range off centre: the end farther from straight ahead
    shifted = kp.KitchenPlanConfig(carry_yaw_range=[-0.3, 1.1])
    np.testing.assert_allclose(ka.least_carry(shifted), kp.arm_point(1.1, 0.3, z), atol=1e-15)


def test_a_stand_no_drop_drive_can_leave_is_refused():
    config = kp.KitchenPlanConfig(**FAR)
    start, cups, targets = kp.sample_situation(config, np.random.default_rng(38109))
    exit_ = kp.exit_point(targets[0])
    params = np.zeros((2, 9))
    params[:, 3:6] = [0.0, 0.3, 1.0]
    params[0, :3], params[1, :3] = STAND_H2_OLD, STAND_H1_OLD
    stand = kp.plan_geometry(params, cups, targets).stand[:, 0]
    # both stand behind table_0 and reach the exit point by straight footprint legs
    assert np.all(stand[:, 1] > 1.7 + 0.32)
    assert ka.reaches(stand, exit_, config.clearance).tolist() == [True, True]
    # GoToPose's law turns as it drives: from the first no drive reaches the exit point
    assert ka.exit_clear(stand, cups, targets, 0, config).tolist() == [False, True]
    assert ka.exit_clear(stand, cups, targets, 0, config, rows=[0]).tolist() == [False, False]
    # and indeed no drop drive, whatever the carry and the drop pose, leaves the first stand
    lo, hi, _ = kp.parameter_bounds(config)
    rows = np.random.default_rng(1).uniform(lo, hi, (300, 9))
    rows[:, :3] = STAND_H2_OLD
    g = kp.plan_geometry(rows, cups, targets)
    assert not ka.drive_route(g, cups, 0, start, config, "drive_drop")[1].any()
    rows[:, :3] = STAND_H1_OLD
    g = kp.plan_geometry(rows, cups, targets)
    assert ka.drive_route(g, cups, 0, start, config, "drive_drop")[1].sum() > 0


def test_h2_plans_the_far_side_situation_it_had_no_plan_for(monkeypatch):
    """38109: h = 2 chose a stand no drop drive leaves (NO_PLAN) where h = 1 planned."""
    config = kp.KitchenPlanConfig(**FAR)
    start, cups, targets = kp.sample_situation(config, np.random.default_rng(38109))
    params, cost = refine_kitchen(config, start, cups, targets, 2, 38109)
    assert math.isfinite(cost)
    g = kp.plan_geometry(params, cups, targets)
    assert ka.exit_clear(g.stand[:, 0], cups, targets, 0, config).tolist() == [True]
    assert ka.drive_route(g, cups, 0, start, config, "drive_drop")[1].tolist() == [True]
    # with the old precondition (straight footprint legs to the exit point): no plan
    monkeypatch.setattr(ka, "exit_clear", lambda s, c, t, k, cf, rows: np.isin(
        np.arange(len(s)), rows) & ka.reaches(s, kp.exit_point(t[k]), cf.clearance))  # fmt: skip
    assert refine_kitchen(config, start, cups, targets, 2, 38109)[1] == math.inf
