"""LittleDog crossing new terrains in physics with a transferred library, and its ablations.

Stolle et al., section VI (execution). Each episode draws a terrain (``seed``
modulo the number of terrains: the modified ``terrain_a`` and rough boards
generated with seeds the demonstrations never used), a start offset uniform in
``+-max_offset_m`` along x and y and a heading offset uniform in
``+-max_yaw_deg`` (redrawn until the start's feet stand on the board:
:func:`draw_start`), and runs the ``littledog_transfer`` diagram from that start
once per condition:

- ``search``: the paper's method (transfer, search with planner-filled gaps, the
  final library run with the integral foot controller);
- ``greedy``: every transferred step, no search (the nearest-step policy alone);
- ``no_integral``: as ``search`` without the integral controller (gain 0);
- ``planner``: no library, the planner's steps alone;
- ``multiple``: as ``search`` with multiple matches per step (section VII).

Success: both front feet past the goal line, the body never lower than 4 cm
above the terrain, no fall. A run ends early once it crossed or fell
(:func:`early_stop_monitor`). A condition whose search finds nothing to execute
(or greedy mode without transferred steps) counts as a failure with no steps.
The summary tabulates success per terrain and condition and plots success rates
with the steps used. Run it with
``python -m repertoire.studies.littledog_transfer_execution --help``.
"""

import dataclasses
import hashlib
import math
from pathlib import Path

import numpy as np
from repertoire.studies.engine import register_study

from repertoire.errors import RepertoireError, ScenarioError

CONDITIONS = ("search", "greedy", "no_integral", "planner", "multiple")
TERRAINS = {
    "modified": dict(target="modified"),
    "generated_31_32": dict(target="generated", board_seeds=[31, 32]),
    "generated_41_42": dict(target="generated", board_seeds=[41, 42]),
}
"""Terrain cases: the modified source terrain and two generated with unseen seeds."""


@dataclasses.dataclass
class TransferExecutionConfig:
    """What every episode shares.

    Attributes:
        terrains: terrain cases (keys of :data:`TERRAINS`), chosen by ``seed % len``.
        conditions: conditions run per episode (see the module doc).
        max_offset_m: start x and y offsets are uniform in [-max, max] (m), among the
            starts whose feet stand on the board (:func:`draw_start`).
        max_yaw_deg: start heading offsets are uniform in [-max, max] (degrees).
        duration_s: simulated time of each run (s).
        library: step library file ("" = the cached default library).
    """

    terrains: list[str] = dataclasses.field(default_factory=lambda: list(TERRAINS))
    conditions: list[str] = dataclasses.field(default_factory=lambda: list(CONDITIONS))
    max_offset_m: float = 0.03
    max_yaw_deg: float = 10.0
    duration_s: float = 45.0
    library: str = ""

    def validate(self) -> None:
        """Raises RepertoireError naming a bad field."""
        if not self.terrains or any(t not in TERRAINS for t in self.terrains):
            raise RepertoireError(f"terrains must be among {list(TERRAINS)}, got {self.terrains}")
        if not self.conditions or any(c not in CONDITIONS for c in self.conditions):
            raise RepertoireError(
                f"conditions must be among {list(CONDITIONS)}, got {self.conditions}"
            )
        if not (0.0 <= self.max_offset_m <= 0.06 and 0.0 <= self.max_yaw_deg <= 20.0):
            raise RepertoireError(
                f"max_offset_m must be in [0, 0.06] m and max_yaw_deg in [0, 20], got "
                f"{self.max_offset_m}, {self.max_yaw_deg}"
            )
        if not (math.isfinite(self.duration_s) and 0.5 <= self.duration_s <= 120.0):
            raise RepertoireError(f"duration_s must be in [0.5, 120] s, got {self.duration_s}")


