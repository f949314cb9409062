"""Standing cups as obstacles of the kitchen arm (systems/kitchen_geometry.py, Reach, Put)."""

import math

import numpy as np
import pytest
from repertoire.diagrams.kitchen import KITCHEN_OBSTACLES
from repertoire.systems.go_to_pose import ActionStatus
from repertoire.systems.kitchen_actions import FINGER_OPEN, Put, Reach
from repertoire.systems.kitchen_geometry import (
    FINGER_HALF,
    arm_forward,
    arm_inverse,
    arm_way_hits,
    chassis_to_world,
    discs_in_discs,
    fingers_in_boxes,
    joint_lines,
    points_in_discs,
)

from repertoire.errors import RepertoireError

BASE = np.array([2.0, 0.55, math.pi / 2, 0.0])  # in front of table_0, facing it
OPEN = [FINGER_OPEN] * 2
CUP = [2.0, 1.1, 0.8001]  # a cup on table_0, 0.55 m ahead of the axle


def _random_ways(seed, n):
    """n random arm ways before table_0: base poses (x, y, yaw, 0) and joint starts and ends."""
    rng = np.random.default_rng(seed)
    base = np.column_stack([rng.uniform(1.8, 2.2, n), rng.uniform(0.4, 0.6, n),
                            rng.uniform(1.3, 1.8, n), np.zeros(n)])  # fmt: skip
    lo, hi = [0.45, -1.2, 0.3], [0.65, 1.2, 0.8]
    return base, rng.uniform(lo, hi, (n, 3)), rng.uniform(lo, hi, (n, 3))


def _chassis(world):
    """World point -> chassis frame of BASE (facing +y: chassis x is world y)."""
    x, y, z = world
    return np.array([y - BASE[1], BASE[0] - x, z - chassis_to_world(BASE, [0, 0, 0])[2]])


def _disc(centre, radius=0.04, half_height=0.05):
    return [centre[0], centre[1], radius, centre[2] + half_height]


def test_disc_obstacles_by_hand():
    disc = [[1.0, 2.0, 0.04, 0.85]]
    # a point: on the rim counts, 1 mm out does not, nor 1 mm above the top; margin grows both
    p = [[1.0399, 2.0, 0.8], [1.0401, 2.0, 0.8], [1.0, 2.0, 0.8501], [1.0, 2.0, 0.8501]]
    np.testing.assert_array_equal(points_in_discs(p[:3], disc), [0, -1, -1])
    np.testing.assert_array_equal(points_in_discs(p, disc, 0.0002), [0, 0, 0, 0])
    # a held cup's bottom disc (radius 0.04): centres 8 cm apart touch, at most at the top
    q = [[1.0799, 2.0, 0.85], [1.0, 2.0801, 0.8], [1.0, 2.0, 0.8501]]
    np.testing.assert_array_equal(discs_in_discs(q, 0.04, disc), [0, -1, -1])
    np.testing.assert_array_equal(discs_in_discs(q, 0.04, disc, 0.0002), [0, 0, -1])
    # a finger box: chassis facing +y, arm straight ahead, fingers open (centres 7.5 cm
    # to each side of the gripper centre along world x, 1 cm half thick, 1.5 cm half deep)
    q_arm = arm_inverse(_chassis([2.0, 1.15, 0.9]))
    centre = chassis_to_world(BASE, arm_forward(q_arm))
    span = [[FINGER_OPEN] * 2] * 2
    face = centre[0] + FINGER_OPEN + FINGER_HALF[1]  # the left-hand finger's outer face (x)
    bottom = centre[2] - FINGER_HALF[2]
    for dx, top, expected in ((0.04, bottom, 0), (0.0401, bottom, -1), (0.04, bottom - 1e-4, -1)):
        obstacle = [[face + dx, centre[1], 0.04, top]]
        assert fingers_in_boxes(BASE, q_arm, span, [], 0.0, obstacle)[0] == expected
    # after the boxes: a disc's index counts them first
    far_box = [[9.0, 9.0, 0.0, 0.1, 0.1, 1.0]]
    assert fingers_in_boxes(BASE, q_arm, span, far_box, 0.0, [[face, centre[1], 0.04, 1.0]])[0] == 1
    # a corner of the finger box: the disc's centre diagonally off it, within its radius
    corner = [face, centre[1] + FINGER_HALF[0]]
    off = 0.04 / math.sqrt(2.0)
    near = [[corner[0] + off - 1e-6, corner[1] + off - 1e-6, 0.04, 1.0]]
    far = [[corner[0] + off + 1e-6, corner[1] + off + 1e-6, 0.04, 1.0]]
    assert fingers_in_boxes(BASE, q_arm, span, [], 0.0, near)[0] == 0
    assert fingers_in_boxes(BASE, q_arm, span, [], 0.0, far)[0] == -1
    with pytest.raises(RepertoireError, match="obstacle disc radii must be > 0"):
        points_in_discs(p, [[1.0, 2.0, 0.0, 0.85]])
    with pytest.raises(RepertoireError, match="obstacle discs must be finite rows of 4 values"):
        arm_way_hits(BASE, q_arm, q_arm, span, [], discs=[[1.0, 2.0, 0.04]])


