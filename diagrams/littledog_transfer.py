"""LittleDog crossing a terrain it never saw with a transferred library (``littledog_transfer``).

Stolle et al., sections V-VI: the step library recorded on the source terrains
(:data:`~repertoire.diagrams.littledog_demos.LIBRARY_TERRAINS`) is transferred
onto a new terrain (:func:`~repertoire.planning.transfer_library.transfer_library`:
terrain features, PCA matching), the section-V search joins the robot's stance
to the goal through transferred steps with gaps filled by the footstep
planner's quadruped crawl model
(:class:`~repertoire.planning.transfer_crawl_filler.CrawlGapFiller`), and the
final library (path steps plus the planned steps, executed by the scripted
crawl) is run in physics by the same closed loop as ``littledog_library``:
nearest-step policy, step executor (spline blend, playback) and integral foot
controller.

The new terrain is either ``modified`` (a source terrain whose part beyond
``change_from`` is replaced by rocks of seed ``rock_seed``, the paper's Fig. 10)
or ``generated`` (rough boards from ``board_seeds``, seeds the demonstrations
never used). ``mode`` selects the ablations of the study: ``search`` (the
paper), ``greedy`` (every transferred step, no search: the policy picks the
nearest), ``planner`` (no library: the planner's steps alone). Transfer and
search take a few seconds in the builder; the transfer of the library onto a
terrain is cached per process (studies run many episodes on one terrain).
"""

import dataclasses
import functools
import math

import numpy as np
from pydrake.systems.framework import Diagram
from repertoire.diagrams.littledog_demos import (
    LIBRARY_TERRAINS,
    crossing_start,
    flat_start,
    library_terrain,
)
from repertoire.diagrams.littledog_library import (
    DEFAULT_LIBRARY,
    LibraryLoopFields,
    build_library_crossing,
    check_littledog_library,
    load_library,
    validate_loop_fields,
)
from repertoire.diagrams.registry import register_diagram
from repertoire.models.terrain import (
    TerrainBoard,
    generate_board,
    replace_with_rocks,
    tile_boards,
)
from repertoire.planning.footstep.height_map import height_map_from_board
from repertoire.planning.footstep.quadruped import CrawlParams as PlannerParams
from repertoire.planning.footstep.quadruped import clear_of_faces, flat_on_ground
from repertoire.planning.littledog_crawl import CrawlParams, heading_of
from repertoire.planning.step_library import StepLibrary
from repertoire.planning.terrain_features import TransferConfig
from repertoire.planning.transfer_crawl_filler import CrawlGapFiller
from repertoire.planning.transfer_library import (
    LibraryTransfer,
    final_library,
    fit_board_pca,
    search_library,
    transfer_library,
)
from repertoire.planning.transfer_search import GapFill, SearchConfig, SearchResult
from repertoire.systems.library_policy import front_progress

from repertoire.criteria import Bound
from repertoire.errors import RepertoireError, ScenarioError

MODES = ("search", "greedy", "planner")
TARGETS = ("modified", "generated")
HALF_EXTENT = 0.25
"""Start at -HALF_EXTENT along +x; the goal line (front feet) is at HALF_EXTENT - 0.02."""
MAP_RESOLUTION = 0.01
"""Cell side of the height map the gap-filling crawl planner plans on (m)."""
GOAL_MARGIN = 0.5 * MAP_RESOLUTION
"""How far past the goal line (m) both planned front feet must end: the search's goal
stance and tolerances aim at a centroid and do not imply the line (a plan of the default
scenario ended with a front foot exactly on it, 0.23 - 3e-17 m), and a foot planned on the
line crosses in physics or not by its tracking error. Half a map cell: footholds lie on
cell centres, the line on one, so a foot on the line fails and the next cell passes
whatever the rounding."""
PLANNER_STEP_COST = 0.02
"""The gap-filling crawl planner's cost per step (its ``step_cost``; a step's cost is this
plus the foot's travel in m). Executing a crawl step takes the same time (1.25 s and the
executor's blend) however far its foot moves, up to about 12 cm, so a step is priced as 2 cm
of travel: at the model's 1 cm the planner crept in 1-3 cm steps where the face rule leaves
few footholds (planner-only start 0 of the execution study: 28 steps, 38.9 s to cross; 20
steps now). 3 cm gave the same step counts on the 15 starts compared (one fewer on one) but
heavier gap searches (generated start 1002: 3.2 -> 9.0 s of the search's 10 s CPU budget)."""


