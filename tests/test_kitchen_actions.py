import math

import numpy as np
import pytest
from repertoire.diagrams.kitchen import KITCHEN_OBSTACLES
from repertoire.systems.go_to_pose import ActionStatus
from repertoire.systems.kitchen_actions import (
    FINGER_CLOSED,
    FINGER_OPEN,
    FootprintGuard,
    Grip,
    Put,
    Reach,
    arm_forward,
    arm_inverse,
    arm_inverse_rows,
    arm_way_hits,
    chassis_to_world,
    discs_in_boxes,
    fingers_blocked,
    fingers_in_boxes,
    fingers_open,
    footprint_hits,
    holds_object,
    joint_line_points,
    joint_lines,
    joint_step,
    point_in_boxes,
    points_in_boxes,
    support_under,
)

from repertoire.errors import RepertoireError

BASE = np.array([2.0, 0.55, math.pi / 2, 0.0])  # in front of table_0, facing it
OPEN = [FINGER_OPEN] * 2


def test_arm_kinematics_closed_form():
    # yaw 90 deg: the gripper is e to the left of the column (COLUMN_X = 0.05, LIFT_BASE_Z = 0.16)
    np.testing.assert_allclose(arm_forward([0.5, math.pi / 2, 0.6]), [0.05, 0.6, 0.66], atol=1e-15)
    q = np.array([0.55, -0.7, 0.42])
    np.testing.assert_allclose(arm_inverse(arm_forward(q)), q, atol=1e-12)
    assert arm_inverse([0.05 + 0.9, 0.0, 0.6]) is None  # extend 0.9 > 0.85
    assert arm_inverse([0.5, 0.0, 1.2]) is None  # lift 1.04 > 0.80
    assert arm_inverse([-0.5, 0.01, 0.6]) is None  # behind the column: yaw ~ pi
    assert arm_inverse([np.nan, 0.0, 0.6]) is None


def test_joint_step_synchronizes_the_joints():
    # lift needs 0.15 / 0.15 = 1 s, yaw 0.8 / 0.8 = 1 s: 10 steps of 0.1 s each
    step = joint_step([0, 0, 0], [0.15, 0.8, 0.0], (0.15, 0.8, 0.2), 0.1)
    np.testing.assert_allclose(step, [0.015, 0.08, 0.0])
    # extend is the slow one (0.4 m at 0.2 m/s = 2 s): lift moves at half its limit
    np.testing.assert_allclose(
        joint_step([0, 0, 0], [0.15, 0, 0.4], (0.15, 0.8, 0.2), 0.1), [0.0075, 0, 0.02]
    )
    np.testing.assert_allclose(
        joint_step([0, 0, 0], [0.01, 0, 0], (0.15, 0.8, 0.2), 0.1), [0.01, 0, 0]
    )


def test_boxes_by_hand():
    boxes = [[1.0, 0.0, math.pi / 2, 0.6, 0.4, 0.75]]  # rotated 90 deg: 0.8 wide in x, 1.2 in y
    assert point_in_boxes([1.41, 0.0, 0.7], boxes) == -1  # 0.41 from the centre > 0.4
    assert point_in_boxes([1.39, 0.55, 0.7], boxes) == 0
    assert point_in_boxes([1.39, 0.55, 0.76], boxes) == -1  # above the top
    assert point_in_boxes([1.39, 0.55, 0.76], boxes, margin=0.02) == 0
    # disc of radius 0.3 at x = 1.0 + 0.4 + 0.29 overlaps; at + 0.31 does not
    assert footprint_hits([1.69, 0.0], boxes, 0.3) == 0
    assert footprint_hits([1.71, 0.0], boxes, 0.3) == -1
    # corner: distance to the corner (1.4, 0.6) is hypot(0.2, 0.2) = 0.283
    assert footprint_hits([1.6, 0.8], boxes, 0.3) == 0
    assert footprint_hits([1.6, 0.8], boxes, 0.28) == -1
    np.testing.assert_allclose(
        chassis_to_world(BASE, [0.85, 0.0, 0.7]), [2.0, 1.4, 0.7975], atol=1e-12
    )


