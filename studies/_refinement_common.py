"""Shared by the refinement and subgoal-assertion studies: the soccer plan and its episodes.

The paper's soccer scenario (Stulp & Beetz, sections 6.3 and 7): a robot at a random
state goes to the ball and dribbles it to a destination. The abstract plan comes from the
PDDL planner (``approachball``, ``dribbleball``; Figure 10), is instantiated by
Algorithm 2 (the approach angle and speed at the ball, ``pos2.phi`` and ``pos2.v``, stay
free) and refined with the learned duration models. Executed in the ``soccer_plan``
world: ``approachBall`` is a GoToPose to ``approach_distance`` behind the ball, facing
``phi`` at speed ``v``; ``dribbleBall`` a DribbleBall in collect mode that fetches the
ball from there and dribbles it to the destination (the plan succeeds only with the ball
held there).
"""

import dataclasses
import functools
import math
import time

import numpy as np
from repertoire.planning.action_models.features import (
    GOTO_POSE_FEATURES,
    UNMIRRORED_GOTO_POSE_FEATURES,
    goto_pose_features,
)

from repertoire.checks import check_range
from repertoire.errors import RepertoireError

SOCCER_DOMAIN = """
(define (domain soccer) (:requirements :strips :typing) (:types pos)
 (:predicates (robot ?p - pos) (ball ?p - pos) (atball ?p - pos) (final ?p - pos))
 (:action approachball :parameters (?from ?to - pos)
   :precondition (and (robot ?from) (ball ?to))
   :effect (and (atball ?to) (not (robot ?from))))
 (:action dribbleball :parameters (?from ?to - pos)
   :precondition (and (atball ?from) (final ?to))
   :effect (and (atball ?to) (not (atball ?from)))))
"""
SOCCER_PROBLEM = """
(define (problem dribble) (:domain soccer) (:objects pos1 pos2 pos3 - pos)
 (:init (robot pos1) (ball pos2) (final pos3))
 (:goal (and (final pos3) (atball pos3))))
"""
STUDY_GAINS = {"k_beta": -0.3, "k_rho": 2.0}
"""GoToPose gains of the plan studies: the weak heading term of actions_goto_pose (straighter
approaches, which can bump the ball) and a faster pose convergence (k_rho 2 instead of 0.8:
with 0.8 the exponential slow-down near every goal, ~4 s per leg, hides what the approach
angle costs)."""
DRIBBLER_REACH = 0.3375
"""How far the ``soccer_dribble`` guide arms reach ahead of the axle [m] (``BUMPER_X +
GUIDE_SIZE[0]``; tested equal to the world's geometry)."""
APPROACH_DISTANCE = 0.5
"""The approach pose's default distance behind the ball centre [m]. The guide arms' tips
touch a ball centred ahead at ``DRIBBLER_REACH + BALL_RADIUS`` = 0.4475 m, and GoToPose
ends within its ``position_tolerance`` (0.05 m) of the pose, so the approach must stop at
least 0.4975 m behind the ball not to bump it; 0.5 m is also DribbleBall's
``collect_distance``, the distance it fetches a ball from. (0.35 m, the old default made
for a dribbler-less robot, put the tips into the ball.)"""

SPEED_RANGE = (0.0, 1.0)
"""Speeds [m/s] the plan's belief state allows (the default range of every ``v``)."""


