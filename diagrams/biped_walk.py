"""The biped executing a footstep plan in the physics simulation (registered as ``biped_walk``).

Wiring: ``FootstepPlanSource`` (the plan) -> :class:`CommandStepper` (the controller's
stateful stepping rule turns the plan's *commands* into footsteps) -> :class:`ZmpComPlanner` (ZMP
reference and Drake's ``ZmpPlanner`` CoM) and :class:`SwingFootPlanner` (sole
trajectories) -> :class:`WalkingIK` (CoM-exact pelvis placement + closed-form
leg IK) -> the plant's ``desired_state`` input (joint PD in the discrete solver).
"""

import dataclasses
from pathlib import Path

import numpy as np
from pydrake.geometry import Box
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Context, Diagram, DiagramBuilder
from repertoire.diagrams.biped import add_biped_world, validate_plant_fields
from repertoire.diagrams.registry import register_diagram
from repertoire.models.biped import LEARNED_TABLE_PATH, LegGains
from repertoire.planning.footstep.actions import ACTIONS, apply_displacement
from repertoire.planning.footstep.types import (
    ActionTable,
    Foot,
    FootstepPlan,
    PlanStatus,
    wrap_angle,
)
from repertoire.systems.footstep_source import FootstepPlanSource
from repertoire.systems.step_feedback import (
    ComSensor,
    FootstepFeedback,
    SolePoseSensor,
    StepReach,
    check_plan_reach,
    check_stance,
)
from repertoire.systems.walking import (
    CommandStepper,
    FootstepSequence,
    SteppingRule,
    SwingFootPlanner,
    WalkingIK,
    ZmpComPlanner,
    plan_com,
    realize_commands,
    realize_plan,
    same_commands,
    standing_com_height,
    whole_body_ik,
)

from repertoire.checks import is_real, is_whole
from repertoire.criteria import Bound
from repertoire.errors import RepertoireError, ScenarioError
from repertoire.limits import require_grid_memory

#: Gains for walking: stiffer than standing so the soles track the pattern closely.
WALK_GAINS = LegGains(
    kp=[20000.0, 40000.0, 40000.0, 40000.0, 30000.0, 20000.0],
    kd=[120.0, 250.0, 250.0, 250.0, 190.0, 120.0],
)


#: The planner's deterministic node budget on a ``map_seed`` floor (and the
#: ``footstep_execution`` study's): the learned table's 49 history classes multiply the
#: lattice's states, and 60k (before session 35) left 16 of 60 unseen 2 m floors and 1 of
#: 60 3 m floors partial, 11 and 1 of them planned whole within 0.15-1.8 s (a million
#: expansions take about 2-4 s of the 10 s time limit).
PLAN_EXPANSIONS = 1_000_000


