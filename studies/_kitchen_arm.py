"""The arm's ways in the kitchen plans: what the arm, its fingers and a held cup sweep.

Preconditions of :func:`~repertoire.studies._kitchen_plan.kitchen_problem` beside the
base's paths: a stand or drop pose whose base path is clear can still make the arm's
straight joint-space reach (to the cup, lifting it, carrying it over its target, putting
it down) pass through a table or a standing cup, or swing the held-out arm through the
counter while the base drives. Each way is checked with the actions' own geometry
(:func:`~repertoire.systems.kitchen_actions.arm_way_hits`: the gripper centre, the finger
boxes, a held cup's bottom disc) against the furniture and the cups standing at that
point of the plan (:func:`fetch_obstacles`); :func:`arm_collisions` names what a
parameter vector's ways enter.
"""

import numpy as np
from repertoire.studies._kitchen_plan import (
    ARM_SPACING,
    FETCHED,
    PUT_CLEARANCE,
    KitchenPlanConfig,
    PlanGeometry,
    _world_in_chassis,
    plan_geometry,
    to_chassis_z,
)
from repertoire.studies._kitchen_routes import GOAL, START, reached_through, shortest_routes
from repertoire.systems.kitchen_geometry import segment_disc_gaps, segment_gaps

from repertoire.errors import RepertoireError


def fetch_obstacles(cups, targets, k: int, growth: float, own: bool = False):
    """What the arm keeps off during fetch ``k`` (grown by ``growth`` horizontally), and names.

    The kitchen's furniture (boxes) and the standing cups, each an upright disc of the
    cup's radius up to its rim (exactly as the executed actions see them:
    :meth:`~repertoire.systems.kitchen_actions.Reach.standing_cups`): the cups fetched
    before ``k`` on their targets, those after it on their places (both ``FETCHED`` cups
    are in the world in both scenarios) and, with ``own``, cup ``k`` on its place (the
    drive to it and the reach above it; the reach down, the lift, the carry and the put
    start or end inside it, so the actions leave it out there).

    Args:
        cups: (2, 3) centres of ``cup_0`` and ``cup_1`` on their places.
        targets: (m, 3) put targets.
        k: the fetch (0 or 1).
        growth: horizontal growth of every obstacle [m].
        own: include cup ``k`` on its place.

    Returns:
        ``(boxes (b, 6), discs (d, 4), names)``: box rows ``[cx, cy, yaw, half_x, half_y,
        top_z]``, disc rows ``[cx, cy, radius, top_z]``; ``names`` of the boxes, then the
        discs (the obstacle indices of :func:`arm_hits` and :func:`arm_drive_hits`).
    """
    from repertoire.diagrams.kitchen import KITCHEN_OBSTACLE_NAMES, KITCHEN_OBSTACLES
    from repertoire.models.diffdrive.generate import CUP_HALF_HEIGHT, CUP_RADIUS

    names = list(KITCHEN_OBSTACLE_NAMES)
    boxes = np.array(KITCHEN_OBSTACLES, dtype=float)
    boxes[:, 3:5] += growth
    discs = []
    for j, name in enumerate(FETCHED):
        if j != k or own:
            p = np.asarray(targets if j < k else cups, dtype=float)[j]
            discs.append([p[0], p[1], CUP_RADIUS + growth, p[2] + CUP_HALF_HEIGHT])
            names.append(name)
    return boxes, np.array(discs).reshape(-1, 4), names


def arm_start(g: PlanGeometry, k: int, up: float) -> np.ndarray:
    """Where fetch ``k``'s arm starts (chassis frame, (n, 3)): tucked, or out of the last cup.

    Fetch 0 starts with the arm tucked (``ARM_TUCKED``); a later fetch where the retract
    left it, ``up`` above the cup put before, at that drop pose.

    Args:
        g: the plan's geometry (n parameter rows).
        k: the fetch.
        up: the plan's ``above_offset`` [m].
    """
    from repertoire.diagrams.kitchen import ARM_TUCKED
    from repertoire.systems.kitchen_actions import arm_forward

    if k == 0:
        return np.broadcast_to(arm_forward(ARM_TUCKED), g.stand[:, 0, :3].shape)
    return _world_in_chassis(g.drop[:, k - 1], g.target[k - 1] + np.array([0.0, 0.0, up]))


