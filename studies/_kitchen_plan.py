"""The kitchen plans of the refinement study: fetch cups from one table to the other.

Stulp & Beetz, section 6.3: "the goal is to put a cup from one table to another, which is
achieved by a sequence of navigation and grasping actions" (scenario 1); scenario 2
delivers two cups. Here a fetch of cup ``k`` is ten actions of the kitchen robot
(``kitchen_action`` world, executed one after the other in physics by
:func:`~repertoire.diagrams.kitchen.run_kitchen_sequence`):

1. ``goto_pose`` to a *stand* pose beside ``table_0`` (arrival speed 0: the arm works
   on a still base), 2. ``reach`` to ``above_offset`` above the cup, 3. ``reach`` there
   again (the base turns a little under the arm's swing: aim again), 4. ``reach`` down
   to the cup, 5. ``grip``, 6. ``reach`` straight up, 7. ``reach`` to a *carry* point
   (the cup above every table and the counter), 8. ``goto_pose`` to a *drop* pose beside
   ``table_1``, 9. ``reach`` with the cup over its target, 10. ``put`` it down (Put
   converts its target at its start, so it aims again too),

and, between two fetches, a ``reach`` straight up out of the placed cup. Free
parameters (the paper: "the distance of the robot to the table ... is another free
parameter ... the velocity and orientation at waypoints are also not fixed"): a stand or
drop pose is given by the robot's heading ``phi`` and the arm joints ``(yaw, extend)``
at which the gripper meets the cup (or the target), so the robot's position
``p - R(phi) (COLUMN_X + e cos(yaw), e sin(yaw))`` keeps the cup within reach by
construction; the carry point is ``(yaw, extend, z)``. Nine free parameters per cup.

Models: the kitchen goToPose and reach duration trees (Table 7 features) fitted on
``actions_kitchen`` episodes (:func:`fit_kitchen_plan_models`, shipped in
``repertoire/models/diffdrive/kitchen_plan_models``); ``grip`` and ``put`` (lower, open)
are constants in closed form from the actions' speeds. A stand or drop pose whose
footprint overlaps furniture, or whose straight path from the previous pose does
(GoToPose drives without obstacle avoidance), is INVALID (predicted +inf), and so is a
stand from which no drop drive, held arm and all, reaches :func:`exit_point` (so a drop
pose stays reachable whatever later steps choose: ``_kitchen_arm.exit_clear``): geometric
preconditions, not learned failure models. So is
a plan whose arm, fingers or held cup would pass through a table, the counter, a wall or
a standing cup on a reach, the carry or the put, or while the base drives with the arm
held out (:mod:`repertoire.studies._kitchen_arm`): a clear base path alone let the arm
swing through the cup waiting beside the fetched one.
"""

import dataclasses
import math
from pathlib import Path

import numpy as np
from repertoire.planning.action_models.kitchen_features import (
    kitchen_goto_features,
    kitchen_reach_features,
)
from repertoire.systems.kitchen_geometry import box_gaps, segment_gaps

from repertoire.checks import check_range
from repertoire.errors import RepertoireError

FETCHED = ("cup_0", "cup_1")
PER_CUP = 9  # free parameters per fetch
PUT_CLEARANCE = 0.05  # Put's default clearance: the cup is carried this far above its target
MODEL_FILES = {"goto_pose": "goto_duration.json", "reach": "reach_duration.json"}
#: Sample spacing of the arm's ways in :func:`arm_hits` [m] (coarser than the actions'
#: 1 cm: the boxes grow by ``arm_clearance`` >= half of it, so no way slips between).
ARM_SPACING = 0.02
SHIPPED_MODELS = "kitchen_plan_models"
"""Folder in ``repertoire/models/diffdrive`` with the goToPose and reach trees fitted on
600 + 600 ``actions_kitchen`` episodes (see docs/results/kitchen.md)."""


