"""PlanExecutor: runs a refined action sequence in a diagram, one action at a time.

Stulp & Beetz (JAIR 2008), section 6: a plan is a sequence of actions whose free
parameters (the subgoals between them) were chosen offline by refinement. The executor
hands each action its refined target, routes the active action's command to the robot
and switches to the next action when the active one reports success on its status
port; a failed or timed-out action ends the plan with that status.

Every action of the plan is its own LeafSystem (a :class:`~repertoire.systems.go_to_pose.
GoToPose` per leg) with ``target`` input, ``command`` output and ``status`` output (an
:class:`~repertoire.systems.go_to_pose.ActionStatus`). Actions that are not yet active
already see their target and the live robot state, so their rate-limited controllers
track the command they would give; only the active one's command reaches the robot.

The switching rule is a plain function, :func:`next_plan_state`; the LeafSystem wraps it.
"""

import math

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import (
    BasicVector,
    Context,
    DiscreteValues,
    EventStatus,
    LeafSystem,
    NumericParameterIndex,
)
from repertoire.systems.go_to_pose import ActionStatus

from repertoire.checks import is_real, is_whole
from repertoire.errors import RepertoireError


def next_plan_state(
    active: int, plan_status: ActionStatus, action_status: ActionStatus, n_actions: int
) -> tuple[int, ActionStatus]:
    """One switching step: the next active index and the plan's status.

    Args:
        active: index of the active action (``n_actions`` once the plan is done).
        plan_status: the plan's status so far.
        action_status: the status the active action reports now.
        n_actions: actions in the plan.

    Returns:
        ``(active, plan_status)``: the index advances when the active action succeeded
        (the plan succeeds after its last action); a failed or timed-out action ends the
        plan with that status; a finished plan does not change.
    """
    if plan_status != ActionStatus.RUNNING:
        return active, plan_status
    if action_status == ActionStatus.SUCCEEDED:
        active += 1
        return active, ActionStatus.SUCCEEDED if active == n_actions else ActionStatus.RUNNING
    if action_status in (ActionStatus.FAILED, ActionStatus.TIMED_OUT):
        return active, ActionStatus(action_status)
    return active, ActionStatus.RUNNING


