import math

import numpy as np
import pytest
from repertoire.diagrams.kitchen import (
    KITCHEN_OBSTACLES,
    KitchenScenario,
    action_status,
    check_kitchen_action,
    cup_position,
    kitchen_simulator,
    run_kitchen_sequence,
)
from repertoire.diagrams.soccer import robot_state
from repertoire.systems.action_status import ActionStatus
from repertoire.systems.kitchen_drive import KitchenGoToPose, stopping_poses
from repertoire.systems.kitchen_geometry import arm_inverse, arm_pose_hits, box_gaps

from repertoire.errors import RepertoireError

TABLE = [[2.0, 0.0, 0.0, 0.5, 0.5, 0.75]]  # x in [1.5, 2.5], y in [-0.5, 0.5]
TUCKED = [0.62, 0.0, 0.25]
OPEN = [0.075, 0.075]


def test_stopping_poses_closed_form():
    # 0.8 m/s: 0.8 * 0.02 held, then 0.8^2 / (2 * 1.0) braking = 0.336 m; 1 cm apart
    poses = stopping_poses([1.0, 2.0, 0.0, 0.8], 0.0, 1.0, 5.0, 0.02, 0.5)
    assert poses.shape == (35, 3)
    np.testing.assert_allclose(poses[[0, -1]], [[1.0, 2.0, 0.0], [1.336, 2.0, 0.0]], atol=1e-15)
    # turning at 2 rad/s: 0.04 + 4 / 10 = 0.44 rad; a point 1 m out moves 0.44 m more
    poses = stopping_poses([0.0, 0.0, math.pi / 2, 0.8], 2.0, 1.0, 5.0, 0.02, 1.0)
    assert poses.shape == (79, 3)
    np.testing.assert_allclose(poses[-1], [0.0, 0.336, math.pi / 2 + 0.44], atol=1e-15)
    # backing up and turning right brake the same way
    np.testing.assert_allclose(
        stopping_poses([0.0, 0.0, 0.0, -0.4], -1.0, 1.0, 5.0, 0.02, 1.0)[-1],
        [-0.4 * 0.02 - 0.08, 0.0, -0.02 - 0.1],
        atol=1e-15,
    )
    assert stopping_poses([0.0, 0.0, 0.0, 0.0], 0.0, 1.0, 5.0, 0.02, 1.0).shape == (2, 3)


def test_arm_pose_hits_by_hand():
    # the arm held straight out, the gripper centre 5 cm above the table's top (0.75 m;
    # the fingers' bottom 1 cm above it): clear everywhere; 10 cm lower, inside the table
    # where the base (0.9 m from it, facing it) puts the gripper over it at x = 1.55
    q = np.array([0.80 - 0.0975 - 0.16, 0.0, 0.6])
    bases = [[0.5, 0.0, 0.0], [0.9, 0.0, 0.0], [0.9, 0.0, math.pi]]
    np.testing.assert_array_equal(arm_pose_hits(bases, q, [OPEN] * 2, TABLE), [-1, -1, -1])
    np.testing.assert_array_equal(arm_pose_hits(bases, q - [0.1, 0, 0], [OPEN] * 2, TABLE),
                                  [-1, 0, -1])  # fmt: skip
    # a cup on the table under the gripper: a disc (after the boxes: none here)
    cup = [[1.55, 0.0, 0.04, 0.85]]
    np.testing.assert_array_equal(arm_pose_hits(bases, q, [OPEN] * 2, [], discs=cup), [-1, 0, -1])
    # the fingers only against a finger disc: the gripper centre inside it is no hit
    np.testing.assert_array_equal(
        arm_pose_hits(bases, q, [OPEN] * 2, [], finger_discs=cup), [-1, -1, -1]
    )
    # above the cup's rim (the fingers' bottom at 0.86): clear
    np.testing.assert_array_equal(
        arm_pose_hits(bases, q + [0.1, 0, 0], [OPEN] * 2, [], discs=cup), [-1, -1, -1]
    )


