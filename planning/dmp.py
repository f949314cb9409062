"""Learning dynamic movement primitives from demonstrations (Pastor et al. 2009, sec. II).

Artefacts:

* :class:`DmpParameters` - an n-DOF DMP (one transformation system per DOF, shared phase),
  in the paper's new formulation (eq. 6-8, default) or the original one (eq. 1-5);
* :class:`QuaternionDmpParameters` - an orientation DMP, either the paper's approach
  (``mode="component"``: one transformation system per quaternion component, output
  post-normalised) or an on-manifold variant (``mode="manifold"``: log/exp maps, unit norm
  kept exactly);
* :class:`TaskSpaceDmp` - the paper's 10-D setup: position (3) + orientation (4) +
  finger DOF (here 3), sharing one phase.

Learning is a least-squares fit of the forcing term (eq. 5 / 8) solved as a Drake
MathematicalProgram (a convex quadratic cost with the precomputed normal equations,
optional ridge term). Derivatives of recorded positions come from a Savitzky-Golay filter
(uniform time stamps) or a smoothing spline (non-uniform time stamps), not raw finite
differences. Artefacts save to / load from JSON exactly (floats round-trip by repr).
"""

import dataclasses
import functools
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Self

import numpy as np
from pydrake.solvers import (
    Binding,
    ChooseBestSolver,
    MakeSolver,
    MathematicalProgram,
    QuadraticCost,
    Solve,
)
from repertoire.planning.dmp_math import (
    FORMULATIONS,
    alpha_for_final_phase,
    angular_velocity,
    basis_centres,
    basis_widths,
    canonical_phase,
    check_n_basis,
    check_positive,
    forcing_features,
    forcing_target,
    quat_conjugate,
    quat_error,
    quat_multiply,
    quaternion_rollout,
    rollout,
)

from repertoire.errors import RepertoireError, SolverError

DEFAULT_K = 156.25  # 25 * 6.25, as in Ijspeert et al. / movement_primitives
DEFAULT_ALPHA = alpha_for_final_phase(0.01)  # theta(tau) = 0.01
QUATERNION_MODES = ("component", "manifold")


