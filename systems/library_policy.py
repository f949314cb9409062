"""The trajectory-library policy: the nearest step by the sum of foot-position distances.

Stolle et al. (section III): after a step, the robot computes its four foot
positions and, for every library step, the sum of the Euclidean distances
between current and recorded start foot positions; the step with the smallest
sum is taken next. :class:`StepIndex` answers that query exactly: a cKDTree on
the stacked 12-vectors gives a first candidate, and since
``||d||_2 <= sum_f ||d_f|| <= 2 ||d||_2`` for the 12-vector ``d`` split into four
3-vectors, only steps within 12-D distance of the candidate's sum can win; those
are re-ranked by the exact sum. Small libraries are searched brute force (faster
in numpy than the tree's Python overhead).
"""

import dataclasses

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, LeafSystem
from repertoire.planning.step_library import StepLibrary
from scipy.spatial import cKDTree

from repertoire.errors import RepertoireError


@dataclasses.dataclass(frozen=True)
class StepChoice:
    """The policy's choice.

    Attributes:
        index: index of the chosen step in the library (-1: none yet).
        distance: sum of foot-position distances to its start (m).
        time: when the choice was made (s).
    """

    index: int = -1
    distance: float = float("inf")
    time: float = 0.0


def foot_distance_sums(keys: np.ndarray, feet: np.ndarray) -> np.ndarray:
    """Sum over the four feet of Euclidean distances, for each row of ``keys`` (S x 12).

    Args:
        keys: stacked start foot positions (S, 12).
        feet: current foot positions, (12,) or (B, 12).

    Returns:
        (S,) or (B, S) sums (m).
    """
    keys = np.asarray(keys, dtype=float).reshape(-1, 4, 3)
    feet = np.asarray(feet, dtype=float)
    d = feet.reshape(feet.shape[:-1] + (1, 4, 3)) - keys
    return np.sqrt(np.einsum("...k,...k->...", d, d)).sum(-1)


def front_progress(feet, heading: float) -> "np.ndarray | float":
    """How far the hinder of the two front feet (``lf``, ``rf``) is along ``heading``.

    The one test of a crossing: both front feet are past a goal line ``goal`` (m along
    the heading from the world origin) when this is ``>= goal``.

    Args:
        feet: world foot centres, ``LEGS`` order, x y z each: (12,), (4, 3), or rows of
            them (N, 12) / (N, 4, 3).
        heading: the direction (rad).

    Returns:
        ``min`` over the two front feet of their position dotted with the heading's
        unit vector, one per row (a float for one set of feet).
    """
    f = np.asarray(feet, dtype=float)
    lead = f.shape[:-2] if f.shape[-2:] == (4, 3) else f.shape[:-1]
    f = f.reshape(*lead, 4, 3)
    d = np.array([np.cos(heading), np.sin(heading)])
    out = np.minimum(f[..., 0, :2] @ d, f[..., 1, :2] @ d)
    return float(out) if out.ndim == 0 else out


