"""The 10-D task-space DMP chain of the arm worlds (Pastor et al. 2009, sec. IV).

:func:`stack_task_space_dmp` stacks a :class:`TaskSpaceDmp` (position 3, quaternion 4,
fingers 3) into one DmpParameters; :class:`TaskSpaceDmpChain` runs a sequence of them with
per-segment goals. Split out of systems/task_space.py (one concept per module).
"""

import numpy as np
from pydrake.systems.framework import BasicVector, Context, LeafSystem
from repertoire.planning.dmp import DmpParameters, TaskSpaceDmp
from repertoire.planning.dmp_math import (
    angular_velocity,
    forcing_term,
    transformation_derivatives,
)

from repertoire.errors import RepertoireError


def stack_task_space_dmp(dmp: TaskSpaceDmp) -> DmpParameters:
    """The paper's 10-D DMP (Fig. 7) as one DmpParameters: [x y z, qw qx qy qz, fingers].

    Args:
        dmp: a TaskSpaceDmp whose orientation is in ``mode="component"`` (one
            transformation system per quaternion component, the paper's approach)
            and that has finger DOF.

    Raises:
        RepertoireError: manifold orientation, no fingers, or mismatched bases.
    """
    if dmp.orientation.mode != "component":
        raise RepertoireError(
            "the task-space chain runs the paper's component quaternion DMP; learn the "
            "orientation with orientation_mode='component'"
        )
    if dmp.fingers is None:
        raise RepertoireError("the task-space chain needs a DMP with finger DOF")
    parts = [dmp.position, dmp.orientation.component_parameters(), dmp.fingers]
    for part in parts[1:]:
        if part.n_basis != parts[0].n_basis or not np.array_equal(part.centres, parts[0].centres):
            raise RepertoireError("position, orientation and finger DMPs must share their basis")
    return DmpParameters(
        np.vstack([p.weights for p in parts]),
        parts[0].centres,
        parts[0].widths,
        np.concatenate([p.K for p in parts]),
        np.concatenate([p.D for p in parts]),
        parts[0].alpha,
        parts[0].tau,
        np.concatenate([p.x0 for p in parts]),
        np.concatenate([p.goal for p in parts]),
        parts[0].formulation,
    )


