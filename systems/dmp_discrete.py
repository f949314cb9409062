"""The discrete-time DMP LeafSystem: canonical + transformation system, exact steps.

One step is the exact first-order-hold update tabulated by
:class:`repertoire.planning.dmp_discrete.DiscreteDmpTables`, the discretisation of
:func:`repertoire.planning.dmp_math.rollout`, so a 1 kHz run reproduces the NumPy rollout
to rounding. The continuous forms are in :mod:`repertoire.systems.dmp`.
"""

import numpy as np
from pydrake.systems.framework import BasicVector, Context, LeafSystem
from repertoire.planning.dmp import DmpParameters
from repertoire.planning.dmp_discrete import DiscreteDmpTables
from repertoire.planning.dmp_math import (
    check_finite_vector,
    check_positive,
    transformation_derivatives,
)
from repertoire.systems.dmp import CouplingAndOnset, VectorDmpPorts
from repertoire.systems.dmp_start import OnsetStartVelocity

from repertoire.errors import RepertoireError


class _DiscreteDmpOutputs(VectorDmpPorts):
    """The outputs of the discrete DMP systems: position, velocity, acceleration, phase.

    Position, velocity and phase depend on the discrete state only; the system provides
    ``_calc_position``, ``_calc_velocity``, ``_calc_acceleration`` and ``_calc_phase``.
    """

    def _declare_discrete_outputs(self, n: int, start: set = frozenset()) -> None:
        only_state = {self.xd_ticket()}
        self._position_port = self.DeclareVectorOutputPort(
            "position", n, self._calc_position, prerequisites_of_calc=only_state
        )
        # the time and start_time too: the velocity is 0 while held; ``start``: what an
        # old-formulation start velocity depends on (the goal input, OnsetStartVelocity)
        held = {self.xd_ticket(), self.time_ticket(), self.all_parameters_ticket()} | start
        self._velocity_port = self.DeclareVectorOutputPort(
            "velocity", n, self._calc_velocity, prerequisites_of_calc=held
        )
        self._acceleration_port = self.DeclareVectorOutputPort(
            "acceleration", n, self._calc_acceleration
        )
        self._phase_port = self.DeclareVectorOutputPort(
            "phase", 1, self._calc_phase, prerequisites_of_calc=only_state
        )

    def get_phase_output_port(self):
        return self._phase_port


