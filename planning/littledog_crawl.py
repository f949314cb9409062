"""LittleDog's statically stable crawl: foothold CHOICE and kinematic EXECUTION, kept apart.

Stolle et al. taught LittleDog its steps with a joystick and inverse kinematics.
This module is the scripted stand-in for that operator, in two independent parts:

- **Choice** (:func:`choose_footholds`): walks a virtual body along a heading and,
  for each foot in crawl order (left hind, left front, right hind, right front),
  inspects the board's exact height function around the nominal foothold and
  picks the nearest spot that is flat (no edge or steep spot within
  ``edge_radius``) and not far above or below the other feet. It returns typed
  :class:`CrawlStep` s (foot index, target foot centre ``p_WF``).
- **Execution** (:func:`plan_crawl`): turns *any* sequence of crawl steps (chosen
  here, or planned by a footstep planner) into joint-angle commands at
  ``dt``: before a foot lifts, the body is shifted level over the centroid of the
  three stance feet; the foot then rises, travels with ``clearance`` above the
  highest terrain under its path, and comes down; every leg's angles come from the
  closed-form leg IK. The result, a :class:`CrawlPlan`, is fed to the plant's PD
  (see :func:`repertoire.diagrams.littledog_worlds.build_crawl_playback`).

Foot positions ``p_WF`` are foot-sphere centres in the world (the sphere touches
the terrain at ``p_WF - [0, 0, FOOT_RADIUS]``). Body poses are 6-vectors
``[x, y, z, roll, pitch, yaw]`` (:mod:`repertoire.models.littledog.pose`).
"""

import dataclasses
import math
import time

import numpy as np
from repertoire.models.littledog import (
    FOOT_RADIUS,
    LEGS,
    STANDING_HEIGHT,
    leg_ik,
    nominal_foot_positions,
)
from repertoire.models.littledog.kinematics import LEG_GEOMETRY, leg_ik_feasible
from repertoire.models.littledog.pose import rotation_from_rpy, world_to_body
from repertoire.planning.step_library import segment_recording

from repertoire.errors import RepertoireError

CRAWL_ORDER: list[int] = [2, 0, 3, 1]
"""Crawl gait order as ``LEGS`` indices: left hind, left front, right hind, right front."""


class CrawlError(RepertoireError):
    """A crawl cannot be chosen or executed (no safe foothold, unreachable pose, time limit)."""


@dataclasses.dataclass(frozen=True)
class CrawlStep:
    """One crawl step: which foot moves and where its centre goes.

    Attributes:
        foot: index into ``LEGS`` (0 lf, 1 rf, 2 lh, 3 rh).
        p_WF: target foot-sphere centre in the world (m), shape (3,).
    """

    foot: int
    p_WF: np.ndarray

    def __post_init__(self) -> None:
        if int(self.foot) != self.foot or not 0 <= self.foot < 4:
            raise CrawlError(f"CrawlStep.foot must be 0..3 (LEGS {LEGS}), got {self.foot!r}")
        p = np.asarray(self.p_WF, dtype=float)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise CrawlError(f"CrawlStep.p_WF must be 3 finite numbers, got {self.p_WF!r}")
        object.__setattr__(self, "foot", int(self.foot))
        object.__setattr__(self, "p_WF", p)


