"""Dynamic movement primitives: the artefacts, their checks and JSON files (Pastor et al. 2009).

Artefacts:

* :class:`DmpParameters` - an n-DOF DMP (one transformation system per DOF, shared phase),
  in the paper's new formulation (eq. 6-8, default) or the original one (eq. 1-5);
* :class:`QuaternionDmpParameters` - an orientation DMP, either the paper's approach
  (``mode="component"``: one transformation system per quaternion component, output
  post-normalised) or an on-manifold variant (``mode="manifold"``: log/exp maps, unit norm
  kept exactly);
* :class:`TaskSpaceDmp` - the paper's 10-D setup: position (3) + orientation (4) +
  finger DOF (here 3), sharing one phase.

Learning (:mod:`repertoire.planning.dmp_learn`) is a least-squares fit of the forcing term
solved as a Drake MathematicalProgram; derivatives of recorded positions come from
:mod:`repertoire.planning.dmp_derivatives`; chaining is :mod:`repertoire.planning.dmp_chain`.
Artefacts save to / load from JSON exactly (floats round-trip by repr).
"""

import dataclasses
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Self

import numpy as np
from repertoire.planning.dmp_math import (
    alpha_for_final_phase,
    check_finite_vector,
    check_formulation,
    check_positive,
    rollout,
)
from repertoire.planning.dmp_quaternion import (
    learned_side,
    lift_quaternion_goal,
    quaternion_rate,
    quaternion_rollout,
)

from repertoire.checks import is_real, refuse_unknown_keys
from repertoire.errors import RepertoireError

DEFAULT_K = 156.25  # 25 * 6.25, as in Ijspeert et al. / movement_primitives
DEFAULT_ALPHA = alpha_for_final_phase(0.01)  # theta(tau) = 0.01
QUATERNION_MODES = ("component", "manifold")


# --------------------------------------------------------------------------- artefacts
def check_per_dof(name: str, value, n: int) -> np.ndarray:
    """``value`` (a scalar or n entries) as shape (n,); RepertoireError naming it otherwise."""
    v = _real_array(value)
    if v is None:
        raise RepertoireError(f"{name} must be a number or one number per DOF ({n}), got {value!r}")
    if v.ndim > 1 or v.size not in (1, n):
        raise RepertoireError(
            f"{name} must be a scalar or have one entry per DOF ({n}), got shape {v.shape}: {value}"
        )
    return np.broadcast_to(v.reshape(-1), (n,)).copy()


def _real_array(value) -> np.ndarray | None:
    """``value`` as a float array if it holds only real numbers, else None.

    Strings (``"1.0"``), bools, None and other objects are not numbers, though
    ``np.asarray(value, dtype=float)`` would convert some of them.
    """
    try:
        a = np.asarray(value)
    except (TypeError, ValueError):
        return None
    if a.dtype.kind in "iuf" or (a.dtype.kind == "O" and all(is_real(v) for v in a.flat)):
        return a.astype(float)
    return None


def _numbers(name: str, value) -> np.ndarray:
    """``value`` as a float array; RepertoireError naming it if it is not numbers."""
    a = _real_array(value)
    if a is None:
        raise RepertoireError(f"{name} must be numbers, got {value!r}")
    return a


def _check_finite(name: str, a: np.ndarray) -> None:
    """RepertoireError naming ``name``'s first NaN or inf entry, its index and its count."""
    bad = ~np.isfinite(a)
    if bad.any():
        k = tuple(int(i) for i in np.argwhere(bad)[0])
        raise RepertoireError(
            f"{name} contains NaN or inf: {name}[{', '.join(map(str, k))}] = {a[k]} "
            f"({int(bad.sum())} of {a.size} not finite)"
        )


def _check_widths(widths: np.ndarray) -> None:
    """Basis widths h_i must be > 0 (psi_i = exp(-h_i (theta - c_i)^2) grows otherwise)."""
    bad = np.flatnonzero(~(widths > 0))
    if bad.size:
        raise RepertoireError(
            f"widths must be > 0, got widths[{bad[0]}] = {widths[bad[0]]} "
            f"({bad.size} of {widths.size} not > 0)"
        )