@dataclasses.dataclass
class LittleDogTransferScenario(LibraryLoopFields):
    """LittleDog crossing a new terrain along +x with a transferred library.

    Attributes:
        target: ``modified`` (source terrain with rocks beyond ``change_from``) or
            ``generated`` (rough boards of ``board_seeds``).
        source: the library terrain modified (``modified``) and whose board kind is
            generated (``generated``).
        change_from: x (m) where the modified part starts. The default, 0.15 m, leaves the
            first 0.55 m of the 0.8 m board as it was and puts rocks on the last 0.25 m (the
            goal line is at 0.23 m): the paper's Fig. 10 replaces the end board. From 0.05 m
            (the default before session 28) the transferred steps were 5 near the start,
            and the planner alone (19 steps) was cheaper than any path through them; from
            0.15 m the search's path is 11 recorded steps and 12 planned ones on the rocks
            (11-12 recorded on each of rock seeds 0-40; seed 8 gave 5 while the goal gap
            placed feet onto the goal stance, see :class:`GoalLineFiller`).
        rock_seed: seed of the rocks on the modified part.
        board_seeds: one seed per generated board (two boards side by side).
        mode: ``search`` | ``greedy`` (no search) | ``planner`` (no library).
        threshold: PCA match threshold of the transfer.
        multiple: several matches per step (section VII).
        planner_time_limit: CPU-time limit of the search with its planner (s); a search
            cut short by it is refused (its best partial path is not executed), or, when
            the planner alone had reached the goal, returns that path. A cap, not a
            routine cut: uncut searches of the execution study's starts take 1-4 s of
            CPU depending on the machine, and a tighter limit makes the path (library
            steps or the planner alone) depend on the machine's speed.

    The start perturbation, source library, loop gains and physics are the fields of
    :class:`~repertoire.diagrams.littledog_library.LibraryLoopFields`.
    """

    target: str = "modified"
    source: str = "terrain_a"
    change_from: float = 0.15
    rock_seed: int = 5
    board_seeds: list[int] = dataclasses.field(default_factory=lambda: [31, 32])
    mode: str = "search"
    threshold: float = 0.05
    multiple: bool = False
    planner_time_limit: float = 10.0

    def validate(self) -> None:
        """Raises ScenarioError naming a bad field."""
        if self.source not in LIBRARY_TERRAINS:
            raise ScenarioError(
                f"source must be a library terrain, one of {sorted(LIBRARY_TERRAINS)}, "
                f"got {self.source!r}"
            )
        try:
            self.plant.validate()
        except RepertoireError as e:
            raise ScenarioError(f"LittleDogTransferScenario: {e}") from e
        if self.target not in TARGETS:
            raise ScenarioError(f"target must be one of {TARGETS}, got {self.target!r}")
        if self.mode not in MODES:
            raise ScenarioError(f"mode must be one of {MODES}, got {self.mode!r}")
        if not (math.isfinite(self.change_from) and -0.35 < self.change_from < 0.35):
            raise ScenarioError(f"change_from must lie in (-0.35, 0.35) m, got {self.change_from}")
        if not _seed_ok(self.rock_seed):
            raise ScenarioError(f"rock_seed must be an integer >= 0, got {self.rock_seed!r}")
        if not (
            isinstance(self.board_seeds, (list, tuple))
            and len(self.board_seeds) == 2
            and all(_seed_ok(s) for s in self.board_seeds)
        ):
            raise ScenarioError(f"board_seeds must be 2 integers >= 0, got {self.board_seeds!r}")
        if not (math.isfinite(self.threshold) and self.threshold > 0.0):
            raise ScenarioError(f"threshold must be positive, got {self.threshold}")
        if not (math.isfinite(self.planner_time_limit) and self.planner_time_limit > 0.0):
            raise ScenarioError(
                f"planner_time_limit must be positive, got {self.planner_time_limit}"
            )
        validate_loop_fields(self)