def _drive(state, omega=0.0, arm=TUCKED, fingers=OPEN, cups=None, braking=None):
    """One update of a KitchenGoToPose at ``state`` (target far ahead): status, failure."""
    n = 0 if cups is None else len(cups)
    names = ["table"] + [f"cup_{j}" for j in range(n)]
    drive = KitchenGoToPose(0.02, obstacles=TABLE, radius=0.32, names=names, cups=n,
                            workspace=(-5.0, 5.0, -5.0, 5.0), braking=braking)  # fmt: skip
    context = drive.CreateDefaultContext()
    drive.get_state_input_port().FixValue(context, state)
    drive.get_target_input_port().FixValue(context, [4.0, state[1], state[2], 0.0])
    drive.get_arm_position_input_port().FixValue(context, arm)
    drive.get_finger_position_input_port().FixValue(context, fingers)
    if n:
        drive.get_cup_positions_input_port().FixValue(context, np.ravel(cups))
    xd = context.get_mutable_discrete_state(0)
    xd.SetFromVector([state[3], omega, ActionStatus.RUNNING, *np.zeros(xd.size() - 3)])
    values = drive.EvalUniquePeriodicDiscreteUpdate(context)
    status = ActionStatus(int(values.get_vector(0).get_value()[2]))
    context.SetDiscreteState(values)
    return status, values.get_vector(0).get_value()[:2], drive.failure(context)


def test_kitchen_goto_pose_stops_before_the_footprint_enters_a_box():
    # 0.8 m/s towards the table's edge at x = 1.5: the base stops within 0.336 m, so it
    # fails once its centre is less than 1.5 - 0.32 - 0.336 = 0.844 m from the edge's x
    status, command, why = _drive([0.85, 0.0, 0.0, 0.8])
    assert status == ActionStatus.FAILED and list(command) == [0.0, 0.0]
    assert why == ("stopped at [x, y, phi] = [0.85, 0.0, 0.0]: the footprint would enter "
                   "table at [1.186, 0.0, 0.0]")  # fmt: skip
    status, command, why = _drive([0.84, 0.0, 0.0, 0.8])
    assert status == ActionStatus.RUNNING and why == ""
    # braking at 3 m/s^2 (the plant's wheels stop harder than the command's a_max): it
    # stops within 0.016 + 0.8^2 / 6 = 0.123 m, so it fails from 1.5 - 0.32 - 0.123 m
    assert _drive([1.05, 0.0, 0.0, 0.8], braking=(3.0, 20.0))[0] == ActionStatus.RUNNING
    assert _drive([1.06, 0.0, 0.0, 0.8], braking=(3.0, 20.0))[0] == ActionStatus.FAILED
    # slow, or driving away, or past it sideways: running
    assert _drive([1.1, 0.0, 0.0, 0.1])[0] == ActionStatus.RUNNING
    assert _drive([1.1, 0.0, math.pi, 0.8])[0] == ActionStatus.RUNNING
    assert _drive([1.0, 0.9, 0.0, 0.8])[0] == ActionStatus.RUNNING
    # a base already too close may back away, not go further in
    assert _drive([1.2, 0.0, 0.0, -0.3])[0] == ActionStatus.RUNNING
    assert _drive([1.2, 0.0, 0.0, 0.05])[0] == ActionStatus.FAILED


