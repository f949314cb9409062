"""Closed-form kinematics of the LittleDog quadruped (one leg at a time).

All positions are in the body frame B of LittleDog: origin at the body's
centre, x forward, y to the left, z up. A leg is named by two letters:
``lf`` (left front), ``rf`` (right front), ``lh`` (left hind), ``rh`` (right
hind). Every leg has three joints, in this order:

- ``<leg>_hip_roll``: axis +x of B, at ``(±0.101, ±0.036, 0)`` m from B's origin;
- ``<leg>_hip_pitch``: axis +y, ``0.024`` m further outwards (along ±y) from the
  hip roll axis;
- ``<leg>_knee``: axis +y, ``0.0751`` m below the hip pitch axis (upper leg);

and the foot frame ``<leg>_foot`` (the centre of the foot sphere, radius
``0.0103`` m) is ``0.102`` m below the knee (lower leg). At zero joint angles
the legs point straight down. A positive pitch or knee angle swings the foot
backwards (towards -x). Front knees bend with negative angles and hind knees
with positive angles, so the knees point towards the body's middle.

The functions are vectorised: joint angles of shape ``(..., 3)`` map to foot
positions of shape ``(..., 3)`` and back.
"""

import dataclasses

import numpy as np

from repertoire.errors import RepertoireError

LEGS: list[str] = ["lf", "rf", "lh", "rh"]
"""Leg prefixes, in the order used for joint vectors and foot arrays."""

JOINT_SUFFIXES: list[str] = ["hip_roll", "hip_pitch", "knee"]
JOINT_NAMES: list[str] = [f"{leg}_{s}" for leg in LEGS for s in JOINT_SUFFIXES]
"""The 12 actuated joint names, leg by leg (``lf_hip_roll, lf_hip_pitch, lf_knee, rf_...``)."""

FOOT_FRAMES: list[str] = [f"{leg}_foot" for leg in LEGS]
"""Names of the foot frames (centre of each foot sphere) in the URDF."""

HIP_X = 0.101
HIP_Y = 0.036
HIP_PITCH_OFFSET_Y = 0.024
UPPER_LEG_LENGTH = 0.0751
LOWER_LEG_LENGTH = 0.102
FOOT_RADIUS = 0.0103
STANDING_HEIGHT = 0.146
"""Nominal height of the body origin above the ground when standing (m)."""

BODY_MASS = 1.8
TOTAL_MASS = 2.75


@dataclasses.dataclass(frozen=True)
class LegGeometry:
    """Fixed geometry and joint limits of one leg.

    Attributes:
        name: leg prefix (``lf``, ``rf``, ``lh``, ``rh``).
        p_BH: hip roll joint position in the body frame (m).
        pitch_offset_y: signed lateral offset from hip roll to hip pitch (m).
        upper_length: hip pitch to knee (m).
        lower_length: knee to foot centre (m).
        knee_sign: -1 for front legs (knee angles <= 0), +1 for hind legs.
        lower: lower joint limits (roll, pitch, knee) in rad.
        upper: upper joint limits (roll, pitch, knee) in rad.
    """

    name: str
    p_BH: tuple[float, float, float]
    pitch_offset_y: float
    upper_length: float
    lower_length: float
    knee_sign: float
    lower: tuple[float, float, float]
    upper: tuple[float, float, float]


def _make_leg(name: str) -> LegGeometry:
    front = name[1] == "f"
    side = 1.0 if name[0] == "l" else -1.0
    if front:
        lower, upper = (-0.6, -3.5, -3.1), (0.6, 2.4, 1.0)
    else:
        lower, upper = (-0.6, -2.4, -1.0), (0.6, 3.5, 3.1)
    return LegGeometry(
        name=name,
        p_BH=((HIP_X if front else -HIP_X), side * HIP_Y, 0.0),
        pitch_offset_y=side * HIP_PITCH_OFFSET_Y,
        upper_length=UPPER_LEG_LENGTH,
        lower_length=LOWER_LEG_LENGTH,
        knee_sign=-1.0 if front else 1.0,
        lower=lower,
        upper=upper,
    )


LEG_GEOMETRY: dict[str, LegGeometry] = {leg: _make_leg(leg) for leg in LEGS}


