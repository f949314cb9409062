"""Typed artefacts of the footstep planner: feet, action tables, plans.

Conventions (shared with the walking controller that executes plans):

* A foot pose is ``(x, y, yaw)`` of the sole centre in the world frame W, yaw about +z.
* ``Foot.LEFT == 0`` and ``Foot.RIGHT == 1``.
* An action table entry ``T(a_prev2, a_prev1, foot, a)`` is the pose of the foot that
  lands (the swing foot, i.e. the other foot than ``foot``) expressed in the frame of the
  current stance foot ``foot``: ``(dx, dy, dyaw)``; plus the step's duration in seconds,
  from the moment the command ``a`` is given to the landing of the swing foot.
* The history of a robot standing still is ``(rest_action, rest_action)``.
"""

import dataclasses
import enum
import json
import math
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np

from repertoire.checks import is_real, is_whole
from repertoire.errors import RepertoireError


class FootstepError(RepertoireError):
    """Bad input to the footstep planner (start, goal, table, environment, limits)."""


class ActionTableError(FootstepError):
    """An action table is malformed: missing entries, non-finite values, bad shapes."""


class GridError(FootstepError):
    """An environment is malformed (resolution mismatch, no grid near a time...)."""


class Foot(enum.IntEnum):
    """Which foot: LEFT = 0, RIGHT = 1."""

    LEFT = 0
    RIGHT = 1

    def other(self) -> "Foot":
        return Foot(1 - int(self))


def parse_foot(value: "Foot | int | str") -> Foot:
    """Return a :class:`Foot` from ``Foot``, 0/1, or ``"left"``/``"right"``.

    Args:
        value: the foot, in any of the accepted spellings.
    """
    if isinstance(value, str):
        key = value.strip().lower()
        if key in ("left", "l"):
            return Foot.LEFT
        if key in ("right", "r"):
            return Foot.RIGHT
        raise FootstepError(f"unknown foot {value!r}; expected 'left' or 'right' (or 0/1)")
    if not is_real(value) or value not in (0, 1):
        raise FootstepError(f"unknown foot {value!r}; expected 0 (left) or 1 (right)")
    return Foot(int(value))


class PlanStatus(str, enum.Enum):  # noqa: UP042 (str mix-in keeps Python 3.10 support)
    """Outcome of a planner call."""

    SUCCESS = "SUCCESS"  # the plan reaches the goal region
    TIME_LIMIT = "TIME_LIMIT"  # time ran out; the plan is the best partial plan
    UNREACHABLE = "UNREACHABLE"  # open list exhausted; the plan is the best partial plan
    NODE_LIMIT = "NODE_LIMIT"  # max_expansions reached; the plan is the best partial plan


def wrap_angle(a: float) -> float:
    """Wrap an angle to [-pi, pi)."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def _read_json(path: Path, error: type[Exception]) -> dict:
    """The JSON object in ``path``; ``error`` names the file when it is missing or not JSON."""
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise error(f"file {path} does not exist") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise error(f"{path} is not valid JSON: {exc}") from None
    if not isinstance(data, dict):
        raise error(f"{path} must hold a JSON object, got {type(data).__name__}")
    return data


def _mirror_dict(mirror: object) -> dict[str, str]:
    """A table file's ``mirror`` as a name -> name dict; errors name the value."""
    if not isinstance(mirror, dict):
        raise ActionTableError(f"mirror must be a dict of name -> name, got {mirror!r}")
    return {str(k): str(v) for k, v in mirror.items()}