def _fixed(system, time=0.0, state=None, **ports):
    ctx = system.CreateDefaultContext()
    for name, value in ports.items():
        system.GetInputPort(name).FixValue(ctx, np.asarray(value, dtype=float))
    if state is not None:
        ctx.SetDiscreteState(np.asarray(state, dtype=float))
    ctx.SetTime(time)
    return ctx


def _update(system, ctx):
    return system.EvalUniquePeriodicDiscreteUpdate(ctx).get_vector().get_value()


def test_reach_moves_succeeds_and_fails():
    reach = Reach(0.02, obstacles=KITCHEN_OBSTACLES)
    q0 = [0.62, 0.0, 0.25]
    target = arm_forward([0.62, 0.0, 0.35])
    ctx = _fixed(reach, finger_position=OPEN, arm_position=q0, target=target, base_state=BASE)
    xd = _update(reach, ctx)
    # first update: command starts at the measured joints, extend moves 0.2 m/s * 0.02 s
    np.testing.assert_allclose(xd, [0.62, 0.0, 0.254, ActionStatus.RUNNING, 1, 0, 0, 0])
    assert reach.get_status_output_port().Eval(ctx) == ActionStatus.RUNNING
    # measured at the target: succeeded, command held
    ctx = _fixed(
        reach, 1.0, [0.62, 0, 0.35, 0, 1, 0, 0, 0], arm_position=[0.62, 0, 0.345],
        finger_position=OPEN, target=target, base_state=BASE,
    )  # fmt: skip
    np.testing.assert_allclose(_update(reach, ctx)[:4], [0.62, 0, 0.35, ActionStatus.SUCCEEDED])
    # out of reach, and inside table_0 (gripper 0.1 m below its top): failed at once, no motion
    for bad in ([2.0, 0.0, 0.6], [0.85, 0.0, 0.55]):
        ctx = _fixed(reach, finger_position=OPEN, arm_position=q0, target=bad, base_state=BASE)
        np.testing.assert_allclose(_update(reach, ctx)[:4], [*q0, ActionStatus.FAILED])
    # timeout after 10 s from the start time stored in the state
    ctx = _fixed(
        reach, 12.5, [0.6, 0, 0.3, 0, 1, 2.5, 0, 2.5], arm_position=q0, target=target,
        finger_position=OPEN, base_state=BASE,
    )  # fmt: skip
    assert _update(reach, ctx)[3] == ActionStatus.TIMED_OUT
    # a finished action stays finished
    ctx.SetDiscreteState([0.6, 0, 0.3, ActionStatus.FAILED, 1, 0, 0, 0])
    assert _update(reach, ctx)[3] == ActionStatus.FAILED


def test_grip_closes_then_judges_by_contact():
    grip = Grip(0.02)
    ctx = _fixed(grip, finger_position=[FINGER_OPEN] * 2, base_state=BASE)
    xd = _update(grip, ctx)
    np.testing.assert_allclose(xd, [0.074, 0.074, ActionStatus.RUNNING, 1, 0, 0, 0])
    # closed setpoint reached at t = 1.0: phase 1 starts; settling for 0.2 s
    ctx = _fixed(grip, 1.0, [0.0305, 0.0305, 0, 1, 0, 0, 0], finger_position=[0.05, 0.05],
                 base_state=BASE)  # fmt: skip
    np.testing.assert_allclose(_update(grip, ctx), [0.03, 0.03, 0, 1, 0, 1, 1.0])
    # after settling: blocked at 0.05 (>= 0.03 + 0.01) -> succeeded; closed on nothing -> failed
    for measured, status in ((0.05, ActionStatus.SUCCEEDED), (0.031, ActionStatus.FAILED)):
        ctx = _fixed(grip, 1.3, [0.03, 0.03, 0, 1, 0, 1, 1.0], finger_position=[measured] * 2,
                     base_state=BASE)  # fmt: skip
        assert _update(grip, ctx)[2] == status


