"""Kitchen GoToPose and Reach episodes: learn their durations (Table 1's kitchen rows).

Each episode (Stulp & Beetz, section 5.1) runs one action of the kitchen robot
(``kitchen_action`` world), alternating by seed over ``config.actions``:

- ``goto_pose``: a start ``[x, y, phi, v]`` and a goal ``[x_g, y_g, phi_g, v_g]``
  sampled uniformly from the config's ranges, resampled until neither the
  start nor the goal footprint overlaps a table, the counter or a wall (the
  straight-driving controller may still run into furniture on its way: such
  episodes time out and are failures);
- ``reach``: the robot stands still; the arm starts at joints sampled from the
  config's joint ranges and reaches for a gripper target that is the forward
  kinematics of other sampled joints (so always within reach).

The record holds the action, the start and goal parameters, the duration until
the status left RUNNING, the status, the failure flag (anything but SUCCEEDED,
or the chassis touched furniture) and the first ``n_states`` states (chassis
``[x, y, phi, v]`` for goto_pose, gripper ``[ax, ay, az]`` for reach).

``summarize`` fits a duration model tree per action on 3/4 of the succeeded
episodes with the kitchen features of Table 7 (``fit_action_model``), and for
reach also with the arm's joint displacements added (our arm is cylindrical:
its duration is set by the turn, extension and lift, see
``kitchen_reach_arm_features``); it writes Table 1's kitchen rows beside the
paper's numbers, goToPose's failure tree (furniture contact) and a
learning-curve figure per action.

Run it with ``python -m repertoire.studies.actions_kitchen --help``.
"""

import dataclasses
import math
import time
from pathlib import Path

import numpy as np
from repertoire.planning.action_models.kitchen_features import (
    KITCHEN_GOTO_FEATURES,
    KITCHEN_REACH_ARM_FEATURES,
    KITCHEN_REACH_FEATURES,
    kitchen_goto_features,
    kitchen_reach_arm_features,
    kitchen_reach_features,
)
from repertoire.studies.engine import register_study

from repertoire.checks import check_range
from repertoire.errors import RepertoireError

ACTIONS = ("goto_pose", "reach")
#: Table 1 of Stulp & Beetz, kitchen rows: (3/4 n_e, mean duration [s], MAE [s]).
PAPER_TABLE1 = {"goto_pose": (2200, 9.0, 0.52), "reach": (2200, 2.6, 0.10)}
PAPER_NAMES = {"goto_pose": "goToPose", "reach": "reach"}


