"""The biped's footstep actions: robot constants, nominal and example tables, pose algebra.

The robot is ASIMO-like: 1.2 m tall, feet 0.16 m x 0.10 m, nominal stance width 0.19 m
(distance between the sole centres). Seven actions per foot, named in :data:`ACTIONS`.
"""

import dataclasses
import math

import numpy as np
from repertoire.planning.footstep.types import ActionTable, Foot, FootstepError, wrap_angle

from repertoire.checks import is_real


@dataclasses.dataclass(frozen=True)
class BipedGeometry:
    """Geometry of the planned biped.

    Attributes:
        foot_length: sole length along the foot's x axis (m).
        foot_width: sole width along the foot's y axis (m).
        stance_width: nominal lateral distance between the sole centres (m).
        body_radius: radius of the bounding circle of the whole robot seen from above (m),
            used by the 2-D mobile-robot planner.
    """

    foot_length: float = 0.16
    foot_width: float = 0.10
    stance_width: float = 0.19
    body_radius: float = 0.30

    def __post_init__(self) -> None:
        """Refuses sizes that are not numbers, not finite, or not positive (naming the field).

        Raises:
            FootstepError: a foot length or width not finite and > 0, a stance width or
                body radius not finite and >= 0.
        """
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            least = "> 0" if f.name.startswith("foot_") else ">= 0"
            ok = is_real(v) and math.isfinite(v)
            if not ok or v < 0.0 or (v == 0.0 and least == "> 0"):
                raise FootstepError(
                    f"BipedGeometry {f.name} must be finite and {least} m, got {v!r}"
                )


ASIMO_LIKE = BipedGeometry()

#: The seven actions (same for both feet), index order of every table.
ACTIONS: list[str] = [
    "forward_long",
    "forward_medium",
    "forward_short",
    "side_step",
    "turn_left",
    "turn_right",
    "stop",
]
#: Left/right mirror pairs (other actions mirror to themselves).
MIRROR: dict[str, str] = {"turn_left": "turn_right", "turn_right": "turn_left"}
#: Default step costs (a long step is the cheapest way to make progress).
STEP_COST: dict[str, float] = {
    "forward_long": 1.0,
    "forward_medium": 1.05,
    "forward_short": 1.1,
    "side_step": 1.3,
    "turn_left": 1.2,
    "turn_right": 1.2,
    "stop": 1.2,
}
TURN_ANGLE = 0.35  # rad per turning step
STEP_DURATION = 0.8  # s


def commanded_displacement(
    action: str, stance: Foot, geometry: BipedGeometry = ASIMO_LIKE
) -> tuple[float, float, float]:
    """The commanded landing pose of the swing foot in the stance foot's frame.

    Args:
        action: one of :data:`ACTIONS`.
        stance: the stance foot (the swing foot is the other one).
        geometry: robot geometry (stance width).

    Returns:
        ``(dx, dy, dyaw)``.
    """
    s = 1.0 if Foot(stance) == Foot.RIGHT else -1.0  # +1: the swing foot is the left one
    w = geometry.stance_width
    forward = {"forward_long": 0.30, "forward_medium": 0.20, "forward_short": 0.10}
    if action in forward:
        return forward[action], s * w, 0.0
    if action == "side_step":
        return 0.0, s * (w + 0.10), 0.0
    if action == "stop":
        return 0.0, s * w, 0.0
    if action in ("turn_left", "turn_right"):
        th = TURN_ANGLE if action == "turn_left" else -TURN_ANGLE
        # Rotate the swing foot's nominal place about the midpoint between the feet and
        # move 5 cm forward.
        mx, my = 0.0, s * w / 2.0
        return 0.05 + mx - math.sin(th) * s * w / 2.0, my + math.cos(th) * s * w / 2.0, th
    raise ValueError(f"unknown action {action!r}; expected one of {ACTIONS}")


def nominal_action_table(
    geometry: BipedGeometry = ASIMO_LIKE, *, step_duration: float = STEP_DURATION
) -> ActionTable:
    """The table of commanded displacements, the same for every history.

    Args:
        geometry: robot geometry.
        step_duration: seconds per step.
    """
    n = len(ACTIONS)
    disp = np.zeros((n, n, 2, n, 3))
    for f in (Foot.LEFT, Foot.RIGHT):
        for a, name in enumerate(ACTIONS):
            disp[:, :, int(f), a] = commanded_displacement(name, f, geometry)
    return ActionTable(
        actions=list(ACTIONS),
        displacement=disp,
        duration=np.full((n, n, 2, n), step_duration),
        step_cost=np.array([STEP_COST[a] for a in ACTIONS]),
        rest_action="stop",
        mirror=dict(MIRROR),
    )


