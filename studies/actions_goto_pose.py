"""GoToPose episodes on the soccer field: learn its duration and ball-collision failure.

Each episode (Stulp & Beetz, section 5.1) samples a start ``[x, y, phi, v]``
and a goal pose ``[x_g, y_g, phi_g, v_g]`` behind the ball (the robot must
approach the ball to dribble it), uniformly from the config's ranges, and runs
the ``soccer_goto_pose`` world until the action's status leaves RUNNING. The
record holds the parameters, the duration, the failure flag (the robot touched
the ball before reaching its pose, read from the plant's contact results, or
the action failed or timed out) and the first ``n_states`` robot states.

``summarize`` fits a duration model tree and a pessimistic failure tree on 3/4
of the episodes (``fit_action_model``), measures them on the rest and writes
Table 1 / Table 2 rows beside the paper's numbers, learning curves and a polar
plot of predicted durations like the paper's Fig. 7.

Run it with ``python -m repertoire.studies.actions_goto_pose --help``.
"""

import dataclasses
import math
import time
from pathlib import Path

import numpy as np
from repertoire.models.diffdrive import MAX_FORWARD_SPEED
from repertoire.studies._action_tables import POSE_FEATURE_FUNCS as FEATURE_FUNCS
from repertoire.studies.engine import register_study

from repertoire.checks import check_range
from repertoire.errors import RepertoireError

BALL_RADIUS = 0.11
#: Table 1 of Stulp & Beetz, soccer (simulated) goToPose: 3/4 n_e, mean duration [s], MAE [s].
PAPER_GOTO = {"episodes": 750, "mean": 6.2, "mae": 0.22}
PAPER_FAILURE_ACCURACY = 0.89  # section 5: failure (collision) tree, correctly classified


@dataclasses.dataclass
class GoToPoseEpisodesConfig:
    """Sampling ranges and simulation settings of the GoToPose episodes.

    Attributes:
        x_range: start x range [m].
        y_range: start y range [m].
        v_range: start speed range [m/s].
        goal_distance_range: goal distance behind the ball centre [m].
        v_g_range: goal speed range [m/s].
        min_start_clearance: starts closer than this to the ball are resampled [m].
        n_states: intermediate states kept per episode.
        state_period: time between kept states [s].
        time_step: plant step [s].
        control_period: GoToPose update period [s].
        gains: GoToPose gain overrides; a weak heading term (k_beta -0.3, the
            default -1.0 curves wide around the ball) drives straighter, so
            approaches from the wrong side touch the ball, as in the paper.
    """

    x_range: list[float] = dataclasses.field(default_factory=lambda: [-1.5, 2.5])
    y_range: list[float] = dataclasses.field(default_factory=lambda: [-1.5, 1.8])
    v_range: list[float] = dataclasses.field(default_factory=lambda: [0.0, 0.5])
    goal_distance_range: list[float] = dataclasses.field(default_factory=lambda: [0.35, 0.5])
    v_g_range: list[float] = dataclasses.field(default_factory=lambda: [0.0, 0.1])
    min_start_clearance: float = 0.6
    n_states: int = 5
    state_period: float = 0.2
    time_step: float = 1e-2
    control_period: float = 0.02
    gains: dict[str, float] = dataclasses.field(default_factory=lambda: {"k_beta": -0.3})

    def validate(self) -> None:
        """Raises RepertoireError naming the first bad field."""
        for name in ("x_range", "y_range", "v_range", "goal_distance_range", "v_g_range"):
            check_range(name, getattr(self, name))
        if not (-3 <= self.x_range[0] and self.x_range[1] <= 3):
            raise RepertoireError(f"x_range must lie on the field [-3, 3], got {self.x_range}")
        if not (-2 <= self.y_range[0] and self.y_range[1] <= 2):
            raise RepertoireError(f"y_range must lie on the field [-2, 2], got {self.y_range}")
        # a start the wheels cannot reach is refused by the world: here, before any episode
        check_range("v_range", self.v_range, (-MAX_FORWARD_SPEED, MAX_FORWARD_SPEED))
        if self.v_g_range[0] < 0:  # GoToPose arrives at >= 0 m/s: such goals only time out
            raise RepertoireError(f"v_g_range must be >= 0 m/s, got {self.v_g_range}")
        if self.goal_distance_range[0] <= BALL_RADIUS:
            raise RepertoireError("goal_distance_range must start beyond the ball radius 0.11 m")
        if self.n_states < 0 or self.state_period <= 0 or self.min_start_clearance < 0:
            raise RepertoireError("n_states >= 0, state_period > 0, min_start_clearance >= 0")


@dataclasses.dataclass
class GoToPoseRecord:
    """One GoToPose episode.

    Attributes:
        x: start x [m].
        y: start y [m].
        phi: start heading [rad].
        v: start speed [m/s].
        x_g: goal x [m].
        y_g: goal y [m].
        phi_g: goal heading [rad].
        v_g: goal speed [m/s].
        duration: time until the status left RUNNING [s].
        status: the final ActionStatus name.
        touched_ball: the robot touched the ball before the status left RUNNING.
        failed: touched the ball, or the action failed or timed out.
        states: the first ``n_states`` states ``[x, y, phi, v]``, flattened.
        wall_time_s: wall time of the episode (timing field).
    """

    x: float
    y: float
    phi: float
    v: float
    x_g: float
    y_g: float
    phi_g: float
    v_g: float
    duration: float
    status: str
    touched_ball: bool
    failed: bool
    states: list[float]
    wall_time_s: float