@dataclasses.dataclass
class BipedWalkScenario:
    """The biped executing footstep commands on flat ground.

    The commands come from (first that applies): ``plan_file``; a footstep plan made
    with the learned table on the random 3 m floor of ``map_seed`` (``map_seed >= 0``,
    obstacles drawn as flat red tiles); else ``actions``.

    Attributes:
        map_seed: seed of the random static floor to plan on (-1: use ``actions``).
        map_size: side of that floor [m].
        plan_expansions: the planner's node budget there (a partial plan when it runs
            out: ``plan_complete`` 0); the time limit is 10 s.
        actions: commanded actions, one per step (names from the footstep ACTIONS).
        start: ``[x, y, yaw]`` of the midpoint between the soles at the start.
        first_stance: ``left`` or ``right``: the foot that stands during the first step.
        plan_file: optional JSON ``FootstepPlan`` to execute instead of ``actions``.
        pelvis_height: pelvis height during walking [m].
        time_step: plant time step [s].
        contact_approximation: ``lagged``, ``sap`` or ``similar``.
        ground_friction: Coulomb friction of the ground.
        max_speed_change: stepping rule: largest change of the forward step [m].
        base_duration: stepping rule: seconds per step at constant speed.
        feedback: place each step on the plan's world pose from the measured stance
            sole (:class:`FootstepFeedback`); the ``actions`` are then planned with the
            controller's own stepping rule (:func:`plan_from_rule`), not the nominal
            table. ``false``: the commands open loop (landings drift on long walks).
    """

    map_seed: int = 0
    map_size: float = 3.0
    plan_expansions: int = PLAN_EXPANSIONS
    actions: list[str] = dataclasses.field(
        default_factory=lambda: [
            "forward_long",
            "forward_long",
            "forward_long",
            "turn_left",
            "forward_medium",
            "stop",
            "stop",
        ]
    )
    start: list[float] = dataclasses.field(default_factory=lambda: [0.0, 0.0, 0.0])
    first_stance: str = "left"
    plan_file: str = ""
    pelvis_height: float = 0.60
    time_step: float = 2e-3
    contact_approximation: str = "sap"
    ground_friction: float = 1.0
    max_speed_change: float = 0.12
    base_duration: float = 1.0
    feedback: bool = True

    def validate(self) -> None:
        """Raises ScenarioError naming the first bad field."""
        for a in self.actions:
            if a not in ACTIONS:
                raise ScenarioError(f"unknown action {a!r} in actions; expected one of {ACTIONS}")
        if len(self.start) != 3 or not np.all(np.isfinite(self.start)):
            raise ScenarioError(f"start must be 3 finite values (x, y, yaw), got {self.start}")
        if self.first_stance not in ("left", "right"):
            raise ScenarioError(
                f"first_stance must be 'left' or 'right', got {self.first_stance!r}"
            )
        if self.map_seed < -1:
            raise ScenarioError(
                f"map_seed must be >= 0 (a floor) or -1 (actions), got {self.map_seed}"
            )
        if self.plan_file or self.map_seed >= 0:
            source = (
                f"plan_file '{self.plan_file}'" if self.plan_file
                else f"the plan on map_seed {self.map_seed}'s floor"
            )  # fmt: skip
            default = BipedWalkScenario()
            for name in ("actions", "start", "first_stance"):
                if getattr(self, name) != getattr(default, name):
                    raise ScenarioError(
                        f"{name} {getattr(self, name)} would be ignored: the steps come from "
                        f"{source}; set map_seed: -1 and plan_file: '' to walk the actions"
                    )
        if not (is_whole(self.plan_expansions) and self.plan_expansions >= 1):
            raise ScenarioError(
                f"plan_expansions must be an integer >= 1, got {self.plan_expansions!r}"
            )
        if self.map_seed >= 0 and not (np.isfinite(self.map_size) and self.map_size >= 1.5):
            raise ScenarioError(f"map_size must be >= 1.5 m, got {self.map_size}")
        if self.map_seed >= 0:
            require_grid_memory(self.map_size, 0.025, f"biped_walk map_size={self.map_size}")
        if self.plan_file and not Path(self.plan_file).is_file():
            raise ScenarioError(f"plan_file '{self.plan_file}' does not exist")
        validate_walk_fields(
            self.pelvis_height, self.time_step, self.contact_approximation, self.ground_friction
        )
        try:
            self.rule().validate()
        except RepertoireError as e:
            raise ScenarioError(str(e)) from e

    def rule(self) -> SteppingRule:
        """The stepping rule of this scenario."""
        return SteppingRule(
            max_speed_change=self.max_speed_change, base_duration=self.base_duration
        )


def validate_walk_fields(
    pelvis_height: float, time_step: float, contact_approximation: str, ground_friction: float
) -> None:
    """Checks the walking biped's pelvis height and plant settings.

    Raises:
        ScenarioError: naming the bad value and what is expected.
    """
    if not (np.isfinite(pelvis_height) and 0.5 <= pelvis_height <= 0.64):
        raise ScenarioError(f"pelvis_height must be in [0.5, 0.64] m, got {pelvis_height}")
    validate_plant_fields(time_step, contact_approximation, ground_friction)


def start_feet(start: list[float], first_stance: str, stance_width: float = 0.19):
    """Sole poses (stance, swing) standing at ``start`` = midpoint (x, y, yaw)."""
    x, y, yaw = start
    s = 1.0 if first_stance == "left" else -1.0
    c, sn = np.cos(yaw), np.sin(yaw)
    off = np.array([-sn, c]) * stance_width / 2
    stance = [x + s * off[0], y + s * off[1], yaw]
    swing = [x - s * off[0], y - s * off[1], yaw]
    return stance, swing


