"""GoToPose's compiled law: the planners' rollout against the LeafSystem, the drive check."""

import numpy as np
import pytest
from repertoire.diagrams.kitchen import KITCHEN_BRAKING, KITCHEN_OBSTACLES
from repertoire.systems.action_status import ActionStatus
from repertoire.systems.go_to_pose import GOTO_GAINS, GoToPose, gains_vector, goto_rollout
from repertoire.systems.goto_law import (
    rollout_hits,
    segment_box_gap,
    segment_disc_gap,
    wrap,
)
from repertoire.systems.kitchen_drive import stopping_run
from repertoire.systems.kitchen_geometry import box_gaps, segment_disc_gaps, segment_gaps

from repertoire.errors import RepertoireError

PERIOD = 0.02


def leaf_drive(start, target, period=PERIOD):
    """GoToPose's LeafSystem closed by hand around the rollout's unicycle (exact arcs)."""
    system = GoToPose(period)
    context = system.CreateDefaultContext()
    system.get_target_input_port().FixValue(context, target)
    s = np.array(start, dtype=float)
    poses = [s.copy()]
    for i in range(2000):
        context.SetTime(i * period)
        system.get_state_input_port().FixValue(context, s)
        xd = system.EvalUniquePeriodicDiscreteUpdate(context).get_vector(0).get_value().copy()
        context.SetDiscreteState(0, xd)
        if xd[2] != ActionStatus.RUNNING:
            return np.array(poses), i, xd[2]
        v, w = xd[:2]
        half = 0.5 * w * period
        chord = v * period * (np.sin(half) / half if half != 0.0 else 1.0)
        s[0] += chord * np.cos(s[2] + half)
        s[1] += chord * np.sin(s[2] + half)
        s[2] += 2.0 * half
        s[3] = v
        poses.append(s.copy())
    raise AssertionError("the LeafSystem did not end")


DRIVES = (  # start, target: ahead, behind (it backs and turns), a turn in place, a side step
    ([0.0, 0.0, 0.0, 0.0], [1.5, 0.7, 1.0, 0.0]),
    ([0.0, 0.0, 2.5, 0.0], [-1.0, 0.2, 0.3, 0.0]),
    ([1.0, -0.5, -1.0, 0.0], [1.0, -0.5, 1.0, 0.0]),
    ([-2.7, -0.2, 3.1, 0.0], [0.3, 1.0, -1.57, 0.0]),
)


def test_rollout_is_the_leaf_systems_drive():
    # the same compiled law: every pose and the arrival update are the LeafSystem's, bit
    # for bit
    starts, targets = np.array([d[0] for d in DRIVES]), np.array([d[1] for d in DRIVES])
    r = goto_rollout(starts, targets, GOTO_GAINS, PERIOD)
    for j, (start, target) in enumerate(DRIVES):
        poses, step, status = leaf_drive(start, target)
        assert status == ActionStatus.SUCCEEDED
        assert r.steps[j] == step == len(poses) - 1
        np.testing.assert_array_equal(r.poses[j, : len(poses)], poses)
        rest = r.poses[j, len(poses) :]  # a row that ended keeps its last state
        np.testing.assert_array_equal(rest, np.repeat(poses[-1:], len(rest), axis=0))
    assert r.steps.tolist() == [251, 337, 50, 474]
    # the drive starting away from its goal (34007's start) leaves the straight line by
    # 0.73 m: what a straight-path check missed
    a, b = starts[3, :2], targets[3, :2]
    u = (b - a) / np.linalg.norm(b - a)
    p = r.poses[3, : r.steps[3] + 1, :2] - a
    assert np.abs(u[0] * p[:, 1] - u[1] * p[:, 0]).max() == pytest.approx(0.7287, abs=1e-4)


def test_rollout_times_out_and_bad_inputs():
    gains = dict(GOTO_GAINS, timeout=0.5)
    r = goto_rollout([[0.0, 0.0, 0.0, 0.0]], [[3.0, 0.0, 0.0, 0.0]], gains, PERIOD)
    assert r.steps.tolist() == [-1] and r.poses.shape == (1, 26, 4)
    poses, step, status = leaf_drive([0.0, 0.0, 0.0, 0.0], [3.0, 0.0, 0.0, 0.0], PERIOD)
    assert status == ActionStatus.SUCCEEDED  # (the default timeout)
    with pytest.raises(RepertoireError, match="does not model the run-up"):
        goto_rollout([[0.0, 0.0, 0.0, 0.0]], [[1.0, 0.0, 0.0, 0.5]], GOTO_GAINS, PERIOD)
    with pytest.raises(RepertoireError, match="finite rows of 4"):
        goto_rollout([[0.0, np.nan, 0.0, 0.0]], [[1.0, 0.0, 0.0, 0.0]], GOTO_GAINS, PERIOD)
    with pytest.raises(RepertoireError, match="period"):
        goto_rollout([[0.0, 0.0, 0.0, 0.0]], [[1.0, 0.0, 0.0, 0.0]], GOTO_GAINS, -0.1)