def _seed_ok(value) -> bool:
    """An integer (or integral number) >= 0: numpy's random generators refuse negative seeds."""
    if isinstance(value, bool):
        return False
    try:
        return int(value) == value and value >= 0
    except (TypeError, ValueError, OverflowError):
        return False


@functools.cache
def source_board(name: str) -> TerrainBoard:
    """A library terrain as one board with its true extent (boards tiled along x)."""
    t = library_terrain(name)
    return tile_boards([generate_board(t.board, int(s)) for s in t.seeds])


def target_board(scenario: LittleDogTransferScenario) -> TerrainBoard:
    """The scenario's new terrain."""
    if scenario.target == "modified":
        return replace_with_rocks(
            source_board(scenario.source), scenario.change_from, seed=scenario.rock_seed
        )
    t = library_terrain(scenario.source)
    return tile_boards([generate_board(t.board, int(s)) for s in scenario.board_seeds])


@functools.cache
def library_terrains_pca():
    """The PCA basis of the terrain profiles of the boards the library was recorded on."""
    return fit_board_pca([source_board(n) for n in sorted(LIBRARY_TERRAINS)])


_TRANSFER_FIELDS = (
    "target",
    "source",
    "change_from",
    "rock_seed",
    "board_seeds",
    "threshold",
    "multiple",
    "library",
)


@functools.lru_cache(maxsize=8)
def _transfer(key: tuple) -> LibraryTransfer:
    values = dict(zip(_TRANSFER_FIELDS, key))
    values["board_seeds"] = list(values["board_seeds"])
    scenario = LittleDogTransferScenario(**values)
    library = load_library(scenario.library)
    names = sorted({s.terrain for s in library})
    foreign = [n for n in names if n not in LIBRARY_TERRAINS]
    if foreign:
        # e.g. a final library saved by an earlier transfer (its steps are on "new_terrain"):
        # a step is matched by its profile on the terrain it was recorded on
        raise ScenarioError(
            f"library {scenario.library or str(DEFAULT_LIBRARY)!r} holds steps recorded on "
            f"{foreign}, not on a library terrain {sorted(LIBRARY_TERRAINS)}: only steps of the "
            "demonstrations can be transferred (their source terrain gives their profiles)"
        )
    sources = {n: source_board(n) for n in names}
    config = TransferConfig(threshold=scenario.threshold, multiple=scenario.multiple)
    return transfer_library(
        library,
        sources,
        target_board(scenario),
        library_terrains_pca(),
        config,
        target_name="new_terrain",
    )


def library_transfer(scenario: LittleDogTransferScenario) -> LibraryTransfer:
    """The library transferred onto the scenario's terrain (cached per terrain and settings)."""
    key = tuple(getattr(scenario, f) for f in _TRANSFER_FIELDS)
    return _transfer(tuple(tuple(v) if isinstance(v, list) else v for v in key))


def off_board(board: TerrainBoard, feet) -> str | None:
    """None if every foot centre of ``feet`` (4, 2+) lies within ``board.bounds()``, else why not.

    The crawl planner plans on a height map of the board's extent and refuses start
    footholds off it.
    """
    x0, x1, y0, y1 = board.bounds()
    xy = np.asarray(feet, dtype=float)[:, :2]
    if np.all((xy[:, 0] >= x0) & (xy[:, 0] <= x1) & (xy[:, 1] >= y0) & (xy[:, 1] <= y1)):
        return None
    fx = ", ".join(f"{v:.3f}" for v in xy[:, 0])
    fy = ", ".join(f"{v:.3f}" for v in xy[:, 1])
    return (
        f"feet at x [{fx}] m, y [{fy}] m leave the board "
        f"(bounds x [{x0:.3f}, {x1:.3f}] m, y [{y0:.3f}, {y1:.3f}] m)"
    )


