"""Helpers shared by the DMP studies.

The studies are goals, obstacles, chaining, and the arm studies (grid, pick-and-place, serving,
obstacle arm). Registration (every DMP study registers the same way), logged paths subsampled
for figures, the default carry control points, the ball's radius, and the statistics and writing
of the results tables.

The diagrams layer is imported inside the functions, as the studies do, so importing a study
module stays cheap.
"""

import copy
import math
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from repertoire.studies.registry import StudyEntry, register_study

from repertoire.errors import RepertoireError


def register_dmp_study(
    module_name: str,
    config_type: type,
    record_type: type,
    *,
    description: str,
    demo_episodes: int,
    smoke: dict,
) -> StudyEntry:
    """Registers the DMP study defined by ``module_name`` and runs it when that is ``__main__``.

    The study is named after the module; its ``run_episode`` and ``summarize`` are the module's
    functions of those names. The demo runs the default config; the smoke config (for tests) is
    the default with the ``smoke`` fields changed.

    Args:
        module_name: The study module's ``__name__`` (``repertoire.studies.<study>``).
        config_type: The study's config dataclass.
        record_type: The study's record dataclass.
        description: One line saying what the study measures.
        demo_episodes: Number of episodes the demo runs.
        smoke: Config fields a tiny test run changes (e.g. ``{"sim_duration_s": 0.3}``).

    Returns:
        The registered entry (when the module was imported, not run).
    """
    module = sys.modules[module_name]
    name = module.__spec__.name.rsplit(".", 1)[-1] if module.__spec__ else module_name
    return register_study(
        name,
        config_type=config_type,
        record_type=record_type,
        run_episode=module.run_episode,
        description=description,
        summarize=module.summarize,
        demo_config=config_type,
        demo_episodes=demo_episodes,
        smoke_config=lambda: config_type(**copy.deepcopy(smoke)),
    ).run_if_main(module_name)


def write_table(out_dir: Path, filename: str, lines: list[str]) -> Path:
    """Writes a Markdown results table (one line per entry) and returns its path.

    Args:
        out_dir: Output directory.
        filename: File name inside ``out_dir``.
        lines: The table's lines, without newlines.
    """
    path = Path(out_dir) / filename
    path.write_text("\n".join(lines) + "\n")
    return path


def log_stride(every_s: float) -> int:
    """How many log samples to step to keep one every ``every_s`` seconds (>= 1).

    Args:
        every_s: Wanted spacing of the kept samples [s].
    """
    from repertoire.diagrams.arm_dmp import LOG_PERIOD

    return max(1, int(round(every_s / LOG_PERIOD)))


def tcp_path(diagram, context, every_s: float) -> np.ndarray:
    """The logged tcp positions, one every ``every_s`` seconds, shape (k, 3) [m].

    Args:
        diagram: An arm world after a run.
        context: Its root context.
        every_s: Spacing of the kept samples [s].
    """
    from repertoire.diagrams.arm_dmp_results import tcp_log

    return tcp_log(diagram, context).point[:: log_stride(every_s)]


#: Figures of a pick-and-place run the studies keep (``pick_and_place_figures`` but its flags).
PICK_PLACE_FIGURES = (
    "cup_to_coaster_m",
    "cup_height_above_coaster_m",
    "cup_tilt_rad",
    "min_obstacle_clearance_m",
    "grasp_reach_error_m",
    "place_reach_error_m",
    "min_ball_gap_m",
    "min_ball_gap_time_s",
    "grasp_slip_m",
    "grasp_slip_time_s",
    "held_offset_m",
    "start_delay_s",
    "release_object_error_m",
    "release_settled",
)

#: How a pick-and-place run ended (``run_pick_and_place``'s ``outcome``), in the order of
#: precedence: the IK stopped it, the cup moved more than ``GRASP_SLIP_TOLERANCE`` in the
#: hand while carried (whether or not it still landed within 2 cm), it was placed, or it
#: ran to the end and missed.
OUTCOMES = ("stopped", "grasp_slip", "placed", "missed")