@dataclasses.dataclass
class SoccerPlanConfig:
    """Sampling ranges and simulation settings shared by the soccer plan studies.

    Attributes:
        x_range: start x range [m].
        y_range: start y range [m].
        v_range: start speed range [m/s], within [0, 1].
        min_start_clearance: starts closer than this to the ball are resampled [m].
        dribble_distance_range: the destination's distance from the ball [m].
        approach_distance: the approach pose's distance behind the ball centre [m].
        approach_v_max: the approach speed is free in [0, approach_v_max] [m/s], <= 1 (GoToPose
            succeeds only within 0.1 m/s of its goal speed, so a faster subgoal the robot
            reaches too slowly costs a run-up; the shipped models were fitted below 0.1). The
            refinement searches only the part of this range the models saw
            (:func:`trained_range`: 0.00025-0.0897 m/s for the shipped models).
        time_step: plant step [s].
        control_period: GoToPose and executor period [s].
        timeout: every GoToPose's time limit, from its own start [s].
        gains: GoToPose gain overrides.
        dribble_gains: DribbleBall gain overrides of the dribble leg (the last of a
            two-action plan; its ``timeout``, from the leg's start, defaults to
            DribbleBall's 15 s).
    """

    x_range: list[float] = dataclasses.field(default_factory=lambda: [-1.5, 2.5])
    y_range: list[float] = dataclasses.field(default_factory=lambda: [-1.5, 1.8])
    v_range: list[float] = dataclasses.field(default_factory=lambda: [0.0, 0.5])
    min_start_clearance: float = 0.6
    dribble_distance_range: list[float] = dataclasses.field(default_factory=lambda: [0.8, 1.3])
    approach_distance: float = APPROACH_DISTANCE
    approach_v_max: float = 0.09
    time_step: float = 1e-2
    control_period: float = 0.02
    timeout: float = 12.0
    gains: dict[str, float] = dataclasses.field(default_factory=lambda: dict(STUDY_GAINS))
    dribble_gains: dict[str, float] = dataclasses.field(default_factory=dict)

    def validate(self) -> None:
        """Raises RepertoireError naming the first bad field."""
        for name in ("x_range", "y_range", "v_range", "dribble_distance_range"):
            check_range(name, getattr(self, name))
        if not (-3 <= self.x_range[0] and self.x_range[1] <= 3):
            raise RepertoireError(f"x_range must lie on the field [-3, 3], got {self.x_range}")
        if not (-2 <= self.y_range[0] and self.y_range[1] <= 2):
            raise RepertoireError(f"y_range must lie on the field [-2, 2], got {self.y_range}")
        if not 0.11 < self.approach_distance < self.min_start_clearance:
            raise RepertoireError(
                f"approach_distance must lie between the ball radius 0.11 m and "
                f"min_start_clearance, got {self.approach_distance}"
            )
        lo, hi = SPEED_RANGE
        if not (lo <= self.v_range[0] and self.v_range[1] <= hi):
            raise RepertoireError(
                f"v_range must lie in the plan's speed range {list(SPEED_RANGE)} m/s, got "
                f"{self.v_range}"
            )
        if not lo <= self.approach_v_max <= hi:
            raise RepertoireError(
                f"approach_v_max must lie in the plan's speed range {list(SPEED_RANGE)} m/s, "
                f"got {self.approach_v_max}"
            )
        if not self.timeout > 0:
            raise RepertoireError(f"timeout must be > 0, got {self.timeout}")
        if self.dribble_distance_range[0] <= self.approach_distance:
            raise RepertoireError("dribble_distance_range must start beyond approach_distance")
        from repertoire.systems.dribble_ball import DRIBBLE_GAINS

        unknown = sorted(set(self.dribble_gains) - set(DRIBBLE_GAINS))
        if unknown:
            raise RepertoireError(
                f"unknown DribbleBall gains {unknown} in dribble_gains; expected "
                f"{list(DRIBBLE_GAINS)}"
            )


def document_shared_fields(cls: type) -> type:
    """Appends :class:`SoccerPlanConfig`'s ``Attributes`` to a subclass's docstring.

    The subclass's docstring must end with its own ``Attributes:`` section; ``repertoire
    show`` then comments every field, inherited ones included.
    """
    import inspect

    shared = inspect.getdoc(SoccerPlanConfig).split("Attributes:\n", 1)[1]
    lines = [f"    {line}" if line else "" for line in shared.splitlines()]
    cls.__doc__ = (cls.__doc__ or "").rstrip() + "\n" + "\n".join(lines) + "\n    "
    return cls


