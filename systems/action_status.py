"""What every action LeafSystem shares: its :class:`ActionStatus` and a base class.

An action (:class:`~repertoire.systems.go_to_pose.GoToPose`,
:class:`~repertoire.systems.dribble_ball.DribbleBall`,
:class:`~repertoire.systems.arm_reach.Reach`, the kitchen actions) keeps its
status in one slot of its discrete state and reports it on an abstract
``status`` output port; the gains of the numeric actions are numeric
parameter 0, read back by name with :meth:`ActionSystem.gains`.
"""

import enum
import math

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, Context, LeafSystem

from repertoire.errors import RepertoireError


class ActionStatus(enum.IntEnum):
    """What an action reports on its ``status`` port."""

    RUNNING = 0
    SUCCEEDED = 1
    FAILED = 2
    TIMED_OUT = 3


class ActionSystem(LeafSystem):
    """A LeafSystem with a ``status`` output port read from its discrete state.

    Subclasses call :meth:`_declare_status_port` where the port belongs in
    their port order, and :meth:`_declare_gains` for named numeric gains.
    """

    def _declare_status_port(self, xd_index, slot: int):
        """Declares the abstract ``status`` output: slot ``slot`` of discrete state ``xd_index``."""
        self._status_xd, self._status_slot = xd_index, slot
        self._status_port = self.DeclareAbstractOutputPort(
            "status",
            lambda: AbstractValue.Make(ActionStatus.RUNNING),
            self._calc_status,
            {self.discrete_state_ticket(xd_index)},
        )
        return self._status_port

    def _declare_gains(self, names, merged: dict[str, float]):
        """Declares the gains ``merged`` (in the order of ``names``) as a numeric parameter."""
        self._gain_names = tuple(names)
        self._gains_index = self.DeclareNumericParameter(
            BasicVector(np.array(list(merged.values())))
        )
        return self._gains_index

    def get_status_output_port(self):
        return self._status_port

    def gains(self, context: Context) -> dict[str, float]:
        """The gains in ``context`` as a dict."""
        values = context.get_numeric_parameter(self._gains_index).get_value()
        return dict(zip(self._gain_names, map(float, values)))

    def _calc_status(self, context: Context, output: AbstractValue) -> None:
        value = context.get_discrete_state(self._status_xd).get_value()[self._status_slot]
        output.set_value(ActionStatus(int(value)))


def check_workspace(workspace) -> np.ndarray:
    """The workspace ``[x_min, x_max, y_min, y_max]`` as an array, checked finite with min < max."""
    ws = np.asarray(workspace, dtype=float)
    if ws.shape != (4,) or not np.all(np.isfinite(ws)) or ws[0] >= ws[1] or ws[2] >= ws[3]:
        raise RepertoireError(
            f"workspace must be finite [x_min, x_max, y_min, y_max] with min < max, got {workspace}"
        )
    return ws


def clip(x: float, lo: float, hi: float) -> float:
    """``x`` limited to ``[lo, hi]`` (``lo <= hi``), as ``float(np.clip(x, lo, hi))`` for scalars.

    The actions' discrete updates clip a few scalars each; numpy's clip costs
    several microseconds a call on a scalar, this a fraction of one.
    """
    return float(min(max(x, lo), hi))


def check_period(period: float) -> None:
    """Raises unless the update period is finite and > 0."""
    if not (math.isfinite(period) and period > 0):
        raise RepertoireError(f"period must be finite and > 0, got {period}")


def merge_gains(defaults: dict[str, float], overrides, owner: str, positive) -> dict[str, float]:
    """``defaults`` with the finite ``overrides`` of known names; the ``positive`` ones checked > 0.

    Args:
        defaults: name -> default, in the order of the numeric parameter.
        overrides: name -> value, or None.
        owner: the action's name, for the error messages.
        positive: names whose merged value must be > 0.
    """
    merged = dict(defaults)
    for k, v in (overrides or {}).items():
        if k not in defaults:
            raise RepertoireError(f"unknown {owner} gain {k!r}; expected {list(defaults)}")
        if not math.isfinite(v):
            raise RepertoireError(f"{owner} gain {k} must be finite, got {v}")
        merged[k] = float(v)
    for k in positive:
        if merged[k] <= 0:
            raise RepertoireError(f"{owner} gain {k} must be > 0, got {merged[k]}")
    return merged