def run_pick_and_place(scenario, sim_duration_s: float, path_every_s: float) -> dict:
    """Builds and runs one pick-and-place world; an IK or scenario error stops it.

    Args:
        scenario: a ``PickPlaceScenario``.
        sim_duration_s: simulated time cap [s]; 0 runs the whole task.
        path_every_s: spacing of the kept tcp positions [s].

    Returns:
        ``failure`` (the error's text, empty when it ran), ``path`` (the tcp, shape
        (k, 3), empty when stopped), ``duration`` (simulated [s]), ``wall`` (simulation
        wall time [s]), each of :data:`PICK_PLACE_FIGURES` (NaN when the run stopped
        before them), ``placed``: it ran and the cup stands on the coaster (within
        2 cm of it horizontally and 1 cm vertically, tilted under 0.2 rad), ``outcome``
        (one of :data:`OUTCOMES`), ``report``: the IK's stop message, else the grasp
        slip's (``grasp_slip_text``), else, when the release began before the cup had
        settled on the coaster, the placing's (``placement_text``), else empty;
        ``joint_margins`` (per arm joint, the IK reference's least distance from its limits
        over the run [rad]; NaN when nothing ran) and ``joint_held_steps`` (per joint, the
        IK steps that held it at a limit: ``joints_at_limits``).
    """
    from repertoire.diagrams.arm_dmp import build_pick_and_place
    from repertoire.diagrams.arm_dmp_results import (
        GRASP_SLIP_TOLERANCE,
        IkTargetError,
        JointLimitRecorder,
        grasp_slip_text,
        pick_and_place_figures,
        placement_text,
        run_arm_world,
    )
    from repertoire.diagrams.arm_dmp_scenarios import PICK_PLACE_LABELS, segment_timing

    out = {"failure": "", "path": np.zeros((0, 3)), "duration": 0.0, "wall": 0.0}
    settle_report = ""
    out.update(dict.fromkeys(PICK_PLACE_FIGURES, float("nan")))
    recorder = None
    try:
        diagram = build_pick_and_place(scenario)
        recorder = JointLimitRecorder(diagram)
        _, duration = segment_timing(PICK_PLACE_LABELS, scenario.settle_time)
        if sim_duration_s > 0:
            duration = min(duration, sim_duration_s)
        out["duration"] = duration
        context, out["wall"] = run_arm_world(diagram, duration, monitors=[recorder])
        figures = pick_and_place_figures(diagram, context)
        out.update({k: figures[k] for k in PICK_PLACE_FIGURES})
        out["path"] = tcp_path(diagram, context, path_every_s)
        if figures["release_settled"] == 0.0:  # the release's wait ran out
            settle_report = placement_text(
                figures["release_object_error_m"],
                figures["release_object_speed_mps"],
                figures["start_delay_s"],
                "cup",
            )
    except (IkTargetError, RepertoireError) as e:
        out["failure"] = str(e)
    out.update(joint_limit_figures(recorder))
    out["placed"] = bool(
        not out["failure"]
        and out["cup_to_coaster_m"] < 0.02
        and abs(out["cup_height_above_coaster_m"]) < 0.01
        and out["cup_tilt_rad"] < 0.2
    )
    slipped = bool(out["grasp_slip_m"] > GRASP_SLIP_TOLERANCE)
    if out["failure"]:
        out["outcome"], out["report"] = "stopped", out["failure"]
    elif slipped:
        out["outcome"] = "grasp_slip"
        out["report"] = grasp_slip_text(out["grasp_slip_m"], out["grasp_slip_time_s"], "cup")
    else:
        out["outcome"] = "placed" if out["placed"] else "missed"
        out["report"] = settle_report
    return out


def joint_limit_figures(recorder) -> dict[str, np.ndarray]:
    """``joint_margins`` and ``joint_held_steps`` of a run (see :func:`run_pick_and_place`).

    Args:
        recorder: the run's :class:`~repertoire.diagrams.arm_dmp_results.JointLimitRecorder`,
            or None when the world was not built (NaN margins, no held steps).
    """
    from repertoire.diagrams.arm_dmp_results import limit_margins
    from repertoire.models.arm7 import ARM_JOINTS, arm7_joint_limits

    if recorder is None or len(recorder.times) == 0:
        n = len(ARM_JOINTS)
        return {"joint_margins": np.full(n, np.nan), "joint_held_steps": np.zeros(n, int)}
    return {
        "joint_margins": limit_margins(recorder.q, *arm7_joint_limits()),
        "joint_held_steps": np.count_nonzero(recorder.held, axis=0),
    }


