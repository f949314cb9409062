"""DMP LeafSystems: canonical system, transformation system, quaternion DMPs, obstacle coupling.

The math lives in :mod:`repertoire.planning.dmp_math`; these systems only wrap it (Pastor
et al. 2009, eq. 1-10). Conventions: the transformation state is ``(x, v)`` with
``v = tau dx/dt`` (the paper's scaled velocity); output ports give physical velocity and
acceleration. Gains, weights, basis, tau and x0 are numeric parameters, so a Monte-Carlo
run can vary them in the Context without rebuilding.

The discrete-time form (exact first-order-hold steps) is in
:mod:`repertoire.systems.dmp_discrete`; chaining in :mod:`repertoire.systems.dmp_sequencer`.
"""

import math

import numpy as np
from pydrake.systems.framework import (
    BasicVector,
    Context,
    LeafSystem,
)
from repertoire.planning.dmp import DmpParameters, QuaternionDmpParameters, check_unit_quaternions
from repertoire.planning.dmp_math import (
    check_finite_vector,
    check_positive,
    forcing_term,
    transformation_derivatives,
)
from repertoire.planning.dmp_obstacle import check_gains, obstacle_coupling
from repertoire.planning.dmp_quaternion import (
    angular_velocity,
    check_turn,
    lift_quaternion_goal,
    manifold_step,
    post_normalised,
    quat_log_error,
)
from repertoire.systems.dmp_start import OnsetStartVelocity

from repertoire.errors import RepertoireError


def check_finite_input(name: str, value: np.ndarray) -> np.ndarray:
    """``value`` of input port ``name``; RepertoireError naming it if any entry is NaN or inf."""
    if not np.isfinite(value).all():
        raise RepertoireError(f"{name} input contains NaN or inf: {value}")
    return value


def check_finite_goal(goal: np.ndarray) -> np.ndarray:
    return check_finite_input("goal", goal)


def check_unit_goal(goal: np.ndarray) -> np.ndarray:
    """A goal orientation input (w, x, y, z) within 1e-6 of unit norm; RepertoireError if not.

    Args:
        goal: The goal input's value, shape (4,).
    """
    norm = float(np.linalg.norm(goal))
    if not abs(norm - 1.0) <= 1e-6:
        raise RepertoireError(f"goal orientation input is not a unit quaternion: |g| = {norm}")
    return goal


def goal_input(port, context: Context, learned: np.ndarray) -> np.ndarray:
    """The goal input's value if it is connected (or fixed), else the ``learned`` goal.

    A DMP whose goal input is left unconnected reproduces its demonstration's goal
    (:class:`repertoire.systems.dmp_sequencer.DmpSequencer` passes its built goals).
    RepertoireError if a connected goal holds NaN or inf; ``learned`` is returned as it is
    (not copied, not checked: validated where it was built).
    """
    if port.HasValue(context):
        return check_finite_goal(port.Eval(context))
    return learned


def check_start_time(start_time: float) -> float:
    """``start_time`` [s] as a float; RepertoireError unless it is a finite number."""
    try:
        value = float(start_time)
    except (TypeError, ValueError):
        value = math.nan
    if not math.isfinite(value):
        raise RepertoireError(f"start_time must be a finite number [s], got {start_time}")
    return value


class Onset:
    """The ``start_time`` parameter (``_start``) of a DMP that holds its state until then.

    While held the position does not move, so the velocity (and acceleration) outputs are
    0; the state keeps the start velocity (``tau v0``, the demonstration's), which the
    movement starts with at the onset. Mixed in before LeafSystem.
    """

    def held(self, context: Context) -> bool:
        """Whether ``context``'s time is before the ``start_time`` parameter.

        Args:
            context: This system's context.
        """
        return context.get_time() < context.get_numeric_parameter(self._start).GetAtIndex(0)

    def set_start_time(self, context: Context, start_time: float) -> None:
        """Hold the state until ``start_time``.

        Args:
            context: This system's context.
            start_time: Movement onset [s].
        """
        context.get_mutable_numeric_parameter(self._start).SetAtIndex(
            0, check_start_time(start_time)
        )