def nominal_start(board: TerrainBoard, params: CrawlParams) -> np.ndarray:
    """The unperturbed start offset: the scripted operator's flat start, else none.

    The library's crossings start at :func:`~repertoire.diagrams.littledog_demos.flat_start`
    (feet flat by the operator's 2 cm ``edge_radius`` rule, within 6 cm), so on the
    modified terrain the transferred steps meet the same start. Where no such start exists
    (generated boards 74/75, 91/92, 94/95 ... : 13 of 300 seed pairs), the offset is 0 and
    :func:`flat_offset` moves the start to the nearest one flat by the planner's rule (it
    found one within 1.5 cm on all 13); before, ``plan_transfer`` raised a bare
    RepertoireError there, which the execution study recorded as a crash.
    """
    try:
        return flat_start(board, 0.0, HALF_EXTENT, params)
    except RepertoireError:
        return np.zeros(2)


def flat_offset(board: TerrainBoard, offset, yaw: float, params: CrawlParams) -> np.ndarray:
    """The start offset nearest ``offset`` (within 4 cm, on a 5 mm grid) with flat footholds.

    Flat by the footstep planner's foothold rules, the rules every planned foothold meets:
    :func:`flat_on_ground` (within the foot's radius on the exact board, the planner's
    default ``max_roughness``) and :func:`clear_of_faces` (no ground rising above it within
    ``face_radius``, 2 cm); the planner refuses start footholds on a rock's edge, and so
    would the robot's first steps, so a perturbed start is moved to the nearest flat one.
    (The scripted operator's stricter 2 cm rule left no flat start within 4 cm near a
    board's edge: 3 of 50 perturbed starts on the modified terrain.) Before the face rule
    applied to the start too, a start foot 1.5 cm from a 2.9 cm rock face (generated
    31/32, study start 3103 of +-4 cm, +-20 deg) climbed it during the 12 cm body shift
    before its first swing and the robot fell over it, as planned feet did before the
    planner kept them clear of faces. Where no start within 4 cm is clear of faces (2 of
    100 starts of that +-4 cm, +-20 deg study), the nearest flat one is taken, as before.

    Only starts with every foot on the board (:func:`off_board`) are taken.

    Raises:
        ScenarioError: no flat start within 4 cm.
    """
    rule = PlannerParams()
    g = np.arange(-8, 9) * 0.005  # 5 mm grid (a 1 cm grid missed flat starts on rough boards)
    trials = sorted(
        ((x, y) for x in g for y in g if x * x + y * y <= 0.04**2 + 1e-12),
        key=lambda o: o[0] ** 2 + o[1] ** 2,
    )
    flat = None  # the nearest start flat but by a face
    for dx, dy in trials:
        off = np.asarray(offset, dtype=float) + [dx, dy]
        try:
            _, feet, _ = crossing_start(board, 0.0, HALF_EXTENT, params.standing_height, off, yaw)
        except RepertoireError:  # the legs cannot reach the ground there: not a start
            continue
        if off_board(board, feet) is None and np.all(flat_on_ground(board, feet[:, :2], rule)):
            if np.all(clear_of_faces(board, feet[:, :2], rule)):
                return off
            flat = off if flat is None else flat
    if flat is not None:
        return flat
    x, y = (float(v) for v in offset)
    raise ScenarioError(
        f"no flat start within 4 cm of offset [{x:.4f}, {y:.4f}] m at yaw {yaw:.3f} rad"
    )


def planner_params() -> PlannerParams:
    """The gap-filling crawl planner's parameters (its defaults but the step cost).

    Its ``max_step_height`` is the model's default, the crawl's reach (9 cm). Session 36
    set it here alone: at the model's 5 cm then, every rock of a board of 5-6 cm rocks was
    a wall, and pair 624/625 ended at 386624 expansions and 562 s of CPU, 37 cm short.
    """
    return PlannerParams(step_cost=PLANNER_STEP_COST)