@dataclasses.dataclass
class ActionTable:
    """The state-dependent displacement table T and the step durations.

    Attributes:
        actions: names of the n actions, index order of every axis.
        displacement: array (n, n, 2, n, 3): ``[a_prev2, a_prev1, foot, a] -> (dx, dy, dyaw)``
            of the landing foot in the frame of the stance foot ``foot``.
        duration: array (n, n, 2, n): seconds per step, same indexing.
        step_cost: array (n,): cost of commanding each action (positive).
        rest_action: name of the action whose repetition means standing still; the
            history at the start of a plan is ``(rest_action, rest_action)``.
        mirror: name -> name of the mirror action (left/right swapped), used when
            building a table from samples measured with one foot only.
    """

    actions: list[str]
    displacement: np.ndarray
    duration: np.ndarray
    step_cost: np.ndarray
    rest_action: str
    mirror: dict[str, str] = dataclasses.field(default_factory=dict)

    def __post_init__(self) -> None:
        for name in ("displacement", "duration", "step_cost"):
            try:
                setattr(self, name, np.asarray(getattr(self, name), dtype=float))
            except (TypeError, ValueError):
                raise ActionTableError(
                    f"{name} must be an array of numbers (ragged or non-numeric: missing "
                    f"entries?), got {getattr(self, name)!r}"[:300]
                ) from None
        if isinstance(self.actions, str) or not isinstance(self.actions, Sequence):
            raise ActionTableError(f"actions must be a list of names, got {self.actions!r}")
        if not isinstance(self.mirror, dict):
            raise ActionTableError(f"mirror must be a dict of name -> name, got {self.mirror!r}")
        self.validate()

    @property
    def n(self) -> int:
        return len(self.actions)

    def index(self, name: "str | int") -> int:
        """Index of an action given by name (or already an index).

        Args:
            name: action name or index.
        """
        if is_whole(name):
            if not 0 <= int(name) < self.n:
                raise ActionTableError(f"action index {name} out of range 0..{self.n - 1}")
            return int(name)
        try:
            return self.actions.index(str(name))
        except ValueError:
            raise ActionTableError(
                f"unknown action {name!r}; the table has {self.actions}"
            ) from None

    def validate(self) -> None:
        """Raise :class:`ActionTableError` unless the table is complete and finite."""
        n = len(self.actions)
        if n == 0:
            raise ActionTableError("an action table needs at least one action")
        if len(set(self.actions)) != n:
            raise ActionTableError(f"action names must be unique, got {self.actions}")
        if self.displacement.shape != (n, n, 2, n, 3):
            raise ActionTableError(
                f"displacement must have shape {(n, n, 2, n, 3)} "
                f"(a_prev2, a_prev1, foot, a, xyz), got {self.displacement.shape}"
            )
        if self.duration.shape != (n, n, 2, n):
            raise ActionTableError(
                f"duration must have shape {(n, n, 2, n)}, got {self.duration.shape}"
            )
        if self.step_cost.shape != (n,):
            raise ActionTableError(f"step_cost must have shape ({n},), got {self.step_cost.shape}")
        for label, arr in (("displacement", self.displacement), ("duration", self.duration)):
            bad = ~np.isfinite(arr)
            if bad.any():
                idx = np.argwhere(bad)[0]
                key = self._key_text(idx)
                raise ActionTableError(
                    f"{label} has {int(bad.sum())} missing or non-finite entries, first at {key}; "
                    "every (a_prev2, a_prev1, foot, a) needs a finite value"
                )
        if (self.duration <= 0).any():
            idx = np.argwhere(self.duration <= 0)[0]
            raise ActionTableError(
                f"durations must be positive, got {self.duration[tuple(idx)]} "
                f"at {self._key_text(idx)}"
            )
        if not np.all(np.isfinite(self.step_cost)) or (self.step_cost <= 0).any():
            raise ActionTableError(f"step costs must be finite and positive, got {self.step_cost}")
        if self.rest_action not in self.actions:
            raise ActionTableError(
                f"rest_action {self.rest_action!r} is not one of the actions {self.actions}"
            )
        for a, b in self.mirror.items():
            if a not in self.actions or b not in self.actions:
                raise ActionTableError(f"mirror pair {a!r} -> {b!r} names an unknown action")

    def _key_text(self, idx: Sequence[int]) -> str:
        names = [self.actions[int(i)] for i in idx[:2]]
        text = f"(a_prev2={names[0]}, a_prev1={names[1]}, foot={Foot(int(idx[2])).name}"
        if len(idx) > 3:
            text += f", a={self.actions[int(idx[3])]}"
        return text + ")"

    def lookup(
        self, a_prev2: "str | int", a_prev1: "str | int", foot: "Foot | int | str", a: "str | int"
    ) -> tuple[float, float, float, float]:
        """Return ``(dx, dy, dyaw, duration)`` for one entry.

        Args:
            a_prev2: the action commanded two steps before.
            a_prev1: the previous action.
            foot: the current stance foot.
            a: the action to command.
        """
        key = (self.index(a_prev2), self.index(a_prev1), int(parse_foot(foot)), self.index(a))
        dx, dy, dyaw = self.displacement[key]
        return float(dx), float(dy), float(dyaw), float(self.duration[key])

    def max_reach(self) -> float:
        """Largest translation of any entry (m): bounds the progress of one step."""
        return float(np.max(np.hypot(self.displacement[..., 0], self.displacement[..., 1])))

    # ------------------------------------------------------------------ I/O
    def to_dict(self) -> dict:
        return {
            "format": "repertoire.footstep.ActionTable/1",
            "actions": list(self.actions),
            "rest_action": self.rest_action,
            "mirror": dict(self.mirror),
            "step_cost": self.step_cost.tolist(),
            "displacement": self.displacement.tolist(),
            "duration": self.duration.tolist(),
        }

    @classmethod
    def from_dict(cls, data: dict) -> "ActionTable":
        """Build from :meth:`to_dict` output (validated).

        Args:
            data: the dictionary.
        """
        required = ("actions", "rest_action", "step_cost", "displacement", "duration")
        missing = [k for k in required if k not in data]
        if missing:
            raise ActionTableError(f"action table data lacks keys {missing}")
        try:
            disp = np.array(data["displacement"], dtype=float)
            dur = np.array(data["duration"], dtype=float)
            cost = np.array(data["step_cost"], dtype=float)
        except (TypeError, ValueError) as exc:
            raise ActionTableError(
                f"action table arrays are ragged or non-numeric (missing entries?): {exc}"
            ) from None
        if isinstance(data["actions"], str) or not isinstance(data["actions"], list):
            raise ActionTableError(f"actions must be a list of names, got {data['actions']!r}")
        return cls(
            actions=[str(a) for a in data["actions"]],
            displacement=disp,
            duration=dur,
            step_cost=cost,
            rest_action=str(data["rest_action"]),
            mirror=_mirror_dict(data.get("mirror", {})),
        )

    def save(self, path: "str | Path") -> Path:
        """Save as JSON (``.json``) or numpy ``.npz``.

        Args:
            path: destination file; the suffix picks the format.
        """
        path = Path(path)
        if path.suffix == ".npz":
            np.savez(
                path,
                actions=np.array(self.actions),
                rest_action=np.array(self.rest_action),
                mirror=np.array(json.dumps(self.mirror)),
                step_cost=self.step_cost,
                displacement=self.displacement,
                duration=self.duration,
            )
        elif path.suffix == ".json":
            path.write_text(json.dumps(self.to_dict(), indent=1))
        else:
            raise ActionTableError(
                f"unknown action table format {path.suffix!r}; use .json or .npz"
            )
        return path

    @classmethod
    def load(cls, path: "str | Path") -> "ActionTable":
        """Load a table written by :meth:`save` (validated).

        Args:
            path: a ``.json`` or ``.npz`` file.
        """
        path = Path(path)
        if not path.exists():
            raise ActionTableError(f"action table file {path} does not exist")
        if path.suffix == ".npz":
            with np.load(path, allow_pickle=False) as z:
                return cls(
                    actions=[str(a) for a in z["actions"]],
                    rest_action=str(z["rest_action"]),
                    mirror=json.loads(str(z["mirror"])),
                    step_cost=z["step_cost"],
                    displacement=z["displacement"],
                    duration=z["duration"],
                )
        if path.suffix == ".json":
            return cls.from_dict(_read_json(path, ActionTableError))
        raise ActionTableError(f"unknown action table format {path.suffix!r}; use .json or .npz")

    @classmethod
    def from_samples(
        cls,
        samples: Iterable[Sequence],
        *,
        actions: Sequence[str],
        rest_action: str,
        step_cost: "Sequence[float] | np.ndarray",
        mirror: "dict[str, str] | None" = None,
        fill_missing_foot_by_mirror: bool = True,
    ) -> "ActionTable":
        """Build a table from measured steps (Chestnutt et al.: T(a-2, a-1, l, a) from data).

        Each sample is ``(a_prev2, a_prev1, foot, a, dx, dy, dyaw, duration)``: actions by
        name or index, ``foot`` the stance foot when ``a`` was commanded (``"left"``,
        ``"right"``, 0 or 1), ``(dx, dy, dyaw)`` the landed swing-foot pose in the stance
        foot's frame, ``duration`` the step time in seconds. Several samples of one key are
        averaged (yaw by circular mean). If ``fill_missing_foot_by_mirror``, a key measured
        for one foot only is filled for the other foot by mirroring (dy -> -dy,
        dyaw -> -dyaw, every action replaced by its ``mirror`` partner).

        Args:
            samples: the measured steps.
            actions: names of the actions (index order).
            rest_action: the action whose repetition means standing still.
            step_cost: cost per action.
            mirror: action -> mirrored action (actions not listed mirror to themselves).
            fill_missing_foot_by_mirror: fill keys missing for one foot from the other.
        """
        actions = [str(a) for a in actions]
        n = len(actions)
        mirror = dict(mirror or {})
        sums = np.zeros((n, n, 2, n, 5))  # dx, dy, cos, sin, duration
        counts = np.zeros((n, n, 2, n), dtype=int)

        def idx(a: "str | int") -> int:
            if is_whole(a):
                if not 0 <= int(a) < n:
                    raise ActionTableError(f"sample action index {a} out of range 0..{n - 1}")
                return int(a)
            if str(a) not in actions:
                raise ActionTableError(f"sample names unknown action {a!r}; known: {actions}")
            return actions.index(str(a))

        for k, s in enumerate(samples):
            if len(s) != 8:
                raise ActionTableError(
                    f"sample {k} has {len(s)} fields; expected (a_prev2, a_prev1, foot, a, "
                    "dx, dy, dyaw, duration)"
                )
            vals = np.array([float(v) for v in s[4:]])
            if not np.all(np.isfinite(vals)):
                raise ActionTableError(f"sample {k} has non-finite values {vals.tolist()}")
            key = (idx(s[0]), idx(s[1]), int(parse_foot(s[2])), idx(s[3]))
            dx, dy, dyaw, dur = vals
            sums[key] += (dx, dy, math.cos(dyaw), math.sin(dyaw), dur)
            counts[key] += 1
        if fill_missing_foot_by_mirror:
            m = [actions.index(mirror.get(a, a)) for a in actions]
            for i in range(n):
                for j in range(n):
                    for f in (0, 1):
                        for a in range(n):
                            if counts[i, j, f, a] == 0:
                                src = (m[i], m[j], 1 - f, m[a])
                                if counts[src] > 0:
                                    dx, dy, c, s_, dur = sums[src]
                                    sums[i, j, f, a] = (dx, -dy, c, -s_, dur)
                                    counts[i, j, f, a] = counts[src]
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = sums / counts[..., None]
        disp = np.stack(
            [mean[..., 0], mean[..., 1], np.arctan2(mean[..., 3], mean[..., 2])], axis=-1
        )
        disp[counts == 0] = np.nan
        dur = mean[..., 4]
        dur[counts == 0] = np.nan
        return cls(
            actions=actions,
            displacement=disp,
            duration=dur,
            step_cost=np.asarray(step_cost, dtype=float),
            rest_action=rest_action,
            mirror=mirror,
        )