def plan_from_actions(
    actions: list[str],
    stance_pose: list[float],
    stance_foot: str,
    swing_pose: list[float],
    table: ActionTable,
    *,
    history: list[str] | None = None,
) -> FootstepPlan:
    """The plan a footstep planner would output for given commands, predicted with ``table``.

    Args:
        actions: commanded actions.
        stance_pose: ``[x, y, yaw]`` of the first stance sole.
        stance_foot: ``left`` or ``right``.
        swing_pose: the other sole.
        table: the action table used to predict landings and times.
        history: two actions before the first (default: standing).
    """
    history = list(history or [table.rest_action, table.rest_action])
    foot = Foot.LEFT if stance_foot == "left" else Foot.RIGHT
    poses, feet, times = [list(stance_pose)], [int(foot)], [0.0]
    hist = list(history)
    for a in actions:
        dx, dy, dyaw, dur = table.lookup(hist[-2], hist[-1], int(foot), a)
        poses.append(list(apply_displacement(poses[-1], (dx, dy, dyaw))))
        foot = foot.other()
        feet.append(int(foot))
        times.append(times[-1] + float(dur))
        hist.append(a)
    return FootstepPlan.from_commands(poses, feet, list(actions), times, list(swing_pose), history)


def _scenario_plan(scenario: BipedWalkScenario) -> tuple[FootstepPlan, list[list[float]]]:
    """The plan to execute and the obstacle rectangles to draw."""
    if scenario.plan_file:
        return FootstepPlan.load(scenario.plan_file), []
    if scenario.map_seed >= 0:
        from repertoire.planning.footstep.planner import PlannerOptions, plan_footsteps
        from repertoire.planning.footstep.scenes import random_static_scene

        if not LEARNED_TABLE_PATH.is_file():
            raise ScenarioError(
                f"learned footstep table {LEARNED_TABLE_PATH} missing; run the footstep_table "
                "study or set map_seed: -1"
            )
        scene = random_static_scene(scenario.map_seed, size=scenario.map_size)
        plan = plan_footsteps(
            scene.grid,
            scene.start,
            scene.start_foot,
            scene.goal,
            ActionTable.load(LEARNED_TABLE_PATH),
            PlannerOptions(time_limit=10.0, max_expansions=int(scenario.plan_expansions)),
        )
        return plan, [obstacle_cells(scene.grid)]
    from repertoire.planning.footstep.actions import nominal_action_table

    stance, swing = start_feet(scenario.start, scenario.first_stance)
    if scenario.feedback:
        plan = plan_from_rule(
            scenario.actions, stance, scenario.first_stance, swing, scenario.rule()
        )
    else:
        plan = plan_from_actions(
            scenario.actions, stance, scenario.first_stance, swing, nominal_action_table()
        )
    return plan, []


def plan_from_rule(
    actions: list[str],
    stance_pose: list[float],
    stance_foot: str,
    swing_pose: list[float],
    rule: SteppingRule,
) -> FootstepPlan:
    """The plan of ``actions`` whose poses are the steps the controller's rule makes of them.

    With feedback the walker places each step on the plan's pose, so a plan of commands
    to walk must hold the steps this controller takes for them (the nominal table's
    commanded displacements differ by up to 0.18 m from standing).

    Args:
        actions: commanded actions.
        stance_pose: ``[x, y, yaw]`` of the first stance sole.
        stance_foot: ``left`` or ``right``.
        swing_pose: the other sole.
        rule: the stepping rule.
    """
    foot = Foot.LEFT if stance_foot == "left" else Foot.RIGHT
    seq = realize_commands(np.asarray(stance_pose, float), foot, np.asarray(swing_pose, float),
                           list(actions), rule)  # fmt: skip
    feet = [int(foot)] + list(seq.swing_feet)
    times = [0.0] + [t - seq.command_times[0] for t in seq.land_times] if actions else [0.0]
    return FootstepPlan.from_commands(
        [list(stance_pose)] + [list(p) for p in seq.poses],
        feet,
        list(actions),
        times,
        list(swing_pose),
        ["stop", "stop"],
    )


def check_start_stance(
    left: np.ndarray, right: np.ndarray, com: np.ndarray, pelvis_height: float
) -> None:
    """:func:`~repertoire.systems.step_feedback.check_stance` of the start soles.

    The robot is placed on the plan's start soles (its first two poses); a start it
    cannot stand on would otherwise be simulated anyway (the walking IK does not stop).

    Args:
        left: left sole ``[x, y, yaw]`` (or ``[x, y, z, yaw]``).
        right: right sole, the same form.
        com: desired CoM ``(x, y)`` at the start.
        pelvis_height: pelvis height [m].

    Raises:
        RepertoireError: naming both soles (rounded to 0.1 mm / 0.1 mrad) and what is
            wrong.
    """
    check_stance(left, right, com, pelvis_height, what="start soles")