def test_kitchen_goto_pose_stops_before_the_turning_arm_sweeps_a_cup():
    # the robot parked beside the table (footprint clear), the arm held out left over the
    # table with its fingers' bottom below a standing cup's rim (0.85), turning left
    arm = arm_inverse([0.05, 0.6, 0.83 - 0.0975])  # gripper 0.6 m to the left at z 0.83
    base = [2.0, -0.9, 0.0, 0.0]  # the gripper over (2.05, -0.3), 0.2 m in from the edge
    cups = [[1.9, -0.3, 0.8]]  # 2 cm from the left finger, which a left turn swings in
    status, _, why = _drive(base, 1.0, arm, cups=cups)
    assert status == ActionStatus.FAILED
    assert why.startswith("stopped at [x, y, phi] = [2.0, -0.9, 0.0]: the arm would enter cup_0 at")
    assert _drive(base, -1.0, arm, cups=cups)[0] == ActionStatus.RUNNING  # turning away
    assert _drive(base, 1.0, arm)[0] == ActionStatus.RUNNING  # no cup there
    # a cup between the fingers: held while neither finger is open (a squeezed cup sways
    # in the grip as the base turns, a finger read 4.5 mm below holds_object's 40 mm and
    # the drive stopped for the cup it carried), around open fingers an obstacle of theirs
    held = [[2.05, -0.3, 0.83]]
    assert _drive(base, 1.0, arm, [0.035, 0.05], cups=held)[0] == ActionStatus.RUNNING
    status, _, why = _drive(base, 1.0, arm, cups=held)
    assert status == ActionStatus.FAILED and why.endswith("the arm would enter cup_0 at "
                                                          "[2.0, -0.9, 0.04]")  # fmt: skip
    # the arm already over the table's top at its height may leave it (a way out of a box)
    low = arm_inverse([0.05, 0.6, 0.74 - 0.0975])
    assert _drive(base, -1.0, low)[0] == ActionStatus.RUNNING


def test_kitchen_goto_pose_bad_arguments_are_named():
    with pytest.raises(RepertoireError, match="radius must be finite and > 0, got 0.0"):
        KitchenGoToPose(obstacles=TABLE, radius=0.0)
    with pytest.raises(RepertoireError, match="cups must be a whole number >= 0, got -1"):
        KitchenGoToPose(obstacles=TABLE, radius=0.3, cups=-1)
    with pytest.raises(RepertoireError, match=r"names must name the 1 boxes, then the 0 cups"):
        KitchenGoToPose(obstacles=TABLE, radius=0.3, names=["a", "b"])
    with pytest.raises(
        RepertoireError, match=r"braking must be 2 finite values > 0, got \(3.0, 0.0\)"
    ):
        KitchenGoToPose(obstacles=TABLE, radius=0.3, braking=(3.0, 0.0))
    with pytest.raises(RepertoireError, match="no cup_positions port"):
        KitchenGoToPose(obstacles=TABLE, radius=0.3).get_cup_positions_input_port()


def test_a_drive_across_table_0_stops_short_and_names_it():
    # unchecked, GoToPose drove straight into table_0 (the controller knows no obstacles)
    cups = {"cup_0": [2.0, 1.2, 0.8001], "cup_1": [2.3, 1.0, 0.8001]}
    scenario = KitchenScenario(action="goto_pose", initial_pose=[0.6, 1.3, 0.0],
                               goto_target=[3.2, 1.3, 0.0, 0.0], cups=list(cups),
                               cup_positions=cups)  # fmt: skip
    results = run_kitchen_sequence([("goto_pose", scenario.goto_target)], scenario)[0]
    assert [(r.action, r.status) for r in results] == [("goto_pose", "FAILED")]
    assert results[0].reason == ("stopped at [x, y, phi] = [1.063, 1.3, 0.0]: the footprint "
                                 "would enter table_0 at [1.184, 1.3, 0.0]")  # fmt: skip
    # run on: the base stops short of the table, touching nothing
    diagram, simulator = kitchen_simulator(scenario)
    simulator.Initialize()
    simulator.AdvanceTo(3.0)
    context = simulator.get_context()
    assert action_status(diagram, context) == ActionStatus.FAILED
    state = robot_state(diagram, context)
    assert abs(state[3]) < 1e-3 and state[0] < 1.5 - 0.32
    assert np.all(box_gaps(state[:2], KITCHEN_OBSTACLES)[0] >= 0.32)
    assert check_kitchen_action(diagram, context)["touching_furniture"] == 0.0
    for name, p in cups.items():
        np.testing.assert_allclose(cup_position(diagram, context, name), p, atol=1e-3)
