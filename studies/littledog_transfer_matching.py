"""LittleDog library transfer without physics: match-back, modified terrain, search (Figs. 9-12).

Stolle et al., section VI. The step library recorded on the source terrains is
transferred onto a new terrain per episode; the case follows from the seed:

- seed 0, 1 (``match_back``): source terrain ``terrain_a`` / ``terrain_b`` with a
  flat board of the same width tiled after it (Fig. 9). A step whose own heading
  lies within the candidate yaws (the crossings at 0 degrees) should match back
  within 2 cm and 5 degrees of its recorded place; placed steps farther away are
  spurious, and those whose profile lies wholly on the flat board are counted.
- seed 2 (``modified``): ``terrain_a`` with a rock field
  (:func:`~repertoire.models.terrain.rock_field`: rocks of seed ``rock_seed`` over
  ``ROCK_FIELD_COVERAGE`` = 0.8 of the area) in
  place of its part beyond ``change_from`` (Fig. 10): the steps whose profile lies on
  the unchanged part matched back at their places, and how many placements touch the
  changed part (a profile sample at or beyond ``change_from``).
- seeds >= 3 (``generated``): two rough boards with seeds the demonstrations never
  used (``1000 + 2 k``, ``1001 + 2 k``).

On the modified and generated terrains the section-V search runs from the nominal
start to the goal, once with one match per step and once with multiple matches
(section VII): recorded and planned steps on the path (Figs. 11-12).

Why the generated rows read "0 + N" (the table gives each search's cost and the planner
alone's): no transferred step there is worth joining, which is the method's outcome on
these boards, not a failed search. A recorded step costs 1 and moves one foot (1.1-2.3
cm of body progress; a planned step, cost 3, 2.3 cm on average), so it saves at most 2,
while joining it takes 2-4 moves placing the feet on its start stance (the gap planner
aims at a centroid and a heading) plus any detour. Measured on seeds 3 and 4 (planner
alone 54): the joinable placed steps cost 61-139 through them. Steps yawed 28-45
degrees are joinable too since the crawl gap filler turns the body to the step's start
heading (gaps from the start that end on the step's start stance: seed 3 10 of its 14
placed steps, seed 4 9 of 14; 7 and 4 when the filler kept its heading and ended
0.26-0.43 m, summed over the feet, from a yawed step's start), but a path from the start
through one of them costs 88 (seed 3, 34 degrees) or more; seed 4 places all of them
0.15-0.18 m off the crossing line. On the modified terrain the 5 steps match back on the
line as one chain: 5 + 17 (56) against the planner alone's 57.

The summary tabulates every case and draws the modified terrain's matches and both
searches over its height map. Run it with ``python -m repertoire.studies.littledog_transfer_matching
--help``.
"""

import dataclasses
import math
from pathlib import Path

import numpy as np
from repertoire.studies.engine import register_study

from repertoire.errors import RepertoireError

FLAT_SEED = 0


def profile_xy(feet) -> np.ndarray:
    """World (x, y) of the 464 profile samples of a stance (its terrain feature's footprint)."""
    from repertoire.planning.terrain_features import profile_offsets, stance_frame

    x, y, yaw = stance_frame(feet)
    uv = profile_offsets()
    c, s = math.cos(yaw), math.sin(yaw)
    return np.column_stack([x + c * uv[:, 0] - s * uv[:, 1], y + s * uv[:, 0] + c * uv[:, 1]])


def profile_x(feet) -> np.ndarray:
    """World x of the 464 profile samples of a stance."""
    return profile_xy(feet)[:, 0]


def at_own_place(new, old, shift_x: float = 0.0) -> bool:
    """A placed step lies within 2 cm (every start foot) and 5 degrees of its recorded place.

    Args:
        new: the placed step (on the target terrain).
        old: the recorded step it was transferred from.
        shift_x: how far the source terrain moved along x in the target (m).
    """
    from repertoire.planning.terrain_features import wrap_angle

    dist = np.linalg.norm(new.start_feet[:, :2] - old.start_feet[:, :2] - [shift_x, 0.0], axis=1)
    yaw = abs(math.degrees(wrap_angle(new.start_pose[5] - old.start_pose[5])))
    return bool(dist.max() < 0.02 and yaw < 5.0)


def could_match_back(library, name: str, region=None) -> list[int]:
    """Steps of terrain ``name`` that can match at their own place on a copy of it.

    Their heading lies within the candidate yaws ([-45, 45] degrees) and, when
    ``region`` ``(x0, x1, half_y)`` is given, their whole profile lies in
    ``[x0, x1) x [-half_y, half_y]`` (on the board, before a changed part).
    """
    from repertoire.planning.terrain_features import wrap_angle

    half_yaw = math.pi / 4 + 1e-9

    def inside(s) -> bool:
        if region is None:
            return True
        p = profile_xy(s.start_feet)
        x0, x1, half_y = region
        return bool(p[:, 0].min() >= x0 and p[:, 0].max() < x1 and np.abs(p[:, 1]).max() <= half_y)

    return [
        i
        for i, s in enumerate(library)
        if s.terrain == name and abs(wrap_angle(s.direction)) <= half_yaw and inside(s)
    ]