def arm_ways(g: PlanGeometry, k: int, up: float) -> dict[str, tuple]:
    """The straight joint-space arm ways of fetch ``k`` by role (as :func:`plan_steps` runs them).

    Each is ``(poses (n, 4), from (n, 3), to (n, 3), finger span, holds the cup, from_world,
    to_world)``, the points in the chassis frame (a pose's arm joints do not change while
    the base drives), ``from_world`` / ``to_world`` the world points (n, 3) the executed
    reach aims an end at (its joints follow the base's actual pose), None for an end the
    arm keeps in the chassis frame (the tucked arm, the last retract's end, the carry
    point): ``above`` (from the tucked arm or the last retract), ``down`` to the cup,
    ``lift_up``, ``lift`` to the carry point, ``put_over`` its target, ``put`` (lowering;
    the fingers then open) and, for ``k`` > 0, ``retract`` out of the cup put before.

    Args:
        g: the plan's geometry (n parameter rows).
        k: the fetch.
        up: the plan's ``above_offset`` [m].
    """
    from repertoire.models.diffdrive.generate import CUP_RADIUS, FINGER_SIZE
    from repertoire.systems.kitchen_actions import FINGER_CLOSED, FINGER_OPEN
    from repertoire.systems.kitchen_geometry import chassis_points_to_world

    rise, put_rise = np.array([0.0, 0.0, up]), np.array([0.0, 0.0, PUT_CLEARANCE])
    stand, drop = g.stand[:, k], g.drop[:, k]
    held = CUP_RADIUS + FINGER_SIZE[1] / 2  # a finger's inner face on the cup
    opened, holding = [[FINGER_OPEN] * 2] * 2, [[held] * 2] * 2
    closing = [[FINGER_CLOSED, held]] * 2  # Put closes the fingers from where they are
    start = arm_start(g, k, up)
    n = len(stand)
    cup_w, above_w = (np.broadcast_to(p, (n, 3)) for p in (g.cup[k], g.cup[k] + rise))
    over_w, target_w = (np.broadcast_to(p, (n, 3)) for p in (g.target[k] + put_rise, g.target[k]))
    carry_w = chassis_points_to_world(stand, g.carry[:, k])  # the lift's reach aims there
    above, at_cup = _world_in_chassis(stand, above_w), _world_in_chassis(stand, cup_w)
    over = _world_in_chassis(drop, over_w)
    ways = {
        "above": (stand, start, above, opened, False, None, above_w),
        "down": (stand, above, at_cup, opened, False, above_w, cup_w),
        "lift_up": (stand, at_cup, above, holding, True, cup_w, above_w),
        "lift": (stand, above, g.carry[:, k], holding, True, above_w, carry_w),
        "put_over": (drop, g.carry[:, k], over, holding, True, None, over_w),
        "put": (drop, over, _world_in_chassis(drop, target_w), closing, True, over_w, target_w),
    }
    if k:
        put_w = np.broadcast_to(g.target[k - 1], (n, 3))
        put = _world_in_chassis(g.drop[:, k - 1], put_w)
        ways["retract"] = (g.drop[:, k - 1], put, put + rise, opened, False, put_w, put_w + rise)
    return ways


def arrival_offsets(position_tolerance: float, heading_tolerance: float) -> np.ndarray:
    """``(8, 3)`` offsets ``[dx, dy, dphi]`` (chassis frame) where GoToPose may stop.

    The corners of the largest box inscribed in its arrival set (within
    ``position_tolerance`` of the goal, ``heading_tolerance`` of its heading): ``dx, dy =
    +-position_tolerance / sqrt(2)``, ``dphi = +-heading_tolerance``.
    """
    a = position_tolerance / np.sqrt(2.0)
    signs = [(sx, sy, sp) for sx in (1.0, -1.0) for sy in (1.0, -1.0) for sp in (1.0, -1.0)]
    return np.array(signs) * [a, a, heading_tolerance]


def offset_poses(pose, offsets) -> np.ndarray:
    """``(m, n, 4)``: the poses ``pose`` (n, 4) moved by each chassis-frame offset (m, 3)."""
    pose, offsets = np.atleast_2d(pose), np.atleast_2d(offsets)
    c, s = np.cos(pose[:, 2]), np.sin(pose[:, 2])
    dx, dy, dphi = (offsets[:, i : i + 1] for i in range(3))
    out = np.repeat(pose[None], len(offsets), axis=0)
    out[..., 0] += c * dx - s * dy
    out[..., 1] += s * dx + c * dy
    out[..., 2] += dphi
    return out


def reachable_on_arrival(pose, points) -> np.ndarray:
    """``(n,)`` True where the arm reaches each world point from every arrival corner.

    ``pose`` (n, 4) stand or drop poses, ``points`` world points ((3,) or (n, 3) each) a
    reach there aims at; the corners are :func:`arrival_offsets` of GoToPose's
    tolerances (a reach from where the drive stopped fails at once when its target is out
    of the joints' ranges).
    """
    from repertoire.systems.go_to_pose import GOTO_GAINS
    from repertoire.systems.kitchen_actions import arm_inverse_rows

    pose = np.atleast_2d(pose)
    offsets = arrival_offsets(GOTO_GAINS["position_tolerance"], GOTO_GAINS["heading_tolerance"])
    at = offset_poses(pose, offsets).reshape(-1, 4)
    ok = np.ones(len(pose), dtype=bool)
    for point in points:
        world = np.broadcast_to(np.asarray(point, dtype=float), (len(pose), 3))
        inside = arm_inverse_rows(_world_in_chassis(at, np.tile(world, (len(offsets), 1))))[1]
        ok &= inside.reshape(len(offsets), len(pose)).all(axis=0)
    return ok