def build_walk_diagram(
    plan: FootstepPlan,
    *,
    rule: SteppingRule | None = None,
    pelvis_height: float = 0.60,
    time_step: float = 2e-3,
    contact_approximation: str = "sap",
    ground_friction: float = 1.0,
    obstacles: list[list[float]] | None = None,
    meshcat=None,
    name: str = "biped_walk",
    feedback: bool = False,
    reach: StepReach | None = None,
    com_gain: float = 0.0,
) -> Diagram:
    """Builds the biped executing ``plan``'s commands.

    Open loop (``feedback=False``) the controller takes the steps the stepping rule makes
    of the commands from the plan's start, however the robot has moved (how the footstep
    table was measured); the landings drift in the world over long plans. With
    ``feedback=True`` a :class:`FootstepFeedback` retargets each step at its lift-off
    from the measured stance sole to the plan's world pose (see
    :mod:`repertoire.systems.step_feedback`); every step of the plan is checked to be
    within ``reach`` of its command first.

    Args:
        plan: the footstep plan (its start poses place the robot; its actions are the commands).
        rule: the controller's stepping rule.
        pelvis_height: pelvis height during walking [m].
        time_step: plant time step [s].
        contact_approximation: ``lagged``, ``sap`` or ``similar``.
        ground_friction: Coulomb friction of the ground.
        obstacles: optional flat obstacles as ``[x_min, y_min, x_max, y_max]`` drawn as
            thin visual-only tiles (the robot steps over them; they have no collision).
        meshcat: optional Meshcat instance for a visualizer.
        name: the Diagram's name.
        feedback: place each step on the plan's world pose from the measured stance sole.
        reach: with ``feedback``, how far a step may differ from its command's.
        com_gain: CoM feedback gain of the leg IK (:class:`WalkingIK`; 0: none). 1 cut
            the largest touch-down lateness of learned-table plans 0.21-0.24 -> 0.12-0.17 s
            (session 37; not on every walk), but the learned table was measured without it.

    Raises:
        RepertoireError: bad settings, start soles the biped cannot stand on, or with
            ``feedback`` a plan step out of ``reach`` (:func:`check_plan_reach`).

    Returns:
        The Diagram with subsystems ``plant``, ``plan_source`` (``FootstepPlanSource``),
        ``command_stepper`` (and with ``feedback`` ``sole_sensor`` and ``step_feedback``),
        ``zmp_com_planner``, ``swing_foot_planner`` and ``walking_ik``.
    """
    validate_walk_fields(pelvis_height, time_step, contact_approximation, ground_friction)
    rule = rule or SteppingRule()
    seq = realize_plan(plan, rule)
    com_height = standing_com_height(pelvis_height)
    planner = plan_com(seq, com_height)
    from repertoire.systems.walking import foot_poses_at

    left, right, _ = foot_poses_at(seq, 0.0)
    check_start_stance(left, right, planner.get_nominal_com(0.0).ravel(), pelvis_height)
    if feedback:
        check_plan_reach(plan, rule, reach or StepReach(), pelvis_height)
    q0, pelvis0 = whole_body_ik(planner.get_nominal_com(0.0).ravel(), left, right, pelvis_height)
    builder = DiagramBuilder()
    X_WP = RigidTransform(RollPitchYaw(0.0, 0.0, pelvis0[3]), pelvis0[:3])
    plant, scene_graph, instance = add_biped_world(
        builder,
        time_step=time_step,
        contact_approximation=contact_approximation,
        gains=WALK_GAINS,
        ground_friction=ground_friction,
        q_joints=q0,
        pelvis_height=pelvis_height,
        X_WP=X_WP,
        extra=lambda p: _add_obstacle_tiles(p, obstacles or []),
    )
    source = builder.AddSystem(FootstepPlanSource(plan))
    source.set_name("plan_source")
    stepper = builder.AddSystem(CommandStepper(rule))
    stepper.set_name("command_stepper")
    zmp = builder.AddSystem(ZmpComPlanner(com_height))
    zmp.set_name("zmp_com_planner")
    swing = builder.AddSystem(SwingFootPlanner())
    swing.set_name("swing_foot_planner")
    ik = builder.AddSystem(WalkingIK(pelvis_height, com_gain=com_gain))
    ik.set_name("walking_ik")
    if com_gain > 0.0:
        com_sensor = builder.AddSystem(ComSensor(plant, instance))
        com_sensor.set_name("com_sensor")
        builder.Connect(plant.get_state_output_port(), com_sensor.GetInputPort("state"))
        builder.Connect(com_sensor.GetOutputPort("com"), ik.GetInputPort("measured_com"))
    builder.Connect(source.GetOutputPort("plan"), stepper.GetInputPort("plan"))
    footsteps = stepper.GetOutputPort("footsteps")
    if feedback:
        sensor = builder.AddSystem(SolePoseSensor(plant, instance))
        sensor.set_name("sole_sensor")
        corrector = builder.AddSystem(FootstepFeedback(plan.num_steps, pelvis_height, reach=reach))
        corrector.set_name("step_feedback")
        builder.Connect(plant.get_body_poses_output_port(), sensor.GetInputPort("body_poses"))
        builder.Connect(sensor.GetOutputPort("soles"), corrector.GetInputPort("soles"))
        builder.Connect(source.GetOutputPort("plan"), corrector.GetInputPort("plan"))
        builder.Connect(footsteps, corrector.GetInputPort("footsteps"))
        footsteps = corrector.GetOutputPort("footsteps")
    builder.Connect(footsteps, zmp.GetInputPort("footsteps"))
    builder.Connect(footsteps, swing.GetInputPort("footsteps"))
    builder.Connect(zmp.GetOutputPort("com"), ik.GetInputPort("com"))
    builder.Connect(swing.GetOutputPort("left_foot"), ik.GetInputPort("left_foot"))
    builder.Connect(swing.GetOutputPort("right_foot"), ik.GetInputPort("right_foot"))
    builder.Connect(ik.GetOutputPort("desired_state"), plant.get_desired_state_input_port(instance))
    if meshcat is not None:
        from pydrake.geometry import MeshcatVisualizer

        MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat)
    diagram = builder.Build()
    diagram.set_name(name)
    return diagram


