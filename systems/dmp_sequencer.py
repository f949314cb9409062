"""The DMP sequencer: chained DMPs in one LeafSystem (Pastor et al. 2009, sec. III-C, Fig. 5).

:class:`DmpSequencer` runs n-D DMP segments one after another; segment i takes over at
``start_times[i]``, before its predecessor has ended, from the predecessor's state by
:func:`repertoire.planning.dmp_chain.handoff_state` (the one hand-off implementation; the
NumPy reference is :func:`repertoire.planning.dmp_chain.chain_rollout`). Every segment has
its own goal input port, read every step while the segment is active (goals may move,
sec. II-B). Optionally a 4-DOF block holds quaternion components (the paper's 10-D arm DMP,
Fig. 7): the goal gets the sign that turns from the segment's start the way the segment
learned (:func:`repertoire.planning.dmp_quaternion.lift_quaternion_goal`: its learned goal for its
learned start, also past 180 deg) and the output is post-normalised with its world angular
velocity. :func:`task_space_sequencer` is that configuration for
:class:`repertoire.planning.dmp.TaskSpaceDmp` segments.

Two integrations of the same equations (eq. 4, 6-7, 9):

* ``time_step`` given: discrete state ``[segment, k, x0, x, v]`` advanced by the exact
  first-order-hold step of :class:`repertoire.planning.dmp_discrete.DiscreteDmpTables`
  (matches ``chain_rollout`` to rounding);
* ``time_step=None``: continuous state ``[theta, x - x0, v]`` (the displacement from the
  active segment's x0, so a movement far from the origin keeps its digits) integrated by
  the simulator, with ``[segment, x0]`` switched by a periodic unrestricted update every
  ``switch_period`` (the arm worlds, whose plant and IK run on their own clocks).

In both, v = tau dx/dt of the active segment.
"""

import numpy as np
from pydrake.systems.framework import BasicVector, Context, LeafSystem
from repertoire.planning.dmp import DmpParameters, TaskSpaceDmp, check_unit_quaternions
from repertoire.planning.dmp_chain import (
    check_handoff,
    check_switch_times,
    handoff_state,
    stack_task_space_dmp,
)
from repertoire.planning.dmp_discrete import DiscreteDmpTables
from repertoire.planning.dmp_math import (
    check_finite_vector,
    check_positive,
    forcing_term,
    transformation_derivatives,
)
from repertoire.planning.dmp_quaternion import (
    angular_velocity,
    learned_side,
    lift_quaternion_goal,
    post_normalised,
    quaternion_rate,
)
from repertoire.systems.dmp import check_finite_input, check_unit_goal, goal_input
from repertoire.systems.dmp_start import OnsetStartVelocity

from repertoire.checks import is_whole
from repertoire.errors import RepertoireError


def check_waits(
    wait_tolerances, n_segments: int, wait_dofs: slice, n: int, max_wait: float, time_step
) -> tuple[list[float | None], slice, float]:
    """Validated ``(wait_tolerances, wait_dofs, max_wait)`` of a :class:`DmpSequencer`.

    Raises:
        RepertoireError: a list of the wrong length, a tolerance that is not a number > 0,
            a DOF slice outside the n, a negative or non-finite ``max_wait``, or waits in
            discrete mode.
    """
    waits = [None] * n_segments if wait_tolerances is None else list(wait_tolerances)
    if len(waits) != n_segments:
        raise RepertoireError(
            f"wait_tolerances needs one entry per segment ({n_segments}), got {len(waits)}"
        )
    for i, w in enumerate(waits):
        if w is not None and not (isinstance(w, int | float) and np.isfinite(w) and w > 0):
            raise RepertoireError(f"wait_tolerances[{i}] must be None or a number > 0, got {w!r}")
    if not (isinstance(wait_dofs, slice) and len(range(n)[wait_dofs]) > 0):
        raise RepertoireError(
            f"wait_dofs must be a slice of some of the {n} DOF, got {wait_dofs!r}"
        )
    if not (np.isfinite(max_wait) and max_wait >= 0):
        raise RepertoireError(f"max_wait must be finite and >= 0 [s], got {max_wait}")
    if any(w is not None for w in waits) and time_step is not None:
        raise RepertoireError("wait_tolerances need the continuous mode (time_step=None)")
    return waits, wait_dofs, float(max_wait)


