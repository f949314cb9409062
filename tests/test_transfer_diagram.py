"""The littledog_transfer diagram: transfer, search, final library and the closed loop."""

import dataclasses

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from repertoire.diagrams.littledog_demos import crossing_start, flat_start
from repertoire.diagrams.littledog_transfer import (
    GOAL_MARGIN,
    GoalLineFiller,
    LittleDogTransferScenario,
    build_littledog_transfer,
    flat_offset,
    goal_stance,
    nominal_start,
    off_board,
    plan_transfer,
    source_board,
    target_board,
)
from repertoire.planning.footstep.quadruped import CrawlParams as PlannerParams
from repertoire.planning.footstep.quadruped import clear_of_faces, flat_on_ground
from repertoire.planning.littledog_crawl import (
    CrawlParams,
    choose_footholds,
    plan_crawl,
    plan_to_steps,
)
from repertoire.planning.step_library import StepLibrary
from repertoire.planning.transfer_library import step_end_feet
from repertoire.planning.transfer_search import GapFill, PlannedStep

from repertoire.errors import ScenarioError


@pytest.fixture(scope="module")
def library_path(tmp_path_factory):
    """The scripted 0-degree crossing of terrain_a as a small library (kinematic, no physics)."""
    board = source_board("terrain_a")
    params = CrawlParams()
    off = flat_start(board, 0.0, 0.25, params)
    pose, feet, _ = crossing_start(board, 0.0, 0.25, params.standing_height, off)
    plan = plan_crawl(feet, pose, choose_footholds(board, feet, 0.0, 0.23, params), board, params)
    lib = StepLibrary(plan_to_steps(plan, terrain="terrain_a", direction=0.0, kind="recorded"))
    path = tmp_path_factory.mktemp("lib") / "crossing"
    lib.save(path)
    return str(path)


def test_search_plan_goes_from_the_start_to_the_goal(library_path):
    scenario = LittleDogTransferScenario(library=library_path)
    plan = plan_transfer(scenario)
    assert plan.search.status == "reached"
    # Never costlier than the planner alone (before: 5 recorded + 17 planned = 56 > 54).
    alone = plan_transfer(dataclasses.replace(scenario, mode="planner"))
    assert plan.search.cost <= alone.search.cost
    kinds = [s.kind for s in plan.library]
    assert kinds.count("recorded") == plan.search.recorded_count
    np.testing.assert_allclose(plan.library[0].start_feet, plan.feet0, atol=1e-9)
    # Every step ends where the next one starts (planned runs end on the recorded start).
    for a, b in zip(plan.library.steps[:-1], plan.library.steps[1:]):
        assert np.linalg.norm(step_end_feet(a) - b.start_feet, axis=1).sum() < 0.04
    end = step_end_feet(plan.library[-1])
    # Both front feet end past the goal line (a plan through the recorded steps used to
    # end with one on it, 0.23 - 3e-17 m: the search's goal test now refuses that).
    assert min(end[0, 0], end[1, 0]) >= plan.goal + GOAL_MARGIN
    # Recorded steps are walked on the unchanged part: their feet, start and end, stand
    # before x = change_from (a profile may reach a few mm past it onto bare slab, whose
    # heights there equal the source's). With the rocks from 0.15 m the search goes
    # through recorded steps (from 0.05 m the planner alone was cheaper).
    recorded = [s for s in plan.library if s.kind == "recorded"]
    assert len(recorded) >= 5
    for s in recorded:
        assert max(s.start_feet[:, 0].max(), step_end_feet(s)[:, 0].max()) < scenario.change_from


def test_ablation_modes(library_path):
    greedy = plan_transfer(LittleDogTransferScenario(library=library_path, mode="greedy"))
    assert greedy.search is None and greedy.library is greedy.transfer.library
    alone = plan_transfer(LittleDogTransferScenario(library=library_path, mode="planner"))
    assert alone.search.recorded_count == 0 and "planner alone" in alone.search.message
    assert {s.kind for s in alone.library} == {"planned"}


def test_closed_loop_starts_the_first_step(library_path):
    scenario = LittleDogTransferScenario(library=library_path)
    diagram = build_littledog_transfer(scenario)
    sim = Simulator(diagram)
    sim.AdvanceTo(0.3)
    log = diagram.GetSubsystemByName("step_log").FindLog(sim.get_context())
    assert log.data()[0, -1] == 0.0  # the nearest step at the start is the first one
    body = diagram.GetSubsystemByName("body_log").FindLog(sim.get_context()).data()
    assert np.all(body[2] > 0.12)  # standing, not fallen