def leg_geometry(leg: str) -> LegGeometry:
    """Returns the geometry of a leg.

    Args:
        leg: one of ``lf``, ``rf``, ``lh``, ``rh`` (case-insensitive).

    Raises:
        RepertoireError: for an unknown leg name.
    """
    key = str(leg).lower()
    if key not in LEG_GEOMETRY:
        raise RepertoireError(f"unknown LittleDog leg '{leg}'; expected one of {LEGS}")
    return LEG_GEOMETRY[key]


def _as_angles(q, name: str) -> np.ndarray:
    q = np.asarray(q, dtype=float)
    if q.shape[-1:] != (3,):
        raise RepertoireError(f"{name} must have shape (..., 3) (roll, pitch, knee), got {q.shape}")
    if not np.all(np.isfinite(q)):
        raise RepertoireError(f"{name} contains NaN or infinite values")
    return q


def leg_fk(leg: str, q) -> np.ndarray:
    """Foot position p_BF in the body frame from one leg's joint angles.

    Args:
        leg: leg prefix (``lf``, ``rf``, ``lh``, ``rh``).
        q: joint angles (hip roll, hip pitch, knee) in rad, shape ``(3,)`` or ``(..., 3)``.

    Returns:
        Foot centre positions, same leading shape as ``q``, last axis (x, y, z) in m.

    Raises:
        RepertoireError: unknown leg, wrong shape or non-finite angles.
    """
    g = leg_geometry(leg)
    q = _as_angles(q, "q")
    roll, pitch, knee = q[..., 0], q[..., 1], q[..., 2]
    # Foot in the hip-roll link frame (before the roll rotation).
    vx = -g.upper_length * np.sin(pitch) - g.lower_length * np.sin(pitch + knee)
    vz = -g.upper_length * np.cos(pitch) - g.lower_length * np.cos(pitch + knee)
    vy = np.full_like(vx, g.pitch_offset_y)
    c, s = np.cos(roll), np.sin(roll)
    p = np.stack([vx, c * vy - s * vz, s * vy + c * vz], axis=-1)
    return p + np.asarray(g.p_BH)


def leg_ik(
    leg: str, p_BF, *, check_limits: bool = True, knee_sign=None, foot_above=None
) -> np.ndarray:
    """Joint angles that put one leg's foot at p_BF (closed form).

    The solution is the one with the foot below the hip (roll in (-pi/2, pi/2)
    for feet under the body; the foot above it, in the leg plane, only where that
    one leaves the joint limits and this one does not) and the knee bent the leg's
    way (front knees <= 0, hind knees >= 0) unless ``knee_sign`` asks for the other
    branch.

    Args:
        leg: leg prefix (``lf``, ``rf``, ``lh``, ``rh``).
        p_BF: desired foot centre in the body frame (m), shape ``(3,)`` or ``(..., 3)``.
        check_limits: if True, raise when a solution violates the joint limits.
        knee_sign: the knee branch, +1 or -1 (broadcast against ``p_BF``'s leading
            shape); default the leg's own (-1 front, +1 hind). The joint limits allow
            front knees up to +1.0 rad and hind knees down to -1.0 rad.
        foot_above: the roll branch, True or False (broadcast like ``knee_sign``): the foot
            above or below the hip pitch axis in the leg plane; default None, below unless
            only above is within the limits (see :func:`foot_above_pitch_axis`).

    Returns:
        Joint angles (hip roll, hip pitch, knee) in rad, same shape as ``p_BF``.

    Raises:
        RepertoireError: unknown leg, wrong shape, non-finite input, target out of
            reach (too far from or too close to the hip), or (with ``check_limits``)
            outside the joint limits.
    """
    g = leg_geometry(leg)
    q, bad, D2 = _leg_ik_solve(g, _as_angles(p_BF, "p_BF"), knee_sign, foot_above)
    if np.any(bad):
        L1, L2, a = g.upper_length, g.lower_length, g.pitch_offset_y
        reach = float(np.ravel(np.sqrt(np.maximum(D2, 0.0)))[np.argmax(np.ravel(bad))])
        by = max(reach - (L1 + L2), abs(L1 - L2) - reach, 0.0)
        raise RepertoireError(
            f"leg {g.name}: foot target out of reach (hip-to-foot distance in the leg plane "
            f"{reach:.4f} m; reachable range [{abs(L1 - L2):.4f}, {L1 + L2:.4f}] m and at least "
            f"{abs(a):.3f} m from the roll axis; missed by {by:.4f} m)"
        )
    if check_limits:
        lo, hi = np.asarray(g.lower), np.asarray(g.upper)
        out = (q < lo - 1e-9) | (q > hi + 1e-9)
        if np.any(out):
            idx = np.argwhere(out)[0]
            joint = JOINT_SUFFIXES[idx[-1]]
            raise RepertoireError(
                f"leg {g.name}: IK solution {joint}={q[tuple(idx[:-1])][idx[-1]]:.3f} rad is "
                f"outside the joint limits [{lo[idx[-1]]}, {hi[idx[-1]]}] rad"
            )
    return q


