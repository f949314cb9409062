"""Chaining DMPs (Pastor et al. 2009, sec. III-C, Fig. 5) and the paper's 10-D stacking.

The one place the hand-off math lives:

* :func:`handoff_state` - the successor's equation start x0 and scaled velocity at a switch, for
  the three hand-offs (``"none"``, ``"velocity"`` = the paper, ``"acceleration"``);
* :func:`chain_rollout` - NumPy chaining built on it (the reference the sequencer
  LeafSystem, :class:`repertoire.systems.dmp_sequencer.DmpSequencer`, is tested against);
* :func:`stack_task_space_dmp` - a :class:`TaskSpaceDmp` (position 3, quaternion
  components 4, fingers) as one n-D :class:`DmpParameters`, with the slice of every part;
* :func:`directional_primitive` - one learned DOF's shape sent along any direction (the
  Fig. 5 square from one minimum-jerk primitive).
"""

from dataclasses import dataclass

import numpy as np
from repertoire.planning.dmp import DmpParameters, TaskSpaceDmp
from repertoire.planning.dmp_math import check_finite_vector, check_positive, forcing_features

from repertoire.checks import is_whole
from repertoire.errors import RepertoireError

HANDOFFS = ("none", "velocity", "acceleration")


def check_handoff(mode: str) -> str:
    """Returns ``mode`` if it is one of :data:`HANDOFFS`, else raises RepertoireError."""
    if mode not in HANDOFFS:
        raise RepertoireError(f"handoff must be one of {HANDOFFS}, got {mode!r}")
    return mode


def acceleration_matched_start(
    dmp: DmpParameters, x: np.ndarray, xd: np.ndarray, xdd: np.ndarray
) -> np.ndarray:
    """Equation start x0 that makes a new-form DMP begin with acceleration ``xdd``.

    At theta = 1 the new form gives ``tau^2 xdd = K (x0 - x) - D tau xd + K f(1)``; solving
    for x0 gives ``x + (tau^2 xdd + D tau xd - K f(1)) / K``.

    Args:
        dmp: The successor DMP (formulation "new").
        x: Position at the switch.
        xd: Velocity at the switch.
        xdd: Predecessor's acceleration at the switch.
    """
    if dmp.formulation != "new":
        raise RepertoireError("acceleration handoff needs the new formulation (eq. 6)")
    f1 = forcing_features(np.array(1.0), dmp.centres, dmp.widths) @ dmp.weights.T
    return x + (dmp.tau**2 * xdd + dmp.D * dmp.tau * xd - dmp.K * f1) / dmp.K


