"""Walking controller: stepping rule, ZMP/CoM, swing, whole-body IK, LeafSystems, physics walk."""

import copy
import math

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from repertoire.diagrams.biped_walk import (
    BipedWalkScenario,
    build_biped_walk,
    build_walk_diagram,
    check_biped_walk,
    execute_plan,
    landing_errors,
    obstacle_cells,
    plan_from_actions,
    start_feet,
)
from repertoire.diagrams.scenario import load_scenario
from repertoire.models.biped import com_in_pelvis, leg_fk, rotation_rpy
from repertoire.planning.footstep.actions import nominal_action_table
from repertoire.planning.footstep.environment import OccupancyGrid
from repertoire.planning.footstep.types import Foot
from repertoire.systems.walking import (
    CommandStepper,
    SteppingRule,
    SwingFootPlanner,
    WalkingIK,
    ZmpComPlanner,
    compose,
    foot_poses_at,
    plan_com,
    realize_commands,
    realize_plan,
    realize_step,
    relative,
    standing_com_height,
    swing_pose,
    whole_body_ik,
    zmp_reference,
)

from repertoire.errors import RepertoireError, ScenarioError

RULE = SteppingRule()


def _plan(actions, stance="left"):
    s, w = start_feet([0.0, 0.0, 0.0], stance)
    return plan_from_actions(actions, s, stance, w, nominal_action_table())


def test_stepping_rule_closed_forms():
    # From standing (v = 0) a long step is clipped to the 0.12 m speed change.
    d, t = realize_step("stop", "stop", "forward_long", Foot.RIGHT, RULE)
    np.testing.assert_allclose(d, [0.12, 0.19, 0.0], atol=1e-12)
    assert t == pytest.approx(1.0 + 0.12)
    # One long step earlier (v = 0.15): 0.27 m.
    d, t = realize_step("stop", "forward_long", "forward_long", Foot.LEFT, RULE)
    np.testing.assert_allclose(d, [0.27, -0.19, 0.0], atol=1e-12)
    assert t == pytest.approx(1.12)
    # A stop after full speed (v = 0.30) takes one more 0.18 m step.
    d, t = realize_step("forward_long", "forward_long", "stop", Foot.RIGHT, RULE)
    np.testing.assert_allclose(d, [0.18, 0.19, 0.0], atol=1e-12)
    # At constant speed the command is obeyed and takes the base duration.
    d, t = realize_step("forward_medium", "forward_medium", "forward_medium", Foot.RIGHT, RULE)
    np.testing.assert_allclose(d, [0.20, 0.19, 0.0], atol=1e-12)
    assert t == pytest.approx(1.0)
    # Side steps and turns keep their lateral and yaw parts.
    d, _ = realize_step("stop", "stop", "side_step", Foot.LEFT, RULE)
    np.testing.assert_allclose(d, [0.0, -0.29, 0.0], atol=1e-12)
    d, _ = realize_step("stop", "stop", "turn_left", Foot.RIGHT, RULE)
    assert d[2] == pytest.approx(0.35)


def test_pose_algebra_round_trip():
    a = np.array([0.3, -0.2, 0.7])
    d = np.array([0.1, 0.19, -0.2])
    np.testing.assert_allclose(relative(a, compose(a, d)), d, atol=1e-12)


def test_realize_commands_alternates_and_times():
    seq = realize_commands(
        [0.0, 0.095, 0.0], Foot.LEFT, [0.0, -0.095, 0.0], ["forward_long"] * 3 + ["stop"], RULE
    )
    assert seq.swing_feet == [1, 0, 1, 0]
    assert seq.command_times[0] == pytest.approx(RULE.initial_hold)
    # Each step is commanded the moment the previous one lands.
    np.testing.assert_allclose(seq.command_times[1:], seq.land_times[:-1])
    np.testing.assert_allclose([p[0] for p in seq.poses], [0.12, 0.39, 0.69, 0.87], atol=1e-12)
    assert seq.end_time == pytest.approx(seq.land_times[-1] + RULE.double_support + RULE.final_hold)