def test_put_carries_lowers_and_releases():
    put = Put(0.02, obstacles=KITCHEN_OBSTACLES)
    q0 = [0.5, 0.0, 0.8]
    target = [0.65, 0.25, 0.7036]  # on table_0, the cup's bottom 3.6 mm above the top
    ports = dict(arm_position=q0, finger_position=[0.05, 0.05], target=target, base_state=BASE)
    xd = _update(put, _fixed(put, **ports))
    goal = arm_inverse(np.add(target, [0, 0, 0.05]))
    np.testing.assert_allclose(xd[:3], joint_step(q0, goal, put.speeds, 0.02))
    np.testing.assert_allclose(xd[3:5], [FINGER_CLOSED] * 2)  # holding the cup
    assert xd[5] == ActionStatus.RUNNING
    # phase 2: opening; measured open -> succeeded
    at = arm_inverse(target)
    state = [*at, 0.07, 0.07, 0, 1, 0, 2, 1.0]
    ports |= dict(arm_position=at, finger_position=[FINGER_OPEN] * 2)
    xd = _update(put, _fixed(put, 1.5, state, **ports))
    np.testing.assert_allclose(xd[3:6], [0.071, 0.071, ActionStatus.SUCCEEDED])
    # a target that puts the cup's bottom 2 cm into the table fails at once
    ports |= dict(arm_position=q0, target=[0.65, 0.25, 0.6726])
    assert _update(put, _fixed(put, **ports))[5] == ActionStatus.FAILED


def test_joint_line_points_spacing_and_ends():
    q0, q1 = [0.5, -1.0, 0.3], [0.6, 1.0, 0.7]
    pts = joint_line_points(q0, q1, spacing=0.01)
    # bound on the way: 0.1 (lift) + 0.4 (extend) + 0.7 * 2.0 (yaw arc) = 1.9 m -> 191 points
    assert len(pts) == 191
    np.testing.assert_allclose(pts[0], arm_forward(q0), atol=1e-15)
    np.testing.assert_allclose(pts[-1], arm_forward(q1), atol=1e-15)
    assert np.max(np.linalg.norm(np.diff(pts, axis=0), axis=1)) <= 0.01
    assert len(joint_line_points(q0, q0)) == 2  # no motion: both ends


def test_reach_refuses_a_way_through_a_table():
    reach = Reach(0.02, obstacles=KITCHEN_OBSTACLES)
    # BASE faces table_0 (edge 0.35 m ahead of the axle, top 0.75 m): the target 0.32 m
    # ahead, below the top, is clear; from over the table the straight joint-space way
    # crosses the top (it dragged the robot under the table), from beside it it does not
    target = [0.32, 0.0, 0.47]
    for q0, status in (([0.62, 0.0, 0.6], ActionStatus.FAILED),
                       ([0.62, 0.0, 0.27], ActionStatus.RUNNING)):  # fmt: skip
        ctx = _fixed(reach, finger_position=OPEN, arm_position=q0, target=target, base_state=BASE)
        assert _update(reach, ctx)[3] == status
    # a start a millimetre inside the top (the gripper resting low) is not an entry
    low = arm_inverse(_at_world_height([0.85, 0.0], 0.749))
    ctx = _fixed(
        reach, finger_position=OPEN, arm_position=low, target=[0.85, 0.0, 0.80], base_state=BASE
    )
    assert _update(reach, ctx)[3] == ActionStatus.RUNNING