def check_gates(start_gates, n_segments: int, time_step) -> list[bool]:
    """Validated ``start_gates`` of a :class:`DmpSequencer` (one bool per segment).

    Raises:
        RepertoireError: a list of the wrong length, an entry that is not a bool, a gate on
            the first segment (it starts the chain, there is nothing to wait for) or gates
            in discrete mode.
    """
    gates = [False] * n_segments if start_gates is None else list(start_gates)
    if len(gates) != n_segments:
        raise RepertoireError(
            f"start_gates needs one entry per segment ({n_segments}), got {len(gates)}"
        )
    for i, g in enumerate(gates):
        if not isinstance(g, bool | np.bool_):
            raise RepertoireError(f"start_gates[{i}] must be True or False, got {g!r}")
    if gates and gates[0]:
        raise RepertoireError("start_gates[0] must be False: the first segment starts the chain")
    if any(gates) and time_step is not None:
        raise RepertoireError("start_gates need the continuous mode (time_step=None)")
    return [bool(g) for g in gates]


class DmpSequencer(OnsetStartVelocity, LeafSystem):
    """Chained n-D DMPs with per-segment goal inputs (sec. III-C).

    Input ports:
        goal_0 ... goal_{m-1} (n each): goal of segment i, read while it is active; when not
            connected, the goal given at construction (default the segment's learned goal,
            as every DMP system's unconnected goal input).
        coupling (``coupling_dofs``, only if > 0): coupling term p (eq. 9) on the first
            ``coupling_dofs`` DOF (e.g. the position under obstacle coupling, eq. 10, whose
            ``v`` is the active segment's ``tau dx/dt``).
        start_gate (1, only with ``start_gates``): a segment with a gate starts only while
            this reads 1 (> 0.5), e.g. a monitor that says the object the predecessor placed
            has settled on its target.

    Output ports:
        position, velocity, acceleration (n): x, dx/dt and d2x/dt2 of the active segment
            (velocity and acceleration are 0 while the state is held before the first start
            time; the state keeps the start velocity the first segment starts with).
        phase (1), segment (1): theta and the active segment's index.
        tau (1): the active segment's temporal scaling [s] (for a coupling term that needs
            the scaled velocity ``v = tau dx/dt`` of eq. 10, e.g.
            :class:`repertoire.systems.obstacle_coupling.MultiPointObstacleCoupling`).
        start_delay (1): how much later than their start times the segments start, the
            waits of ``wait_tolerances`` summed [s] (0 in discrete mode).
        orientation (4), angular_velocity (3) (with ``quaternion_at``): the post-normalised
            quaternion block [w, x, y, z] and its world-frame angular velocity. Each
            segment runs its block from the sign of the start on its learned start's side
            (``q . x0_learned >= 0``; the R^4 state is negated at a start or hand-off
            otherwise), so the output's sign may differ from ``x_start``'s: the same
            orientation.
        NAME_position, NAME_velocity, NAME_acceleration: for every entry of ``parts``, that
            slice of the three vector outputs.
    """

    def __init__(
        self,
        segments: list[DmpParameters],
        start_times: list[float],
        *,
        goals: list[np.ndarray] | None = None,
        x_start: np.ndarray | None = None,
        time_step: float | None = 1e-3,
        switch_period: float = 1e-3,
        handoff: str = "velocity",
        quaternion_at: int | None = None,
        coupling_dofs: int = 0,
        parts: dict[str, slice] | None = None,
        wait_tolerances: list[float | None] | None = None,
        wait_dofs: slice = slice(None),
        max_wait: float = 0.0,
        start_gates: list[bool] | None = None,
    ) -> None:
        """Builds the sequencer.

        Args:
            segments: The DMPs in execution order, all with the same number of DOF n.
            start_times: Onset of each segment [s], increasing, >= 0 (rounded to the time
                step in discrete mode); the state is held before the first.
            goals: Default goal of every segment (used while its port is not connected);
                None: each segment's learned goal.
            x_start: Start of the first segment; default its learned x0. The chain starts
                with the first segment's learned velocity ``v0`` (:meth:`set_start` to
                change it).
            time_step: Discrete exact step [s]; None integrates continuously.
            switch_period: How often the switch times are checked [s] (continuous only).
            handoff: ``"none"``, ``"velocity"`` (the paper) or ``"acceleration"``.
            quaternion_at: Index of a 4-DOF quaternion block, or None.
            coupling_dofs: Size of the coupling input (0 = no input).
            parts: Named slices with their own output ports.
            wait_tolerances: Per segment, None (start on time) or a distance: segment i
                (i >= 1) starts at its start time only once segment i - 1 has come within
                this distance of its goal on ``wait_dofs`` (sec. III-C: a DMP started
                "after the preceding DMP has been executed completely"; a coupling term
                that delayed the predecessor delays the successor, not its start point),
                and at most ``max_wait`` later; the delay shifts every later start time.
                Continuous mode only.
            wait_dofs: The DOF ``wait_tolerances`` measure (e.g. the position block).
            max_wait: Longest wait for one segment [s] (then it starts anyway).
            start_gates: Per segment, whether it also waits (like ``wait_tolerances``, at
                most ``max_wait``, the delay shifting later starts) until the ``start_gate``
                input reads 1: readiness the world measures rather than the DMP's state
                (the placed object at rest on its target). Continuous mode only.

        Raises:
            RepertoireError: an empty chain, bad times, mismatched segments or goals, a bad
                handoff, quaternion block or coupling size, bad wait tolerances or gates.
        """
        super().__init__()
        times = check_switch_times(start_times, len(segments), "start times")
        for i, s in enumerate(segments):
            if not isinstance(s, DmpParameters):
                raise RepertoireError(f"segment {i} is {type(s).__name__}, not DmpParameters")
        n = segments[0].n_dims
        for i, s in enumerate(segments):
            if s.n_dims != n:
                raise RepertoireError(f"segment {i} has {s.n_dims} DOF, segment 0 has {n}")
        self._handoff = check_handoff(handoff)
        if handoff == "acceleration" and any(s.formulation != "new" for s in segments):
            raise RepertoireError("acceleration handoff needs the new formulation (eq. 6)")
        if quaternion_at is not None and not (
            is_whole(quaternion_at) and 0 <= quaternion_at <= n - 4
        ):
            raise RepertoireError(
                f"quaternion_at must be in [0, {n - 4}] (the 4 quaternion DOF inside the {n}), "
                f"got {quaternion_at!r}"
                if n >= 4
                else f"quaternion_at = {quaternion_at!r} needs segments with at least 4 DOF (a "
                f"quaternion block), but they have {n}"
            )
        if not (is_whole(coupling_dofs) and 0 <= coupling_dofs <= n):
            raise RepertoireError(f"coupling_dofs must be in [0, {n}], got {coupling_dofs}")
        if goals is not None and len(goals) != len(segments):
            raise RepertoireError(f"{len(segments)} segments need as many goals, got {len(goals)}")
        self._n, self._segments, self._times = n, list(segments), times
        self._waits, self._wait_dofs, self._max_wait = check_waits(
            wait_tolerances, len(segments), wait_dofs, n, max_wait, time_step
        )
        self._gates = check_gates(start_gates, len(segments), time_step)
        self._goals = (  # unconnected goal ports stand for these (default: the learned goals)
            [sg.goal for sg in segments]
            if goals is None
            else [check_finite_vector(f"goal {i}", g, n) for i, g in enumerate(goals)]
        )
        self._q = None if quaternion_at is None else slice(quaternion_at, quaternion_at + 4)
        x_start = segments[0].x0 if x_start is None else self._check_start(x_start)
        x_start = self._learned_side(0, x_start)[0]
        # the first segment's demonstrated start velocity (v = tau dx/dt), as every DMP system;
        # in the old formulation scaled to goal_0 at the onset (repertoire.systems.dmp_start)
        self._start_dmp, self._learned_v = segments[0], segments[0].initial_scaled_velocity()
        v_start = self._start_velocity(x_start)
        self._goal_ports = [
            self.DeclareVectorInputPort(f"goal_{i}", n) for i in range(len(segments))
        ]
        self._coupling_dofs = coupling_dofs
        self._coupling_port = (
            self.DeclareVectorInputPort("coupling", coupling_dofs) if coupling_dofs else None
        )
        self._gate_port = self.DeclareVectorInputPort("start_gate", 1) if any(self._gates) else None
        if time_step is None:
            check_positive("switch_period", switch_period)
            self._switch_period = float(switch_period)
            self._dt = None
            # [theta, x - x0 (the displacement from the active segment's x0), v]
            self.DeclareContinuousState(BasicVector(np.concatenate([[1.0], np.zeros(n), v_start])))
            self._switch = self.DeclareDiscreteState(np.concatenate([[0.0], x_start]))
            # the accumulated delay of the start times (segments that waited, see _maybe_switch)
            self._delay = self.DeclareDiscreteState(np.zeros(1))
            self.DeclarePeriodicUnrestrictedUpdateEvent(switch_period, 0.0, self._maybe_switch)
            state = {self.xc_ticket(), self.discrete_state_ticket(self._switch)}
        else:
            self._dt = check_positive("time_step", time_step)
            self._steps = np.round(times / self._dt).astype(int)
            if np.any(np.diff(self._steps) <= 0):
                raise RepertoireError(f"start times closer than the time step: {times.tolist()}")
            self._tabs = [DiscreteDmpTables(s, self._dt) for s in segments]
            self._state = self.DeclareDiscreteState(
                np.concatenate([[0.0, 0.0], x_start, x_start, v_start])
            )
            self.DeclarePeriodicDiscreteUpdateEvent(self._dt, 0.0, self._update)
            state = {self.xd_ticket()}
        # the flag "the start velocity is the learned one, to be scaled to goal_0 at the onset"
        self._pending = (
            self.DeclareDiscreteState(self._scaled_dofs())
            if segments[0].scales_start_velocity()
            else None
        )
        if self._pending is not None:  # the velocity depends on goal_0 until the onset
            state = state | {
                self.discrete_state_ticket(self._pending),
                self.input_port_ticket(self._goal_ports[0].get_index()),
            }
        for part, sl in (parts or {}).items():
            if not (
                isinstance(sl, slice)
                and all(b is None or -n <= b <= n for b in (sl.start, sl.stop))
            ):
                raise RepertoireError(
                    f"part {part!r} must be a slice within the {n} DOF, got {sl!r}"
                )
        self._declare_outputs(n, state, parts or {})

    def _declare_outputs(self, n: int, state: set, parts: dict[str, slice]) -> None:
        getters = {"position": self._x, "velocity": self._xd, "acceleration": self._acc}
        held = state | {self.time_ticket()}  # velocities are 0 while held (_held: the time)
        for name, get in getters.items():
            pre = {"position": state, "velocity": held}.get(name, {self.all_sources_ticket()})
            self.DeclareVectorOutputPort(
                name, n, lambda c, o, g=get: o.SetFromVector(g(c)), prerequisites_of_calc=pre
            )
            for part, sl in parts.items():
                size = len(range(n)[sl])
                self.DeclareVectorOutputPort(
                    f"{part}_{name}",
                    size,
                    lambda c, o, g=get, s=sl: o.SetFromVector(g(c)[s]),
                    prerequisites_of_calc=pre,
                )
        self.DeclareVectorOutputPort(
            "phase", 1, lambda c, o: o.SetFromVector([self._theta(c)]), prerequisites_of_calc=state
        )
        self.DeclareVectorOutputPort(
            "segment",
            1,
            lambda c, o: o.SetFromVector([self._segment(c)]),
            prerequisites_of_calc=state,
        )
        self.DeclareVectorOutputPort(
            "tau",
            1,
            lambda c, o: o.SetFromVector([self._segments[self._segment(c)].tau]),
            prerequisites_of_calc=state,
        )
        self.DeclareVectorOutputPort(
            "start_delay",
            1,
            lambda c, o: o.SetFromVector([self.start_delay(c)]),
            prerequisites_of_calc={self.all_state_ticket()},
        )
        if self._q is not None:
            self.DeclareVectorOutputPort(
                "orientation",
                4,
                lambda c, o: o.SetFromVector(self._quaternion(c)[0]),
                prerequisites_of_calc=state,
            )
            self.DeclareVectorOutputPort(
                "angular_velocity",
                3,
                lambda c, o: o.SetFromVector(angular_velocity(*self._quaternion(c))),
                prerequisites_of_calc=held,
            )

    def set_start(
        self, context: Context, x_start: np.ndarray, xd_start: np.ndarray | None = None
    ) -> None:
        """Restart the chain at ``x_start`` with the first segment.

        Args:
            context: This system's context.
            x_start: Start position, shape (n,).
            xd_start: Start velocity dx/dt, shape (n,); default the first segment's learned
                ``v0`` (zero for a rest-to-rest demonstration).
        """
        first = self._segments[0]
        x_start = self._check_start(x_start)
        if xd_start is None:
            x = self._learned_side(0, x_start)[0]
            v = self._start_velocity(x)
        else:
            v = first.tau * check_finite_vector("xd_start", xd_start, self._n)
            x, v = self._learned_side(0, x_start, v)
        if self._dt is None:
            context.SetContinuousState(np.concatenate([[1.0], np.zeros(self._n), v]))
            context.SetDiscreteState(self._switch, np.concatenate([[0.0], x]))
            context.SetDiscreteState(self._delay, np.zeros(1))
        else:
            context.SetDiscreteState(self._state, np.concatenate([[0.0, 0.0], x, x, v]))
        if self._pending is not None:
            context.SetDiscreteState(self._pending, self._scaled_dofs() * (xd_start is None))

    def _start_velocity(self, x: np.ndarray) -> np.ndarray:
        """The first segment's learned scaled start velocity for a chain starting at ``x``.

        ``tau v0``, but the quaternion block turns at the learned angular velocity from
        ``x``'s orientation (``omega0 q / 2``, as DmpSystem and
        :meth:`repertoire.planning.dmp.QuaternionDmpParameters.rollout` start), not with
        the learned start's R^4 rate (off by 6e-4 rad at 0.5 s from a start turned 0.54 rad).

        Args:
            x: The chain's start, its quaternion block on the learned side.
        """
        v = self._learned_v.copy()
        if self._q is not None:
            first = self._segments[0]
            omega0 = angular_velocity(first.x0[self._q], first.v0[self._q])
            v[self._q] = first.tau * quaternion_rate(omega0, x[self._q])
        return v

    def _scaled_dofs(self) -> np.ndarray:
        """1 per DOF whose learned start velocity scales with goal_0 (not the quaternion)."""
        flag = np.ones(self._n)
        if self._q is not None:
            flag[self._q] = 0.0  # the learned turn rate at the start (_start_velocity)
        return flag

    # --- state access (both modes) ---------------------------------------------------
    def _split(
        self, context: Context, onset: bool = True
    ) -> tuple[int, float, np.ndarray, np.ndarray, np.ndarray]:
        """(segment, theta or step count, x0, x, v) of the active segment.

        ``v`` with the flagged learned start velocity scaled to goal_0 (``onset``;
        :meth:`_onset_velocity`), else the state's.
        """
        n = self._n
        if self._dt is None:
            sw = context.get_discrete_state(self._switch).value()
            z = context.get_continuous_state_vector().CopyToVector()
            out = int(sw[0]), z[0], sw[1:], sw[1:] + z[1 : 1 + n], z[1 + n :]
        else:
            s = context.get_discrete_state(self._state).get_value()
            out = int(s[0]), s[1], s[2 : 2 + n], s[2 + n : 2 + 2 * n], s[2 + 2 * n :]
        return (*out[:4], self._first_velocity(context, out[2], out[4])) if onset else out

    def _first_velocity(self, context: Context, x0: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``v`` with the flagged learned start scaled to goal_0 (old formulation, eq. 1).

        :class:`repertoire.systems.dmp_start.OnsetStartVelocity`: the state keeps the learned
        ``tau v0`` until the onset, where goal_0 scales it once (the first step, or the first
        switch check from the first start time on, continuous).
        """
        return self._onset_velocity(context, v, x0, lambda: self._goal(context, 0, x0))

    def _segment(self, context: Context) -> int:
        return self._split(context, onset=False)[0]

    def _theta(self, context: Context) -> float:
        seg, k, *_ = self._split(context, onset=False)
        return k if self._dt is None else self._tabs[seg].phase_and_f(k)[0]

    def _x(self, context: Context) -> np.ndarray:
        return self._split(context, onset=False)[3]

    def _xd(self, context: Context) -> np.ndarray:
        if self._held(context):  # the position does not move (the state keeps tau v0)
            return np.zeros(self._n)
        seg, _, _, _, v = self._split(context)
        return v / self._segments[seg].tau

    def _quaternion(self, context: Context) -> tuple[np.ndarray, np.ndarray]:
        """Post-normalised quaternion and its time derivative."""
        return post_normalised(self._x(context)[self._q], self._xd(context)[self._q])

    def _goal(self, context: Context, seg: int, x0: np.ndarray) -> np.ndarray:
        port = self._goal_ports[seg]
        goal = np.array(goal_input(port, context, self._goals[seg]), dtype=float)  # a copy
        if self._q is not None:
            # The sign of the quaternion goal that turns from x0 the way the segment learned
            # (its learned goal for its learned start, even past 180 deg).
            learned = self._segments[seg]
            goal[self._q] = lift_quaternion_goal(
                check_unit_goal(goal[self._q]),
                x0[self._q],
                learned.goal[self._q],
                learned.x0[self._q],
            )
        return goal

    def _coupling(self, context: Context) -> np.ndarray | None:
        if self._coupling_port is None or not self._coupling_port.HasValue(context):
            return None
        p = np.zeros(self._n)
        p[: self._coupling_dofs] = check_finite_input("coupling", self._coupling_port.Eval(context))
        return p

    def _displacement(self, context: Context, x0: np.ndarray, x: np.ndarray) -> np.ndarray:
        """``x - x0``: the continuous state itself (no rounding far from the origin)."""
        if self._dt is None:
            return context.get_continuous_state_vector().CopyToVector()[1 : 1 + self._n]
        return x - x0

    def _rhs(self, context: Context, seg, theta, x0, x, v, f) -> tuple[np.ndarray, np.ndarray]:
        """``(x', v')`` of segment ``seg``, in the displacement from its x0 (as the steps)."""
        p = self._segments[seg]
        coupling = self._coupling(context)
        return transformation_derivatives(
            self._displacement(context, x0, x),
            v,
            theta,
            self._goal(context, seg, x0) - x0,
            np.zeros(self._n),
            f,
            p.K,
            p.D,
            p.tau,
            p.formulation,
            0.0 if coupling is None else coupling,
        )

    def _acc(self, context: Context) -> np.ndarray:
        if self._held(context):  # the state does not move before the first start time
            return np.zeros(self._n)
        seg, k, x0, x, v = self._split(context)
        p = self._segments[seg]
        if self._dt is None:
            theta, f = k, forcing_term(k, p.weights, p.centres, p.widths)
        else:
            theta, f = self._tabs[seg].phase_and_f(k)
        return self._rhs(context, seg, theta, x0, x, v, f)[1] / p.tau

    def _held(self, context: Context) -> bool:
        """Before the first start time the state is held (discrete: its rounded step)."""
        if self._dt is not None:  # as _update: the step count against the rounded onset
            return int(round(context.get_time() / self._dt)) < self._steps[0]
        return context.get_time() < self._times[0] - 1e-9

    def _check_start(self, x_start: np.ndarray) -> np.ndarray:
        """``x_start`` as n finite numbers with a unit quaternion block; RepertoireError if not.

        (A chain started off the unit sphere ran silently; the state may leave it later,
        the component DMP runs in R^4, but the start is an orientation.)
        """
        x = check_finite_vector("x_start", x_start, self._n)
        if self._q is not None:
            check_unit_quaternions(x[self._q][None], name="x_start's quaternion block")
        return x

    def _learned_side(self, seg: int, *vectors: np.ndarray) -> list[np.ndarray]:
        """``vectors`` with the quaternion block negated if ``vectors[0]``'s is on the far side.

        The component quaternion DMP runs in R^4, where ``q`` and ``-q`` are one orientation
        but not one state: segment ``seg``'s forcing term was learned from its learned start
        ``x0[q]``, so it is run from the sign of the start with ``q . x0[q] >= 0`` (as
        :meth:`repertoire.planning.dmp.QuaternionDmpParameters.rollout` does). Position,
        velocity (and acceleration) of the block are negated together: the same motion.

        Args:
            seg: The segment that starts.
            *vectors: Its start position, then e.g. velocity and acceleration, shape (n,).
        """
        out = [None if v is None else np.array(v, dtype=float) for v in vectors]
        if (
            self._q is not None
            and learned_side(out[0][self._q], self._segments[seg].x0[self._q]) < 0
        ):
            for v in out:
                if v is not None:
                    v[self._q] *= -1.0
        return out

    def _next(self, context: Context, seg: int, x: np.ndarray, v: np.ndarray):
        """Hand-off to segment ``seg + 1``: (x, x0, v) of the successor.

        The quaternion block is put on the successor's learned side (:meth:`_learned_side`).
        """
        acc = self._acc(context) if self._handoff == "acceleration" else None
        x, v, acc = self._learned_side(seg + 1, x, v, acc)
        x0, v = handoff_state(
            self._segments[seg + 1], x, v, self._segments[seg].tau, self._handoff, acc
        )
        return x, x0, v

    # --- continuous mode ---------------------------------------------------------------
    def DoCalcTimeDerivatives(self, context: Context, derivatives) -> None:
        seg, theta, x0, x, v = self._split(context)
        if self._held(context):
            derivatives.get_mutable_vector().SetZero()
            return
        p = self._segments[seg]
        f = forcing_term(theta, p.weights, p.centres, p.widths)
        xd, vd = self._rhs(context, seg, theta, x0, x, v, f)
        derivatives.get_mutable_vector().SetFromVector(
            np.concatenate([[-p.alpha * theta / p.tau], xd, p.tau * (vd / p.tau)])
        )

    def start_delay(self, context: Context) -> float:
        """How much later than their start times the segments now start [s] (waits summed)."""
        return (
            float(context.get_discrete_state(self._delay).value()[0]) if self._dt is None else 0.0
        )

    def _maybe_switch(self, context: Context, state) -> None:
        seg, _, x0_active, x, v = self._split(context)
        if self._pending_flag(context) is not None and not self._held(context):
            z = context.get_continuous_state_vector().CopyToVector()  # the onset: scale once
            z[1 + self._n :] = v
            state.get_mutable_continuous_state().get_mutable_vector().SetFromVector(z)
            state.get_mutable_discrete_state(self._pending).SetFromVector(np.zeros(self._n))
        t, delay = context.get_time(), self.start_delay(context)
        due = self._times[seg + 1] + delay if seg + 1 < len(self._times) else np.inf
        if t < due - 1e-9:
            return
        tol = self._waits[seg + 1]
        if t < due + self._max_wait - 1e-9:
            if tol is not None:
                gap = self._goal(context, seg, x0_active)[self._wait_dofs] - x[self._wait_dofs]
                if np.linalg.norm(gap) > tol:
                    return
            if self._gates[seg + 1] and not self._gate_open(context):
                return
        if t - due >= self._switch_period - 1e-9:  # it waited (the first check after due failed)
            state.get_mutable_discrete_state(self._delay).SetFromVector([t - self._times[seg + 1]])
        x, x0, v_new = self._next(context, seg, x, v)
        state.get_mutable_continuous_state().get_mutable_vector().SetFromVector(
            np.concatenate([[1.0], x - x0, v_new])
        )
        state.get_mutable_discrete_state(self._switch).SetFromVector(
            np.concatenate([[seg + 1], x0])
        )

    def _gate_open(self, context: Context) -> bool:
        """Whether the ``start_gate`` input reads 1 (> 0.5); RepertoireError if unconnected."""
        if not self._gate_port.HasValue(context):
            raise RepertoireError(
                "DmpSequencer's start_gate input is not connected, but start_gates "
                f"{self._gates} make segments wait for it"
            )
        return bool(check_finite_input("start_gate", self._gate_port.Eval(context))[0] > 0.5)

    # --- discrete mode -----------------------------------------------------------------
    def _update(self, context: Context, discrete_state) -> None:
        seg, k, x0, x, v = self._split(context)
        step = int(round(context.get_time() / self._dt))
        if step < self._steps[0]:
            discrete_state.set_value(self._state, context.get_discrete_state(self._state).value())
            return
        if self._pending_flag(context) is not None:  # the onset: v above is scaled, once
            discrete_state.set_value(self._pending, np.zeros(self._n))
        if seg + 1 < len(self._segments) and step >= self._steps[seg + 1]:
            x, x0, v = self._next(context, seg, x, v)
            seg, k = seg + 1, 0
        p = self._coupling(context)
        z = self._tabs[seg].step(
            np.concatenate([x, v]), int(k), self._goal(context, seg, x0), x0, p
        )
        discrete_state.set_value(self._state, np.concatenate([[float(seg), k + 1.0], x0, z]))


def task_space_sequencer(
    segments: list[TaskSpaceDmp],
    start_times: list[float],
    x_start: np.ndarray,
    *,
    switch_period: float = 0.004,
    wait_tolerances: list[float | None] | None = None,
    wait_dofs: slice = slice(0, 3),
    max_wait: float = 0.0,
    start_gates: list[bool] | None = None,
) -> DmpSequencer:
    """The arm's chain of 10-D DMPs (Fig. 7): position, quaternion components, fingers.

    A continuous :class:`DmpSequencer` over the stacked segments
    (:func:`repertoire.planning.dmp_chain.stack_task_space_dmp`) with the quaternion
    block normalised, the coupling input on the position (3) and the output parts
    ``tcp`` (position) and ``finger``, velocity hand-off. Goal ports take
    ``[p (3), q (4), fingers]``.

    Args:
        segments: Task-space DMPs in execution order (component orientation, fingers).
        start_times: Onset of each segment [s]; the first is 0, increasing.
        x_start: The chain's start [p, q, fingers] (the robot's current state).
        switch_period: How often the switch times are checked [s].
        wait_tolerances: Per segment, None or the distance [m] the tcp position of the
            segment before must have come to its goal before this one starts
            (:class:`DmpSequencer`).
        wait_dofs: The position DOF that distance is measured on (default all three).
        max_wait: Longest wait of one segment [s].
        start_gates: Per segment, whether it waits for the ``start_gate`` input
            (:class:`DmpSequencer`).

    Raises:
        RepertoireError: empty chain, bad times, a manifold orientation, no fingers,
            segments with different finger DOF, or ``wait_dofs`` beyond the position.
    """
    if len(start_times) and float(start_times[0]) != 0.0:
        raise RepertoireError(f"start_times must start at 0, got {list(start_times)}")
    stacked = []
    for i, dmp in enumerate(segments):
        if dmp.orientation.mode != "component" or dmp.fingers is None:
            raise RepertoireError(
                f"segment {i}: the task-space chain runs the paper's component quaternion DMP "
                "with finger DOF; learn it with orientation_mode='component' and fingers"
            )
        stacked.append(stack_task_space_dmp(dmp))
    if not stacked:
        raise RepertoireError("a DMP chain needs at least one segment")
    if not (isinstance(wait_dofs, slice) and set(range(10)[wait_dofs]) <= {0, 1, 2}):
        raise RepertoireError(f"wait_dofs must be a slice of the position (0-2), got {wait_dofs!r}")
    n = stacked[0].parameters.n_dims
    if any(s.parameters.n_dims != n for s in stacked):
        raise RepertoireError("every segment must have the same number of finger DOF")
    return DmpSequencer(
        [s.parameters for s in stacked],
        start_times,
        x_start=x_start,
        time_step=None,
        switch_period=switch_period,
        quaternion_at=3,
        coupling_dofs=3,
        parts={"tcp": slice(0, 3), "finger": slice(7, n)},
        wait_tolerances=wait_tolerances,
        wait_dofs=wait_dofs,
        max_wait=max_wait,
        start_gates=start_gates,
    )


__all__ = ["DmpSequencer", "task_space_sequencer"]
