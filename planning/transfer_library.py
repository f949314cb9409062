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
import time
from collections.abc import Callable, Mapping

import numpy as np
from repertoire.models.littledog import FOOT_RADIUS, LEGS, leg_fk
from repertoire.models.littledog.pose import rotation_from_rpy
from repertoire.models.terrain import TerrainBoard
from repertoire.planning.footstep.quadruped import CrawlParams as PlannerParams
from repertoire.planning.footstep.quadruped import flat_on_ground
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
    Match,
    MatchResult,
    TransferConfig,
    TransferError,
    TransferredStep,
    TransferResult,
    candidate_frames,
    fit_pca,
    refine_matches,
    target_candidates,
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
        timings: wall seconds of ``candidates`` and ``features`` (once per new terrain),
            ``matching``, ``refine`` and ``chains`` (summed over the source terrains).
        candidate_count: candidate frames on the new terrain (on the board).
        off_terrain_count: candidate frames whose profile leaves the new terrain.
        chained: placements joined to a neighbour of their demonstration by
            :func:`extend_chains` (0 without chains).
        links: pairs ``(a, b)`` of placements (indices into ``library``) where ``b`` is
            the next step of ``a``'s demonstration and starts within ``chain_join`` of
            ``a``'s end: recorded edges the search can take without planned steps.
        unsupported: source-library indices of matches (within the threshold) dropped
            because the new terrain does not support the placed step
            (:func:`step_supported`, ``TransferConfig.support_tolerance``), one per
            dropped match; a step dropped everywhere is not in ``discarded``.
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
    chained: int = 0
    links: list[tuple[int, int]] = dataclasses.field(default_factory=list)
    unsupported: list[int] = dataclasses.field(default_factory=list)

    @property
    def message(self) -> str:
        """What happened, in words."""
        placed = 0 if self.library is None else len(self.library)
        sources = len(set(self.source_index.tolist()))
        text = f"{placed} steps placed from {sources} source steps; {len(self.discarded)} discarded"
        if self.unsupported:
            text += f"; {len(self.unsupported)} matches dropped: the terrain does not support them"
        if self.chained:
            text += f"; {self.chained} placements in recorded chains"
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
    unsupported: list[int] = []
    per_terrain: dict[str, TransferResult] = {}
    config = TransferConfig() if config is None else config
    _check_support_tolerance(config.support_tolerance)
    chains = config.multiple and config.chains
    successor = chain_successors(library, config.chain_join)
    feats, timings = target_candidates(target, config)
    timings.update(matching=0.0, refine=0.0, chains=0.0)
    cands = off = chained = 0
    for name in names:
        rows = [i for i, s in enumerate(steps) if s.terrain == name]
        feet = np.stack([steps[i].start_feet for i in rows])
        poses = np.stack([steps[i].start_pose for i in rows])
        r = transfer_steps(sources[name], feet, poses, target, pca, config, feats)

        def supported(t: TransferredStep, r=r, rows=rows, name=name) -> bool:
            src = steps[rows[t.step]]
            placed = _placed_step(src, r, t, target_name)
            return step_supported(sources[name], target, src, placed, config.support_tolerance)

        keep = [supported(t) for t in r.steps]
        unsupported += [rows[t.step] for t, k in zip(r.steps, keep) if not k]
        kept = [t for t, k in zip(r.steps, keep) if k]
        r = dataclasses.replace(
            r, steps=kept, matches=dataclasses.replace(r.matches, matches=[t.match for t in kept])
        )
        if chains:
            t0 = time.perf_counter()
            local = {g: a for a, g in enumerate(rows)}
            nxt = np.array([local.get(int(successor[g]), -1) for g in rows])
            ends = np.stack([step_end_feet(steps[g]) for g in rows])
            r, added = extend_chains(r, target, pca, feet, poses, ends, nxt, config, supported)
            chained += added
            timings["chains"] += time.perf_counter() - t0
        per_terrain[name] = r
        for k in ("matching", "refine"):
            timings[k] += r.timings[k]
        cands, off = r.matches.candidate_count, r.matches.off_terrain_count
        discarded += [rows[j] for j in r.matches.discarded]
        off_source += [rows[j] for j in r.off_source]
        for t in r.steps:
            new_steps.append(_placed_step(steps[rows[t.step]], r, t, target_name))
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
        chained=chained,
        links=placed_links(new_steps, np.array(index, dtype=int), successor, config.chain_join),
        unsupported=sorted(unsupported),
    )


