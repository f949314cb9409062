"""The crawl planner's footholds keep clear of rising faces (``clear_of_faces``)."""

import math

import numpy as np
import pytest
from repertoire.models.littledog.kinematics import FOOT_RADIUS, nominal_foot_positions
from repertoire.planning.footstep.height_map import height_map_from_board
from repertoire.planning.footstep.quadruped import CrawlParams, clear_of_faces, plan_crawl
from repertoire.planning.footstep.types import FootstepError, PlanStatus
from repertoire.planning.transfer_crawl_filler import CrawlGapFiller
from repertoire.planning.transfer_search import PlannedStep

BASE = 0.04


class StepBoard:
    """Ground ``BASE`` for x < 0 and ``BASE + rise`` for x >= 0: one straight face at x = 0."""

    def __init__(self, rise: float) -> None:
        self.rise = rise

    def height(self, x, y):
        x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
        return np.where(x >= 0.0, BASE + self.rise, BASE)


class CurbBoard:
    """Flat ground with a curb ``rise`` high over ``x0 <= x <= x1`` (two faces across y)."""

    def __init__(self, x0: float, x1: float, rise: float) -> None:
        self.x0, self.x1, self.rise = x0, x1, rise

    def height(self, x, y):
        x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
        return np.where((x >= self.x0) & (x <= self.x1), BASE + self.rise, BASE)


def at(*d: float) -> np.ndarray:
    """Points at distances ``d`` in front of the face at x = 0 (on y = 0)."""
    return np.column_stack([-np.asarray(d, dtype=float), np.zeros(len(d))])


def test_a_face_within_face_radius_is_refused_and_beyond_it_is_not():
    params = CrawlParams()
    assert params.face_radius == 0.02
    board = StepBoard(0.0144)  # a 1.44 cm face: higher than the foot sphere's centre
    np.testing.assert_array_equal(
        clear_of_faces(board, at(0.005, 0.0105, 0.015, 0.0199, 0.0201, 0.05), params),
        [False, False, False, False, True, True],
    )


def test_the_height_tolerance_is_max_roughness_and_falling_ground_is_not_checked():
    params = CrawlParams()
    near = at(0.012)  # outside the foot's own radius, inside face_radius
    assert clear_of_faces(StepBoard(params.max_roughness), near, params).tolist() == [True]
    assert clear_of_faces(StepBoard(params.max_roughness + 1e-4), near, params).tolist() == [False]
    assert clear_of_faces(StepBoard(-0.03), at(0.005), params).tolist() == [True]


def test_face_radius_sets_the_distance_and_the_foot_radius_turns_the_rule_off():
    board = StepBoard(0.03)
    narrow = CrawlParams(face_radius=0.015)
    np.testing.assert_array_equal(clear_of_faces(board, at(0.0149, 0.0151), narrow), [False, True])
    off = CrawlParams(face_radius=FOOT_RADIUS)
    np.testing.assert_array_equal(clear_of_faces(board, at(0.0, 0.0105), off), [True, True])
    assert clear_of_faces(board, np.zeros((0, 2)), CrawlParams()).shape == (0,)


@pytest.mark.parametrize("bad", [-0.001, math.nan, math.inf])
def test_face_radius_bad_input_names_it(bad):
    with pytest.raises(FootstepError, match="face_radius"):
        CrawlParams(face_radius=bad).validate()


CURB = (0.205, 0.245)
"""The curb's faces (x, m)."""


def _curb_plan(face_radius: float):
    board = CurbBoard(CURB[0], CURB[1], 0.0144)  # faces between the 1 cm map's cells
    hm = height_map_from_board(board, (-0.3, 0.7), (-0.3, 0.3), 0.01)
    start = nominal_foot_positions()[:, :2]
    params = CrawlParams(face_radius=face_radius)
    plan = plan_crawl(hm, start, (0.45, 0.0), params, time_limit=20.0, ground=board)
    landing = np.array([s.p_WF[:2] for s in plan.steps])
    return plan, board, params, landing


def test_planned_footholds_over_a_curb_keep_face_radius_from_its_faces():
    plan, board, params, landing = _curb_plan(0.02)
    assert plan.status is PlanStatus.SUCCESS
    assert np.all(clear_of_faces(board, landing, params))
    # on the ground before and after the curb, at least face_radius from its faces
    low = np.abs(board.height(landing[:, 0], landing[:, 1]) - BASE) < 1e-12
    assert np.all((landing[low, 0] <= CURB[0] - 0.02) | (landing[low, 0] >= CURB[1] + 0.02))
    # without the rule (face_radius = the foot's radius) the same crawl lands nearer
    old, _, _, near = _curb_plan(FOOT_RADIUS)
    assert old.status is PlanStatus.SUCCESS
    low = np.abs(board.height(near[:, 0], near[:, 1]) - BASE) < 1e-12
    gap = np.minimum(np.abs(near[low, 0] - CURB[0]), np.abs(near[low, 0] - CURB[1]))
    assert gap.min() == pytest.approx(0.015)  # the cell at x = 0.19: 1.5 cm from the face


def test_the_gap_filler_holds_placing_moves_to_the_rule():
    board = StepBoard(0.0144)
    hm = height_map_from_board(board, (-0.5, 0.3), (-0.3, 0.3), 0.01)
    feet = np.column_stack([nominal_foot_positions()[:, :2], np.full(4, BASE + FOOT_RADIUS)])
    feet[:, 0] -= feet[:, 0].max() + 0.06  # the front feet 6 cm before the face
    filler = CrawlGapFiller(hm, board=board)

    def placing(x: float) -> list[PlannedStep]:
        after = feet.copy()
        after[0, 0] = x  # lf moves forward to x
        return [PlannedStep(feet, after, 0)]

    assert filler.usable_prefix(placing(-0.025)) == 1
    assert filler.usable_prefix(placing(-0.015)) == 0
    loose = CrawlGapFiller(hm, params=CrawlParams(face_radius=FOOT_RADIUS), board=board)
    assert loose.usable_prefix(placing(-0.015)) == 1