# --------------------------------------------------------------------------- artefacts
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

    def __post_init__(self) -> None:
        self.weights = np.atleast_2d(np.asarray(self.weights, dtype=float))
        n, b = self.weights.shape
        self.centres = np.asarray(self.centres, dtype=float).reshape(-1)
        self.widths = np.asarray(self.widths, dtype=float).reshape(-1)
        self.K = np.broadcast_to(np.asarray(self.K, dtype=float), (n,)).copy()
        self.D = np.broadcast_to(np.asarray(self.D, dtype=float), (n,)).copy()
        self.x0 = np.asarray(self.x0, dtype=float).reshape(-1)
        self.goal = np.asarray(self.goal, dtype=float).reshape(-1)
        self.alpha = float(self.alpha)
        self.tau = float(self.tau)
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
        for name in ("x0", "goal"):
            if getattr(self, name).shape != (n,):
                raise RepertoireError(
                    f"{name} has {getattr(self, name).size} entries but weights have {n} DOF"
                )
        for name in ("weights", "centres", "widths", "K", "D", "x0", "goal"):
            if not np.all(np.isfinite(getattr(self, name))):
                raise RepertoireError(f"{name} contains NaN or inf")
        check_positive("tau", self.tau)
        check_positive("alpha", self.alpha)
        if np.any(self.K <= 0) or np.any(self.D < 0):
            raise RepertoireError("K must be > 0 and D >= 0")
        if self.formulation not in FORMULATIONS:
            raise RepertoireError(
                f"formulation must be one of {FORMULATIONS}, got {self.formulation!r}"
            )
        if self.names and len(self.names) != n:
            raise RepertoireError(f"{len(self.names)} names for {n} DOF")

    def with_goal(self, goal: np.ndarray, x0: np.ndarray | None = None) -> "DmpParameters":
        """Copy with a new goal (and optionally a new start).

        Args:
            goal: New goal, shape (n_dims,).
            x0: New start, shape (n_dims,); default unchanged.
        """
        return dataclasses.replace(
            self, goal=np.asarray(goal, float), x0=self.x0 if x0 is None else x0
        )

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
            **kwargs: Passed on (``v0``, ``method``, ``coupling``).
        """
        return rollout(
            self.weights,
            self.centres,
            self.widths,
            self.K,
            self.D,
            self.alpha,
            self.tau if tau is None else tau,
            self.x0 if x0 is None else x0,
            self.goal if goal is None else goal,
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
      forcing term lives in rotation-vector space (world frame), the goal attractor is the
      shortest-arc error ``2 log(g q^*)``. Reproduction error 1.7e-5 (component mode
      1.8e-5) on 500-sample demonstrations.

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

    def __post_init__(self) -> None:
        self.weights = np.atleast_2d(np.asarray(self.weights, dtype=float))
        self.centres = np.asarray(self.centres, dtype=float).reshape(-1)
        self.widths = np.asarray(self.widths, dtype=float).reshape(-1)
        self.q0 = np.asarray(self.q0, dtype=float).reshape(-1)
        self.goal = np.asarray(self.goal, dtype=float).reshape(-1)
        self.K, self.D = float(self.K), float(self.D)
        self.alpha, self.tau = float(self.alpha), float(self.tau)
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
        for name in ("q0", "goal"):
            check_unit_quaternions(getattr(self, name)[None], name=name)
        check_positive("tau", self.tau)
        check_positive("alpha", self.alpha)
        check_positive("K", self.K)

    @property
    def n_basis(self) -> int:
        return int(self.weights.shape[1])

    def component_parameters(self) -> DmpParameters:
        """The 4-D component DMP (``mode="component"`` only)."""
        if self.mode != "component":
            raise RepertoireError("component_parameters() needs mode='component'")
        return DmpParameters(
            self.weights,
            self.centres,
            self.widths,
            self.K,
            self.D,
            self.alpha,
            self.tau,
            self.q0,
            self.goal,
            names=["qw", "qx", "qy", "qz"],
        )

    def rollout(
        self,
        *,
        goal: np.ndarray | None = None,
        q0: np.ndarray | None = None,
        dt: float = 1e-3,
        n_steps: int | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Roll out; returns ``(t, q, raw)``.

        For ``"component"`` ``q`` is the post-normalised quaternion and ``raw`` the
        un-normalised component state; for ``"manifold"`` ``raw`` is the angular velocity.

        Args:
            goal: Goal orientation; default the learned one.
            q0: Start orientation; default the learned one.
            dt: Time step [s].
            n_steps: Number of steps; default ``round(tau/dt)``.
        """
        g = self.goal if goal is None else np.asarray(goal, float)
        s = self.q0 if q0 is None else np.asarray(q0, float)
        check_unit_quaternions(np.stack([g, s]), name="goal/start orientation")
        if self.mode == "component":
            g = g if g @ s >= 0 else -g
            r = self.component_parameters().rollout(goal=g, x0=s, dt=dt, n_steps=n_steps)
            q = r.x / np.linalg.norm(r.x, axis=1, keepdims=True)
            return r.t, q, r.x
        return quaternion_rollout(
            self.weights,
            self.centres,
            self.widths,
            self.K,
            self.D,
            self.alpha,
            self.tau,
            s,
            g,
            dt=dt,
            n_steps=n_steps,
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

    @property
    def n_fingers(self) -> int:
        return 0 if self.fingers is None else self.fingers.n_dims

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
            check_unit_quaternions(np.asarray(orientation, float)[None], name="goal orientation")
            ori = dataclasses.replace(ori, goal=np.asarray(orientation, float))
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
        return cls(
            DmpParameters.from_dict(d["position"]),
            QuaternionDmpParameters.from_dict(d["orientation"]),
            None if d["fingers"] is None else DmpParameters.from_dict(d["fingers"]),
        )


ARTEFACT_TYPES = {
    "DmpParameters": DmpParameters,
    "QuaternionDmpParameters": QuaternionDmpParameters,
    "TaskSpaceDmp": TaskSpaceDmp,
}


def _check_type(d: dict, expected: str) -> None:
    if d.get("type") != expected:
        raise RepertoireError(f"expected a {expected} record, got type {d.get('type')!r}")


def save_dmp(dmp, path: str | Path) -> Path:
    """Save a DMP artefact as JSON (exact: floats are written by repr).

    Args:
        dmp: DmpParameters, QuaternionDmpParameters or TaskSpaceDmp.
        path: Output file (``.json``).
    """
    path = Path(path)
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
    return dmp_from_dict(json.loads(Path(path).read_text()))


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
    t = np.asarray(t, dtype=float).reshape(-1)
    x = np.asarray(x, dtype=float)
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
    bad = ~np.isfinite(x)
    if bad.any() or not np.all(np.isfinite(t)):
        k = int(np.argwhere(bad)[0, 0]) if bad.any() else int(np.argwhere(~np.isfinite(t))[0, 0])
        raise RepertoireError(f"{name} contains NaN or inf (first at sample {k})")
    dt = np.diff(t)
    if np.any(dt <= 0):
        k = int(np.argmax(dt <= 0))
        raise RepertoireError(
            f"{name} time stamps must be strictly increasing; t[{k + 1}]={t[k + 1]} <= "
            f"t[{k}]={t[k]}"
        )
    return t, x


def check_unit_quaternions(
    q: np.ndarray, *, tolerance: float = 1e-6, name: str = "quaternions"
) -> np.ndarray:
    """Raise RepertoireError if any quaternion's norm differs from 1 by more than tolerance.

    Args:
        q: Shape (N, 4).
        tolerance: Allowed ``| |q| - 1 |``.
        name: Name used in messages.
    """
    q = np.asarray(q, dtype=float)
    if q.ndim != 2 or q.shape[1] != 4:
        raise RepertoireError(f"{name} must have shape (N, 4) (w, x, y, z), got {q.shape}")
    if not np.all(np.isfinite(q)):
        raise RepertoireError(f"{name} contains NaN or inf")
    dev = np.abs(np.linalg.norm(q, axis=1) - 1.0)
    k = int(np.argmax(dev))
    if dev[k] > tolerance:
        raise RepertoireError(
            f"{name} are not unit: | |q| - 1 | = {dev[k]:.3g} at sample {k} (norm "
            f"{np.linalg.norm(q[k]):.6g}), tolerance {tolerance:g}; normalise them first"
        )
    return q


# --------------------------------------------------------------------------- derivatives
def estimate_derivatives(
    t: np.ndarray,
    x: np.ndarray,
    *,
    method: str = "auto",
    window: int | None = None,
    smoothing: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """First and second time derivatives of recorded positions.

    ``"savgol"`` (uniform time stamps): Savitzky-Golay filter of polynomial order 5 (exact
    for minimum-jerk segments), edge samples from a polynomial fit of the edge window.
    ``"local_poly"`` (any time stamps): the same idea on non-uniform stamps, a least-squares
    polynomial of order 5 fitted to the ``window`` nearest samples around each sample.
    ``"spline"`` (any time stamps): a smoothing spline (``scipy`` ``make_smoothing_spline``;
    ``smoothing`` is its lambda, None = generalised cross-validation, which can over-smooth
    noise-free data) differentiated analytically. ``"auto"`` picks savgol when the stamps
    are uniform to 1e-6 relative, local_poly otherwise.

    Args:
        t: Time stamps, strictly increasing, shape (N,).
        x: Samples, shape (N, n).
        method: ``"auto"``, ``"savgol"``, ``"local_poly"`` or ``"spline"``.
        window: Savitzky-Golay / local-polynomial window (odd). Default: savgol chooses it
            by generalised cross-validation (see _gcv_savgol_window), so noisy
            demonstrations are smoothed and clean ones keep about N/40 (>= 7);
            local_poly uses about N/40, >= 7.
        smoothing: Smoothing-spline lambda.
    """
    t, x = check_demonstration(t, x)
    n = t.size
    dt = np.diff(t)
    uniform = np.ptp(dt) <= 1e-6 * dt.mean()
    if method == "auto":
        method = "savgol" if uniform else "local_poly"
    if method == "savgol":
        if not uniform:
            raise RepertoireError("method='savgol' needs uniform time stamps; use 'spline'")
        h = float(dt.mean())
        max_w = n if n % 2 else n - 1
        if window is None:
            w = _gcv_savgol_window(x, h, max_w)
        else:
            w = min(window, max_w)
        if w % 2 == 0 or w < 3:
            raise RepertoireError(f"Savitzky-Golay window must be odd and >= 3, got {w}")
        order = min(5, w - 1)
        return _savgol_derivatives(x, w, order, h)
    if method == "local_poly":
        return _local_polynomial_derivatives(t, x, window)
    if method == "spline":
        if n < 5:
            from scipy.interpolate import make_interp_spline

            spline = make_interp_spline(t, x, k=2)
        else:
            from scipy.interpolate import make_smoothing_spline

            spline = make_smoothing_spline(t, x, lam=smoothing, axis=0)
        return spline.derivative(1)(t), spline.derivative(2)(t)
    raise RepertoireError(
        f"method must be 'auto', 'savgol', 'local_poly' or 'spline', got {method!r}"
    )


@functools.lru_cache(maxsize=16)
def _savgol_operators(w: int, order: int, h: float) -> tuple[np.ndarray, ...]:
    """Savitzky-Golay first/second-derivative operators for uniform samples, cached.

    Returns ``(c1, c2, E1_first, E2_first, E1_last, E2_last, c0, E0_first, E0_last)``:
    interior dot-product coefficients, and for the ``w // 2`` samples at each edge the
    derivative of the polynomial fitted to the edge window (scipy's ``mode="interp"``) as a
    matrix on it; the ``0`` entries are the smoothing (zeroth-derivative) operators.
    """
    from scipy.signal import savgol_coeffs

    half = w // 2
    c0 = savgol_coeffs(w, order, deriv=0, use="dot")
    c1 = savgol_coeffs(w, order, deriv=1, delta=h, use="dot")
    c2 = savgol_coeffs(w, order, deriv=2, delta=h, use="dot")
    s = np.arange(w, dtype=float)
    u = (s - half) / half  # window positions scaled to [-1, 1]: a well-conditioned fit
    fit = np.linalg.pinv(np.vander(u, order + 1, increasing=True))  # samples -> coefficients
    j = np.arange(order + 1)

    def evaluate(points: np.ndarray, k: int) -> np.ndarray:
        falling = np.ones(order + 1)
        for m in range(k):
            falling = falling * (j - m)
        powers = np.where(j >= k, points[:, None] ** np.maximum(j - k, 0), 0.0)
        return (falling * powers) @ fit / (half * h) ** k

    first, last = u[:half], u[w - half :]
    return (
        c1,
        c2,
        evaluate(first, 1),
        evaluate(first, 2),
        evaluate(last, 1),
        evaluate(last, 2),
        c0,
        evaluate(first, 0),
        evaluate(last, 0),
    )


def _gcv_savgol_window(x: np.ndarray, h: float, max_w: int) -> int:
    """Savitzky-Golay window (order 5) chosen by generalised cross-validation.

    Candidates grow geometrically (x1.5) from ``max(7, 2 (N // 80) + 1)`` to about N / 4.
    For each, the smoothed positions ``S_w x`` give ``GCV(w) = RSS / (1 - tr(S_w) / N)^2``
    (summed over DOF); the smallest window within 1e-6 of the minimum (or of a round-off
    floor) wins, so noise-free demonstrations keep the smallest window and stay exact for
    minimum-jerk segments, and noisy ones get the window that averages the noise out.
    """
    n = x.shape[0]
    # GCV's argmin does not change with the data's scale; scaling keeps huge
    # coordinates from overflowing the residual sums.
    scale = float(np.max(np.abs(x))) if x.size else 0.0
    if scale > 0.0 and np.isfinite(scale):
        x = x / scale
    w = min(max(7, 2 * (n // 80) + 1), max_w)
    candidates = [w]
    while True:
        nxt = int(round(candidates[-1] * 1.5)) | 1
        if nxt > min(max_w, n // 4):
            break
        candidates.append(nxt)
    scores = []
    for w in candidates:
        order = min(5, w - 1)
        ops = _savgol_operators(w, order, h)
        c0, e0f, e0l = ops[6], ops[7], ops[8]
        half = w // 2
        smooth = np.empty_like(x)
        windows = np.lib.stride_tricks.sliding_window_view(x, w, axis=0)
        smooth[half : n - half] = windows @ c0
        smooth[:half], smooth[n - half :] = e0f @ x[:w], e0l @ x[-w:]
        trace = c0[half] * (n - 2 * half) + np.trace(e0f[:, :half]) + np.trace(e0l[:, w - half :])
        rss = float(np.sum((smooth - x) ** 2))
        scores.append(rss / max(1.0 - trace / n, 1e-12) ** 2)
    floor = x.size * (1e-10 * max(1.0, float(np.max(np.abs(x))))) ** 2
    best = max(min(scores), floor) * (1.0 + 1e-6)
    return next(w for w, g in zip(candidates, scores, strict=True) if g <= best)


def _savgol_derivatives(
    x: np.ndarray, w: int, order: int, h: float
) -> tuple[np.ndarray, np.ndarray]:
    """``savgol_filter(x, w, order, deriv=1|2, delta=h, axis=0, mode="interp")``, both at once."""
    c1, c2, e1f, e2f, e1l, e2l = _savgol_operators(w, order, h)[:6]
    half = w // 2
    windows = np.lib.stride_tricks.sliding_window_view(x, w, axis=0)  # (n - w + 1, dims, w)
    xd, xdd = np.empty_like(x), np.empty_like(x)
    xd[half : x.shape[0] - half], xdd[half : x.shape[0] - half] = windows @ c1, windows @ c2
    xd[:half], xdd[:half] = e1f @ x[:w], e2f @ x[:w]
    xd[x.shape[0] - half :], xdd[x.shape[0] - half :] = e1l @ x[-w:], e2l @ x[-w:]
    return xd, xdd


def _local_polynomial_derivatives(
    t: np.ndarray, x: np.ndarray, window: int | None
) -> tuple[np.ndarray, np.ndarray]:
    """Savitzky-Golay on non-uniform stamps: per-sample least-squares polynomial fits."""
    n = t.size
    max_w = n if n % 2 else n - 1
    w = window if window is not None else max(7, 2 * (n // 80) + 1)
    w = min(w, max_w)
    if w % 2 == 0 or w < 3:
        raise RepertoireError(f"local-polynomial window must be odd and >= 3, got {w}")
    order = min(5, w - 1)
    half = w // 2
    start = np.clip(np.arange(n) - half, 0, n - w)
    idx = start[:, None] + np.arange(w)[None, :]  # (n, w) window indices
    dt = t[idx] - t[:, None]
    scale = np.abs(dt).max(axis=1, keepdims=True)
    V = (dt / scale)[..., None] ** np.arange(order + 1)  # (n, w, order+1)
    coef = np.linalg.pinv(V) @ x[idx]  # (n, order+1, n_dims)
    s = scale[:, :, None][:, 0]
    return coef[:, 1] / s, 2.0 * coef[:, 2] / s**2


# --------------------------------------------------------------------------- least squares
def build_forcing_fit_program(
    features: np.ndarray, ridge: float = 0.0
) -> tuple[MathematicalProgram, np.ndarray, Binding[QuadraticCost]]:
    """Least-squares fit of one DOF's forcing weights as a MathematicalProgram.

    Minimises ``||Phi w - f||^2 + ridge ||w||^2`` with the normal equations precomputed:
    a convex QuadraticCost with Hessian ``2 (Phi^T Phi + ridge I)``. The Hessian is the same
    for every DOF (eq. 8's regressors do not depend on the DOF), so one program serves them
    all: :func:`fit_forcing_weights` only updates the cost's linear term ``-2 Phi^T f_d``.
    This is about 6x faster than one stacked program over all DOFs, whose dense KKT system
    grows with the square of the number of DOFs.

    Args:
        features: Regressors Phi, shape (N, n_basis).
        ridge: Ridge (Tikhonov) weight, >= 0.

    Returns:
        ``(prog, w, cost)``: the program, its (n_basis,) decision variables, and the cost
        binding (linear term zero until set).
    """
    if ridge < 0 or not np.isfinite(ridge):
        raise RepertoireError(f"ridge must be a finite number >= 0, got {ridge}")
    b = features.shape[1]
    prog = MathematicalProgram()
    w = prog.NewContinuousVariables(b, "w")
    H = features.T @ features
    if ridge > 0:
        H = H + ridge * np.eye(b)
    cost = prog.AddQuadraticCost(2.0 * H, np.zeros(b), 0.0, w, is_convex=True)
    return prog, w, cost


def solve_program(prog: MathematicalProgram, what: str = "program", *, solver=None):
    """Solve and check ``is_success()``; raise SolverError naming the solver otherwise.

    Args:
        prog: The program.
        what: Description used in the error message.
        solver: A solver instance to reuse (default: Drake's best choice for ``prog``).
    """
    result = Solve(prog) if solver is None else solver.Solve(prog)
    if not result.is_success():
        raise SolverError(
            f"{what}: solver {result.get_solver_id().name()} failed with "
            f"{result.get_solution_result()}"
        )
    return result


def fit_forcing_weights(features: np.ndarray, targets: np.ndarray, ridge: float = 0.0):
    """Build the forcing fit once and solve it per DOF; returns weights (n_dims, n_basis).

    Args:
        features: Regressors, shape (N, n_basis).
        targets: Targets, shape (N, n_dims).
        ridge: Ridge weight, >= 0.
    """
    prog, w, cost = build_forcing_fit_program(features, ridge)
    Q = cost.evaluator().Q()
    linear = -2.0 * (features.T @ targets)
    constant = np.sum(targets * targets, axis=0)
    solver = MakeSolver(ChooseBestSolver(prog))
    weights = np.empty((targets.shape[1], features.shape[1]))
    for d in range(targets.shape[1]):
        cost.evaluator().UpdateCoefficients(Q, linear[:, d], float(constant[d]), is_convex=True)
        result = solve_program(prog, "DMP forcing-term least squares", solver=solver)
        weights[d] = result.GetSolution(w)
    return weights


def _gains(n: int, K, D) -> tuple[np.ndarray, np.ndarray]:
    Kv = np.broadcast_to(np.asarray(DEFAULT_K if K is None else K, dtype=float), (n,)).copy()
    if np.any(~np.isfinite(Kv)) or np.any(Kv <= 0):
        raise RepertoireError(f"K must be finite and > 0, got {K}")
    Dv = 2.0 * np.sqrt(Kv) if D is None else np.broadcast_to(np.asarray(D, float), (n,)).copy()
    if np.any(~np.isfinite(Dv)) or np.any(Dv < 0):
        raise RepertoireError(f"D must be finite and >= 0, got {D}")
    return Kv, Dv


def _basis(n_basis: int, alpha: float | None, overlap: float) -> tuple:
    n_basis = check_n_basis(n_basis)
    a = DEFAULT_ALPHA if alpha is None else check_positive("alpha", alpha)
    c = basis_centres(n_basis, a)
    return a, c, basis_widths(c, a, overlap)


def _demo_targets(
    t, x, xd, xdd, alpha, Kv, Dv, tau, formulation, centres, widths, min_displacement=1e-9
):
    s = t - t[0]
    theta = canonical_phase(s, tau, alpha)
    x0, g = x[0], x[-1]
    if formulation == "old":
        small = np.abs(g - x0) <= min_displacement
        if small.any():
            raise RepertoireError(
                "the old formulation (eq. 5) divides by g - x0, but start equals goal in DOF "
                f"{np.flatnonzero(small).tolist()}; use formulation='new'"
            )
    F = forcing_target(x, xd, xdd, theta, g, x0, Kv, Dv, tau, formulation)
    return forcing_features(theta, centres, widths), F


def learn_dmp(
    t: np.ndarray,
    x: np.ndarray,
    *,
    n_basis: int = 50,
    K: float | np.ndarray | None = None,
    D: float | np.ndarray | None = None,
    alpha: float | None = None,
    formulation: str = "new",
    ridge: float = 0.0,
    overlap: float = 0.5,
    derivatives: str = "auto",
    window: int | None = None,
    smoothing: float | None = None,
    xd: np.ndarray | None = None,
    xdd: np.ndarray | None = None,
    names: list[str] | None = None,
    min_displacement: float = 1e-9,
) -> DmpParameters:
    """Learn an n-DOF DMP from one demonstration (eq. 5 or 8 + linear least squares).

    ``tau`` is the demonstration's duration, ``x0``/``goal`` its first/last sample.

    Args:
        t: Time stamps [s], strictly increasing (may be non-uniform), shape (N,), N >= 3.
        x: Positions, shape (N, n) or (N,).
        n_basis: Number of basis functions, >= 1.
        K: Spring constant(s); default 156.25.
        D: Damping; default critically damped ``2 sqrt(K)``.
        alpha: Canonical constant; default ``ln(100)`` (theta(tau) = 0.01).
        formulation: ``"new"`` (eq. 6-8) or ``"old"`` (eq. 1-5).
        ridge: Ridge weight of the least squares, >= 0.
        overlap: Basis-function overlap at neighbouring centres.
        derivatives: ``"auto"``, ``"savgol"`` or ``"spline"`` (see estimate_derivatives).
        window: Savitzky-Golay window.
        smoothing: Smoothing-spline lambda.
        xd: Known velocities (skip estimation), shape (N, n).
        xdd: Known accelerations, shape (N, n).
        names: Optional DOF names.
        min_displacement: Old form only: |g - x0| at or below this in any DOF is an error
            (eq. 5 divides by it); 0 allows tiny displacements (to show the blow-up).
    """
    t, x = check_demonstration(t, x)
    if formulation not in FORMULATIONS:
        raise RepertoireError(f"formulation must be one of {FORMULATIONS}, got {formulation!r}")
    n = x.shape[1]
    Kv, Dv = _gains(n, K, D)
    a, c, h = _basis(n_basis, alpha, overlap)
    if xd is None or xdd is None:
        xd_e, xdd_e = estimate_derivatives(
            t, x, method=derivatives, window=window, smoothing=smoothing
        )
        xd = xd_e if xd is None else xd
        xdd = xdd_e if xdd is None else xdd
    xd = np.asarray(xd, float).reshape(x.shape)
    xdd = np.asarray(xdd, float).reshape(x.shape)
    tau = float(t[-1] - t[0])
    Phi, F = _demo_targets(t, x, xd, xdd, a, Kv, Dv, tau, formulation, c, h, min_displacement)
    weights = fit_forcing_weights(Phi, F, ridge)
    return DmpParameters(
        weights, c, h, Kv, Dv, a, tau, x[0], x[-1], formulation, names=list(names or [])
    )


def learn_dmp_from_demonstrations(
    demonstrations: list[tuple[np.ndarray, np.ndarray]],
    *,
    n_basis: int = 50,
    K: float | np.ndarray | None = None,
    D: float | np.ndarray | None = None,
    alpha: float | None = None,
    formulation: str = "new",
    ridge: float = 0.0,
    overlap: float = 0.5,
    derivatives: str = "auto",
    names: list[str] | None = None,
) -> DmpParameters:
    """Learn one DMP from several demonstrations (a joint least-squares fit).

    Each demonstration keeps its own duration (tau), start and goal when its f_target is
    computed; the weights minimise the summed squared error over all of them. The result's
    tau, x0 and goal are the means over the demonstrations.

    Args:
        demonstrations: List of ``(t, x)`` pairs with the same number of DOF.
        n_basis: Number of basis functions.
        K: Spring constant(s).
        D: Damping; default critically damped.
        alpha: Canonical constant.
        formulation: ``"new"`` or ``"old"``.
        ridge: Ridge weight.
        overlap: Basis overlap.
        derivatives: Derivative method.
        names: Optional DOF names.
    """
    if not demonstrations:
        raise RepertoireError("need at least one demonstration, got an empty list")
    demos = [
        check_demonstration(t, x, name=f"demonstration {i}")
        for i, (t, x) in enumerate(demonstrations)
    ]
    n = demos[0][1].shape[1]
    for i, (_, x) in enumerate(demos):
        if x.shape[1] != n:
            raise RepertoireError(
                f"demonstration {i} has {x.shape[1]} DOF, demonstration 0 has {n}"
            )
    Kv, Dv = _gains(n, K, D)
    a, c, h = _basis(n_basis, alpha, overlap)
    feats, targs, taus = [], [], []
    for t, x in demos:
        xd, xdd = estimate_derivatives(t, x, method=derivatives)
        tau = float(t[-1] - t[0])
        Phi, F = _demo_targets(t, x, xd, xdd, a, Kv, Dv, tau, formulation, c, h)
        feats.append(Phi)
        targs.append(F)
        taus.append(tau)
    weights = fit_forcing_weights(np.vstack(feats), np.vstack(targs), ridge)
    x0 = np.mean([x[0] for _, x in demos], axis=0)
    g = np.mean([x[-1] for _, x in demos], axis=0)
    return DmpParameters(
        weights, c, h, Kv, Dv, a, float(np.mean(taus)), x0, g, formulation, names=list(names or [])
    )


def make_quaternions_continuous(q: np.ndarray) -> np.ndarray:
    """Flip signs so consecutive quaternions are on the same hemisphere (q and -q agree).

    Args:
        q: Shape (N, 4).
    """
    q = np.array(q, dtype=float)
    dots = np.sum(q[1:] * q[:-1], axis=1)
    flips = np.cumsum(dots < 0) % 2
    q[1:][flips == 1] *= -1.0
    return q


def learn_quaternion_dmp(
    t: np.ndarray,
    q: np.ndarray,
    *,
    mode: str = "manifold",
    n_basis: int = 50,
    K: float | None = None,
    D: float | None = None,
    alpha: float | None = None,
    ridge: float = 0.0,
    overlap: float = 0.5,
    derivatives: str = "auto",
    unit_tolerance: float = 1e-6,
) -> QuaternionDmpParameters:
    """Learn an orientation DMP from a unit-quaternion demonstration.

    ``mode="component"`` is the paper's approach (sec. IV-B: one transformation system per
    component, post-normalised at the output). ``mode="manifold"`` learns the forcing term
    of ``tau eta' = K e(g,q) - D eta - K e(g,q0) theta + K f`` with ``e = 2 log(g q^*)``
    and ``eta = tau omega``; its rollout keeps |q| = 1 to rounding.

    Args:
        t: Time stamps, shape (N,).
        q: Quaternions (w, x, y, z), shape (N, 4), unit norm within unit_tolerance.
        mode: ``"component"`` or ``"manifold"``.
        n_basis: Number of basis functions.
        K: Spring constant; default 156.25.
        D: Damping; default 2 sqrt(K).
        alpha: Canonical constant.
        ridge: Ridge weight.
        overlap: Basis overlap.
        derivatives: Derivative method.
        unit_tolerance: Allowed deviation of |q| from 1.
    """
    t, q = check_demonstration(t, q, name="quaternion demonstration")
    check_unit_quaternions(q, tolerance=unit_tolerance, name="quaternion demonstration")
    if mode not in QUATERNION_MODES:
        raise RepertoireError(f"mode must be one of {QUATERNION_MODES}, got {mode!r}")
    q = make_quaternions_continuous(q)
    Kv, Dv = _gains(1, K, D)
    if mode == "component":
        p = learn_dmp(
            t,
            q,
            n_basis=n_basis,
            K=Kv[0],
            D=Dv[0],
            alpha=alpha,
            ridge=ridge,
            overlap=overlap,
            derivatives=derivatives,
        )
        return QuaternionDmpParameters(
            p.weights, p.centres, p.widths, Kv[0], Dv[0], p.alpha, p.tau, q[0], q[-1], mode
        )
    a, c, h = _basis(n_basis, alpha, overlap)
    qd, qdd = estimate_derivatives(t, q, method=derivatives)
    omega = angular_velocity(q, qd)
    omegad = 2.0 * quat_multiply(qdd, quat_conjugate(q))[:, 1:]
    tau = float(t[-1] - t[0])
    theta = canonical_phase(t - t[0], tau, a)
    g, q0 = q[-1], q[0]
    F = (
        (tau * tau * omegad + Dv[0] * tau * omega) / Kv[0]
        - quat_error(g, q)
        + quat_error(g, q0)[None] * theta[:, None]
    )
    weights = fit_forcing_weights(forcing_features(theta, c, h), F, ridge)
    return QuaternionDmpParameters(weights, c, h, Kv[0], Dv[0], a, tau, q0, g, mode)


def learn_task_space_dmp(
    t: np.ndarray,
    positions: np.ndarray,
    quaternions: np.ndarray,
    fingers: np.ndarray | None = None,
    *,
    orientation_mode: str = "manifold",
    n_basis: int = 50,
    K: float | None = None,
    alpha: float | None = None,
    ridge: float = 0.0,
) -> TaskSpaceDmp:
    """Learn the paper's 10-D DMP (position + quaternion + fingers) from one demonstration.

    Args:
        t: Time stamps, shape (N,).
        positions: End-effector positions p_WE, shape (N, 3).
        quaternions: End-effector orientations (w, x, y, z), shape (N, 4).
        fingers: Finger positions, shape (N, k), or None.
        orientation_mode: ``"component"`` (paper) or ``"manifold"``.
        n_basis: Number of basis functions.
        K: Spring constant; default 156.25.
        alpha: Canonical constant.
        ridge: Ridge weight.
    """
    positions = np.asarray(positions, float)
    if positions.ndim != 2 or positions.shape[1] != 3:
        raise RepertoireError(f"positions must have shape (N, 3), got {positions.shape}")
    pos = learn_dmp(
        t, positions, n_basis=n_basis, K=K, alpha=alpha, ridge=ridge, names=["x", "y", "z"]
    )
    ori = learn_quaternion_dmp(
        t, quaternions, mode=orientation_mode, n_basis=n_basis, K=K, alpha=alpha, ridge=ridge
    )
    fin = None
    if fingers is not None:
        fin = learn_dmp(t, fingers, n_basis=n_basis, K=K, alpha=alpha, ridge=ridge)
    return TaskSpaceDmp(pos, ori, fin)


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
    Fig. 5 square made of one minimum-jerk primitive.

    Args:
        dmp: A learned DMP (any number of DOF).
        start: Start of the new movement, shape (n,).
        goal: Goal of the new movement, shape (n,).
        dof: Which learned DOF gives the shape.
    """
    start = np.asarray(start, float).reshape(-1)
    goal = np.asarray(goal, float).reshape(-1)
    if start.shape != goal.shape:
        raise RepertoireError(f"start has {start.size} entries, goal {goal.size}")
    if not 0 <= dof < dmp.n_dims:
        raise RepertoireError(f"dof must be in [0, {dmp.n_dims}), got {dof}")
    amplitude = dmp.goal[dof] - dmp.x0[dof]
    if abs(amplitude) < 1e-9:
        raise RepertoireError(
            f"DOF {dof} of the primitive does not move (g - x0 = {amplitude:.3g}); "
            "cannot scale its shape"
        )
    n = start.size
    weights = np.outer((goal - start) / amplitude, dmp.weights[dof])
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
    )