def sample_situation(config: SoccerPlanConfig, rng: np.random.Generator):
    """A start ``[x, y, phi, v]`` and a destination ``[x, y, phi, 0]`` beyond the ball.

    The destination lies ``dribble_distance`` from the ball along a uniform direction,
    facing away from the ball; one that leaves the field is resampled, and so is a start
    or destination where the robot would stand in a goal
    (:func:`~repertoire.diagrams.soccer.clear_of_goals`).
    """
    from repertoire.diagrams.soccer import BALL_POSITION, clear_of_goals, draw_start_xy

    bx, by = BALL_POSITION
    x, y = draw_start_xy(rng, config.x_range, config.y_range, config.min_start_clearance)
    start = [x, y, rng.uniform(-math.pi, math.pi), rng.uniform(*config.v_range)]
    for _ in range(1000):
        psi = rng.uniform(-math.pi, math.pi)
        d = rng.uniform(*config.dribble_distance_range)
        dest = [bx + d * math.cos(psi), by + d * math.sin(psi), psi, 0.0]
        if abs(dest[0]) <= 2.7 and abs(dest[1]) <= 1.7 and clear_of_goals(dest[0], dest[1]):
            break
    else:
        raise RepertoireError("no destination on the field in dribble_distance_range")
    return np.array(start, dtype=float), np.array(dest, dtype=float)


def approach_target(phi, v, distance: float) -> np.ndarray:
    """GoToPose target(s) ``distance`` behind the ball, facing ``phi`` at speed ``v``."""
    from repertoire.diagrams.soccer import BALL_POSITION

    phi, v = np.broadcast_arrays(np.asarray(phi, dtype=float), np.asarray(v, dtype=float))
    if not (np.isfinite(phi).all() and np.isfinite(v).all()):
        raise RepertoireError(f"approach phi and v must be finite, got {phi!r} and {v!r}")
    bx, by = BALL_POSITION
    return np.stack([bx - distance * np.cos(phi), by - distance * np.sin(phi), phi, v], axis=-1)


# Names of the columns of approach_features / dribble_features (un-mirrored).
LEG_FEATURES = UNMIRRORED_GOTO_POSE_FEATURES


def check_leg_model(model, path) -> None:
    """Checks that ``model`` was fitted on :data:`LEG_FEATURES`; renames older files' columns.

    Models saved before the un-mirrored columns had their own names carry Table 7's
    ``GOTO_POSE_FEATURES`` names; a negative training minimum of ``angle_to`` (the
    mirrored ``angle_to`` is ``>= 0``) proves they were fitted un-mirrored, and their
    names are replaced in memory.

    Raises:
        RepertoireError: the model's features are not the legs' (un-mirrored) ones.
    """
    names = list(model.feature_names)
    if names == list(LEG_FEATURES):
        return
    if names == list(GOTO_POSE_FEATURES) and model.train_min[1] < 0.0:
        model.feature_names = list(LEG_FEATURES)
        return
    raise RepertoireError(
        f"action model '{path}' was fitted on features {names}; the soccer refinement "
        f"studies compute {list(LEG_FEATURES)} (goto_pose_features(..., mirrored=False)): "
        "refit it with refinement_explore"
    )


def approach_features(start, phi, v, distance: float) -> np.ndarray:
    """Table 7 features of the approach leg(s) (start -> behind the ball).

    Un-mirrored (``goto_pose_features(..., mirrored=False)``, columns
    :data:`LEG_FEATURES`), as the shipped models were fitted; the refinement studies
    move to the mirrored form when they are refitted.
    """
    target = approach_target(phi, v, distance)
    start = np.broadcast_to(np.asarray(start, dtype=float), target.shape)
    return np.atleast_2d(goto_pose_features(start, target, mirrored=False))


def dribble_features(phi, v, dest, distance: float) -> np.ndarray:
    """Table 7 features of the dribble leg(s) (behind the ball -> destination), un-mirrored."""
    start = approach_target(phi, v, distance)
    dest = np.broadcast_to(np.asarray(dest, dtype=float), start.shape)
    return np.atleast_2d(goto_pose_features(start, dest, mirrored=False))