def _scalar(name: str, value) -> float:
    """``value`` as a float; RepertoireError naming it if it is not one number.

    A real number or a one-element numeric array; a string such as ``"1.0"`` or a bool is
    refused (``float`` would take them).
    """
    if is_real(value):
        return float(value)
    a = _real_array(value) if isinstance(value, np.ndarray) else None
    if a is None or a.size != 1:
        raise RepertoireError(f"{name} must be a number, got {value!r}")
    return float(a.reshape(-1)[0])


class _FieldsRecord:
    """``to_dict``/``from_dict`` of a dataclass of arrays, numbers, strings and lists.

    The record is ``{"type": class name, field: value}`` with arrays as lists; ``from_dict``
    checks the type and the constructor validates the values.
    """

    def to_dict(self) -> dict:
        """JSON-ready record: ``type`` and every field (arrays as lists)."""
        out: dict = {"type": type(self).__name__}
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if isinstance(v, np.ndarray):
                v = v.tolist()
            elif isinstance(v, list):
                v = list(v)
            out[f.name] = v
        return out

    @classmethod
    def from_dict(cls, d: dict) -> Self:
        """Rebuild from :meth:`to_dict`'s record.

        Args:
            d: the record.
        """
        _check_type(d, cls.__name__)
        fields = dataclasses.fields(cls)
        keys = set(d) - {"type"}
        missing = [
            f.name
            for f in fields
            if f.name not in keys
            and f.default is dataclasses.MISSING
            and f.default_factory is dataclasses.MISSING
        ]
        unknown = sorted(keys - {f.name for f in fields})
        if missing or unknown:
            problems = [f"missing keys {missing}"] * bool(missing)
            problems += [f"unknown keys {unknown}"] * bool(unknown)
            raise RepertoireError(f"malformed {cls.__name__} record: {', '.join(problems)}")
        return cls(**{k: v for k, v in d.items() if k != "type"})