def _placed_step(
    src: LibraryStep, r: TransferResult, t: TransferredStep, target_name: str
) -> LibraryStep:
    """Source step ``src`` re-expressed at placement ``t`` of transfer result ``r``."""
    frame, height = r.source_frames[t.step], r.source_heights[t.step]
    _, body = transfer_stance(
        src.start_feet, src.body_pose, frame, height, t.match.frame, t.match.height
    )
    d = float(t.match.frame[2] - frame[2])
    return dataclasses.replace(
        src,
        start_feet=t.feet,
        start_pose=t.body_pose,
        body_pose=body,
        terrain=target_name,
        direction=float(wrap_angle(src.direction + d)),
    )


def foot_path(step: LibraryStep) -> np.ndarray:
    """The moving foot's centre at every sample of the step (T, 3), world frame.

    Forward kinematics of its leg at the action's joint angles under the recorded body
    poses.
    """
    f = int(step.foot)
    p_BF = leg_fk(LEGS[f], step.q[:, 3 * f : 3 * f + 3])
    R = rotation_from_rpy(step.body_pose[:, 3:])
    return np.einsum("tij,tj->ti", R, p_BF) + step.body_pose[:, :3]


def step_end_feet(step: LibraryStep) -> np.ndarray:
    """A step's end stance (4, 3): stance feet where they started, the moving foot by FK.

    The moving foot is where the action's last joint angles put it under the last
    recorded body pose (:func:`foot_path`).
    """
    end = np.array(step.start_feet, dtype=float)
    end[int(step.foot)] = foot_path(step)[-1]
    return end


def _check_support_tolerance(tolerance: float) -> None:
    if not (math.isfinite(tolerance) and tolerance >= 0.0):
        raise TransferError(f"support_tolerance must be a length >= 0 m, got {tolerance}")


def step_supported(
    source: TerrainBoard,
    target: TerrainBoard,
    step: LibraryStep,
    placed: LibraryStep,
    tolerance: float,
    rule: PlannerParams | None = None,
) -> bool:
    """Whether ``target`` supports ``placed`` the way ``source`` supported ``step`` (section VII).

    ``placed`` is ``step`` re-expressed at its match on the new terrain. Its stance feet
    (the four at the start, which stay down while one foot swings) and the moving
    foot's landing (:func:`foot_path`'s last sample) must each stand within
    ``tolerance`` of their recorded height above the ground (foot centre minus
    ``FOOT_RADIUS`` minus the exact terrain height under it) on ground flat by the
    footstep planner's rule (:func:`~repertoire.planning.footstep.quadruped.flat_on_ground`)
    wherever the source ground was; the swing foot (samples labelled off the ground)
    must not sink deeper below the new ground than below its source (or above it, 0)
    by more than ``tolerance``. A match at the step's own place on its own terrain
    passes by construction; the terrain between the feet is the match's business.
    The body and the legs' links are not checked.

    Raises:
        TransferError: a negative or non-finite ``tolerance``.
    """
    _check_support_tolerance(tolerance)
    rule = PlannerParams() if rule is None else rule

    def contacts(s: LibraryStep, board: TerrainBoard):
        path = foot_path(s)
        feet = np.vstack([s.start_feet, path[-1:]])
        swing = path[~np.asarray(s.stance, dtype=bool)[:, int(s.foot)]]
        gap = feet[:, 2] - FOOT_RADIUS - board.height(feet[:, 0], feet[:, 1])
        air = swing[:, 2] - FOOT_RADIUS - board.height(swing[:, 0], swing[:, 1])
        return gap, flat_on_ground(board, feet, rule), air

    gap0, flat0, air0 = contacts(step, source)
    gap1, flat1, air1 = contacts(placed, target)
    return bool(
        np.all(np.abs(gap1 - gap0) <= tolerance)
        and np.all(flat1 | ~flat0)
        and np.all(air1 >= np.minimum(air0, 0.0) - tolerance)
    )