def test_segment_gaps_against_dense_samples():
    # one compiled kernel serves kitchen_geometry.segment_gaps and the rollouts: checked
    # against numpy's point-to-rectangle distances (box_gaps) of 4001 points per segment
    rng = np.random.default_rng(3)
    a, b = rng.uniform(-4, 4, (400, 2)), rng.uniform(-4, 4, (400, 2))
    b[:50] = a[:50]  # points
    b[50:80, 1] = a[50:80, 1]  # along the box axes
    got = segment_gaps(a, b, KITCHEN_OBSTACLES)
    s = np.linspace(0.0, 1.0, 4001)
    for i in range(len(a)):
        points = a[i] + s[:, None] * (b[i] - a[i])
        sampled = box_gaps(points, KITCHEN_OBSTACLES).min(axis=0)
        half_step = 0.5 * np.linalg.norm(b[i] - a[i]) / 4000
        assert np.all(got[i] <= sampled + 1e-12)  # no sample is nearer than the exact gap
        assert np.all(got[i] >= sampled - half_step - 1e-12)  # nor farther by more than that
    assert (got == 0).sum() > 20
    pair = [[segment_box_gap(*p, *q, box) for box in KITCHEN_OBSTACLES] for p, q in zip(a, b)]
    np.testing.assert_array_equal(pair, got)
    disc = np.array([0.5, -0.2, 0.04])
    assert segment_disc_gap(0.0, 0.0, 1.0, 0.0, disc) == pytest.approx(0.16, abs=1e-15)
    assert segment_disc_gap(-1.0, -0.2, -0.5, -0.2, disc) == pytest.approx(0.96, abs=1e-15)
    gaps = segment_disc_gaps([[0.0, 0.0], [-1.0, -0.2]], [[1.0, 0.0], [-0.5, -0.2]], [disc])
    np.testing.assert_allclose(gaps, [[0.16], [0.96]], rtol=0, atol=1e-15)
    assert segment_disc_gaps([[0.0, 0.0]], [[1.0, 0.0]], np.zeros((0, 4))).shape == (1, 0)


def test_rollout_hits_is_the_rollouts_stopping_runs_against_the_boxes():
    # the compiled check against numpy's: the rollout's poses, each update's stopping run
    # (the run-time check's motion) as a segment, exact box and disc distances
    rng = np.random.default_rng(5)
    n = 60
    starts = np.column_stack([rng.uniform(-3, 0.5, n), rng.uniform(-2, 2, n),
                              rng.uniform(-3, 3, n), np.zeros(n)])  # fmt: skip
    targets = np.column_stack([rng.uniform(0.5, 3, n), rng.uniform(-2, 2, n),
                               rng.uniform(-3, 3, n), np.zeros(n)])  # fmt: skip
    discs = np.array([[0.0, 0.0, 0.3, 1.0]])
    limits = np.column_stack([np.full((n, 7), -np.inf), np.full(n, 0.5)])
    limits[::2, 1] = 0.8  # the arm reaches table_0 on every second row
    radius = 0.35
    r = goto_rollout(starts, targets, GOTO_GAINS, PERIOD)
    want = []
    for j in range(n):
        end = r.steps[j] if r.steps[j] >= 0 else r.poses.shape[1] - 1
        p = r.poses[j, : end + 1]
        run = stopping_run(p[:, 3], 0.0, *KITCHEN_BRAKING, PERIOD)[0]
        q = p[:, :2] + run[:, None] * np.column_stack([np.cos(p[:, 2]), np.sin(p[:, 2])])
        boxes = segment_gaps(p, q, KITCHEN_OBSTACLES)
        d = q - p[:, :2]
        dd = np.maximum((d * d).sum(1), 1e-300)
        t = np.clip(((discs[0, :2] - p[:, :2]) * d).sum(1) / dd, 0, 1)
        to_disc = np.hypot(*(p[:, :2] + t[:, None] * d - discs[0, :2]).T) - discs[0, 2]
        base = boxes < radius
        entered = np.column_stack([boxes < limits[j, :7], to_disc < limits[j, 7]])
        hit = -1
        for i in range(len(p)):
            if base[i].any():
                hit = int(np.argmax(base[i]))
                break
            if entered[i].any():
                hit = int(np.argmax(entered[i]))
                break
        want.append(hit)
    g = gains_vector(GOTO_GAINS)
    last = int(GOTO_GAINS["timeout"] / PERIOD)
    got = rollout_hits(starts, targets, g, PERIOD, last, np.array(KITCHEN_BRAKING),
                       KITCHEN_OBSTACLES, discs, limits, radius)  # fmt: skip
    assert got.tolist() == want
    assert {-1, 1, 7} <= set(want)  # clear rows, table_0 and the disc


def test_wrap_is_the_modulo_bit_for_bit():
    # the modulo is skipped inside [0, 2 pi): the same bits as pi - (pi - a) % 2 pi
    rng = np.random.default_rng(11)
    near_pi = [np.nextafter(np.pi, 0), np.nextafter(-np.pi, 0), np.nextafter(-np.pi, -4)]
    edges = [0.0, -0.0, np.pi, -np.pi, 2 * np.pi, -2 * np.pi, 3 * np.pi, *near_pi, 1e-300, 40.0]
    for a in [*edges, *rng.uniform(-10, 10, 2000), *rng.normal(0, 1e-3, 200)]:
        want = np.pi - (np.pi - a) % (2.0 * np.pi)
        assert np.float64(wrap(a)).tobytes() == np.float64(want).tobytes(), a