@dataclasses.dataclass
class CrawlParams:
    """Timing and geometry of the crawl (YAML-loadable).

    Attributes:
        stride: how far each foot (and the body, per gait cycle) advances (m).
        shift_time: time to shift the body over the support triangle (s).
        swing_time: time of one foot's swing (s).
        settle_time: pause with four feet down after touchdown (s).
        lift_delay: pause after the body shift before the foot lifts (s).
        shift_margin: the body goes this much beyond the support triangle's centroid,
            away from the foot about to lift (m).
        clearance: swing height above the highest terrain under the path (m).
        press: how far below its foothold a stance foot is commanded, to keep it loaded (m).
        standing_height: body origin above the mean ground under the feet (m).
        search_radius: footholds are searched this far around the nominal one (m).
        search_step: grid spacing of the foothold search (m).
        edge_radius: a foothold needs flat terrain within this radius (m).
        flat_tolerance: largest height spread within ``edge_radius`` counted as flat (m).
        max_rise: largest height difference from the other feet's mean ground (m).
        dt: sample period of the joint commands (s).
        ground_tolerance: how far a step's foot centre may lie above or below the exact
            ground plus the foot radius (m); :func:`plan_crawl` refuses a step whose foothold
            is farther off (a foot commanded into a rock, or into the air where it never
            loads). Half the foot radius, as the transfer's support tolerance: physics
            recordings stand within 1 mm, transferred steps within that tolerance.
    """

    stride: float = 0.07
    shift_time: float = 0.5
    swing_time: float = 0.5
    settle_time: float = 0.15
    lift_delay: float = 0.1
    shift_margin: float = 0.01
    clearance: float = 0.025
    press: float = 0.003
    standing_height: float = 0.14
    search_radius: float = 0.04
    search_step: float = 0.005
    edge_radius: float = 0.02
    flat_tolerance: float = 0.003
    max_rise: float = 0.045
    dt: float = 0.01
    ground_tolerance: float = 0.005

    def validate(self) -> None:
        """Raises CrawlError naming any field outside its range."""
        ranges = {
            "stride": (0.0, 0.12),
            "shift_time": (0.05, 5.0),
            "swing_time": (0.05, 5.0),
            "settle_time": (0.0, 5.0),
            "lift_delay": (0.0, 5.0),
            "shift_margin": (0.0, 0.04),
            "clearance": (0.0, 0.08),
            "press": (0.0, 0.02),
            "standing_height": (0.08, 0.17),
            "search_radius": (0.0, 0.1),
            "search_step": (0.001, 0.05),
            "edge_radius": (0.0, 0.05),
            "flat_tolerance": (0.0, 0.05),
            "max_rise": (0.0, 0.08),
            "dt": (0.001, 0.05),
            "ground_tolerance": (0.0, 0.05),
        }
        for name, (lo, hi) in ranges.items():
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and lo <= value <= hi):
                raise CrawlError(f"CrawlParams.{name} must be in [{lo}, {hi}], got {value!r}")
        if self.stride <= 0.0:
            raise CrawlError(f"CrawlParams.stride must be > 0, got {self.stride}")


@dataclasses.dataclass
class CrawlPlan:
    """Joint commands of a crawl sampled every ``dt``.

    Attributes:
        times: sample times from 0 (s), shape (N,).
        q: commanded joint angles (``JOINT_NAMES`` order), shape (N, 12).
        body_pose: the intended body pose at each sample, shape (N, 6).
        stance: planned contact of each foot (``LEGS`` order), shape (N, 4) bool.
        step_index: which step each sample belongs to, shape (N,) (-1 for the initial hold).
        feet: foot centres after each step, shape (len(steps) + 1, 4, 3); row 0 is the start.
        steps: the executed steps.
        foot_commands: commanded foot centres at each sample (N, 4, 3); stance feet are
            commanded ``press`` below their footholds.
    """

    times: np.ndarray
    q: np.ndarray
    body_pose: np.ndarray
    stance: np.ndarray
    step_index: np.ndarray
    feet: np.ndarray
    steps: list[CrawlStep]
    foot_commands: np.ndarray

    @property
    def duration(self) -> float:
        return float(self.times[-1])


def _smooth(s: np.ndarray) -> np.ndarray:
    s = np.clip(s, 0.0, 1.0)
    return s * s * s * (10.0 + s * (-15.0 + 6.0 * s))


def heading_of(p_WF: np.ndarray):
    """Yaw (rad) of the line from the hind feet's midpoint to the front feet's midpoint.

    ``p_WF`` is one stance (4 x 3; a float is returned) or a stack (..., 4, 3).
    """
    p = np.asarray(p_WF, dtype=float)
    d = 0.5 * (p[..., 0, :] + p[..., 1, :]) - 0.5 * (p[..., 2, :] + p[..., 3, :])
    yaw = np.arctan2(d[..., 1], d[..., 0])
    return float(yaw) if p.ndim == 2 else yaw


