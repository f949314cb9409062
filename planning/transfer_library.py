"""Whole-StepLibrary transfer and the final library of a search (Stolle et al., section V).

:func:`transfer_library` moves every step of a :class:`StepLibrary` onto a new
terrain: steps are grouped by their source terrain (looked up by name; a missing
source is an error naming it), each group is matched with
:func:`~repertoire.planning.terrain_features.transfer_steps`, and every match
becomes a :class:`LibraryStep` re-expressed in the matched frame: start feet,
start pose and the recorded body poses along the step move by the planar rigid
transform between the step's own frame and the matched frame (plus the
difference of the profiles' mean heights); joint angles, times, stance labels,
the moving foot and the kind (recorded / planned) are unchanged; the terrain
becomes the new terrain's name and the direction gains the frames' yaw
difference.

:func:`search_library` runs the section-V search
(:func:`~repertoire.planning.transfer_search.search_transfer`) over a transferred
library (a step's end stance: its three stance feet where they started, the
moving foot where the action's last joint angles put it), and
:func:`final_library` turns the found path into the final StepLibrary: the path's
transferred steps in order, each run of planner-filled steps executed by the
scripted crawl (:func:`~repertoire.planning.littledog_crawl.plan_crawl`) and cut
into ``planned`` steps (:func:`~repertoire.planning.littledog_crawl.plan_to_steps`).
The result is saved and loaded in the StepLibrary format.
"""

import dataclasses
import math
import re
from collections.abc import Mapping

import numpy as np
from repertoire.models.littledog import FOOT_RADIUS, LEGS, leg_fk
from repertoire.models.littledog.pose import body_to_world
from repertoire.models.terrain import TerrainBoard
from repertoire.planning.littledog_crawl import (
    CRAWL_ORDER,
    CrawlError,
    CrawlParams,
    CrawlStep,
    plan_crawl,
    plan_to_steps,
)
from repertoire.planning.step_library import LibraryStep, StepLibrary
from repertoire.planning.terrain_features import (
    FeaturePCA,
    TransferConfig,
    TransferError,
    TransferResult,
    candidate_frames,
    fit_pca,
    terrain_features,
    transfer_stance,
    transfer_steps,
    wrap_angle,
)
from repertoire.planning.transfer_search import (
    GapFiller,
    PlannedStep,
    SearchConfig,
    SearchResult,
    foot_distance,
    search_transfer,
)


@dataclasses.dataclass
class LibraryTransfer:
    """Outcome of :func:`transfer_library`.

    Attributes:
        library: the transferred steps as a StepLibrary on the new terrain, or None when
            no step matched (every step discarded).
        source_index: for each transferred step, the index of its step in the source
            library (a step may appear more than once with multiple matches).
        costs: each transferred step's match cost (PCA distance).
        discarded: source-library indices of steps that matched nowhere.
        off_source: source-library indices of steps whose profile leaves their own
            terrain (reported, not matched).
        per_terrain: the matching result of each source terrain.
        timings: summed wall seconds of ``candidates``, ``features``, ``matching``,
            ``refine``.
        candidate_count: candidate frames on the new terrain (on the board).
        off_terrain_count: candidate frames whose profile leaves the new terrain.
    """

    library: StepLibrary | None
    source_index: np.ndarray
    costs: np.ndarray
    discarded: list[int]
    off_source: list[int]
    per_terrain: dict[str, TransferResult]
    timings: dict[str, float]
    candidate_count: int
    off_terrain_count: int

    @property
    def message(self) -> str:
        """What happened, in words."""
        placed = 0 if self.library is None else len(self.library)
        sources = len(set(self.source_index.tolist()))
        text = f"{placed} steps placed from {sources} source steps; {len(self.discarded)} discarded"
        if self.off_source:
            text += f"; {len(self.off_source)} steps' profiles leave their own terrain"
        if self.library is None:
            text += "; no step matched: the search plans with the planner alone"
        return text