def test_search_cut_short_by_its_cpu_limit_is_refused(library_path):
    scenario = LittleDogTransferScenario(library=library_path, planner_time_limit=1e-9)
    with pytest.raises(ScenarioError, match="status time_limit.*not executed"):
        plan_transfer(scenario)


@pytest.mark.parametrize(
    "change, match",
    [
        (dict(mode="fly"), "mode"),
        (dict(target="moon"), "target"),
        (dict(change_from=1.0), "change_from"),
        (dict(threshold=0.0), "threshold"),
        (dict(board_seeds=[1]), "board_seeds"),
        (dict(rock_seed=-4), r"^rock_seed must be an integer >= 0, got -4$"),
        (dict(rock_seed=2.5), r"^rock_seed must be an integer >= 0, got 2\.5$"),
        (dict(board_seeds=[-1, 3]), r"^board_seeds must be 2 integers >= 0, got \[-1, 3\]$"),
        (dict(board_seeds=[31, "a"]), r"^board_seeds must be 2 integers >= 0, got \[31, 'a'\]$"),
        (dict(source="terrain_z"), "terrain_z"),
        (dict(start_offset=[0.5, 0.0]), "start_offset"),
        (dict(library="/nonexistent/lib"), "nonexistent"),
    ],
)
def test_bad_scenarios_are_refused(change, match):
    scenario = dataclasses.replace(LittleDogTransferScenario(), **change)
    with pytest.raises(ScenarioError, match=match):
        plan_transfer(scenario)


def test_perturbed_start_snaps_to_the_nearest_flat_start():
    board = source_board("terrain_a")
    params = CrawlParams()
    wanted = np.array([0.0082, -0.0138]) + flat_start(board, 0.0, 0.25, params)
    got = flat_offset(board, wanted, -0.16, params)
    assert np.max(np.abs(got - wanted)) <= 0.04 + 1e-12
    _, feet, _ = crossing_start(board, 0.0, 0.25, params.standing_height, got, -0.16)
    rule = PlannerParams()
    assert np.all(
        flat_on_ground(board, feet[:, :2], rule) & clear_of_faces(board, feet[:, :2], rule)
    )
    # Nearest first: every grid offset closer to the wanted one has a foot off flat ground
    # or by a face.
    g = np.arange(-8, 9) * 0.005
    for dx in g:
        for dy in g:
            if dx * dx + dy * dy < float(np.sum((got - wanted) ** 2)) - 1e-12:
                off = wanted + [dx, dy]
                _, f, _ = crossing_start(board, 0.0, 0.25, params.standing_height, off, -0.16)
                ok = flat_on_ground(board, f[:, :2], rule) & clear_of_faces(board, f[:, :2], rule)
                assert not np.all(ok)


def test_start_off_the_board_is_refused_naming_the_offset(library_path):
    # Rear feet 1 mm behind the board's -0.4 m edge: the crawl planner would refuse the
    # start and the search would only say "unreachable"; refused before it instead.
    scenario = LittleDogTransferScenario(
        library=library_path, mode="planner", start_offset=[-0.04, 0.0]
    )
    with pytest.raises(ScenarioError) as info:
        plan_transfer(scenario)
    assert str(info.value) == (
        "start_offset [-0.0400, 0.0000] m (start_yaw_offset 0.000 rad) puts the start off "
        "the board: feet at x [-0.199, -0.199, -0.401, -0.401] m, y [0.070, -0.050, 0.070, "
        "-0.050] m leave the board (bounds x [-0.400, 0.400] m, y [-0.400, 0.400] m)"
    )
    # The largest offset of the shipped studies along -x (3 cm) stays on the board.
    plan = plan_transfer(dataclasses.replace(scenario, start_offset=[-0.03, 0.0]))
    assert plan.search.status == "reached"
    assert off_board(plan.board, plan.feet0) is None