def test_arm_way_hits_with_discs_agree_with_a_sample_by_sample_check():
    # random ways before table_0 among three standing cups, batched, against every
    # sample checked on its own (boxes first, then discs; a way starting in a box counts
    # only what it enters after leaving it, one starting in a disc enters it)
    n = 10
    base, q0, q1 = _random_ways(12, n)
    discs = np.array([_disc([2.0, 1.1, 0.8001]), _disc([2.3, 1.2, 0.8001]),
                      _disc([1.7, 1.0, 0.8001])])  # fmt: skip
    span = [[0.05, 0.05]] * 2
    for cup in (None, (0.05, 0.04)):
        got = arm_way_hits(base, q0, q1, span, KITCHEN_OBSTACLES, 0.01, cup, discs=discs)
        samples = joint_lines(q0, q1, 0.01, 0.0912)
        b = len(KITCHEN_OBSTACLES)
        for r in range(n):
            per_sample = []
            for q in samples[r]:
                c = chassis_to_world(base[r], arm_forward(q))
                found = [fingers_in_boxes(base[r], q, span, KITCHEN_OBSTACLES, 0.01, discs)[0]]
                found += [b + points_in_discs(c, discs, 0.01)[0]]
                if cup is not None:
                    found += [b + discs_in_discs(c - [0, 0, 0.05], 0.04, discs, 0.01)[0]]
                found = [f for f in found if f >= 0 and f != b - 1]  # (b - 1: no disc)
                per_sample.append(min(found, default=-1))
            k = 0
            while 0 <= per_sample[0] < b and k < len(per_sample) and per_sample[k] == per_sample[0]:
                k += 1  # a way starting in a box (not a disc): what it enters after it
            assert got[r] == next((i for i in per_sample[k:] if i >= 0), -1), (r, cup)
        assert np.any(got >= b) and np.any(got < 0)  # ways into cups and clear ways


def _fixed(system, **ports):
    ctx = system.CreateDefaultContext()
    for name, value in ports.items():
        system.GetInputPort(name).FixValue(ctx, np.asarray(value, dtype=float))
    return ctx


def _first_status(system, **ports) -> int:
    ctx = _fixed(system, **ports)
    ctx.SetDiscreteState(system.EvalUniquePeriodicDiscreteUpdate(ctx).get_vector().get_value())
    return system.get_status_output_port().Eval(ctx)  # after the first update