def state_dependent_example_table(geometry: BipedGeometry = ASIMO_LIKE) -> ActionTable:
    """A synthetic history-dependent table in the spirit of the paper's Fig. 2.

    Not measured: it only makes the state dependence visible before a measured table
    exists. From standing (previous action ``stop``) forward steps are 60 % as long and
    take 0.2 s longer; a ``stop`` after a long or medium forward step still moves 40 % of
    that step forward (the robot slows down over one more small step).

    Args:
        geometry: robot geometry.
    """
    table = nominal_action_table(geometry)
    disp = table.displacement.copy()
    dur = table.duration.copy()
    i = {a: k for k, a in enumerate(ACTIONS)}
    stop = i["stop"]
    for name in ("forward_long", "forward_medium", "forward_short"):
        a = i[name]
        disp[:, stop, :, a, 0] *= 0.6
        dur[:, stop, :, a] += 0.2
    for name in ("forward_long", "forward_medium"):
        prev = i[name]
        for f in (0, 1):
            disp[:, prev, f, stop, 0] = 0.4 * table.displacement[0, 0, f, prev, 0]
    return dataclasses.replace(table, displacement=disp, duration=dur)


def apply_displacement(
    pose: "tuple[float, float, float] | np.ndarray", d: "tuple[float, float, float] | np.ndarray"
) -> tuple[float, float, float]:
    """Compose a stance pose with a displacement expressed in its frame.

    Args:
        pose: ``(x, y, yaw)`` of the stance foot in the world.
        d: ``(dx, dy, dyaw)`` in the stance foot's frame.

    Returns:
        the world pose ``(x, y, yaw)`` of the landed foot (yaw wrapped to [-pi, pi)).
    """
    x, y, th = (float(v) for v in pose)
    c, s = math.cos(th), math.sin(th)
    return x + c * d[0] - s * d[1], y + s * d[0] + c * d[1], wrap_angle(th + d[2])


def relative_displacement(
    stance: "tuple[float, float, float] | np.ndarray",
    landed: "tuple[float, float, float] | np.ndarray",
) -> tuple[float, float, float]:
    """Inverse of :func:`apply_displacement`: ``landed`` in the frame of ``stance``.

    Args:
        stance: world pose of the stance foot.
        landed: world pose of the landed foot.
    """
    x, y, th = (float(v) for v in stance)
    c, s = math.cos(th), math.sin(th)
    ex, ey = float(landed[0]) - x, float(landed[1]) - y
    return c * ex + s * ey, -s * ex + c * ey, wrap_angle(float(landed[2]) - th)


def history_classes(table: ActionTable) -> np.ndarray:
    """Merge histories ``(a_prev2, a_prev1)`` whose futures are identical under T.

    Two histories are equivalent when they give the same displacements and durations for
    every foot and action, and the histories they lead to after any action are equivalent
    again (partition refinement, as in DFA minimisation). States that differ only by
    equivalent histories are merged by the search without changing any plan's cost.

    Args:
        table: the action table.

    Returns:
        (n, n) int array: class id of each history.
    """
    n = table.n
    sig: dict[bytes, int] = {}
    cls = np.zeros((n, n), dtype=int)
    for i2 in range(n):
        for i1 in range(n):
            b = table.displacement[i2, i1].tobytes() + table.duration[i2, i1].tobytes()
            cls[i2, i1] = sig.setdefault(b, len(sig))
    while True:
        sig2: dict[tuple, int] = {}
        new = np.zeros_like(cls)
        for i2 in range(n):
            for i1 in range(n):
                key = (int(cls[i2, i1]), *(int(cls[i1, a]) for a in range(n)))
                new[i2, i1] = sig2.setdefault(key, len(sig2))
        if len(sig2) == len(np.unique(cls)):
            return new
        cls = new


def swing_start_classes(table: ActionTable, hist: np.ndarray) -> np.ndarray:
    """History classes split by where the swing foot lifts from, relative to the stance foot.

    After ``a_prev1`` the swing foot stands where it stood before that step: in the stance
    foot's frame at ``-R(-dyaw) (dx, dy)``, with ``(dx, dy, dyaw)`` the step's entry
    ``T(a_prev3, a_prev2, swing foot, a_prev1)``. Where swings are checked against tall
    cells that point decides which landings pass, so two states on one lattice cell whose
    swing feet stand apart must not be merged (with one class per history, as for the
    nominal table, the cheaper arrival's swing foot hides the other's landings: on 1.4 m
    maps of thin 0.3 m posts, at 2.5 cm / 72 bins, the admissible mode's plan cost up to
    31 % more than with this split, and 7 of 388 maps were UNREACHABLE with a plan
    here). Histories are split by their class in ``hist`` and the entries over
    ``a_prev3``: one entry (a table whose entries do not depend on their first history
    index), so states with one class have one swing start.

    Args:
        table: the action table.
        hist: ``(n, n)`` history classes (:func:`history_classes`).

    Returns:
        (n, n) int array: the finer class of each history ``(a_prev2, a_prev1)``.
    """
    n = table.n
    sig: dict[tuple, int] = {}
    out = np.zeros((n, n), dtype=int)
    for a2 in range(n):
        for a1 in range(n):
            entries = np.unique(table.displacement[:, a2, :, a1].reshape(n, -1), axis=0)
            out[a2, a1] = sig.setdefault((int(hist[a2, a1]), entries.tobytes()), len(sig))
    return out