def swing_pose(feet, foot: int, p_new, params: CrawlParams) -> np.ndarray:
    """The body pose the crawl holds while ``foot`` swings from ``feet[foot]`` to ``p_new``.

    Level, over the centroid of the three stance feet moved ``shift_margin`` away from
    the lifting foot, heading from the four feet after the step (:func:`heading_of`),
    ``standing_height`` above their mean ground, lowered (:func:`reachable_height`) until
    every stance foot and the swing foot's old and new positions lie within
    :data:`MAX_LEG_EXTENSION` of their hips. :func:`plan_crawl` executes every step with
    it and the footstep planner's crawl model checks reach with it (one definition).

    Args:
        feet: foot centres before the step (4 x 3, ``LEGS`` order).
        foot: the swing foot (``LEGS`` index).
        p_new: its new foot centre (3,), or K candidates (K, 3).
        params: crawl parameters.

    Returns:
        The pose ``[x, y, z, roll, pitch, yaw]`` (6,), or (K, 6) for K candidates.
    """
    feet = np.asarray(feet, dtype=float)
    p = np.asarray(p_new, dtype=float)
    cand = p.reshape(-1, 3)
    if len(cand) == 0:
        return np.zeros((0, 6))
    after = np.repeat(feet[None], len(cand), axis=0)
    after[:, foot] = cand
    stance = [i for i in range(4) if i != foot]
    centroid = feet[stance, :2].mean(axis=0)
    away = centroid - feet[foot, :2]
    pose = np.zeros((len(cand), 6))
    pose[:, :2] = centroid + params.shift_margin * away / max(np.linalg.norm(away), 1e-9)
    pose[:, 2] = np.mean(after[:, :, 2] - FOOT_RADIUS, axis=1) + params.standing_height
    pose[:, 5] = heading_of(after)
    points = np.concatenate([np.repeat(feet[None], len(cand), axis=0), cand[:, None]], axis=1)
    pose[:, 2] = reachable_height(pose, points, [0, 1, 2, 3, foot], params)
    return pose[0] if p.ndim == 1 else pose


def joint_angles(pose: np.ndarray, p_WF: np.ndarray, what: str = "") -> np.ndarray:
    """The 12 joint angles putting the feet at ``p_WF`` (4 x 3) with the body at ``pose``.

    Raises:
        CrawlError: naming the leg whose foot is out of reach or outside the joint limits.
    """
    p_BF = world_to_body(pose, p_WF)
    q = np.empty(p_BF.shape[:-2] + (12,))
    for i, leg in enumerate(LEGS):
        try:
            q[..., 3 * i : 3 * i + 3] = leg_ik(leg, p_BF[..., i, :])
        except RepertoireError as e:
            raise CrawlError(f"{what}: {e}") from e
    return q


MAX_LEG_EXTENSION = 0.165
"""Largest hip-to-foot distance the crawl plans with (m; the legs reach 0.177 m)."""


def reachable_height(pose, points, legs, params: CrawlParams):
    """Body height, at most ``pose[2]``, keeping every foot point within its leg's reach.

    Args:
        pose: the body pose (its z is the wanted height), (6,) or K poses (K, 6).
        points: foot centres the legs must reach, (M, 3) or (K, M, 3).
        legs: the ``LEGS`` index of each point (M,).
        params: crawl parameters (stance feet are commanded ``press`` lower).

    Returns:
        The height (a float), or K heights for K poses.
    """
    pose = np.asarray(pose, dtype=float)
    poses = pose.reshape(-1, 6)
    pts = np.asarray(points, dtype=float).reshape(len(poses), -1, 3)
    pts = pts - np.array([0.0, 0.0, params.press])
    hips = np.array([LEG_GEOMETRY[LEGS[i]].p_BH for i in legs])
    R = rotation_from_rpy(poses[:, 3:])
    z = poses[:, 2].copy()
    for _ in range(20):
        origin = np.column_stack([poses[:, :2], z])
        p_B = np.einsum("kmi,kij->kmj", pts - origin[:, None, :], R)
        excess = np.linalg.norm(p_B - hips, axis=-1).max(axis=-1) - MAX_LEG_EXTENSION
        low = excess > 0.0
        if not low.any():
            break
        z[low] -= excess[low] + 1e-4
    return float(z[0]) if pose.ndim == 1 else z


