"""Obstacle coupling term of Pastor et al. 2009, eq. 10, in 2-D and 3-D.

``p = gamma R v phi exp(-beta phi)``: ``phi`` is the angle between the direction to the
obstacle ``o - x`` and the velocity ``v`` relative to the obstacle, ``R`` rotates by
``pi / 2`` about ``r = (o - x) x v``.

``v`` is the transformation system's state of eq. 7, the scaled velocity ``tau dx/dt``
(eq. 9 adds ``p(x, v)`` to ``tau v'``), so :func:`obstacle_coupling` takes the physical
velocity and the DMP's ``tau``. With ``v`` the coupled DMP keeps the paper's temporal
invariance: in the phase time ``t / tau`` eq. 9 does not contain ``tau``, so the same DMP
run slower or faster takes the same path around the obstacle. Fed ``dx/dt`` instead (before
session 35) the term was ``1 / tau`` of the paper's, and a DMP slowed from tau = 1 s to 2 s
passed an obstacle 22 mm closer (110 -> 88 mm; 135 mm at 0.5 s).

Heading straight at the obstacle (``phi = 0``) is the term's degenerate case: ``r``
vanishes, so the axis is undefined, and ``phi exp(-beta phi)`` is 0, so the term is 0
whatever axis one picks. A movement that heads straight at the obstacle stays on that
line (the term is symmetric about it) and passes through the obstacle's centre: before
this module, a straight DMP along x through a ball on the line passed it at 0 mm (the
distance to the line's nearest sample). The line is an unstable equilibrium: for any
``phi > 0`` eq. 10 turns the velocity away and ``phi`` grows, about as ``exp(gamma t /
tau^2)`` while small. So what fails is only the symmetry breaking, and :func:`obstacle_
coupling` breaks it deterministically:

* ``phi = atan2(|r|, (o - x) . v)``, exact to round-off near 0 and pi (``acos`` of the
  cosine, used before, reads every angle below 1.5e-8 rad as 0, and returned 1.5e-8
  rad for some exactly parallel vectors: which way a near-straight movement went
  depended on the cosine's last bit);
* where ``|r| <= STRAIGHT_TOLERANCE |o - x| |v|`` (``sin phi`` at round-off level, the
  direction of ``r`` is noise) and ``v`` points at the obstacle, the term is eq. 10
  evaluated as if ``phi = STRAIGHT_TOLERANCE`` about the fallback axis
  :func:`fallback_axis` (world z's component perpendicular to ``v``; world x's when ``v``
  is within about 26 degrees of z). In the plane z = 0 that axis is +z: the movement is
  turned to its left (counter-clockwise), the same in 2-D and in 3-D. The term's magnitude
  is continuous at the cone's boundary and its value there is the limit of eq. 10 from
  the fallback's side: an obstacle on the line gives the path of an obstacle an
  infinitesimal distance to the right of it;
* everywhere else (``|r|`` above the tolerance) the term is eq. 10 exactly.

With heading away (``phi = pi``) the axis is also undefined; eq. 10's value there is
``gamma pi exp(-beta pi) |v|`` about any axis perpendicular to ``v``, so the fallback
axis is used with ``phi = pi``.
"""

import math

import numpy as np

from repertoire.checks import is_real
from repertoire.errors import RepertoireError

#: ``sin(phi)`` at or below which the velocity counts as parallel to ``o - x`` (round-off
#: level: the cross product's components carry errors of about 1e-16 |o - x| |v|).
STRAIGHT_TOLERANCE = 1e-12


def fallback_axis(v: np.ndarray) -> np.ndarray:
    """The unit rotation axis eq. 10 uses when ``(o - x) x v`` vanishes.

    World z's component perpendicular to ``v`` (world x's when ``|v_z| > 0.9 |v|``),
    normalised; ``R v = axis x v`` then turns a velocity in the plane z = 0 to its left
    (counter-clockwise about +z), so a 2-D movement stays in its plane.

    Args:
        v: A non-zero velocity, shape (3,).

    Returns:
        The unit axis, shape (3,), perpendicular to ``v``.

    Raises:
        RepertoireError: ``v`` is zero, non-finite or not a 3-vector.
    """
    v = np.asarray(v, dtype=float).reshape(-1)
    if v.size != 3 or not np.all(np.isfinite(v)):
        raise RepertoireError(f"v must be a finite 3-vector, got {v}")
    speed = float(np.linalg.norm(v))
    if speed == 0.0:
        raise RepertoireError("v must be non-zero: a zero velocity has no perpendicular axis")
    return np.array(_fallback_axis(float(v[0]), float(v[1]), float(v[2]), speed))