class CanonicalSystem(Onset, LeafSystem):
    """Canonical system ``tau theta' = -alpha theta`` (eq. 4), ``theta(0) = 1``.

    Before the parameter ``start_time`` the phase is held at 1 (for a delayed start).

    Input ports:
        tau (1, optional, ``time_scaling_input=True``): online temporal scaling [s],
            replaces the ``tau`` parameter; unconnected: the parameter (as in
            :class:`TransformationSystem`).

    Output ports:
        phase (1): theta (depends on the state only).

    Numeric parameters: tau, alpha, start_time.
    """

    def __init__(
        self,
        tau: float = 1.0,
        alpha: float = float(np.log(100.0)),
        *,
        time_scaling_input: bool = False,
        start_time: float = 0.0,
    ) -> None:
        super().__init__()
        check_positive("tau", tau)
        check_positive("alpha", alpha)
        self._tau_index = self.DeclareNumericParameter(BasicVector([float(tau)]))
        self._alpha_index = self.DeclareNumericParameter(BasicVector([float(alpha)]))
        self._start = self.DeclareNumericParameter(BasicVector([check_start_time(start_time)]))
        self.DeclareContinuousState(BasicVector([1.0]))
        self._tau_port = self.DeclareVectorInputPort("tau", 1) if time_scaling_input else None
        self._phase_port = self.DeclareVectorOutputPort(
            "phase", 1, self._calc_phase, prerequisites_of_calc={self.xc_ticket()}
        )

    def get_tau_input_port(self):
        return self._tau_port

    def get_phase_output_port(self):
        return self._phase_port

    def tau(self, context: Context) -> float:
        """Effective tau (input if declared and connected, else parameter); raises if <= 0.

        Args:
            context: This system's context.
        """
        if self._tau_port is not None and self._tau_port.HasValue(context):
            tau = float(self._tau_port.Eval(context)[0])
        else:
            tau = float(context.get_numeric_parameter(self._tau_index).GetAtIndex(0))
        if not 0.0 < tau < math.inf:
            raise RepertoireError(f"tau must be a finite number > 0, got {tau}")
        return tau

    def set_phase(self, context: Context, theta: float = 1.0) -> None:
        """Set the phase state.

        Args:
            context: This system's context.
            theta: Phase value.
        """
        context.get_mutable_continuous_state_vector().SetAtIndex(0, float(theta))

    def DoCalcTimeDerivatives(self, context: Context, derivatives) -> None:
        if self.held(context):
            derivatives.get_mutable_vector().SetAtIndex(0, 0.0)
            return
        alpha = context.get_numeric_parameter(self._alpha_index).GetAtIndex(0)
        theta = context.get_continuous_state_vector().GetAtIndex(0)
        derivatives.get_mutable_vector().SetAtIndex(0, -alpha * theta / self.tau(context))

    def _calc_phase(self, context: Context, output: BasicVector) -> None:
        output.SetAtIndex(0, context.get_continuous_state_vector().GetAtIndex(0))


class VectorDmpPorts:
    """Port getters shared by the vector DMP LeafSystems (mixed in before LeafSystem).

    The system sets ``_n``, ``_goal_port`` (None without a goal input), ``_learned_goal``
    (the goal an unconnected goal input stands for) and the ``_position_port``,
    ``_velocity_port`` and ``_acceleration_port`` outputs.
    """

    def _goal(self, context: Context) -> np.ndarray:
        """The goal input, or the learned goal when it is not connected (:func:`goal_input`)."""
        return goal_input(self._goal_port, context, self._learned_goal)

    def get_goal_input_port(self):
        return self._goal_port

    def get_position_output_port(self):
        return self._position_port

    def get_velocity_output_port(self):
        return self._velocity_port

    def get_acceleration_output_port(self):
        return self._acceleration_port

    @property
    def n_dims(self) -> int:
        return self._n


class CouplingAndOnset(Onset, VectorDmpPorts):
    """Optional coupling input and the ``start_time`` parameter (``_coupling_port``, ``_start``)."""

    def get_coupling_input_port(self):
        return self._coupling_port

    def _has_coupling(self, context: Context) -> bool:
        """Whether the coupling input is declared and connected (or fixed)."""
        return self._coupling_port is not None and self._coupling_port.HasValue(context)

    def _coupling(self, context: Context) -> "np.ndarray | float":
        """The coupling input if declared and connected, else 0; RepertoireError if not finite."""
        if not self._has_coupling(context):
            return 0.0
        return check_finite_input("coupling", self._coupling_port.Eval(context))