def test_fingers_in_boxes_by_hand():
    # chassis at the origin facing +x: the gripper centre is at world (0.05 + e, 0, 0.2575 +
    # lift) for arm yaw 0, the fingers (3 cm along x, 2 cm along y, 8 cm tall) at y = +-f
    box = [[1.0, 0.0, 0.0, 0.2, 0.5, 0.75]]  # x in [0.8, 1.2], y in [-0.5, 0.5], top 0.75
    base, open_ = np.zeros(4), [[0.075, 0.075]] * 2

    def hit(base, lift, e, span=open_, boxes=box, margin=0.0):
        return int(fingers_in_boxes(base, [lift, 0.0, e], span, boxes, margin)[0])

    # over the top: the fingers' bottom 4 cm below the centre (world z 0.7901 / 0.7899)
    assert hit(base, 0.5326, 0.85) == -1 and hit(base, 0.5324, 0.85) == 0
    assert hit(base, 0.5326, 0.85, margin=0.001) == 0  # grown on top
    # in front of it, below the top: the fingers' front faces 1.5 cm ahead of the centre
    assert hit(base, 0.3, 0.8 - 0.05 - 0.0151) == -1 and hit(base, 0.3, 0.8 - 0.05 - 0.0149) == 0
    # beside it: the centre 5 cm beyond its side (world y 0.55), a finger at -f reaches over
    side = np.array([0.0, 0.55, 0.0, 0.0])
    closed, wide = [[0.039, 0.039]] * 2, [[0.041, 0.041]] * 2  # outer faces at 0.049, 0.051
    assert hit(side, 0.3, 0.85, closed) == -1 and hit(side, 0.3, 0.85, wide) == 0
    # a finger swept from 0.03 to 0.075 (closing) covers everything between
    assert hit(side, 0.3, 0.85, [[0.03, 0.075]] * 2) == 0
    # a box turned 45 deg (a diamond, its corner at x = 1 - 0.1 sqrt 2): exact, not its
    # bounding box; the left finger centred 5 cm off the corner's line, from y 0.04 to 0.06,
    # meets the diamond's edge at x = 0.8586 + 0.04
    diamond = [[1.0, 0.0, math.pi / 4, 0.1, 0.1, 0.75]]
    off = np.array([0.0, 0.05 - 0.075, 0.0, 0.0])
    corner = 1.0 - 0.1 * math.sqrt(2)
    for face, expected in ((corner + 0.04 - 1e-4, -1), (corner + 0.04 + 1e-4, 0)):
        assert hit(off, 0.3, face - 0.015 - 0.05, boxes=diamond) == expected
    # vectorized over samples; the first box in the list wins
    two = box + diamond
    q = [[0.3, 0.0, 0.5], [0.3, 0.0, 0.85]]
    np.testing.assert_array_equal(fingers_in_boxes(base, q, open_, two), [-1, 0])


def test_reach_checks_the_fingers_not_only_the_centre():
    reach = Reach(0.02, obstacles=KITCHEN_OBSTACLES)
    # BASE faces table_0 (edge 0.35 m ahead of the axle, top at world z 0.75): a reach
    # from 5 cm before the edge to 0.25 m over the table, level. The gripper centre's way
    # clears the top at world z 0.77, the fingers (their bottoms 4 cm lower) do not; the
    # fingers clear it from a centre 4 cm above the top on
    for z_world, status in ((0.77, ActionStatus.FAILED), (0.7899, ActionStatus.FAILED),
                            (0.7901, ActionStatus.RUNNING)):  # fmt: skip
        q0, target = (
            arm_inverse(_at_world_height([0.30, 0.0], z_world)),
            _at_world_height([0.60, 0.0], z_world),
        )
        centres = [chassis_to_world(BASE, a) for a in joint_line_points(q0, arm_inverse(target))]
        assert all(point_in_boxes(p, KITCHEN_OBSTACLES) == -1 for p in centres)
        ctx = _fixed(reach, finger_position=OPEN, arm_position=q0, target=target, base_state=BASE)
        assert _update(reach, ctx)[3] == status


def test_holds_object_by_hand():
    # blocked: at least 1 cm short of closed (0.03); open: within 5 mm of 0.075
    assert fingers_blocked([0.04, 0.05]) and not fingers_blocked([0.0399, 0.05])
    assert fingers_open([0.0701, 0.08]) and not fingers_open([0.0699, 0.08])
    assert holds_object([0.05, 0.05])  # on a cup (radius 4 cm, fingers 1 cm half thick)
    assert holds_object([0.04, 0.0699])
    assert not holds_object([0.0399, 0.05])  # closed on nothing
    assert not holds_object(OPEN) and not holds_object([0.05, 0.0701])  # one open
    assert not holds_object([np.nan, 0.05])