def start_level(board: TerrainBoard, feet, rule: PlannerParams) -> bool:
    """Whether the ground under ``feet`` (4, 2+) differs by at most ``rule.max_step_height``.

    A foot standing higher above the others than the crawl planner steps up or down
    (on a rock top above the slab the other feet stand on) can step only onto ground of
    its own height: on boards of rocks taller than that it stays on its rock, shuffling
    on the rock's top until the planner's limit (boards of 5-6 cm rocks at the 5 cm of
    sessions before 36: 4 of the pairs 610/611 ... 624/625 and 7 of 630/631 ... 658/659
    started so; none at the crawl's reach, 9 cm; :func:`plan_transfer` names it when the
    search does not reach the goal).
    """
    xy = np.asarray(feet, dtype=float)[:, :2]
    return bool(np.ptp(board.height(xy[:, 0], xy[:, 1])) <= rule.max_step_height + 1e-12)


def perturbed_start(
    scenario: LittleDogTransferScenario, board: TerrainBoard, params: CrawlParams
) -> tuple[np.ndarray, np.ndarray]:
    """The scenario's start offset (nominal plus ``start_offset``) and its feet (4, 3).

    The start as the scenario asks for it, before :func:`flat_offset` moves it to flat
    footholds; its feet may leave the board (:func:`off_board` says).

    Raises:
        ScenarioError: the robot cannot stand there (e.g. a start straddling steps higher
            than the legs reach).
    """
    offset = nominal_start(board, params) + np.asarray(scenario.start_offset, dtype=float)
    try:
        _, feet, _ = crossing_start(
            board, 0.0, HALF_EXTENT, params.standing_height, offset, scenario.start_yaw_offset
        )
    except RepertoireError as e:
        x, y = (float(v) for v in offset)
        raise ScenarioError(
            f"littledog_transfer: the robot cannot stand at the start (offset [{x:.4f}, "
            f"{y:.4f}] m, yaw offset {scenario.start_yaw_offset:.3f} rad): {e}"
        ) from e
    return offset, feet


@dataclasses.dataclass
class TransferPlan:
    """What the builder runs: terrain, start, goal, the search and the final library.

    ``search_s`` is the search's CPU time with its planner (s); the transfer's wall
    times are in ``transfer.timings``.
    """

    board: TerrainBoard
    pose0: np.ndarray
    feet0: np.ndarray
    q0: np.ndarray
    goal: float
    transfer: LibraryTransfer
    search: SearchResult | None
    library: StepLibrary
    search_s: float = 0.0


def goal_stance(feet0: np.ndarray, goal: float) -> np.ndarray:
    """The search's goal stance: the start stance ``feet0`` (4, 3) facing the goal line.

    ``feet0`` turned about its centroid to the crossing's heading (+x, :func:`heading_of`
    0), moved along +x until its front feet stand 6 cm past the line ``x = goal`` (so
    the centroid stops within the search's 3 cm of it), and centred across the board.
    The planner's gap to it ends facing +x (its goal heading is this stance's, within 5
    degrees) with both front feet past the line (:class:`GoalLineFiller`).

    The start's yaw offset is a perturbation of the start, not of the task. Before, the
    goal stance kept it (``feet0`` moved, not turned): from the scenario's edge (offset
    [0, -0.1] m, yaw offset -0.5 rad, rock seed 502) the planner alone had to cross
    crabbing at -29 degrees and centre itself after the line at that heading (39 steps,
    24 before both front feet crossed), and the search's path turned to 0 degrees for
    three recorded steps and back to -22 degrees for the goal (30 steps, 28 before
    crossing; 37.68 s in physics, and 42.85 s with session 34's plan, past the run's 40
    s). Facing +x it is the planner alone, 21 steps, 20 before crossing: 26.15 s.
    """
    feet0 = np.asarray(feet0, dtype=float)
    yaw = -heading_of(feet0)
    centre = feet0[:, :2].mean(axis=0)
    turn = np.array([[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]])
    goal_feet = feet0.copy()
    goal_feet[:, :2] = (feet0[:, :2] - centre) @ turn.T + centre
    shift = goal + 0.06 - min(goal_feet[0, 0], goal_feet[1, 0])
    goal_feet[:, 0] += shift
    goal_feet[:, 1] -= centre[1]  # centred across the board
    return goal_feet