class TransformationSystem(OnsetStartVelocity, CouplingAndOnset, LeafSystem):
    """n-DOF transformation system, the paper's new form (eq. 6, 9) or the old one (eq. 1).

    Continuous state ``[x - x0 (n), v (n)]``: the displacement from the ``x0`` parameter
    (the equations see positions only through ``g - x``, ``g - x0`` and ``x - x0``, so a
    movement far from the origin keeps its digits, as the discrete step and the NumPy
    rollout do) and ``v = tau dx/dt``; initially ``x = x0`` and ``v = tau dmp.v0`` (the
    demonstration's initial velocity, :meth:`DmpParameters.initial_scaled_velocity`). In
    the old formulation that learned velocity is scaled to the goal input at the onset, as
    ``rollout`` scales it to its goal (:mod:`repertoire.systems.dmp_start`: a discrete flag
    and, at the first simulator step from the onset, a per-step update).
    :meth:`set_start` and :meth:`set_state` take absolute positions. Before the
    ``start_time`` parameter the state is held: derivatives and the velocity and
    acceleration outputs are 0 (the state keeps ``v``, the velocity the movement starts
    with at the onset).

    Input ports:
        phase (1): theta from a CanonicalSystem.
        goal (n): goal g (may change during the movement); unconnected: the learned goal
            ``dmp.goal``.
        coupling (n, optional): coupling term p added to ``tau v'`` (eq. 9).
        tau (1, optional): online temporal scaling, replaces the tau parameter.

    Output ports:
        position (n): x = x0 + state (state and the x0 parameter).
        velocity (n): dx/dt = v / tau, 0 while held (state, parameters and time only, so
            a coupling computed from it is not an algebraic loop).
        acceleration (n): d2x/dt2 = v' / tau.

    Numeric parameters: weights (n * n_basis, row-major (n, n_basis)), centres, widths,
    K (n), D (n), tau (1), x0 (n), start_time (1).
    """

    def __init__(
        self,
        dmp: DmpParameters,
        *,
        coupling_input: bool = False,
        time_scaling_input: bool = False,
    ) -> None:
        super().__init__()
        if not isinstance(dmp, DmpParameters):
            raise RepertoireError(f"TransformationSystem needs DmpParameters, got {type(dmp)}")
        dmp.validate()
        n, b = dmp.weights.shape
        self._n, self._b = n, b
        self._formulation = dmp.formulation
        self._learned_goal = dmp.goal.copy()
        self._w = self.DeclareNumericParameter(BasicVector(dmp.weights.reshape(-1)))
        self._c = self.DeclareNumericParameter(BasicVector(dmp.centres))
        self._h = self.DeclareNumericParameter(BasicVector(dmp.widths))
        self._K = self.DeclareNumericParameter(BasicVector(dmp.K))
        self._D = self.DeclareNumericParameter(BasicVector(dmp.D))
        self._tau = self.DeclareNumericParameter(BasicVector([dmp.tau]))
        self._x0 = self.DeclareNumericParameter(BasicVector(dmp.x0))
        self._start = self.DeclareNumericParameter(BasicVector([0.0]))
        self._declare_start_velocity(dmp)
        state0 = np.concatenate([np.zeros(n), self._learned_v])
        self.DeclareContinuousState(BasicVector(state0), n, n, 0)
        self._phase_port = self.DeclareVectorInputPort("phase", 1)
        self._goal_port = self.DeclareVectorInputPort("goal", n)
        if self._pending is not None:
            self.DeclarePerStepUnrestrictedUpdateEvent(self._scale_start)
        self._coupling_port = self.DeclareVectorInputPort("coupling", n) if coupling_input else None
        self._tau_port = self.DeclareVectorInputPort("tau", 1) if time_scaling_input else None
        state_and_params = {self.xc_ticket(), self.all_parameters_ticket()}
        self._position_port = self.DeclareVectorOutputPort(
            "position", n, self._calc_position, prerequisites_of_calc=state_and_params
        )
        # the time too: the velocity is 0 while held before start_time
        vel_prereq = (
            state_and_params | {self.time_ticket()} | self._start_tickets()
            if self._tau_port is None
            else {self.all_sources_ticket()}
        )
        self._velocity_port = self.DeclareVectorOutputPort(
            "velocity", n, self._calc_velocity, prerequisites_of_calc=vel_prereq
        )
        self._acceleration_port = self.DeclareVectorOutputPort(
            "acceleration", n, self._calc_acceleration
        )

    # ports (goal, coupling, position, velocity, acceleration: see VectorDmpPorts)
    def get_phase_input_port(self):
        return self._phase_port

    def get_tau_input_port(self):
        return self._tau_port

    # context helpers
    def set_start(self, context: Context, x0: np.ndarray, xd0: np.ndarray | None = None) -> None:
        """Set the start x0 (parameter and state) and the initial physical velocity.

        Args:
            context: This system's context.
            x0: Start position, shape (n,).
            xd0: Initial velocity dx/dt, shape (n,); default the learned ``dmp.v0`` (its
                scaled velocity ``tau v0`` at the learned tau, whatever the context's tau;
                in the old formulation scaled to the goal input at the onset).
        """
        x0 = check_finite_vector("x0", x0, self._n)
        if xd0 is None:
            v = self._learned_v
        else:
            v = self._tau_value(context) * check_finite_vector("xd0", xd0, self._n)
        context.get_mutable_numeric_parameter(self._x0).SetFromVector(x0)
        self._set_learned_start(context, xd0 is None)
        context.get_mutable_continuous_state_vector().SetFromVector(
            np.concatenate([np.zeros(self._n), v])
        )

    def get_start(self, context: Context) -> np.ndarray:
        """A copy of the start x0 (numeric parameter).

        Args:
            context: This system's context.
        """
        return context.get_numeric_parameter(self._x0).get_value().copy()

    def set_state(self, context: Context, x: np.ndarray, xd: np.ndarray) -> None:
        """Set the state to position ``x`` (absolute) and velocity ``dx/dt = xd``; x0 stays.

        Args:
            context: This system's context.
            x: Position, shape (n,).
            xd: Velocity dx/dt, shape (n,).
        """
        x = check_finite_vector("x", x, self._n)
        xd = check_finite_vector("xd", xd, self._n)
        x0 = context.get_numeric_parameter(self._x0).get_value()
        v = self._tau_value(context) * xd
        context.get_mutable_continuous_state_vector().SetFromVector(np.concatenate([x - x0, v]))
        self._set_learned_start(context, False)

    def _tau_value(self, context: Context) -> float:
        if self._tau_port is not None and self._tau_port.HasValue(context):
            tau = float(self._tau_port.Eval(context)[0])
        else:
            tau = float(context.get_numeric_parameter(self._tau).GetAtIndex(0))
        if not 0.0 < tau < math.inf:
            raise RepertoireError(f"tau must be a finite number > 0, got {tau}")
        return tau

    def _derivatives(self, context: Context) -> tuple[np.ndarray, np.ndarray]:
        n = self._n
        z = context.get_continuous_state_vector().CopyToVector()
        y, v = z[:n], z[n:]  # y = x - x0
        if self.held(context):
            return np.zeros(n), np.zeros(n)
        theta = float(self._phase_port.Eval(context)[0])
        p = context.get_numeric_parameter
        x0 = p(self._x0).value()
        v = self._onset_velocity(context, v, x0)
        goal = self._goal(context) - x0  # the equations in the displacement from x0
        W = p(self._w).value().reshape(n, self._b)
        f = forcing_term(theta, W, p(self._c).value(), p(self._h).value())
        coupling = self._coupling(context)
        return transformation_derivatives(
            y,
            v,
            theta,
            goal,
            np.zeros(n),
            f,
            p(self._K).value(),
            p(self._D).value(),
            self._tau_value(context),
            self._formulation,
            coupling,
        )

    def DoCalcTimeDerivatives(self, context: Context, derivatives) -> None:
        xd, vd = self._derivatives(context)
        derivatives.get_mutable_vector().SetFromVector(np.concatenate([xd, vd]))

    def _calc_position(self, context: Context, output: BasicVector) -> None:
        y = context.get_continuous_state_vector().CopyToVector()[: self._n]
        output.SetFromVector(context.get_numeric_parameter(self._x0).get_value() + y)

    def _calc_velocity(self, context: Context, output: BasicVector) -> None:
        if self.held(context):  # the position does not move (the state keeps tau v0)
            output.SetFromVector(np.zeros(self._n))
            return
        v = context.get_continuous_state_vector().CopyToVector()[self._n :]
        v = self._onset_velocity(context, v, context.get_numeric_parameter(self._x0).value())
        output.SetFromVector(v / self._tau_value(context))

    def _scale_start(self, context: Context, state) -> None:
        """From the onset on, the flagged start velocity scaled to the goal input, once."""
        if self.held(context) or self._pending_flag(context) is None:
            return
        z = context.get_continuous_state_vector().CopyToVector()
        x0 = context.get_numeric_parameter(self._x0).value()
        z[self._n :] = self._onset_velocity(context, z[self._n :], x0)
        state.get_mutable_continuous_state().get_mutable_vector().SetFromVector(z)
        state.get_mutable_discrete_state(self._pending).SetFromVector(np.zeros(self._n))

    def _calc_acceleration(self, context: Context, output: BasicVector) -> None:
        _, vd = self._derivatives(context)
        output.SetFromVector(vd / self._tau_value(context))