@dataclasses.dataclass
class LittleDogTransferConfig:
    """What every episode shares.

    Attributes:
        threshold: PCA match threshold.
        change_from: x (m) where the modified terrain starts to differ (0.05 m here,
            a larger changed part than the ``littledog_transfer`` diagram's default
            0.15 m: more of the library's profiles meet the new rocks).
        rock_seed: seed of the modified part's rocks.
        library: step library file ("" = the cached default library).
    """

    threshold: float = 0.05
    change_from: float = 0.05
    rock_seed: int = 5
    library: str = ""

    def validate(self) -> None:
        """Raises RepertoireError naming a bad field.

        The transfer scenario's own checks of the fields it passes on (else a bad rock seed
        failed only the modified-terrain episode, recorded as an error row).
        """
        from repertoire.diagrams.littledog_transfer import LittleDogTransferScenario

        LittleDogTransferScenario(
            threshold=self.threshold, change_from=self.change_from, rock_seed=self.rock_seed
        ).validate()


@dataclasses.dataclass
class LittleDogTransferRecord:
    """One terrain.

    Attributes:
        case: ``match_back``, ``modified`` or ``generated``.
        terrain: what the target terrain is made of.
        placed: steps placed (one match per step).
        discarded: library steps matched nowhere.
        eligible: steps heading within the candidate yaws on their own terrain (could
            match back); modified: of the modified source terrain, those whose recorded
            profile lies wholly on the board before ``change_from`` (the unchanged
            part); else 0.
        back_within: of those, placed within 2 cm and 5 degrees of their recorded place.
        spurious: match-back: placed more than 2 cm / 5 degrees from their own place
            (steps of the other source terrain included); modified: placed with a profile
            sample on the changed part.
        on_flat: match-back only: placed with the whole profile on the flat board.
        placed_multiple: placements with multiple matches per step.
        status, recorded, planned: the search with one match per step (empty / 0 for
            match-back).
        status_multiple, recorded_multiple, planned_multiple: the same with multiple
            matches.
        wall_transfer_s, wall_transfer_multiple_s: the transfers' wall times (s);
            wall_search_cpu_s: the search's CPU time with its planner (s). Named ``wall*_s``
            so that the study engine leaves them out when it compares runs.
        chained_multiple: of the multiple matches, placements in recorded chains (joined
            to a neighbour of their demonstration, ``LibraryTransfer.chained``).
        unsupported, unsupported_multiple: matches within the threshold dropped because
            the new terrain does not support the placed step (``LibraryTransfer.unsupported``:
            a foot off its recorded height or on an edge, the swing foot in the ground),
            one match per step / multiple matches.
        cost, alone_cost: the search with one match per step: its path's cost (recorded
            steps 1, planned 3) and the planner alone's, which a path through recorded
            steps must beat (NaN where not searched).
    """

    case: str
    terrain: str
    placed: int
    discarded: int
    eligible: int
    back_within: int
    spurious: int
    on_flat: int
    placed_multiple: int
    status: str
    recorded: int
    planned: int
    status_multiple: str
    recorded_multiple: int
    planned_multiple: int
    wall_transfer_s: float
    wall_transfer_multiple_s: float
    wall_search_cpu_s: float
    chained_multiple: int = 0
    unsupported: int = 0
    unsupported_multiple: int = 0
    cost: float = math.nan
    alone_cost: float = math.nan


def _match_back(config, seed: int, library, pca):
    import time

    from repertoire.diagrams.littledog_transfer import source_board
    from repertoire.models.terrain import TerrainParams, generate_board, tile_boards
    from repertoire.planning.terrain_features import TransferConfig
    from repertoire.planning.transfer_library import transfer_library

    name = ("terrain_a", "terrain_b")[seed]
    source = source_board(name)
    flat = generate_board(
        TerrainParams(kind="flat", size_x=0.4, size_y=source.params.size_y), FLAT_SEED
    )
    target = tile_boards([source, flat])
    shift = -0.5 * flat.params.size_x  # the source's centre moves by this along x
    flat_from = target.params.size_x * 0.5 - flat.params.size_x
    t = time.perf_counter()
    cfg = TransferConfig(threshold=config.threshold)
    r = transfer_library(
        library,
        {n: source_board(n) for n in ("terrain_a", "terrain_b")},
        target,
        pca,
        cfg,
        "match_back",
    )
    elapsed = time.perf_counter() - t
    eligible = could_match_back(library, name)
    within = spurious = on_flat = 0
    for new, j in zip(r.library or [], r.source_index):
        old = library[int(j)]
        if profile_x(new.start_feet).min() > flat_from:
            on_flat += 1
        ok = old.terrain == name and at_own_place(new, old, shift)
        within += int(ok and int(j) in eligible)
        spurious += int(not ok)
    placed = 0 if r.library is None else len(r.library)
    return LittleDogTransferRecord(
        "match_back",
        f"{name} + flat board",
        placed,
        len(r.discarded),
        len(eligible),
        within,
        spurious,
        on_flat,
        0,
        "",
        0,
        0,
        "",
        0,
        0,
        elapsed,
        0.0,
        0.0,
        unsupported=len(r.unsupported),
    )