def past_goal(feet, goal: float) -> bool:
    """Whether both front feet of ``feet`` (4, 3) end ``GOAL_MARGIN`` past the goal line."""
    return bool(front_progress(feet, 0.0) >= goal + GOAL_MARGIN)


class GoalLineFiller:
    """A gap filler whose gaps to the goal stance end with both front feet past the line.

    A gap to ``goal_feet`` is planned with the line as part of the planner's goal test
    (the wrapped filler's ``front_line``: both front feet at x >= ``goal + GOAL_MARGIN``),
    so the planner picks a final stance that crosses; a gap that still ends short is
    returned as it is (the search's goal test refuses it). No feet are placed onto the goal
    stance (``place=False``): it is a made-up target whose centroid and line the planner's
    goal test checks, not a recorded step's start to join. Other gaps are the wrapped
    filler's. (Before, the planner aimed at the goal stance's centroid and a gap that ended
    with a front foot short of the line was planned on from its end; that failed where
    the crawl had no step from that stance: one of 20 perturbed starts of the planner-only
    ablation with the rocks from 0.15 m. On 50 modified-terrain and 40 generated-terrain
    starts, search and planner alone, the plans with the line alone equal those with the
    old planning-on kept behind it as a fallback.)
    """

    def __init__(self, filler, goal_feet: np.ndarray, goal: float) -> None:
        self.filler = filler
        self.goal_feet = np.array(goal_feet, dtype=float)
        self.goal = float(goal)

    def __call__(self, start: np.ndarray, target: np.ndarray, time_limit: float) -> GapFill:
        """Fills the gap from ``start`` to ``target`` (4, 3) as described above."""
        if not np.array_equal(target, self.goal_feet):
            return self.filler(start, target, time_limit)
        return self.filler(
            start, target, time_limit, front_line=(1.0, 0.0, self.goal + GOAL_MARGIN), place=False
        )