def mode_settled_headings(dest, config: SoccerPlanConfig) -> list[tuple[float, float]]:
    """Approach headings ``phi`` at which the plan settles the dribble's collect mode.

    DribbleBall in collect mode drives onto the ball when the ball -> destination
    direction ``psi`` lies within ``collect_angle`` of its heading once the ball is held,
    and circles the ball otherwise (about 4 s more). The approach leaves the robot within
    GoToPose's ``heading_tolerance`` of the planned ``phi``, so the executed mode follows
    from the plan only where the planned turn ``|wrap(psi - phi)|`` is at most
    ``collect_angle - heading_tolerance`` (drives on) or at least ``collect_angle +
    heading_tolerance`` (circles). Between, it depends on where the approach stopped, which
    no model feature sees, and a duration tree fitted across that step is optimistic just
    inside it, where refinement aimed (session 34: refined plans 1.6 s slower than
    predicted).

    Args:
        dest: the destination ``[x, y, ...]``.
        config: the plan settings (their GoToPose and DribbleBall gains).

    Returns:
        ``(lo, hi)`` intervals of ``phi`` (not wrapped: ``psi`` plus an offset): the
        drive-on one, then the circling one; an empty one is left out.
    """
    from repertoire.diagrams.soccer import BALL_POSITION
    from repertoire.systems.dribble_ball import DRIBBLE_GAINS
    from repertoire.systems.go_to_pose import GOTO_GAINS

    collect = {**DRIBBLE_GAINS, **config.dribble_gains}["collect_angle"]
    margin = {**GOTO_GAINS, **config.gains}["heading_tolerance"]
    psi = math.atan2(dest[1] - BALL_POSITION[1], dest[0] - BALL_POSITION[0])
    inner, outer = min(collect - margin, math.pi), max(collect + margin, 0.0)
    out = [(psi - inner, psi + inner)] if inner > 0.0 else []
    return out + ([(psi + outer, psi + 2.0 * math.pi - outer)] if outer < math.pi else [])


@functools.cache
def abstract_soccer_plan():
    """The PDDL plan (approachball, dribbleball), planned once per process."""
    from repertoire.planning.plans import plan_pddl

    return plan_pddl(SOCCER_DOMAIN, SOCCER_PROBLEM)


def trained_range(lo: float, hi: float, uses) -> tuple[float, float]:
    """``[lo, hi]`` narrowed to the training range of each ``(model, feature name)`` in ``uses``.

    A refined parameter lies on a face of its range wherever the linear leaves fall towards
    it. The approach speed's range is ``[0, approach_v_max]``, and the models were fitted on
    speeds drawn uniformly from that same interval, whose ends no episode draws (the shipped
    models saw 0.00025-0.0897 m/s): refined over the whole range, every plan's speed lay
    just outside the models' training box and ``out_of_range`` flagged it. Searching only
    where the models saw data keeps refined plans inside it.

    Args:
        lo: the parameter's lower bound (the belief state's).
        hi: its upper bound.
        uses: ``(model, name)`` pairs: a fitted ``TreeModel`` and the feature that equals
            the parameter (the approach speed is ``v_g`` of the leg that ends there and
            ``v`` of the leg that starts there).

    Returns:
        The intersection; ``(lo, hi)`` unchanged where it would be empty (a range the models
        never saw, e.g. ``approach_v_max = 0``): such a plan is an extrapolation, and
        ``out_of_range`` still says so.

    Raises:
        RepertoireError: ``[lo, hi]`` is not a finite range, or a model has no feature of
            that name.
    """
    check_range("trained_range's [lo, hi]", [lo, hi])
    new_lo, new_hi = float(lo), float(hi)
    for model, name in uses:
        names = list(getattr(model, "feature_names", None) or [])
        if name not in names:
            raise RepertoireError(f"the model has no feature {name!r}; its features are {names}")
        j = names.index(name)
        new_lo, new_hi = max(new_lo, model.train_min[j]), min(new_hi, model.train_max[j])
    return (new_lo, new_hi) if new_lo <= new_hi else (float(lo), float(hi))


def instantiated_plan(start, dest, config: SoccerPlanConfig):
    """Algorithm 2 on the episode's belief state: ``ball.phi`` and ``ball.v`` stay free."""
    from repertoire.diagrams.soccer import BALL_POSITION
    from repertoire.planning.plans import (
        ActionRegistry,
        ActionTemplate,
        BeliefState,
        ParameterTemplate,
        instantiate_plan,
    )

    def pose(index: int, suffix: str = ""):
        return tuple(ParameterTemplate(q + suffix, q, index) for q in ("x", "y", "phi", "v"))

    registry = ActionRegistry()
    for name in ("approachBall", "dribbleBall"):
        registry.register(ActionTemplate(name, pose(0) + pose(1, "_g")))
    values = {("robot", q): float(s) for q, s in zip(("x", "y", "phi", "v"), start, strict=True)}
    values |= {("ball", "x"): BALL_POSITION[0], ("ball", "y"): BALL_POSITION[1]}
    values |= {("final", q): float(d) for q, d in zip(("x", "y", "phi", "v"), dest, strict=True)}
    belief = BeliefState(
        values=values,
        constraints={("atball", "v"): (0.0, config.approach_v_max)},
        defaults={"x": (-3.0, 3.0), "y": (-2.0, 2.0), "phi": (-math.pi, math.pi), "v": SPEED_RANGE},
    )
    return instantiate_plan(abstract_soccer_plan(), registry, belief)