@dataclasses.dataclass
class TransferExecutionRecord:
    """One perturbed start on one terrain, every condition (lists follow ``conditions``).

    Attributes:
        terrain: the terrain case.
        offset_x_m, offset_y_m, offset_yaw_deg: the start perturbation.
        conditions: the conditions run.
        success: crossed without falling, per condition.
        fell: fell, per condition.
        time_to_cross_s: NaN if it did not cross, per condition.
        steps_started: steps the executor started until the run ended, per condition.
        recorded: recorded steps in the executed library, per condition.
        planned: planned steps in the executed library, per condition.
        error: why a condition had nothing to execute ("" if it ran), per condition.
        wall_time_s: wall time of the episode (s).
        same_run_as: per condition, the earlier condition of this episode whose run it
            shares ("" if simulated itself): the same final library, start and loop
            gains give the same deterministic simulation, so it is run once.
        run_keys: per condition, :func:`run_key` of the run ("" if nothing ran): a later
            code version whose plan has the same key (and the same closed loop) would
            simulate the same run.
        start_draws: how many starts :func:`draw_start` drew until one stood on the board
            (1: the first).
    """

    terrain: str
    offset_x_m: float
    offset_y_m: float
    offset_yaw_deg: float
    conditions: list[str]
    success: list[bool]
    fell: list[bool]
    time_to_cross_s: list[float]
    steps_started: list[int]
    recorded: list[int]
    planned: list[int]
    error: list[str]
    wall_time_s: float
    same_run_as: list[str] = dataclasses.field(default_factory=list)
    run_keys: list[str] = dataclasses.field(default_factory=list)
    start_draws: int = 1


def run_key(scenario, plan) -> str:
    """Digest of what a run's simulation depends on beyond the terrain and duration.

    The loop fields of the scenario (gains, plant settings: every field but the
    transfer's ``mode``, ``multiple``, ``threshold`` and ``planner_time_limit``, which act
    only through the library), the start (pose, joints) and every field of every step of
    the final library. Two runs of one episode with equal keys simulate identically.
    """
    h = hashlib.sha256()
    skip = {"mode", "multiple", "threshold", "planner_time_limit"}
    loop = {f.name: getattr(scenario, f.name) for f in dataclasses.fields(scenario)}
    h.update(repr(sorted((k, repr(v)) for k, v in loop.items() if k not in skip)).encode())
    for a in (plan.pose0, plan.q0):
        h.update(np.ascontiguousarray(a, dtype=float).tobytes())
    for step in plan.library:
        for f in dataclasses.fields(step):
            v = getattr(step, f.name)
            h.update(
                np.ascontiguousarray(v).tobytes() if isinstance(v, np.ndarray) else repr(v).encode()
            )
    return h.hexdigest()


def scenario_for(config: TransferExecutionConfig, terrain: str, condition: str, offset, yaw):
    """The ``littledog_transfer`` scenario of one run."""
    from repertoire.diagrams.littledog_transfer import LittleDogTransferScenario

    mode = {"greedy": "greedy", "planner": "planner"}.get(condition, "search")
    return LittleDogTransferScenario(
        **TERRAINS[terrain],
        mode=mode,
        multiple=condition == "multiple",
        gain=0.0 if condition == "no_integral" else 0.05,
        start_offset=[float(offset[0]), float(offset[1])],
        start_yaw_offset=float(yaw),
        library=config.library,
    )


MAX_START_DRAWS = 1000
"""Draws :func:`draw_start` makes before it gives up (at the config's widest perturbation,
6 cm and 20 degrees, 8 of seeds 0-59 draw twice or three times)."""