def test_off_board_and_flat_offset_keep_every_foot_on_the_board():
    board = source_board("terrain_a")
    params = CrawlParams()
    assert off_board(board, np.array([[0.4, 0.4], [-0.4, -0.4], [0, 0], [0, 0]])) is None
    why = off_board(
        board, np.array([[0.1, 0.0, 0.0], [0.1, 0.0, 0.0], [-0.41, 0.0, 0.0], [0.0, 0.401, 0.0]])
    )
    assert why == (
        "feet at x [0.100, 0.100, -0.410, 0.000] m, y [0.000, 0.000, 0.000, 0.401] m leave "
        "the board (bounds x [-0.400, 0.400] m, y [-0.400, 0.400] m)"
    )
    # A wanted start 1 mm off the board: the nearest flat start with every foot on it.
    wanted = flat_start(board, 0.0, 0.25, params) + [-0.04, 0.0]
    got = flat_offset(board, wanted, 0.0, params)
    _, feet, _ = crossing_start(board, 0.0, 0.25, params.standing_height, got, 0.0)
    assert off_board(board, feet) is None
    assert np.all(flat_on_ground(board, feet[:, :2], PlannerParams()))


def test_gap_planner_map_covers_the_boards_extent(library_path, monkeypatch):
    """The gap planner's height map is the target board's extent (``bounds()``), not a
    square built from its length (a tiled or moved board need not be square or centred)."""
    import repertoire.diagrams.littledog_transfer as lt

    seen = []
    real = lt.height_map_from_board

    def record(board, x_range, y_range, resolution):
        seen.append((board.bounds(), tuple(x_range), tuple(y_range)))
        return real(board, x_range, y_range, resolution)

    monkeypatch.setattr(lt, "height_map_from_board", record)
    scenario = LittleDogTransferScenario(
        library=library_path, target="generated", board_seeds=[1000, 1001]
    )
    assert plan_transfer(scenario).search.status == "reached"
    (x0, x1, y0, y1), xr, yr = seen[0]
    assert (xr, yr) == ((x0, x1), (y0, y1))


class _Shift:
    """Stand-in gap filler: one step moving every foot to the target's centroid shift,
    except front foot 0 which stays ``lag`` m behind it, or on a given front line if it
    ``honours_line`` (as the crawl planner's goal test does); records its calls."""

    def __init__(self, lag: float, honours_line: bool = False):
        self.lag, self.honours_line = lag, honours_line
        self.targets: list[np.ndarray] = []
        self.lines: list = []
        self.places: list = []

    def __call__(self, start, target, time_limit, front_line=None, place=True):
        self.targets.append(np.array(target))
        self.lines.append(front_line)
        self.places.append(place)
        end = np.array(start, dtype=float)
        end[:, :2] += target[:, :2].mean(axis=0) - end[:, :2].mean(axis=0)
        end[0, 0] -= self.lag
        if front_line is not None and self.honours_line:
            end[0, 0] = max(end[0, 0], front_line[2])
        return GapFill([PlannedStep(np.array(start), end, 0)], "reached")


def _goal_case():
    goal = 0.23
    start = np.zeros((4, 3))
    start[:, 0] = [0.1, 0.1, -0.1, -0.1]
    goal_feet = start + [0.16, 0.0, 0.0]  # front feet at 0.26, centroid at 0.16
    return goal, start, goal_feet


def test_goal_line_filler_gives_the_line_to_the_planners_goal_test():
    goal, start, goal_feet = _goal_case()
    inner = _Shift(lag=0.04, honours_line=True)  # would end 1 cm short without the line
    fill = GoalLineFiller(inner, goal_feet, goal)(start, goal_feet, 1.0)
    assert fill.status == "reached" and len(fill.steps) == 1
    assert inner.lines == [(1.0, 0.0, goal + GOAL_MARGIN)]
    assert fill.steps[-1].end_feet[0, 0] == goal + GOAL_MARGIN
    # no feet are placed onto the made-up goal stance
    assert inner.places == [False]
    # a gap to another target gets no line, and the wrapped filler's own placing
    GoalLineFiller(inner, goal_feet, goal)(start, goal_feet - [0.05, 0.0, 0.0], 1.0)
    assert inner.lines[-1] is None and inner.places[-1] is True