class StepIndex:
    """Exact nearest-step queries on a library's start foot positions.

    Args:
        library: the step library.
        brute_force_below: libraries with fewer steps are searched brute force.
    """

    def __init__(self, library: StepLibrary, brute_force_below: int = 512) -> None:
        if not isinstance(library, StepLibrary):
            raise RepertoireError(f"StepIndex needs a StepLibrary, got {type(library).__name__}")
        if isinstance(brute_force_below, bool) or not (
            isinstance(brute_force_below, int | np.integer) and brute_force_below >= 0
        ):
            raise RepertoireError(
                f"brute_force_below must be an integer >= 0, got {brute_force_below!r}"
            )
        self.keys = np.ascontiguousarray(library.keys)
        self._keys43 = self.keys.reshape(-1, 4, 3)
        self._tree = cKDTree(self.keys) if len(self.keys) >= brute_force_below else None

    def _check(self, feet) -> np.ndarray:
        try:
            feet = np.asarray(feet, dtype=float)
        except (TypeError, ValueError) as e:
            raise RepertoireError(f"feet must be numbers, got {feet!r}: {e}") from e
        if feet.shape[-1:] != (12,) and feet.shape[-2:] != (4, 3):
            raise RepertoireError(f"feet must be (..., 12) or (..., 4, 3), got {feet.shape}")
        feet = feet.reshape(feet.shape[:-2] + (12,)) if feet.shape[-2:] == (4, 3) else feet
        if not np.isfinite(feet).all():
            raise RepertoireError("feet contain NaN or infinite values")
        return feet

    def query(self, feet) -> tuple[int, float]:
        """The nearest step to one set of foot positions: ``(index, distance sum)``."""
        feet = self._check(feet)
        if feet.shape != (12,):
            raise RepertoireError(f"query takes one foot set (12,), got {feet.shape}")
        if self._tree is None:
            d = self._keys43 - feet.reshape(4, 3)
            sums = np.sqrt(np.einsum("sfk,sfk->sf", d, d)).sum(1)
            i = int(sums.argmin())
            return i, float(sums[i])
        _, i0 = self._tree.query(feet)
        bound = float(foot_distance_sums(self.keys[i0 : i0 + 1], feet)[0])
        # Sorted, so that ties go to the lowest index as in the brute-force search.
        near = np.sort(
            np.asarray(self._tree.query_ball_point(feet, bound * (1 + 1e-12)), dtype=int)
        )
        sums = foot_distance_sums(self.keys[near], feet)
        j = int(np.argmin(sums))
        return int(near[j]), float(sums[j])

    def query_batch(self, feet) -> tuple[np.ndarray, np.ndarray]:
        """Nearest steps for B foot sets (B x 12): ``(indices, distance sums)``."""
        feet = np.atleast_2d(self._check(feet))
        if feet.ndim != 2:
            raise RepertoireError(
                f"query_batch takes B foot sets (B, 12) or (B, 4, 3), got {feet.shape}"
            )
        out_i = np.empty(len(feet), dtype=int)
        out_d = np.empty(len(feet))
        chunk = max(1, 100_000 // max(len(self.keys), 1))
        for a in range(0, len(feet), chunk):
            sums = foot_distance_sums(self.keys, feet[a : a + chunk])
            out_i[a : a + chunk] = np.argmin(sums, axis=1)
            out_d[a : a + chunk] = sums[np.arange(len(sums)), out_i[a : a + chunk]]
        return out_i, out_d


class LibraryPolicy(LeafSystem):
    """Chooses the nearest library step whenever all four feet are down.

    The choice is discrete state, updated every ``period``: when all four
    contact flags are set, the step nearest to the measured foot positions is
    chosen; otherwise the previous choice is kept. With a ``goal_line``, the
    policy stops choosing once both front feet (``lf``, ``rf``) are past it, the
    test :func:`~repertoire.diagrams.littledog_library.crossing_figures` counts a
    crossing by: the step under way ends and the robot holds its last stance
    (:class:`~repertoire.systems.step_executor.StepExecutor` starts a step only
    on a fresh choice). Without one, a robot past the library's last step keeps
    replaying the step nearest to where it stands, for as long as it is simulated.

    Input ports:
        feet: measured world foot centres (12: ``LEGS`` order, x y z each).
        contact: 4 contact flags (nonzero = down).

    Output ports:
        choice: the current :class:`StepChoice` (abstract).
    """

    def __init__(
        self,
        library: StepLibrary,
        period: float = 0.01,
        goal_line: "tuple[float, float] | None" = None,
    ) -> None:
        """Creates the system.

        Args:
        library: the step library (at least one step).
        period: update period (s).
        goal_line: ``(heading, goal)``: the crossing direction (rad) and the goal
            line's distance along it from the world origin (m); None: no goal.
        """
        super().__init__()
        if not (np.isfinite(period) and period > 0.0):
            raise RepertoireError(f"period must be > 0 s, got {period}")
        self._goal = None
        if goal_line is not None:
            try:
                heading, goal = (float(v) for v in goal_line)
            except (TypeError, ValueError):
                raise RepertoireError(
                    f"goal_line must be (heading rad, goal m), got {goal_line!r}"
                ) from None
            if not (np.isfinite(heading) and np.isfinite(goal)):
                raise RepertoireError(f"goal_line must be finite, got {goal_line!r}")
            self._goal = (heading, goal)
        self.index = StepIndex(library)
        self.feet_input = self.DeclareVectorInputPort("feet", 12)
        self.contact_input = self.DeclareVectorInputPort("contact", 4)
        self._choice = self.DeclareAbstractState(AbstractValue.Make(StepChoice()))
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, 0.0, self._update)
        self.choice_output = self.DeclareStateOutputPort("choice", self._choice)

    def _update(self, context: Context, state) -> None:
        contact = self.contact_input.Eval(context)
        if not np.isfinite(contact).all():  # NaN != 0 would read as "down"
            raise RepertoireError(f"LibraryPolicy contact flags must be finite, got {contact}")
        if not np.all(contact != 0):
            return
        feet = self.feet_input.Eval(context)
        if self.past_goal(feet):
            return
        i, d = self.index.query(feet)
        state.get_mutable_abstract_state(int(self._choice)).set_value(
            StepChoice(i, d, context.get_time())
        )

    def past_goal(self, feet) -> bool:
        """Whether both front feet of ``feet`` (12, ``LEGS`` order) are past the goal line."""
        if self._goal is None:
            return False
        heading, goal = self._goal
        return bool(front_progress(feet, heading) >= goal)


__all__ = ["LibraryPolicy", "StepChoice", "StepIndex", "foot_distance_sums", "front_progress"]
