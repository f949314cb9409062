"""Placing the held object: the goal moved by the object's offset from the commanded tcp, and
the placement monitor that gates the release."""

import numpy as np
import pytest
from pydrake.math import RigidTransform
from pydrake.multibody.math import SpatialVelocity
from repertoire.planning.arm_library import R_SIDE, quaternion_wxyz
from repertoire.systems.arm_goals import GoalSchedule, HeldObjectOffset, SegmentGoal
from repertoire.systems.arm_monitors import PlacementMonitor, placement_error

from repertoire.errors import RepertoireError

Q_SIDE = quaternion_wxyz(R_SIDE)  # x_T up, z_T (the approach) along +x_W, y_T along -y_W
FINGERS = np.array([0.1, 0.2, 0.3])


def _offset_step(system, context, t, segment, p_WO, tcp_desired) -> np.ndarray:
    context.SetTime(t)
    system.GetInputPort("segment").FixValue(context, [float(segment)])
    system.GetInputPort("body_poses").FixValue(
        context, [RigidTransform(), RigidTransform(), RigidTransform(list(p_WO))]
    )
    system.GetInputPort("tcp_desired").FixValue(context, list(tcp_desired))
    context.SetDiscreteState(system.EvalUniquePeriodicDiscreteUpdate(context).value())
    return system.GetOutputPort("offset").Eval(context).copy()


def test_held_object_offset_is_the_objects_horizontal_offset_from_the_command_while_held():
    system = HeldObjectOffset(2, [1], period=0.004, max_offset=0.01)
    context = system.CreateDefaultContext()
    assert system.GetOutputPort("offset").Eval(context).tolist() == [0.0, 0.0, 0.0]
    # Not held (the grasp, segment 0): nothing is read.
    offset = _offset_step(system, context, 1.0, 0, [0.5, 0.1, 0.7], [0.4, 0.3, 0.8])
    assert offset.tolist() == [0.0, 0.0, 0.0]
    # Held: the object's origin 55 mm below, 1.5 mm ahead and 0.5 mm left of the command.
    offset = _offset_step(system, context, 2.8, 1, [0.5015, 0.1005, 0.745], [0.5, 0.1, 0.8])
    np.testing.assert_allclose(offset, [0.0015, 0.0005, 0.0], atol=1e-15)
    # It slid 2 mm in the hand: the next reading follows.
    offset = _offset_step(system, context, 2.804, 1, [0.6035, 0.2005, 0.745], [0.6, 0.2, 0.8])
    np.testing.assert_allclose(offset, [0.0035, 0.0005, 0.0], atol=1e-15)
    # Knocked 3 cm and 4 cm in the hand: scaled back to max_offset, 1 cm (6 mm and 8 mm).
    offset = _offset_step(system, context, 2.808, 1, [0.63, 0.24, 0.745], [0.6, 0.2, 0.8])
    np.testing.assert_allclose(offset, [0.006, 0.008, 0.0], atol=1e-15)
    # Released (segment 2): the last held reading is kept.
    offset = _offset_step(system, context, 6.0, 2, [0.9, 0.9, 0.7], [0.0, 0.0, 0.8])
    np.testing.assert_allclose(offset, [0.006, 0.008, 0.0], atol=1e-15)
    with pytest.raises(RepertoireError, match="tcp_desired must be 3 finite numbers"):
        _offset_step(system, context, 6.1, 1, [0.9, 0.9, 0.7], [np.nan, 0.0, 0.8])
    with pytest.raises(RepertoireError, match="held_object must be a body index >= 0"):
        HeldObjectOffset(-1, [1], period=0.004, max_offset=0.01)
    with pytest.raises(RepertoireError, match="held_segments must list one or more segment"):
        HeldObjectOffset(2, [], period=0.004, max_offset=0.01)
    with pytest.raises(RepertoireError, match="period must be a finite number > 0, got 0.0"):
        HeldObjectOffset(2, [1], period=0.0, max_offset=0.01)
    with pytest.raises(RepertoireError, match="max_offset must be a finite number > 0, got -1"):
        HeldObjectOffset(2, [1], period=0.004, max_offset=-1)