def draw_start(config: TransferExecutionConfig, terrain: str, rng: np.random.Generator):
    """A start perturbation whose feet stand on the board, drawn from ``rng``.

    Offsets uniform in ``+-max_offset_m`` along x and y and a heading offset uniform in
    ``+-max_yaw_deg`` are drawn until the perturbed start (before
    :func:`~repertoire.diagrams.littledog_transfer.flat_offset`) has every foot on the
    terrain's board, so the starts are uniform over the perturbations that stand on it. A
    start whose first draw stands on it is the one drawn before (same ``rng`` calls), so
    stored episodes keep their starts (no start of seeds 0-149 at the configs' 3 cm and 10
    degrees is redrawn). Before, a start off the board was an episode with nothing to
    execute: at ``max_offset_m`` 0.06 and 20 degrees 8 of seeds 0-59 (5 of the 20 on the
    modified terrain, whose nominal hind feet stand 3.9 cm from the board's back edge). A
    start where the robot cannot stand is taken as drawn:
    :func:`~repertoire.diagrams.littledog_transfer.plan_transfer` refuses it.

    Args:
        config: the study's config.
        terrain: a key of :data:`TERRAINS`.
        rng: the episode's generator.

    Returns:
        ``(offset (2,) m, yaw rad, draws)``.

    Raises:
        RepertoireError: no start on the board in :data:`MAX_START_DRAWS` draws.
    """
    from repertoire.diagrams.littledog_transfer import off_board, perturbed_start, target_board
    from repertoire.planning.littledog_crawl import CrawlParams

    board = None
    for draws in range(1, MAX_START_DRAWS + 1):
        offset = rng.uniform(-config.max_offset_m, config.max_offset_m, size=2)
        yaw = math.radians(float(rng.uniform(-config.max_yaw_deg, config.max_yaw_deg)))
        scenario = scenario_for(config, terrain, "search", offset, yaw)
        board = target_board(scenario) if board is None else board
        try:
            _, feet = perturbed_start(scenario, board, CrawlParams())
        except ScenarioError:
            return offset, yaw, draws
        if off_board(board, feet) is None:
            return offset, yaw, draws
    raise RepertoireError(
        f"no start with its feet on the {terrain} board in {MAX_START_DRAWS} draws "
        f"(max_offset_m {config.max_offset_m}, max_yaw_deg {config.max_yaw_deg})"
    )


FALL_TILT = 0.5
FALL_CLEARANCE = 0.04
"""A fall as :func:`~repertoire.diagrams.littledog_library.crossing_figures` counts it."""


def stop_reason(feet, body_pose, board, goal: float) -> str:
    """``crossed`` (both front feet past the goal line along +x), ``fell`` or ``""``.

    Args:
        feet: world foot centres (4 x 3 or 12), LEGS order (front feet first).
        body_pose: body pose [x, y, z, roll, pitch, yaw].
        board: the terrain.
        goal: the goal line (m along +x).
    """
    f = np.asarray(feet, dtype=float).reshape(4, 3)
    p = np.asarray(body_pose, dtype=float)
    if min(f[0, 0], f[1, 0]) >= goal:
        return "crossed"
    clearance = float(p[2] - board.height(np.array([p[0]]), np.array([p[1]]))[0])
    if max(abs(p[3]), abs(p[4])) > FALL_TILT or clearance < FALL_CLEARANCE:
        return "fell"
    return ""


def early_stop_monitor(diagram, period: float = 0.1):
    """A simulator monitor ending a ``littledog_transfer`` run once it crossed or fell.

    Checked every ``period`` s of simulated time from the inputs of the body and feet
    logs; the run ends one period after the first detection, so the logs (sampled every
    10 ms) hold the event and the diagram's check reads the same figures as a full run.
    """
    from pydrake.systems.framework import EventStatus

    board, _, goal = diagram._repertoire_crossing
    body = diagram.GetSubsystemByName("body_log")
    feet = diagram.GetSubsystemByName("feet_log")
    state = {"next": 0.0, "seen": ""}

    def monitor(root):
        t = root.get_time()
        if t < state["next"]:
            return EventStatus.Succeeded()
        state["next"] = t + period
        if state["seen"]:
            return EventStatus.ReachedTermination(None, state["seen"])
        state["seen"] = stop_reason(
            feet.get_input_port().Eval(feet.GetMyContextFromRoot(root)),
            body.get_input_port().Eval(body.GetMyContextFromRoot(root)),
            board,
            goal,
        )
        return EventStatus.Succeeded()

    return monitor