def fit_board_pca(
    boards, spacing: float = 0.03, yaw_count: int = 5, variance: float = 0.95
) -> FeaturePCA:
    """PCA of the profiles of candidate frames over ``boards`` (the paper fits board features).

    Raises:
        TransferError: no board, or too few on-board profiles.
    """
    boards = list(boards)
    if not boards:
        raise TransferError("fit_board_pca needs at least one TerrainBoard")
    values = []
    for b in boards:
        f = terrain_features(b, candidate_frames(b, spacing, yaw_count))
        values.append(f.values[f.on_terrain])
    return fit_pca(np.concatenate(values), variance)


def _source_boards(library: StepLibrary, sources: Mapping[str, TerrainBoard]) -> list[str]:
    if not isinstance(library, StepLibrary):
        raise TransferError(f"transfer_library needs a StepLibrary, got {type(library).__name__}")
    names = sorted({s.terrain for s in library})
    missing = [n for n in names if n not in sources or sources[n] is None]
    if missing:
        raise TransferError(
            f"the library's source terrain(s) {missing} are missing: steps are matched by "
            f"their profiles on the terrain they were recorded on (given: {sorted(sources)})"
        )
    for n in names:
        if not isinstance(sources[n], TerrainBoard):
            raise TransferError(
                f"source terrain {n!r} must be a TerrainBoard, got {type(sources[n]).__name__}"
            )
    return names


def transfer_library(
    library: StepLibrary,
    sources: Mapping[str, TerrainBoard],
    target: TerrainBoard,
    pca: FeaturePCA,
    config: TransferConfig | None = None,
    target_name: str = "transferred",
) -> LibraryTransfer:
    """Transfers every step of ``library`` onto ``target`` (a StepLibrary on the new terrain).

    Args:
        library: the source library (steps name their source terrain).
        sources: source terrains by name (every terrain the library names).
        target: the new terrain.
        pca: PCA basis of board profiles (:func:`fit_board_pca`).
        config: transfer settings (threshold, multiple matches, candidate grid).
        target_name: terrain name stored with the transferred steps.

    Raises:
        TransferError: a missing source terrain, bad settings or shapes.
    """
    names = _source_boards(library, sources)
    if not isinstance(target, TerrainBoard):
        raise TransferError(f"target must be a TerrainBoard, got {type(target).__name__}")
    if not (isinstance(target_name, str) and target_name):
        raise TransferError(f"target_name must be a non-empty name, got {target_name!r}")
    steps = library.steps
    new_steps: list[LibraryStep] = []
    index: list[int] = []
    costs: list[float] = []
    discarded: list[int] = []
    off_source: list[int] = []
    per_terrain: dict[str, TransferResult] = {}
    timings = {"candidates": 0.0, "features": 0.0, "matching": 0.0, "refine": 0.0}
    cands = off = 0
    for name in names:
        rows = [i for i, s in enumerate(steps) if s.terrain == name]
        feet = np.stack([steps[i].start_feet for i in rows])
        poses = np.stack([steps[i].start_pose for i in rows])
        r = transfer_steps(sources[name], feet, poses, target, pca, config)
        per_terrain[name] = r
        for k in timings:
            timings[k] += r.timings[k]
        cands, off = r.matches.candidate_count, r.matches.off_terrain_count
        discarded += [rows[j] for j in r.matches.discarded]
        off_source += [rows[j] for j in r.off_source]
        for t in r.steps:
            src = steps[rows[t.step]]
            frame, height = r.source_frames[t.step], r.source_heights[t.step]
            _, body = transfer_stance(
                src.start_feet, src.body_pose, frame, height, t.match.frame, t.match.height
            )
            d = float(t.match.frame[2] - frame[2])
            new_steps.append(
                dataclasses.replace(
                    src,
                    start_feet=t.feet,
                    start_pose=t.body_pose,
                    body_pose=body,
                    terrain=target_name,
                    direction=float(wrap_angle(src.direction + d)),
                )
            )
            index.append(rows[t.step])
            costs.append(t.match.cost)
    return LibraryTransfer(
        library=StepLibrary(new_steps) if new_steps else None,
        source_index=np.array(index, dtype=int),
        costs=np.array(costs),
        discarded=sorted(discarded),
        off_source=sorted(off_source),
        per_terrain=per_terrain,
        timings=timings,
        candidate_count=cands,
        off_terrain_count=off,
    )