@dataclasses.dataclass
class KitchenEpisodesConfig:
    """Sampling ranges and simulation settings of the kitchen episodes.

    Attributes:
        actions: the actions to alternate over (by seed).
        x_range: start and goal x range [m] (the room is x in [-4, 4]).
        y_range: start and goal y range [m] (the room is y in [-3, 3]).
        v_range: start speed range [m/s].
        v_g_range: goal speed range [m/s], within GoToPose's v_max 0.8 (it judges the
            arrival speed within max(0.1, v_g / 2) of v_g; a goal it reaches too slowly
            costs a run-up: see ``repertoire.systems.go_to_pose``).
        lift_range: reach joint range of the lift [m] (start and goal).
        yaw_range: reach joint range of the arm yaw [rad].
        extend_range: reach joint range of the extension [m].
        n_states: intermediate states kept per episode.
        state_period: time between kept states [s].
        goto_time_step: plant step of goto_pose episodes [s].
        reach_time_step: plant step of reach episodes [s].
        goto_timeout: GoToPose time limit [s].
        cups: the cups of kitchen.sdf in the world (``KITCHEN_CUPS`` names). None by
            default: reach episodes stand at the origin, over 2 m from every cup, and
            a goto_pose robot meets furniture before its tucked fingers reach a cup
            (they could only graze a cup's top, 1 cm lower, while the chassis drives
            under a table); each cup costs six velocities and a contact in every step.
        reuse_diagram: build the world once per worker process and reset it for each
            episode (False: build it for every episode, the old way; for benchmarks).
    """

    actions: list[str] = dataclasses.field(default_factory=lambda: list(ACTIONS))
    x_range: list[float] = dataclasses.field(default_factory=lambda: [-3.4, 3.4])
    y_range: list[float] = dataclasses.field(default_factory=lambda: [-2.4, 2.4])
    v_range: list[float] = dataclasses.field(default_factory=lambda: [0.0, 0.3])
    v_g_range: list[float] = dataclasses.field(default_factory=lambda: [0.0, 0.1])
    lift_range: list[float] = dataclasses.field(default_factory=lambda: [0.35, 0.75])
    yaw_range: list[float] = dataclasses.field(default_factory=lambda: [-1.5, 1.5])
    extend_range: list[float] = dataclasses.field(default_factory=lambda: [0.3, 0.8])
    n_states: int = 5
    state_period: float = 0.2
    goto_time_step: float = 1e-2
    reach_time_step: float = 1e-2
    goto_timeout: float = 20.0
    cups: list[str] = dataclasses.field(default_factory=list)
    reuse_diagram: bool = True

    def validate(self) -> None:
        """Raises RepertoireError naming the first bad field."""
        from repertoire.models.diffdrive.generate import EXTEND_RANGE, LIFT_RANGE, YAW_RANGE

        if not self.actions or any(a not in ACTIONS for a in self.actions):
            raise RepertoireError(
                f"actions must be a non-empty list of {ACTIONS}, got {self.actions}"
            )
        bounds = {
            "x_range": (-3.6, 3.6),
            "y_range": (-2.6, 2.6),
            "v_range": (0.0, 0.8),
            "v_g_range": (0.0, 0.8),
            "lift_range": LIFT_RANGE,
            "yaw_range": YAW_RANGE,
            "extend_range": EXTEND_RANGE,
        }
        for name, within in bounds.items():
            check_range(name, getattr(self, name), within)
        if self.n_states < 0 or not (self.state_period > 0):
            raise RepertoireError("n_states must be >= 0 and state_period > 0")
        for name in ("goto_time_step", "reach_time_step"):
            if not (0 < getattr(self, name) <= 0.01):
                raise RepertoireError(f"{name} must be in (0, 0.01] s, got {getattr(self, name)}")
        from repertoire.diagrams.kitchen import KITCHEN_CUPS

        if any(c not in KITCHEN_CUPS for c in self.cups) or len(set(self.cups)) < len(self.cups):
            raise RepertoireError(f"cups must be distinct names of {KITCHEN_CUPS}, got {self.cups}")
        if not (self.goto_timeout > 0 and math.isfinite(self.goto_timeout)):
            raise RepertoireError(f"goto_timeout must be finite and > 0, got {self.goto_timeout}")


@dataclasses.dataclass
class KitchenRecord:
    """One kitchen episode.

    Attributes:
        action: ``goto_pose`` or ``reach``.
        start: goto_pose ``[x, y, phi, v]``; reach: gripper ``[ax, ay, az]`` (chassis frame).
        goal: goto_pose ``[x_g, y_g, phi_g, v_g]``; reach: gripper target ``[ax, ay, az]``.
        duration: time until the status left RUNNING [s].
        status: the final ActionStatus name (RUNNING: stopped when it touched furniture).
        touched_furniture: the chassis or arm touched a table, the counter or a wall.
        failed: not SUCCEEDED, or touched furniture.
        states: the first ``n_states`` states, flattened.
        wall_time_s: wall time of the episode (timing field).
    """

    action: str
    start: list[float]
    goal: list[float]
    duration: float
    status: str
    touched_furniture: bool
    failed: bool
    states: list[float]
    wall_time_s: float


def action_of(config: KitchenEpisodesConfig, seed: int) -> str:
    """The action episode ``seed`` runs: ``config.actions`` in turn."""
    return config.actions[seed % len(config.actions)]


def sample_parameters(config: KitchenEpisodesConfig, seed: int) -> tuple[str, list, list]:
    """Seeded ``(action, start, goal)`` of an episode (see the module docstring)."""
    from repertoire.diagrams.kitchen import KITCHEN_OBSTACLES, ROBOT_RADIUS
    from repertoire.systems.kitchen_actions import arm_forward, footprint_hits

    action = action_of(config, seed)
    rng = np.random.default_rng(seed)
    if action == "reach":
        ranges = (config.lift_range, config.yaw_range, config.extend_range)
        q0 = [rng.uniform(*r) for r in ranges]
        q1 = [rng.uniform(*r) for r in ranges]
        return action, [float(v) for v in arm_forward(q0)], [float(v) for v in arm_forward(q1)]
    points = []
    for _ in range(2):
        for _ in range(1000):
            xy = [rng.uniform(*config.x_range), rng.uniform(*config.y_range)]
            if footprint_hits(xy, KITCHEN_OBSTACLES, ROBOT_RADIUS + 0.05) < 0:
                break
        else:
            raise RepertoireError("no free start/goal in the x/y ranges: widen them")
        points.append(xy)
    start = [*points[0], rng.uniform(-math.pi, math.pi), rng.uniform(*config.v_range)]
    goal = [*points[1], rng.uniform(-math.pi, math.pi), rng.uniform(*config.v_g_range)]
    return action, [float(v) for v in start], [float(v) for v in goal]