def _swing_path(p0, p1, s, params: CrawlParams, board) -> np.ndarray:
    """Foot centre along a lift / travel / lower path for phases ``s`` in [0, 1].

    ``p1`` is one target (3,) (returns (len(s), 3)) or K targets (K, 3) (returns (K, len(s), 3)).
    """
    p0 = np.asarray(p0, dtype=float)
    p1 = np.asarray(p1, dtype=float)
    ends = p1.reshape(-1, 3)
    u = np.linspace(0.0, 1.0, 25)
    line = p0[:2] + u[None, :, None] * (ends[:, None, :2] - p0[:2])
    r = params.edge_radius
    offsets = np.array([[0, 0], [r, 0], [-r, 0], [0, r], [0, -r]])
    pts = (line[:, :, None, :] + offsets[None, None]).reshape(len(ends), -1, 2)
    heights = np.asarray(board.height(pts[..., 0].ravel(), pts[..., 1].ravel()), dtype=float)
    top = heights.reshape(len(ends), -1).max(axis=1) + FOOT_RADIUS
    zc = (np.maximum(np.maximum(top, p0[2]), ends[:, 2]) + params.clearance)[:, None]
    lift, travel = _smooth(s / 0.3), _smooth((s - 0.3) / 0.4)
    lower = _smooth((s - 0.7) / 0.3)
    xy = p0[:2] + travel[None, :, None] * (ends[:, None, :2] - p0[:2])
    z0, z1 = p0[2] - params.press, ends[:, 2:3] - params.press
    z = np.where(s < 0.3, z0 + lift * (zc - z0), np.where(s < 0.7, zc, zc + lower * (z1 - zc)))
    path = np.concatenate([xy, z[..., None]], axis=-1)
    return path[0] if p1.ndim == 1 else path


def swing_commands(feet, foot: int, p_new, params: CrawlParams, board) -> np.ndarray:
    """Commanded foot centres from lift to settle of one step (what :func:`plan_crawl` emits).

    The lift delay (feet before the step), the swing of ``foot`` to ``p_new`` (the other
    feet at their footholds), then the settle (feet after the step); every stance foot
    ``press`` below its foothold.

    Args:
        feet: foot centres before the step (4 x 3).
        foot: the swing foot.
        p_new: its new foot centre (3,), or K candidates (K, 3).
        params: crawl parameters.
        board: terrain with ``height(x, y)`` (the swing clears its highest point).

    Returns:
        (n_lift + n_swing + n_settle, 4, 3), or (K, ...) for K candidates.
    """
    feet = np.asarray(feet, dtype=float)
    p = np.asarray(p_new, dtype=float)
    cand = p.reshape(-1, 3)
    K, dt = len(cand), params.dt
    down = np.array([0.0, 0.0, params.press])
    n_lift = round(params.lift_delay / dt)
    n_swing = max(1, round(params.swing_time / dt))
    n_settle = max(1, round(params.settle_time / dt)) if params.settle_time > 0 else 0
    cmd = np.repeat((feet - down)[None, None], K, axis=0)
    cmd = np.repeat(cmd, n_lift + n_swing + n_settle, axis=1)
    s = np.arange(1, n_swing + 1) / n_swing
    cmd[:, n_lift : n_lift + n_swing, foot] = _swing_path(feet[foot], cand, s, params, board)
    cmd[:, n_lift + n_swing :, foot] = cand[:, None] - down
    return cmd[0] if p.ndim == 1 else cmd