def arm_hits(
    g: PlanGeometry, cups, k: int, role: str, config: KitchenPlanConfig, ways: dict | None = None
) -> np.ndarray:
    """Per parameter row, what the arm way ``role`` of fetch ``k`` enters (:func:`arm_ways`).

    :func:`~repertoire.systems.kitchen_actions.arm_way_hits` (the gripper centre, the
    finger boxes and a held cup's bottom disc) against :func:`fetch_obstacles` grown by
    ``arm_clearance`` (cup ``k`` too on the way ``above`` it, and the fingers alone
    against the cup the way ``down`` ends in or the ``retract`` starts in, as the
    executed reach sees them), sampled every ``ARM_SPACING``; a ``put`` also opens the
    fingers at its target. With ``config.arrival_check`` a way clear from its stand or
    drop pose is checked again from each of :func:`arrival_offsets` (GoToPose stops
    anywhere within its tolerances; the executed reach aims its world ends from there:
    ``from_world``, ``to_world`` of :func:`arm_ways`), and counts only if clear from all.

    Args:
        g: the plan's geometry (n parameter rows).
        cups: (2, 3) centres of both cups on their places.
        k: the fetch.
        role: a role of :func:`arm_ways`.
        config: ``above_offset``, ``arm_clearance`` and ``arrival_check``.
        ways: ``arm_ways(g, k, config.above_offset)`` if already at hand.

    Returns:
        ``(n,)`` indices into :func:`fetch_obstacles`' names (the names' length for the
        fingers against the cup of ``down`` or ``retract``); -1 where the way is clear,
        the names' length + 1 where an end lies out of the arm's reach.
    """
    from repertoire.diagrams.kitchen import ARM_TRACKING
    from repertoire.models.diffdrive.generate import CUP_HALF_HEIGHT, CUP_RADIUS
    from repertoire.systems.go_to_pose import GOTO_GAINS
    from repertoire.systems.kitchen_actions import (
        FINGER_CLOSED,
        FINGER_OPEN,
        arm_inverse_rows,
        arm_way_hits,
        fingers_in_boxes,
    )

    ways = arm_ways(g, k, config.above_offset) if ways is None else ways
    if role not in ways:
        raise RepertoireError(f"role must be one of {sorted(ways)} for fetch {k}, got {role!r}")
    pose, a_from, a_to, span, held, from_world, to_world = ways[role]
    k_world, own = (k - 1, False) if role == "retract" else (k, role == "above")
    boxes, discs, names = fetch_obstacles(cups, g.target, k_world, config.arm_clearance, own)
    cup = (CUP_HALF_HEIGHT, CUP_RADIUS) if held else None
    # the cup the open fingers go down to (or up from, the retract): the fingers only,
    # as the executed reach sees it (Reach.standing_cups)
    fingers_only = np.zeros((0, 4))
    if role in ("down", "retract"):
        j = k_world if role == "down" else k - 1
        p = np.asarray(cups if role == "down" else g.target, dtype=float)[j]
        fingers_only = np.array([[p[0], p[1], CUP_RADIUS + config.arm_clearance,
                                  p[2] + CUP_HALF_HEIGHT]])  # fmt: skip

    def check(pose, a_from, a_to):
        (q0, ok0), (q1, ok1) = arm_inverse_rows(a_from), arm_inverse_rows(a_to)
        # the way the servoed joints take (ARM_TRACKING), as the executed actions check it
        hit = arm_way_hits(pose, q0, q1, span, boxes, 0.0, cup, ARM_SPACING, discs,
                           fingers_only, ARM_TRACKING)  # fmt: skip
        if role == "put":
            opening = [[FINGER_CLOSED, FINGER_OPEN]] * 2
            release = fingers_in_boxes(pose, q1, opening, boxes, 0.0, discs)
            hit = np.where(hit < 0, release, hit)
        return np.where(ok0 & ok1, hit, len(names) + 1)

    hit = check(pose, a_from, a_to)
    rows = np.flatnonzero(hit < 0)
    if not config.arrival_check or rows.size == 0:
        return hit
    offsets = arrival_offsets(GOTO_GAINS["position_tolerance"], GOTO_GAINS["heading_tolerance"])
    m = len(offsets)
    at = offset_poses(pose[rows], offsets).reshape(-1, 4)  # (m * rows, 4), offset-major
    ends = []
    for chassis, world in ((a_from, from_world), (a_to, to_world)):
        if world is None:  # kept in the chassis frame
            ends.append(np.tile(chassis[rows], (m, 1)))
        else:
            ends.append(_world_in_chassis(at, np.tile(world[rows], (m, 1))))
    moved = check(at, *ends).reshape(m, rows.size)
    entered = moved >= 0
    first = moved[np.argmax(entered, axis=0), np.arange(rows.size)]  # the first offset's
    hit[rows] = np.where(entered.any(axis=0), first, -1)
    return hit