def test_reach_keeps_off_the_standing_cups():
    # a level swing at world z 0.83 across a cup standing where the way's middle passes
    # (rim 0.8501; the fingers' bottom 0.79 clears table_0's top 0.75): refused at once
    z = 0.83
    q0 = arm_inverse(_chassis([2.25, 1.1, z]))
    target = _chassis([1.75, 1.1, z])
    middle = chassis_to_world(BASE, arm_forward(0.5 * (q0 + arm_inverse(target))))
    on_way = [middle[0], middle[1], 0.8001]
    ports = dict(arm_position=q0, target=target, base_state=BASE, finger_position=OPEN)
    aside = [2.6, 1.6, 0.8001]
    failed, running = ActionStatus.FAILED, ActionStatus.RUNNING
    assert _first_status(Reach(0.02, obstacles=KITCHEN_OBSTACLES), **ports) == running  # no port
    reach = Reach(0.02, obstacles=KITCHEN_OBSTACLES, cups=2)
    assert _first_status(reach, cup_positions=[*on_way, *aside], **ports) == failed
    assert _first_status(reach, cup_positions=[*aside, *on_way], **ports) == failed
    assert _first_status(reach, cup_positions=[*aside, *aside], **ports) == running
    # a way above the rim: the fingers' bottom (4 cm below the centre) 1 mm over it
    high = dict(ports, arm_position=arm_inverse(_chassis([2.25, 1.1, 0.8902])),
                target=_chassis([1.75, 1.1, 0.8902]))  # fmt: skip
    assert _first_status(reach, cup_positions=[*on_way, *aside], **high) == running
    # the cup a way ends in (a reach down to grip it) or starts in (holding it) is not an
    # obstacle of that way; the other cup still is
    down = dict(ports, arm_position=arm_inverse(_chassis([2.0, 1.1, 0.93])),
                target=_chassis(CUP))  # fmt: skip
    assert _first_status(reach, cup_positions=[*CUP, *aside], **down) == running
    beside = [2.0, 1.2, 0.8001]  # 10 cm further: the open fingers' way down passes it
    assert _first_status(reach, cup_positions=[*CUP, *beside], **down) == running
    up = dict(down, arm_position=arm_inverse(_chassis(CUP)), target=_chassis([2.0, 1.1, 0.93]))
    up["finger_position"] = [0.05, 0.05]  # holding it
    assert _first_status(reach, cup_positions=[*CUP, *aside], **up) == running
    # but the fingers still keep off it: into it from the side (the fingers spread along
    # world x) or out of it sideways with the fingers open, they push it
    side = dict(down, arm_position=arm_inverse(_chassis([2.2, 1.1, 0.8001])))
    assert _first_status(reach, cup_positions=[*CUP, *aside], **side) == failed
    out = dict(down, arm_position=arm_inverse(_chassis(CUP)), target=_chassis([2.2, 1.1, 0.8001]))
    assert _first_status(reach, cup_positions=[*CUP, *aside], **out) == failed
    out["finger_position"] = [0.05, 0.05]  # holding it: it goes along
    assert _first_status(reach, cup_positions=[*CUP, *aside], **out) == running
    across = [2.0 + 0.085 + 0.04 - 0.001, 1.1, 0.8001]  # 1 mm under a finger's way down
    assert _first_status(reach, cup_positions=[*CUP, *across], **down) == failed
    discs, fingers_only = reach.standing_cups(
        _fixed(reach, cup_positions=[*CUP, *aside]), [CUP], 0.04, 0.05
    )
    np.testing.assert_allclose(discs, [[2.6, 1.6, 0.04, 0.8501]])
    assert fingers_only.shape == (0, 4)
    fingers_only = reach.standing_cups(
        _fixed(reach, cup_positions=[*CUP, *aside]), [[0, 0, 0], CUP], 0.04, 0.05, held=(0,)
    )[1]
    np.testing.assert_allclose(fingers_only, [[2.0, 1.1, 0.04, 0.8501]])
    with pytest.raises(RepertoireError, match="cups=0: no cup_positions port"):
        Reach(0.02).get_cup_positions_input_port()
    with pytest.raises(RepertoireError, match="cups must be a whole number >= 0, got -1"):
        Reach(0.02, cups=-1)
    with pytest.raises(RepertoireError, match="cup_margin must be finite and >= 0, got -0.01"):
        Put(0.02, cup_margin=-0.01)


def test_put_keeps_off_the_standing_cups():
    # carry the held cup (gripper at world z 0.93) from +x to put it down 12 cm from a
    # standing cup: fine; 7.9 cm (the bottoms' discs overlap 1 mm) or a finger opening at
    # the target (on the -x side, which the way does not pass) 1 mm into it or within
    # cup_margin (5 mm, half the way's samples) of it: refused
    held = [2.3, 1.3, 0.93]
    put = Put(0.02, obstacles=KITCHEN_OBSTACLES, cups=2)
    target = [2.0, 1.3, 0.8011]
    base = dict(arm_position=arm_inverse(_chassis(held)), base_state=BASE,
                finger_position=[0.05, 0.05], target=_chassis(target))  # fmt: skip
    failed, running = ActionStatus.FAILED, ActionStatus.RUNNING
    cases = (([2.0, 1.42, 0.8001], running), ([2.0, 1.379, 0.8001], failed),
             ([2.0 - 0.085 - 0.04 + 0.001, 1.3, 0.8001], failed),
             ([2.0 - 0.085 - 0.04 - 0.0049, 1.3, 0.8001], failed),  # inside cup_margin
             ([2.0 - 0.085 - 0.04 - 0.0051, 1.3, 0.8001], running))  # fmt: skip
    for other, status in cases:
        assert _first_status(put, cup_positions=[*held[:2], 0.93, *other], **base) == status, other