def _check_knee_sign(g: LegGeometry, knee_sign) -> np.ndarray:
    if knee_sign is None:
        return np.asarray(g.knee_sign)
    sign = np.asarray(knee_sign, dtype=float)
    if not np.all((sign == 1.0) | (sign == -1.0)):
        raise RepertoireError(f"knee_sign must be +1 or -1, got {knee_sign!r}")
    return sign


def _leg_ik_branch(g: LegGeometry, r: np.ndarray, sign, below: bool) -> np.ndarray:
    """Angles of one roll branch: the foot below (``vz`` < 0) or above the pitch axis."""
    rx, ry, rz = r[..., 0], r[..., 1], r[..., 2]
    a = g.pitch_offset_y
    L1, L2 = g.upper_length, g.lower_length
    vx = rx
    vz = np.sqrt(np.maximum(ry**2 + rz**2 - a**2, 0.0)) * (-1.0 if below else 1.0)
    cos_knee = (vx**2 + vz**2 - L1**2 - L2**2) / (2.0 * L1 * L2)
    knee = sign * np.arccos(np.clip(cos_knee, -1.0, 1.0))
    alpha = np.arctan2(-vx, -vz)
    pitch = alpha - np.arctan2(L2 * np.sin(knee), L1 + L2 * np.cos(knee))
    # The difference of two atan2 lies in (-2 pi, 2 pi): take the pitch's representative
    # modulo 2 pi within the joint limits when there is one (the range is < 2 pi wide).
    lo = g.lower[1] - 1e-9
    pitch = np.where(pitch < lo, pitch + 2.0 * np.pi, pitch)
    pitch = np.where(pitch >= lo + 2.0 * np.pi, pitch - 2.0 * np.pi, pitch)
    roll = np.arctan2(rz, ry) - np.arctan2(vz, a)
    roll = (roll + np.pi) % (2.0 * np.pi) - np.pi
    return np.stack([roll, pitch, knee], axis=-1)


def _within_limits(g: LegGeometry, q: np.ndarray) -> np.ndarray:
    lo, hi = np.asarray(g.lower), np.asarray(g.upper)
    return np.all((q >= lo - 1e-9) & (q <= hi + 1e-9), axis=-1)


def foot_above_pitch_axis(q) -> np.ndarray:
    """Whether joint angles ``q`` (..., 3) put the foot above the hip pitch axis (roll branch).

    In the leg plane (the plane the roll turns) the foot lies ``-L1 cos(pitch) - L2
    cos(pitch + knee)`` below the pitch axis; positive means above. Pass the result as
    ``foot_above`` to :func:`leg_ik` to stay on a configuration's branch.
    """
    q = _as_angles(q, "q")
    pitch, knee = q[..., 1], q[..., 2]
    return -UPPER_LEG_LENGTH * np.cos(pitch) - LOWER_LEG_LENGTH * np.cos(pitch + knee) > 0.0


def _check_foot_above(foot_above):
    if foot_above is None:
        return None
    above = np.asarray(foot_above)
    if above.dtype != bool:
        raise RepertoireError(f"foot_above must be True, False or None, got {foot_above!r}")
    return above