def soccer_duration_models(
    approach_model, dribble_model, config: SoccerPlanConfig, *, within_data: bool = True
) -> dict:
    """``refinement_problem`` models of the two actions from fitted duration trees.

    With ``within_data`` each carries its tree's training box as its ``domain``: the
    refinement chooses the approach angle and speed only where the features they drive
    lie inside the data (the start's own features do not constrain).
    """
    from repertoire.planning.plans import ActionDurationModel
    from repertoire.planning.refinement import PiecewiseLinearModel

    d = config.approach_distance

    def approach(p):
        start = np.column_stack([p["x"], p["y"], p["phi"], p["v"]])
        return approach_features(start, p["phi_g"], p["v_g"], d)

    def dribble(p):
        dest = np.column_stack([p["x_g"], p["y_g"], p["phi_g"], p["v_g"]])
        return dribble_features(p["phi"], p["v"], dest, d)

    def entry(tree, features, reads):
        model = PiecewiseLinearModel.from_leaves(tree.leaves)
        if not within_data:
            return ActionDurationModel(model, features)
        return ActionDurationModel(model, features, (tree.train_min, tree.train_max), reads)

    # per LEG_FEATURES column (dist, angle_to, angle_at, v, v_g) the parameters it reads:
    # the approach ends behind the ball along phi_g, the dribble starts there along phi
    return {
        "approachBall": entry(approach_model, approach, APPROACH_READS),
        "dribbleBall": entry(dribble_model, dribble, DRIBBLE_READS),
    }


def approach_succeeds(failure_tree, config: SoccerPlanConfig):
    """``refinement_problem``'s ``succeeds`` for the approach: not a predicted collision.

    Section 7.2's Algorithm 4: the approach's model returns INVALID (+inf) where the
    failure tree (``refinement_explore``'s ``approach_failure``: the approach touches the
    ball) predicts failure, so the refinement chooses only subgoals it predicts succeed.

    Args:
        failure_tree: the approach failure tree (fitted on :data:`LEG_FEATURES`).
        config: gives ``approach_distance``.

    Returns:
        Approach parameters (name -> (n,) values) -> (n,) booleans, True where the tree
        predicts success.
    """
    d = config.approach_distance

    def succeeds(p) -> np.ndarray:
        start = np.column_stack([p["x"], p["y"], p["phi"], p["v"]])
        return ~failure_tree.predict_failure(approach_features(start, p["phi_g"], p["v_g"], d))

    return succeeds


APPROACH_READS = (
    ("x", "y", "phi_g"),
    ("x", "y", "phi", "phi_g"),
    ("x", "y", "phi_g"),
    ("v",),
    ("v_g",),
)
"""The approach's parameters each of its :data:`LEG_FEATURES` reads."""
DRIBBLE_READS = (
    ("phi", "x_g", "y_g"),
    ("phi", "x_g", "y_g"),
    ("phi", "x_g", "y_g", "phi_g"),
    ("v",),
    ("v_g",),
)
"""The dribble's parameters each of its :data:`LEG_FEATURES` reads."""


@dataclasses.dataclass
class PlanRun:
    """One executed plan: status, finish time per action, contact and ball figures.

    ``active`` is the action that was running when the plan ended (the failed one) or the
    number of actions after success; a failed action's finish time is when it failed.
    """

    status: str
    active: int
    finish_times: list[float]
    touched_ball_first: bool
    touched_ball_goto: bool
    ball_moved_m: float
    ball_held: bool
    wall_time_s: float