def test_a_ways_samples_do_not_depend_on_the_other_rows():
    # rows are sampled as alone and padded with their end: the hits of a batch are the
    # hits of its rows one by one (a batch used to sample every row as finely as its
    # longest, so a row's verdict near an obstacle depended on its neighbours)
    n = 40
    base, q0, q1 = _random_ways(4, n)
    q1[::2] = q0[::2] + 0.01  # short ways beside long ones
    lines = joint_lines(q0, q1, 0.02, 0.0912)
    for r in (0, 1):
        alone = joint_lines(q0[r], q1[r], 0.02, 0.0912)[0]
        np.testing.assert_array_equal(lines[r, : len(alone)], alone)
        np.testing.assert_array_equal(
            lines[r, len(alone) :], np.broadcast_to(alone[-1], lines[r, len(alone) :].shape)
        )
    discs = [_disc([2.0, 1.1, 0.8001]), _disc([2.3, 1.2, 0.8001])]
    span = [[FINGER_OPEN] * 2] * 2
    boxes = KITCHEN_OBSTACLES
    got = arm_way_hits(base, q0, q1, span, boxes, 0.02, None, 0.02, discs)
    alone = [arm_way_hits(base[r], q0[r], q1[r], span, boxes, 0.02, None, 0.02, discs)[0]
             for r in range(n)]  # fmt: skip
    np.testing.assert_array_equal(got, alone)
    assert np.any(got >= 0) and np.any(got < 0)


def test_finger_disc_gaps_by_hand():
    from repertoire.models.diffdrive.generate import COLUMN_X, FINGER_SIZE
    from repertoire.systems.kitchen_geometry import finger_disc_gaps, fingers_in_boxes

    # chassis at the origin facing +x, arm straight ahead: the gripper centre at
    # (COLUMN_X + 0.5, 0); the left finger's footprint is x in gx -+ 0.015, y in f -+ 0.01
    q, f, r = [0.3, 0.0, 0.5], 0.05, 0.035
    gx, span = COLUMN_X + 0.5, [[f, f], [f, f]]
    half_x, half_y = FINGER_SIZE[0] / 2, FINGER_SIZE[1] / 2
    discs = np.array(
        [
            [gx + half_x + 0.1 + r, f, r, 2.0],  # 0.1 m ahead of the left finger's face
            [gx, f, r, 2.0],  # right over the left finger's centre: overlapping by r
            [gx + half_x + 0.03, -f - half_y - 0.04, 0.01, 2.0],  # off the right one's corner
        ]
    )
    gaps = finger_disc_gaps([0.0, 0.0, 0.0], q, span, discs)
    assert gaps.shape == (1, 3)
    assert gaps[0] == pytest.approx([0.1, -r, math.hypot(0.03, 0.04) - 0.01], abs=1e-12)
    assert finger_disc_gaps([0.0, 0.0, 0.0], q, span, np.zeros((0, 4))).shape == (1, 0)
    # a disc is entered (the fingers low beside it) exactly when its gap <= the margin
    for gap, margin, hit in ((0.004, 0.005, 0), (0.006, 0.005, -1)):
        disc = [[gx + half_x + gap + r, f, r, 2.0]]
        assert finger_disc_gaps([0.0, 0.0, 0.0], q, span, disc)[0, 0] == pytest.approx(gap)
        assert fingers_in_boxes([0.0, 0.0, 0.0], q, span, [], margin, disc)[0] == hit