@dataclasses.dataclass
class FootstepPlan:
    """A footstep plan: the stance foot poses in order and the actions between them.

    ``poses[0]`` is the stance foot at the start (``feet[0]``); step ``k`` (1..N) is
    commanded with ``actions[k-1]`` at ``times[k-1]`` and lands the other foot at
    ``poses[k]`` at ``times[k]``. ``initial_swing_pose`` is where the first swing foot
    stands at the start.

    Attributes:
        poses: (N+1) x 3 list of ``[x, y, yaw]``.
        feet: N+1 foot indices (0 left, 1 right): ``feet[k]`` stands at ``poses[k]``.
        actions: N action names.
        times: N+1 times (s): ``times[k]`` is when ``poses[k]`` becomes the stance foot.
        status: SUCCESS, or TIME_LIMIT / UNREACHABLE / NODE_LIMIT with the best partial plan.
        cost: accumulated location + step cost of the plan.
        cost_to_go: heuristic estimate left at the last pose (0 means at the goal).
        nodes_expanded: nodes taken from the open list.
        nodes_generated: successor states evaluated.
        planning_time_s: wall time of the search including the heuristic precomputation.
        initial_swing_pose: ``[x, y, yaw]`` of the other foot at the start.
        goal: ``[x, y]`` of the goal (stance foot within ``goal_tolerance``).
        goal_tolerance: radius of the goal region (m).
        initial_history: the two actions before the plan's first action.
        xy_resolution: lattice spacing (m) of the search that produced the plan (0: not
            from a search).
        yaw_bins: yaw bins per turn of that search (0: not from a search).
        reason: why a plan that is not SUCCESS stops short, where the planner can tell (a
            dynamic world's start foot hit before the first step lands, landings past the
            environment's last grid); "" otherwise.
    """

    poses: list[list[float]]
    feet: list[int]
    actions: list[str]
    times: list[float]
    status: PlanStatus
    cost: float
    cost_to_go: float
    nodes_expanded: int
    nodes_generated: int
    planning_time_s: float
    initial_swing_pose: list[float]
    goal: list[float]
    goal_tolerance: float
    initial_history: list[str]
    xy_resolution: float = 0.0
    yaw_bins: int = 0
    reason: str = ""

    def __post_init__(self) -> None:
        """Checks the plan's shape and values: a bad plan is refused where it is made.

        Raises:
            FootstepError: lengths that do not match the actions, poses that are not
                finite ``[x, y, yaw]`` rows, times that are not finite, feet that are not
                0 or 1 or that do not alternate from step to step.
        """
        self.status = PlanStatus(self.status)
        n = len(self.actions)
        if len(self.poses) != n + 1 or len(self.feet) != n + 1 or len(self.times) != n + 1:
            raise FootstepError(
                f"a plan with {n} actions needs {n + 1} poses, feet and times; got "
                f"{len(self.poses)}, {len(self.feet)}, {len(self.times)}"
            )
        for name in ("poses", "initial_swing_pose"):
            try:
                value = np.asarray(getattr(self, name), dtype=float)
            except (TypeError, ValueError):
                raise FootstepError(
                    f"plan {name} must be numbers [x, y, yaw], got {getattr(self, name)!r}"
                ) from None
            shape = (n + 1, 3) if name == "poses" else (3,)
            if value.shape != shape or not np.isfinite(value).all():
                raise FootstepError(
                    f"plan {name} must be finite [x, y, yaw] of shape {shape}, got "
                    f"{getattr(self, name)!r}"
                )
        try:
            times = np.asarray(self.times, dtype=float)
        except (TypeError, ValueError):
            raise FootstepError(f"plan times must be numbers, got {self.times!r}") from None
        if not np.isfinite(times).all():
            raise FootstepError(f"plan times must be finite, got {self.times}")
        for k, foot in enumerate(self.feet):
            if isinstance(foot, bool) or foot not in (0, 1):
                raise FootstepError(f"plan feet must be 0 (left) or 1 (right), got {foot!r} at {k}")
            if k and foot == self.feet[k - 1]:
                raise FootstepError(
                    f"plan feet must alternate from step to step, got {self.feet[k - 1]} then "
                    f"{foot} at poses {k - 1} and {k}"
                )

    @property
    def num_steps(self) -> int:
        return len(self.actions)

    @property
    def succeeded(self) -> bool:
        return self.status is PlanStatus.SUCCESS

    @property
    def duration(self) -> float:
        return float(self.times[-1] - self.times[0])

    def poses_array(self) -> np.ndarray:
        return np.asarray(self.poses, dtype=float).reshape(-1, 3)

    @classmethod
    def from_commands(
        cls,
        poses: list[list[float]],
        feet: list[int],
        actions: list[str],
        times: list[float],
        initial_swing_pose: list[float],
        initial_history: list[str],
        *,
        goal: list[float] | None = None,
        goal_tolerance: float = 0.1,
    ) -> "FootstepPlan":
        """A plan given as commands rather than found by a search.

        Its status is SUCCESS and its cost, cost-to-go and search figures are zero.

        Args:
            poses: (N+1) stance poses ``[x, y, yaw]``.
            feet: N+1 foot indices.
            actions: N action names.
            times: N+1 times (s).
            initial_swing_pose: the other foot at the start.
            initial_history: the two actions before the first one.
            goal: ``[x, y]``; default the last pose's position.
            goal_tolerance: radius of the goal region (m).
        """
        return cls(
            poses=poses,
            feet=feet,
            actions=actions,
            times=times,
            status="SUCCESS",
            cost=0.0,
            cost_to_go=0.0,
            nodes_expanded=0,
            nodes_generated=0,
            planning_time_s=0.0,
            initial_swing_pose=initial_swing_pose,
            goal=list(poses[-1][:2]) if goal is None else goal,
            goal_tolerance=goal_tolerance,
            initial_history=initial_history,
        )

    def to_dict(self) -> dict:
        d = dataclasses.asdict(self)
        d["status"] = self.status.value
        d["format"] = "repertoire.footstep.FootstepPlan/1"
        return d

    @classmethod
    def from_dict(cls, data: dict) -> "FootstepPlan":
        """Rebuild a plan from :meth:`to_dict` output.

        Args:
            data: the dictionary.
        """
        fields = {f.name for f in dataclasses.fields(cls)}
        optional = {"reason"}  # plans saved before it was a field
        missing = fields - set(data) - optional
        if missing:
            raise FootstepError(f"plan data lacks keys {sorted(missing)}")
        if data["status"] not in [s.value for s in PlanStatus]:
            raise FootstepError(
                f"plan status {data['status']!r} is not one of {[s.value for s in PlanStatus]}"
            )
        return cls(**{k: data[k] for k in fields if k in data})

    def save(self, path: "str | Path") -> Path:
        """Write the plan as JSON.

        Args:
            path: destination ``.json`` file.
        """
        path = Path(path)
        path.write_text(json.dumps(self.to_dict(), indent=1))
        return path

    @classmethod
    def load(cls, path: "str | Path") -> "FootstepPlan":
        """Read a plan written by :meth:`save`.

        Args:
            path: a ``.json`` file.
        """
        return cls.from_dict(_read_json(Path(path), FootstepError))