def test_goal_line_filler_returns_a_gap_that_still_ends_short_as_it_is():
    goal, start, goal_feet = _goal_case()
    inner = _Shift(lag=0.04)  # ignores the line: ends with foot 0 at 0.22, 1 cm short
    fill = GoalLineFiller(inner, goal_feet, goal)(start, goal_feet, 1.0)
    # planned once, with the line; the search's goal test refuses the short end
    assert fill.status == "reached" and len(fill.steps) == 1
    assert inner.lines == [(1.0, 0.0, goal + GOAL_MARGIN)]
    assert min(fill.steps[-1].end_feet[:2, 0]) == pytest.approx(0.22)
    assert GOAL_MARGIN == 0.005
    # A gap to another target is the wrapped filler's own.
    inner = _Shift(lag=0.04)
    other = goal_feet - [0.05, 0.0, 0.0]
    assert len(GoalLineFiller(inner, goal_feet, goal)(start, other, 1.0).steps) == 1
    assert inner.lines == [None]


@pytest.mark.parametrize("rock_seed", [8, 31, 39])
def test_search_uses_the_recorded_run_whatever_the_goal_stance_stands_on(library_path, rock_seed):
    # Placing feet onto the goal stance added up to 4 planned steps to the goal gaps, so
    # with this library the search kept 0 (seed 8) or 8 (seeds 31, 39) recorded steps
    # (cost 54, 59, 59); rock seed 5 gave 12 + 12 then. The planner alone costs 60
    # (20 steps; 54 and 18 before its footholds kept 2 cm from faces, ``clear_of_faces``).
    # 12 + 11 since the gap into the chain takes the fewest steps onto its start
    # (``CrawlGapFiller.shortest_placed``: 3 planned steps there, 4 before).
    plan = plan_transfer(LittleDogTransferScenario(library=library_path, rock_seed=rock_seed))
    s = plan.search
    assert (s.status, s.recorded_count, s.planned_count, s.cost) == ("reached", 12, 11, 45.0)
    assert s.planner_alone_cost == 60.0


def test_planner_alone_places_no_feet_onto_the_goal_stance_on_rocks(library_path):
    # Rock seed 31: the goal stance's footholds (the start stance shifted, start heights)
    # are flat on top of rocks; the gap to the goal placed feet onto it after the planner's
    # 18 steps, lf, rh and rf 3.3-4.0 cm below the rock tops (21 steps, cost 63). The goal
    # is the planner's goal test (centroid, heading, line), not a stance to place feet on.
    # (20 planned steps since the planner keeps its footholds 2 cm from faces; 18 before.)
    from repertoire.models.littledog import FOOT_RADIUS

    scenario = LittleDogTransferScenario(library=library_path, mode="planner", rock_seed=31)
    plan = plan_transfer(scenario)
    assert plan.search.status == "reached"
    assert (plan.search.recorded_count, plan.search.planned_count) == (0, 20)
    for item in plan.search.path:
        f = item.planned.end_feet
        np.testing.assert_allclose(
            f[:, 2] - FOOT_RADIUS, plan.board.height(f[:, 0], f[:, 1]), atol=1e-9
        )
    for step in plan.library:
        for f in (step.start_feet, step_end_feet(step)):
            assert np.all(
                np.abs(f[:, 2] - FOOT_RADIUS - plan.board.height(f[:, 0], f[:, 1])) < 5e-3
            )
    end = step_end_feet(plan.library[-1])
    assert min(end[0, 0], end[1, 0]) >= plan.goal + GOAL_MARGIN


def test_planner_alone_crosses_where_planning_on_from_the_end_had_no_step(library_path):
    # A perturbed start of the execution study (seed 1) on the default rocks: the gap to
    # the goal stance's centroid ended with a front foot on the line (0.23 m) and the crawl
    # had no step from that stance, so planning on failed and nothing could be executed.
    scenario = LittleDogTransferScenario(
        library=library_path, mode="planner", start_offset=[0.00071, 0.02703],
        start_yaw_offset=np.deg2rad(-7.1168),
    )  # fmt: skip
    plan = plan_transfer(scenario)
    assert plan.search.status == "reached" and plan.search.recorded_count == 0
    end = step_end_feet(plan.library[-1])
    assert min(end[0, 0], end[1, 0]) >= plan.goal + GOAL_MARGIN