def _fallback_axis(v1: float, v2: float, v3: float, speed: float) -> tuple[float, float, float]:
    u1, u2, u3 = v1 / speed, v2 / speed, v3 / speed
    h1, h2, h3 = (0.0, 0.0, 1.0) if abs(u3) <= 0.9 else (1.0, 0.0, 0.0)
    c = h1 * u1 + h2 * u2 + h3 * u3
    a1, a2, a3 = h1 - c * u1, h2 - c * u2, h3 - c * u3
    an = math.sqrt(a1 * a1 + a2 * a2 + a3 * a3)  # >= sqrt(1 - 0.9^2) > 0.43
    return a1 / an, a2 / an, a3 / an


def check_gains(gamma: float, beta: float) -> list[float]:
    """``[gamma, beta]`` of eq. 10 as floats; RepertoireError unless both are finite and >= 0.

    Numbers only: a string such as ``"1"`` or a bool is refused (``float`` would take it).

    Args:
        gamma: Gain of eq. 10.
        beta: Angular decay of eq. 10 (the paper's c).
    """
    if not all(is_real(g) and 0.0 <= g < math.inf for g in (gamma, beta)):
        raise RepertoireError(
            f"gamma and beta must be finite and >= 0, got {_shown(gamma)}, {_shown(beta)}"
        )
    return [float(gamma), float(beta)]