def step_reachable(feet, foot: int, p_new, params: CrawlParams, board) -> np.ndarray:
    """Which candidate steps the crawl can execute: leg IK at the :func:`swing_pose`.

    Checks every leg (joint limits included) for every command of
    :func:`swing_commands` with the body at the step's :func:`swing_pose`, and the feet
    before the step there (the end of the body shift). The shift's intermediate poses
    (between the previous step's pose and this one) are not checked here: they depend
    on the previous step: :func:`shift_reachable` checks them.

    Args:
        feet: foot centres before the step (4 x 3).
        foot: the swing foot.
        p_new: K candidate foot centres (K, 3).
        params: crawl parameters.
        board: terrain with ``height(x, y)``.

    Returns:
        Boolean mask (K,).
    """
    feet = np.asarray(feet, dtype=float)
    cand = np.asarray(p_new, dtype=float).reshape(-1, 3)
    if len(cand) == 0:
        return np.zeros(0, dtype=bool)
    poses = swing_pose(feet, foot, cand, params)
    cmd = swing_commands(feet, foot, cand, params, board)
    R = rotation_from_rpy(poses[:, 3:])
    origin = poses[:, None, :3]
    # Before the lift every foot, and through the step every stance foot, is commanded
    # at its foothold (press below): one point per leg; the swing foot's path varies.
    held = feet - np.array([0.0, 0.0, params.press])
    held_B = np.einsum("kmi,kij->kmj", held[None] - origin, R)
    swing_B = np.einsum("kni,kij->knj", cmd[:, :, foot] - origin, R)
    ok = leg_ik_feasible(LEGS[foot], swing_B).all(axis=1)
    for i, leg in enumerate(LEGS):
        ok &= leg_ik_feasible(leg, held_B[:, i])
    return ok


def shift_poses(pose, target, params: CrawlParams) -> np.ndarray:
    """The body poses of the shift before a step, from ``pose`` to ``target`` (its last).

    ``round(shift_time / dt)`` samples (at least one) of a smooth blend, the yaw the short
    way round, as :func:`plan_crawl` commands them; ``target`` may be (K, 6) for K
    shifts from the same pose, giving (K, n, 6).
    """
    pose, target = np.asarray(pose, dtype=float), np.asarray(target, dtype=float)
    n = max(1, round(params.shift_time / params.dt))
    s = _smooth(np.arange(1, n + 1) / n)[:, None]
    d = target - pose
    d[..., 5] = (d[..., 5] + math.pi) % (2.0 * math.pi) - math.pi
    return pose + s * d[..., None, :]


def shift_reachable(feet, pose, targets, params: CrawlParams) -> np.ndarray:
    """Which shifts from ``pose`` to each of ``targets`` (K, 6) every leg can follow.

    The four feet stay at ``feet`` (foot centres, 4 x 3, pressed ``press`` into the
    ground as commanded) while the body moves through :func:`shift_poses`; the ends are
    the previous step's swing pose and this step's (:func:`step_reachable` checks the
    latter). Both ends reachable does not make the blend reachable: the joint limits
    bound a non-convex set (a 5 cm drop with a turn took a hip pitch past its limit
    halfway). Returns a boolean mask (K,).
    """
    targets = np.asarray(targets, dtype=float).reshape(-1, 6)
    if len(targets) == 0:
        return np.zeros(0, dtype=bool)
    poses = shift_poses(pose, targets, params).reshape(-1, 6)  # (K n, 6)
    R = rotation_from_rpy(poses[:, 3:])
    held = np.asarray(feet, dtype=float) - np.array([0.0, 0.0, params.press])
    held_B = (held[None] - poses[:, None, :3]) @ R  # the feet in the body frame, per pose
    ok = np.ones(len(poses), dtype=bool)
    for i, leg in enumerate(LEGS):
        ok &= leg_ik_feasible(leg, held_B[:, i])
    return ok.reshape(len(targets), -1).all(axis=1)