class TaskSpaceDmpChain(LeafSystem):
    """A sequence of 10-D task-space DMPs (Fig. 7) run one after another in one system.

    Each segment is the paper's 10-D DMP: end-effector position (3), orientation
    as four quaternion components with post-normalisation (4) and finger DOF
    (n_fingers), all sharing one phase, in the new formulation (eq. 6-7, 9; the
    math is :func:`repertoire.planning.dmp_math.transformation_derivatives`).
    Segment ``k`` starts at ``start_times[k]``: the phase is reset to 1, the new
    segment's start ``x0`` is the current position and the velocity is handed
    over (``x_pred -> x_succ``, ``v_pred -> v_succ``, section III-C), so the
    references stay continuous. The goal is an input, read every step, so it
    may change during the movement (section II-B); the world supplies the
    active segment's goal from the ``segment`` output. (``DmpSequencer`` of
    ``repertoire.systems.dmp_compose`` chains plain n-D DMPs with one goal; the arm
    worlds need a goal per segment read from the scene, the post-normalised
    orientation and the world angular velocity for the IK, hence this system.)

    Continuous state: [theta, x (10), v (10)] with ``v = tau dx/dt``. Discrete
    state: [segment index, x0 (10)], switched by a periodic unrestricted update.

    Input ports:
        goal: the active segment's goal [p (3), q (4), fingers (n_fingers)].
        coupling: position coupling term p of eq. 9-10 (3), e.g. ObstacleCoupling.

    Output ports:
        position: p_d (3).
        velocity: v_d (3).
        orientation: post-normalised q_d [w, x, y, z] (4).
        angular_velocity: w_d in W (3).
        finger_position, finger_velocity, finger_acceleration: n_fingers each.
        segment: [index of the active segment] (1).
        phase: [theta] (1).
    """

    def __init__(
        self,
        segments: list[TaskSpaceDmp],
        start_times: list[float],
        x_start: np.ndarray,
        *,
        switch_period: float = 0.004,
    ):
        """Builds the chain.

        Args:
            segments: the task-space DMPs in execution order (component orientation,
                same number of finger DOF).
            start_times: onset of each segment in s; the first is 0, increasing.
            x_start: the chain's start [p, q, fingers] (the robot's current state).
            switch_period: how often the switch times are checked, in s.

        Raises:
            RepertoireError: empty chain, bad times, or mismatched segments.
        """
        super().__init__()
        if len(segments) == 0:
            raise RepertoireError("a DMP chain needs at least one segment")
        if len(start_times) != len(segments):
            raise RepertoireError(
                f"need one start time per segment: {len(segments)} segments, "
                f"{len(start_times)} start times"
            )
        times = np.asarray(start_times, dtype=float)
        if times[0] != 0.0 or np.any(np.diff(times) <= 0.0):
            raise RepertoireError(
                f"start_times must start at 0 and increase, got {list(start_times)}"
            )
        self._params = [stack_task_space_dmp(s) for s in segments]
        n = self._params[0].n_dims
        if any(p.n_dims != n for p in self._params):
            raise RepertoireError("every segment must have the same number of finger DOF")
        x_start = np.asarray(x_start, dtype=float)
        if x_start.shape != (n,):
            raise RepertoireError(f"x_start must have {n} entries, got shape {x_start.shape}")
        self._n = n
        self._m = n - 7
        self._times = times
        self._goal = self.DeclareVectorInputPort("goal", n)
        self._coupling = self.DeclareVectorInputPort("coupling", 3)
        self.DeclareContinuousState(BasicVector(np.concatenate([[1.0], x_start, np.zeros(n)])))
        self._switch = self.DeclareDiscreteState(np.concatenate([[0.0], x_start]))
        self.DeclarePeriodicUnrestrictedUpdateEvent(switch_period, 0.0, self._maybe_switch)
        xc = {self.xc_ticket(), self.discrete_state_ticket(self._switch)}
        m = self._m
        self.DeclareVectorOutputPort(
            "position", 3, lambda c, o: o.SetFromVector(self._x(c)[:3]), prerequisites_of_calc=xc
        )
        self.DeclareVectorOutputPort(
            "velocity",
            3,
            lambda c, o: o.SetFromVector(self._xd(c)[:3]),
            prerequisites_of_calc=xc,
        )
        self.DeclareVectorOutputPort(
            "orientation", 4, lambda c, o: o.SetFromVector(self._q(c)[0]), prerequisites_of_calc=xc
        )
        self.DeclareVectorOutputPort(
            "angular_velocity",
            3,
            lambda c, o: o.SetFromVector(angular_velocity(*self._q(c))),
            prerequisites_of_calc=xc,
        )
        self.DeclareVectorOutputPort(
            "finger_position",
            m,
            lambda c, o: o.SetFromVector(self._x(c)[7:]),
            prerequisites_of_calc=xc,
        )
        self.DeclareVectorOutputPort(
            "finger_velocity",
            m,
            lambda c, o: o.SetFromVector(self._xd(c)[7:]),
            prerequisites_of_calc=xc,
        )
        self.DeclareVectorOutputPort(
            "finger_acceleration", m, lambda c, o: o.SetFromVector(self._derivatives(c)[2][7:])
        )
        self.DeclareVectorOutputPort(
            "segment",
            1,
            lambda c, o: o.SetFromVector([self._segment(c)]),
            prerequisites_of_calc={self.discrete_state_ticket(self._switch)},
        )
        self.DeclareVectorOutputPort(
            "phase", 1, lambda c, o: o.SetFromVector([self._theta(c)]), prerequisites_of_calc=xc
        )

    @property
    def segment_parameters(self) -> list[DmpParameters]:
        """The 10-D parameters of every segment."""
        return self._params

    def _segment(self, context: Context) -> int:
        return int(context.get_discrete_state(self._switch).GetAtIndex(0))

    def _theta(self, context: Context) -> float:
        return context.get_continuous_state_vector().GetAtIndex(0)

    def _x(self, context: Context) -> np.ndarray:
        return context.get_continuous_state_vector().CopyToVector()[1 : 1 + self._n]

    def _xd(self, context: Context) -> np.ndarray:
        z = context.get_continuous_state_vector().CopyToVector()
        return z[1 + self._n :] / self._params[self._segment(context)].tau

    def _q(self, context: Context) -> tuple[np.ndarray, np.ndarray]:
        """Normalised quaternion and its time derivative."""
        raw = self._x(context)[3:7]
        raw_dot = self._xd(context)[3:7]
        norm = np.linalg.norm(raw)
        q = raw / norm
        return q, (raw_dot - q * (q @ raw_dot)) / norm

    def _derivatives(self, context: Context) -> tuple[float, np.ndarray, np.ndarray]:
        """(theta', x', physical acceleration) of the active segment."""
        p = self._params[self._segment(context)]
        z = context.get_continuous_state_vector().CopyToVector()
        n = self._n
        theta, x, v = z[0], z[1 : 1 + n], z[1 + n :]
        x0 = context.get_discrete_state(self._switch).value()[1:]
        goal = np.array(self._goal.Eval(context), dtype=float)
        if not np.all(np.isfinite(goal)):
            raise RepertoireError(f"the DMP goal must be finite, got {goal}")
        if goal[3:7] @ x0[3:7] < 0.0:  # same hemisphere as the start: shortest rotation
            goal[3:7] = -goal[3:7]
        coupling = np.zeros(n)
        coupling[:3] = self._coupling.Eval(context)
        f = forcing_term(theta, p.weights, p.centres, p.widths)
        xd, vd = transformation_derivatives(
            x, v, theta, goal, x0, f, p.K, p.D, p.tau, p.formulation, coupling
        )
        return -p.alpha * theta / p.tau, xd, vd / p.tau

    def DoCalcTimeDerivatives(self, context: Context, derivatives) -> None:
        theta_dot, xd, acc = self._derivatives(context)
        tau = self._params[self._segment(context)].tau
        derivatives.get_mutable_vector().SetFromVector(np.concatenate([[theta_dot], xd, tau * acc]))

    def _maybe_switch(self, context: Context, state) -> None:
        k = self._segment(context)
        if k + 1 >= len(self._times) or context.get_time() < self._times[k + 1] - 1e-9:
            return
        n = self._n
        z = context.get_continuous_state_vector().CopyToVector()
        x, v = z[1 : 1 + n], z[1 + n :]
        # Hand over position and physical velocity: v_succ = tau_succ * v_pred / tau_pred.
        v_new = v * self._params[k + 1].tau / self._params[k].tau
        state.get_mutable_continuous_state().get_mutable_vector().SetFromVector(
            np.concatenate([[1.0], x, v_new])
        )
        state.get_mutable_discrete_state(self._switch).SetFromVector(np.concatenate([[k + 1], x]))