def run_plan(
    config: SoccerPlanConfig, start, targets, *, dribble: bool = False, dribbler: bool = False
) -> PlanRun:
    """Runs ``targets`` from ``start`` in the ``soccer_plan`` world.

    One GoToPose per target; with ``dribble`` the last target is DribbleBall's (collect
    mode, ``config.dribble_gains``, in the dribbler world); with ``dribbler`` only
    GoToPose actions, by the robot with the dribbler (a ball approach by the dribbling
    robot). Stops when the plan ends or one second after every action could have timed
    out (the timeouts count from each action's start). ``touched_ball_first`` is True if
    the robot touched the ball while the first action was active (a bumped approach),
    ``touched_ball_goto`` while any GoToPose action was (the dribble is meant to touch
    it); ``ball_held`` whether the robot ends holding the ball
    (:func:`~repertoire.diagrams.soccer_plan.ball_held`). A dribbling plan's status is
    ``SUCCEEDED`` only with the ball held at its end (a DribbleBall that succeeds holds
    it; checked again here, it is what success means).
    """
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import EventStatus
    from repertoire.diagrams.soccer import set_initial_speed
    from repertoire.diagrams.soccer_plan import (
        SoccerPlanScenario,
        ball_held,
        ball_moved,
        build_soccer_plan,
        finish_times,
        plan_status,
        plan_succeeded,
    )
    from repertoire.systems.dribble_ball import DRIBBLE_GAINS
    from repertoire.systems.go_to_pose import ActionStatus

    t0 = time.perf_counter()
    scenario = SoccerPlanScenario(
        initial_pose=[float(s) for s in start[:3]],
        initial_speed=float(start[3]),
        targets=[[float(x) for x in t] for t in targets],
        time_step=config.time_step,
        control_period=config.control_period,
        gains={**config.gains, "timeout": config.timeout},
        dribble=dribble,
        dribbler=dribbler,
        dribble_gains=dict(config.dribble_gains),
    )
    diagram = build_soccer_plan(scenario)
    dribble_timeout = {**DRIBBLE_GAINS, **config.dribble_gains}["timeout"] if dribble else 0.0
    plant = diagram.GetSubsystemByName("plant")
    executor = diagram.GetSubsystemByName("executor")
    ball = plant.GetBodyByName("ball").index()
    robot_bodies = {plant.GetBodyByName(n).index() for n in ("chassis",)}
    robot_bodies |= {
        plant.GetBodyByName(f"{s}_wheel").index()
        for s in ("left", "right")
        if plant.HasBodyNamed(f"{s}_wheel")
    }
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    set_initial_speed(diagram, context, float(start[3]))
    plant_context = plant.GetMyContextFromRoot(context)
    executor_context = executor.GetMyContextFromRoot(context)
    touched = [False] * len(targets)

    def monitor(root_context) -> EventStatus:
        active = int(executor.get_active_action_output_port().Eval(executor_context)[0])
        if active < scenario.n_goto() and not touched[active]:
            results = plant.get_contact_results_output_port().Eval(plant_context)
            for i in range(results.num_point_pair_contacts()):
                info = results.point_pair_contact_info(i)
                pair = {info.bodyA_index(), info.bodyB_index()}
                if ball in pair and pair & robot_bodies:
                    touched[active] = True
        if plan_status(diagram, root_context) != ActionStatus.RUNNING:
            return EventStatus.ReachedTermination(None, "plan ended")
        return EventStatus.Succeeded()

    simulator.set_monitor(monitor)
    simulator.AdvanceTo(scenario.n_goto() * config.timeout + dribble_timeout + 1.0)
    status = plan_status(diagram, context).name
    if status == "SUCCEEDED" and not plan_succeeded(diagram, context):
        status = "FAILED"  # a dribble that ends without the ball
    return PlanRun(
        status=status,
        active=int(executor.get_active_action_output_port().Eval(executor_context)[0]),
        finish_times=[float(t) for t in finish_times(diagram, context)],
        touched_ball_first=bool(touched[0]),
        touched_ball_goto=any(touched),
        ball_moved_m=ball_moved(diagram, context),
        ball_held=bool(ball_held(diagram, context)),
        wall_time_s=time.perf_counter() - t0,
    )