def plan_transfer(scenario: LittleDogTransferScenario) -> TransferPlan:
    """Transfer, search and final library of a scenario (no physics).

    Raises:
        ScenarioError: bad scenario, a start whose feet leave the board or where the robot
            cannot stand, or the search did not reach the goal (its CPU-time limit reached,
            or no path): the status and the best partial path are named and the partial
            path is not executed.
    """
    scenario.validate()
    board = target_board(scenario)
    params = CrawlParams()
    offset, feet = perturbed_start(scenario, board, params)
    why = off_board(board, feet)
    if why is not None:
        x, y = (float(v) for v in scenario.start_offset)
        raise ScenarioError(
            f"start_offset [{x:.4f}, {y:.4f}] m (start_yaw_offset "
            f"{scenario.start_yaw_offset:.3f} rad) puts the start off the board: {why}"
        )
    offset = flat_offset(board, offset, scenario.start_yaw_offset, params)
    pose0, feet0, q0 = crossing_start(
        board, 0.0, HALF_EXTENT, params.standing_height, offset, scenario.start_yaw_offset
    )
    goal = HALF_EXTENT - 0.02
    transfer = library_transfer(scenario)
    goal_feet = goal_stance(feet0, goal)
    if scenario.mode == "greedy":
        if transfer.library is None:
            raise ScenarioError(f"greedy mode: no step transferred ({transfer.message})")
        return TransferPlan(board, pose0, feet0, q0, goal, transfer, None, transfer.library)
    x0, x1, y0, y1 = board.bounds()  # a tiled target is longer than it is wide
    hmap = height_map_from_board(board, (x0, x1), (y0, y1), MAP_RESOLUTION)
    # Recorded (physics) steps end up to 2.7 cm (summed over the feet) from the next start.
    # step_reach: the crawl planner moves a foot up to 12.9 cm per step (median 10 cm over
    # 8 planner-only plans); a gap estimate at 8 cm overstated gaps by ~25 %, so the search
    # never planned gaps through recorded steps once the planner alone was known.
    config = SearchConfig(
        join_tolerance=0.04,
        goal_tolerance=0.03,
        step_reach=0.13,
        time_limit=scenario.planner_time_limit,
    )
    # A gap enters a recorded step within the same join tolerance (the executor takes it up).
    filler = GoalLineFiller(
        CrawlGapFiller(
            hmap,
            planner_params(),
            board=board,
            place_feet=True,
            place_within=config.join_tolerance,
        ),
        goal_feet,
        goal,
    )
    source = None if scenario.mode == "planner" else transfer.library
    try:
        result = search_library(
            source, feet0, goal_feet, filler, config, board, lambda f: past_goal(f, goal)
        )
        if result.status != "reached":
            why = ""
            rule = planner_params()
            if not start_level(board, feet0, rule):
                z = board.height(feet0[:, 0], feet0[:, 1])
                why = (
                    f"; the start's feet stand on ground {100 * np.ptp(z):.1f} cm apart in "
                    f"height, more than the planner's max_step_height "
                    f"{100 * rule.max_step_height:.1f} cm: the higher feet can step "
                    "only onto ground near their own height (on rocks taller than that step "
                    "they stay on their rocks)"
                )
            raise ScenarioError(
                f"the search stopped with status {result.status} ({result.message}); "
                f"its best partial path is not executed{why}"
            )
        final = final_library(result, source, board, "new_terrain")
    except RepertoireError as e:
        raise ScenarioError(f"littledog_transfer: {e}") from e
    return TransferPlan(board, pose0, feet0, q0, goal, transfer, result, final, result.cpu_s)


@register_diagram(
    "littledog_transfer",
    scenario_type=LittleDogTransferScenario,
    description="LittleDog crossing a modified terrain with its step library transferred there "
    "(terrain features, PCA matching, search with planner-filled gaps, integral foot controller)",
    duration=40.0,
    check=lambda diagram, context: check_littledog_library(diagram, context),
    criteria={"crossed": Bound(lo=1.0), "min_clearance_m": Bound(lo=0.04), "fell": Bound(hi=0.0)},
)
def build_littledog_transfer(
    scenario: LittleDogTransferScenario, *, meshcat=None, plan: TransferPlan | None = None
) -> Diagram:
    """Builds the closed loop on the new terrain with the final library.

    Args:
        scenario: the scenario (validated here).
        meshcat: optional Meshcat for a visualizer.
        plan: an already computed :func:`plan_transfer` of ``scenario``.

    Returns:
        The Diagram ``littledog_transfer`` with the subsystems and loggers of
        ``littledog_library`` (``body_log``, ``feet_log``, ``integrator_log``,
        ``ideal_log``, ``step_log``, ``contact_log``).
    """
    if not isinstance(scenario, LittleDogTransferScenario):
        raise ScenarioError(
            f"littledog_transfer takes a LittleDogTransferScenario, got {type(scenario).__name__}"
        )
    plan = plan_transfer(scenario) if plan is None else plan
    return build_library_crossing(
        "littledog_transfer", scenario, plan.board, plan.pose0, plan.q0, plan.library, 0.0,
        plan.goal, meshcat,
    )  # fmt: skip


__all__ = [
    "MODES",
    "LittleDogTransferScenario",
    "TransferPlan",
    "build_littledog_transfer",
    "library_transfer",
    "off_board",
    "perturbed_start",
    "plan_transfer",
    "start_level",
    "source_board",
    "target_board",
]
