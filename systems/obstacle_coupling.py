"""Obstacle avoidance coupling term (Pastor et al. 2009, eq. 10) at several points of the hand.

:func:`multi_point_obstacle_coupling` is the math, :class:`MultiPointObstacleCoupling`
the LeafSystem. Split out of systems/task_space.py (one concept per module).
"""

import math

import numpy as np
from pydrake.common.eigen_geometry import Quaternion
from pydrake.math import RotationMatrix
from pydrake.systems.framework import BasicVector, Context, LeafSystem
from repertoire.planning.dmp_obstacle import obstacle_coupling

from repertoire.checks import is_real
from repertoire.errors import RepertoireError


# ----------------------------------------------------------------------------- obstacle coupling
def multi_point_obstacle_coupling(
    x: np.ndarray,
    xd: np.ndarray,
    R_WE: np.ndarray,
    points_E: np.ndarray,
    obstacle: np.ndarray,
    gamma: float,
    beta: float,
    *,
    obstacle_radius: float = 0.0,
    length_scale: float = 0.0,
    obstacle_velocity: "np.ndarray | None" = None,
    tau: float = 1.0,
    goal: "np.ndarray | None" = None,
) -> np.ndarray:
    """Eq. 10 applied at several control points of the hand and its load, summed.

    Control point ``i`` sits at ``c_i = x + R_WE @ points_E[i]`` (``x`` is the
    end-effector's position, ``R_WE`` its orientation); it moves with the
    end-effector's linear velocity ``xd`` (the rotation's contribution is left out:
    the orientation DMPs turn slowly while carrying). Each point gets the paper's
    term ``p_i = gamma R_i v phi_i exp(-beta phi_i)``
    (:func:`repertoire.planning.dmp_obstacle.obstacle_coupling`, same axis sign) and
    the sum drives the end-effector's position DMP::

        p = sum_i s(d_i) p_i,   s(d) = exp(-max(d - obstacle_radius, 0) / length_scale)

    with ``d_i = |c_i - o|``. Eq. 10's velocity is the paper's scaled ``v = tau dx/dt``
    (eq. 7) of the DMP the term drives, as in
    :func:`repertoire.planning.dmp_obstacle.obstacle_coupling`: ``gamma`` is in the units of
    the phase time ``t / tau``, so a DMP re-timed to another ``tau`` takes the same path
    around the ball. In a :class:`~repertoire.systems.dmp_sequencer.DmpSequencer` pass the
    active segment's ``tau`` (its ``tau`` output): each segment then sees eq. 10 with one
    gain, whatever its duration. (Until session 36 this term took ``dx/dt``: the gain acted
    as ``gamma / tau`` of the paper's on each segment.) ``length_scale = 0`` gives ``s = 1``:
    the paper's eq. 10 exactly, summed over the points (with the single point ``[0, 0, 0]``
    it *is* eq. 10 on the end-effector). ``length_scale > 0`` is our
    extension: eq. 10 depends on the angle only, so a gain strong enough to clear a cup-sized load
    (which needs a smaller ``beta``, acting over a wider angle) would also bend the
    movement far from the obstacle and keep it from its goal; the distance factor
    fades the term out beyond a few ``length_scale`` from the ball's surface.

    With ``goal`` (the end-effector's goal) and ``length_scale > 0`` each point's term is
    also gated by what is left of the movement: ``h_i = 1`` while the ball's surface is
    nearer the point than the goal is to ``x`` (``gap_i <= |goal - x|``), falling smoothly
    (cubic) to 0 one ``length_scale`` beyond. A ball farther away than the goal is behind
    the movement or past its end. Without the gate the term kept acting at the goal: eq. 10
    turns ``v`` (it does no work, it vanishes with ``v``) but with the gain the arm needs
    (``gamma = 50000 / 3``) the exp fade still leaves it a turning rate about as large as
    the DMP's damping 11-20 cm from the ball, and a gyroscopic term that strong makes the
    slowest mode of the spring-damper decay several times slower: the DMP circled its goal
    at 2.6-4.2 mm/s for a second after the place segment's end (session 37).

    Args:
        x: End-effector position in W, shape (3,).
        xd: End-effector velocity dx/dt in W, shape (3,).
        R_WE: End-effector orientation (3 x 3 rotation matrix).
        points_E: Control points in the end-effector frame E, shape (k, 3), k >= 1.
        obstacle: Obstacle centre o in W, shape (3,).
        gamma: Gain of eq. 10 (>= 0).
        beta: Angular decay of eq. 10 (the paper's c, >= 0).
        obstacle_radius: Radius of the obstacle [m] (>= 0), where ``s`` is 1.
        length_scale: Decay length of ``s`` [m] (>= 0; 0 switches the factor off).
        obstacle_velocity: The obstacle's velocity in W, shape (3,) (None: static); each
            point's angle is taken to its velocity relative to the obstacle.
        tau: The driven DMP's temporal scaling [s] (> 0): eq. 10's ``v`` is ``tau`` times
            the velocity relative to the obstacle.
        goal: The end-effector's goal position in W, shape (3,) (None: no gate; the gate
            needs ``length_scale > 0``).

    Returns:
        The summed coupling term, shape (3,).

    Raises:
        RepertoireError: a negative gain, radius or length, badly shaped points, a tau
            that is not a finite number > 0, or a goal that is not a finite 3-vector.
    """
    if gamma < 0 or beta < 0 or obstacle_radius < 0 or length_scale < 0:
        raise RepertoireError(
            "gamma, beta, obstacle_radius and length_scale must be >= 0, got "
            f"{gamma}, {beta}, {obstacle_radius}, {length_scale}"
        )
    pts = np.asarray(points_E, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 3 or pts.shape[0] == 0 or not np.all(np.isfinite(pts)):
        raise RepertoireError(
            f"control points must be a non-empty k x 3 array of finite numbers, got shape "
            f"{pts.shape}"
        )
    x = np.asarray(x, dtype=float).reshape(3)
    o = np.asarray(obstacle, dtype=float).reshape(3)
    R = np.asarray(R_WE, dtype=float).reshape(3, 3)
    if not (is_real(tau) and 0.0 < tau < math.inf):
        raise RepertoireError(f"tau must be a finite number > 0 [s], got {tau!r}")
    to_go = None
    if goal is not None:
        g = np.asarray(goal, dtype=float)
        if g.shape not in ((3,), (3, 1)) or not np.all(np.isfinite(g)):
            raise RepertoireError(f"goal must be a finite 3-vector, got {goal!r}")
        to_go = float(np.linalg.norm(g.reshape(3) - x))
    total = np.zeros(3)
    for c in x + pts @ R.T:
        scale = 1.0
        if length_scale > 0.0:
            gap = max(float(np.linalg.norm(c - o)) - obstacle_radius, 0.0)
            scale = float(np.exp(-gap / length_scale))
            if to_go is not None:
                scale *= remaining_movement_gate(gap, to_go, length_scale)
            if scale < 1e-12:
                continue
        total += scale * obstacle_coupling(c, xd, o, gamma, beta, obstacle_velocity, tau=tau)
    return total


def remaining_movement_gate(gap: float, to_go: float, length_scale: float) -> float:
    """1 while a ball ``gap`` away is nearer than the goal, 0 one ``length_scale`` beyond.

    ``h = 3 u^2 - 2 u^3`` with ``u = clip(1 + (to_go - gap) / length_scale, 0, 1)``: 1 for
    ``gap <= to_go``, 0 for ``gap >= to_go + length_scale``, continuously differentiable.

    Args:
        gap: Distance of a control point from the ball's surface [m] (>= 0).
        to_go: Distance of the end-effector from its goal [m] (>= 0).
        length_scale: Width of the fall [m] (> 0).
    """
    u = min(max(1.0 + (to_go - gap) / length_scale, 0.0), 1.0)
    return u * u * (3.0 - 2.0 * u)


class MultiPointObstacleCoupling(LeafSystem):
    """Eq. 10 at several control points (tcp, the carried cup, the fingers), summed.

    Wraps :func:`multi_point_obstacle_coupling`; with the single control point
    ``[0, 0, 0]`` and ``length_scale = 0`` it outputs the paper's eq. 10 on the
    end-effector (as :class:`repertoire.systems.dmp.ObstacleCoupling`), with ``v = tau
    dx/dt``: ``tau`` from the ``tau`` input when connected (a
    :class:`~repertoire.systems.dmp_sequencer.DmpSequencer`'s ``tau`` output, the active
    segment's), else the ``tau`` parameter.

    Input ports:
        position: end-effector position x in W (3).
        velocity: end-effector velocity dx/dt in W (3).
        orientation: end-effector orientation [w, x, y, z] (4; normalised here).
        obstacle: obstacle centre o in W (3).
        obstacle_velocity: optional obstacle velocity in W (3; unconnected: static).
        tau: optional temporal scaling of the driven DMP [s] (1; unconnected: the ``tau``
            parameter).
        goal: optional goal position of the end-effector in W (3; unconnected: no gate,
            see :func:`multi_point_obstacle_coupling`).

    Output ports:
        coupling: the summed coupling term p (3), for the DMP chain's ``coupling`` input.

    Numeric parameters: [gamma, beta, obstacle_radius, length_scale], [tau].
    """

    def __init__(
        self,
        points_E: np.ndarray,
        *,
        gamma: float = 1000.0,
        beta: float = 20.0 / np.pi,
        obstacle_radius: float = 0.0,
        length_scale: float = 0.0,
        tau: float = 1.0,
    ) -> None:
        """Builds the coupling.

        Args:
            points_E: control points in the end-effector frame, shape (k, 3).
            gamma: gain of eq. 10.
            beta: angular decay of eq. 10.
            obstacle_radius: obstacle radius [m] for the distance factor.
            length_scale: decay length of the distance factor [m] (0: off, exact eq. 10).
            tau: the driven DMP's temporal scaling [s] while the ``tau`` input is not
                connected.

        Raises:
            RepertoireError: negative gains, badly shaped control points or a tau that is
                not a finite number > 0.
        """
        super().__init__()
        # Validates everything once (a zero velocity gives a zero term).
        multi_point_obstacle_coupling(
            np.zeros(3),
            np.zeros(3),
            np.eye(3),
            points_E,
            np.ones(3),
            gamma,
            beta,
            obstacle_radius=obstacle_radius,
            length_scale=length_scale,
            tau=tau,
        )
        self._points = np.array(points_E, dtype=float)
        self._params = self.DeclareNumericParameter(
            BasicVector([float(gamma), float(beta), float(obstacle_radius), float(length_scale)])
        )
        self._x = self.DeclareVectorInputPort("position", 3)
        self._v = self.DeclareVectorInputPort("velocity", 3)
        self._q = self.DeclareVectorInputPort("orientation", 4)
        self._o = self.DeclareVectorInputPort("obstacle", 3)
        self._vo = self.DeclareVectorInputPort("obstacle_velocity", 3)
        self._tau = self.DeclareNumericParameter(BasicVector([float(tau)]))
        self._tau_port = self.DeclareVectorInputPort("tau", 1)
        self._goal_port = self.DeclareVectorInputPort("goal", 3)
        self.DeclareVectorOutputPort("coupling", 3, self._calc)

    def _calc(self, context: Context, output: BasicVector) -> None:
        gamma, beta, radius, length = context.get_numeric_parameter(self._params).value()
        q = np.asarray(self._q.Eval(context), dtype=float)
        norm = float(np.linalg.norm(q))
        if not np.isfinite(norm) or norm < 1e-9:
            raise RepertoireError(f"orientation must be a non-zero quaternion, got {q}")
        R = RotationMatrix(Quaternion(q / norm)).matrix()
        if self._tau_port.HasValue(context):
            tau = float(self._tau_port.Eval(context)[0])
        else:
            tau = float(context.get_numeric_parameter(self._tau).GetAtIndex(0))
        output.SetFromVector(
            multi_point_obstacle_coupling(
                self._x.Eval(context),
                self._v.Eval(context),
                R,
                self._points,
                self._o.Eval(context),
                gamma,
                beta,
                obstacle_radius=radius,
                length_scale=length,
                obstacle_velocity=self._vo.Eval(context) if self._vo.HasValue(context) else None,
                tau=tau,
                goal=self._goal_port.Eval(context) if self._goal_port.HasValue(context) else None,
            )
        )