class DiscreteDmpSystem(OnsetStartVelocity, CouplingAndOnset, _DiscreteDmpOutputs, LeafSystem):
    """Canonical + transformation system in one discrete-time LeafSystem (fast, exact).

    Every ``time_step`` the spring-damper state is advanced by the exact first-order-hold
    discretisation used by :func:`repertoire.planning.dmp_math.rollout` (goal, x0 and
    coupling held over the step; phase and forcing term linear between the step's ends).
    The phase after k steps is ``exp(-alpha k dt / tau)`` exactly, so the per-step
    coefficients are tabulated at construction and one step costs a few vector operations:
    a 1 kHz rollout is cheap and reproduces the NumPy rollout to rounding.

    Discrete state ``[k, x (n), v (n)]`` (k = steps since onset, v = tau dx/dt; initially
    ``x0`` and ``tau dmp.v0``, the demonstration's start; in the old formulation scaled to
    the goal input at the onset step, as ``rollout`` scales it to its goal,
    :mod:`repertoire.systems.dmp_start`); the state is held before the ``start_time``
    parameter (velocity and acceleration outputs 0 then, as in
    :class:`TransformationSystem`).

    Input ports:
        goal (n): goal g (may change during the movement); unconnected: the learned goal
            ``dmp.goal``.
        coupling (n, optional): coupling term p added to ``tau v'``.

    Output ports:
        position (n), velocity (n) (dx/dt), acceleration (n) (d2x/dt2 at the current
        state and inputs), phase (1); velocity and acceleration are 0 while the state is
        held before ``start_time``, as in :class:`TransformationSystem`.

    Numeric parameters: x0 (n), start_time (1). Weights, basis, K, D, tau, alpha and the
    time step are construction arguments (the discretisation is precomputed from them); use
    :class:`TransformationSystem` when they must vary per context.
    """

    def __init__(
        self, dmp: DmpParameters, *, time_step: float = 1e-3, coupling_input: bool = False
    ) -> None:
        super().__init__()

        if not isinstance(dmp, DmpParameters):
            raise RepertoireError(f"DiscreteDmpSystem needs DmpParameters, got {type(dmp)}")
        dmp.validate()
        check_positive("time_step", time_step)
        n = dmp.n_dims
        self._n = n
        self._dmp = dmp
        self._learned_goal = dmp.goal.copy()
        self._dt = float(time_step)
        self._formulation = dmp.formulation
        self._tau = dmp.tau
        self._tab = DiscreteDmpTables(dmp, self._dt)
        self._x0 = self.DeclareNumericParameter(BasicVector(dmp.x0))
        self._start = self.DeclareNumericParameter(BasicVector([0.0]))
        self._state = self.DeclareDiscreteState(
            np.concatenate([[0.0], dmp.x0, dmp.initial_scaled_velocity()])
        )
        self._declare_start_velocity(dmp)  # after _state: the state is discrete group 0
        self.DeclarePeriodicDiscreteUpdateEvent(self._dt, 0.0, self._update)
        self._goal_port = self.DeclareVectorInputPort("goal", n)
        self._coupling_port = self.DeclareVectorInputPort("coupling", n) if coupling_input else None
        self._declare_discrete_outputs(n, self._start_tickets())

    @property
    def time_step(self) -> float:
        return self._dt

    def set_start(
        self,
        context: Context,
        x0: np.ndarray,
        xd0: np.ndarray | None = None,
        *,
        learned: np.ndarray | None = None,
    ) -> None:
        """Set the start x0 (parameter and state) and initial velocity; phase back to 1.

        Args:
            context: This system's context.
            x0: Start position, shape (n,).
            xd0: Initial velocity dx/dt; default the learned ``dmp.v0`` (in the old
                formulation scaled to the goal input at the onset).
            learned: With ``xd0``, per DOF whether its entry is the learned ``dmp.v0``
                (then scaled as the default is); default none.
        """
        x0 = check_finite_vector("x0", x0, self._n)
        v = self._learned_v if xd0 is None else self._tau * check_finite_vector("xd0", xd0, self._n)
        context.get_mutable_numeric_parameter(self._x0).SetFromVector(x0)
        context.get_mutable_discrete_state(self._state).SetFromVector(
            np.concatenate([[0.0], x0, v])
        )
        self._set_learned_start(context, xd0 is None if learned is None else learned)

    def get_start(self, context: Context) -> np.ndarray:
        """A copy of the start x0 (numeric parameter).

        Args:
            context: This system's context.
        """
        return context.get_numeric_parameter(self._x0).get_value().copy()

    def _update(self, context: Context, discrete_state) -> None:
        s = context.get_discrete_state(self._state).get_value()
        if self.held(context):
            discrete_state.set_value(self._state, s)
            return
        goal = self._goal(context)
        x0 = context.get_numeric_parameter(self._x0).get_value()
        p = self._coupling(context) if self._has_coupling(context) else None
        z = s[1:].copy()
        if self._pending_flag(context) is not None:  # the onset: scale the learned start once
            z[self._n :] = self._onset_velocity(context, z[self._n :], x0)
            discrete_state.set_value(self._pending, np.zeros(self._n))
        out = np.empty_like(s)
        out[0] = s[0] + 1.0
        out[1:] = self._tab.step(z, int(s[0]), goal, x0, p)
        discrete_state.set_value(self._state, out)

    def _calc_position(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(context.get_discrete_state(self._state).get_value()[1 : 1 + self._n])

    def _calc_velocity(self, context: Context, output: BasicVector) -> None:
        if self.held(context):  # the state does not move (it keeps tau v0, as continuous)
            output.SetFromVector(np.zeros(self._n))
            return
        s = context.get_discrete_state(self._state).get_value()
        x0 = context.get_numeric_parameter(self._x0).get_value()
        output.SetFromVector(self._onset_velocity(context, s[1 + self._n :], x0) / self._tau)

    def _calc_phase(self, context: Context, output: BasicVector) -> None:
        k = context.get_discrete_state(self._state).GetAtIndex(0)
        output.SetAtIndex(0, self._tab.phase_and_f(k)[0])

    def _calc_acceleration(self, context: Context, output: BasicVector) -> None:
        s = context.get_discrete_state(self._state).get_value()
        n = self._n
        if self.held(context):
            output.SetFromVector(np.zeros(n))  # held: the state does not move (as continuous)
            return
        theta, f = self._tab.phase_and_f(s[0])
        coupling = self._coupling(context)
        x0 = context.get_numeric_parameter(self._x0).get_value()
        _, vd = transformation_derivatives(
            s[1 : 1 + n],
            self._onset_velocity(context, s[1 + n :], x0),
            theta,
            self._goal(context),
            x0,
            f,
            self._dmp.K,
            self._dmp.D,
            self._tau,
            self._formulation,
            coupling,
        )
        output.SetFromVector(vd / self._tau)


__all__ = ["DiscreteDmpSystem"]