def library_stances(library: StepLibrary | None) -> tuple[np.ndarray, np.ndarray]:
    """Start and end stances of every step, (M, 4, 3) each (M = 0 for None)."""
    if library is None:
        return np.zeros((0, 4, 3)), np.zeros((0, 4, 3))
    starts = np.stack([s.start_feet for s in library])
    ends = np.stack([step_end_feet(s) for s in library])
    return starts, ends


def _check_chain_join(join: float) -> None:
    if not (math.isfinite(join) and join > 0.0):
        raise TransferError(f"chain_join must be a positive length, got {join}")


def chain_successors(library: StepLibrary, join: float = 0.04) -> np.ndarray:
    """The next step of each step's demonstration: its index, or -1 (M,).

    Step ``i + 1`` continues step ``i`` when both come from the same terrain and step
    ``i + 1`` starts within ``join`` (foot-location metric, m) of where step ``i`` ends
    (:func:`step_end_feet`): a recorded crossing stores its steps in order.

    Raises:
        TransferError: a non-positive ``join``.
    """
    _check_chain_join(join)
    steps = library.steps
    out = np.full(len(steps), -1, dtype=int)
    for i in range(len(steps) - 1):
        a, b = steps[i], steps[i + 1]
        if a.terrain == b.terrain and float(foot_distance(step_end_feet(a), b.start_feet)) <= join:
            out[i] = i + 1
    return out


def placed_links(
    placed: list[LibraryStep], source_index, successor, join: float
) -> list[tuple[int, int]]:
    """Recorded chain links among placed steps: pairs ``(a, b)`` of indices into ``placed``.

    ``b``'s source step follows ``a``'s in its demonstration (``successor``, indexed by
    ``source_index``) and ``b`` starts within ``join`` (foot-location metric) of ``a``'s end.
    """
    idx = np.asarray(source_index, dtype=int)
    if not placed:
        return []
    starts = np.stack([s.start_feet for s in placed])
    out = []
    for a, step in enumerate(placed):
        nxt = successor[idx[a]]
        if nxt < 0:
            continue
        b = np.flatnonzero(idx == nxt)
        if b.size:
            d = foot_distance(step_end_feet(step), starts[b])
            out += [(a, int(q)) for q in b[d <= join]]
    return out


def chain_frames(source_from, source_to, matched) -> np.ndarray:
    """Frames continuing chains: ``source_to`` moved by the transform ``source_from -> matched``.

    All (N, 3) ``[x, y, yaw]``: the planar rigid transform taking each step's own frame
    (``source_from``) to its match (``matched``) applied to the neighbouring step's own
    frame (``source_to``).
    """
    a, b, m = (np.asarray(v, dtype=float).reshape(-1, 3) for v in (source_from, source_to, matched))
    d = m[:, 2] - a[:, 2]
    c, s = np.cos(d), np.sin(d)
    rel = b[:, :2] - a[:, :2]
    x = m[:, 0] + c * rel[:, 0] - s * rel[:, 1]
    y = m[:, 1] + s * rel[:, 0] + c * rel[:, 1]
    return np.column_stack([x, y, wrap_angle(b[:, 2] + d)])