def step_end_feet(step: LibraryStep) -> np.ndarray:
    """A step's end stance (4, 3): stance feet where they started, the moving foot by FK.

    The moving foot is where the action's last joint angles put it under the last
    recorded body pose (forward kinematics of its leg).
    """
    end = np.array(step.start_feet, dtype=float)
    f = int(step.foot)
    p_BF = leg_fk(LEGS[f], step.q[-1, 3 * f : 3 * f + 3])
    end[f] = body_to_world(step.body_pose[-1], p_BF)
    return end


def library_stances(library: StepLibrary | None) -> tuple[np.ndarray, np.ndarray]:
    """Start and end stances of every step, (M, 4, 3) each (M = 0 for None)."""
    if library is None:
        return np.zeros((0, 4, 3)), np.zeros((0, 4, 3))
    starts = np.stack([s.start_feet for s in library])
    ends = np.stack([step_end_feet(s) for s in library])
    return starts, ends


def search_library(
    library: StepLibrary | None,
    start,
    goal,
    gap_filler: GapFiller,
    config: SearchConfig | None = None,
    terrain: TerrainBoard | None = None,
) -> SearchResult:
    """The section-V search over a transferred library (None: the planner alone).

    Raises:
        TransferSearchError: see :func:`~repertoire.planning.transfer_search.search_transfer`.
    """
    starts, ends = library_stances(library)
    return search_transfer(start, goal, starts, ends, gap_filler, config, terrain)


def stance_pose(feet, standing_height: float) -> np.ndarray:
    """A level body pose over a stance: centroid, standing height, heading rear -> front."""
    p = np.asarray(feet, dtype=float)
    axis = p[:2, :2].mean(axis=0) - p[2:, :2].mean(axis=0)
    c = p[:, :2].mean(axis=0)
    z = float(p[:, 2].mean()) - FOOT_RADIUS + standing_height
    return np.array([c[0], c[1], z, 0.0, 0.0, math.atan2(axis[1], axis[0])])


def planned_library_steps(
    planned: list[PlannedStep],
    board: TerrainBoard,
    terrain_name: str,
    pose0=None,
    params: CrawlParams | None = None,
) -> list[LibraryStep]:
    """Library steps (kind ``planned``) executing a run of planned steps by the scripted crawl.

    Args:
        planned: consecutive planned steps (each starts where the previous ended).
        board: the terrain (exact heights for swing clearance).
        terrain_name: stored with the steps.
        pose0: body pose at the run's start (default level over the first stance). Where
            the legs cannot reach a step from the pose carried along the run, the run is
            cut there and continues level over that step's stance (the executor blends).
        params: crawl timing and geometry.

    Raises:
        TransferError: an empty run, or a pose the legs cannot reach.
    """
    params = CrawlParams() if params is None else params
    if not planned:
        raise TransferError("planned_library_steps needs at least one planned step")
    out: list[LibraryStep] = []
    rest = list(planned)
    while rest:
        feet0 = np.asarray(rest[0].start_feet, dtype=float)
        level = stance_pose(feet0, params.standing_height)
        pose = level if pose0 is None else np.asarray(pose0, dtype=float)
        crawl = [CrawlStep(p.foot, np.asarray(p.end_feet, float)[p.foot]) for p in rest]
        try:
            plan = plan_crawl(feet0, pose, crawl, board, params, hold_time=params.dt)
            done = len(rest)
        except CrawlError as e:
            # A run joined from several gaps carries the body pose from one into the next;
            # execute up to the unreachable step, then restart level over its stance.
            m = re.search(r"step (\d+) \(moving foot", str(e))
            done = int(m.group(1)) if m else 0
            if done == 0:
                if pose0 is None:
                    raise TransferError(
                        f"planned steps cannot be executed by the crawl: {e}"
                    ) from e
                pose0 = None
                continue
            plan = plan_crawl(feet0, pose, crawl[:done], board, params, hold_time=params.dt)
        out += plan_to_steps(plan, terrain=terrain_name, direction=float(pose[5]), kind="planned")
        pose0 = out[-1].body_pose[-1]
        rest = rest[done:]
    return out