def run_episode(config: KitchenEpisodesConfig, seed: int) -> KitchenRecord:
    """Runs one kitchen episode."""
    from pydrake.systems.framework import EventStatus
    from repertoire.diagrams.kitchen import (
        KitchenScenario,
        action_status,
        furniture_and_robot_bodies,
        gripper_position,
        kitchen_simulator,
        touches,
        world_to_chassis,
    )
    from repertoire.diagrams.soccer import robot_state, set_initial_speed
    from repertoire.systems.go_to_pose import ActionStatus
    from repertoire.systems.kitchen_actions import arm_inverse

    config.validate()
    t0 = time.perf_counter()
    action, start, goal = sample_parameters(config, seed)
    if action == "goto_pose":
        scenario = KitchenScenario(
            action="goto_pose",
            initial_pose=start[:3],
            goto_target=goal,
            time_step=config.goto_time_step,
            gains={"timeout": config.goto_timeout},
            cups=list(config.cups),
        )
        limit = config.goto_timeout + 0.1
    else:
        scenario = KitchenScenario(
            action="reach",
            initial_pose=[0.0, 0.0, 0.0],
            initial_arm=list(arm_inverse(start)),
            arm_target=goal,
            time_step=config.reach_time_step,
            cups=list(config.cups),
        )
        limit = 10.0
    diagram, simulator = kitchen_simulator(scenario, reuse=config.reuse_diagram)
    plant = diagram.GetSubsystemByName("plant")
    furniture, robot = furniture_and_robot_bodies(plant)
    context = simulator.get_mutable_context()
    if action == "goto_pose":
        set_initial_speed(diagram, context, start[3])
    plant_context = plant.GetMyContextFromRoot(context)
    touched, states, next_time = [False], [], [0.0]
    width = 4 if action == "goto_pose" else 3
    # ports and subcontexts looked up once, not on every step
    contact_port = plant.get_contact_results_output_port()
    status_system = diagram.GetSubsystemByName("action")
    status_port = status_system.get_status_output_port()
    status_context = status_system.GetMyContextFromRoot(context)

    def monitor(root_context) -> EventStatus:
        if touches(contact_port.Eval(plant_context), furniture, robot):
            touched[0] = True
        if len(states) < width * config.n_states and root_context.get_time() >= next_time[0]:
            if action == "goto_pose":
                states.extend(float(s) for s in robot_state(diagram, root_context))
            else:
                base = robot_state(diagram, root_context)
                states.extend(
                    float(s)
                    for s in world_to_chassis(base, gripper_position(diagram, root_context))
                )
            next_time[0] += config.state_period
        if status_port.Eval(status_context) != ActionStatus.RUNNING:
            return EventStatus.ReachedTermination(None, "action finished")
        if touched[0]:
            return EventStatus.ReachedTermination(None, "touched furniture: a failure")
        if root_context.get_time() >= limit:
            return EventStatus.ReachedTermination(None, "episode time limit")
        return EventStatus.Succeeded()

    simulator.set_monitor(monitor)
    simulator.Initialize()  # the monitor sees the start state
    simulator.AdvanceTo(limit + 1.0)
    status = action_status(diagram, context)
    if status == ActionStatus.RUNNING and not touched[0]:
        status = ActionStatus.TIMED_OUT  # the episode's time limit
    return KitchenRecord(
        action=action,
        start=start,
        goal=goal,
        duration=float(context.get_time()),
        status=status.name,
        touched_furniture=bool(touched[0]),
        failed=bool(touched[0] or status != ActionStatus.SUCCEEDED),
        states=states,
        wall_time_s=time.perf_counter() - t0,
    )


def _feature_funcs(function, names) -> dict:
    """Feature name -> function of a record, for a feature function of (start, goal)."""
    return {
        name: (lambda r, j=j: float(function(r.start, r.goal)[j])) for j, name in enumerate(names)
    }