def test_gap_planner_prices_a_step_as_planner_step_cost_of_travel(library_path, monkeypatch):
    """A crawl step takes the same time however far its foot moves: the gap planner's
    ``step_cost`` is PLANNER_STEP_COST, and with it the execution study's planner-only
    start 0 (where the face rule leaves few footholds) no longer creeps in 1 cm steps."""
    import repertoire.diagrams.littledog_transfer as lt
    import repertoire.planning.transfer_crawl_filler as tcf

    costs = []
    real = tcf.plan_crawl

    def record(height_map, start, goal, params, **kw):
        costs.append(params.step_cost)
        return real(height_map, start, goal, params, **kw)

    monkeypatch.setattr(tcf, "plan_crawl", record)
    # The start flat_offset took before it kept start feet clear of faces too (its lh foot
    # stands by one): the start where the planner crept. (From the start it takes now, 21
    # steps at either step cost.)
    monkeypatch.setattr(lt, "clear_of_faces", lambda board, xy, rule: np.ones(len(xy), bool))

    # And the goal stance before it faced +x (it kept the start's -9.2 degrees; facing +x
    # the plan has 19 steps at either step cost).
    def start_heading_goal(feet0, goal):
        return feet0 + [goal + 0.06 - min(feet0[0, 0], feet0[1, 0]), -feet0[:, 1].mean(), 0.0]

    monkeypatch.setattr(lt, "goal_stance", start_heading_goal)
    scenario = LittleDogTransferScenario(
        library=library_path, mode="planner", start_offset=[0.0082177, -0.0138128],
        start_yaw_offset=np.deg2rad(-9.1805),
    )  # fmt: skip
    plan = plan_transfer(scenario)
    assert costs and set(costs) == {lt.PLANNER_STEP_COST}
    monkeypatch.setattr(lt, "PLANNER_STEP_COST", PlannerParams().step_cost)
    before = plan_transfer(scenario)
    for p in (plan, before):
        assert p.search.status == "reached" and p.search.recorded_count == 0
    travel = [np.linalg.norm(b.start_feet - a.start_feet, axis=1).max() for a, b in
              zip(plan.library.steps[:-1], plan.library.steps[1:])]  # fmt: skip
    # measured: 20 steps against 28 at the model's 1 cm (two of them moved a foot 1 cm)
    assert len(plan.library) == 20 and len(before.library) == 28
    assert min(travel) > 0.02


def test_board_without_the_operators_flat_start_still_plans(library_path):
    """Generated boards 74/75 have no start flat by the scripted operator's 2 cm rule
    (``flat_start`` raises); the start is then the nominal one moved by ``flat_offset``
    (the planner's rule) and the transfer plans, where it raised a bare RepertoireError."""
    from repertoire.diagrams.littledog_transfer import nominal_start, target_board

    from repertoire.errors import RepertoireError

    scenario = LittleDogTransferScenario(
        library=library_path, target="generated", board_seeds=[74, 75], mode="planner"
    )
    board = target_board(scenario)
    with pytest.raises(RepertoireError, match="no flat start within 6 cm"):
        flat_start(board, 0.0, 0.25, CrawlParams())
    np.testing.assert_array_equal(nominal_start(board, CrawlParams()), [0.0, 0.0])
    plan = plan_transfer(scenario)
    assert plan.search.status == "reached"
    assert np.all(flat_on_ground(board, plan.feet0[:, :2], PlannerParams()))
    # where the operator's start exists it is kept (the library's crossings start there)
    source = source_board("terrain_a")
    np.testing.assert_array_equal(
        nominal_start(source, CrawlParams()), flat_start(source, 0.0, 0.25, CrawlParams())
    )


def test_start_where_the_robot_cannot_stand_is_a_scenario_error(library_path, monkeypatch):
    """A start straddling stacked steps (front feet 13 cm above the hind ones, beyond the
    legs' reach) is refused as a ScenarioError naming the start, as the execution study
    expects; it was a bare RepertoireError from the standing pose."""
    import repertoire.diagrams.littledog_transfer as lt
    from repertoire.models.terrain import TerrainParams, generate_board, tile_boards

    steps = TerrainParams(kind="steps", size_x=0.4, size_y=0.8, step_rise=[0.025, 0.045])
    monkeypatch.setattr(
        lt,
        "target_board",
        lambda s: tile_boards([generate_board(steps, 82), generate_board(steps, 83)]),
    )
    scenario = LittleDogTransferScenario(library=library_path, target="generated", mode="planner")
    with pytest.raises(
        ScenarioError, match=r"cannot stand at the start \(offset \[0.0000, 0.0000\]"
    ):
        plan_transfer(scenario)


