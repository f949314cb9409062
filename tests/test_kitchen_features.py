import math

import numpy as np
import pytest
from repertoire.planning.action_models.kitchen_features import (
    KITCHEN_GOTO_FEATURES,
    KITCHEN_REACH_ARM_FEATURES,
    KITCHEN_REACH_FEATURES,
    kitchen_goto_features,
    kitchen_reach_arm_features,
    kitchen_reach_features,
)
from repertoire.systems.kitchen_actions import arm_forward

from repertoire.errors import RepertoireError


def test_goto_features_by_hand():
    # goal 3 m ahead and 4 m left: dist 5, direction atan2(4, 3) = 0.9273
    d = math.atan2(4, 3)
    f = kitchen_goto_features([0, 0, 0, 0.3], [3, 4, math.pi, 0.2])
    assert len(KITCHEN_GOTO_FEATURES) == 5
    assert f == pytest.approx([0.2, 5.0, d, math.pi - d, math.pi])
    # heading pi/2: the goal is to the right (signed -0.6435): angle_at changes sign
    f = kitchen_goto_features([0, 0, math.pi / 2, 0], [3, 4, 0.0, 0])
    assert f == pytest.approx([0.0, 5.0, math.pi / 2 - d, d, math.pi / 2])
    # wrapping: heading 3.0 to goal heading -3.0 is a turn of 0.283, not 6.0
    f = kitchen_goto_features([0, 0, 3.0, 0], [-1, 0, -3.0, 0])
    assert f[4] == pytest.approx(2 * math.pi - 6.0)
    assert f[2] == pytest.approx(math.pi - 3.0)
    # batches: rows equal single evaluations
    rows = kitchen_goto_features(
        [[0, 0, 0, 0.3], [0, 0, math.pi / 2, 0]], [[3, 4, math.pi, 0.2]] * 2
    )
    assert rows.shape == (2, 5)
    np.testing.assert_allclose(
        rows[1], kitchen_goto_features([0, 0, math.pi / 2, 0], [3, 4, math.pi, 0.2])
    )


def test_reach_features_by_hand():
    f = kitchen_reach_features([0.1, 0.2, 0.3], [0.4, 0.6, 0.3 + 1.2])
    # d = (0.3, 0.4, 1.2): |d| = 1.3
    expected = [1.3, 0.5, math.hypot(0.3, 1.2), math.hypot(0.4, 1.2),
                math.atan2(0.4, 0.3), math.atan2(1.2, 0.3), math.atan2(1.2, 0.4)]  # fmt: skip
    assert len(KITCHEN_REACH_FEATURES) == 7
    assert f == pytest.approx(expected)
    assert kitchen_reach_features([[0, 0, 0]] * 3, [1, 0, 0]).shape == (3, 7)


def test_reach_arm_features_by_hand():
    c = 0.05  # the arm's column, ahead of the axle
    # yaw 0 at extension 0.3, height 0.5 -> yaw pi/2 at extension 0.6, height 0.7
    f = kitchen_reach_arm_features([c + 0.3, 0.0, 0.5], [c, 0.6, 0.7])
    assert KITCHEN_REACH_ARM_FEATURES == ("turn", "d_radial", "d_height")
    assert f == pytest.approx([math.pi / 2, 0.3, 0.2])
    # the turn is the short way round: yaw 3.0 -> -3.0 is 2 pi - 6
    f = kitchen_reach_arm_features(
        [c + 0.4 * math.cos(3.0), 0.4 * math.sin(3.0), 0.0],
        [c + 0.4 * math.cos(-3.0), 0.4 * math.sin(-3.0), 0.0],
    )
    assert f == pytest.approx([2 * math.pi - 6.0, 0.0, 0.0], abs=1e-12)
    # equal to the joint displacements of the arm's inverse kinematics
    q0, q1 = np.array([0.4, -1.2, 0.35]), np.array([0.7, 0.9, 0.8])
    f = kitchen_reach_arm_features(arm_forward(q0), arm_forward(q1))
    assert f == pytest.approx(np.abs(q1 - q0)[[1, 2, 0]])
    assert kitchen_reach_arm_features([[0.5, 0, 0]] * 2, [0.3, 0.3, 0.1]).shape == (2, 3)
    with pytest.raises(RepertoireError, match="finite"):
        kitchen_reach_arm_features([0, np.inf, 0], [1, 1, 1])


def test_bad_feature_input():
    with pytest.raises(RepertoireError, match="finite"):
        kitchen_reach_features([0, 0, np.nan], [1, 1, 1])
    with pytest.raises(RepertoireError, match="4 values"):
        kitchen_goto_features([0, 0, 0], [1, 1, 1, 1])