def arm_drive_hits(a, b, arm, boxes, clearance: float, held: bool, discs=None) -> np.ndarray:
    """Per row, the first obstacle the still arm enters while the base drives straight ``a -> b``.

    The arm at chassis point ``arm`` (n, 3) sweeps a disc of its horizontal distance from
    the base's centre plus ``FINGER_REACH`` and ``clearance`` (every heading: GoToPose
    turns) along the path (exact: :func:`~repertoire.systems.kitchen_geometry.segment_gaps`
    for the boxes, the segment's distance from a disc's centre less its radius for the
    discs), against the obstacles whose top is above the fingers' bottom (or, ``held``,
    the cup's bottom).

    Args:
        a: (n, >= 2) start poses of the base. b: (n, >= 2) end poses.
        arm: (n, 3) the gripper centre in the chassis frame.
        boxes: (k, 6) obstacle boxes (not grown).
        clearance: added to the arm's reach [m].
        held: a cup hangs from the fingers.
        discs: (j, 4) upright discs ``[cx, cy, radius, top_z]`` (standing cups).

    Returns:
        ``(n,)`` obstacle indices (boxes, then discs), -1 where clear.
    """
    radius, lowest = arm_reach(arm, clearance, held)
    boxes = np.asarray(boxes, dtype=float).reshape(-1, 6)
    discs = np.asarray(discs if discs is not None else [], dtype=float).reshape(-1, 4)
    a, b = (np.broadcast_to(np.atleast_2d(p)[:, :2], (len(radius), 2)) for p in (a, b))
    # every path against every obstacle at once; one counts where its top is above the
    # arm's lowest point
    gaps = np.hstack([segment_gaps(a, b, boxes), segment_disc_gaps(a, b, discs)])
    tops = np.concatenate([boxes[:, 5], discs[:, 3]])
    blocked = (gaps < radius[:, None]) & (lowest[:, None] <= tops)
    return np.where(blocked.any(axis=1), np.argmax(blocked, axis=1), -1)


def arm_reach(arm, clearance: float, held: bool) -> tuple[np.ndarray, np.ndarray]:
    """``(reach, lowest)`` of the still arm per row of chassis arm points ``arm`` (n, 3).

    The horizontal reach of the fingers (or a held cup) from the base's centre plus
    ``clearance``, and the world height of their lowest point (see :func:`arm_drive_hits`).
    """
    from repertoire.models.diffdrive.generate import CUP_HALF_HEIGHT
    from repertoire.systems.kitchen_actions import FINGER_HALF, FINGER_REACH

    arm = np.atleast_2d(arm)
    reach = np.hypot(arm[:, 0], arm[:, 1]) + FINGER_REACH + clearance
    z_world = arm[:, 2] - to_chassis_z(0.0)
    return reach, z_world - max(FINGER_HALF[2], CUP_HALF_HEIGHT if held else 0.0)


def law_drive_hits(a, b, arm, boxes, radius: float, clearance: float, held: bool, discs=None):
    """Per row, the first obstacle GoToPose's drive ``a -> b`` brings the base or the arm into.

    GoToPose's law arcs off the straight path (it turns while it drives), so the drive is
    predicted by the law itself (:func:`~repertoire.systems.goto_law.rollout_hits`: the
    compiled law of the LeafSystem, at the kitchen's control period and GoToPose's
    gains, on a kinematic unicycle) and checked as the run-time check
    (:class:`~repertoire.systems.kitchen_drive.KitchenGoToPose`) checks it: at each
    update the base's stopping run (at ``KITCHEN_BRAKING``), the footprint (``radius``)
    against the boxes first, then the still arm (:func:`arm_drive_hits`' test: its reach
    plus ``clearance`` at every heading, against the obstacles whose top is above its
    lowest point). The first update that enters one names it (boxes, then ``discs``);
    -1 where clear. ``a`` (n, 4) start states, ``b`` (n, 4) targets at rest, ``arm``
    (n, 3) chassis arm points.
    """
    boxes = np.asarray(boxes, dtype=float).reshape(-1, 6)
    discs = np.asarray(discs if discs is not None else [], dtype=float).reshape(-1, 4)
    a = np.atleast_2d(np.asarray(a, dtype=float))
    n = len(a)
    b = np.broadcast_to(np.atleast_2d(np.asarray(b, dtype=float)), a.shape)
    arm = np.broadcast_to(np.atleast_2d(np.asarray(arm, dtype=float)), (n, 3))
    # a refinement asks again for many drives (a GA's children keep most of a parent's
    # genes): the results of the drives met before are looked up
    world = (boxes.tobytes(), discs.tobytes(), float(radius), float(clearance), bool(held))
    rows = np.ascontiguousarray(np.hstack([a[:, :4], b[:, :4], arm]))
    keys = [(world, r.tobytes()) for r in rows]
    out = np.array([_LAW_MEMO.get(key, -2) for key in keys], dtype=int)
    new = np.flatnonzero(out == -2)
    if new.size:
        out[new] = _law_drive_hits(a[new], b[new], arm[new], boxes, radius, clearance, held, discs)
        if len(_LAW_MEMO) + new.size > LAW_MEMO_SIZE:
            _LAW_MEMO.clear()
        _LAW_MEMO.update((keys[i], int(out[i])) for i in new)
    return out