def extend_chains(
    result: TransferResult,
    target: TerrainBoard,
    pca: FeaturePCA,
    feet: np.ndarray,
    poses: np.ndarray,
    ends: np.ndarray,
    successor: np.ndarray,
    config: TransferConfig,
    supported: Callable[[TransferredStep], bool] | None = None,
) -> tuple[TransferResult, int]:
    """Chain-consistent matches: recorded chains transferred as chains (section VII).

    Independent matches are local minima of one step's cost, placed without regard to
    where the next step matched, so two neighbouring steps of a demonstration rarely
    join on the new terrain. Here every placed step's neighbours in its demonstration
    (``successor`` and predecessor) are offered at the frame that continues the chain
    (:func:`chain_frames`: the placed step's match applied to the neighbour's own
    frame). An offer is kept if the neighbour's profile there matches within
    ``config.threshold`` (offers matching only within ``coarse_factor`` times it are
    refined locally as any match) and the two placed stances join within
    ``config.chain_join``. The minimum spacing holds: an independent match of the same
    step closer than ``min_spacing`` that does not join the chain is replaced by the
    chain's (it is the same place, inconsistently refined); one that already joins it
    carries the chain on; one that is in another chain is kept and the offer dropped.
    Chains grow one at a time from the best (lowest-cost) matches, each until the
    terrain stops matching, so a match joins at most one chain. At most
    ``max_matches`` matches per step.

    Args:
        result: the independent matches of one source terrain's steps.
        target: the new terrain.
        pca: the PCA basis used for ``result``.
        feet, poses, ends: the steps' start stances (S, 4, 3), start poses (S, 6) and
            end stances (S, 4, 3) on their source terrain.
        successor: next step of each step's demonstration, or -1 (S,).
        config: transfer settings.
        supported: whether the new terrain supports a placement (offers it refuses are
            not kept); default: every placement.

    Returns:
        the result with the chain matches, and how many placements are chain members
        (joined to a neighbour of their demonstration).

    Raises:
        TransferError: a non-positive ``chain_join``.
    """
    _check_chain_join(config.chain_join)
    successor = np.asarray(successor, dtype=int)
    predecessor = np.full_like(successor, -1)
    has = np.flatnonzero(successor >= 0)
    predecessor[successor[has]] = has
    frames, heights, values = result.source_frames, result.source_heights, result.step_values
    off = set(result.off_source)
    placed: list[TransferredStep | None] = list(result.steps)
    by_step: dict[int, list[int]] = {}
    for k, t in enumerate(placed):
        by_step.setdefault(t.step, []).append(k)
    members: set[int] = set()
    yaw_step = config.yaw_step

    def end_stance(t: TransferredStep) -> np.ndarray:
        s = t.step
        return transfer_stance(
            ends[s], poses[s], frames[s], heights[s], t.match.frame, t.match.height
        )[0]

    def joined(a: TransferredStep, b: TransferredStep) -> bool:
        """Whether step ``b`` continues ``a`` (a's end on b's start)."""
        return float(foot_distance(end_stance(a), b.feet)) <= config.chain_join

    def offers(k: int) -> list[tuple[Match, bool]]:
        """The neighbours of placement ``k`` at the frames continuing its chain, if they match."""
        t = placed[k]
        links = [
            (int(j), forward)
            for j, forward in ((successor[t.step], True), (predecessor[t.step], False))
            if j >= 0 and int(j) not in off
        ]
        if not links:
            return []
        j = np.array([a[0] for a in links])
        trial = chain_frames(frames[[t.step] * len(j)], frames[j], [t.match.frame] * len(j))
        feats = terrain_features(target, trial)
        out = []
        for n in np.flatnonzero(feats.on_terrain):
            z = pca.project(feats.values[n : n + 1]) - pca.project(values[j[n] : j[n] + 1])
            m = Match(int(j[n]), trial[n], float(feats.mean_height[n]), float(np.linalg.norm(z)))
            if config.threshold < m.cost <= config.threshold * config.coarse_factor:
                if config.refine_levels:  # matching only coarsely: refined as any match
                    sub = MatchResult([m], [], 1, 0)
                    m = refine_matches(
                        target, values, sub, pca, config.spacing, yaw_step, config.refine_levels
                    ).matches[0]
            if m.cost <= config.threshold:
                out.append((m, links[n][1]))
        return out

    grown: set[int] = set()
    for seed in sorted(range(len(placed)), key=lambda k: placed[k].match.cost):
        queue = [seed]
        while queue:
            k = queue.pop()
            if k in grown or placed[k] is None:
                continue
            grown.add(k)
            t = placed[k]
            for m, forward in offers(k):
                jj = m.step
                f, p = transfer_stance(
                    feet[jj], poses[jj], frames[jj], heights[jj], m.frame, m.height
                )
                new = TransferredStep(jj, f, p, m)
                if not (joined(t, new) if forward else joined(new, t)):
                    continue
                if supported is not None and not supported(new):
                    continue
                mine = [q for q in by_step.get(jj, []) if placed[q] is not None]
                close = [
                    q
                    for q in mine
                    if np.linalg.norm(placed[q].match.frame[:2] - m.frame[:2]) < config.min_spacing
                ]
                linked = [
                    q for q in close if (joined(t, placed[q]) if forward else joined(placed[q], t))
                ]
                if linked:  # already in place: the chain goes on through it
                    members.update((k, linked[0]))
                    queue.append(linked[0])
                    continue
                if any(q in members for q in close) or len(mine) - len(close) >= config.max_matches:
                    continue  # another chain holds this place, or the step has enough matches
                for q in close:
                    placed[q] = None
                placed.append(new)
                by_step.setdefault(jj, []).append(len(placed) - 1)
                members.update((k, len(placed) - 1))
                queue.append(len(placed) - 1)
    kept = [t for t in placed if t is not None]
    chained = sum(1 for q in members if placed[q] is not None)
    matched = {t.step for t in kept}
    out = dataclasses.replace(
        result,
        steps=kept,
        matches=dataclasses.replace(
            result.matches,
            matches=[t.match for t in kept],
            discarded=[d for d in result.matches.discarded if d not in matched],
        ),
    )
    return out, chained


