"""The start velocity of an old-formulation DMP in a LeafSystem, scaled to its goal input.

Eq. 1 multiplies the forcing term by ``g - x0``: a run to another goal is the demonstration
scaled per DOF by ``s = (g - x0) / (learned g - learned x0)``, its start velocity too
(:meth:`repertoire.planning.dmp.DmpParameters.start_scale`, used by ``rollout`` and
``with_goal``). A LeafSystem learns its goal only from its input port, so the state keeps
the learned ``tau v0`` with a per-DOF flag ("the learned start, to be scaled") until the
onset: there the goal input scales it, once. A goal that changes later acts through eq. 1's
``K (g - x)`` and ``(g - x0) f`` only, not on the velocity reached: as ``rollout`` with one
goal per sample (it scales ``v0`` by the first) and ``with_goal`` (a new goal is a new run).
"""

from collections.abc import Callable

import numpy as np
from pydrake.systems.framework import Context
from repertoire.planning.dmp import DmpParameters

from repertoire.errors import RepertoireError


class OnsetStartVelocity:
    """Mixed in (before LeafSystem) by the vector DMP systems; see the module docstring.

    The system sets ``_n``, ``_goal_port`` and ``_goal(context)`` (the goal input or the
    learned goal); :class:`repertoire.systems.dmp_sequencer.DmpSequencer` sets
    ``_start_dmp``, ``_learned_v`` and ``_pending`` itself and passes its goal_0. The flag
    is a discrete state group, declared only for a DMP whose start velocity can scale
    (:meth:`DmpParameters.scales_start_velocity`); every other DMP has the state it had.
    """

    def _declare_start_velocity(self, dmp: DmpParameters) -> None:
        """Keep the learned ``tau v0`` and declare the per-DOF flag if it can scale."""
        self._start_dmp = dmp
        self._learned_v = dmp.initial_scaled_velocity()
        self._pending = (
            self.DeclareDiscreteState(np.ones(dmp.n_dims)) if dmp.scales_start_velocity() else None
        )

    def _start_tickets(self) -> set:
        """What the start velocity depends on besides the state: the goal input and the flag."""
        if self._pending is None:
            return set()
        return {
            self.input_port_ticket(self._goal_port.get_index()),
            self.discrete_state_ticket(self._pending),
        }

    def _set_learned_start(self, context: Context, learned) -> None:
        """Flag the DOF whose start velocity is the learned one (``learned``: bool or (n,))."""
        flag = np.asarray(learned, dtype=bool).astype(float)
        if flag.shape not in ((), (self._n,)):
            raise RepertoireError(
                f"learned must be one bool or one per DOF ({self._n}), got shape {flag.shape}"
            )
        if self._pending is not None:
            context.SetDiscreteState(self._pending, np.broadcast_to(flag, (self._n,)).copy())

    def _pending_flag(self, context: Context) -> np.ndarray | None:
        """The flag if any DOF still waits for its onset scaling, else None."""
        if self._pending is None:
            return None
        flag = context.get_discrete_state(self._pending).value()
        return flag if flag.any() else None

    def _onset_velocity(
        self,
        context: Context,
        v: np.ndarray,
        x0: np.ndarray,
        goal: "Callable[[], np.ndarray] | None" = None,
    ) -> np.ndarray:
        """The scaled velocity ``v`` with the flagged learned start scaled to the goal input.

        Args:
            context: This system's context.
            v: The state's scaled velocity (the learned ``tau v0`` while held).
            x0: The equations' start (absolute).
            goal: Returns the goal (absolute), called only while a DOF waits; default
                ``self._goal(context)``.
        """
        flag = self._pending_flag(context)
        if flag is None:
            return v
        g = self._goal(context) if goal is None else goal()
        return v + flag * (self._start_dmp.start_scale(g, x0) - 1.0) * self._learned_v


__all__ = ["OnsetStartVelocity"]