def test_reach_with_a_held_cup_checks_its_bottom():
    # the level way of test_reach_checks_the_fingers_not_only_the_centre over table_0's
    # top (world z 0.75): the fingers (4 cm below the centre) clear it from a centre at
    # 0.79 on; a held cup's bottom (5 cm below, or cup_half_height) from 0.80 on
    cases = (
        (0.7901, OPEN, 0.05, ActionStatus.RUNNING),  # no cup: as before
        (0.7901, [0.05, 0.05], 0.05, ActionStatus.FAILED),
        (0.7999, [0.05, 0.05], 0.05, ActionStatus.FAILED),
        (0.8001, [0.05, 0.05], 0.05, ActionStatus.RUNNING),
        (0.7901, [0.05, 0.05], 0.04, ActionStatus.RUNNING),  # a cup 8 cm tall clears it
        (0.7901, [0.0399, 0.0399], 0.05, ActionStatus.RUNNING),  # closed on nothing
    )
    for z_world, fingers, half_height, status in cases:
        reach = Reach(0.02, obstacles=KITCHEN_OBSTACLES, cup_half_height=half_height)
        q0 = arm_inverse(_at_world_height([0.30, 0.0], z_world))
        target = _at_world_height([0.60, 0.0], z_world)
        ports = dict(arm_position=q0, target=target, base_state=BASE)
        xd = _update(reach, _fixed(reach, finger_position=fingers, **ports))
        assert xd[3] == status, (z_world, fingers, half_height)
        if status == ActionStatus.FAILED:  # at once, the command where the arm is
            np.testing.assert_allclose(xd[:3], q0)


def test_discs_in_boxes_by_hand():
    box = [[0.0, 0.0, 0.0, 1.0, 0.5, 0.75]]  # x in [-1, 1], y in [-0.5, 0.5], top 0.75
    # a cup bottom (radius 4 cm) 3 cm beyond the edge: its rim is over the top, its centre
    # not; above the top, 5 cm beyond the edge, at a corner (4.2 cm away) it is clear
    p = [[1.03, 0.0, 0.74], [1.03, 0.0, 0.76], [1.05, 0.0, 0.74], [1.03, 0.53, 0.74]]
    np.testing.assert_array_equal(discs_in_boxes(p, 0.04, box), [0, -1, -1, -1])
    assert point_in_boxes(p[0], box) == -1  # the point under the centre misses it
    np.testing.assert_array_equal(discs_in_boxes(p, 0.04, box, margin=0.0025), [0, -1, -1, 0])
    assert discs_in_boxes([0.0, 0.0, 0.75], 0.04, box)[0] == 0  # touching counts
    # radius 0 and no margin: the point test; vectorised as point_in_boxes
    pts = np.random.default_rng(4).uniform([-3, -2.5, 0.5], [3, 2.5, 1.3], (300, 3))
    expected = [point_in_boxes(q, KITCHEN_OBSTACLES) for q in pts]
    np.testing.assert_array_equal(points_in_boxes(pts, KITCHEN_OBSTACLES), expected)
    np.testing.assert_array_equal(discs_in_boxes(pts, 0.0, KITCHEN_OBSTACLES), expected)


def test_arm_way_hits_agree_with_a_sample_by_sample_check():
    # random ways of the arm before table_0 (batched, bases per row, pruned by height and
    # reach) against each sample checked on its own, first box in the boxes' order
    rng = np.random.default_rng(11)
    n = 8
    base = np.column_stack([rng.uniform(1.5, 2.5, n), rng.uniform(0.2, 0.6, n),
                            rng.uniform(0.8, 2.3, n), np.zeros(n)])  # fmt: skip
    lo, hi = [0.5, -1.2, 0.25], [0.8, 1.2, 0.85]
    q0, q1 = rng.uniform(lo, hi, (n, 3)), rng.uniform(lo, hi, (n, 3))
    boxes = np.vstack([KITCHEN_OBSTACLES, [[2.2, 1.1, 0.0, 0.04, 0.04, 0.85]]])  # a cup
    span = [[0.05, 0.05]] * 2
    for cup in (None, (0.05, 0.04)):
        got = arm_way_hits(base, q0, q1, span, boxes, 0.01, cup)
        samples = joint_lines(q0, q1, 0.01, 0.0912)
        for r in range(n):
            per_sample = []
            for q in samples[r]:
                centre = chassis_to_world(base[r], arm_forward(q))
                found = [point_in_boxes(centre, boxes, 0.01),
                         fingers_in_boxes(base[r], q, span, boxes, 0.01)[0]]  # fmt: skip
                if cup is not None:
                    found.append(discs_in_boxes(centre - [0, 0, 0.05], 0.04, boxes, 0.01)[0])
                per_sample.append(min([f for f in found if f >= 0], default=-1))
            k = 0
            while k < len(per_sample) and per_sample[k] >= 0 and per_sample[k] == per_sample[0]:
                k += 1  # a way starting in a box: entries after it leaves
            assert got[r] == next((i for i in per_sample[k:] if i >= 0), -1), (r, cup)
        assert np.any(got >= 0) and np.any(got < 0)  # both kinds among the ways
    with pytest.raises(RepertoireError, match="spacing must be finite and > 0, got 0.0"):
        arm_way_hits(base, q0, q1, span, boxes, spacing=0.0)
    with pytest.raises(RepertoireError, match="obstacle boxes must be finite rows of 6"):
        arm_way_hits(base, q0, q1, span, [[1.0, 2.0, 3.0]])
    # the rows of arm_inverse: out of reach (or not finite) where arm_inverse says None
    a = [[0.9, 0.0, 0.7], [0.05, 0.0, 0.7], [0.9, 0.0, 1.5], [np.nan, 0.0, 0.7]]
    q, ok = arm_inverse_rows(a)
    np.testing.assert_array_equal(ok, [arm_inverse(p) is not None for p in a])
    np.testing.assert_allclose(q[0], arm_inverse(a[0]))


