"""DribbleBall episodes on the soccer field: learn the dribbling duration and ball loss.

Each episode (Stulp & Beetz, section 5.1) samples a start ``[x, y, phi, v]``
with the ball held in front of the robot, and a goal ``[x_g, y_g, phi_g, v_g]``
at a distance in ``goal_distance_range`` on the field, uniformly from the
config's ranges, and runs the ``soccer_dribble`` world until the action's status
leaves RUNNING. The record holds the parameters (and the ball, Table 6), the
duration, the failure flag (the ball was lost, or the action timed out) and the
first ``n_states`` states ``[x, y, phi, v, x_ball, y_ball]``.

Table 7 gives dribbleBall the goToPose features (``dist, angle_to, angle_at,
v, v_g``): the ball sits at the held spot, so its position adds nothing.
``summarize`` writes the Table 1 row beside the paper's, the ball-loss tree's
confusion matrix, learning curves and a polar plot of predicted durations.

Run it with ``python -m repertoire.studies.actions_dribble --help``.
"""

import dataclasses
import math
import time
from pathlib import Path

import numpy as np
from repertoire.studies._action_tables import POSE_FEATURE_FUNCS as FEATURE_FUNCS
from repertoire.studies.engine import register_study

from repertoire.checks import check_range
from repertoire.errors import RepertoireError

PAPER_DRIBBLE = {"episodes": 750, "mean": 7.4, "mae": 0.29}  # Table 1, soccer (simulated)
FIELD = (-3.0, 3.0, -2.0, 2.0)


@dataclasses.dataclass
class DribbleEpisodesConfig:
    """Sampling ranges and simulation settings of the DribbleBall episodes.

    Attributes:
        x_range: start x range [m].
        y_range: start y range [m].
        v_range: start speed of the robot and the ball [m/s].
        goal_distance_range: distance from the start to the goal [m].
        v_g_range: goal speed range [m/s].
        goal_heading_spread: the goal heading is the start-to-goal direction plus
            a uniform turn in ``[-spread, spread]`` [rad] (a dribble ends facing
            roughly where it went; the start heading is uniform).
        margin: goals closer than this to the field's edge are resampled [m].
        n_states: intermediate states kept per episode.
        state_period: time between kept states [s].
        time_step: plant step [s].
        control_period: DribbleBall update period [s].
        gains: DribbleBall gain overrides.
        reuse_diagram: build the world once per worker process and reset it for each
            episode (False: build it for every episode, the old way; for benchmarks).
    """

    x_range: list[float] = dataclasses.field(default_factory=lambda: [-2.2, 2.2])
    y_range: list[float] = dataclasses.field(default_factory=lambda: [-1.4, 1.4])
    v_range: list[float] = dataclasses.field(default_factory=lambda: [0.0, 0.3])
    goal_distance_range: list[float] = dataclasses.field(default_factory=lambda: [0.5, 2.5])
    v_g_range: list[float] = dataclasses.field(default_factory=lambda: [0.0, 0.1])
    goal_heading_spread: float = 1.2
    margin: float = 0.5
    n_states: int = 5
    state_period: float = 0.2
    time_step: float = 1e-2
    control_period: float = 0.02
    gains: dict[str, float] = dataclasses.field(default_factory=dict)
    reuse_diagram: bool = True

    def validate(self) -> None:
        """Raises RepertoireError naming the first bad field."""
        for name in ("x_range", "y_range", "v_range", "goal_distance_range", "v_g_range"):
            check_range(name, getattr(self, name))
        if not (FIELD[0] <= self.x_range[0] and self.x_range[1] <= FIELD[1]):
            raise RepertoireError(f"x_range must lie on the field [-3, 3], got {self.x_range}")
        if not (FIELD[2] <= self.y_range[0] and self.y_range[1] <= FIELD[3]):
            raise RepertoireError(f"y_range must lie on the field [-2, 2], got {self.y_range}")
        if self.goal_distance_range[0] <= 0 or self.v_range[0] < 0 or self.v_g_range[0] < 0:
            raise RepertoireError("goal_distance_range must be > 0, speed ranges >= 0")
        if not (0 <= self.goal_heading_spread <= math.pi):
            raise RepertoireError(
                f"goal_heading_spread must be in [0, pi], got {self.goal_heading_spread}"
            )
        if not (0 <= self.margin < 1.5):
            raise RepertoireError(f"margin must be in [0, 1.5) m, got {self.margin}")
        if self.n_states < 0 or self.state_period <= 0:
            raise RepertoireError("n_states >= 0, state_period > 0")