def plan_crawl(
    p_WF0,
    pose0,
    steps: list[CrawlStep],
    board,
    params: CrawlParams | None = None,
    *,
    hold_time: float = 0.3,
) -> CrawlPlan:
    """Executes a sequence of crawl steps kinematically (joint commands every ``dt``).

    Args:
        p_WF0: foot centres at the start (4 x 3, ``LEGS`` order).
        pose0: body pose at the start ``[x, y, z, roll, pitch, yaw]``.
        steps: the steps, executed in order (any foot order; three feet stay down).
        board: terrain with an exact ``height(x, y)``.
        params: crawl parameters.
        hold_time: initial hold at the start pose (s).

    Raises:
        CrawlError: bad input, a step foothold off the ground (``ground_tolerance``), or a
            pose the legs cannot reach (naming step and leg).
    """
    params = CrawlParams() if params is None else params
    params.validate()
    feet = np.asarray(p_WF0, dtype=float).copy()
    pose = np.asarray(pose0, dtype=float).copy()
    if feet.shape != (4, 3) or not np.all(np.isfinite(feet)):
        raise CrawlError(f"p_WF0 must be 4 x 3 finite foot positions, got shape {feet.shape}")
    if pose.shape != (6,) or not np.all(np.isfinite(pose)):
        raise CrawlError(f"pose0 must be 6 finite numbers [x, y, z, r, p, y], got {pose0!r}")
    if not steps:
        raise CrawlError("plan_crawl needs at least one CrawlStep")
    if not (math.isfinite(hold_time) and hold_time >= 0.0):
        raise CrawlError(f"hold_time must be >= 0 s, got {hold_time}")
    dt = params.dt
    down = np.array([0.0, 0.0, params.press])
    poses, stances, indices, foot_cmds = [], [], [], []

    def emit(n: int, pose_s, cmd_s, stance_row, k: int) -> None:
        poses.append(pose_s)
        foot_cmds.append(cmd_s)
        stances.append(np.repeat(stance_row[None], n, axis=0))
        indices.append(np.full(n, k))

    n_hold = max(1, round(hold_time / dt))
    emit(
        n_hold,
        np.repeat(pose[None], n_hold, 0),
        np.repeat((feet - down)[None], n_hold, 0),
        np.ones(4, bool),
        -1,
    )
    history = [feet.copy()]
    for k, step in enumerate(steps):
        if not isinstance(step, CrawlStep):
            raise CrawlError(f"steps[{k}] must be a CrawlStep, got {type(step).__name__}")
        f = step.foot
        ground = np.asarray(board.height(step.p_WF[:1], step.p_WF[1:2]), dtype=float)
        off = float(step.p_WF[2] - FOOT_RADIUS - ground.ravel()[0])
        if abs(off) > params.ground_tolerance:
            x, y, z = (float(v) for v in step.p_WF)
            raise CrawlError(
                f"step {k} (moving foot {LEGS[f]}) foothold centre [{x:.4f}, {y:.4f}, {z:.4f}] "
                f"m lies {abs(off):.4f} m {'below' if off < 0 else 'above'} the ground plus the "
                f"foot radius (at most {params.ground_tolerance} m): not a foothold"
            )
        after = feet.copy()
        after[f] = step.p_WF
        target = swing_pose(feet, f, step.p_WF, params)
        # Shift: body moves, all four feet stay.
        shift = shift_poses(pose, target, params)
        n = len(shift)
        emit(n, shift, np.repeat((feet - down)[None], n, 0), np.ones(4, bool), k)
        pose = target
        # Lift delay, swing of foot f, settle: body still (the commands the planner checks).
        cmd = swing_commands(feet, f, step.p_WF, params, board)
        n_lift = round(params.lift_delay / dt)
        n_swing = max(1, round(params.swing_time / dt))
        rows = np.ones((len(cmd), 4), bool)
        rows[n_lift : n_lift + n_swing, f] = False
        poses.append(np.repeat(pose[None], len(cmd), 0))
        foot_cmds.append(cmd)
        stances.append(rows)
        indices.append(np.full(len(cmd), k))
        feet = after
        history.append(feet.copy())
    body_pose = np.concatenate(poses)
    cmds = np.concatenate(foot_cmds)
    index = np.concatenate(indices)
    q = np.empty((len(body_pose), 12))
    for k in range(-1, len(steps)):
        sel = index == k
        what = "start pose" if k < 0 else f"step {k} (moving foot {LEGS[steps[k].foot]})"
        p_BF = np.stack([world_to_body(p, c) for p, c in zip(body_pose[sel], cmds[sel])])
        for i, leg in enumerate(LEGS):
            try:
                q[sel, 3 * i : 3 * i + 3] = leg_ik(leg, p_BF[:, i])
            except RepertoireError as e:
                raise CrawlError(f"{what} cannot be reached: {e}") from e
    times = np.arange(len(body_pose)) * dt
    return CrawlPlan(
        times=times,
        q=q,
        body_pose=body_pose,
        stance=np.concatenate(stances),
        step_index=index,
        feet=np.stack(history),
        steps=list(steps),
        foot_commands=cmds,
    )