def handoff_state(
    successor: DmpParameters,
    x: np.ndarray,
    v: np.ndarray,
    tau_pred: float,
    mode: str = "velocity",
    acceleration: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The successor's equation start and scaled velocity when it takes over at ``x``.

    The phase restarts at 1. By ``mode``:

    * ``"none"``: x0 = x, v = 0 (a restart from rest, for comparison);
    * ``"velocity"`` (the paper): x0 = x and the physical velocity carries over,
      ``v_succ = v_pred tau_succ / tau_pred`` (v = tau dx/dt);
    * ``"acceleration"``: as "velocity", with x0 from :func:`acceleration_matched_start` so
      the successor starts with the predecessor's acceleration (new formulation only).

    Args:
        successor: The DMP that takes over.
        x: Position at the switch, shape (n,).
        v: Predecessor's scaled velocity ``tau_pred dx/dt``, shape (n,).
        tau_pred: The predecessor's tau [s].
        mode: One of :data:`HANDOFFS`.
        acceleration: Predecessor's physical acceleration at the switch (``"acceleration"``).

    Returns:
        (x0, v_succ): the successor's equation start and scaled velocity.
    """
    check_handoff(mode)
    check_positive("tau_pred", tau_pred)
    n = successor.n_dims
    x = check_finite_vector("x", x, n)
    v = check_finite_vector("v", v, n)
    if acceleration is not None:
        acceleration = check_finite_vector("acceleration", acceleration, n)
    if mode == "none":
        return x.copy(), np.zeros_like(v)
    v_succ = v * successor.tau / tau_pred
    if mode == "velocity":
        return x.copy(), v_succ
    if acceleration is None:
        raise RepertoireError("the acceleration handoff needs the predecessor's acceleration")
    return acceleration_matched_start(successor, x, v / tau_pred, acceleration), v_succ


def check_switch_times(times, n_segments: int, what: str = "switch times") -> np.ndarray:
    """``times`` as an array after checking one per segment, increasing and >= 0.

    Raises:
        RepertoireError: empty chain, wrong count, or times not increasing from >= 0.
    """
    if n_segments < 1:
        raise RepertoireError("a DMP chain needs at least one segment")
    t = np.asarray(times, dtype=float).reshape(-1)
    if t.size != n_segments:
        raise RepertoireError(f"{n_segments} segments need as many {what}, got {t.size}")
    if not np.all(np.isfinite(t)) or t[0] < 0 or np.any(np.diff(t) <= 0):
        raise RepertoireError(f"{what} must be increasing and >= 0, got {t.tolist()}")
    return t


@dataclass
class ChainRollout:
    """A chained DMP trajectory (sec. III-C).

    Attributes:
        t: Times [s], shape (N,).
        x: Positions, shape (N, n).
        xd: Velocities, shape (N, n).
        xdd: Accelerations, shape (N, n) (the active segment's).
        segment: Active segment index per sample, shape (N,).
        switch_steps: Sample index of each switch (segments 1..).
        acceleration_jumps: ``|xdd_succ - xdd_pred|`` (max over DOF) at each switch.
        velocity_jumps: ``|xd_succ - xd_pred|`` (max over DOF) at each switch.
    """

    t: np.ndarray
    x: np.ndarray
    xd: np.ndarray
    xdd: np.ndarray
    segment: np.ndarray
    switch_steps: list[int]
    acceleration_jumps: list[float]
    velocity_jumps: list[float]


def chain_rollout(
    segments: list[DmpParameters],
    goals: list[np.ndarray],
    switch_times: list[float],
    *,
    x0: np.ndarray | None = None,
    duration: float | None = None,
    dt: float = 1e-3,
    handoff: str = "velocity",
) -> ChainRollout:
    """NumPy chaining: segment i starts at ``switch_times[i]`` from its predecessor's state.

    The state is handed over by :func:`handoff_state` (mode ``handoff``); each segment is the
    exact first-order-hold rollout of :func:`repertoire.planning.dmp_math.rollout`.

    Args:
        segments: DMPs (same number of DOF).
        goals: One goal per segment.
        switch_times: Start time of each segment (first usually 0), increasing.
        x0: Start of the first segment; default its learned start. The chain starts with
            the first segment's learned velocity ``v0`` (zero for a rest demonstration; in
            the old formulation scaled to its goal, as its rollout) at ``switch_times[0]``;
            before it the position is held and ``xd`` and ``xdd`` are 0.
        duration: Total duration [s], more than one step past the last switch time;
            default last switch + last tau.
        dt: Time step [s], > 0.
        handoff: ``"none"``, ``"velocity"`` or ``"acceleration"``.
    """
    check_handoff(handoff)
    check_switch_times(switch_times, len(segments))
    for i, s in enumerate(segments):
        if not isinstance(s, DmpParameters):
            raise RepertoireError(f"segment {i} is {type(s).__name__}, not DmpParameters")
    check_positive("dt", dt)
    if len(goals) != len(segments):
        raise RepertoireError(f"{len(segments)} segments need as many goals, got {len(goals)}")
    steps = [int(round(s / dt)) for s in switch_times]
    if any(b <= a for a, b in zip(steps, steps[1:])):
        raise RepertoireError(f"switch times closer than dt = {dt}: {list(switch_times)}")
    if duration is None:
        duration = switch_times[-1] + segments[-1].tau
    check_positive("duration", duration)
    total = int(round(duration / dt))
    if total <= steps[-1]:
        raise RepertoireError(
            f"duration = {duration} must be more than one step (dt = {dt}) past the last "
            f"switch time {switch_times[-1]}"
        )
    n = segments[0].n_dims
    x = np.asarray(segments[0].x0 if x0 is None else x0, float)
    xd = segments[0].v0.copy()  # the first segment's learned start velocity (as DmpSequencer)
    # held before the first switch: the position stands still, so velocity and acceleration
    # are 0 (as every DMP system's outputs); the movement starts with xd at the onset
    X, XD, XDD = (
        [np.tile(x, (steps[0], 1))],
        [np.zeros((steps[0], n))],
        [np.zeros((steps[0], n))],
    )
    SEG = [np.zeros(steps[0], dtype=int)]
    acc_jumps, vel_jumps = [], []
    prev_acc = None
    bounds = steps[1:] + [total]
    for i, (dmp, g) in enumerate(zip(segments, goals)):
        if dmp.n_dims != n:
            raise RepertoireError(f"segment {i} has {dmp.n_dims} DOF, segment 0 has {n}")
        m = bounds[i] - steps[i]
        if prev_acc is None:
            x_eq, v0 = x, xd
        else:
            tau_pred = segments[i - 1].tau
            x_eq, v = handoff_state(dmp, x, tau_pred * xd, tau_pred, handoff, prev_acc)
            v0 = v / dmp.tau
        # name the segment: a bad goal of segment i said only "goal ..." (or float()'s error)
        if g is None or np.ndim(g) not in (1, 2):  # a vector, or one per sample (a moving goal)
            raise RepertoireError(f"segment {i}: goal must be a vector of {n} numbers, got {g!r}")
        try:
            goal = np.asarray(g, float)
        except (TypeError, ValueError) as err:
            raise RepertoireError(f"segment {i}: goal must be {n} numbers, got {g!r}") from err
        try:
            if prev_acc is None:  # old formulation: v0 scaled to the goal (as its rollout)
                v0 = dmp.start_velocity(goal[0] if goal.ndim == 2 else goal, x_eq)
            r = dmp.rollout(goal=goal, x0=x_eq, v0=v0, dt=dt, n_steps=m, x_init=x)
        except RepertoireError as err:
            raise type(err)(f"segment {i}: {err}") from err
        if prev_acc is not None:
            acc_jumps.append(float(np.max(np.abs(r.xdd[0] - prev_acc))))
            vel_jumps.append(float(np.max(np.abs(r.xd[0] - xd))))
        X.append(r.x[:-1])
        XD.append(r.xd[:-1])
        XDD.append(r.xdd[:-1])
        SEG.append(np.full(m, i))
        x, xd, prev_acc = r.x[-1], r.xd[-1], r.xdd[-1]
    X.append(x[None])
    XD.append(xd[None])
    XDD.append(prev_acc[None])
    SEG.append(np.array([len(segments) - 1]))
    return ChainRollout(
        np.arange(total + 1) * dt,
        np.concatenate(X),
        np.concatenate(XD),
        np.concatenate(XDD),
        np.concatenate(SEG),
        steps[1:],
        acc_jumps,
        vel_jumps,
    )


@dataclass
class StackedDmp:
    """A TaskSpaceDmp as one n-D DMP.

    Attributes:
        parameters: The stacked DmpParameters, DOF in the order of ``slices``.
        slices: Part name (``position``, ``orientation`` for component quaternions,
            ``fingers``) -> its DOF in ``parameters``.
    """

    parameters: DmpParameters
    slices: dict[str, slice]


def stack_task_space_dmp(dmp: TaskSpaceDmp) -> StackedDmp:
    """The paper's 10-D DMP (Fig. 7) as one DmpParameters: [x y z, qw qx qy qz, fingers].

    The orientation is stacked when it is in ``mode="component"`` (one transformation
    system per quaternion component, the paper's approach); a manifold orientation is
    left out (it runs as its own system). Fingers are stacked when present.

    Args:
        dmp: The task-space DMP.

    Raises:
        RepertoireError: the parts do not share their basis (centres and widths) or their
            formulation (a component orientation is always ``"new"``).
    """
    parts = [("position", dmp.position)]
    if dmp.orientation.mode == "component":
        parts.append(("orientation", dmp.orientation.component_parameters()))
    if dmp.fingers is not None:
        parts.append(("fingers", dmp.fingers))
    first = dmp.position
    for name, p in parts[1:]:
        if p.formulation != first.formulation:  # one stacked DMP runs one equation
            raise RepertoireError(
                f"the {name} DMP is in the {p.formulation!r} formulation, the position DMP in "
                f"{first.formulation!r}: they cannot be stacked into one DMP"
            )
        if not (
            np.array_equal(p.centres, first.centres) and np.array_equal(p.widths, first.widths)
        ):
            raise RepertoireError(f"the {name} DMP does not share the position DMP's basis")
    slices, start = {}, 0
    for name, p in parts:
        slices[name] = slice(start, start + p.n_dims)
        start += p.n_dims
    stacked = DmpParameters(
        np.vstack([p.weights for _, p in parts]),
        first.centres,
        first.widths,
        np.concatenate([p.K for _, p in parts]),
        np.concatenate([p.D for _, p in parts]),
        first.alpha,
        first.tau,
        np.concatenate([p.x0 for _, p in parts]),
        np.concatenate([p.goal for _, p in parts]),
        first.formulation,
        v0=np.concatenate([p.v0 for _, p in parts]),
    )
    return StackedDmp(stacked, slices)


__all__ = [
    "HANDOFFS",
    "ChainRollout",
    "StackedDmp",
    "acceleration_matched_start",
    "chain_rollout",
    "check_handoff",
    "check_switch_times",
    "directional_primitive",
    "handoff_state",
    "stack_task_space_dmp",
]


def directional_primitive(
    dmp: DmpParameters, start: np.ndarray, goal: np.ndarray, *, dof: int = 0
) -> DmpParameters:
    """An n-D DMP that moves along ``goal - start`` with the shape of one learned DOF.

    The new formulation does not scale the forcing term with ``g - x0`` (that is what cures
    the old form's blow-up and mirroring), so a primitive learned along one axis, sent to
    a goal along another axis, still pushes along the first one (it moves out and back).
    This helper generalises a 1-D shape to any direction: DOF ``dof`` of ``dmp`` (learned
    displacement ``A = goal_dof - x0_dof``, nonzero) drives every output DOF d with weights
    ``w * (goal_d - start_d) / A`` - linear amplitude scaling chosen by the user, as for a
    Fig. 5 square made of one minimum-jerk primitive. The old formulation (eq. 1) already
    multiplies the forcing term by ``goal_d - start_d`` (its weights were learned divided by
    ``A``, eq. 5), so there every DOF takes the weights ``w`` unchanged: scaling them too
    would apply the amplitude twice.

    Args:
        dmp: A learned DMP (any number of DOF).
        start: Start of the new movement, shape (n,).
        goal: Goal of the new movement, shape (n,).
        dof: Which learned DOF gives the shape.
    """
    # any number of entries (the new DMP's DOF), finite, and as many in goal as in start
    start = check_finite_vector("start", start, np.size(start))
    goal = check_finite_vector("goal", goal, start.size)
    if not (is_whole(dof) and 0 <= dof < dmp.n_dims):
        raise RepertoireError(f"dof must be in [0, {dmp.n_dims}), got {dof}")
    amplitude = dmp.goal[dof] - dmp.x0[dof]
    if abs(amplitude) < 1e-9:
        raise RepertoireError(
            f"DOF {dof} of the primitive does not move (g - x0 = {amplitude:.3g}); "
            "cannot scale its shape"
        )
    n = start.size
    scale = (goal - start) / amplitude
    # the old form's forcing term is (g - x0) f: the amplitude is in the equation already
    weight_scale = scale if dmp.formulation == "new" else np.ones(n)
    weights = np.outer(weight_scale, dmp.weights[dof])
    return DmpParameters(
        weights,
        dmp.centres,
        dmp.widths,
        np.full(n, dmp.K[dof]),
        np.full(n, dmp.D[dof]),
        dmp.alpha,
        dmp.tau,
        start,
        goal,
        dmp.formulation,
        v0=scale * dmp.v0[dof],  # the equations are linear: v0 scales with the shape
    )
