"""Two-joint Reach episodes on arm7: learn the reaching duration (Table 1, arm control).

Each episode (Stulp & Beetz, section 5.1) samples a start
``[theta^a, thetadot^a, theta^b, thetadot^b]`` and a goal
``[theta_g^a, thetadot_g^a, theta_g^b, thetadot_g^b]`` (shoulder_flexion and
elbow, Table 6) uniformly from the config's ranges, and runs the ``arm_reach``
world until the action's status leaves RUNNING. The record holds the
parameters, the duration, the failure flag (not succeeded) and the first
``n_states`` joint states. The features are Table 7's arm-control ones
(:func:`~repertoire.planning.action_models.arm_reach_features`).

Run it with ``python -m repertoire.studies.actions_arm_reach --help``.
"""

import dataclasses
import time
from pathlib import Path

import numpy as np
from repertoire.planning.action_models.features import ARM_REACH_FEATURES, arm_reach_features
from repertoire.studies.engine import register_study

from repertoire.checks import check_range
from repertoire.errors import RepertoireError

PAPER_REACH = {"episodes": 1100, "mean": 2.9, "mae": 0.21}  # Table 1, arm control
LIMITS = {"a": (-0.9, 2.8), "b": (0.0, 2.6)}  # arm7 shoulder_flexion, elbow [rad]


@dataclasses.dataclass
class ReachEpisodesConfig:
    """Sampling ranges and simulation settings of the Reach episodes.

    Attributes:
        theta_a_range: start and goal range of joint a (shoulder_flexion) [rad].
        theta_b_range: start and goal range of joint b (elbow) [rad].
        speed_range: start and goal velocity range of each joint [rad/s].
        n_states: intermediate states kept per episode.
        state_period: time between kept states [s].
        time_step: plant step [s].
        control_period: Reach update period [s].
        gains: Reach gain overrides.
    """

    theta_a_range: list[float] = dataclasses.field(default_factory=lambda: [-0.3, 1.8])
    theta_b_range: list[float] = dataclasses.field(default_factory=lambda: [0.3, 2.3])
    speed_range: list[float] = dataclasses.field(default_factory=lambda: [-0.4, 0.4])
    n_states: int = 5
    state_period: float = 0.2
    time_step: float = 5e-3
    control_period: float = 0.01
    gains: dict[str, float] = dataclasses.field(default_factory=dict)

    def validate(self) -> None:
        """Raises RepertoireError naming the first bad field."""
        for name in ("theta_a_range", "theta_b_range", "speed_range"):
            check_range(name, getattr(self, name))
        for name, key in (("theta_a_range", "a"), ("theta_b_range", "b")):
            lo, hi = LIMITS[key]
            r = getattr(self, name)
            if r[0] < lo or r[1] > hi:
                raise RepertoireError(f"{name} {r} must lie in the joint limits [{lo}, {hi}]")
        if self.n_states < 0 or self.state_period <= 0:
            raise RepertoireError("n_states >= 0, state_period > 0")


@dataclasses.dataclass
class ReachRecord:
    """One Reach episode.

    Attributes:
        theta_a: start angle of joint a [rad].
        thetadot_a: start speed of joint a [rad/s].
        theta_b: start angle of joint b [rad].
        thetadot_b: start speed of joint b [rad/s].
        theta_g_a: goal angle of joint a [rad].
        thetadot_g_a: goal speed of joint a [rad/s].
        theta_g_b: goal angle of joint b [rad].
        thetadot_g_b: goal speed of joint b [rad/s].
        duration: time until the status left RUNNING [s].
        status: the final ActionStatus name.
        failed: the action did not succeed.
        states: the first ``n_states`` of ``[theta^a, thetadot^a, theta^b, thetadot^b]``.
        wall_time_s: wall time of the episode (timing field).
    """

    theta_a: float
    thetadot_a: float
    theta_b: float
    thetadot_b: float
    theta_g_a: float
    thetadot_g_a: float
    theta_g_b: float
    thetadot_g_b: float
    duration: float
    status: str
    failed: bool
    states: list[float]
    wall_time_s: float