@dataclasses.dataclass
class DribbleRecord:
    """One DribbleBall episode.

    Attributes:
        x: start x [m].
        y: start y [m].
        phi: start heading [rad].
        v: start speed [m/s].
        x_ball: start ball x [m].
        y_ball: start ball y [m].
        x_g: goal x [m].
        y_g: goal y [m].
        phi_g: goal heading [rad].
        v_g: goal speed [m/s].
        duration: time until the status left RUNNING [s].
        status: the final ActionStatus name.
        lost_ball: the action failed because the ball left its held spot.
        failed: the action did not succeed (ball lost or timed out).
        states: the first ``n_states`` of ``[x, y, phi, v, x_ball, y_ball]``, flattened.
        wall_time_s: wall time of the episode (timing field).
    """

    x: float
    y: float
    phi: float
    v: float
    x_ball: float
    y_ball: float
    x_g: float
    y_g: float
    phi_g: float
    v_g: float
    duration: float
    status: str
    lost_ball: bool
    failed: bool
    states: list[float]
    wall_time_s: float


def sample_parameters(config: DribbleEpisodesConfig, seed: int) -> tuple[list[float], list[float]]:
    """Seeded start ``[x, y, phi, v]`` and goal ``[x_g, y_g, phi_g, v_g]``.

    The goal lies ``goal_distance`` from the start in a uniform direction and at
    least ``margin`` inside the field; other draws are resampled. So are starts where the
    robot, or the ball held ahead of it (``DribbleScenario.ball_offset``; checked with the
    robot's footprint disc, which also covers the dribbler's guide arms), would touch a
    goal post or net.
    """
    from repertoire.diagrams.soccer import clear_of_goals
    from repertoire.diagrams.soccer_dribble import DribbleScenario

    forward, left = DribbleScenario().ball_offset
    rng = np.random.default_rng(seed)
    for _ in range(1000):
        x, y = rng.uniform(*config.x_range), rng.uniform(*config.y_range)
        phi = rng.uniform(-math.pi, math.pi)
        c, s = math.cos(phi), math.sin(phi)
        ball = (x + c * forward - s * left, y + s * forward + c * left)
        if clear_of_goals(x, y) and clear_of_goals(*ball):
            break
    else:
        raise RepertoireError("no start with the robot and its ball clear of the goals")
    v = rng.uniform(*config.v_range)
    m = config.margin
    for _ in range(1000):
        d, direction = rng.uniform(*config.goal_distance_range), rng.uniform(-math.pi, math.pi)
        xg, yg = x + d * math.cos(direction), y + d * math.sin(direction)
        if FIELD[0] + m <= xg <= FIELD[1] - m and FIELD[2] + m <= yg <= FIELD[3] - m:
            break
    else:
        raise RepertoireError("no goal inside the field's margin at goal_distance_range")
    phi_g = float(
        np.remainder(
            direction
            + rng.uniform(-config.goal_heading_spread, config.goal_heading_spread)
            + math.pi,
            2 * math.pi,
        )
        - math.pi
    )
    v_g = rng.uniform(*config.v_g_range)
    return [float(x), float(y), float(phi), float(v)], [float(xg), float(yg), phi_g, float(v_g)]