def search_library(
    library: StepLibrary | None,
    start,
    goal,
    gap_filler: GapFiller,
    config: SearchConfig | None = None,
    terrain: TerrainBoard | None = None,
    goal_test=None,
) -> SearchResult:
    """The section-V search over a transferred library (None: the planner alone).

    ``goal_test``: what the final stance must also satisfy (see
    :func:`~repertoire.planning.transfer_search.search_transfer`).

    Raises:
        TransferSearchError: see :func:`~repertoire.planning.transfer_search.search_transfer`.
    """
    starts, ends = library_stances(library)
    return search_transfer(start, goal, starts, ends, gap_filler, config, terrain, goal_test)


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


def placing_steps(
    current, target, tolerance: float = 0.005, within: float = 0.0, before=None
) -> list[PlannedStep]:
    """One-foot steps (crawl order) moving feet farther than ``tolerance`` onto ``target``.

    With ``within`` = 0 every such foot is placed. With ``within`` > 0 (the search's join
    tolerance: what the executor's blend and the integral foot controller take up, as
    they do between a demonstration's own steps) the fewest feet are placed, largest
    offsets first, that leave a summed offset of at most ``within`` AND at most half
    the last move's length (the last placing move, or the move from ``before`` to
    ``current``), so the nearest-step policy takes the target's step next rather than
    that move again.
    """
    cur = np.array(current, dtype=float)
    target = np.asarray(target, dtype=float)
    off = np.linalg.norm(cur - target, axis=1)
    far = [int(f) for f in np.argsort(-off, kind="stable") if off[f] > tolerance]
    last = np.inf if before is None else float(foot_distance(before, cur))
    k = len(far)
    if within > 0.0:
        for k in range(len(far) + 1):
            moved = [f for f in CRAWL_ORDER if f in far[:k]]
            rest = float(off.sum() - off[far[:k]].sum())
            length = float(off[moved[-1]]) if moved else last
            if rest <= within and rest <= 0.5 * length:
                break
    out = []
    for f in CRAWL_ORDER:
        if f in far[:k]:
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
    (the crawl planner aims at a centroid); :func:`placing_steps` then moves the fewest
    feet (farther than ``tolerance``, m) onto that step's start footholds that leave at
    most ``join`` (m, summed over the feet: the search's join tolerance, taken up by the
    executor's blend and the integral controller) and the nearest-step policy picking
    the recorded step next. Between two path steps joined by no planned step but farther
    apart than ``join`` the same placing moves are inserted.

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
            last = search_run[-1]
            extra = placing_steps(last.end_feet, step.start_feet, tolerance, join, last.start_feet)
        elif out and float(foot_distance(step_end_feet(out[-1]), step.start_feet)) > join:
            # A gap the planner "filled" with no steps (centroids already close): place the
            # feet from the previous step's end so the policy can pick this step next.
            extra = placing_steps(step_end_feet(out[-1]), step.start_feet, tolerance, join)
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
    "chain_frames",
    "placed_links",
    "chain_successors",
    "extend_chains",
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