def obstacle_cells(grid) -> list[list[float]]:
    """Occupied cells of an occupancy grid as ``[x_min, y_min, x_max, y_max]`` rectangles.

    Runs of occupied cells along y in each column are merged into one rectangle.
    """
    rects = []
    r = grid.resolution
    x0, y0 = grid.origin
    occ = grid.occupied
    for ix in range(occ.shape[0]):
        iy = 0
        while iy < occ.shape[1]:
            if occ[ix, iy]:
                start = iy
                while iy < occ.shape[1] and occ[ix, iy]:
                    iy += 1
                rects.append([x0 + ix * r, y0 + start * r, x0 + (ix + 1) * r, y0 + iy * r])
            else:
                iy += 1
    return rects


def _add_obstacle_tiles(plant, obstacles: list[list[float]]) -> None:
    for k, (x0, y0, x1, y1) in enumerate(obstacles):
        X = RigidTransform([(x0 + x1) / 2, (y0 + y1) / 2, 0.001])
        plant.RegisterVisualGeometry(
            plant.world_body(),
            X,
            Box(x1 - x0, y1 - y0, 0.002),
            f"obstacle_{k}",
            np.array([0.8, 0.1, 0.1, 1.0]),
        )


@register_diagram(
    "biped_walk",
    scenario_type=BipedWalkScenario,
    description="biped executing footstep commands: stepping rule -> ZMP/CoM (ZmpPlanner) -> "
    "swing feet -> leg IK -> joint PD",
    duration=20.0,
    check=lambda diagram, context: check_biped_walk(diagram, context),
    criteria={"fell": Bound(hi=0.0), "steps_landed": Bound(lo=10.0)},
)
def build_biped_walk(scenario: BipedWalkScenario, *, meshcat=None) -> Diagram:
    """Builds the walking biped from a scenario (see :func:`build_walk_diagram`).

    Args:
        scenario: a :class:`BipedWalkScenario` (validated here).
        meshcat: optional Meshcat instance.
    """
    scenario.validate()
    plan, obstacles = _scenario_plan(scenario)
    return build_walk_diagram(
        plan,
        obstacles=obstacles[0] if obstacles else None,
        rule=scenario.rule(),
        pelvis_height=scenario.pelvis_height,
        time_step=scenario.time_step,
        contact_approximation=scenario.contact_approximation,
        ground_friction=scenario.ground_friction,
        meshcat=meshcat,
        feedback=scenario.feedback,
    )