def run_episode(config: DribbleEpisodesConfig, seed: int) -> DribbleRecord:
    """Runs one DribbleBall episode in the soccer world."""
    from pydrake.systems.framework import EventStatus
    from repertoire.diagrams.soccer import set_initial_speed
    from repertoire.diagrams.soccer_dribble import (
        DribbleScenario,
        dribble_simulator,
        dribble_status,
        robot_and_ball,
    )
    from repertoire.systems.go_to_pose import ActionStatus

    config.validate()
    t0 = time.perf_counter()
    start, goal = sample_parameters(config, seed)
    scenario = DribbleScenario(
        initial_pose=start[:3],
        target=goal,
        time_step=config.time_step,
        control_period=config.control_period,
        gains=dict(config.gains),
    )
    diagram, simulator = dribble_simulator(scenario, reuse=config.reuse_diagram)
    context = simulator.get_mutable_context()
    set_initial_speed(diagram, context, start[3])
    set_ball_velocity(
        diagram, context, start[3] * math.cos(start[2]), start[3] * math.sin(start[2])
    )
    ball = scenario.ball_xy()
    states: list[float] = []
    next_state_time = [0.0]

    action = diagram.GetSubsystemByName("dribble_ball")
    status_port = action.get_status_output_port()
    action_context = action.GetMyContextFromRoot(context)

    def monitor(root_context) -> EventStatus:
        if len(states) < 6 * config.n_states and root_context.get_time() >= next_state_time[0]:
            s, b = robot_and_ball(diagram, root_context)
            states.extend(float(v) for v in (*s, *b))
            next_state_time[0] += config.state_period
        if status_port.Eval(action_context) != ActionStatus.RUNNING:
            return EventStatus.ReachedTermination(None, "action finished")
        return EventStatus.Succeeded()

    simulator.set_monitor(monitor)
    simulator.Initialize()  # the monitor sees the start state
    timeout = action.gains(action_context)["timeout"]
    simulator.AdvanceTo(timeout + 1.0)
    status = dribble_status(diagram, context)
    return DribbleRecord(
        *start,
        float(ball[0]),
        float(ball[1]),
        *goal,
        duration=float(context.get_time()),
        status=status.name,
        lost_ball=status == ActionStatus.FAILED,
        failed=status != ActionStatus.SUCCEEDED,
        states=states,
        wall_time_s=time.perf_counter() - t0,
    )


def set_ball_velocity(diagram, context, vx: float, vy: float) -> None:
    """Gives the ball a rolling velocity ``[vx, vy]`` in ``context``."""
    from pydrake.multibody.math import SpatialVelocity
    from repertoire.diagrams.soccer_dribble import BALL_RADIUS

    plant = diagram.GetSubsystemByName("plant")
    pc = plant.GetMyMutableContextFromRoot(context)
    # rolling without slipping: omega = z x v / r
    w = np.array([-vy, vx, 0.0]) / BALL_RADIUS
    plant.SetFreeBodySpatialVelocity(
        pc, plant.GetBodyByName("ball"), SpatialVelocity(w, [vx, vy, 0.0])
    )


def summarize(
    records: list[DribbleRecord], config: DribbleEpisodesConfig, out_dir: Path
) -> dict[str, Path]:
    """Table 1 row and ball-loss tree (Markdown), learning curves and a polar plot.

    Returns:
        Paths by name (nothing is fitted below ``min_records()`` succeeded episodes).
    """
    from repertoire.studies._action_tables import summarize_action_study

    n_done = sum(r.status == "SUCCEEDED" for r in records)
    n_lost = sum(r.lost_ball for r in records)
    n_timeout = sum(r.status == "TIMED_OUT" for r in records)
    return summarize_action_study(
        "actions_dribble",
        "dribbleBall (soccer, sim)",
        records,
        out_dir,
        lambda r: r.status == "SUCCEEDED",
        FEATURE_FUNCS,
        PAPER_DRIBBLE,
        "ball lost",
        f"DribbleBall: learning curves ({sum(r.failed for r in records)} failed of {len(records)})",
        preamble=f"{len(records)} episodes: {n_done} succeeded, {n_lost} lost the ball, "
        f"{n_timeout} timed out.\n",
        polar_title="DribbleBall: predicted duration (s, radial)\n"
        "by start direction, goal facing 0°",
    )


def demo_config() -> DribbleEpisodesConfig:
    """The demo config (the defaults)."""
    return DribbleEpisodesConfig()


def smoke_config() -> DribbleEpisodesConfig:
    """A tiny config for tests: short dribbles."""
    return DribbleEpisodesConfig(goal_distance_range=[0.4, 0.6], v_range=[0.0, 0.0])


register_study(
    "actions_dribble",
    config_type=DribbleEpisodesConfig,
    record_type=DribbleRecord,
    run_episode=run_episode,
    description="DribbleBall episodes on the soccer field: duration model tree, ball-loss tree",
    summarize=summarize,
    demo_config=demo_config,
    demo_episodes=40,
    smoke_config=smoke_config,
).run_if_main(__name__)