def test_a_library_of_steps_from_no_library_terrain_is_a_scenario_error(library_path, tmp_path):
    """The final library of a transfer (steps on "new_terrain") given as the library to
    transfer: a bare RepertoireError from the source-terrain lookup before, which the
    execution study does not catch (a crash, not a start with nothing to execute)."""
    plan = plan_transfer(LittleDogTransferScenario(library=library_path, mode="planner"))
    plan.library.save(tmp_path / "final")
    scenario = LittleDogTransferScenario(library=str(tmp_path / "final"), mode="planner")
    with pytest.raises(
        ScenarioError,
        match=r"holds steps recorded on \['new_terrain'\], not on a library terrain "
        r"\['terrain_a', 'terrain_b'\]",
    ):
        plan_transfer(scenario)


def test_a_perturbed_start_keeps_its_feet_clear_of_faces_where_it_can():
    """The start is moved to the nearest one whose feet meet the planner's foothold rules,
    the face rule too. Before, only flatness: on generated 31/32 (execution study start 3103
    of +-4 cm, +-20 deg) rh stood 1.5 cm from a 2.9 cm rock face, climbed it during the 12 cm
    body shift before its first swing, and the robot fell (crosses in 28.1 s now)."""
    params, rule = CrawlParams(), PlannerParams()
    board = target_board(LittleDogTransferScenario(target="generated"))
    offset = nominal_start(board, params) + [-0.020171007895455232, 0.014750780014962439]
    yaw = -0.3397045058668001

    def feet(off):
        return crossing_start(board, 0.0, 0.25, params.standing_height, off, yaw)[1][:, :2]

    got = flat_offset(board, offset, yaw, params)
    np.testing.assert_allclose(got, offset + [-0.01, 0.015], rtol=0, atol=1e-12)
    assert (
        flat_on_ground(board, feet(got), rule).all()
        and clear_of_faces(board, feet(got), rule).all()
    )
    old = offset + [-0.005, 0.005]  # the nearest flat start, taken before
    assert flat_on_ground(board, feet(old), rule).all()
    assert clear_of_faces(board, feet(old), rule).tolist() == [True, True, True, False]
    # No start within 4 cm clear of faces (modified terrain, study start 3045): the nearest
    # flat one, as before.
    board = target_board(LittleDogTransferScenario())
    offset = nominal_start(board, params) + [0.0343940275982156, 0.03283480254724442]
    yaw = -0.24794105150539994
    got = flat_offset(board, offset, yaw, params)
    np.testing.assert_allclose(got, offset + [-0.01, -0.005], rtol=0, atol=1e-12)
    assert flat_on_ground(board, feet(got), rule).all()
    assert not clear_of_faces(board, feet(got), rule).all()


def test_goal_stance_faces_the_crossing_whatever_the_start_heading():
    """The goal stance is the start stance turned to +x (a rigid move), its front feet 6 cm
    past the line, centred across the board; before, it kept the start's yaw offset."""
    from repertoire.planning.littledog_crawl import heading_of

    board = source_board("terrain_a")
    params = CrawlParams()
    _, feet0, _ = crossing_start(board, 0.0, 0.25, params.standing_height, [0.0, -0.1], -0.5)
    assert heading_of(feet0) == pytest.approx(-0.5, abs=0.05)
    goal = goal_stance(feet0, 0.23)
    assert heading_of(goal) == pytest.approx(0.0, abs=1e-12)
    assert min(goal[0, 0], goal[1, 0]) == pytest.approx(0.29, abs=1e-12)
    assert goal[:, 1].mean() == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_array_equal(goal[:, 2], feet0[:, 2])

    def spans(f):
        return np.linalg.norm(f[:, None, :2] - f[None, :, :2], axis=-1)

    np.testing.assert_allclose(spans(goal), spans(feet0), atol=1e-12)


def test_planner_alone_from_the_scenarios_edge_crosses_facing_the_line(library_path):
    """Offset [0, -0.1] m, yaw offset -0.5 rad (rock seed 502): with a goal stance at the
    start's heading the planner crossed crabbing at -29 degrees and centred itself after
    the line (39 steps, the front feet across after 24); facing +x, 21 steps, 20."""
    from repertoire.planning.littledog_crawl import heading_of

    scenario = LittleDogTransferScenario(
        library=library_path, mode="planner", rock_seed=502, start_offset=[0.0, -0.1],
        start_yaw_offset=-0.5,
    )  # fmt: skip
    plan = plan_transfer(scenario)
    starts = np.array([s.start_feet for s in plan.library] + [step_end_feet(plan.library[-1])])
    across = np.flatnonzero(np.minimum(starts[:, 0, 0], starts[:, 1, 0]) >= plan.goal)
    assert (len(plan.library), int(across[0])) == (21, 20)
    assert abs(heading_of(starts[-1])) <= np.radians(5.0)