@dataclasses.dataclass
class KitchenPlanConfig:
    """The kitchen scenario, its free-parameter ranges and the simulation settings.

    Attributes:
        scenario: 1 (one cup, 10 actions) or 2 (two cups, 21 actions: :func:`plan_steps`).
        x_range: start x range of the robot [m] (the open part of the room: GoToPose
            drives straight, without avoiding furniture).
        y_range: start y range of the robot [m].
        cup_x_range: x range of the fetched cups on ``table_0`` [m].
        cup_y_range: y range of the fetched cups (near its edge facing ``table_1``) [m].
        target_side_range: put targets lie this far [m] from ``table_1``'s long axis
            towards ``table_0`` (its half width is 0.4 m; 0.1 m from the edge at most).
        yaw_range: arm yaw at the cup / target (stand and drop poses) [rad].
        extend_range: arm extension at the cup / target [m].
        carry_yaw_range: arm yaw of the carry point [rad].
        carry_extend_range: arm extension of the carry point [m].
        carry_z_range: world height of the carried cup's centre [m] (its bottom above the
            0.9 m counter).
        above_offset: the first reach ends this far above the cup [m].
        clearance: footprint margin of stand/drop poses and their straight paths [m].
        arm_clearance: horizontal margin of the arm's, the fingers' and a held cup's
            ways around the furniture and the standing cups (:func:`arm_hits`) [m], at
            least half of ``ARM_SPACING``.
        arrival_check: check each arm way also from the corners of GoToPose's arrival
            tolerances around its stand or drop pose (:func:`arm_hits`): the drive stops
            anywhere within 5 cm and 0.15 rad, and the reach is aimed from there.
        time_step: plant step [s] (the contact grasp holds the cup while driving at
            2 ms, not at 5 ms).
        step_limit: simulated seconds allowed per action [s].
        deliver_tolerance: the cup must end within this of its target [m].
        models_dir: folder with ``goto_duration.json`` and ``reach_duration.json``
            (empty: the shipped models).
        solver: refinement back-end for these non-affine features, ``"ga"`` or ``"de"``.
    """

    scenario: int = 1
    x_range: list[float] = dataclasses.field(default_factory=lambda: [-3.2, 0.8])
    y_range: list[float] = dataclasses.field(default_factory=lambda: [-2.4, 2.4])
    cup_x_range: list[float] = dataclasses.field(default_factory=lambda: [1.6, 2.6])
    cup_y_range: list[float] = dataclasses.field(default_factory=lambda: [0.98, 1.25])
    target_side_range: list[float] = dataclasses.field(default_factory=lambda: [0.1, 0.3])
    yaw_range: list[float] = dataclasses.field(default_factory=lambda: [-1.2, 1.2])
    extend_range: list[float] = dataclasses.field(default_factory=lambda: [0.35, 0.8])
    carry_yaw_range: list[float] = dataclasses.field(default_factory=lambda: [-1.2, 1.2])
    carry_extend_range: list[float] = dataclasses.field(default_factory=lambda: [0.3, 0.45])
    carry_z_range: list[float] = dataclasses.field(default_factory=lambda: [0.96, 1.0])
    above_offset: float = 0.1
    clearance: float = 0.05
    arm_clearance: float = 0.02
    arrival_check: bool = True
    time_step: float = 2e-3
    step_limit: float = 25.0
    deliver_tolerance: float = 0.1
    models_dir: str = ""
    solver: str = "ga"

    def validate(self) -> None:
        """Raises RepertoireError naming the first bad field."""
        from repertoire.models.diffdrive.generate import EXTEND_RANGE, YAW_RANGE

        if self.scenario not in (1, 2):
            raise RepertoireError(f"scenario must be 1 or 2, got {self.scenario!r}")
        bounds = {
            "x_range": (-3.6, 3.6),
            "y_range": (-2.6, 2.6),
            "cup_x_range": (1.55, 2.65),  # table_0's top less the cup radius
            "cup_y_range": (0.95, 1.65),
            # the drop poses stand on table_1's side towards table_0 (exit_point): from
            # there targets beyond the axis were out of reach (every plan NO_PLAN)
            "target_side_range": (0.0, 0.3),
            "yaw_range": YAW_RANGE,
            "extend_range": EXTEND_RANGE,
            "carry_yaw_range": YAW_RANGE,
            "carry_extend_range": EXTEND_RANGE,
            "carry_z_range": (0.91, 1.05),
        }
        for name, within in bounds.items():
            check_range(name, getattr(self, name), within)
        diagonal = math.hypot(np.diff(self.cup_x_range)[0], np.diff(self.cup_y_range)[0])
        if diagonal < 0.25:
            raise RepertoireError(f"cup_x_range x cup_y_range must hold two cups 0.25 m apart; "
                                  f"its diagonal is {diagonal:.3f} m")  # fmt: skip
        for name in ("above_offset", "clearance", "step_limit", "deliver_tolerance"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise RepertoireError(f"{name} must be finite and > 0, got {value}")
        if not (math.isfinite(self.arm_clearance) and self.arm_clearance >= ARM_SPACING / 2):
            raise RepertoireError(f"arm_clearance must be at least ARM_SPACING / 2 = "
                                  f"{ARM_SPACING / 2} m (the way's samples), got "
                                  f"{self.arm_clearance}")  # fmt: skip
        if not 0 < self.time_step <= 0.01:
            raise RepertoireError(f"time_step must be in (0, 0.01] s, got {self.time_step}")
        if self.solver not in ("ga", "de"):
            raise RepertoireError(f"solver must be 'ga' or 'de' (angles), got {self.solver!r}")


# --------------------------------------------------------------------------------------
# Geometry


def footprint_clear(xy, boxes, radius: float) -> np.ndarray:
    """True per point where a robot disc at ``xy`` (n, 2) overlaps no box (vectorised).

    ``boxes`` are rows ``[cx, cy, yaw, half_x, half_y, top_z]`` as in
    :func:`~repertoire.systems.kitchen_actions.footprint_hits`.
    """
    return np.all(box_gaps(xy, boxes) >= radius, axis=1)


def path_clear(a, b, boxes, radius) -> np.ndarray:
    """True per row where a disc swept along the segment ``a -> b`` ((n, 2) each) is clear.

    Clear: the segment's exact distance to each box (:func:`segment_gaps`) is at least
    ``radius`` (a number or one per row).
    """
    radius = np.asarray(radius, dtype=float)
    return np.all(segment_gaps(a, b, boxes) >= radius.reshape(-1, 1), axis=1)


def arm_point(yaw, extend, z_chassis) -> np.ndarray:
    """Gripper centre(s) ``(n, 3)`` in the chassis frame for arm yaw/extension and height."""
    from repertoire.models.diffdrive.generate import COLUMN_X

    yaw, extend, z = np.broadcast_arrays(*(np.asarray(v, float) for v in (yaw, extend, z_chassis)))
    return np.stack([COLUMN_X + extend * np.cos(yaw), extend * np.sin(yaw), z], axis=-1)


def base_pose(point, phi, yaw, extend) -> np.ndarray:
    """Chassis ``(n, 4)`` poses ``[x, y, phi, 0]`` putting the gripper over ``point``'s x, y."""
    a = arm_point(yaw, extend, 0.0)
    phi = np.broadcast_to(np.asarray(phi, dtype=float), a.shape[:-1])
    c, s = np.cos(phi), np.sin(phi)
    x = point[0] - (c * a[..., 0] - s * a[..., 1])
    y = point[1] - (s * a[..., 0] + c * a[..., 1])
    return np.stack([x, y, phi, np.zeros_like(phi)], axis=-1)


def to_chassis_z(z_world):
    """A world height in the chassis frame (origin on the wheel axle)."""
    from repertoire.models.diffdrive import WHEEL_RADIUS

    return np.asarray(z_world, dtype=float) - WHEEL_RADIUS


# --------------------------------------------------------------------------------------
# Situations and plans


def sample_situation(config: KitchenPlanConfig, rng: np.random.Generator):
    """A start, the two cups on ``table_0`` and one put target per fetched cup.

    Returns ``(start, cups, targets)``: the start ``[x, y, phi, 0]`` off the furniture;
    ``cup_0`` and ``cup_1`` (2, 3) uniform in the cup ranges, 0.25 m apart (both are
    displaced in both scenarios); (m, 3) targets uniform on ``table_1``'s top (0.1 m from
    its ends, ``target_side_range`` from its axis), at least 0.15 m from the cups standing
    there and from each other.
    """
    from repertoire.diagrams.kitchen import KITCHEN_CUP_POSITIONS, KITCHEN_OBSTACLES, ROBOT_RADIUS

    for _ in range(1000):
        xy = np.array([rng.uniform(*config.x_range), rng.uniform(*config.y_range)])
        if footprint_clear(xy, KITCHEN_OBSTACLES, ROBOT_RADIUS + 2 * config.clearance)[0]:
            break
    else:
        raise RepertoireError("no free start in x_range x y_range: widen them")
    start = np.array([*xy, rng.uniform(-math.pi, math.pi), 0.0])
    for _ in range(1000):  # a first cup that leaves the second no room is drawn again
        first = np.array([rng.uniform(*config.cup_x_range), rng.uniform(*config.cup_y_range)])
        for _ in range(1000):
            p = np.array([rng.uniform(*config.cup_x_range), rng.uniform(*config.cup_y_range)])
            if np.linalg.norm(p - first) >= 0.25:
                break
        else:
            continue
        break
    else:
        raise RepertoireError("no two cups 0.25 m apart in cup_x_range x cup_y_range")
    cups = [np.array([*q, KITCHEN_CUP_POSITIONS["cup_0"][2]]) for q in (first, p)]
    cx, cy, yaw, hx, hy, top = KITCHEN_OBSTACLES[2]  # table_1
    taken = [np.array(KITCHEN_CUP_POSITIONS[c][:2]) for c in ("cup_2", "cup_3")]
    targets = []
    for _ in range(config.scenario):
        for _ in range(1000):
            u, w = rng.uniform(-hx + 0.1, hx - 0.1), rng.uniform(*config.target_side_range)
            p = np.array([cx + math.cos(yaw) * u - math.sin(yaw) * w,
                          cy + math.sin(yaw) * u + math.cos(yaw) * w])  # fmt: skip
            if all(np.linalg.norm(p - q) >= 0.15 for q in taken):
                break
        else:
            raise RepertoireError("no free put target on table_1")
        taken.append(p)
        targets.append([float(p[0]), float(p[1]), KITCHEN_CUP_POSITIONS["cup_0"][2] + 0.001])
    return start, np.array(cups), np.array(targets)


def parameter_bounds(config: KitchenPlanConfig) -> tuple[np.ndarray, np.ndarray, tuple]:
    """Lower and upper bounds and names of the plan's free parameters (9 per cup)."""
    pi = math.pi
    one_lo = [-pi, config.yaw_range[0], config.extend_range[0], config.carry_yaw_range[0],
              config.carry_extend_range[0], config.carry_z_range[0], -pi, config.yaw_range[0],
              config.extend_range[0]]  # fmt: skip
    one_hi = [pi, config.yaw_range[1], config.extend_range[1], config.carry_yaw_range[1],
              config.carry_extend_range[1], config.carry_z_range[1], pi, config.yaw_range[1],
              config.extend_range[1]]  # fmt: skip
    names = []
    for k in range(config.scenario):
        names += [f"stand{k}.phi", f"stand{k}.yaw", f"stand{k}.extend", f"carry{k}.yaw",
                  f"carry{k}.extend", f"carry{k}.z", f"drop{k}.phi", f"drop{k}.yaw",
                  f"drop{k}.extend"]  # fmt: skip
    n = config.scenario
    return np.tile(one_lo, n), np.tile(one_hi, n), tuple(names)


@dataclasses.dataclass(frozen=True)
class PlanGeometry:
    """Everything the actions of a plan need, for a batch of parameter vectors.

    Attributes (n parameter vectors, m cups):
        stand: (n, m, 4) stand poses. drop: (n, m, 4) drop poses.
        carry: (n, m, 3) carry points (chassis frame).
        cup: (m, 3) cup centres (world). target: (m, 3) put targets (world).
    """

    stand: np.ndarray
    drop: np.ndarray
    carry: np.ndarray
    cup: np.ndarray
    target: np.ndarray

    def rows(self, index) -> "PlanGeometry":
        """The geometry of the parameter vectors ``index`` (an index array or a mask)."""
        return PlanGeometry(self.stand[index], self.drop[index], self.carry[index], self.cup,
                            self.target)  # fmt: skip


def plan_geometry(params, cups, targets) -> PlanGeometry:
    """Stand, drop and carry poses of ``params`` (n, 9 m) for the situation's cups/targets."""
    p = np.atleast_2d(np.asarray(params, dtype=float))
    m = len(targets)
    p = p.reshape(p.shape[0], m, PER_CUP)
    cup = np.asarray(cups, dtype=float)[:m]
    target = np.asarray(targets, dtype=float)
    stand = np.stack([base_pose(cup[k], p[:, k, 0], p[:, k, 1], p[:, k, 2]) for k in range(m)], 1)
    drop = np.stack([base_pose(target[k], p[:, k, 6], p[:, k, 7], p[:, k, 8]) for k in range(m)], 1)
    carry = arm_point(p[:, :, 3], p[:, :, 4], to_chassis_z(p[:, :, 5]))
    return PlanGeometry(stand, drop, carry, cup, target)


def plan_steps(geometry: PlanGeometry, row: int, config: KitchenPlanConfig) -> list[tuple]:
    """The executable ``run_kitchen_sequence`` steps of one parameter vector."""
    from repertoire.systems.kitchen_actions import chassis_to_world

    g, steps = geometry, []
    up = np.array([0.0, 0.0, config.above_offset])
    for k in range(g.cup.shape[0]):
        if k:
            steps.append(("reach", list(g.target[k - 1] + up)))  # out of the placed cup
        stand, drop = g.stand[row, k], g.drop[row, k]
        steps += [
            ("goto_pose", [float(v) for v in stand]),
            ("reach", [float(v) for v in g.cup[k] + up]),
            ("reach", [float(v) for v in g.cup[k] + up]),
            ("reach", [float(v) for v in g.cup[k]]),
            ("grip", []),
            ("reach", [float(v) for v in g.cup[k] + up]),
            ("reach", [float(v) for v in chassis_to_world(stand, g.carry[row, k])]),
            ("goto_pose", [float(v) for v in drop]),
            ("reach", [float(v) for v in g.target[k] + [0.0, 0.0, PUT_CLEARANCE]]),
            ("put", [float(v) for v in g.target[k]]),
        ]
    return steps


def executed_steps(geometry: PlanGeometry, row: int, start, cups, config: KitchenPlanConfig):
    """:func:`plan_steps` with each drive's via leg before it, where it has one.

    A drive whose straight path is not clear goes via points around the furniture
    (:func:`~repertoire.studies._kitchen_arm.drive_route`, as the refinement predicted
    it): a ``goto_pose`` to each via pose, then the drive's own.

    Returns:
        ``(steps, owner)``: the ``run_kitchen_sequence`` steps and, per step, the index
        of the plan action (:func:`action_names`) it belongs to.
    """
    from repertoire.studies._kitchen_arm import drive_route

    g = geometry.rows([row])
    vias = []  # per drive in plan order: its via poses (none where straight or not clear)
    for k in range(g.cup.shape[0]):
        for role in ("drive_stand", "drive_drop"):
            via, ok = drive_route(g, cups, k, start, config, role)
            vias.append([v for v in via[0] if ok[0] and not np.isnan(v[0])])
    steps, owner, drives = [], [], iter(vias)
    for i, step in enumerate(plan_steps(geometry, row, config)):
        if step[0] == "goto_pose":
            for via in next(drives):
                steps.append(("goto_pose", [float(v) for v in via]))
                owner.append(i)
        steps.append(step)
        owner.append(i)
    return steps, owner


def exit_point(target) -> np.ndarray:
    """Where a robot stands in front of a put target: 0.9 m from it, off ``table_1``'s side.

    A stand pose must reach this point along straight, free legs, straight or around the
    furniture (:func:`~repertoire.studies._kitchen_arm.reaches`), so a drop pose stays
    reachable whatever the later refinement steps choose.
    """
    from repertoire.diagrams.kitchen import KITCHEN_OBSTACLES

    yaw = KITCHEN_OBSTACLES[2, 2]  # table_1; targets lie on its +y side
    return np.asarray(target, dtype=float)[:2] + 0.9 * np.array([-math.sin(yaw), math.cos(yaw)])


def _world_in_chassis(pose: np.ndarray, point) -> np.ndarray:
    """(n, 3) chassis-frame coordinates of world ``point`` (3,) or (n, 3) for (n, 4) poses."""
    point = np.broadcast_to(np.asarray(point, dtype=float), pose[:, :3].shape)
    c, s = np.cos(pose[:, 2]), np.sin(pose[:, 2])
    dx, dy = point[:, 0] - pose[:, 0], point[:, 1] - pose[:, 1]
    return np.column_stack([c * dx + s * dy, -s * dx + c * dy, to_chassis_z(point[:, 2])])


def action_names(scenario: int) -> list[str]:
    """The actions of a scenario's plan in execution order (as :func:`plan_steps`)."""
    fetch = ["goto_pose", "reach", "reach", "reach", "grip", "reach", "reach", "goto_pose"]
    fetch += ["reach", "put"]
    return fetch + (["reach", *fetch] if scenario == 2 else [])


def grip_duration() -> float:
    """Grip's duration in closed form: close at its speed from open, then settle [s]."""
    from repertoire.systems.kitchen_actions import FINGER_CLOSED, FINGER_OPEN, FINGER_SPEED, Grip

    return (FINGER_OPEN - FINGER_CLOSED) / FINGER_SPEED + Grip().settle


def put_tail_duration() -> float:
    """Put after reaching above its target: lower by its clearance, open the fingers [s]."""
    from repertoire.systems.kitchen_actions import (
        ARM_SPEEDS,
        FINGER_CLOSED,
        FINGER_OPEN,
        FINGER_SPEED,
        Put,
    )

    return Put().clearance / ARM_SPEEDS[0] + (FINGER_OPEN - FINGER_CLOSED) / FINGER_SPEED


# --------------------------------------------------------------------------------------
# The refinement problem


def _constant_model(value: float):
    from repertoire.planning.refinement import PiecewiseLinearModel

    return PiecewiseLinearModel([[-np.inf]], [[np.inf]], [[0.0]], [value])


def kitchen_problem(
    start, cups, targets, config: KitchenPlanConfig, models: dict, *, sweeps: dict | None = None
):
    """The refinement problem of a kitchen plan: one term per action, in execution order.

    Args:
        start: ``[x, y, phi, v]`` of the robot.
        cups: (2, 3) centres of ``cup_0`` and ``cup_1``.
        targets: (m, 3) put targets, one per fetched cup.
        config: ranges and settings.
        models: ``{"goto_pose": TreeModel, "reach": TreeModel}`` duration trees.
        sweeps: a switch ``{"arrival": bool}`` the caller may flip between cost
            evaluations: whether the arm ways are also checked from the corners of the
            drive's arrival tolerances (:func:`~repertoire.studies._kitchen_arm.arm_hits`;
            only with ``config.arrival_check``, which it defaults to). That the arm
            reaches its targets from every corner is checked either way.

    Returns:
        ``(problem, action_names)``.
    """
    from repertoire.planning.refinement import (
        DurationTerm,
        PiecewiseLinearModel,
        RefinementProblem,
    )

    goto = PiecewiseLinearModel.from_leaves(models["goto_pose"].leaves)
    # a drive's term: its predicted duration (the goto tree on each of its one or two
    # legs, summed: drive_time) passed through one linear leaf
    summed = PiecewiseLinearModel([[-np.inf]], [[np.inf]], [[1.0]], [0.0])
    reach = PiecewiseLinearModel.from_leaves(models["reach"].leaves)
    put = _constant_model(put_tail_duration())
    put_up = np.array([0.0, 0.0, PUT_CLEARANCE])
    grip = _constant_model(grip_duration())
    lower, upper, names = parameter_bounds(config)
    start = np.asarray(start, dtype=float)
    m = len(targets)
    up = np.array([0.0, 0.0, config.above_offset])
    terms: list = []
    actions: list[str] = []

    last: dict = {}  # the geometry of the last parameter batch (every term of a cost
    # evaluation gets the same batch) and its arm ways per fetch
    sweeps = {"arrival": config.arrival_check} if sweeps is None else sweeps
    unswept = dataclasses.replace(config, arrival_check=False)

    def geometry(params):
        p = np.atleast_2d(np.asarray(params, dtype=float))
        key = (p.shape, p.tobytes(), bool(sweeps["arrival"]))
        if last.get("key") != key:
            last.update(key=key, g=plan_geometry(p, cups, targets), ways={},
                        invalid=np.zeros(len(p), dtype=bool))  # fmt: skip
        return last["g"]

    def mark(g, valid):  # rows a term of this batch found invalid: the whole cost is +inf,
        if g is last.get("g"):  # so the drives (rolled out, the costliest) skip them
            last["invalid"] |= ~valid

    def ways(g, k):  # arm_ways of fetch k of the geometry geometry() returned last
        if g is not last.get("g"):
            return arm_ways(g, k, config.above_offset)
        if k not in last["ways"]:
            last["ways"][k] = arm_ways(g, k, config.above_offset)
        return last["ways"][k]

    def add(name, model, features, uses):
        terms.append(DurationTerm(model, features, tuple(uses), f"{len(terms)}:{name}"))
        actions.append(name)

    from repertoire.studies._kitchen_arm import (
        arm_hits,
        arm_start,
        arm_ways,
        drive_ends,
        drive_route,
        exit_clear,
        reachable_on_arrival,
    )

    def arm_clear(f, g, k, role):  # the features where the arm's way is clear, else NaN
        hits = arm_hits(g, cups, k, role, config if sweeps["arrival"] else unswept, ways(g, k))
        mark(g, hits < 0)
        return np.where((hits < 0)[:, None], f, np.nan)

    def drive_time(g, k, role, ok):  # (n, 1) predicted drive durations, NaN: no clear route
        a, b = drive_ends(g, k, start, role)  # (only where ok: the stand's exit path)
        if g is last.get("g"):
            ok = ok & ~last["invalid"]
        via, clear = drive_route(g, cups, k, start, config, role, np.flatnonzero(ok))
        mark(g, clear)
        count = (~np.isnan(via[:, :, 0])).sum(axis=1)
        straight = clear & (count == 0)
        t = goto.predict(np.where(straight[:, None], kitchen_goto_features(a, b), np.nan))
        legs = np.flatnonzero(clear & ~straight)  # a leg to each via point and one on
        if legs.size:  # summed leg by leg
            n_via, ends = count[legs], np.concatenate([via[legs], b[legs, None]], axis=1)
            ends[np.arange(legs.size), n_via] = b[legs]
            t[legs] = goto.predict(kitchen_goto_features(a[legs], ends[:, 0]))
            for leg in range(1, int(n_via.max()) + 1):
                on = np.flatnonzero(n_via >= leg)
                t[legs[on]] += goto.predict(kitchen_goto_features(ends[on, leg - 1], ends[on, leg]))
        return np.where(clear, t, np.nan)[:, None]

    for k in range(m):
        base = PER_CUP * k
        stand_ids, carry_ids = [base, base + 1, base + 2], [base + 3, base + 4, base + 5]
        drop_ids = [base + 6, base + 7, base + 8]
        prev_ids = [] if k == 0 else [base - 3, base - 2, base - 1]

        if k:

            def retract(params, k=k):  # straight up out of the placed cup: fixed
                g = geometry(params)
                a = _world_in_chassis(g.drop[:, k - 1], g.target[k - 1])
                return arm_clear(kitchen_reach_features(a, a + up), g, k, "retract")

            add("reach", reach, retract, prev_ids)

        def goto_stand(params, k=k):  # straight, or via a point around the furniture
            g = geometry(params)
            ok = np.ones(g.stand.shape[0], dtype=bool)
            if config.arrival_check:  # the cup in reach wherever the drive stops
                ok &= reachable_on_arrival(g.stand[:, k], (g.cup[k] + up, g.cup[k]))
            if g is last.get("g"):
                ok &= ~last["invalid"]
            # a drop drive can leave the stand (the law, the held arm: exit_clear)
            ok = exit_clear(g.stand[:, k], cups, targets, k, config, np.flatnonzero(ok))
            return drive_time(g, k, "drive_stand", ok)

        add("goto_pose", summed, goto_stand, prev_ids + stand_ids)

        def reach_above(params, k=k):
            g = geometry(params)
            above = _world_in_chassis(g.stand[:, k], g.cup[k] + up)
            start_arm = arm_start(g, k, config.above_offset)  # where the last action left it
            return arm_clear(kitchen_reach_features(start_arm, above), g, k, "above")

        add("reach", reach, reach_above, prev_ids + stand_ids)

        def re_aim(params, k=k):  # the base turned under the arm's swing: aim again
            g = geometry(params)
            a = _world_in_chassis(g.stand[:, k], g.cup[k] + up)
            return kitchen_reach_features(a, a)

        add("reach", reach, re_aim, stand_ids)

        def reach_down(params, k=k):
            g = geometry(params)
            a = _world_in_chassis(g.stand[:, k], g.cup[k])
            return arm_clear(kitchen_reach_features(a + up, a), g, k, "down")

        add("reach", reach, reach_down, stand_ids)
        add("grip", grip, lambda params: np.zeros((np.atleast_2d(params).shape[0], 1)), [])

        def lift_up(params, k=k):  # straight up with the cup, clear of its neighbour
            g = geometry(params)
            a = _world_in_chassis(g.stand[:, k], g.cup[k])
            return arm_clear(kitchen_reach_features(a, a + up), g, k, "lift_up")

        add("reach", reach, lift_up, stand_ids)

        def lift(params, k=k):
            g = geometry(params)
            a = _world_in_chassis(g.stand[:, k], g.cup[k] + up)
            return arm_clear(kitchen_reach_features(a, g.carry[:, k]), g, k, "lift")

        add("reach", reach, lift, stand_ids + carry_ids)

        def goto_drop(params, k=k):  # arm and cup held out: straight, or via a point
            g = geometry(params)
            ok = np.ones(g.stand.shape[0], dtype=bool)
            if config.arrival_check:  # the target in reach wherever the drive stops
                ok &= reachable_on_arrival(g.drop[:, k], (g.target[k] + put_up, g.target[k]))
            return drive_time(g, k, "drive_drop", ok)

        add("goto_pose", summed, goto_drop, stand_ids + drop_ids)

        def reach_put(params, k=k):  # carry the cup over its target (Put then aims again)
            g = geometry(params)
            above = _world_in_chassis(g.drop[:, k], g.target[k] + put_up)
            return arm_clear(kitchen_reach_features(g.carry[:, k], above), g, k, "put_over")

        add("reach", reach, reach_put, carry_ids + drop_ids)

        def put_down(params, k=k):  # lower the cup, open the fingers
            g = geometry(params)
            return arm_clear(np.zeros((g.stand.shape[0], 1)), g, k, "put")

        add("put", put, put_down, drop_ids)
    if actions != action_names(m):
        raise RepertoireError(f"internal: plan actions {actions} differ from action_names")
    return RefinementProblem(tuple(terms), lower, upper, names), actions


# --------------------------------------------------------------------------------------
# Models


def models_folder(models_dir: str) -> Path:
    """``models_dir``, or for ``""`` the kitchen models shipped with the package."""
    from repertoire.studies.refinement_soccer import models_folder as folder

    return folder(models_dir, SHIPPED_MODELS)


def load_kitchen_models(models_dir: str) -> dict:
    """The goToPose and reach duration trees (``MODEL_FILES``) from ``models_dir``."""
    from repertoire.planning.action_models import load_model

    folder = models_folder(models_dir)
    paths = {a: folder / f for a, f in MODEL_FILES.items()}
    missing = [str(p) for p in paths.values() if not p.is_file()]
    if missing:
        raise RepertoireError(
            f"no kitchen action models {missing}: fit them from an actions_kitchen store "
            "with fit_kitchen_plan_models"
        )
    return {a: load_model(p) for a, p in paths.items()}


def fit_kitchen_plan_models(store: str | Path, out_dir: str | Path) -> dict[str, float]:
    """Fits the goToPose and reach duration trees on an ``actions_kitchen`` store's episodes.

    Succeeded episodes only, Table 7 features (``actions_kitchen.FEATURE_FUNCS``),
    3/4 train and 1/4 held out (``fit_action_model``); writes ``MODEL_FILES`` to
    ``out_dir``.

    Returns:
        The held-out MAE per action [s].
    """
    from repertoire.planning.action_models import fit_action_model, save_model
    from repertoire.studies.actions_kitchen import FEATURE_FUNCS
    from repertoire.studies.engine import load_records

    _, records = load_records(store, "actions_kitchen")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    maes = {}
    for action, file in MODEL_FILES.items():
        done = [r for r in records.values() if r.action == action and not r.failed]
        fitted = fit_action_model(done, FEATURE_FUNCS[action], "duration")
        save_model(fitted.model, out_dir / file)
        maes[action] = float(fitted.mae)
    return maes


# --------------------------------------------------------------------------------------
# Execution


@dataclasses.dataclass
class KitchenRun:
    """One kitchen plan executed in physics.

    Attributes:
        status: ``SUCCEEDED`` if every action succeeded and every cup ended within
            ``deliver_tolerance`` of its target, else the failed action's status name
            (``MISSED`` when the actions succeeded but a cup is not at its target).
        durations: each executed plan action's duration [s] (a drive with a via point:
            both its legs).
        total: their sum [s].
        cup_errors: each fetched cup's final distance from its target [m].
        reason: why the failed action failed, where it says (a drive's run-time check),
            else ``""``.
    """

    status: str
    durations: list[float]
    total: float
    cup_errors: list[float]
    reason: str = ""


def run_kitchen_plan(
    config: KitchenPlanConfig, start, cups, targets, params, *, on_sample=None
) -> KitchenRun:
    """Executes the plan of ``params`` with ``run_kitchen_sequence`` (no second executor).

    ``on_sample`` is passed on to it (e.g. a :class:`KitchenTracer`).
    """
    from repertoire.diagrams.kitchen import KitchenScenario, cup_position, run_kitchen_sequence

    steps, owner = executed_steps(plan_geometry(params, cups, targets), 0, start, cups, config)
    scenario = KitchenScenario(
        initial_pose=[float(v) for v in start[:3]],
        time_step=config.time_step,
        cups=list(FETCHED),  # the cups this plan touches: a plant half as costly per step
        cup_positions={name: [float(v) for v in c] for name, c in zip(FETCHED, cups, strict=True)},
    )
    results, diagram, context = run_kitchen_sequence(
        steps, scenario, step_limit=config.step_limit, on_sample=on_sample
    )
    errors = [
        float(np.linalg.norm(cup_position(diagram, context, name) - targets[k]))
        for k, name in enumerate(FETCHED[: len(targets)])
    ]
    status = "SUCCEEDED"
    failed = [r.status for r in results if r.status != "SUCCEEDED"]
    if failed or len(results) < len(steps):
        status = failed[0] if failed else "INCOMPLETE"
    elif max(errors) > config.deliver_tolerance:
        status = "MISSED"
    durations = [0.0] * (owner[len(results) - 1] + 1 if results else 0)
    for i, r in zip(owner, results):  # a drive's via leg and the drive: one plan action
        durations[i] += float(r.duration)
    reason = next((r.reason for r in results if r.reason), "")
    return KitchenRun(status, durations, float(sum(durations)), errors, reason)


class KitchenTracer:
    """``on_sample`` of ``run_kitchen_sequence``: the robot and the cups as a plan runs.

    Keeps every ``every``-th simulator step. After the run, :attr:`rows` holds one row
    per kept step: the time from the plan's start [s], the chassis ``[x, y, phi]``, the
    arm joints ``[lift, yaw, extend]``, the fingers ``[left, right]`` and the centres of
    ``cup_0`` and ``cup_1`` (world); :attr:`steps` the plan step each row belongs to.
    """

    def __init__(self, every: int = 5):
        """Keeps one simulator step in ``every`` (5: every 10 ms at the 2 ms plant step)."""
        self.every = every
        self._rows: list[list[float]] = []
        self._steps: list[int] = []
        self._step, self._offset, self._last, self._calls = 0, 0.0, 0.0, 0

    def __call__(self, diagram, context, step: int) -> None:
        """Records the state of ``context`` (the running step's diagram), every ``every`` calls."""
        from repertoire.diagrams.kitchen import cup_position
        from repertoire.diagrams.soccer import robot_state
        from repertoire.systems.kitchen_actions import ARM_JOINTS, FINGER_JOINTS

        if step != self._step:  # a new step: its clock starts at 0
            self._step, self._offset, self._calls = step, self._offset + self._last, 0
        self._last = context.get_time()
        self._calls += 1
        if (self._calls - 1) % self.every:
            return
        plant = diagram.GetSubsystemByName("plant")
        plant_context = plant.GetMyContextFromRoot(context)
        joints = [plant.GetJointByName(n).GetOnePosition(plant_context)
                  for n in (*ARM_JOINTS, *FINGER_JOINTS)]  # fmt: skip
        cups = [cup_position(diagram, context, name) for name in FETCHED]
        self._rows.append([self._offset + self._last, *robot_state(diagram, context)[:3], *joints,
                           *np.concatenate(cups)])  # fmt: skip
        self._steps.append(step)

    @property
    def rows(self) -> np.ndarray:
        """``(k, 15)`` kept states (see the class docstring)."""
        return np.array(self._rows, dtype=float).reshape(-1, 15)

    @property
    def steps(self) -> np.ndarray:
        """``(k,)`` the plan step of each row."""
        return np.array(self._steps, dtype=int)