def test_reach_with_a_held_cup_checks_its_whole_bottom():
    # straight down beside table_0's edge (world y 0.9; BASE faces it, the slide along
    # +y): the gripper centre at world y 0.88, the fingers' front faces at 0.895 and the
    # point under the centre clear the table; the held cup's rim (4 cm radius) reaches
    # 2 cm over the top and its bottom ends 2 cm below it
    start, target = _at_world_height([0.33, 0.0], 0.85), _at_world_height([0.33, 0.0], 0.78)
    ports = dict(arm_position=arm_inverse(start), target=target, base_state=BASE)
    for radius, fingers, status in ((0.04, [0.05, 0.05], ActionStatus.FAILED),
                                    (0.015, [0.05, 0.05], ActionStatus.RUNNING),
                                    (0.04, OPEN, ActionStatus.RUNNING)):  # fmt: skip
        reach = Reach(0.02, obstacles=KITCHEN_OBSTACLES, cup_radius=radius)
        assert _update(reach, _fixed(reach, finger_position=fingers, **ports))[3] == status
    with pytest.raises(RepertoireError, match="cup_radius must be finite and > 0, got 0.0"):
        Reach(0.02, cup_radius=0.0)


def test_put_checks_the_fingers_carrying_and_opening():
    # chassis at the origin facing +x, a table under x in [0.7, 1.3], and a tall block on it
    # beside the target (its face 7 cm to the left of the cup's centre)
    table = [1.0, 0.0, 0.0, 0.3, 0.3, 0.75]
    block = [0.9, 0.17, 0.0, 0.05, 0.1, 1.2]  # y from 0.07
    base = [0.0, 0.0, 0.0, 0.0]
    target = [0.9, 0.0, 0.801 - 0.0975]  # the cup's bottom 1 mm above the top
    ports = dict(arm_position=[0.6, 0.0, 0.5], target=target, base_state=base)
    # carrying, the fingers on the cup (0.05: outer faces at 0.06) pass the block; opening
    # at the target (to 0.075: faces at 0.085) they would hit it
    put = Put(0.02, obstacles=[table, block])
    assert _update(put, _fixed(put, finger_position=[0.05, 0.05], **ports))[5] == (
        ActionStatus.FAILED
    )
    clear = Put(0.02, obstacles=[table, [0.9, 0.188, 0.0, 0.05, 0.1, 1.2]])  # face at 0.088
    assert _update(clear, _fixed(clear, finger_position=[0.05, 0.05], **ports))[5] == (
        ActionStatus.RUNNING
    )
    # fingers measured wide open while carrying (no cup: they sweep 0.03 .. 0.08, faces
    # out to 0.09) hit it
    xd = _update(clear, _fixed(clear, finger_position=[0.08, 0.08], **ports))
    assert xd[5] == ActionStatus.FAILED


def _at_world_height(xy, z_world):
    """The chassis-frame point at chassis ``xy`` whose world height is ``z_world``."""
    return [xy[0], xy[1], z_world - chassis_to_world(BASE, [0.0, 0.0, 0.0])[2]]