def run_episode(config: TransferExecutionConfig, seed: int) -> TransferExecutionRecord:
    """Draws the start perturbation from ``seed`` and runs every condition."""
    import time

    from repertoire.diagrams.littledog_library import check_littledog_library
    from repertoire.diagrams.littledog_transfer import build_littledog_transfer, plan_transfer
    from repertoire.diagrams.simulate import simulate

    config.validate()
    start = time.perf_counter()
    rng = np.random.default_rng(seed)
    terrain = config.terrains[seed % len(config.terrains)]
    offset, yaw, draws = draw_start(config, terrain, rng)
    keys = ("success", "fell", "ttc", "steps", "recorded", "planned", "error", "same", "key")
    out = {k: [] for k in keys}
    runs: dict[str, int] = {}  # run_key -> index of the condition that simulated it
    for condition in config.conditions:
        scenario = scenario_for(config, terrain, condition, offset, yaw)
        try:
            plan = plan_transfer(scenario)
        except ScenarioError as e:
            for k, v in (("success", False), ("fell", False), ("ttc", math.nan), ("steps", 0)):
                out[k].append(v)
            out["recorded"].append(0)
            out["planned"].append(0)
            out["error"].append(str(e))
            out["same"].append("")
            out["key"].append("")
            continue
        key = run_key(scenario, plan)
        if key in runs:
            i = runs[key]
            for k in keys:
                out[k].append(out[k][i])
            out["same"][-1] = config.conditions[i]
            continue
        runs[key] = len(out["success"])
        diagram = build_littledog_transfer(scenario, plan=plan)
        # Runs end once crossed or fallen (the figures are those of the full duration).
        _, context = simulate(diagram, config.duration_s, monitors=[early_stop_monitor(diagram)])
        f = check_littledog_library(diagram, context)
        kinds = [s.kind for s in plan.library]
        out["success"].append(bool(f["crossed"] >= 1.0 and f["fell"] == 0.0))
        out["fell"].append(bool(f["fell"]))
        out["ttc"].append(float(f["time_to_cross_s"]))
        out["steps"].append(int(f["steps_started"]))
        out["recorded"].append(kinds.count("recorded"))
        out["planned"].append(kinds.count("planned"))
        out["error"].append("")
        out["same"].append("")
        out["key"].append(key)
    return TransferExecutionRecord(
        terrain=terrain,
        offset_x_m=float(offset[0]),
        offset_y_m=float(offset[1]),
        offset_yaw_deg=math.degrees(yaw),
        conditions=list(config.conditions),
        success=out["success"],
        fell=out["fell"],
        time_to_cross_s=out["ttc"],
        steps_started=out["steps"],
        recorded=out["recorded"],
        planned=out["planned"],
        error=out["error"],
        wall_time_s=time.perf_counter() - start,
        same_run_as=out["same"],
        run_keys=out["key"],
        start_draws=draws,
    )