@dataclass
class DmpParameters(_FieldsRecord):
    """A learned n-DOF DMP.

    Attributes:
        weights: Forcing-term weights, shape (n_dims, n_basis).
        centres: Basis centres in phase, shape (n_basis,).
        widths: Basis widths, shape (n_basis,).
        K: Spring constants, shape (n_dims,).
        D: Damping constants, shape (n_dims,) (critically damped: 2 sqrt(K)).
        alpha: Canonical-system constant.
        tau: Temporal scaling (duration of the demonstration) [s].
        x0: Start (first demonstrated sample), shape (n_dims,).
        goal: Goal (last demonstrated sample), shape (n_dims,).
        formulation: ``"new"`` (eq. 6-8) or ``"old"`` (eq. 1-5).
        names: Optional names of the DOF.
        v0: Initial velocity dx/dt of the demonstration [per s] at the learned ``tau``,
            shape (n_dims,); None (the default) is zero, a rest-to-rest movement. The
            forcing term is learned with the demonstration's own velocities (eq. 8), so a
            demonstration that starts in motion is reproduced only from that velocity:
            rollouts and the DMP LeafSystems start from it unless given another
            (:meth:`initial_scaled_velocity`).
    """

    weights: np.ndarray
    centres: np.ndarray
    widths: np.ndarray
    K: np.ndarray
    D: np.ndarray
    alpha: float
    tau: float
    x0: np.ndarray
    goal: np.ndarray
    formulation: str = "new"
    names: list[str] = field(default_factory=list)
    v0: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.weights = np.atleast_2d(_numbers("weights", self.weights))
        if self.weights.ndim != 2 or self.weights.shape[0] < 1:
            raise RepertoireError(
                f"weights must have shape (n_dims >= 1, n_basis), got {self.weights.shape}"
            )
        n, b = self.weights.shape
        self.centres = _numbers("centres", self.centres).reshape(-1)
        self.widths = _numbers("widths", self.widths).reshape(-1)
        self.K = check_per_dof("K", self.K, n)
        self.D = check_per_dof("D", self.D, n)
        self.x0 = _numbers("x0", self.x0).reshape(-1)
        self.goal = _numbers("goal", self.goal).reshape(-1)
        self.v0 = np.zeros(n) if self.v0 is None else _numbers("v0", self.v0).reshape(-1)
        self.alpha = _scalar("alpha", self.alpha)
        self.tau = _scalar("tau", self.tau)
        if not isinstance(self.names, (list, tuple)) or not all(
            isinstance(m, str) for m in self.names
        ):
            raise RepertoireError(
                f"names must be a list of strings (one per DOF), got {self.names!r}"
            )
        self.names = list(self.names)
        self.validate()

    @property
    def n_dims(self) -> int:
        return int(self.weights.shape[0])

    @property
    def n_basis(self) -> int:
        return int(self.weights.shape[1])

    def validate(self) -> None:
        """Check shapes and values; raise RepertoireError on the first problem."""
        n, b = self.weights.shape
        if b < 1:
            raise RepertoireError("a DMP needs at least one basis function, got 0")
        for name in ("centres", "widths"):
            if getattr(self, name).shape != (b,):
                raise RepertoireError(
                    f"{name} has shape {getattr(self, name).shape}, weights have {b} basis "
                    "functions"
                )
        for name in ("x0", "goal", "v0"):
            if getattr(self, name).shape != (n,):
                raise RepertoireError(
                    f"{name} has {getattr(self, name).size} entries but weights have {n} DOF"
                )
        for name in ("weights", "centres", "widths", "K", "D", "x0", "goal", "v0"):
            _check_finite(name, getattr(self, name))
        check_positive("tau", self.tau)
        check_positive("alpha", self.alpha)
        if np.any(self.K <= 0) or np.any(self.D < 0):
            raise RepertoireError(f"K must be > 0 and D >= 0, got K = {self.K}, D = {self.D}")
        _check_widths(self.widths)
        check_formulation(self.formulation)
        if self.names and len(self.names) != n:
            raise RepertoireError(f"{len(self.names)} names for {n} DOF")

    def initial_scaled_velocity(self) -> np.ndarray:
        """The default initial state's scaled velocity ``v(0) = tau dx/dt``, shape (n_dims,).

        ``tau * v0`` at the learned tau. The equations (eq. 6-7) see the velocity only as
        ``v = tau dx/dt``, so a rollout with another ``tau`` starts from the same ``v`` (the
        physical velocity ``v0 * learned tau / tau``): the time-scaled demonstration.
        """
        return self.tau * self.v0

    def start_scale(self, goal: np.ndarray, x0: np.ndarray) -> np.ndarray:
        """Per DOF, how a run from x0 to goal scales the learned start velocity, shape (n_dims,).

        The new formulation (eq. 6) adds ``K f`` unscaled: 1. The old one (eq. 1) multiplies
        f by ``g - x0``: its run is the demonstration scaled per DOF by ``s = (g - x0) /
        (learned g - learned x0)`` (1 where the learned displacement is 0, which eq. 1
        cannot scale).

        Args:
            goal: The run's goal (at its start), shape (n_dims,).
            x0: The run's start, shape (n_dims,).
        """
        scale = np.ones(self.n_dims)
        if self.formulation == "new":
            return scale
        goal = check_finite_vector("goal", goal, self.n_dims)
        x0 = check_finite_vector("x0", x0, self.n_dims)
        learned = self.goal - self.x0
        moved = learned != 0.0
        scale[moved] = (goal - x0)[moved] / learned[moved]
        return scale

    def start_velocity(self, goal: np.ndarray, x0: np.ndarray) -> np.ndarray:
        """The start velocity dx/dt [per s] (learned tau) of a run: ``start_scale(goal, x0) v0``.

        Args:
            goal: The run's goal (at its start), shape (n_dims,).
            x0: The run's start, shape (n_dims,).
        """
        if self.formulation == "new" or not np.any(self.v0):
            return self.v0
        return self.start_scale(goal, x0) * self.v0

    def scales_start_velocity(self) -> bool:
        """Whether :meth:`start_scale` can change ``v0`` (old form, ``v0`` in a moved DOF)."""
        return self.formulation == "old" and bool(np.any(self.v0[self.goal != self.x0]))

    def with_tau(self, tau: float) -> "DmpParameters":
        """Copy re-timed: ``x(t)`` becomes ``x(t self.tau / tau)``, the same path in space.

        Eq. 4, 6-7 have no tau in the phase time ``t / tau``; ``v0`` becomes ``self.tau v0 /
        tau`` (the same scaled velocity), as ``rollout(tau=tau)`` does.

        Args:
            tau: The new duration [s], > 0.
        """
        tau = check_positive("tau", tau)
        return dataclasses.replace(self, tau=tau, v0=self.initial_scaled_velocity() / tau)

    def with_goal(self, goal: np.ndarray, x0: np.ndarray | None = None) -> "DmpParameters":
        """Copy with a new goal (and optionally a new start).

        Args:
            goal: New goal, shape (n_dims,).
            x0: New start, shape (n_dims,); default unchanged.
        """
        goal = check_finite_vector("goal", goal, self.n_dims)
        x0 = self.x0 if x0 is None else check_finite_vector("x0", x0, self.n_dims)
        return dataclasses.replace(self, goal=goal, x0=x0, v0=self.start_velocity(goal, x0))

    def rollout(
        self,
        *,
        goal: np.ndarray | None = None,
        x0: np.ndarray | None = None,
        tau: float | None = None,
        dt: float = 1e-3,
        n_steps: int | None = None,
        **kwargs,
    ):
        """NumPy rollout (see :func:`repertoire.planning.dmp_math.rollout`).

        Args:
            goal: Goal, (n,) or per-sample (n_steps+1, n); default the learned goal.
            x0: Start; default the learned start.
            tau: Temporal scaling; default the learned tau.
            dt: Time step [s].
            n_steps: Number of steps; default ``round(tau/dt)``.
            **kwargs: Passed on (``v0``: the initial velocity dx/dt, default the learned one
                scaled to this tau, :meth:`initial_scaled_velocity`; ``method``,
                ``coupling``, ``x_init``).
        """
        tau = self.tau if tau is None else check_positive("tau", tau)
        x0 = self.x0 if x0 is None else check_finite_vector("x0", x0, self.n_dims)
        goal = self.goal if goal is None else goal
        if kwargs.get("v0") is None:  # the learned scaled velocity tau v0 (see above)
            g0 = np.asarray(goal, dtype=float)
            v0 = self.start_velocity(g0[0] if g0.ndim == 2 else g0, x0)
            kwargs["v0"] = v0 if tau == self.tau else self.tau * v0 / tau
        return rollout(
            self.weights,
            self.centres,
            self.widths,
            self.K,
            self.D,
            self.alpha,
            tau,
            x0,
            goal,
            dt=dt,
            n_steps=n_steps,
            formulation=self.formulation,
            **kwargs,
        )