def test_goal_schedule_shifts_only_the_goals_that_place_the_held_object_exactly():
    goals = [
        SegmentGoal("grasp", np.array([0.4, -0.2, 0.8]), Q_SIDE, FINGERS),
        SegmentGoal("place", np.array([0.0, 0.0, 0.065]), Q_SIDE, FINGERS, 1, places_held=True),
        SegmentGoal("release", np.array([-0.12, 0.0, 0.145]), Q_SIDE, FINGERS, 1),
    ]
    schedule = GoalSchedule(goals)
    context = schedule.CreateDefaultContext()
    schedule.GetInputPort("body_poses").FixValue(
        context, [RigidTransform(), RigidTransform([0.5, 0.1, 0.75])]
    )
    # No offset measured yet (zeros): the goal is the coaster's plus the offset.
    schedule.GetInputPort("held_object_offset").FixValue(context, [0.0, 0.0, 0.0])
    np.testing.assert_allclose(
        schedule.GetOutputPort("goal_1").Eval(context)[:3], [0.5, 0.1, 0.815], atol=1e-15
    )
    # The cup 1.5 mm ahead (+x) and 0.5 mm right (-y) of the commanded tcp (its z ignored).
    schedule.GetInputPort("held_object_offset").FixValue(context, [0.0015, -0.0005, -0.055])
    np.testing.assert_allclose(
        schedule.GetOutputPort("goal_1").Eval(context),
        [0.4985, 0.1005, 0.815, *Q_SIDE, *FINGERS],
        atol=1e-15,
    )
    np.testing.assert_allclose(schedule.GetOutputPort("goal_0").Eval(context)[:3], [0.4, -0.2, 0.8])
    np.testing.assert_allclose(
        schedule.GetOutputPort("goal_2").Eval(context)[:3], [0.38, 0.1, 0.895], atol=1e-15
    )
    schedule.GetInputPort("held_object_offset").FixValue(context, [0.0, np.nan, 0.0])
    with pytest.raises(RepertoireError, match=r"goal 1 \(place\): held_object_offset must be 3"):
        schedule.GetOutputPort("goal_1").Eval(context)
    # Without a goal that places the held object there is no such input.
    assert not GoalSchedule(goals[:1]).HasInputPort("held_object_offset")
    bad = SegmentGoal("place", np.zeros(3), Q_SIDE, FINGERS, places_held=1)
    with pytest.raises(RepertoireError, match=r"goal 0 \(place\): places_held must be True or"):
        GoalSchedule([bad])


def test_placement_error_is_the_horizontal_distance_and_relative_speed():
    d, v = placement_error([0.3, 0.4, 9.0], [0.0, 0.05, 7.0], [0.0, 0.0, 1.0], [0.03, 0.01, 0.0])
    assert d == pytest.approx(0.5, abs=1e-15)
    assert v == pytest.approx(0.05, abs=1e-15)


def _monitor_step(system, context, t, segment, p_WO, v_WO, p_WB=(0.5, 0.1, 0.75), v_WB=(0, 0, 0)):
    context.SetTime(t)
    system.GetInputPort("segment").FixValue(context, [float(segment)])
    poses = [RigidTransform(), RigidTransform(list(p_WB)), RigidTransform(list(p_WO))]
    velocities = [SpatialVelocity(np.zeros(6))] + [
        SpatialVelocity(np.zeros(3), np.asarray(v, float)) for v in (v_WB, v_WO)
    ]
    system.GetInputPort("body_poses").FixValue(context, poses)
    system.GetInputPort("body_spatial_velocities").FixValue(context, velocities)
    settled = system.GetOutputPort("settled").Eval(context)[0]
    placement = system.GetOutputPort("placement").Eval(context).copy()
    context.SetDiscreteState(system.EvalUniquePeriodicDiscreteUpdate(context).value())
    return settled, placement, system.GetOutputPort("at_release").Eval(context).copy()