def test_tracked_joint_lines_closed_forms():
    from repertoire.systems.kitchen_geometry import ArmTracking

    # only the extension moves, 0.2 m at 0.2 m/s (T = 1 s), lagging 0.05 s; the yaw's
    # 0.1 s lag sets the horizon T + 0.4 s; 1 cm samples, 5 cm of time apart
    tracking = ArmTracking((0.05, 0.1, 0.05), (0.15, 0.8, 0.2))
    q = joint_lines([0.5, 0.0, 0.4], [0.5, 0.0, 0.6], 0.01, 0.0, tracking)[0]
    assert q.shape == (29, 3)
    for k, t in ((10, 0.5), (20, 1.0)):
        share = t - 0.05 * -math.expm1(-t / 0.05)  # t / T - tau / T (1 - e^(-t/tau))
        np.testing.assert_allclose(q[k], [0.5, 0.0, 0.4 + 0.2 * share], atol=1e-15)
    at_ramp = 1.0 - 0.05 * -math.expm1(-1.0 / 0.05)
    np.testing.assert_allclose(q[24, 2], 0.6 - 0.2 * (1 - at_ramp) * math.exp(-0.2 / 0.05))
    np.testing.assert_array_equal(q[-1], [0.5, 0.0, 0.6])  # settled
    # equal lags: the joints keep together, on the straight line; the lift sags as a lag
    same = ArmTracking((0.05, 0.05, 0.05), (0.15, 0.8, 0.2), sag=0.003, cup_sag=0.001)
    q0, q1 = np.array([0.6, -0.4, 0.6]), np.array([0.55, 0.2, 0.4])
    q = joint_lines(q0, q1, 0.01, 0.09, same)[0]
    sink = 0.003 * -np.expm1(-np.linspace(0.0, 1.2, len(q)) / 0.05)  # T + 4 tau = 1.2 s
    share = (q[:, 1:] - q0[1:]) / (q1 - q0)[1:]
    np.testing.assert_allclose(share[:, 0], share[:, 1], atol=1e-12)
    free = np.maximum((q0 + share[:, :1] * (q1 - q0))[:, 0] - sink, q1[0])  # not below 0.55
    np.testing.assert_allclose(q[:-1, 0], free[:-1], atol=1e-12)
    assert q[5, 0] < free[5] + 1e-12 < q0[0] - share[5, 0] * 0.05 + 1e-12  # sunk mid-way
    np.testing.assert_array_equal(q[-1], q1)  # settled at its end
    held = joint_lines(q0, q1, 0.01, 0.09, same, held=True)[0]
    sink = 0.004 * -np.expm1(-np.linspace(0.0, 1.2, len(q)) / 0.05)  # with the cup's 1 mm
    np.testing.assert_allclose(held[5, 0], q0[0] - share[5, 0] * 0.05 - sink[5], atol=1e-12)
    # a way up from a table (a cup lifted off it) does not dip below its start
    up = joint_lines(q1, q1 + [0.1, 0.0, 0.0], 0.01, 0.09, same, held=True)[0]
    assert up[:, 0].min() == q1[0]
    # no tracking: the straight line, as before
    np.testing.assert_allclose(joint_lines(q0, q1, 0.01, 0.09)[0, -1], q1, atol=1e-15)
    with pytest.raises(RepertoireError, match=r"lags must be 3 finite values >= 0 s"):
        ArmTracking((0.05, -0.1, 0.05), (0.15, 0.8, 0.2))
    with pytest.raises(RepertoireError, match=r"sag must be finite and >= 0 m, got nan"):
        ArmTracking((0.05, 0.1, 0.05), (0.15, 0.8, 0.2), sag=float("nan"))
    with pytest.raises(RepertoireError, match="tracking must be an ArmTracking or None"):
        Reach(tracking=(0.05, 0.1, 0.05))


def test_a_reach_whose_lift_runs_ahead_of_its_yaw_over_a_cup_is_refused():
    # random reach 5003 among two cups: its straight joint line passed over cup_1's rim
    # just outside the 5 mm margin, so it ran, the lift 2.5 mm below its setpoint under
    # the arm's weight and ahead of the lagging yaw; the fingers ran 4.8 mm below the
    # line, pushed cup_1 49 mm and the reach reported SUCCEEDED
    from repertoire.diagrams.kitchen import ARM_TRACKING, world_to_chassis
    from repertoire.models.diffdrive.generate import CUP_HALF_HEIGHT, CUP_RADIUS

    base = [2.0, 0.55, math.pi / 2, 0.0]
    start = [2.2912269761617843, 1.1927369840817812, 0.9023119978507526]
    end = [2.0527464308837216, 0.997442053548847, 0.8533288910361991]
    q0, q1 = (arm_inverse(world_to_chassis(base, p)) for p in (start, end))
    cup_1 = [2.22177375170813, 1.1860967627621235, 0.8001]
    discs = [[cup_1[0], cup_1[1], CUP_RADIUS + 0.005, cup_1[2] + CUP_HALF_HEIGHT]]
    span = [OPEN, OPEN]
    assert arm_way_hits(base, q0, q1, span, KITCHEN_OBSTACLES, discs=discs)[0] == -1
    hit = arm_way_hits(base, q0, q1, span, KITCHEN_OBSTACLES, discs=discs, tracking=ARM_TRACKING)
    assert hit[0] == len(KITCHEN_OBSTACLES)  # cup_1