def footstep_sequence(diagram: Diagram, context: Context) -> FootstepSequence:
    """The realized footstep sequence of a walking diagram."""
    stepper = diagram.GetSubsystemByName("command_stepper")
    return stepper.GetOutputPort("footsteps").Eval(stepper.GetMyContextFromRoot(context))


def sole_poses(diagram: Diagram, context: Context) -> dict[int, np.ndarray]:
    """Measured (x, y, yaw) of both soles {0: left, 1: right} and their heights."""
    plant = diagram.GetSubsystemByName("plant")
    pc = plant.GetMyContextFromRoot(context)
    out = {}
    for f, name in ((0, "left_sole"), (1, "right_sole")):
        X = plant.GetFrameByName(name).CalcPoseInWorld(pc)
        R = X.rotation().matrix()
        out[f] = np.array([X.translation()[0], X.translation()[1], np.arctan2(R[1, 0], R[0, 0])])
    return out


TOUCHDOWN_DT = 0.004  # [s]
#: How far a sole may stand from the plan's start pose when execute_plan starts (the
#: builder places the robot there by IK to about 1e-6 m; a diagram whose plan was swapped
#: for one that starts elsewhere is off by the distance between the starts).
START_TOLERANCE_M = 0.01
START_TOLERANCE_RAD = 0.02


def foot_in_contact(diagram: Diagram, context: Context, foot: int) -> bool:
    """Whether a foot (0 left, 1 right) has a point contact with anything."""
    plant = diagram.GetSubsystemByName("plant")
    pc = plant.GetMyContextFromRoot(context)
    body = plant.GetBodyByName("left_foot" if foot == 0 else "right_foot").index()
    results = plant.get_contact_results_output_port().Eval(pc)
    for i in range(results.num_point_pair_contacts()):
        info = results.point_pair_contact_info(i)
        if body in (info.bodyA_index(), info.bodyB_index()):
            return True
    return False


def pelvis_state(diagram: Diagram, context: Context) -> tuple[np.ndarray, float]:
    """Pelvis position (3,) and tilt from vertical [rad]."""
    plant = diagram.GetSubsystemByName("plant")
    pc = plant.GetMyContextFromRoot(context)
    X = plant.EvalBodyPoseInWorld(pc, plant.GetBodyByName("pelvis"))
    tilt = float(np.arccos(np.clip(X.rotation().matrix()[2, 2], -1.0, 1.0)))
    return X.translation().copy(), tilt


@dataclasses.dataclass
class WalkResult:
    """Outcome of executing a plan.

    Attributes:
        landed: measured (x, y, yaw) of each step's swing sole after landing.
        stance: measured (x, y, yaw) of the stance sole at the same instants.
        expected: the controller's own target of each step (the stepping rule's, open
            loop, in the world frame it starts in; with feedback the steps aim at
            ``planned`` instead).
        planned: the plan's pose of each step (what the planner predicted).
        durations: measured time of each step from its command to the swing foot's
            touch-down (first contact of the foot; 4 ms resolution; NaN if it had no
            contact before the next step's lift-off) [s].
        scheduled_durations: the controller's planned command-to-landing times [s].
        fell: the pelvis dropped below 0.4 m or tilted more than 0.5 rad.
        final_time: simulated time reached [s].
        max_tilt: largest pelvis tilt seen at the sampled instants [rad].
        final_soles: measured ``[x, y, yaw]`` of the left and the right sole at
            ``final_time`` (where the robot stands at the end, also after a plan of no
            steps).
    """

    landed: list[list[float]]
    stance: list[list[float]]
    expected: list[list[float]]
    planned: list[list[float]]
    durations: list[float]
    scheduled_durations: list[float]
    fell: bool
    final_time: float
    max_tilt: float
    final_soles: list[list[float]] = dataclasses.field(default_factory=list)