def run_episode(config: LittleDogTransferConfig, seed: int) -> LittleDogTransferRecord:
    """One terrain (the case follows from the seed, see the module doc)."""
    from repertoire.diagrams.littledog_library import load_library
    from repertoire.diagrams.littledog_transfer import (
        LittleDogTransferScenario,
        library_terrains_pca,
        plan_transfer,
        source_board,
    )

    config.validate()
    if seed < 0:
        raise RepertoireError(f"seed must be >= 0, got {seed}")
    library = load_library(config.library)
    if seed < 2:
        return _match_back(config, seed, library, library_terrains_pca())
    if seed == 2:
        kw = dict(target="modified", change_from=config.change_from, rock_seed=config.rock_seed)
        terrain = f"terrain_a, rock field from x = {config.change_from} m"
    else:
        seeds = [1000 + 2 * (seed - 3), 1001 + 2 * (seed - 3)]
        kw = dict(target="generated", board_seeds=seeds)
        terrain = f"rough boards {seeds}"
    base = LittleDogTransferScenario(threshold=config.threshold, library=config.library, **kw)
    try:
        single = plan_transfer(base)
        multi = plan_transfer(dataclasses.replace(base, multiple=True))
    except RepertoireError as e:  # no flat start, no path: counted, not fatal
        return LittleDogTransferRecord(
            "modified" if seed == 2 else "generated",
            terrain,
            0,
            0,
            0,
            0,
            0,
            0,
            0,
            f"error: {e}",
            0,
            0,
            "error",
            0,
            0,
            0.0,
            0.0,
            0.0,
        )
    spurious = within = 0
    eligible: list[int] = []
    if seed == 2:
        source = source_board(base.source).params
        region = (-0.5 * source.size_x, config.change_from, 0.5 * source.size_y)
        eligible = could_match_back(library, base.source, region)
        placed_at = zip(single.transfer.library or [], single.transfer.source_index)
        for new, j in placed_at:
            spurious += int(profile_x(new.start_feet).max() >= config.change_from)
            within += int(int(j) in eligible and at_own_place(new, library[int(j)]))
    placed = lambda p: 0 if p.transfer.library is None else len(p.transfer.library)  # noqa: E731
    return LittleDogTransferRecord(
        "modified" if seed == 2 else "generated",
        terrain,
        placed(single),
        len(single.transfer.discarded),
        len(eligible),
        within,
        int(spurious),
        0,
        placed(multi),
        single.search.status,
        single.search.recorded_count,
        single.search.planned_count,
        multi.search.status,
        multi.search.recorded_count,
        multi.search.planned_count,
        sum(single.transfer.timings.values()),
        sum(multi.transfer.timings.values()),
        single.search_s,
        chained_multiple=multi.transfer.chained,
        unsupported=len(single.transfer.unsupported),
        unsupported_multiple=len(multi.transfer.unsupported),
        cost=single.search.cost,
        alone_cost=single.search.planner_alone_cost,
    )