class QuaternionGoalSign(LeafSystem):
    """The component quaternion DMP's goal with the learned sign (``g`` or ``-g``).

    The component form (sec. IV-B) runs in R^4, where ``g`` and ``-g`` (one orientation)
    are different goals: one turns the learned way round, the other back the other way. This
    system passes the goal on with the sign that turns from the movement's start the way
    the DMP learned (:func:`repertoire.planning.dmp_quaternion.lift_quaternion_goal`, as
    :meth:`repertoire.planning.dmp.QuaternionDmpParameters.rollout` does; for the learned
    start, the sign nearest the learned goal), so the goal input takes either sign, also
    for demonstrations turning past 180 deg.

    Input ports:
        goal (4): goal orientation (w, x, y, z), unit (RepertoireError otherwise, as in
            :class:`ManifoldQuaternionSystem`); unconnected: the learned goal.

    Output ports:
        goal (4): the same orientation with the learned goal's sign.

    Numeric parameters: start (4), the component DMP's start q0 (default the learned one).
    """

    def __init__(self, dmp: QuaternionDmpParameters) -> None:
        super().__init__()
        if not isinstance(dmp, QuaternionDmpParameters):
            raise RepertoireError(
                f"QuaternionGoalSign needs QuaternionDmpParameters, got {type(dmp).__name__}"
            )
        self._learned_goal, self._learned_q0 = dmp.goal.copy(), dmp.q0.copy()
        self._start = self.DeclareNumericParameter(BasicVector(dmp.q0))
        self._in = self.DeclareVectorInputPort("goal", 4)
        self._out = self.DeclareVectorOutputPort("goal", 4, self._calc)

    def set_start(self, context: Context, q0: np.ndarray) -> None:
        """Set the start the goal's sign is chosen from (the component DMP's q0).

        Args:
            context: This system's context.
            q0: Start orientation (w, x, y, z), shape (4,).
        """
        context.get_mutable_numeric_parameter(self._start).SetFromVector(
            check_finite_vector("q0", q0, 4)
        )

    def _calc(self, context: Context, output: BasicVector) -> None:
        goal = check_unit_goal(goal_input(self._in, context, self._learned_goal))
        start = context.get_numeric_parameter(self._start).get_value()
        output.SetFromVector(
            lift_quaternion_goal(goal, start, self._learned_goal, self._learned_q0)
        )


