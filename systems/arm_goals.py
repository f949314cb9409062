"""Goals of the arm's DMP chain segments: fixed, or following a body (Pastor et al. 2009, Fig. 13).

:class:`SegmentGoal` is one segment's goal; :class:`GoalSchedule` gives the chain the goal of
every segment on its own port, a tracked body's pose re-read when evaluated (the paper's
moving coaster; the chain reads only its active segment's port).
"""

import dataclasses

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import BasicVector, Context, LeafSystem

from repertoire.errors import RepertoireError


def check_body_index(body, what: str, *, fixed_allowed: bool = False) -> int:
    """``body`` as an int body index, or a RepertoireError naming ``what`` and the value.

    Args:
        body: a body index (int, numpy integer or Drake ``BodyIndex``).
        what: what the value is, for the message.
        fixed_allowed: also accept -1 (no body: a fixed goal).

    Raises:
        RepertoireError: a name, a float, a bool or an index below 0 (below -1 with
            ``fixed_allowed``).
    """
    lowest = -1 if fixed_allowed else 0
    if not isinstance(body, (str, bool, float, np.floating)):
        try:
            index = int(body)
        except (TypeError, ValueError):
            index = None
        if index is not None and index >= lowest:
            return index
    raise RepertoireError(
        f"{what} must be a body index >= {lowest}, got {body!r}"
        + (
            " (-1 for a fixed goal; resolve an 'instance:body' name to the plant's body index)"
            if fixed_allowed
            else ""
        )
    )


@dataclasses.dataclass
class SegmentGoal:
    """The goal of one chain segment.

    Attributes:
        label: motion library label.
        position: fixed goal position (3), or the offset from ``body`` when tracking.
        orientation: goal quaternion [w, x, y, z].
        fingers: goal finger angles (3).
        body: a tracked body (the goal follows it) as a body index or "instance:body",
            or -1 for a fixed goal.
    """

    label: str
    position: np.ndarray
    orientation: np.ndarray
    fingers: np.ndarray
    body: int | str = -1


class GoalSchedule(LeafSystem):
    """Gives the DMP chain the goal of every segment; tracked goals follow a body.

    This is the "vision" of the paper's experiment: a goal tied to a body (the
    coaster) is re-read from the plant every step, so the DMP's goal changes when
    the body moves.

    Input ports:
        body_poses: the plant's body poses (abstract).
        segment: [active segment index] (1), needed only by the ``goal`` output.

    Output ports:
        goal_0 ... goal_{m-1}: segment k's goal [p (3), q (4), fingers (3)] (10), for the
            per-segment goal inputs of :class:`repertoire.systems.dmp_sequencer.DmpSequencer`.
        goal: the active segment's goal (10), for logging.
    """

    def __init__(self, goals: list[SegmentGoal]):
        """Builds the schedule.

        Args:
            goals: one goal per chain segment (one or more); a tracked goal's ``body`` is a
                body index of the plant whose poses arrive on ``body_poses`` (a
                ``"instance:body"`` name is resolved to one by the world builder).

        Raises:
            RepertoireError: no goals, a goal of the wrong size, not finite, a non-unit
                orientation, or a body that is neither -1 nor a body index.
        """
        super().__init__()
        if len(goals) == 0:
            raise RepertoireError("GoalSchedule needs one or more segment goals, got none")
        for k, g in enumerate(goals):
            for what, value, size in (
                ("position", g.position, 3),
                ("orientation", g.orientation, 4),
                ("fingers", g.fingers, 3),
            ):
                v = np.asarray(value, dtype=float).reshape(-1)
                if v.size != size or not np.all(np.isfinite(v)):
                    raise RepertoireError(
                        f"goal {k} ({g.label}): {what} must be {size} finite numbers, got "
                        f"{np.asarray(value).tolist()}"
                    )
            norm = float(np.linalg.norm(g.orientation))
            if abs(norm - 1.0) > 1e-6:
                raise RepertoireError(
                    f"goal {k} ({g.label}): orientation must be a unit quaternion [w, x, y, z], "
                    f"its norm is {norm:.6f} (off by {abs(norm - 1.0):.2e})"
                )
        self._goals = goals
        self._bodies = [
            check_body_index(g.body, f"goal {k} ({g.label}): body", fixed_allowed=True)
            for k, g in enumerate(goals)
        ]
        self._poses = self.DeclareAbstractInputPort(
            "body_poses", AbstractValue.Make([RigidTransform()])
        )
        self._segment = self.DeclareVectorInputPort("segment", 1)
        self.DeclareVectorOutputPort("goal", 10, self._calc_active)
        for k in range(len(goals)):
            self.DeclareVectorOutputPort(f"goal_{k}", 10, lambda c, o, k=k: self._calc(c, o, k))

    def _calc_active(self, context: Context, output: BasicVector) -> None:
        segment = float(self._segment.Eval(context)[0])
        m = len(self._goals)
        if not (np.isfinite(segment) and segment == int(segment) and 0 <= segment < m):
            raise RepertoireError(f"segment must be a segment index 0 ... {m - 1}, got {segment}")
        self._calc(context, output, int(segment))

    def _calc(self, context: Context, output: BasicVector, k: int) -> None:
        g = self._goals[k]
        p = np.asarray(g.position, float)
        body = self._bodies[k]
        if body >= 0:
            poses = self._poses.Eval(context)
            if body >= len(poses):
                raise RepertoireError(
                    f"goal {k} ({g.label}) tracks body {body}, but body_poses holds only "
                    f"{len(poses)} poses"
                )
            p = poses[body].translation() + p
        output.SetFromVector(np.concatenate([p, g.orientation, g.fingers]))