def obstacle_coupling(
    x: np.ndarray,
    xd: np.ndarray,
    obstacle: np.ndarray,
    gamma: float,
    beta: float,
    obstacle_velocity: "np.ndarray | None" = None,
    *,
    tau: float = 1.0,
) -> np.ndarray:
    """Obstacle coupling term ``p = gamma R v phi exp(-beta phi)`` of eq. 10 (2-D or 3-D).

    ``phi`` is the angle between the direction to the obstacle ``o - x`` and the velocity
    relative to the obstacle (the paper's words), ``v = tau (xd - obstacle_velocity)``: the
    scaled velocity of eq. 7 (the module docstring says why ``tau`` matters); ``R`` and
    the ``v`` it turns are that relative velocity too, so the term is eq. 10 in the frame
    moving with the obstacle (Pastor et al.'s Fig. 13 avoids a moving ball). A static
    obstacle (``obstacle_velocity`` None or zero) gives eq. 10 with the end-effector's own
    velocity. The angle does not depend on ``tau``; the term is ``tau`` times the term for
    ``tau = 1``.
    ``R`` rotates by pi/2 about ``r = (o - x) x v``, which turns ``v`` away from the obstacle
    (the paper prints ``(x - o) x v``; with a right-handed +pi/2 rotation that axis would turn
    ``v`` *towards* the obstacle, so we use the sign of Hoffmann et al. 2009 and
    movement_primitives). 2-D vectors are the plane z = 0 of 3-D (the result is the 3-D
    term's x and y). Cases: ``v = 0`` gives ``p = 0``; ``v`` within round-off of parallel
    to ``o - x`` uses :func:`fallback_axis`, with ``phi = STRAIGHT_TOLERANCE`` when heading
    straight at the obstacle (the module docstring says why: eq. 10 is 0 there and the
    straight line through the obstacle is an unstable equilibrium) and ``phi = pi`` when
    heading straight away.
    ``x = o`` (e.g. an obstacle placed on the goal, reached at the end) gives ``p = 0``:
    ``phi`` has no limit there, but ``|p| = gamma |v| phi exp(-beta phi) <= gamma |v| /
    (e beta)`` goes to 0 with ``v`` as the DMP settles. An obstacle on the goal leaves the
    goal attracting: ``R v`` is perpendicular to ``v``, so ``p`` does no work on
    ``|v|^2 / 2 + K |x - g|^2 / 2`` and the movement still converges to ``g`` (eq. 10 has
    no distance term, so nothing is singular and nothing is refused).

    Args:
        x: Position, shape (3,) or (2,).
        xd: Velocity, the same shape.
        obstacle: Obstacle position, the same shape.
        gamma: Gain (>= 0).
        beta: Angular decay (the paper's c, >= 0).
        obstacle_velocity: The obstacle's velocity do/dt, the same shape (None: static).
        tau: The DMP's temporal scaling [s] (> 0): eq. 10's ``v`` is ``tau`` times the
            velocity relative to the obstacle. 1 gives the term of the physical velocity.

    Returns:
        ``p``, the shape of ``x``.

    Raises:
        RepertoireError: vectors of other sizes or with NaN/inf, a negative or non-numeric
            gain, or a tau that is not a finite number > 0.
    """
    # Plain-float arithmetic: called once per control step, numpy's per-call overhead on
    # 3-vectors (np.cross, np.linalg.norm) dominates otherwise.
    xa = np.asarray(x, dtype=float).reshape(-1)
    n = xa.size
    if n not in (2, 3):
        raise RepertoireError(f"x must have 2 or 3 entries (x, y[, z]), got {n}: {x}")
    x1, x2, x3 = _finite(n, "x", xa)
    v1, v2, v3 = _finite(n, "xd", xd)
    o1, o2, o3 = _finite(n, "obstacle", obstacle)
    if obstacle_velocity is not None:
        u1, u2, u3 = _finite(n, "obstacle_velocity", obstacle_velocity)
        v1, v2, v3 = v1 - u1, v2 - u2, v3 - u3
    check_gains(gamma, beta)
    if not (is_real(tau) and 0.0 < tau < math.inf):
        raise RepertoireError(f"tau must be a finite number > 0 [s], got {_shown(tau)}")
    d1, d2, d3 = o1 - x1, o2 - x2, o3 - x3
    speed = math.sqrt(v1 * v1 + v2 * v2 + v3 * v3)
    dist = math.sqrt(d1 * d1 + d2 * d2 + d3 * d3)
    if speed < 1e-12 or dist < 1e-12:
        return np.zeros(n)
    r1, r2, r3 = d2 * v3 - d3 * v2, d3 * v1 - d1 * v3, d1 * v2 - d2 * v1
    rn = math.sqrt(r1 * r1 + r2 * r2 + r3 * r3)
    dot = d1 * v1 + d2 * v2 + d3 * v3
    if rn <= STRAIGHT_TOLERANCE * dist * speed:
        # The limit of eq. 10 as the obstacle comes to the line from the right of the
        # direction x -> o: the axis is +a heading at it and -a heading away, so both
        # push to the same side (the left of x -> o).
        a1, a2, a3 = _fallback_axis(v1, v2, v3, speed)
        if dot > 0.0:
            phi = STRAIGHT_TOLERANCE
        else:
            a1, a2, a3, phi = -a1, -a2, -a3, math.pi
    else:
        a1, a2, a3 = r1 / rn, r2 / rn, r3 / rn
        phi = math.atan2(rn, dot)
    # Rotation of v by +pi/2 about the axis (v is perpendicular to it): R v = axis x v.
    s = tau * gamma * phi * math.exp(-beta * phi)  # R (tau v) = tau R v
    p = (s * (a2 * v3 - a3 * v2), s * (a3 * v1 - a1 * v3), s * (a1 * v2 - a2 * v1))
    return np.array(p[:n])


def _shown(value) -> str:
    """A number as printed; anything else (a string such as ``"1"``) by its repr."""
    return str(value) if is_real(value) else repr(value)


def _finite(n: int, name: str, value) -> tuple[float, float, float]:
    """Three finite floats from an n-vector (z = 0 in 2-D); RepertoireError naming it."""
    a = np.asarray(value, dtype=float).reshape(-1)
    if a.size != n:
        axes = "(x, y, z)" if n == 3 else "(x, y)"
        raise RepertoireError(f"{name} must have {n} entries {axes}, got {a.size}: {value}")
    a1, a2 = float(a[0]), float(a[1])
    a3 = float(a[2]) if n == 3 else 0.0
    # plain floats: numpy's per-call overhead dominates on 3-vectors (once per control step)
    if not (math.isfinite(a1) and math.isfinite(a2) and math.isfinite(a3)):
        raise RepertoireError(f"{name} contains NaN or inf: {a}")
    return a1, a2, a3