def sample_parameters(config: GoToPoseEpisodesConfig, seed: int) -> tuple[list[float], list[float]]:
    """Seeded start ``[x, y, phi, v]`` and goal ``[x_g, y_g, phi_g, v_g]``.

    The goal faces the ball from ``goal_distance`` behind it along a uniform
    approach heading; starts too close to the ball or in a goal are resampled.
    """
    from repertoire.diagrams.soccer import BALL_POSITION, draw_start_xy

    rng = np.random.default_rng(seed)
    bx, by = BALL_POSITION
    x, y = draw_start_xy(rng, config.x_range, config.y_range, config.min_start_clearance)
    phi = rng.uniform(-math.pi, math.pi)
    v = rng.uniform(*config.v_range)
    phi_g = rng.uniform(-math.pi, math.pi)
    d = rng.uniform(*config.goal_distance_range)
    v_g = rng.uniform(*config.v_g_range)
    goal = [bx - d * math.cos(phi_g), by - d * math.sin(phi_g), phi_g, v_g]
    return [float(x), float(y), float(phi), float(v)], [float(g) for g in goal]


def run_episode(config: GoToPoseEpisodesConfig, seed: int) -> GoToPoseRecord:
    """Runs one GoToPose episode in the soccer world."""
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import EventStatus
    from repertoire.diagrams.soccer import (
        GoToPoseScenario,
        build_soccer_goto_pose,
        goto_status,
        robot_state,
        set_initial_speed,
    )
    from repertoire.systems.go_to_pose import ActionStatus

    config.validate()
    t0 = time.perf_counter()
    start, goal = sample_parameters(config, seed)
    diagram = build_soccer_goto_pose(
        GoToPoseScenario(
            initial_pose=start[:3],
            initial_speed=start[3],
            target=goal,
            time_step=config.time_step,
            control_period=config.control_period,
            gains=dict(config.gains),
        )
    )
    plant = diagram.GetSubsystemByName("plant")
    ball_body = plant.GetBodyByName("ball").index()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    set_initial_speed(diagram, context, start[3])
    plant_context = plant.GetMyContextFromRoot(context)
    touched = [False]
    states: list[float] = []
    next_state_time = [0.0]

    def monitor(root_context) -> EventStatus:
        results = plant.get_contact_results_output_port().Eval(plant_context)
        for i in range(results.num_point_pair_contacts()):
            info = results.point_pair_contact_info(i)
            if ball_body in (info.bodyA_index(), info.bodyB_index()):
                other = (
                    info.bodyB_index() if info.bodyA_index() == ball_body else info.bodyA_index()
                )
                if plant.get_body(other).name() != "ground" and other != plant.world_body().index():
                    touched[0] = True
        if len(states) < 4 * config.n_states and root_context.get_time() >= next_state_time[0]:
            states.extend(float(s) for s in robot_state(diagram, root_context))
            next_state_time[0] += config.state_period
        if goto_status(diagram, root_context) != ActionStatus.RUNNING:
            return EventStatus.ReachedTermination(None, "action finished")
        return EventStatus.Succeeded()

    simulator.set_monitor(monitor)
    goto = diagram.GetSubsystemByName("goto_pose")
    timeout = goto.gains(goto.GetMyContextFromRoot(context))["timeout"]
    simulator.AdvanceTo(timeout + 1.0)
    status = goto_status(diagram, context)
    return GoToPoseRecord(
        *start,
        *goal,
        duration=float(context.get_time()),
        status=status.name,
        touched_ball=bool(touched[0]),
        failed=bool(touched[0] or status != ActionStatus.SUCCEEDED),
        states=states,
        wall_time_s=time.perf_counter() - t0,
    )


def summarize(
    records: list[GoToPoseRecord], config: GoToPoseEpisodesConfig, out_dir: Path
) -> dict[str, Path]:
    """Fits the models and writes Table 1/2 (Markdown), learning curves and a Fig. 7 polar plot.

    Returns:
        Paths by name (nothing is fitted below ``min_records()`` successful episodes).
    """
    from repertoire.studies._action_tables import summarize_action_study

    n_failed = sum(r.failed for r in records)
    return summarize_action_study(
        "actions_goto_pose",
        "goToPose (soccer, sim)",
        records,
        out_dir,
        lambda r: r.status == "SUCCEEDED" and not r.touched_ball,
        FEATURE_FUNCS,
        PAPER_GOTO,
        "ball collision",
        f"GoToPose: learning curves ({n_failed} failed of {len(records)} episodes)",
        failure_heading="Table 2: failure (ball collision) tree, held-out quarter",
        paper_accuracy=PAPER_FAILURE_ACCURACY,
        # Fig. 7: predicted duration around a goal at the origin facing +x
        polar_title="Predicted duration (s, radial) by start direction\ngoal at centre facing 0°",
    )


def demo_config() -> GoToPoseEpisodesConfig:
    """The demo config (the defaults)."""
    return GoToPoseEpisodesConfig()


def smoke_config() -> GoToPoseEpisodesConfig:
    """A tiny config for tests: starts close to the goal region, a coarse step."""
    return GoToPoseEpisodesConfig(x_range=[-0.5, 0.0], y_range=[0.0, 0.5], time_step=1e-2)


register_study(
    "actions_goto_pose",
    config_type=GoToPoseEpisodesConfig,
    record_type=GoToPoseRecord,
    run_episode=run_episode,
    description="GoToPose episodes on the soccer field: duration model tree, collision tree",
    summarize=summarize,
    demo_config=demo_config,
    demo_episodes=40,
    smoke_config=smoke_config,
).run_if_main(__name__)