@dataclass
class QuaternionDmpParameters(_FieldsRecord):
    """A learned orientation DMP.

    The two modes, measured on 50 seeded minimum-jerk slerp demonstrations (about 1 rad),
    1 ms steps, goals turned by about 0.3 / 1.2 rad from the demonstrated one:

    * ``"component"`` (paper): the four components leave the unit sphere during the
      movement, ``| |q| - 1 |`` before post-normalisation median 0.04 / 0.11, max 0.21 /
      0.38; the normalised output follows a different path than the geodesic-based
      variant (max angle between the two outputs median 0.09 / 0.41 rad, up to 1.4 rad);
      the interpolation is in R^4, so its angular velocity is not the demonstrated one
      when the goal changes. Both reach the goal (< 2e-3 rad at 2 tau).
    * ``"manifold"``: ``| |q| - 1 | < 1e-14`` throughout (exponential-map update), the
      forcing term lives in rotation-vector space (world frame), the goal attractor is
      ``2 log(g q^*)`` on S^3 (no hemisphere flip, as Ude et al. 2014), continuous along
      the demonstration even where the rotation left passes 180 deg. Reproduction error
      1.7e-5 (component mode 1.8e-5) on 500-sample demonstrations.

    Both modes turn the learned way round: ``goal`` and ``-goal`` are one orientation but
    two targets (turn by phi, or by 360 deg - phi the other way), and rollouts and the
    LeafSystems pick the sign the demonstration had (``goal`` is the demonstration's last
    sample with signs made continuous, so ``goal . q0 < 0`` for a demonstration turning
    more than 180 deg). A rest-to-rest 200 deg yaw is reproduced to about 2e-5 rad in both
    modes. The manifold mode refuses to turn a full 360 deg or more (in learning, any
    sample that far from the goal; in a rollout, a goal that far from the start); the
    component mode has no such limit.

    Attributes:
        weights: ``(4, n_basis)`` for ``mode="component"`` (one transformation system per
            quaternion component, the paper's approach) or ``(3, n_basis)`` for
            ``mode="manifold"`` (rotation-vector forcing term).
        centres: Basis centres, shape (n_basis,).
        widths: Basis widths, shape (n_basis,).
        K: Spring constant.
        D: Damping constant.
        alpha: Canonical-system constant.
        tau: Temporal scaling [s].
        q0: Start orientation (w, x, y, z), unit.
        goal: Goal orientation (w, x, y, z), unit.
        mode: ``"component"`` or ``"manifold"``.
        omega0: Initial angular velocity of the demonstration (world frame) [rad/s] at the
            learned ``tau``, shape (3,); None (the default) is zero (starting at rest).
            Rollouts and the LeafSystems start from it unless given another, as
            :attr:`DmpParameters.v0`.
    """

    weights: np.ndarray
    centres: np.ndarray
    widths: np.ndarray
    K: float
    D: float
    alpha: float
    tau: float
    q0: np.ndarray
    goal: np.ndarray
    mode: str = "manifold"
    omega0: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.weights = np.atleast_2d(_numbers("weights", self.weights))
        self.centres = _numbers("centres", self.centres).reshape(-1)
        self.widths = _numbers("widths", self.widths).reshape(-1)
        self.q0 = _numbers("q0", self.q0).reshape(-1)
        self.goal = _numbers("goal", self.goal).reshape(-1)
        om = np.zeros(3) if self.omega0 is None else _numbers("omega0", self.omega0)
        self.omega0 = om.reshape(-1)
        if self.omega0.shape != (3,) or not np.all(np.isfinite(self.omega0)):
            raise RepertoireError(
                f"omega0 must be 3 finite numbers (an angular velocity), got {self.omega0}"
            )
        self.K, self.D = _scalar("K", self.K), _scalar("D", self.D)
        self.alpha, self.tau = _scalar("alpha", self.alpha), _scalar("tau", self.tau)
        if self.mode not in QUATERNION_MODES:
            raise RepertoireError(f"mode must be one of {QUATERNION_MODES}, got {self.mode!r}")
        rows = 4 if self.mode == "component" else 3
        if self.weights.shape[0] != rows or self.weights.shape[1] < 1:
            raise RepertoireError(
                f"mode {self.mode!r} needs weights of shape ({rows}, n_basis>=1), got "
                f"{self.weights.shape}"
            )
        b = self.weights.shape[1]
        if self.centres.shape != (b,) or self.widths.shape != (b,):
            raise RepertoireError("centres and widths must match the number of weights columns")
        for name in ("weights", "centres", "widths"):
            _check_finite(name, getattr(self, name))
        _check_widths(self.widths)
        for name in ("q0", "goal"):
            check_unit_quaternions(getattr(self, name)[None], name=name)
        check_positive("tau", self.tau)
        check_positive("alpha", self.alpha)
        check_positive("K", self.K)
        if not np.isfinite(self.D) or self.D < 0:
            raise RepertoireError(f"D must be a finite number >= 0, got {self.D}")

    @property
    def n_basis(self) -> int:
        return int(self.weights.shape[1])

    def _dynamics(self) -> tuple:
        """``(weights, centres, widths, K, D, alpha, tau)``: what both modes' dynamics take."""
        return self.weights, self.centres, self.widths, self.K, self.D, self.alpha, self.tau

    def with_tau(self, tau: float) -> "QuaternionDmpParameters":
        """Copy re-timed (the same turn; ``omega0`` times ``self.tau / tau``).

        Args:
            tau: The new duration [s], > 0 (as :meth:`DmpParameters.with_tau`).
        """
        tau = check_positive("tau", tau)
        return dataclasses.replace(self, tau=tau, omega0=self.omega0 * (self.tau / tau))

    def component_parameters(self) -> DmpParameters:
        """The 4-D component DMP (``mode="component"`` only).

        It starts at ``q0`` with ``dq/dt = omega0 q0 / 2`` (:func:`quaternion_rate`).
        """
        if self.mode != "component":
            raise RepertoireError("component_parameters() needs mode='component'")
        return DmpParameters(
            *self._dynamics(),
            self.q0,
            self.goal,
            names=["qw", "qx", "qy", "qz"],
            v0=quaternion_rate(self.omega0, self.q0),
        )

    def rollout(
        self,
        *,
        goal: np.ndarray | None = None,
        q0: np.ndarray | None = None,
        tau: float | None = None,
        dt: float = 1e-3,
        n_steps: int | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Roll out; returns ``(t, q, raw)``.

        For ``"component"`` ``q`` is the post-normalised quaternion and ``raw`` the
        un-normalised component state; for ``"manifold"`` ``raw`` is the angular velocity.

        Both modes start with the learned angular velocity ``omega0`` (scaled by
        ``self.tau / tau`` for another ``tau``, as the vector DMP's ``v0``).

        ``goal`` and ``-goal`` are the same orientation; the sign used is the one that turns
        from ``q0`` the way the DMP learned
        (:func:`repertoire.planning.dmp_quaternion.lift_quaternion_goal`): the learned goal
        for the learned start, so a demonstration turning more than 180 deg is reproduced
        rather than turned back the short way.

        Args:
            goal: Goal orientation (w, x, y, z), unit; default the learned one.
            q0: Start orientation, unit; default the learned one.
            tau: Temporal scaling [s], > 0; default the learned one.
            dt: Time step [s], > 0.
            n_steps: Number of steps, >= 1; default ``round(tau/dt)``.
        """
        g = self.goal if goal is None else _quaternion_argument("goal", goal)
        s = self.q0 if q0 is None else _quaternion_argument("q0", q0)
        tau = self.tau if tau is None else check_positive("tau", tau)
        omega0 = self.omega0 if tau == self.tau else self.omega0 * (self.tau / tau)
        check_positive("dt", dt)
        if self.mode == "component":
            # q and -q are one orientation but not one R^4 state: start on the learned start's
            # side (the forcing term was learned there) and report the given sign.
            sign = learned_side(s, self.q0)
            s = sign * s
            g = lift_quaternion_goal(g, s, self.goal, self.q0)
            r = self.component_parameters().rollout(
                goal=g, x0=s, tau=tau, dt=dt, n_steps=n_steps, v0=quaternion_rate(omega0, s)
            )
            q = r.x / np.linalg.norm(r.x, axis=1, keepdims=True)
            return r.t, sign * q, sign * r.x
        g = lift_quaternion_goal(g, s, self.goal, self.q0)
        w, c, h, K, D, alpha, _ = self._dynamics()
        return quaternion_rollout(
            w, c, h, K, D, alpha, tau, s, g, dt=dt, n_steps=n_steps, omega0=omega0
        )


@dataclass
class TaskSpaceDmp:
    """The paper's 10-D DMP: end-effector position, orientation and finger DOF, one phase.

    Attributes:
        position: 3-D DMP of the end-effector position p_WE [m].
        orientation: Orientation DMP of the end-effector quaternion.
        fingers: DMP of the finger DOF (None if the task has no fingers).
    """

    position: DmpParameters
    orientation: QuaternionDmpParameters
    fingers: DmpParameters | None = None

    def __post_init__(self) -> None:
        if self.position.n_dims != 3:
            raise RepertoireError(f"position DMP must be 3-D, got {self.position.n_dims}")
        parts = [self.position, self.orientation] + ([self.fingers] if self.fingers else [])
        for p in parts[1:]:
            if p.tau != self.position.tau or p.alpha != self.position.alpha:
                raise RepertoireError("all parts of a TaskSpaceDmp must share tau and alpha")

    @property
    def tau(self) -> float:
        return self.position.tau

    @property
    def alpha(self) -> float:
        return self.position.alpha

    def with_tau(self, tau: float) -> "TaskSpaceDmp":
        """Copy with every part re-timed (:meth:`DmpParameters.with_tau`).

        Args:
            tau: The new duration [s], > 0.
        """
        fingers = None if self.fingers is None else self.fingers.with_tau(tau)
        return TaskSpaceDmp(self.position.with_tau(tau), self.orientation.with_tau(tau), fingers)

    def with_goal(
        self,
        position: np.ndarray | None = None,
        orientation: np.ndarray | None = None,
        fingers: np.ndarray | None = None,
    ) -> "TaskSpaceDmp":
        """Copy with new goals (None keeps the learned one).

        Args:
            position: Goal position, shape (3,).
            orientation: Goal quaternion (w, x, y, z).
            fingers: Goal finger positions.
        """
        pos = self.position if position is None else self.position.with_goal(position)
        ori = self.orientation
        if orientation is not None:
            g = _quaternion_argument("goal orientation", orientation)
            # Stored with the sign nearest the current goal, so the copy turns the same way.
            ori = dataclasses.replace(ori, goal=lift_quaternion_goal(g, ori.q0, ori.goal, ori.q0))
        fin = self.fingers
        if fingers is not None:
            if fin is None:
                raise RepertoireError("this TaskSpaceDmp has no finger DOF")
            fin = fin.with_goal(fingers)
        return TaskSpaceDmp(pos, ori, fin)

    def to_dict(self) -> dict:
        return {
            "type": "TaskSpaceDmp",
            "position": self.position.to_dict(),
            "orientation": self.orientation.to_dict(),
            "fingers": None if self.fingers is None else self.fingers.to_dict(),
        }

    @classmethod
    def from_dict(cls, d: dict) -> "TaskSpaceDmp":
        _check_type(d, "TaskSpaceDmp")
        # a misspelt "fingers" would load a DMP without its fingers
        refuse_unknown_keys(
            d, ("type", "position", "orientation", "fingers"), "TaskSpaceDmp record"
        )
        return cls(
            DmpParameters.from_dict(d["position"]),
            QuaternionDmpParameters.from_dict(d["orientation"]),
            None if d.get("fingers") is None else DmpParameters.from_dict(d["fingers"]),
        )


ARTEFACT_TYPES = {
    "DmpParameters": DmpParameters,
    "QuaternionDmpParameters": QuaternionDmpParameters,
    "TaskSpaceDmp": TaskSpaceDmp,
}


def _check_type(d: dict, expected: str) -> None:
    if not isinstance(d, dict):
        raise RepertoireError(f"expected a {expected} record (a dict), got {type(d).__name__}")
    if d.get("type") != expected:
        raise RepertoireError(f"expected a {expected} record, got type {d.get('type')!r}")


def save_dmp(dmp, path: str | Path) -> Path:
    """Save a DMP artefact as JSON (exact: floats are written by repr).

    Args:
        dmp: DmpParameters, QuaternionDmpParameters or TaskSpaceDmp.
        path: Output file; its suffix must be ``.json`` (as :meth:`MotionLibrary.save`).

    Raises:
        RepertoireError: another suffix (``d.npz`` got JSON inside before).
    """
    path = Path(path)
    if path.suffix != ".json":
        raise RepertoireError(
            f"a DMP artefact is saved as JSON: {path} must end in '.json', "
            f"not {path.suffix or 'no suffix'!r}"
        )
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(dmp.to_dict(), indent=1))
    return path


def dmp_from_dict(d: dict):
    """Rebuild any DMP artefact from its ``to_dict()`` record.

    Args:
        d: A dict with a ``type`` key.
    """
    kind = d.get("type") if isinstance(d, dict) else None
    if kind not in ARTEFACT_TYPES:
        raise RepertoireError(
            f"unknown DMP artefact type {kind!r}; expected one of {sorted(ARTEFACT_TYPES)}"
        )
    return ARTEFACT_TYPES[kind].from_dict(d)


def load_dmp(path: str | Path):
    """Load a DMP artefact saved by :func:`save_dmp`.

    Args:
        path: JSON file.
    """
    try:
        record = json.loads(Path(path).read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise RepertoireError(f"cannot read a DMP artefact from {path}: {err}") from err
    try:
        return dmp_from_dict(record)
    except (KeyError, TypeError, ValueError) as err:
        what = f"missing key {err}" if isinstance(err, KeyError) else str(err)
        raise RepertoireError(f"{path}: malformed DMP artefact: {what}") from err


# --------------------------------------------------------------------------- validation
def check_demonstration(t: np.ndarray, x: np.ndarray, *, name: str = "demonstration") -> tuple:
    """Validate a demonstration and return it as float arrays ``(t (N,), x (N, n))``.

    Raises RepertoireError for NaN/inf samples, fewer than 3 samples, non-increasing time
    stamps or mismatched lengths.

    Args:
        t: Time stamps, shape (N,).
        x: Samples, shape (N,) or (N, n).
        name: Name used in messages.
    """
    if np.iscomplexobj(t) or np.iscomplexobj(x):
        raise RepertoireError(f"{name} must be real numbers, got complex values")
    try:
        t, x = np.asarray(t, dtype=float), np.asarray(x, dtype=float)
    except (TypeError, ValueError) as err:
        raise RepertoireError(f"{name} time stamps and samples must be numbers: {err}") from err
    if t.ndim > 1 and t.size != max(t.shape):
        raise RepertoireError(f"{name} time stamps must be one vector (N,), got shape {t.shape}")
    t = t.reshape(-1)
    if x.ndim == 1:
        x = x[:, None]
    if x.ndim != 2:
        raise RepertoireError(f"{name} must have shape (N, n_dims), got {x.shape}")
    if x.shape[0] != t.size:
        raise RepertoireError(f"{name} has {x.shape[0]} samples but {t.size} time stamps")
    if t.size < 3:
        raise RepertoireError(f"{name} needs at least 3 samples, got {t.size}")
    if x.shape[1] < 1:
        raise RepertoireError(f"{name} has no DOF")
    if not np.all(np.isfinite(t)):
        k = int(np.argwhere(~np.isfinite(t))[0, 0])
        raise RepertoireError(f"{name} time stamps contain NaN or inf (first at t[{k}] = {t[k]})")
    bad = ~np.isfinite(x)
    if bad.any():
        raise RepertoireError(
            f"{name} contains NaN or inf (first at sample {int(np.argwhere(bad)[0, 0])})"
        )
    dt = np.diff(t)
    if np.any(dt <= 0):
        k = int(np.argmax(dt <= 0))
        raise RepertoireError(
            f"{name} time stamps must be strictly increasing; t[{k + 1}]={t[k + 1]} <= "
            f"t[{k}]={t[k]}"
        )
    return t, x


def _quaternion_argument(name: str, value) -> np.ndarray:
    """A unit quaternion argument as shape (4,); RepertoireError naming it otherwise."""
    q = np.asarray(value, dtype=float)
    if q.shape != (4,):
        raise RepertoireError(
            f"{name} must be a unit quaternion (w, x, y, z) of shape (4,), got shape "
            f"{q.shape}: {value}"
        )
    check_unit_quaternions(q[None], name=name)
    return q


def check_unit_quaternions(
    q: np.ndarray, *, tolerance: float = 1e-6, name: str = "quaternions"
) -> np.ndarray:
    """Raise RepertoireError if any quaternion's norm differs from 1 by more than tolerance.

    Args:
        q: Shape (N, 4).
        tolerance: Allowed ``| |q| - 1 |``.
        name: Name used in messages.
    """
    if not 0.0 <= tolerance < np.inf:
        raise RepertoireError(f"tolerance must be a finite number >= 0, got {tolerance}")
    q = np.asarray(q, dtype=float)
    if q.ndim != 2 or q.shape[1] != 4:
        raise RepertoireError(f"{name} must have shape (N, 4) (w, x, y, z), got {q.shape}")
    if not np.all(np.isfinite(q)):
        k = int(np.argwhere(~np.isfinite(q))[0, 0])
        raise RepertoireError(f"{name} contains NaN or inf (first at sample {k}: {q[k]})")
    dev = np.abs(np.linalg.norm(q, axis=1) - 1.0)
    k = int(np.argmax(dev))
    if dev[k] > tolerance:
        raise RepertoireError(
            f"{name} are not unit: | |q| - 1 | = {dev[k]:.3g} at sample {k} (norm "
            f"{np.linalg.norm(q[k]):.6g}), tolerance {tolerance:g}; normalise them first"
        )
    return q