def summarize(
    records: list[TransferExecutionRecord], config: TransferExecutionConfig, out_dir: Path
) -> dict[str, Path]:
    """Success table per terrain and condition; success-rate figure; the path it runs.

    Returns:
        ``{"table": md, "success": png}``, and ``"path": png`` when the modified terrain
        ran: the search's path from the nominal start there, recorded and planned steps
        over the height map (:func:`_path_figure`).
    """
    from matplotlib.figure import Figure

    out_dir = Path(out_dir)
    lines = [
        "| terrain | condition | episodes | success | fell | nothing to execute | median time "
        "to cross (s) | median recorded + planned steps (of the runs) | run shared with |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    rates: dict[str, list[float]] = {c: [] for c in config.conditions}
    terrains = [t for t in config.terrains if any(r.terrain == t for r in records)]
    for name in terrains:
        rs = [r for r in records if r.terrain == name]
        for c in config.conditions:
            rows = [(r, r.conditions.index(c)) for r in rs if c in r.conditions]
            if not rows:
                rates[c].append(math.nan)
                continue
            ok = [r.success[i] for r, i in rows]
            times = [r.time_to_cross_s[i] for r, i in rows if r.success[i]]
            med = f"{np.median(times):.1f}" if times else "-"
            # steps of the libraries that ran: a start with nothing to execute has none
            ran = [(r, i) for r, i in rows if not r.error[i]]
            steps = (
                f"{np.median([r.recorded[i] for r, i in ran]):.0f} + "
                f"{np.median([r.planned[i] for r, i in ran]):.0f}"
                if ran
                else "-"
            )
            same = [r.same_run_as[i] for r, i in rows if i < len(r.same_run_as)]
            shared = ", ".join(f"{o} {same.count(o)}" for o in sorted(set(same) - {""})) or "-"
            lines.append(
                f"| {name} | {c} | {len(rows)} | {sum(ok)}/{len(rows)} "
                f"| {sum(r.fell[i] for r, i in rows)} | {sum(bool(r.error[i]) for r, i in rows)} "
                f"| {med} | {steps} | {shared} |"
            )
            rates[c].append(sum(ok) / len(rows))
    table = out_dir / "littledog_transfer_execution.md"
    table.write_text("\n".join(lines) + "\n")
    fig = Figure(figsize=(8.0, 4.0), layout="constrained")
    ax = fig.add_subplot(1, 1, 1)
    width = 0.8 / max(len(config.conditions), 1)
    x = np.arange(len(terrains))
    for k, c in enumerate(config.conditions):
        n = [sum(1 for r in records if r.terrain == t and c in r.conditions) for t in terrains]
        ax.bar(x + k * width, rates[c], width, label=f"{c}")
        for xi, ri, ni in zip(x + k * width, rates[c], n):
            if math.isfinite(ri):
                # successes / runs: a 0 % bar has no height, the label says what was run
                ax.text(xi, ri + 0.02, f"{round(ri * ni)}/{ni} succeeded", ha="center", fontsize=7)
    ax.set_xticks(x + 0.4 - 0.5 * width, terrains)
    ax.set_ylim(0.0, 1.3)  # room above the bars for the legend
    ax.set_yticks(np.linspace(0.0, 1.0, 6))
    ax.set_ylabel("success rate (crossed, no fall)")
    ax.set_xlabel("new terrain")
    ax.legend(
        fontsize=7,
        title="condition",
        title_fontsize=7,
        loc="upper center",
        ncol=len(config.conditions),
    )
    ax.set_title(
        f"Transferred library in physics, perturbed starts (+-{100 * config.max_offset_m:.0f} cm, "
        f"+-{config.max_yaw_deg:.0f} deg)",
        fontsize=9,
    )
    png = out_dir / "littledog_transfer_success.png"
    fig.savefig(png, dpi=110)
    files = {"table": table, "success": png}
    if "modified" in terrains:
        files["path"] = _path_figure(config, out_dir / "littledog_transfer_path.png")
    return files


def _path_figure(config: TransferExecutionConfig, path: Path) -> Path:
    """The modified terrain's library and the search's path from the nominal start (a PNG).

    The scenario every modified-terrain episode runs (the search condition, no start
    offset): transferred steps, and the final library's recorded steps (green circles)
    and planned ones (orange squares) over the rocks from ``change_from``.
    """
    from repertoire.diagrams.littledog_transfer import plan_transfer
    from repertoire.planning.transfer_plot import library_path_figure

    scenario = scenario_for(config, "modified", "search", (0.0, 0.0), 0.0)
    plan = plan_transfer(scenario)
    return library_path_figure(
        plan.board,
        plan.transfer.library,
        plan.library,
        path,
        changed_from=scenario.change_from,
        goal=plan.goal,
        title=f"Modified terrain, nominal start: {plan.search.message}",
        links=plan.transfer.links,
    )


def demo_config() -> TransferExecutionConfig:
    """The modified terrain, the paper's method only (about 30 s of wall time)."""
    return TransferExecutionConfig(terrains=["modified"], conditions=["search"])


def smoke_config() -> TransferExecutionConfig:
    """The modified terrain, the paper's method, 2 s runs."""
    return TransferExecutionConfig(terrains=["modified"], conditions=["search"], duration_s=2.0)


register_study(
    "littledog_transfer_execution",
    config_type=TransferExecutionConfig,
    record_type=TransferExecutionRecord,
    run_episode=run_episode,
    description="LittleDog with a transferred library in physics on new terrains: success rate; "
    "ablations greedy (no search), no integral controller, planner only, multiple matches",
    summarize=summarize,
    demo_config=demo_config,
    demo_episodes=1,
    smoke_config=smoke_config,
).run_if_main(__name__)