def placing_steps(current, target, tolerance: float = 0.005) -> list[PlannedStep]:
    """One-foot steps (crawl order) moving each foot farther than ``tolerance`` onto ``target``."""
    cur = np.array(current, dtype=float)
    target = np.asarray(target, dtype=float)
    out = []
    for f in CRAWL_ORDER:
        if np.linalg.norm(cur[f] - target[f]) > tolerance:
            nxt = cur.copy()
            nxt[f] = target[f]
            out.append(PlannedStep(cur, nxt, f))
            cur = nxt
    return out


def final_library(
    result: SearchResult,
    transferred: StepLibrary | None,
    board: TerrainBoard,
    terrain_name: str = "transferred",
    params: CrawlParams | None = None,
    tolerance: float = 0.005,
    join: float = 0.04,
) -> StepLibrary:
    """The final library of a search: path steps in order, planner runs as ``planned`` steps.

    A planner run ends with the feet's centroid near the next recorded step's start
    (the crawl planner aims at a centroid); :func:`placing_steps` then moves each foot
    farther than ``tolerance`` (m) onto that step's start foothold, so every run ends
    exactly where the recorded step begins and the nearest-step policy picks it next.
    Between two path steps joined by no planned step but farther apart than ``join``
    (m, summed over the feet) the same placing moves are inserted.

    Raises:
        TransferError: an empty path (nothing to execute) or a recorded step missing
            from ``transferred``.
    """
    if not result.path:
        raise TransferError(f"the search found no steps to execute ({result.message})")
    out: list[LibraryStep] = []
    run: list[PlannedStep] = []
    pose = None

    def flush() -> None:
        nonlocal run, pose
        if run:
            made = planned_library_steps(run, board, terrain_name, pose, params)
            out.extend(made)
            pose = made[-1].body_pose[-1]
            run = []

    for item in result.path:
        if item.kind == "planned":
            run.append(item.planned)
            continue
        if transferred is None or not 0 <= item.step < len(transferred):
            raise TransferError(f"path step {item.step} is not in the transferred library")
        step = transferred[item.step]
        search_run, extra = list(run), []
        if search_run:
            extra = placing_steps(search_run[-1].end_feet, step.start_feet, tolerance)
        elif out and float(foot_distance(step_end_feet(out[-1]), step.start_feet)) > join:
            # A gap the planner "filled" with no steps (centroids already close): place the
            # feet from the previous step's end so the policy can pick this step next.
            extra = placing_steps(step_end_feet(out[-1]), step.start_feet, tolerance)
        run = search_run + extra
        try:
            flush()
        except TransferError:
            # The legs cannot reach the placing moves: leave the last few cm to the
            # executor's blend (the search's own gap steps were checked executable).
            run = search_run
            flush()
        out.append(step)
        pose = step.body_pose[-1]
    flush()
    return StepLibrary(out)


__all__ = [
    "LibraryTransfer",
    "final_library",
    "fit_board_pca",
    "library_stances",
    "placing_steps",
    "planned_library_steps",
    "search_library",
    "stance_pose",
    "step_end_feet",
    "transfer_library",
]