class QuaternionNormalizer(LeafSystem):
    """Post-normalisation of the paper's component quaternion DMP (sec. IV-B).

    Input ports:
        quaternion (4): un-normalised (w, x, y, z) from a 4-DOF transformation system.
        quaternion_rate (4): its time derivative.

    Output ports:
        orientation (4): ``n = q / |q|``.
        angular_velocity (3): ``2 vec(n' n^*)`` (world frame), with
            ``n' = (q' - n (n . q')) / |q|``.
        norm_error (1): ``|q| - 1`` (how far the component DMP left the unit sphere).
    """

    def __init__(self) -> None:
        super().__init__()
        self._in = self.DeclareVectorInputPort("quaternion", 4)
        self._rate = self.DeclareVectorInputPort("quaternion_rate", 4)
        self._out = self.DeclareVectorOutputPort("orientation", 4, self._calc)
        self._omega = self.DeclareVectorOutputPort("angular_velocity", 3, self._calc_omega)
        self._err = self.DeclareVectorOutputPort("norm_error", 1, self._calc_err)

    def get_quaternion_input_port(self):
        return self._in

    def get_quaternion_rate_input_port(self):
        return self._rate

    def get_orientation_output_port(self):
        return self._out

    def get_angular_velocity_output_port(self):
        return self._omega

    def _normalised(self, context: Context, rate: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        q = check_finite_input("quaternion", self._in.Eval(context))
        return post_normalised(q, rate)

    def _calc(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._normalised(context, np.zeros(4))[0])

    def _calc_omega(self, context: Context, output: BasicVector) -> None:
        u, ud = self._normalised(context, self._rate.Eval(context))
        output.SetFromVector(angular_velocity(u, ud))

    def _calc_err(self, context: Context, output: BasicVector) -> None:
        output.SetAtIndex(0, float(np.linalg.norm(self._in.Eval(context)) - 1.0))


class ManifoldQuaternionSystem(Onset, LeafSystem):
    """On-manifold quaternion DMP, discrete time (exact unit norm via the exponential map).

    Discrete state ``[q (4), eta (3)]`` (eta = tau omega, world frame; initially ``q0`` and
    ``tau omega0``, the demonstration's start), updated every
    ``time_step`` by :func:`repertoire.planning.dmp_quaternion.manifold_step` (velocity Verlet
    with the rotation applied through the exponential map) for
    ``tau eta' = K e(g,q) - D eta - K e(g,q0) theta + K f(theta)``, ``e = 2 log(g q^*)``
    on S^3 (:func:`repertoire.planning.dmp_quaternion.quat_log_error`). The goal input's sign
    does not matter: the sign that turns the learned way round is used
    (:func:`repertoire.planning.dmp_quaternion.lift_quaternion_goal`), so a demonstration turning
    past 180 deg is reproduced; a goal a full turn from q0 that way is refused.
    The phase at the end of a step is ``theta exp(-alpha dt / tau)`` (the tau parameter).
    The state is held before the ``start_time`` parameter (the angular velocity output is
    then 0; the state keeps ``tau omega0``, which the turn starts with at the onset).

    Input ports:
        phase (1): theta.
        goal (4): goal orientation (w, x, y, z), unit; unconnected: the learned goal.

    Output ports:
        orientation (4): q.
        angular_velocity (3): omega = eta / tau (world frame).

    Numeric parameters: weights (3 * n_basis), centres, widths, K, D, tau, q0, start_time.
    """

    def __init__(self, dmp: QuaternionDmpParameters, *, time_step: float = 1e-3) -> None:
        super().__init__()
        if not isinstance(dmp, QuaternionDmpParameters) or dmp.mode != "manifold":
            raise RepertoireError(
                "ManifoldQuaternionSystem needs QuaternionDmpParameters(mode='manifold')"
            )
        check_positive("time_step", time_step)
        self._b = dmp.n_basis
        self._dt = float(time_step)
        # The phase input is assumed to decay as the canonical system with this DMP's
        # alpha and the context's tau (used for the phase at the end of each step).
        self._alpha = float(dmp.alpha)
        # The learned start and goal fix which sign of a goal input turns the learned way
        # round (lift_quaternion_goal); they belong to the weights, like n_basis.
        self._learned_goal, self._learned_q0 = dmp.goal.copy(), dmp.q0.copy()
        self._w = self.DeclareNumericParameter(BasicVector(dmp.weights.reshape(-1)))
        self._c = self.DeclareNumericParameter(BasicVector(dmp.centres))
        self._h = self.DeclareNumericParameter(BasicVector(dmp.widths))
        self._gains = self.DeclareNumericParameter(BasicVector([dmp.K, dmp.D, dmp.tau]))
        self._q0 = self.DeclareNumericParameter(BasicVector(dmp.q0))
        self._start = self.DeclareNumericParameter(BasicVector([0.0]))
        self._learned_eta = dmp.tau * dmp.omega0  # the demonstration's initial eta
        self._state = self.DeclareDiscreteState(np.concatenate([dmp.q0, self._learned_eta]))
        self.DeclarePeriodicDiscreteUpdateEvent(self._dt, 0.0, self._update)
        self._phase_port = self.DeclareVectorInputPort("phase", 1)
        self._goal_port = self.DeclareVectorInputPort("goal", 4)
        self._q_port = self.DeclareVectorOutputPort(
            "orientation", 4, self._calc_q, prerequisites_of_calc={self.xd_ticket()}
        )
        self._w_port = self.DeclareVectorOutputPort(
            "angular_velocity",
            3,
            self._calc_omega,
            # the time too: 0 while held before start_time
            prerequisites_of_calc={
                self.xd_ticket(),
                self.all_parameters_ticket(),
                self.time_ticket(),
            },
        )

    def get_phase_input_port(self):
        return self._phase_port

    def get_goal_input_port(self):
        return self._goal_port

    def get_orientation_output_port(self):
        return self._q_port

    def get_angular_velocity_output_port(self):
        return self._w_port

    def set_start(self, context: Context, q0: np.ndarray, omega0: np.ndarray | None = None):
        """Set start orientation (parameter and state) and initial angular velocity.

        Args:
            context: This system's context.
            q0: Unit quaternion (w, x, y, z).
            omega0: Initial angular velocity (world); default the learned ``dmp.omega0``
                (its ``eta = tau omega0`` at the learned tau).
        """
        q0 = check_finite_vector("q0", q0, 4)
        check_unit_quaternions(q0[None], name="q0")
        if omega0 is None:
            eta = self._learned_eta
        else:
            tau = context.get_numeric_parameter(self._gains).GetAtIndex(2)
            eta = tau * check_finite_vector("omega0", omega0, 3)
        context.get_mutable_numeric_parameter(self._q0).SetFromVector(q0)
        context.get_mutable_discrete_state(self._state).SetFromVector(np.concatenate([q0, eta]))

    def get_start(self, context: Context) -> np.ndarray:
        """A copy of the start orientation q0 (numeric parameter).

        Args:
            context: This system's context.
        """
        return context.get_numeric_parameter(self._q0).get_value().copy()

    def _update(self, context: Context, discrete_state) -> None:
        s = context.get_discrete_state(self._state).CopyToVector()
        if self.held(context):
            discrete_state.get_mutable_vector(self._state).SetFromVector(s)
            return
        q, eta = s[:4], s[4:]
        p = context.get_numeric_parameter
        K, D, tau = p(self._gains).value()
        theta = float(self._phase_port.Eval(context)[0])
        theta_next = theta * math.exp(-self._alpha * self._dt / tau)
        goal = check_unit_goal(goal_input(self._goal_port, context, self._learned_goal))
        W = p(self._w).value().reshape(3, self._b)
        f = forcing_term(np.array([theta, theta_next]), W, p(self._c).value(), p(self._h).value())
        q0 = p(self._q0).value()
        goal = lift_quaternion_goal(goal, q0, self._learned_goal, self._learned_q0)
        check_turn(goal, q0, what="from q0 to the goal orientation input")
        e0 = quat_log_error(goal, q0)
        a = (K * quat_log_error(goal, q) - K * e0 * theta + K * f[0]) / tau
        eta, q, _ = manifold_step(q, eta, a, goal, e0, theta_next, f[1], K, D, tau, self._dt)
        discrete_state.get_mutable_vector(self._state).SetFromVector(np.concatenate([q, eta]))

    def _calc_q(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(context.get_discrete_state(self._state).CopyToVector()[:4])

    def _calc_omega(self, context: Context, output: BasicVector) -> None:
        if self.held(context):  # the orientation does not move (the state keeps tau omega0)
            output.SetFromVector(np.zeros(3))
            return
        tau = context.get_numeric_parameter(self._gains).GetAtIndex(2)
        output.SetFromVector(context.get_discrete_state(self._state).CopyToVector()[4:] / tau)


class ObstacleCoupling(LeafSystem):
    """Obstacle-avoidance coupling term of eq. 10 in 3-D (or in the plane, ``n_dims=2``).

    ``p = gamma R v phi exp(-beta phi)`` with the paper's scaled velocity ``v = tau dx/dt``
    (eq. 7), so the coupled DMP takes the same path at any tau; see
    :func:`repertoire.planning.dmp_obstacle.obstacle_coupling` for the axis sign and the
    v = 0 / parallel cases (heading straight at the obstacle included).
    :class:`repertoire.systems.dmp_compose.DmpSystem` sets ``tau`` to its DMP's.

    Input ports (n = ``n_dims``, 3 by default):
        position (n): end-effector position x.
        velocity (n): end-effector velocity dx/dt.
        obstacle (n): obstacle position o.
        obstacle_velocity (n): optional obstacle velocity do/dt (unconnected: a static
            obstacle); eq. 10's angle is taken to the velocity relative to the obstacle.

    Output ports:
        coupling (n): p, to be fed to a TransformationSystem's coupling input.

    Numeric parameters: gamma, beta; tau (the DMP's, :meth:`set_tau`).
    """

    def __init__(
        self,
        gamma: float = 1000.0,
        beta: float = 20.0 / np.pi,
        *,
        n_dims: int = 3,
        tau: float = 1.0,
    ) -> None:
        """Builds the system.

        Args:
            gamma: Gain of eq. 10 (>= 0).
            beta: Angular decay of eq. 10 (>= 0).
            n_dims: 3, or 2 for a movement in the plane (eq. 10 in its z = 0 plane).
            tau: The coupled DMP's temporal scaling [s] (> 0): eq. 10 turns ``tau`` times
                the velocity input (the paper's ``v``).

        Raises:
            RepertoireError: negative or non-finite gains, ``n_dims`` not 2 or 3, or a tau
                that is not a finite number > 0.
        """
        super().__init__()
        if isinstance(n_dims, bool) or n_dims not in (2, 3):
            raise RepertoireError(f"ObstacleCoupling needs n_dims 2 or 3, got {n_dims!r}")
        n = int(n_dims)
        self._params = self.DeclareNumericParameter(BasicVector(check_gains(gamma, beta)))
        self._tau = self.DeclareNumericParameter(BasicVector([check_positive("tau", tau)]))
        self._x = self.DeclareVectorInputPort("position", n)
        self._v = self.DeclareVectorInputPort("velocity", n)
        self._o = self.DeclareVectorInputPort("obstacle", n)
        self._vo = self.DeclareVectorInputPort("obstacle_velocity", n)
        self._out = self.DeclareVectorOutputPort("coupling", n, self._calc)

    def set_gains(self, context: Context, gamma: float, beta: float) -> None:
        """Set gamma and beta.

        Args:
            context: This system's context.
            gamma: Gain >= 0.
            beta: Angular decay >= 0.
        """
        context.get_mutable_numeric_parameter(self._params).SetFromVector(check_gains(gamma, beta))

    def set_tau(self, context: Context, tau: float) -> None:
        """Set the coupled DMP's tau (eq. 10's ``v`` is ``tau`` times the velocity input).

        Args:
            context: This system's context.
            tau: Temporal scaling [s], > 0.
        """
        context.get_mutable_numeric_parameter(self._tau).SetAtIndex(0, check_positive("tau", tau))

    def _calc(self, context: Context, output: BasicVector) -> None:
        gamma, beta = context.get_numeric_parameter(self._params).value()
        tau = float(context.get_numeric_parameter(self._tau).GetAtIndex(0))
        vo = self._vo.Eval(context) if self._vo.HasValue(context) else None
        x, v, o = self._x.Eval(context), self._v.Eval(context), self._o.Eval(context)
        output.SetFromVector(obstacle_coupling(x, v, o, gamma, beta, vo, tau=tau))