class PlanExecutor(LeafSystem):
    """Executes ``n`` actions in order, passing each its refined target.

    Input ports:
        status_i (i = 0..n-1): the i-th action's :class:`ActionStatus` (abstract).
        command_i: the i-th action's command (``command_size`` vector).

    Output ports:
        target_i: the i-th action's refined target (``target_size`` vector).
        active_i: ``[1]`` while the i-th action is the active one, else ``[0]``; wire it
            to the action's ``active`` input, so that an action does not report success
            (or failure) before its turn because the robot passed its target earlier.
        command: the active action's command; zeros once the plan has ended.
        status: the plan's :class:`ActionStatus` (abstract).
        active_action: ``[index]`` of the active action (``n`` once the plan has ended).
        finish_times: ``(n,)`` time each action ended (NaN while not ended).

    Parameters: numeric parameter ``i`` is action i's target, so a Monte-Carlo study
    can change the refined subgoals in a context without rebuilding.

    Discrete state: ``[active, plan status, finish time of each action (-1: not yet)]``,
    updated every ``period`` s (the actions' period: an action's status is read one
    update after it changed).
    """

    def __init__(
        self,
        targets,
        *,
        command_size: int = 2,
        period: float = 0.02,
    ):
        """Creates the executor.

        Args:
            targets: (n, t) the refined target of each action (finite), n >= 1.
            command_size: size of the actions' command vectors.
            period: switching period [s] (> 0).

        Raises:
            RepertoireError: no action, non-finite targets, bad sizes or period.
        """
        super().__init__()
        try:
            T = np.asarray(targets, dtype=float)
        except (TypeError, ValueError) as e:
            sizes = [len(t) if hasattr(t, "__len__") else None for t in targets]
            raise RepertoireError(
                f"targets must be an (n, t) array: one target of t numbers per action, got "
                f"targets of sizes {sizes}"
            ) from e
        if T.ndim != 2 or T.shape[0] < 1 or T.shape[1] < 1:
            raise RepertoireError(
                f"targets must be an (n, t) array with n >= 1 actions, got shape {T.shape}"
            )
        if not np.all(np.isfinite(T)):
            bad = sorted({int(i) for i in np.argwhere(~np.isfinite(T))[:, 0]})
            raise RepertoireError(f"targets of actions {bad} are not finite: {T[bad].tolist()}")
        whole = is_whole(command_size)
        if not (whole and command_size >= 1):
            raise RepertoireError(f"command_size must be an int >= 1, got {command_size!r}")
        command_size = int(command_size)
        if not (is_real(period) and math.isfinite(period) and period > 0):
            raise RepertoireError(f"period must be finite and > 0, got {period!r}")
        period = float(period)
        self.n_actions, self.target_size = T.shape
        self.command_size = command_size
        self.period = period
        self._target_params = [self.DeclareNumericParameter(BasicVector(t)) for t in T]
        self._status_ports = [
            self.DeclareAbstractInputPort(f"status_{i}", AbstractValue.Make(ActionStatus.RUNNING))
            for i in range(self.n_actions)
        ]
        self._command_ports = [
            self.DeclareVectorInputPort(f"command_{i}", command_size) for i in range(self.n_actions)
        ]
        initial = np.concatenate([[0.0, float(ActionStatus.RUNNING)], np.full(T.shape[0], -1.0)])
        self._xd = self.DeclareDiscreteState(initial)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        self.DeclareForcedDiscreteUpdateEvent(self._update)  # for tests and scripted steps
        for i in range(self.n_actions):
            self.DeclareVectorOutputPort(
                f"target_{i}",
                self.target_size,
                lambda context, output, i=i: output.SetFromVector(self.target(context, i)),
                {self.numeric_parameter_ticket(NumericParameterIndex(self._target_params[i]))},
            )
            self.DeclareVectorOutputPort(
                f"active_{i}",
                1,
                lambda context, output, i=i: output.SetFromVector([self._is_active(context, i)]),
                {self.discrete_state_ticket(self._xd)},
            )
        ticket = {self.discrete_state_ticket(self._xd), self.all_input_ports_ticket()}
        self._command_out = self.DeclareVectorOutputPort(
            "command", command_size, self._calc_command, ticket
        )
        self._status_out = self.DeclareAbstractOutputPort(
            "status",
            lambda: AbstractValue.Make(ActionStatus.RUNNING),
            self._calc_status,
            {self.discrete_state_ticket(self._xd)},
        )
        self._active_out = self.DeclareVectorOutputPort(
            "active_action",
            1,
            lambda c, o: o.SetFromVector(self._xd_value(c)[:1]),
            {self.discrete_state_ticket(self._xd)},
        )
        self._finish_out = self.DeclareVectorOutputPort(
            "finish_times",
            self.n_actions,
            self._calc_finish_times,
            {self.discrete_state_ticket(self._xd)},
        )

    def get_status_input_port(self, i: int):
        return self._status_ports[i]

    def get_command_input_port(self, i: int):
        return self._command_ports[i]

    def get_command_output_port(self):
        return self._command_out

    def get_status_output_port(self):
        return self._status_out

    def get_active_action_output_port(self):
        return self._active_out

    def get_finish_times_output_port(self):
        return self._finish_out

    def target(self, context: Context, i: int) -> np.ndarray:
        """Action ``i``'s target in ``context``."""
        return context.get_numeric_parameter(self._target_params[i]).CopyToVector()

    def set_target(self, context: Context, i: int, target) -> None:
        """Sets action ``i``'s refined target in ``context`` (finite, ``target_size``)."""
        t = np.asarray(target, dtype=float).reshape(-1)
        if t.shape != (self.target_size,) or not np.all(np.isfinite(t)):
            raise RepertoireError(
                f"target of action {i} must be {self.target_size} finite values, got {target}"
            )
        if not 0 <= i < self.n_actions:
            raise RepertoireError(f"action index {i} is not in 0..{self.n_actions - 1}")
        context.get_mutable_numeric_parameter(self._target_params[i]).SetFromVector(t)

    def _is_active(self, context: Context, i: int) -> float:
        xd = self._xd_value(context)
        return float(int(xd[0]) == i and int(xd[1]) == ActionStatus.RUNNING)

    def _xd_value(self, context: Context) -> np.ndarray:
        return context.get_discrete_state(self._xd).get_value()

    def _update(self, context: Context, discrete_state: DiscreteValues) -> EventStatus:
        xd = self._xd_value(context).copy()
        active, status = int(xd[0]), ActionStatus(int(xd[1]))
        if status != ActionStatus.RUNNING:
            return EventStatus.DidNothing()
        reported = self._status_ports[active].Eval(context)
        new_active, new_status = next_plan_state(active, status, reported, self.n_actions)
        if new_active != active or new_status != status:
            xd[2 + active] = context.get_time()
        xd[0], xd[1] = new_active, float(new_status)
        discrete_state.get_mutable_vector(self._xd).SetFromVector(xd)
        return EventStatus.Succeeded()

    def _calc_command(self, context: Context, output: BasicVector) -> None:
        xd = self._xd_value(context)
        active, status = int(xd[0]), int(xd[1])
        if status != ActionStatus.RUNNING:
            output.SetFromVector(np.zeros(self.command_size))
            return
        output.SetFromVector(self._command_ports[active].Eval(context))

    def _calc_finish_times(self, context: Context, output: BasicVector) -> None:
        times = self._xd_value(context)[2:]
        output.SetFromVector(np.where(times < 0, np.nan, times))

    def _calc_status(self, context: Context, output: AbstractValue) -> None:
        output.set_value(ActionStatus(int(self._xd_value(context)[1])))