def _tall_rocks(seed: int):
    """Two generated boards (seeds ``seed``, ``seed + 1``) of rocks 5-6 cm high."""
    from repertoire.models.terrain import TerrainParams, generate_board, tile_boards

    params = TerrainParams(kind="rocks", size_x=0.4, size_y=0.8, rock_count=12)
    params.rock_height = [0.05, 0.06]
    return tile_boards([generate_board(params, seed), generate_board(params, seed + 1)])


def test_a_failed_search_from_a_start_not_level_says_so(library_path, monkeypatch):
    """Pair 610/611 of 5-6 cm rocks: the start stands rf and rh on rock tops 5.9 and 5.1 cm
    above the slab, which the planner may not step down from; a search that does not
    reach the goal names that."""
    import repertoire.diagrams.littledog_transfer as lt
    from repertoire.planning.transfer_search import SearchResult

    board = _tall_rocks(610)
    monkeypatch.setattr(lt, "target_board", lambda scenario: board)
    five = dataclasses.replace(lt.planner_params(), max_step_height=0.05)  # before session 36
    monkeypatch.setattr(lt, "planner_params", lambda: five)
    cut = SearchResult("time_limit", [], 0.0, 0, 0, 1, 0, "a gap filler's time limit", 10.0)
    monkeypatch.setattr(lt, "search_library", lambda *args: cut)
    scenario = LittleDogTransferScenario(library=library_path, mode="planner", target="generated")
    with pytest.raises(ScenarioError) as e:
        plan_transfer(scenario)
    assert "status time_limit" in str(e.value)
    assert "feet stand on ground 5.9 cm apart in height, more than the planner's" in str(e.value)


def test_the_gap_planner_keeps_the_models_step_height_and_its_own_step_cost():
    """The gap planner is the crawl model with its own step cost; its step height is the
    model's default, the crawl's reach (test_footstep_quadruped checks that reach)."""
    from repertoire.diagrams.littledog_transfer import planner_params

    params = planner_params()
    assert (params.max_step_height, params.step_cost) == (0.09, 0.02)
    assert dataclasses.replace(params, step_cost=0.01) == PlannerParams()


def test_the_planner_alone_crosses_rocks_taller_than_the_models_step(library_path, monkeypatch):
    """Pair 624/625 of 5-6 cm rocks: at the model's 5 cm every rock was a wall and the
    search ended in the gap planner's time limit (386624 expansions, 562 s of CPU without
    one, 37 cm short of the goal); with the crawl's reach the planner alone plans 22 steps,
    and the start of 610/611 (rf and rh on rock tops 5.9 and 5.1 cm up) is level."""
    import repertoire.diagrams.littledog_transfer as lt

    board = _tall_rocks(624)
    monkeypatch.setattr(lt, "target_board", lambda scenario: board)
    scenario = LittleDogTransferScenario(library=library_path, mode="planner", target="generated")
    plan = plan_transfer(scenario)
    assert (plan.search.status, plan.search.planned_count, len(plan.library)) == ("reached", 22, 22)
    starts = np.array([s.start_feet for s in plan.library] + [step_end_feet(plan.library[-1])])
    assert np.all(np.minimum(starts[-1:, 0, 0], starts[-1:, 1, 0]) >= plan.goal + GOAL_MARGIN)
    board, params = _tall_rocks(610), CrawlParams()
    offset = flat_offset(board, nominal_start(board, params), 0.0, params)
    feet = crossing_start(board, 0.0, 0.25, params.standing_height, offset)[1]
    z = board.height(feet[:, 0], feet[:, 1])
    assert np.round(100 * (z - z.min()), 1).tolist() == [0.0, 5.9, 0.0, 5.1]
    rules = [PlannerParams(max_step_height=0.05), lt.planner_params()]
    assert [lt.start_level(board, feet, rule) for rule in rules] == [False, True]