def test_support_under_by_hand():
    boxes = [[1.0, 0.0, math.pi / 2, 0.6, 0.4, 0.75]]  # top x in [0.6, 1.4], y in [-0.6, 0.6]
    assert support_under([1.0, 0.0, 0.751], boxes, 0.04, 0.02) == 0
    assert support_under([1.359, 0.0, 0.751], boxes, 0.04, 0.02) == 0  # the rim 1 mm inside
    assert support_under([1.361, 0.0, 0.751], boxes, 0.04, 0.02) == -1  # 1 mm over the edge
    assert support_under([1.0, 0.561, 0.751], boxes, 0.04, 0.02) == -1
    assert support_under([1.0, 0.0, 0.769], boxes, 0.04, 0.02) == 0  # 1.9 cm drop
    assert support_under([1.0, 0.0, 0.771], boxes, 0.04, 0.02) == -1
    assert support_under([1.0, 0.0, 0.749], boxes, 0.04, 0.02) == -1  # below the top
    assert support_under([2.0, 0.0, 0.751], boxes, 0.04, 0.02) == -1  # over the floor


def test_put_refuses_a_target_with_nothing_to_stand_on():
    put = Put(0.02, obstacles=KITCHEN_OBSTACLES)
    # BASE faces table_0 (its edge 0.35 m ahead of the axle): the cup's bottom 1.1 mm
    # above the top, its centre 0.05 m (whole disc on the top) and 0.03 m (1 cm over
    # the edge) inside the edge, or 0.05 m before it (in the air)
    ports = dict(arm_position=[0.5, 0.0, 0.8], finger_position=[0.05, 0.05], base_state=BASE)
    for x, status in ((0.40, ActionStatus.RUNNING), (0.38, ActionStatus.FAILED),
                      (0.30, ActionStatus.FAILED)):  # fmt: skip
        assert _update(put, _fixed(put, target=[x, 0.0, 0.7036], **ports))[5] == status
    # 3 cm above the top: dropped from too high
    assert _update(put, _fixed(put, target=[0.5, 0.0, 0.7336], **ports))[5] == ActionStatus.FAILED
    # without obstacles there is no world to stand on: only reach is checked
    free = Put(0.02)
    xd = _update(free, _fixed(free, target=[0.30, 0.0, 0.7036], **ports))
    assert xd[5] == ActionStatus.RUNNING


def test_footprint_guard():
    guard = FootprintGuard(KITCHEN_OBSTACLES, 0.32)
    ctx = guard.CreateDefaultContext()
    guard.get_input_port().FixValue(ctx, [2.1, 1.3, 0.0, 0.0])  # table_0's centre
    assert np.all(np.isnan(guard.get_output_port().Eval(ctx)))
    guard.get_input_port().FixValue(ctx, [0.0, 0.0, 0.3, 0.1])
    np.testing.assert_allclose(guard.get_output_port().Eval(ctx), [0.0, 0.0, 0.3, 0.1])
    # the remembered answer follows the target: same x, y with other heading, then a table
    guard.get_input_port().FixValue(ctx, [0.0, 0.0, -1.0, 0.0])
    np.testing.assert_allclose(guard.get_output_port().Eval(ctx), [0.0, 0.0, -1.0, 0.0])
    guard.get_input_port().FixValue(ctx, [2.0, -1.6, 0.0, 0.0])  # table_1's centre
    assert np.all(np.isnan(guard.get_output_port().Eval(ctx)))


def test_bad_construction_names_the_value():
    with pytest.raises(RepertoireError, match="period"):
        Reach(0.0)
    with pytest.raises(RepertoireError, match="speeds"):
        Reach(speeds=(0.1, -1.0, 0.2))
    with pytest.raises(RepertoireError, match="rows of 6"):
        Reach(obstacles=[1.0, 2.0])
    with pytest.raises(RepertoireError, match="cup_half_height must be finite and > 0, got 0.0"):
        Reach(cup_half_height=0.0)
    with pytest.raises(RepertoireError, match="closed"):
        Grip(closed=0.2)
    with pytest.raises(RepertoireError, match="radius"):
        FootprintGuard(KITCHEN_OBSTACLES, float("nan"))