def plan_to_steps(plan: CrawlPlan, *, terrain: str, direction: float, kind: str = "planned"):
    """Library steps made from a crawl plan's commands (no physics), for example planned steps.

    The plan is cut like a recording (:func:`~repertoire.planning.step_library.segment_recording`)
    with its planned stance labels, commanded foot centres (raised by the press depth,
    i.e. the footholds) and intended body poses.

    Args:
        plan: a crawl plan.
        terrain: the terrain name stored with the steps.
        direction: the direction stored with the steps (rad).
        kind: ``planned`` (default) or ``recorded``.

    Returns:
        One :class:`~repertoire.planning.step_library.LibraryStep` per crawl step.
    """
    press = plan.foot_commands[0, 0, 2] - plan.feet[0, 0, 2]
    steps = segment_recording(
        plan.times,
        plan.q,
        plan.body_pose,
        plan.foot_commands - np.array([0.0, 0.0, press]),
        plan.stance,
        terrain=terrain,
        direction=direction,
        min_flight=1,
    )
    return [dataclasses.replace(s, kind=kind) for s in steps]


def foothold_ok(board, xy, params: CrawlParams) -> np.ndarray:
    """True where the terrain within ``edge_radius`` of each point of ``xy`` (M x 2) is flat."""
    return foothold_range(board, xy, params) <= params.flat_tolerance


def foothold_range(board, xy, params: CrawlParams) -> np.ndarray:
    """The terrain's height range (m) within ``edge_radius`` of each point of ``xy`` (M x 2).

    Sampled at the centre and on rings at the radius and half of it (8 points each).
    """
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    r = params.edge_radius
    angles = np.linspace(0.0, 2.0 * np.pi, 8, endpoint=False)
    ring = np.concatenate(
        [
            [[0.0, 0.0]],
            r * np.column_stack([np.cos(angles), np.sin(angles)]),
            0.5 * r * np.column_stack([np.cos(angles), np.sin(angles)]),
        ]
    )
    pts = xy[:, None, :] + ring[None]
    h = board.height(pts[..., 0], pts[..., 1])
    return h.max(axis=1) - h.min(axis=1)


def choose_foothold(
    board, nominal_xy, other_feet: np.ndarray, params: CrawlParams, leg: str, *, feet=None
):
    """The safe foothold nearest to ``nominal_xy``: flat around it, height near the others'.

    Args:
        feet: the four foot centres before the step (4 x 3); when given, a safe foothold
            must also be one the crawl can step to (:func:`step_reachable`).

    Returns:
        The foot centre ``p_WF`` (3,).

    Raises:
        CrawlError: when no candidate within ``search_radius`` is safe.
    """
    r, h = params.search_radius, params.search_step
    n = int(round(r / h))
    g = np.arange(-n, n + 1) * h
    U, V = np.meshgrid(g, g)
    cand = np.column_stack([U.ravel(), V.ravel()])
    cand = cand[np.linalg.norm(cand, axis=1) <= r + 1e-12] + np.asarray(nominal_xy)
    ok = foothold_ok(board, cand, params)
    z = board.height(cand[:, 0], cand[:, 1])
    ref = float(np.mean(other_feet[:, 2] - FOOT_RADIUS))
    ok &= np.abs(z - ref) <= params.max_rise
    if feet is not None and np.any(ok):
        rows = np.flatnonzero(ok)
        p = np.column_stack([cand[rows], z[rows] + FOOT_RADIUS])
        ok[rows] = step_reachable(feet, LEGS.index(leg), p, params, board)
    if not np.any(ok):
        reach = ", out of the crawl's reach" if feet is not None else ""
        raise CrawlError(
            f"no safe foothold for foot {leg} within {r} m of ({nominal_xy[0]:.3f}, "
            f"{nominal_xy[1]:.3f}): every spot is on an edge, steep{reach}, or more than "
            f"{params.max_rise} m above/below the other feet; the board has no crossable path"
        )
    cost = np.linalg.norm(cand - nominal_xy, axis=1) + 0.5 * np.abs(z - ref)
    cost[~ok] = np.inf
    best = int(np.argmin(cost))
    return np.array([cand[best, 0], cand[best, 1], z[best] + FOOT_RADIUS])