def execute_plan(
    plan: FootstepPlan,
    *,
    rule: SteppingRule | None = None,
    pelvis_height: float = 0.60,
    time_step: float = 2e-3,
    contact_approximation: str = "sap",
    settle: float = 0.1,
    diagram: Diagram | None = None,
    simulator: Simulator | None = None,
    max_steps: int | None = None,
    feedback: bool | None = None,
    reach: StepReach | None = None,
) -> WalkResult:
    """Simulates the biped executing ``plan`` and measures every landing.

    A landing is measured ``settle`` seconds after the step's touch-down time (the swing
    sole then stands still until it lifts again).

    Args:
        plan: the footstep plan.
        rule: the controller's stepping rule.
        pelvis_height: pelvis height [m].
        time_step: plant time step [s].
        contact_approximation: ``sap`` (default), ``lagged`` or ``similar``.
        settle: delay after touch-down before measuring [s].
        diagram: optionally a diagram already built by :func:`build_walk_diagram` for ``plan``.
        simulator: optionally a simulator of ``diagram``.
        max_steps: stop after measuring this many landings (default: all, then the final hold).
        feedback: walk with world-frame step feedback (see :func:`build_walk_diagram`);
            None: as the given ``diagram`` was built, else open loop.
        reach: with ``feedback``, the correction bounds (for a diagram built here).

    Raises:
        RepertoireError: bad ``settle`` or ``max_steps``, or a ``diagram`` (or its context)
            walking another plan than ``plan`` (:func:`same_commands`): the landings were
            measured against ``plan`` while the robot walked the other one; or a robot
            that does not stand on the plan's start soles (within ``START_TOLERANCE_M``
            and ``START_TOLERANCE_RAD``): a plan set into a diagram built for a plan that
            starts elsewhere; or ``feedback`` True or False for a ``diagram`` built the
            other way.
    """
    if not (is_real(settle) and np.isfinite(settle) and settle >= 0.0):
        raise RepertoireError(f"settle must be a finite delay >= 0 s, got {settle!r}")
    if max_steps is not None and not (is_whole(max_steps) and max_steps >= 0):
        raise RepertoireError(f"max_steps must be None or an int >= 0, got {max_steps!r}")
    rule = rule or SteppingRule()
    if diagram is None:
        diagram = build_walk_diagram(
            plan,
            rule=rule,
            pelvis_height=pelvis_height,
            time_step=time_step,
            contact_approximation=contact_approximation,
            feedback=bool(feedback),
            reach=reach,
        )
    built = diagram.HasSubsystemNamed("step_feedback")
    if feedback is not None and bool(feedback) != built:
        raise RepertoireError(
            f"execute_plan(feedback={feedback}) got a diagram built "
            f"{'with' if built else 'without'} step feedback: it would walk "
            f"{'with' if built else 'without'} it; build the diagram with "
            f"feedback={feedback} or leave feedback None"
        )
    if simulator is None:
        simulator = Simulator(diagram)
    context = simulator.get_context()
    source = diagram.GetSubsystemByName("plan_source")
    walked = source.get_plan(source.GetMyContextFromRoot(context))
    if not same_commands(walked, plan):
        raise RepertoireError(
            f"execute_plan's plan ({plan.num_steps} steps from {plan.poses[0]}) is not the "
            f"one the diagram walks ({walked.num_steps} steps from {walked.poses[0]}): the "
            "landings would be measured against the wrong plan; build the diagram for this "
            "plan or SetPlan it in the simulator's context"
        )
    simulator.Initialize()
    seq = footstep_sequence(diagram, context)
    soles = sole_poses(diagram, context)
    for foot, want in ((0, seq.initial_left), (1, seq.initial_right)):
        off = float(np.linalg.norm(soles[foot][:2] - np.asarray(want[:2])))
        turn = abs(wrap_angle(soles[foot][2] - want[2]))
        if not (off <= START_TOLERANCE_M and turn <= START_TOLERANCE_RAD):
            raise RepertoireError(
                f"the robot's {('left', 'right')[foot]} sole stands at "
                f"{(np.round(soles[foot], 4) + 0.0).tolist()} but the plan starts it at "
                f"{(np.round(want, 4) + 0.0).tolist()} ([x, y, yaw]; {off:.4f} m, {turn:.4f} rad "
                f"apart, tolerance {START_TOLERANCE_M} m, {START_TOLERANCE_RAD} rad): the "
                "steps would be taken from where the robot stands; build the diagram for "
                "this plan"
            )
    landed, stance, max_tilt, fell = [], [], 0.0, False
    n_steps = seq.num_steps if max_steps is None else min(max_steps, seq.num_steps)
    touchdowns = []
    for k in range(n_steps):
        # Touch-down: the first instant (4 ms resolution) after mid-swing at which the
        # swing foot has a contact; searched until the next step's lift-off.
        t_lift = seq.command_times[k] + seq.double_support
        t = t_lift + 0.5 * (seq.land_times[k] - t_lift)
        touchdown = float("nan")
        while t <= seq.land_times[k] + seq.double_support:
            simulator.AdvanceTo(t)
            if foot_in_contact(diagram, context, seq.swing_feet[k]):
                touchdown = t
                break
            t += TOUCHDOWN_DT
        touchdowns.append(touchdown)
        simulator.AdvanceTo(max(seq.land_times[k] + settle, context.get_time()))
        p, tilt = pelvis_state(diagram, context)
        max_tilt = max(max_tilt, tilt)
        if p[2] < 0.4 or tilt > 0.5 or not np.all(np.isfinite(p)):
            fell = True
            break
        soles = sole_poses(diagram, context)
        landed.append(soles[seq.swing_feet[k]].tolist())
        stance.append(soles[1 - seq.swing_feet[k]].tolist())
    if not fell and n_steps == seq.num_steps:
        simulator.AdvanceTo(seq.end_time)
        p, tilt = pelvis_state(diagram, context)
        max_tilt = max(max_tilt, tilt)
        fell = bool(p[2] < 0.4 or tilt > 0.5 or not np.all(np.isfinite(p)))
    durations = [td - tc for tc, td in zip(seq.command_times, touchdowns)]
    scheduled = [tl - tc for tc, tl in zip(seq.command_times, seq.land_times)]
    return WalkResult(
        landed=landed,
        stance=stance,
        expected=[list(p) for p in seq.poses],
        planned=[list(p) for p in plan.poses[1:]],
        durations=durations,
        scheduled_durations=scheduled,
        fell=fell,
        final_time=context.get_time(),
        max_tilt=max_tilt,
        final_soles=[v.tolist() for _, v in sorted(sole_poses(diagram, context).items())],
    )