def test_zmp_reference_and_com_plan():
    seq = realize_commands(
        [0.0, 0.095, 0.0], Foot.LEFT, [0.0, -0.095, 0.0], ["forward_medium"] * 4, RULE
    )
    zmp = zmp_reference(seq)
    np.testing.assert_allclose(zmp.value(0.0).ravel(), [0.0, 0.0], atol=1e-12)
    # During the first swing the ZMP sits on the left (stance) sole.
    t_mid = 0.5 * (seq.command_times[0] + RULE.double_support + seq.land_times[0])
    np.testing.assert_allclose(zmp.value(t_mid).ravel(), [0.0, 0.095], atol=1e-12)
    final_mid = 0.5 * (np.array(seq.poses[-1][:2]) + np.array(seq.poses[-2][:2]))
    np.testing.assert_allclose(zmp.value(seq.end_time).ravel(), final_mid, atol=1e-12)
    planner = plan_com(seq, 0.68)
    # The LIPM CoM starts at rest between the feet and ends near the final midpoint.
    np.testing.assert_allclose(planner.get_nominal_com(0.0).ravel(), [0.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(planner.get_nominal_com(seq.end_time).ravel(), final_mid, atol=0.01)
    # Its centre of pressure follows the reference within a few centimetres.
    errs = []
    for t in np.linspace(0.0, seq.end_time, 200):
        com = planner.get_nominal_com(t).ravel()
        comdd = planner.get_nominal_comdd(t).ravel()
        cop = com - 0.68 / 9.81 * comdd
        errs.append(np.linalg.norm(cop - zmp.value(t).ravel()))
    assert max(errs) < 0.03


def test_swing_pose_shape():
    p0, p1 = np.array([0.0, 0.1, 0.0]), np.array([0.3, 0.1, 0.2])
    np.testing.assert_allclose(swing_pose(p0, p1, 0.0, 0.05), [0, 0.1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(swing_pose(p0, p1, 1.0, 0.05), [0.3, 0.1, 0, 0.2], atol=1e-12)
    mid = swing_pose(p0, p1, 0.5, 0.05)
    assert mid[2] == pytest.approx(0.05) and mid[0] == pytest.approx(0.15)
    # Before phase 0.15 the foot only lifts.
    assert swing_pose(p0, p1, 0.1, 0.05)[0] == 0.0


def test_whole_body_ik_meets_com_and_feet():
    left = np.array([0.1, 0.12, 0.03, 0.2])
    right = np.array([-0.05, -0.08, 0.0, 0.1])
    com = np.array([0.03, 0.01])
    q, pelvis = whole_body_ik(com, left, right, 0.6, iterations=8)
    R_WP = rotation_rpy(0, 0, pelvis[3])
    c = pelvis[:3] + R_WP @ com_in_pelvis(q)
    np.testing.assert_allclose(c[:2], com, atol=1e-6)
    assert pelvis[3] == pytest.approx(0.15)
    for k, (foot, side) in enumerate(((left, "left"), (right, "right"))):
        p, R = leg_fk(q[6 * k : 6 * k + 6], side)
        p_W = pelvis[:3] + R_WP @ p
        np.testing.assert_allclose(p_W, foot[:3], atol=1e-9)
        assert math.atan2((R_WP @ R)[1, 0], (R_WP @ R)[0, 0]) == pytest.approx(foot[3])
    assert 0.6 < standing_com_height(0.6) < 0.75


def test_leaf_systems_match_pure_functions():
    plan = _plan(["forward_long", "turn_left", "stop"])
    stepper = CommandStepper(RULE)
    ctx = stepper.CreateDefaultContext()
    stepper.GetInputPort("plan").FixValue(ctx, plan)
    seq = stepper.GetOutputPort("footsteps").Eval(ctx)
    assert seq.poses == realize_plan(plan, RULE).poses
    stepper.GetInputPort("plan").FixValue(ctx, _plan(["side_step"]))
    assert stepper.GetOutputPort("footsteps").Eval(ctx).actions == ["side_step"]

    swing = SwingFootPlanner()
    sctx = swing.CreateDefaultContext()
    swing.GetInputPort("footsteps").FixValue(sctx, seq)
    t = seq.command_times[0] + RULE.double_support + 0.3
    sctx.SetTime(t)
    left, right, support = foot_poses_at(seq, t)
    np.testing.assert_allclose(swing.GetOutputPort("left_foot").Eval(sctx), left)
    np.testing.assert_allclose(swing.GetOutputPort("right_foot").Eval(sctx), right)
    assert swing.GetOutputPort("support").Eval(sctx)[0] == support == 1

    zmp = ZmpComPlanner(0.68)
    zctx = zmp.CreateDefaultContext()
    zmp.GetInputPort("footsteps").FixValue(zctx, seq)
    zctx.SetTime(1.0)
    planner = plan_com(seq, 0.68)
    np.testing.assert_allclose(
        zmp.GetOutputPort("com").Eval(zctx)[:2], planner.get_nominal_com(1.0).ravel(), atol=1e-12
    )
    np.testing.assert_allclose(
        zmp.GetOutputPort("zmp_reference").Eval(zctx), zmp_reference(seq).value(1.0).ravel()
    )

    # The same footsteps again (an equal copy, as an upstream update re-sends them) keep the
    # plan already made; changed footsteps make a new one.
    made = zmp.GetOutputPort("zmp_planner").Eval(zctx).planner
    zmp.GetInputPort("footsteps").FixValue(zctx, copy.deepcopy(seq))
    assert zmp.GetOutputPort("zmp_planner").Eval(zctx).planner is made
    moved = copy.deepcopy(seq)
    moved.poses[0] = [moved.poses[0][0] + 0.02, *moved.poses[0][1:]]
    zmp.GetInputPort("footsteps").FixValue(zctx, moved)
    assert zmp.GetOutputPort("zmp_planner").Eval(zctx).planner is not made
    zctx.SetTime(t := seq.land_times[0] + 0.2)  # the moved foot carries the ZMP then
    np.testing.assert_allclose(
        zmp.GetOutputPort("zmp_reference").Eval(zctx), zmp_reference(moved).value(t).ravel()
    )
    assert not np.allclose(
        zmp.GetOutputPort("zmp_reference").Eval(zctx), zmp_reference(seq).value(t).ravel()
    )

    ik = WalkingIK(0.6)
    ictx = ik.CreateDefaultContext()
    com = np.array([0.01, 0.0, 0.0, 0.0])
    ik.GetInputPort("com").FixValue(ictx, com)
    ik.GetInputPort("left_foot").FixValue(ictx, [0.0, 0.095, 0.0, 0.0])
    ik.GetInputPort("right_foot").FixValue(ictx, [0.0, -0.095, 0.0, 0.0])
    simulator = Simulator(ik, ictx)
    simulator.Initialize()
    q, pelvis = whole_body_ik(com[:2], [0, 0.095, 0, 0], [0, -0.095, 0, 0], 0.6, iterations=6)
    desired = ik.GetOutputPort("desired_state").Eval(ictx)
    np.testing.assert_allclose(desired[:12], q, atol=1e-9)
    np.testing.assert_allclose(desired[12:], 0.0, atol=1e-6)
    np.testing.assert_allclose(ik.GetOutputPort("pelvis_reference").Eval(ictx), pelvis, atol=1e-9)


def test_physics_walk_lands_on_the_controller_targets():
    plan = _plan(["forward_long", "forward_long", "stop"])
    result = execute_plan(plan)
    assert not result.fell
    assert len(result.landed) == 3
    pos, yaw = landing_errors(result.landed, result.expected)
    assert pos.max() < 0.01 and yaw.max() < math.radians(2)
    # The state-dependent rule: the commanded 0.30 m first step is only 0.12 m, and the
    # plan made with the nominal table is off by that much.
    pos_plan, _ = landing_errors(result.landed, result.planned)
    assert pos_plan[0] == pytest.approx(0.18, abs=0.01)
    assert result.max_tilt < 0.1


def test_registered_diagram_from_actions():
    scenario = load_scenario(
        BipedWalkScenario, data="map_seed: -1\nactions: [forward_short, stop]\n"
    )
    diagram = build_biped_walk(scenario)
    assert diagram.get_name() == "biped_walk"
    simulator = Simulator(diagram)
    simulator.AdvanceTo(3.0)
    figures = check_biped_walk(diagram, simulator.get_context())
    assert figures["fell"] == 0.0 and figures["steps_landed"] == 2.0
    assert abs(figures["pelvis_height_m"] - 0.6) < 0.01


def test_obstacle_cells_merge_columns():
    occ = np.zeros((4, 5), dtype=bool)
    occ[1, 1:4] = True
    occ[3, 0] = True
    grid = OccupancyGrid(occ, 0.5, (0.0, 0.0))
    assert obstacle_cells(grid) == [[0.5, 0.5, 1.0, 2.0], [1.5, 0.0, 2.0, 0.5]]


def test_bad_input():
    with pytest.raises(RepertoireError, match="unknown action 'jump'"):
        realize_step("stop", "stop", "jump", Foot.LEFT, RULE)
    with pytest.raises(RepertoireError, match="double_support"):
        realize_commands([0, 0.1, 0], Foot.LEFT, [0, -0.1, 0], [], SteppingRule(double_support=2.0))
    with pytest.raises(RepertoireError, match="finite"):
        realize_commands([np.nan, 0.1, 0], Foot.LEFT, [0, -0.1, 0], ["stop"], RULE)
    stepper = CommandStepper()
    ctx = stepper.CreateDefaultContext()
    stepper.GetInputPort("plan").FixValue(ctx, "not a plan")
    with pytest.raises(RepertoireError, match="FootstepPlan"):
        stepper.GetOutputPort("footsteps").Eval(ctx)
    with pytest.raises(RepertoireError, match="com_height"):
        ZmpComPlanner(2.0)
    zmp = ZmpComPlanner(0.68)
    zctx = zmp.CreateDefaultContext()
    zmp.GetInputPort("footsteps").FixValue(zctx, _plan(["stop"]))  # a plan, not footsteps
    with pytest.raises(RepertoireError, match="footsteps input needs a FootstepSequence"):
        zmp.GetOutputPort("com").Eval(zctx)
    with pytest.raises(ScenarioError, match="unknown action 'hop'"):
        load_scenario(BipedWalkScenario, data="actions: [hop]\n")
    with pytest.raises(ScenarioError, match="could not load"):
        load_scenario(BipedWalkScenario, data="actions: forward_long: 1\n")
    with pytest.raises(ScenarioError, match="plan_file"):
        load_scenario(BipedWalkScenario, data="plan_file: /nonexistent/plan.json\n")
    with pytest.raises(ScenarioError, match="pelvis_height"):
        load_scenario(BipedWalkScenario, data="pelvis_height: 0.9\n")
    for bad in (0, -3):
        with pytest.raises(
            ScenarioError, match=f"plan_expansions must be an integer >= 1, got {bad}"
        ):
            load_scenario(BipedWalkScenario, data=f"plan_expansions: {bad}\n")
    with pytest.raises(ScenarioError, match="'plan_expansions' expects a whole number"):
        load_scenario(BipedWalkScenario, data="plan_expansions: 1.5\n")
    with pytest.raises(ScenarioError, match="first_stance"):
        BipedWalkScenario(first_stance="middle").validate()


def test_check_figures_say_whether_the_plan_is_complete():
    # map_seed 2 on a 2 m floor with a 60000-node budget: the planner hits it and the biped
    # walks the best partial plan (15 steps, 1.09 m of heuristic cost left); the figures
    # said nothing about it before. That was the scenario's budget before session 35: the
    # default one (a million) plans it whole (17 steps, 67412 expansions).
    figures = {}
    for name, yaml in (
        ("partial", "map_seed: 2\nmap_size: 2.0\nplan_expansions: 60000\n"),
        ("whole", "map_seed: 2\nmap_size: 2.0\n"),
        ("actions", "map_seed: -1\n"),
    ):
        diagram = build_biped_walk(load_scenario(BipedWalkScenario, data=yaml))
        figures[name] = check_biped_walk(diagram, diagram.CreateDefaultContext())
    assert figures["partial"]["plan_complete"] == 0.0
    assert figures["partial"]["steps_planned"] == 15.0
    assert figures["whole"]["plan_complete"] == 1.0
    assert figures["whole"]["steps_planned"] == 17.0
    assert figures["actions"]["plan_complete"] == 1.0
    assert figures["actions"]["steps_planned"] == len(BipedWalkScenario().actions)


def test_walk_builder_and_execute_plan_check_their_arguments():
    # The builder and execute_plan are public entry points: a pelvis height the scenario
    # refuses (0.9 m: legs out of reach) walked silently, a negative time_step or a NaN
    # settle aborted the process inside Drake, max_steps=-1 measured nothing.
    plan = _plan(["stop"])
    cases = (
        ({"pelvis_height": 0.9}, r"pelvis_height must be in \[0.5, 0.64\] m, got 0.9"),
        ({"pelvis_height": math.nan}, "pelvis_height must be in .* got nan"),
        ({"time_step": -1e-3}, r"time_step must be in \(0, 0.01\] s .* got -0.001"),
        ({"contact_approximation": "tamsi"}, "contact_approximation .* got 'tamsi'"),
    )
    for kwargs, message in cases:
        with pytest.raises(RepertoireError, match=message):
            build_walk_diagram(plan, **kwargs)
        with pytest.raises(RepertoireError, match=message):
            execute_plan(plan, **kwargs)
    with pytest.raises(RepertoireError, match="ground_friction must be > 0, got -1"):
        build_walk_diagram(plan, ground_friction=-1.0)
    for settle in (math.nan, -0.5):
        with pytest.raises(
            RepertoireError, match=f"settle must be a finite delay >= 0 s, got {settle}"
        ):
            execute_plan(plan, settle=settle)
    with pytest.raises(RepertoireError, match="max_steps must be None or an int >= 0, got -1"):
        execute_plan(plan, max_steps=-1)


def test_start_time_must_be_finite_and_not_negative():
    # A NaN or negative start put breaks before 0 into the ZMP reference, and Drake's
    # PiecewisePolynomial aborted the whole process; now it is a clear error.
    for bad in (np.nan, -1.0, np.inf):
        with pytest.raises(RepertoireError, match=f"start_time must be finite and >= 0.*{bad}"):
            realize_commands([0, 0.1, 0], Foot.LEFT, [0, -0.1, 0], ["stop"], RULE, start_time=bad)
        with pytest.raises(RepertoireError, match="start_time must be finite"):
            CommandStepper(start_time=bad)
    seq = realize_commands([0, 0.095, 0], Foot.LEFT, [0, -0.095, 0], ["stop"], RULE, start_time=2.0)
    assert seq.command_times == [pytest.approx(2.0 + RULE.initial_hold)]
    zmp = zmp_reference(seq)
    np.testing.assert_allclose(zmp.value(1.0).ravel(), [0.0, 0.0], atol=1e-12)


def test_walking_ik_com_feedback_aims_past_the_plan_by_the_measured_error():
    # com_gain K: the IK puts the CoM at c + K (c - measured), exactly whole_body_ik's there.
    assert WalkingIK(0.6).num_input_ports() == 3  # no measured_com port without feedback
    ik = WalkingIK(0.6, com_gain=1.0)
    ictx = ik.CreateDefaultContext()
    left, right = [0.0, 0.095, 0.0, 0.0], [0.0, -0.095, 0.0, 0.0]
    ik.GetInputPort("com").FixValue(ictx, [0.01, 0.002, 0.0, 0.0])
    ik.GetInputPort("left_foot").FixValue(ictx, left)
    ik.GetInputPort("right_foot").FixValue(ictx, right)
    ik.GetInputPort("measured_com").FixValue(ictx, [0.004, 0.012, 0.7])
    simulator = Simulator(ik, ictx)
    simulator.Initialize()
    q, pelvis = whole_body_ik(np.array([0.016, -0.008]), left, right, 0.6, iterations=6)
    np.testing.assert_allclose(ik.GetOutputPort("desired_state").Eval(ictx)[:12], q, atol=1e-9)
    np.testing.assert_allclose(ik.GetOutputPort("pelvis_reference").Eval(ictx), pelvis, atol=1e-9)
    for bad in (-0.5, math.nan, math.inf, "1", None):
        with pytest.raises(RepertoireError, match="com_gain"):
            WalkingIK(0.6, com_gain=bad)


def test_com_sensor_is_the_plants_com():
    plan = _plan(["stop"])
    diagram = build_walk_diagram(plan, com_gain=1.0)
    context = diagram.CreateDefaultContext()
    plant = diagram.GetSubsystemByName("plant")
    sensor = diagram.GetSubsystemByName("com_sensor")
    pc = plant.GetMyContextFromRoot(context)
    plant.SetPositions(pc, plant.GetPositions(pc) + 0.01)  # away from the default pose
    want = plant.CalcCenterOfMassPositionInWorld(pc)
    got = sensor.GetOutputPort("com").Eval(sensor.GetMyContextFromRoot(context))
    np.testing.assert_allclose(got, want, atol=1e-12)
    assert not build_walk_diagram(plan).HasSubsystemNamed("com_sensor")


def test_com_feedback_lands_the_feet_closer_to_their_schedule():
    # Five long steps from standing (session 35's walk): without CoM feedback the stance
    # soles roll up to 1.97 deg and the feet touch down 0.16-0.22 s after their scheduled
    # landings; with com_gain 1 the roll halves and so does the lateness. No fall either way.
    plan = _plan(["forward_long"] * 5 + ["stop", "stop"])
    late = {}
    for gain in (0.0, 1.0):
        result = execute_plan(plan, diagram=build_walk_diagram(plan, com_gain=gain))
        assert not result.fell
        late[gain] = np.subtract(result.durations, result.scheduled_durations)
    assert late[0.0].max() > 0.2
    assert late[1.0].max() < 0.15
    assert np.all(late[1.0] <= late[0.0] + 1e-9)