def _leg_ik_solve(g: LegGeometry, p: np.ndarray, knee_sign=None, foot_above=None):
    """Closed-form IK of :func:`leg_ik`: angles, out-of-reach mask, squared leg-plane reach.

    A foot position has two roll branches for a given knee branch: in the leg plane (the
    plane the roll turns) the foot lies below the hip pitch axis or above it. The branch
    below is taken unless its angles leave the joint limits and the branch above's do
    not (a leg folded with the foot above its hip: pitch beyond +-pi/2, which the limits
    allow; before, the IK refused about 46 % of the foot positions of joint angles drawn
    uniformly within the limits, naming a roll of 1-3 rad outside them).
    """
    sign = _check_knee_sign(g, knee_sign)
    above = _check_foot_above(foot_above)
    r = p - np.asarray(g.p_BH)
    a = g.pitch_offset_y
    d2_yz = r[..., 1] ** 2 + r[..., 2] ** 2 - a**2
    L1, L2 = g.upper_length, g.lower_length
    D2 = r[..., 0] ** 2 + np.maximum(d2_yz, 0.0)
    cos_knee = (D2 - L1**2 - L2**2) / (2.0 * L1 * L2)
    bad = (d2_yz < 0.0) | (cos_knee > 1.0 + 1e-12) | (cos_knee < -1.0 - 1e-12)
    q = _leg_ik_branch(g, r, sign, below=True)
    if above is not None:
        if np.any(above):
            q = np.where(above[..., None], _leg_ik_branch(g, r, sign, below=False), q)
        return q, bad, D2
    out = ~_within_limits(g, q)
    if np.any(out):
        above = _leg_ik_branch(g, r, sign, below=False)
        use = out & _within_limits(g, above)
        q = np.where(use[..., None], above, q)
    return q, bad, D2


def leg_ik_feasible(leg: str, p_BF, *, knee_sign=None, foot_above=None) -> np.ndarray:
    """Where :func:`leg_ik` (joint limits checked) succeeds, without raising: a mask.

    Args:
        leg: leg prefix.
        p_BF: foot centres in the body frame, shape ``(..., 3)``.
        knee_sign: the knee branch (as in :func:`leg_ik`).
        foot_above: the roll branch (as in :func:`leg_ik`).

    Returns:
        Boolean array of shape ``p_BF.shape[:-1]``: in reach and within the joint limits.
    """
    g = leg_geometry(leg)
    q, bad, _ = _leg_ik_solve(g, _as_angles(p_BF, "p_BF"), knee_sign, foot_above)
    return ~bad & _within_limits(g, q)


def nominal_foot_positions(
    base_height: float = STANDING_HEIGHT,
    foot_heights=None,
    *,
    offset_x: float = 0.0,
    offset_y: float = 0.0,
) -> np.ndarray:
    """Foot centre positions p_BF (4 x 3, in LEGS order) of the nominal stance.

    Each foot is under its hip pitch joint (plus optional offsets), its sphere
    touching ground at ``foot_heights[i]`` while the body origin is at
    ``base_height`` (both in the same vertical frame, body level).

    Args:
        base_height: height of the body origin (m).
        foot_heights: ground heights under the four feet (m); default all zero.
        offset_x: forward shift of every foot from under its hip (m).
        offset_y: outward shift of every foot (m, positive = away from the body).
    """
    heights = np.zeros(4) if foot_heights is None else np.asarray(foot_heights, dtype=float)
    if heights.shape != (4,) or not np.all(np.isfinite(heights)):
        raise RepertoireError(f"foot_heights must be 4 finite numbers, got {foot_heights!r}")
    if not np.isfinite(base_height):
        raise RepertoireError(f"base_height must be finite, got {base_height}")
    p = np.zeros((4, 3))
    for i, leg in enumerate(LEGS):
        g = LEG_GEOMETRY[leg]
        side = np.sign(g.pitch_offset_y)
        p[i, 0] = g.p_BH[0] + offset_x
        p[i, 1] = g.p_BH[1] + g.pitch_offset_y + side * offset_y
        p[i, 2] = heights[i] + FOOT_RADIUS - base_height
    return p


def standing_configuration(
    base_height: float = STANDING_HEIGHT,
    foot_heights=None,
    *,
    offset_x: float = 0.0,
    offset_y: float = 0.0,
) -> np.ndarray:
    """The 12 joint angles (JOINT_NAMES order) of the nominal standing stance.

    Args:
        base_height: height of the body origin above the reference (m).
        foot_heights: ground heights under the four feet (m); default all zero.
        offset_x: forward shift of every foot from under its hip (m).
        offset_y: outward shift of every foot (m).

    Raises:
        RepertoireError: when a foot cannot reach its ground within the joint limits.
    """
    p = nominal_foot_positions(base_height, foot_heights, offset_x=offset_x, offset_y=offset_y)
    return np.concatenate([leg_ik(leg, p[i]) for i, leg in enumerate(LEGS)])