def test_placement_monitor_settles_within_both_tolerances_and_records_the_release_exactly():
    """The cup (body 2) placed on the coaster (body 1): target 6 mm above its origin."""
    system = PlacementMonitor(
        2, 1, [0.0, 0.0, 0.006], tolerance=0.001, speed_tolerance=0.005,
        release_segment=2, period=0.004,
    )  # fmt: skip
    context = system.CreateDefaultContext()
    assert np.isnan(system.GetOutputPort("at_release").Eval(context)).all()
    # 2 mm off (any height): not settled; the place segment (1) records nothing.
    settled, placement, at = _monitor_step(system, context, 3.0, 1, [0.5, 0.102, 0.9], (0, 0, 0))
    assert settled == 0.0 and np.isnan(at).all()
    np.testing.assert_allclose(placement, [0.002, 0.0], atol=1e-15)
    # 0.6 mm off, at rest relative to the coaster, which still slides at 3 cm/s: settled.
    settled, placement, _ = _monitor_step(
        system, context, 3.1, 1, [0.5006, 0.1, 0.8], (0.03, 0.0, -0.2), v_WB=(0.03, 0.0, 0.0)
    )
    assert settled == 1.0
    np.testing.assert_allclose(placement, [0.0006, 0.0], atol=1e-15)
    # Within the tolerance but moving 6 mm/s horizontally relative to it: not settled.
    settled, placement, _ = _monitor_step(
        system, context, 3.2, 1, [0.5006, 0.1, 0.8], (0, 0.006, 0)
    )
    assert settled == 0.0
    np.testing.assert_allclose(placement, [0.0006, 0.006], atol=1e-15)
    # The release's first check records the placement there and keeps it.
    _, _, at = _monitor_step(system, context, 3.3, 2, [0.5, 0.1006, 0.8], (0.004, 0.0, 0.0))
    np.testing.assert_allclose(at, [0.0006, 0.004, 1.0], atol=1e-15)
    _, _, at = _monitor_step(system, context, 3.4, 2, [0.7, 0.1, 0.8], (1.0, 0.0, 0.0))
    np.testing.assert_allclose(at, [0.0006, 0.004, 1.0], atol=1e-15)
    # A fixed target (-1) in W; the release found the object unsettled: 0 recorded.
    fixed = PlacementMonitor(
        2, -1, [0.5, 0.1, 0.0], tolerance=0.001, speed_tolerance=0.005,
        release_segment=2, period=0.004,
    )  # fmt: skip
    fixed_context = fixed.CreateDefaultContext()
    _, _, at = _monitor_step(fixed, fixed_context, 1.0, 2, [0.503, 0.104, 0.8], (0, 0, 0))
    np.testing.assert_allclose(at, [0.005, 0.0, 0.0], atol=1e-15)


def test_placement_monitor_refuses_bad_arguments_and_short_body_lists_naming_them():
    kwargs = {"tolerance": 0.001, "speed_tolerance": 0.005, "release_segment": 2, "period": 0.004}
    with pytest.raises(RepertoireError, match="held_object must be a body index >= 0, got -1"):
        PlacementMonitor(-1, 1, np.zeros(3), **kwargs)
    with pytest.raises(RepertoireError, match="target_body must be a body index >= -1"):
        PlacementMonitor(2, "coaster", np.zeros(3), **kwargs)
    with pytest.raises(RepertoireError, match="held_object and target_body must differ, both"):
        PlacementMonitor(2, 2, np.zeros(3), **kwargs)
    with pytest.raises(RepertoireError, match="p_BG"):
        PlacementMonitor(2, 1, [0.0, np.nan, 0.0], **kwargs)
    for name, value in (("tolerance", 0.0), ("speed_tolerance", -1.0), ("period", np.inf)):
        with pytest.raises(RepertoireError, match=f"{name} must be a finite number > 0"):
            PlacementMonitor(2, 1, np.zeros(3), **{**kwargs, name: value})
    for segment in (-1, 1.0, True):
        with pytest.raises(RepertoireError, match="release_segment must be a segment index"):
            PlacementMonitor(2, 1, np.zeros(3), **{**kwargs, "release_segment": segment})
    system = PlacementMonitor(2, 1, np.zeros(3), **kwargs)
    context = system.CreateDefaultContext()
    system.GetInputPort("body_poses").FixValue(context, [RigidTransform()] * 2)
    system.GetInputPort("body_spatial_velocities").FixValue(context, [SpatialVelocity()] * 3)
    with pytest.raises(RepertoireError, match="body 2 is not in body_poses and body_spatial_vel"):
        system.GetOutputPort("settled").Eval(context)