#: Feature functions by model: goToPose and reach with Table 7's features, and reach
#: with Table 7's plus the arm's joint displacements (``reach_arm``).
FEATURE_FUNCS = {
    "goto_pose": _feature_funcs(kitchen_goto_features, KITCHEN_GOTO_FEATURES),
    "reach": _feature_funcs(kitchen_reach_features, KITCHEN_REACH_FEATURES),
    "reach_arm": _feature_funcs(kitchen_reach_features, KITCHEN_REACH_FEATURES)
    | _feature_funcs(kitchen_reach_arm_features, KITCHEN_REACH_ARM_FEATURES),
}


def summarize(
    records: list[KitchenRecord], config: KitchenEpisodesConfig, out_dir: Path
) -> dict[str, Path]:
    """Fits duration model trees per action; writes Table 1's kitchen rows and learning curves.

    Reach is fitted twice: with Table 7's Cartesian features and with the arm's
    joint displacements added. goToPose also gets a failure tree (furniture
    contact or not succeeded; the paper gives none for the kitchen).

    Returns:
        Paths by name (an action with too few succeeded episodes gets a row saying so).
    """
    from repertoire.planning.action_models import fit_action_model
    from repertoire.studies._action_tables import (
        failure_table,
        learning_curve_figure,
        min_records,
    )

    out_dir = Path(out_dir)
    need = min_records()
    md = [
        "## Table 1, kitchen rows: duration models (MAE on the held-out quarter)",
        "",
        "| action | episodes (ours, all / succeeded; 3/4 train) | failed | mean duration (s) "
        "ours | MAE (s) ours | 3/4 n_e paper | mean duration (s) paper | MAE (s) paper |",
        "|---|---|---|---|---|---|---|---|",
    ]
    rules, failure, paths = [], [], {}
    for action in config.actions:
        recs = [r for r in records if r.action == action]
        done = [r for r in recs if not r.failed]
        paper = PAPER_TABLE1[action]
        mean = f"{np.mean([r.duration for r in done]):.2f}" if done else "-"
        variants = [(f"{PAPER_NAMES[action]} (kitchen)", FEATURE_FUNCS[action])]
        if action == "reach":
            variants.append(("reach (kitchen), + arm features", FEATURE_FUNCS["reach_arm"]))
        for label, funcs in variants:
            train, mae = "", f"too few ({len(done)} succeeded; at least {need} needed)"
            if len(done) >= need:
                fitted = fit_action_model(done, funcs, "duration")
                train, mae = f"; {fitted.n_train}", f"{fitted.mae:.3f}"
                rules += [f"### {label}", "", "```", fitted.model.rules(), "```", ""]
            md.append(
                f"| {label} | {len(recs)} / {len(done)}{train} | {len(recs) - len(done)} | {mean} "
                f"| {mae} | {paper[0]} | {paper[1]} | {paper[2]} |"
            )
        if action == "goto_pose" and len(recs) >= need:
            failure, _ = failure_table(
                recs,
                FEATURE_FUNCS[action],
                "Failure tree of kitchen goToPose (furniture contact or not succeeded; the "
                "paper has none), held-out quarter",
            )
        if len(done) >= need:
            more = ("+ arm features", FEATURE_FUNCS["reach_arm"]) if action == "reach" else None
            paths[f"learning_curves_{action}"] = learning_curve_figure(
                recs,
                lambda r: not r.failed,
                FEATURE_FUNCS[action],
                paper[2],
                f"Kitchen {PAPER_NAMES[action]}: learning curves ({len(recs) - len(done)} "
                f"failed of {len(recs)})",
                out_dir / f"actions_kitchen_{action}_learning_curves.png",
                more_features=more,
            )
    md += ["", *failure, "", "## Duration tree rules", "", *rules]
    tables = out_dir / "actions_kitchen_tables.md"
    tables.write_text("\n".join(md) + "\n")
    return {"tables": tables, **paths}


def demo_config() -> KitchenEpisodesConfig:
    """The demo config (the defaults)."""
    return KitchenEpisodesConfig()


def smoke_config() -> KitchenEpisodesConfig:
    """A tiny config for tests: a small free region, short reaches."""
    return KitchenEpisodesConfig(
        x_range=[-1.0, 0.0], y_range=[-1.0, 0.0], lift_range=[0.5, 0.6], yaw_range=[-0.3, 0.3]
    )


register_study(
    "actions_kitchen",
    config_type=KitchenEpisodesConfig,
    record_type=KitchenRecord,
    run_episode=run_episode,
    description="kitchen GoToPose and Reach episodes: duration model trees (Table 1 kitchen rows)",
    summarize=summarize,
    demo_config=demo_config,
    demo_episodes=120,
    smoke_config=smoke_config,
).run_if_main(__name__)