def sample_parameters(config: ReachEpisodesConfig, seed: int) -> tuple[list[float], list[float]]:
    """Seeded start and goal ``[theta^a, thetadot^a, theta^b, thetadot^b]``."""
    rng = np.random.default_rng(seed)

    def draw() -> list[float]:
        return [
            float(rng.uniform(*config.theta_a_range)),
            float(rng.uniform(*config.speed_range)),
            float(rng.uniform(*config.theta_b_range)),
            float(rng.uniform(*config.speed_range)),
        ]

    return draw(), draw()


def run_episode(config: ReachEpisodesConfig, seed: int) -> ReachRecord:
    """Runs one Reach episode on arm7."""
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import EventStatus
    from repertoire.diagrams.arm_reach import (
        ReachScenario,
        build_arm_reach,
        joint_state,
        reach_status,
        set_start_velocity,
    )
    from repertoire.systems.go_to_pose import ActionStatus

    config.validate()
    t0 = time.perf_counter()
    start, goal = sample_parameters(config, seed)
    diagram = build_arm_reach(
        ReachScenario(
            start=start,
            target=goal,
            time_step=config.time_step,
            control_period=config.control_period,
            gains=dict(config.gains),
        )
    )
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    set_start_velocity(diagram, context, start[1], start[3])
    states: list[float] = []
    next_state_time = [0.0]

    def monitor(root_context) -> EventStatus:
        if len(states) < 4 * config.n_states and root_context.get_time() >= next_state_time[0]:
            states.extend(float(v) for v in joint_state(diagram, root_context))
            next_state_time[0] += config.state_period
        if reach_status(diagram, root_context) != ActionStatus.RUNNING:
            return EventStatus.ReachedTermination(None, "action finished")
        return EventStatus.Succeeded()

    simulator.set_monitor(monitor)
    reach = diagram.GetSubsystemByName("reach")
    simulator.AdvanceTo(reach.gains(reach.GetMyContextFromRoot(context))["timeout"] + 1.0)
    status = reach_status(diagram, context)
    return ReachRecord(
        *start,
        *goal,
        duration=float(context.get_time()),
        status=status.name,
        failed=status != ActionStatus.SUCCEEDED,
        states=states,
        wall_time_s=time.perf_counter() - t0,
    )


def _params(r: ReachRecord) -> tuple[list[float], list[float]]:
    start = [r.theta_a, r.thetadot_a, r.theta_b, r.thetadot_b]
    return start, [r.theta_g_a, r.thetadot_g_a, r.theta_g_b, r.thetadot_g_b]


FEATURE_FUNCS = {
    name: (lambda r, j=j: float(arm_reach_features(*_params(r))[j]))
    for j, name in enumerate(ARM_REACH_FEATURES)
}


def summarize(
    records: list[ReachRecord], config: ReachEpisodesConfig, out_dir: Path
) -> dict[str, Path]:
    """Table 1 row (Markdown) and learning curves.

    Returns:
        Paths by name (nothing is fitted below ``min_records()`` succeeded episodes).
    """
    from repertoire.studies._action_tables import summarize_action_study

    return summarize_action_study(
        "actions_arm_reach",
        "reach (arm control, 2 joints)",
        records,
        out_dir,
        lambda r: r.status == "SUCCEEDED",
        FEATURE_FUNCS,
        PAPER_REACH,
        "not reached",
        f"Reach (arm7, 2 joints): learning curves ({sum(r.failed for r in records)} failed "
        f"of {len(records)})",
    )


def demo_config() -> ReachEpisodesConfig:
    """The demo config (the defaults)."""
    return ReachEpisodesConfig()


def smoke_config() -> ReachEpisodesConfig:
    """A tiny config for tests: short reaches from rest."""
    return ReachEpisodesConfig(
        theta_a_range=[0.4, 0.6], theta_b_range=[1.2, 1.4], speed_range=[0.0, 0.0]
    )


register_study(
    "actions_arm_reach",
    config_type=ReachEpisodesConfig,
    record_type=ReachRecord,
    run_episode=run_episode,
    description="two-joint Reach episodes on arm7: duration model tree (Table 1, arm control)",
    summarize=summarize,
    demo_config=demo_config,
    demo_episodes=40,
    smoke_config=smoke_config,
).run_if_main(__name__)