def choose_footholds(
    board,
    p_WF0,
    heading: float,
    goal: float,
    params: CrawlParams | None = None,
    *,
    max_steps: int = 200,
    time_limit: float = 30.0,
) -> list[CrawlStep]:
    """The scripted operator: crawl steps along ``heading`` until the front feet pass ``goal``.

    The virtual body centre advances ``stride / 4`` per step; each foot, in
    :data:`CRAWL_ORDER`, aims ``3/8 stride`` ahead of its nominal offset from the
    centre (so feet spread evenly around their nominal positions) and takes the
    nearest safe foothold the crawl can step to (:func:`choose_foothold`).

    Args:
        board: terrain with an exact ``height(x, y)``.
        p_WF0: foot centres at the start (4 x 3).
        heading: walking direction, yaw about world z (rad).
        goal: the goal line, as a distance along ``heading`` from the world origin (m).
        params: crawl parameters.
        max_steps: refuse to plan more steps than this.
        time_limit: wall-clock limit of the search (s).

    Raises:
        CrawlError: no safe foothold (the board has no crossable path), or a limit hit.
    """
    params = CrawlParams() if params is None else params
    params.validate()
    feet = np.asarray(p_WF0, dtype=float).copy()
    if feet.shape != (4, 3) or not np.all(np.isfinite(feet)):
        raise CrawlError(f"p_WF0 must be 4 x 3 finite foot positions, got {p_WF0!r}")
    if not (math.isfinite(heading) and math.isfinite(goal)):
        raise CrawlError(f"heading and goal must be finite, got {heading}, {goal}")
    direction = np.array([math.cos(heading), math.sin(heading)])
    R = np.array([[direction[0], -direction[1]], [direction[1], direction[0]]])
    nominal = nominal_foot_positions(STANDING_HEIGHT)[:, :2]
    centre = feet[:, :2].mean(axis=0)
    start = time.monotonic()
    steps: list[CrawlStep] = []
    k = 0
    while min(feet[0, :2] @ direction, feet[1, :2] @ direction) < goal:
        if len(steps) >= max_steps:
            raise CrawlError(f"crawl did not reach the goal line {goal} m within {max_steps} steps")
        if time.monotonic() - start > time_limit:
            raise CrawlError(f"foothold search exceeded its time limit of {time_limit} s")
        f = CRAWL_ORDER[k % 4]
        centre = centre + 0.25 * params.stride * direction
        target = centre + R @ (nominal[f] + np.array([0.375 * params.stride, 0.0]))
        others = np.delete(feet, f, axis=0)
        p = choose_foothold(board, target, others, params, LEGS[f], feet=feet)
        feet[f] = p
        steps.append(CrawlStep(f, p))
        k += 1
    return steps


__all__ = [
    "CRAWL_ORDER",
    "CrawlError",
    "CrawlParams",
    "CrawlPlan",
    "CrawlStep",
    "choose_foothold",
    "choose_footholds",
    "foothold_ok",
    "foothold_range",
    "heading_of",
    "joint_angles",
    "plan_crawl",
    "plan_to_steps",
    "reachable_height",
    "shift_poses",
    "shift_reachable",
    "step_reachable",
    "swing_commands",
    "swing_pose",
]
