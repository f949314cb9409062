"""Goals of the arm's DMP chain segments: fixed, or following a body (Pastor et al. 2009, Fig. 13).

:class:`SegmentGoal` is one segment's goal; :class:`GoalSchedule` gives the chain the goal of
every segment on its own port, a tracked body's pose re-read when evaluated (the paper's
moving coaster; the chain reads only its active segment's port). A goal that places the held
object is moved by the object's horizontal offset from the commanded tcp, which
:class:`HeldObjectOffset` measures while the object is held: the object, not the tcp, is set
down on the target.
"""

import dataclasses
from collections.abc import Sequence

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
        places_held: the segment sets the held object down: ``position`` is where the
            tcp goes for the object's origin to stand straight below it on target, and the
            goal is moved by minus the object's horizontal offset from the commanded tcp
            (:class:`GoalSchedule`'s ``held_object_offset`` input).
    """

    label: str
    position: np.ndarray
    orientation: np.ndarray
    fingers: np.ndarray
    body: int | str = -1
    places_held: bool = False


class GoalSchedule(LeafSystem):
    """Gives the DMP chain the goal of every segment; tracked goals follow a body.

    This is the "vision" of the paper's experiment: a goal tied to a body (the
    coaster) is re-read from the plant every step, so the DMP's goal changes when
    the body moves.

    Input ports:
        body_poses: the plant's body poses (abstract).
        segment: [active segment index] (1), needed only by the ``goal`` output.
        held_object_offset (3, only if a goal ``places_held``): the held object's origin
            from the commanded tcp in W [m] (:class:`HeldObjectOffset`; only x and y are
            used): such a goal is ``body + position - [x, y, 0]``.

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
            if not isinstance(g.places_held, bool | np.bool_):
                raise RepertoireError(
                    f"goal {k} ({g.label}): places_held must be True or False, got "
                    f"{g.places_held!r}"
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
        self._held = (
            self.DeclareVectorInputPort("held_object_offset", 3)
            if any(g.places_held for g in goals)
            else None
        )
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
        if g.places_held:
            offset = self._held.Eval(context)
            if not np.all(np.isfinite(offset)):
                raise RepertoireError(
                    f"goal {k} ({g.label}): held_object_offset must be 3 finite numbers, got "
                    f"{np.asarray(offset).tolist()}"
                )
            p = p - np.array([offset[0], offset[1], 0.0])
        output.SetFromVector(np.concatenate([p, g.orientation, g.fingers]))


class HeldObjectOffset(LeafSystem):
    """The held object's horizontal offset from the commanded tcp, sampled while it is held.

    Every ``period``, while the active segment is one of ``held_segments``, it reads
    ``p_WO - p_WT_desired`` (x and y; the object's origin O from the tcp position the chain
    commands). That is where the object ends up relative to the command: its place in the
    hand (the grasp's offset and any slip while carried), the tcp's tracking error and the
    hand's tilt. A goal that places the held object subtracts it
    (:class:`GoalSchedule`), so the object converges onto the target as the command
    converges onto the goal. Outside the held segments the last reading is kept (zeros
    before any). A reading farther than ``max_offset`` is scaled back to that length: an
    object knocked that far in the hand has slipped out of its grasp (a slip the worlds
    report), and a goal that followed it would be moved by centimetres, out of reach.

    Input ports:
        body_poses: the plant's body poses (abstract).
        tcp_desired: the commanded tcp position in W [m] (3).
        segment: the active segment's index (1).

    Output ports:
        offset: [x, y, 0] [m] (3).
    """

    def __init__(
        self,
        held_object: int,
        held_segments: Sequence[int],
        *,
        period: float,
        max_offset: float,
    ):
        """Builds the system.

        Args:
            held_object: index of the held object's body in the body poses.
            held_segments: indices of the segments during which the object is held.
            period: update period [s].
            max_offset: the longest offset given [m] (> 0).

        Raises:
            RepertoireError: a body that is not an index >= 0, no held segment or one that is
                not a whole number >= 0, or a period or a max_offset that is not > 0.
        """
        super().__init__()
        self._object = check_body_index(held_object, "held_object")
        held = list(held_segments)
        if not held or not all(
            isinstance(k, int | np.integer) and not isinstance(k, bool) and k >= 0 for k in held
        ):
            raise RepertoireError(
                f"held_segments must list one or more segment indices >= 0, got {held_segments}"
            )
        for name, value in (("period", period), ("max_offset", max_offset)):
            if not (isinstance(value, int | float) and np.isfinite(value) and value > 0.0):
                raise RepertoireError(f"{name} must be a finite number > 0, got {value!r}")
        self._max = float(max_offset)
        self._held = {int(k) for k in held}
        self._poses = self.DeclareAbstractInputPort(
            "body_poses", AbstractValue.Make([RigidTransform()])
        )
        self._tcp = self.DeclareVectorInputPort("tcp_desired", 3)
        self._segment = self.DeclareVectorInputPort("segment", 1)
        self._state = self.DeclareDiscreteState(2)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        self.DeclareVectorOutputPort(
            "offset",
            3,
            lambda c, o: o.SetFromVector([*c.get_discrete_state(self._state).value(), 0.0]),
            prerequisites_of_calc={self.discrete_state_ticket(self._state)},
        )

    def _update(self, context: Context, state) -> None:
        x = context.get_discrete_state(self._state).value().copy()
        if int(round(self._segment.Eval(context)[0])) in self._held:
            poses = self._poses.Eval(context)
            if self._object >= len(poses):
                raise RepertoireError(
                    f"body {self._object} is not in body_poses, which holds {len(poses)} poses"
                )
            tcp = self._tcp.Eval(context)
            if not np.all(np.isfinite(tcp)):
                raise RepertoireError(f"tcp_desired must be 3 finite numbers, got {tcp.tolist()}")
            x = (poses[self._object].translation() - tcp)[:2]
            length = float(np.hypot(*x))
            if length > self._max:
                x = x * (self._max / length)
        state.get_mutable_vector(self._state).SetFromVector(x)