def summarize(
    records: list[LittleDogTransferRecord], config: LittleDogTransferConfig, out_dir: Path
) -> dict[str, Path]:
    """Table of every case; the modified terrain's transferred steps and searches (figures).

    Returns:
        ``{"table": md, "modified": png, "modified_multiple": png, "turn": png}`` (figures
        only when a modified-terrain episode ran; "turn": the gap filler's crawl turning
        the body 30 degrees there).
    """
    from repertoire.diagrams.littledog_transfer import LittleDogTransferScenario, plan_transfer
    from repertoire.planning.transfer_plot import library_path_figure

    out_dir = Path(out_dir)
    lines = [
        "| case | terrain | placed | discarded | unsupported (one / multiple) "
        "| back within 2 cm / 5 deg | spurious | on flat "
        "| search: recorded + planned (status) | multiple matches: placed (in chains); "
        "recorded + planned (status) | transfer s (wall) | search s (CPU) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in records:
        back = f"{r.back_within}/{r.eligible}" if r.case != "generated" else "-"
        flat = str(r.on_flat) if r.case == "match_back" else "-"
        one = f"{r.recorded} + {r.planned} ({r.status})" if r.status else "-"
        if r.status == "reached":
            one += f"; cost {r.cost:g}, planner alone {r.alone_cost:g}"
        many = (
            f"{r.placed_multiple} ({r.chained_multiple}); {r.recorded_multiple} + "
            f"{r.planned_multiple} "
            f"({r.status_multiple})"
            if r.status_multiple
            else "-"
        )
        lines.append(
            f"| {r.case} | {r.terrain} | {r.placed} | {r.discarded} "
            f"| {r.unsupported} / {r.unsupported_multiple} | {back} | {r.spurious} "
            f"| {flat} | {one} | {many} | {r.wall_transfer_s:.1f} | {r.wall_search_cpu_s:.2f} |"
        )
    searched = [r for r in records if r.status]
    if searched:
        lines.append("")
        lines.append(
            f"Planned steps over {len(searched)} searched terrains: one match per step "
            f"{sum(r.planned for r in searched)}, multiple matches "
            f"{sum(r.planned_multiple for r in searched)}; recorded steps "
            f"{sum(r.recorded for r in searched)} vs {sum(r.recorded_multiple for r in searched)}."
        )
        lines.append(
            "A recorded step costs 1 and a planned one 3; the search keeps the planner alone "
            "unless a path through recorded steps is cheaper, so a row reading 0 + N means "
            "no transferred step was worth joining (see the module's documentation)."
        )
    table = out_dir / "littledog_transfer_matching.md"
    table.write_text("\n".join(lines) + "\n")
    files = {"table": table}
    if any(r.case == "modified" for r in records):
        base = LittleDogTransferScenario(
            threshold=config.threshold,
            library=config.library,
            change_from=config.change_from,
            rock_seed=config.rock_seed,
        )
        for key, multiple in (("modified", False), ("modified_multiple", True)):
            plan = plan_transfer(dataclasses.replace(base, multiple=multiple))
            what = "multiple matches per step" if multiple else "one match per step"
            files[key] = library_path_figure(
                plan.board,
                plan.transfer.library,
                plan.library,
                out_dir / f"littledog_transfer_{key}.png",
                changed_from=config.change_from,
                goal=plan.goal,
                title=f"Modified terrain, {what}: {plan.search.message}",
                links=plan.transfer.links,
            )
        files["turn"] = _turn_figure(plan, out_dir / "littledog_transfer_turn.png")
    return files


def _turn_figure(plan, path: Path, degrees: float = 30.0) -> Path:
    """The gap filler's crawl turning the body on the modified terrain (a figure).

    From the terrain's start stance to a goal 0.2 m ahead at a heading of ``degrees``, as
    the gap filler does to join a step matched with a yaw.
    """
    import math

    from repertoire.diagrams.littledog_transfer import MAP_RESOLUTION
    from repertoire.models.littledog import FOOT_RADIUS
    from repertoire.planning.footstep.height_map import height_map_from_board
    from repertoire.planning.footstep.plot import crawl_plan_figure
    from repertoire.planning.footstep.quadruped import plan_crawl
    from repertoire.planning.littledog_crawl import heading_of

    x0, x1, y0, y1 = plan.board.bounds()
    hmap = height_map_from_board(plan.board, (x0, x1), (y0, y1), MAP_RESOLUTION)
    feet = np.asarray(plan.feet0, dtype=float)
    goal = feet[:, :2].mean(axis=0) + [0.2, 0.0]
    crawl = plan_crawl(
        hmap,
        feet - [0.0, 0.0, FOOT_RADIUS],  # ground contact points
        goal,
        time_limit=30.0,
        goal_heading=math.radians(degrees),
        ground=plan.board,
    )
    end = crawl.steps[-1].stance if crawl.steps else crawl.start_stance
    title = (
        f"Crawl gap filler turning the body: goal heading {degrees:g} deg (within 5), "
        f"{crawl.status.value}, {len(crawl.steps)} steps, heading "
        f"{math.degrees(heading_of(feet)):.1f} -> {math.degrees(heading_of(end)):.1f} deg"
    )
    return crawl_plan_figure(hmap, crawl, path, goal=(*goal, 0.03), title=title)


def demo_config() -> LittleDogTransferConfig:
    """The defaults (about 10-30 s of wall time per episode)."""
    return LittleDogTransferConfig()


register_study(
    "littledog_transfer_matching",
    config_type=LittleDogTransferConfig,
    record_type=LittleDogTransferRecord,
    run_episode=run_episode,
    description="LittleDog library transfer without physics: match-back with spurious matches on "
    "flat ground, modified terrain, search with planner-filled gaps, multiple matches",
    summarize=summarize,
    demo_config=demo_config,
    demo_episodes=3,
    smoke_config=demo_config,
).run_if_main(__name__)