def landing_errors(
    landed: list[list[float]], target: list[list[float]]
) -> tuple[np.ndarray, np.ndarray]:
    """Position [m] and yaw [rad] error of each measured landing against a target pose."""
    n = min(len(landed), len(target))
    if n == 0:
        return np.zeros(0), np.zeros(0)
    a = np.asarray(landed[:n], float)
    b = np.asarray(target[:n], float)
    pos = np.linalg.norm(a[:, :2] - b[:, :2], axis=1)
    yaw = np.abs(np.array([wrap_angle(x) for x in a[:, 2] - b[:, 2]]))
    return pos, yaw


def check_biped_walk(diagram: Diagram, context: Context) -> dict[str, float]:
    """Figures after a walk: pelvis height and tilt, distance walked, steps taken so far.

    ``steps_planned`` and ``plan_complete`` (1 when the plan's status is SUCCESS, 0 for
    the best partial plan of a search that hit its time or node limit) say whether the
    steps walked were a whole plan to the goal.
    """
    p, tilt = pelvis_state(diagram, context)
    seq = footstep_sequence(diagram, context)
    source = diagram.GetSubsystemByName("plan_source")
    plan = source.get_plan(source.GetMyContextFromRoot(context))
    t = context.get_time()
    done = sum(1 for tl in seq.land_times if tl <= t)
    start = 0.5 * (np.asarray(seq.initial_left[:2]) + np.asarray(seq.initial_right[:2]))
    return {
        "pelvis_height_m": float(p[2]),
        "tilt_rad": tilt,
        "distance_m": float(np.linalg.norm(p[:2] - start)),
        "steps_landed": float(done),
        "fell": float(p[2] < 0.4 or tilt > 0.5),
        "steps_planned": float(plan.num_steps),
        "plan_complete": float(plan.status == PlanStatus.SUCCESS),
    }


__all__ = [
    "BipedWalkScenario",
    "WalkResult",
    "build_biped_walk",
    "build_walk_diagram",
    "check_biped_walk",
    "check_start_stance",
    "execute_plan",
    "landing_errors",
    "plan_from_actions",
    "plan_from_rule",
    "same_commands",
    "sole_poses",
    "start_feet",
]