#: How many drives :func:`law_drive_hits` remembers (all are forgotten when full).
LAW_MEMO_SIZE = 200_000
_LAW_MEMO: dict = {}


def _law_drive_hits(a, b, arm, boxes, radius, clearance, held, discs) -> np.ndarray:
    """:func:`law_drive_hits` computed (the arrays checked and shaped)."""
    from repertoire.diagrams.kitchen import KITCHEN_BRAKING, KitchenScenario
    from repertoire.systems.go_to_pose import GOTO_GAINS, gains_vector
    from repertoire.systems.goto_law import rollout_hits

    period = KitchenScenario.control_period
    reach, lowest = arm_reach(arm, clearance, held)
    tops = np.concatenate([boxes[:, 5], discs[:, 3]])
    limits = np.where(lowest[:, None] <= tops, reach[:, None], -np.inf)
    last = int(np.floor(GOTO_GAINS["timeout"] / period + 1e-9))
    g, brake = gains_vector(GOTO_GAINS), np.array(KITCHEN_BRAKING, dtype=float)
    return rollout_hits(np.ascontiguousarray(a), np.ascontiguousarray(b), g, period, last,
                        brake, boxes, discs, limits, float(radius))  # fmt: skip


def drive_ends(g: PlanGeometry, k: int, start, role: str) -> tuple[np.ndarray, np.ndarray]:
    """Start and end poses ``(n, 4)`` of fetch ``k``'s drive ``role`` (see :func:`drive_hits`)."""
    if role == "drive_stand":
        prev = g.drop[:, k - 1] if k else np.broadcast_to(start, g.stand[:, k].shape)
        return prev, g.stand[:, k]
    if role == "drive_drop":
        return g.stand[:, k], g.drop[:, k]
    raise RepertoireError(f"role must be 'drive_stand' or 'drive_drop', got {role!r}")


def _drive_arm(g: PlanGeometry, cups, k: int, config: KitchenPlanConfig, role: str):
    """``(arm (n, 3), held, boxes, discs, names)`` of fetch ``k``'s drive ``role``."""
    drive_ends(g, k, np.zeros(4), role)  # the role's name checked
    if role == "drive_stand":
        boxes, discs, names = fetch_obstacles(cups, g.target, k, 0.0, own=True)
        return arm_start(g, k, config.above_offset), False, boxes, discs, names
    boxes, discs, names = fetch_obstacles(cups, g.target, k, 0.0)
    return g.carry[:, k], True, boxes, discs, names


def drive_hits(
    g: PlanGeometry, cups, k: int, start, config: KitchenPlanConfig, role: str, via=None
):
    """:func:`arm_drive_hits` of fetch ``k``'s drive ``role``: ``drive_stand`` or ``drive_drop``.

    ``drive_stand``: from the start or the last drop pose to the stand, the arm tucked or
    where the last retract left it, cup ``k`` standing on its place; ``drive_drop``: from
    the stand to the drop pose with the cup held at the carry point. With ``via``, each
    row drives through its via points (not NaN) in order, one leg to each and on
    (:func:`route_poses`: at rest, facing the next point).

    Args:
        g: the plan's geometry. cups: (2, 3) both cups on their places.
        k: the fetch. start: the robot's start ``[x, y, phi, v]``.
        config: ``above_offset`` and ``arm_clearance``. role: the drive.
        via: ``(n, >= 2)`` one via point per row or ``(n, l, >= 2)`` up to ``l`` (NaN:
            none; a row's via points first, then its NaNs), as :func:`drive_route` gives.

    Returns:
        ``(hits, names)``: per row the index of the first obstacle in ``names``
        (:func:`fetch_obstacles`) the first leg that enters one enters, -1 where clear.
    """
    from repertoire.diagrams.kitchen import ROBOT_RADIUS

    a, b = drive_ends(g, k, start, role)
    arm, held, boxes, discs, names = _drive_arm(g, cups, k, config, role)
    radius, c = ROBOT_RADIUS + config.clearance, config.arm_clearance
    if via is None:
        return law_drive_hits(a, b, arm, boxes, radius, c, held, discs), names
    via = np.asarray(via, dtype=float)
    via = via[:, None, :] if via.ndim == 2 else via
    poses = route_poses(via, b)
    count = (~np.isnan(via[:, :, 0])).sum(axis=1)
    hits = np.full(len(b), -1)
    for leg in range(via.shape[1] + 1):  # leg l: from via l - 1 (or a) to via l (or b)
        rows = np.flatnonzero((count >= leg) & (hits < 0))
        if rows.size == 0:
            break
        frm = a[rows] if leg == 0 else poses[rows, leg - 1]
        to = np.where((count[rows] > leg)[:, None], poses[rows, min(leg, via.shape[1] - 1)],
                      b[rows])  # fmt: skip
        hits[rows] = law_drive_hits(frm, to, arm[rows], boxes, radius, c, held, discs)
    return hits, names