#: The goal of :func:`joint_limit_probe`: the hand at home turned this far about its x axis.
PROBE_TURN_RAD = 2.0


def joint_limit_probe(duration: float = 3.0):
    """The hand at home asked to turn :data:`PROBE_TURN_RAD` about its x axis (a grasp goal).

    The wrist's limits do not allow that orientation, so the IK holds wrist joints at their
    limits and reports ``STATUS_JOINT_LIMITS`` (docs/results/arm.md's example: stopped at 1.92 s).

    Args:
        duration: simulated seconds at most [s].

    Returns:
        ``(recorder, report)``: the run's
        :class:`~repertoire.diagrams.arm_dmp_results.JointLimitRecorder` and the IK's
        stop message (empty if it did not stop).
    """
    from pydrake.math import RotationMatrix
    from repertoire.diagrams.arm_dmp import build_arm_world
    from repertoire.diagrams.arm_dmp_results import (
        IkTargetError,
        JointLimitRecorder,
        run_arm_world,
    )
    from repertoire.diagrams.arm_dmp_scenarios import PickPlaceScenario
    from repertoire.models.arm7 import HAND_OPEN, ArmObject
    from repertoire.planning.arm_library import home_tcp_pose, quaternion_wxyz
    from repertoire.systems.arm_goals import SegmentGoal

    home = home_tcp_pose()
    turned = home.rotation() @ RotationMatrix.MakeXRotation(PROBE_TURN_RAD)
    goal = SegmentGoal("grasp", home.translation(), quaternion_wxyz(turned), np.array(HAND_OPEN))
    cup = ArmObject(name="cup", kind="cup", xy=[0.55, -0.25])
    diagram = build_arm_world(
        "joint_limit_probe", PickPlaceScenario(), [cup], [goal], graspable=["cup:cup"]
    )
    recorder = JointLimitRecorder(diagram)
    try:
        run_arm_world(diagram, duration, monitors=[recorder])
    except IkTargetError as e:
        return recorder, str(e)
    return recorder, ""


#: Colour of an outcome in the arm studies' figures: True (success) green, False red.
OUTCOME_COLOURS = {True: "tab:green", False: "tab:red"}


def outcome_handles(
    outcomes, label: str, *, words: tuple[str, str] = ("success", "failure"), lw: float = 1.0
) -> list:
    """Legend lines for the outcomes a figure drew, in :data:`OUTCOME_COLOURS`.

    An entry is made only for an outcome present in ``outcomes``, so a legend never names a
    colour the figure does not show (success first, then failure).

    Args:
        outcomes: The drawn episodes' outcomes (truthy: success).
        label: What the lines are (``"tcp path"``); each entry reads ``"label, word"``.
        words: The words for (success, failure).
        lw: Line width of the entries.

    Returns:
        ``matplotlib.lines.Line2D`` handles, 0 to 2 of them.
    """
    from matplotlib.lines import Line2D

    present = {bool(o) for o in outcomes}
    return [
        Line2D([], [], color=OUTCOME_COLOURS[ok], lw=lw, label=f"{label}, {word}")
        for ok, word in zip((True, False), words, strict=True)
        if ok in present
    ]


def legend_below(ax, handles: list, *, ncols: int, below_in: float = 0.5, fontsize: float = 8):
    """A legend centred under ``ax``, ``below_in`` inches under its bottom edge.

    A fixed distance in inches clears the tick labels and the x label whatever the axes'
    height (a fraction of the axes' height reached into the x label of a flat top view).

    Args:
        ax: The axes.
        handles: Legend handles (with labels).
        ncols: Legend columns.
        below_in: Gap between the axes' bottom and the legend's top [inch].
        fontsize: Font size of the entries.

    Returns:
        The legend.
    """
    from matplotlib.transforms import ScaledTranslation

    shift = ScaledTranslation(0.0, -below_in, ax.figure.dpi_scale_trans)
    return ax.legend(
        handles=handles,
        loc="upper center",
        bbox_to_anchor=(0.5, 0.0),
        bbox_transform=ax.transAxes + shift,
        borderaxespad=0.0,  # the gap is below_in exactly
        ncols=ncols,
        fontsize=fontsize,
    )