def via_pose(via, b) -> np.ndarray:
    """Via poses ``[x, y, phi, 0]`` at points ``via`` ``(n, >= 2)`` facing the ends ``b``."""
    via = np.atleast_2d(via)[:, :2]
    to_end = np.atleast_2d(b)[:, :2] - via
    return np.column_stack([via, np.arctan2(to_end[:, 1], to_end[:, 0]), np.zeros(len(via))])


def route_poses(via, b) -> np.ndarray:
    """``(n, l, 4)`` poses at via points ``via`` ``(n, l, >= 2)``, each facing the next point.

    A via point faces the row's next via point, the last one (before the NaN rows) the
    drive's end ``b`` (n, >= 2) (:func:`via_pose`, at rest); NaN via points stay NaN.
    """
    via = np.asarray(via, dtype=float)[:, :, :2]
    out = np.full(via.shape[:2] + (4,), np.nan)
    for leg in range(via.shape[1]):
        ahead = via[:, leg + 1] if leg + 1 < via.shape[1] else np.full_like(via[:, leg], np.nan)
        ahead = np.where(np.isnan(ahead[:, :1]), np.atleast_2d(b)[:, :2], ahead)
        out[:, leg] = via_pose(via[:, leg], ahead)
    out[np.isnan(via[:, :, 0])] = np.nan
    return out


def via_points(clearance: float) -> np.ndarray:
    """Candidate via points ``(m, 2)`` of drives around the furniture.

    The corners of the counter's and the tables' footprints grown by the robot's radius,
    ``clearance`` and 1 cm (there a robot clears its own box), those whose footprint
    (``ROBOT_RADIUS + clearance``) clears every box and lies in the kitchen's workspace.
    """
    from repertoire.diagrams.kitchen import KITCHEN_OBSTACLES, KITCHEN_WORKSPACE, ROBOT_RADIUS
    from repertoire.studies._kitchen_plan import footprint_clear

    grow = ROBOT_RADIUS + clearance + 0.01
    points = []
    for cx, cy, yaw, hx, hy, _ in KITCHEN_OBSTACLES[:3]:  # counter, table_0, table_1
        c, s = np.cos(yaw), np.sin(yaw)
        for u, w in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
            du, dw = u * (hx + grow), w * (hy + grow)
            points.append([cx + c * du - s * dw, cy + s * du + c * dw])
    points = np.array(points)
    x0, x1, y0, y1 = KITCHEN_WORKSPACE
    inside = (
        (points[:, 0] >= x0) & (points[:, 0] <= x1) & (points[:, 1] >= y0) & (points[:, 1] <= y1)
    )
    ok = inside & footprint_clear(points, KITCHEN_OBSTACLES, ROBOT_RADIUS + clearance)
    return points[ok]


def corners_seen(points, radius: float) -> np.ndarray:
    """``(m, m)``: True where the footprint (``radius``) drives straight from point i to j.

    Along :func:`~repertoire.studies._kitchen_plan.path_clear` against the furniture
    (``KITCHEN_OBSTACLES``); False on the diagonal.
    """
    from repertoire.diagrams.kitchen import KITCHEN_OBSTACLES
    from repertoire.studies._kitchen_plan import path_clear

    m = len(points)
    clear = path_clear(np.repeat(points, m, axis=0), np.tile(points, (m, 1)), KITCHEN_OBSTACLES,
                       radius).reshape(m, m)  # fmt: skip
    return clear & ~np.eye(m, dtype=bool)


def clear_to_points(ends, points, radius: float, *, towards: bool = True) -> np.ndarray:
    """``(n, m)``: True where the footprint drives straight from ``ends[i]`` to ``points[j]``.

    With ``towards=False`` the legs run the other way, from each point to each end.
    Along :func:`~repertoire.studies._kitchen_plan.path_clear` against the furniture.
    """
    from repertoire.diagrams.kitchen import KITCHEN_OBSTACLES
    from repertoire.studies._kitchen_plan import path_clear

    ends = np.atleast_2d(ends)[:, :2]
    n, m = len(ends), len(points)
    e, p = np.repeat(ends, m, axis=0), np.tile(points, (n, 1))
    frm, to = (e, p) if towards else (p, e)
    return path_clear(frm, to, KITCHEN_OBSTACLES, radius).reshape(n, m)


def reaches(a, point, clearance: float) -> np.ndarray:
    """``(n,)`` True where a footprint at ``a`` (n, >= 2) reaches ``point`` by straight legs.

    Straight, or through any number of :func:`via_points`: every leg's footprint
    (``ROBOT_RADIUS + clearance``) clear of the furniture
    (:func:`~repertoire.studies._kitchen_plan.path_clear`; no drive law).

    Raises:
        RepertoireError: ``point`` is not finite or its footprint enters a piece of
            furniture (no start reaches it), naming it.
    """
    from repertoire.diagrams.kitchen import KITCHEN_OBSTACLE_NAMES, KITCHEN_OBSTACLES, ROBOT_RADIUS
    from repertoire.studies._kitchen_plan import path_clear
    from repertoire.systems.kitchen_geometry import box_gaps

    a = np.atleast_2d(np.asarray(a, dtype=float))[:, :2]
    point = np.asarray(point, dtype=float)[:2]
    radius = ROBOT_RADIUS + clearance
    if not np.all(np.isfinite(point)):
        raise RepertoireError(f"point must be finite, got {point.tolist()}")
    gaps = box_gaps(point[None], KITCHEN_OBSTACLES)[0]
    if np.any(gaps < radius):
        inside = KITCHEN_OBSTACLE_NAMES[int(np.argmin(gaps - radius))]
        raise RepertoireError(f"point {point.tolist()} lies inside {inside} grown by the "
                              f"footprint radius {radius}: nothing reaches it")  # fmt: skip
    points = via_points(clearance)
    m = len(points)
    seen = corners_seen(points, radius)
    on = reached_through(seen, clear_to_points(point, points, radius, towards=False)[0])
    ok = path_clear(a, np.broadcast_to(point, a.shape), KITCHEN_OBSTACLES, radius)
    rest = np.flatnonzero(~ok)
    if rest.size and m:
        ok[rest] = (clear_to_points(a[rest], points, radius) & on[None, :]).any(axis=1)
    return ok


def least_carry(config: KitchenPlanConfig) -> np.ndarray:
    """The carry point (chassis frame) whose held arm blocks the fewest drives.

    Of the carry ranges: the least horizontal reach (the extension's lower end, at the yaw
    end farthest from straight ahead: the reach grows with ``cos(yaw)`` and the extension)
    and the highest cup, so its lowest point is above the most obstacles
    (:func:`arm_reach`). A drive this arm cannot make, no carry point makes.
    """
    from repertoire.studies._kitchen_plan import arm_point

    yaws = np.array(config.carry_yaw_range, dtype=float)
    yaw = yaws[np.argmin(np.cos(yaws))]
    z = to_chassis_z(config.carry_z_range[1])
    return arm_point(yaw, config.carry_extend_range[0], z)


def exit_clear(stand, cups, targets, k: int, config: KitchenPlanConfig, rows=None):
    """``(n,)`` True where fetch ``k``'s drop drive can leave the stand for its exit point.

    The drive from each stand pose (n, 4) to :func:`~repertoire.studies._kitchen_plan.exit_point`
    (at rest, facing target ``k``) must be clear as a drop drive is checked
    (:func:`route`: the law's path, the footprint and the held arm, through any number of
    corners) with the held arm at :func:`least_carry`; straight footprint legs
    (:func:`reaches`) alone let a stand behind ``table_0`` pass from which the law, turning
    as it drives, brings the footprint into the table whatever carry and drop follow.
    Rows not in ``rows`` (default all) are not clear.
    """
    from repertoire.studies._kitchen_plan import exit_point

    stand = np.atleast_2d(np.asarray(stand, dtype=float))
    target = np.asarray(targets, dtype=float)[k]
    exit_ = exit_point(target)
    n = len(stand)
    rows = np.arange(n) if rows is None else np.flatnonzero(np.isin(np.arange(n), rows))
    rows = rows[reaches(stand[rows], exit_, config.clearance)]
    phi = np.arctan2(target[1] - exit_[1], target[0] - exit_[0])
    end = np.broadcast_to([exit_[0], exit_[1], phi, 0.0], (n, 4))
    arm = np.broadcast_to(least_carry(config), (n, 3))
    boxes, discs, _ = fetch_obstacles(cups, targets, k, 0.0)
    return route(stand, end, arm, True, boxes, discs, config, rows)[1]