def carry_control_points() -> list[list[float]]:
    """The default eq.-10 control points while carrying (``CARRY_CONTROL_POINTS``)."""
    from repertoire.diagrams.arm_dmp_scenarios import CARRY_CONTROL_POINTS

    return [list(p) for p in CARRY_CONTROL_POINTS]


def default_obstacle_gamma() -> float:
    """The arm's default gain of eq. 10 (``arm_dmp_scenarios.OBSTACLE_GAMMA``, in the paper's v)."""
    from repertoire.diagrams.arm_dmp_scenarios import OBSTACLE_GAMMA

    return float(OBSTACLE_GAMMA)


def obstacle_radius() -> float:
    """Radius of the ball obstacle [m] (``models.arm7.OBSTACLE_RADIUS``)."""
    from repertoire.models.arm7 import OBSTACLE_RADIUS

    return float(OBSTACLE_RADIUS)


def stat_pair(values, first, second, digits: int = 2) -> str:
    """'first / second' of the finite values (e.g. median / max), or 'n/a' if none.

    Args:
        values: Numbers (NaN and inf are left out).
        first: Statistic printed first (e.g. ``np.median``).
        second: Statistic printed second (e.g. ``np.max``).
        digits: Decimals.
    """
    finite = np.asarray(values, dtype=float)
    finite = finite[np.isfinite(finite)]
    if finite.size == 0:
        return "n/a"
    return f"{first(finite):.{digits}f} / {second(finite):.{digits}f}"


def finite_max(values) -> float:
    """Largest finite value, NaN if there is none.

    Args:
        values: Numbers (NaN and inf are left out).
    """
    finite = np.asarray(values, dtype=float)
    finite = finite[np.isfinite(finite)]
    return float(finite.max()) if finite.size else float("nan")


def check_arm_config(config, ranges: Mapping[str, Sequence[float]]) -> None:
    """Checks an arm study config: sampling ranges and the run's timing.

    Args:
        config: The config (named in the messages; has ``sim_duration_s`` and ``path_every_s``).
        ranges: Field name -> its ``[min, max]`` sampling range.

    Raises:
        RepertoireError: A range that is not two finite numbers in order, a negative
            ``sim_duration_s`` or a ``path_every_s`` that is not positive, a ``time_step``
            that is not positive, or (where the config has them) obstacle gains or length
            scale that are negative; every number must be finite.
    """
    owner = type(config).__name__
    for name, r in ranges.items():
        if len(r) != 2 or not all(math.isfinite(v) for v in r) or r[0] > r[1]:
            raise RepertoireError(f"{owner}.{name} must be [min, max], got {r}")
    if not (0 <= config.sim_duration_s < math.inf and 0 < config.path_every_s < math.inf):
        raise RepertoireError(
            f"{owner} needs finite sim_duration_s >= 0 and path_every_s > 0, got "
            f"{config.sim_duration_s}, {config.path_every_s}"
        )
    if hasattr(config, "time_step") and not 0 < config.time_step < math.inf:
        raise RepertoireError(f"{owner}.time_step must be finite and > 0, got {config.time_step}")
    for name in ("obstacle_gamma", "obstacle_beta", "obstacle_length_scale"):
        if hasattr(config, name) and not 0 <= getattr(config, name) < math.inf:
            raise RepertoireError(
                f"{owner}.{name} must be finite and >= 0, got {getattr(config, name)}"
            )


def timing_rows(records) -> list[str]:
    """The results-table rows of simulated time per episode and wall time per simulation.

    The wall time counts the runs that were not stopped (``failure`` empty).

    Args:
        records: Episode records with ``sim_time_s``, ``wall_sim_s`` and ``failure``.
    """
    ok = [r for r in records if not r.failure]
    walls = np.array([r.wall_sim_s for r in ok]) if ok else np.array([np.nan])
    return [
        f"| simulated time per episode [s] | {np.mean([r.sim_time_s for r in records]):.1f} |",
        f"| wall time per simulation, mean / max [s] | {stat_pair(walls, np.mean, np.max)} |",
    ]