def drive_route(g: PlanGeometry, cups, k: int, start, config: KitchenPlanConfig, role: str,
                rows=None) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Fetch ``k``'s drive ``role``: straight where clear, else the shortest clear route.

    GoToPose drives without avoiding anything, so a plan's drive must be clear: the
    base's footprint (``ROBOT_RADIUS + clearance``) along each straight leg
    (:func:`~repertoire.studies._kitchen_plan.path_clear`), and the footprint and the
    held-out arm along the path GoToPose's law drives (:func:`drive_hits`). The route is
    the shortest (the legs' straight lengths summed) through any number of
    :func:`via_points` (each at rest, facing the next point) whose legs are all clear
    (:func:`shortest_routes`; the straight drive where it is clear).

    Args:
        g, cups, k, start, config, role: as for :func:`drive_hits`.
        rows: the parameter rows to route (default all); the others are not clear.

    Returns:
        ``(via (n, l, 4), ok (n,))``: each row's via poses ``[x, y, phi, 0]`` in driving
        order, NaN after them (``l`` >= 1 the most any row has; all NaN where straight or
        not clear), and whether the drive is clear.
    """
    a, b = drive_ends(g, k, start, role)
    arm, held, boxes, discs, _ = _drive_arm(g, cups, k, config, role)
    return route(a, b, arm, held, boxes, discs, config, rows)


def route(a, b, arm, held: bool, boxes, discs, config: KitchenPlanConfig, rows=None):
    """:func:`drive_route` of drives ``a -> b`` ((n, 4) each) with the arm at ``arm`` (n, 3).

    ``held``, ``boxes`` and ``discs`` as for :func:`law_drive_hits`; ``config`` gives the
    clearances; ``rows`` as for :func:`drive_route`, whose ``(via, ok)`` it returns.
    """
    from repertoire.diagrams.kitchen import KITCHEN_OBSTACLES, ROBOT_RADIUS
    from repertoire.studies._kitchen_plan import path_clear

    n = len(b)
    rows = np.arange(n) if rows is None else np.flatnonzero(np.isin(np.arange(n), rows))
    radius, c = ROBOT_RADIUS + config.clearance, config.arm_clearance
    points = via_points(config.clearance)
    m = len(points)
    ok = np.zeros(n, dtype=bool)
    # the straight drive first where its footprint path is clear (no route is shorter)
    straight = rows[path_clear(a[rows], b[rows], KITCHEN_OBSTACLES, radius)]
    ok[straight] = law_drive_hits(a[straight], b[straight], arm[straight], boxes, radius, c, held,
                                  discs) < 0  # fmt: skip
    rows = rows[~ok[rows]]
    ar, br = a[rows], b[rows]
    seen = corners_seen(points, radius)
    from_a = clear_to_points(ar, points, radius).reshape(-1, m)
    to_b = clear_to_points(br, points, radius, towards=False).reshape(-1, m)
    direct = np.zeros(len(rows), dtype=bool)  # not clear, or not clear along the law

    def xy(nodes, sub):  # the nodes' points, vectorised
        out = np.where((nodes == GOAL)[:, None], br[sub, :2], ar[sub, :2])
        corner = nodes >= 0
        out[corner] = points[nodes[corner]]
        return out

    def legs_clear(sub, legs):  # legs (u, v, w): from u facing v to v facing w, at rest
        u, v, w = (np.array([GOAL if x is None else x for x in c], dtype=int) for c in zip(*legs))
        frm = np.where((u == START)[:, None], ar[sub], via_pose(xy(u, sub), xy(v, sub)))
        to = np.where((v == GOAL)[:, None], br[sub], via_pose(xy(v, sub), xy(w, sub)))
        arms = arm[rows[sub]]
        return law_drive_hits(frm, to, arms, boxes, radius, config.arm_clearance, held, discs) < 0

    routes = shortest_routes(ar, br, points, seen, from_a, to_b, direct, legs_clear)
    ok[rows] = [route is not None for route in routes]
    most = max([1] + [len(route) for route in routes if route is not None])
    via = np.full((n, most, 2), np.nan)
    for r, route in zip(rows, routes, strict=True):
        if route:
            via[r, : len(route)] = points[list(route)]
    return route_poses(via, b), ok


def arm_collisions(params, start, cups, targets, config: KitchenPlanConfig) -> list[tuple]:
    """What the arm's ways and drives of one parameter vector enter (a diagnosis).

    Args:
        params: one parameter vector (9 per fetched cup).
        start: the robot's start ``[x, y, phi, v]``.
        cups: (2, 3) both cups on their places. targets: (m, 3) put targets.
        config: the plan's config.

    Returns:
        ``(fetch k, role, obstacle name)`` per way (roles of :func:`arm_ways`) or drive
        (:func:`drive_hits`) that enters an obstacle; empty when all are clear.
    """
    g, found = plan_geometry(params, cups, targets), []
    for k in range(len(targets)):
        for role in arm_ways(g, k, config.above_offset):
            hit = arm_hits(g, cups, k, role, config)[0]
            own = role == "above"
            names = fetch_obstacles(cups, targets, k - (role == "retract"), 0.0, own)[2]
            if hit >= 0:
                own = FETCHED[k - (role == "retract")]  # the fingers against its cup
                found.append((k, role, (names + [own, "out of reach"])[hit]))
        for role in ("drive_stand", "drive_drop"):
            hit, names = drive_hits(g, cups, k, start, config, role)
            if hit[0] >= 0:
                found.append((k, role, names[hit[0]]))
    return found
