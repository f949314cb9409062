"""Motion library: labelled DMPs with context, task composition, grasp orientation (sec. III, IV-C).

A :class:`MotionLibrary` stores learned DMPs as :class:`MotionPrimitive`s with a semantic
label (grasp, place, release, pour, retreat) and a context (object, approach side, ...).
Tasks are sequences of labels (pick-and-place = grasp -> place -> release); a library
composes a task by recalling one primitive per label. Section IV-C's automatic final grasp
orientation propagates the DMP to the new goal, averages the velocity over the end of the
movement to get the approach direction, and turns the demonstrated final orientation by
the rotation that takes the demonstrated approach direction to the new one.
Libraries save to / load from one ``.json`` file exactly, with a ``format_version``.
"""

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from repertoire.planning.dmp import (
    DmpParameters,
    QuaternionDmpParameters,
    TaskSpaceDmp,
    check_unit_quaternions,
    dmp_from_dict,
)
from repertoire.planning.dmp_quaternion import (
    quat_multiply,
)

from repertoire.checks import is_whole, refuse_unknown_keys
from repertoire.errors import RepertoireError, UnknownNameError

FORMAT_VERSION = 1
"""Format version :meth:`MotionLibrary.save` writes (1: the layout of the first files)."""
READ_VERSIONS = (1,)
"""Format versions :meth:`MotionLibrary.load` reads; a file without the field is version 1."""


def _numpy_to_json(value):
    """``json.dumps`` default: NumPy arrays and scalars as lists and numbers (lossless)."""
    if isinstance(value, (np.ndarray, np.generic)):
        return value.tolist()
    raise TypeError(f"Object of type {type(value).__name__} is not JSON serializable")


def _as_json(value):
    """``value`` as a JSON round trip gives it back.

    Tuples and arrays come back as lists, NumPy scalars as numbers, keys as strings. NaN
    and infinities are refused (ValueError): JSON has no such numbers (Python would write
    ``NaN``, which other JSON readers reject), and a NaN would never match in ``find``.
    """
    return json.loads(json.dumps(value, default=_numpy_to_json, allow_nan=False))


def _query_value(value):
    """A ``find`` constraint normalised like stored contexts; non-JSON values as they are."""
    try:
        return _as_json(value)
    except (TypeError, ValueError):
        return value


LIBRARY_KEYS = ("type", "format_version", "primitives")
"""The keys of a library file (:meth:`MotionLibrary.to_dict`)."""
PRIMITIVE_KEYS = ("name", "label", "dmp", "context")
"""The keys of a primitive's record (:meth:`MotionPrimitive.to_dict`)."""


LABELS = ("grasp", "place", "release", "pour", "retreat")
TASKS: dict[str, list[str]] = {
    "pick_and_place": ["grasp", "place", "release"],
    "serve_water": ["grasp", "pour", "place", "release"],
}


@dataclass
class MotionPrimitive:
    """A labelled DMP in the library.

    Attributes:
        name: Unique name in the library.
        label: Semantic label, one of LABELS.
        dmp: The learned DMP (TaskSpaceDmp, DmpParameters or QuaternionDmpParameters).
        context: Free-form context: strings, numbers or lists of them (object, side, ...).
            Stored as JSON gives it back (tuples become lists), so :meth:`MotionLibrary.find`
            matches the same before a save and after a load.
    """

    name: str
    label: str
    dmp: TaskSpaceDmp | DmpParameters | QuaternionDmpParameters
    context: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise RepertoireError(
                f"a motion primitive needs a non-empty string name, got {self.name!r}"
            )
        if self.label not in LABELS:
            raise RepertoireError(f"label must be one of {LABELS}, got {self.label!r}")
        if not isinstance(self.dmp, (TaskSpaceDmp, DmpParameters, QuaternionDmpParameters)):
            raise RepertoireError(
                f"primitive {self.name!r} needs a TaskSpaceDmp, DmpParameters or "
                f"QuaternionDmpParameters, got {type(self.dmp).__name__}"
            )
        if not isinstance(self.context, dict):
            raise RepertoireError(
                f"context of {self.name!r} must be a dict, got {type(self.context).__name__}"
            )
        try:
            self.context = _as_json(self.context)
        except (TypeError, ValueError) as err:
            raise RepertoireError(
                f"context of {self.name!r} must hold only JSON values: {err}"
            ) from err

    def to_dict(self) -> dict:
        return {
            "name": self.name,
            "label": self.label,
            "dmp": self.dmp.to_dict(),
            "context": self.context,
        }

    @classmethod
    def from_dict(cls, d: dict) -> "MotionPrimitive":
        return cls(d["name"], d["label"], dmp_from_dict(d["dmp"]), dict(d.get("context", {})))


class MotionLibrary:
    """A set of labelled motion primitives."""

    def __init__(self, primitives: list[MotionPrimitive] | None = None) -> None:
        self._primitives: dict[str, MotionPrimitive] = {}
        for p in primitives or []:
            self.add(p)

    def __len__(self) -> int:
        return len(self._primitives)

    def __iter__(self):
        return iter(self._primitives.values())

    def __contains__(self, name: str) -> bool:
        return name in self._primitives

    def add(self, primitive: MotionPrimitive, *, replace: bool = False) -> MotionPrimitive:
        """Add a primitive.

        Args:
            primitive: The primitive.
            replace: Allow replacing one with the same name.
        """
        if primitive.name in self._primitives and not replace:
            raise RepertoireError(f"the library already has a primitive named {primitive.name!r}")
        self._primitives[primitive.name] = primitive
        return primitive

    def add_dmp(self, name: str, label: str, dmp, context: dict | None = None) -> MotionPrimitive:
        """Shortcut: wrap a DMP as a MotionPrimitive and add it.

        Args:
            name: Unique name.
            label: Semantic label.
            dmp: The DMP artefact.
            context: Context dict.
        """
        return self.add(MotionPrimitive(name, label, dmp, dict(context or {})))

    def get(self, name: str) -> MotionPrimitive:
        """The primitive called ``name``.

        Args:
            name: Primitive name.
        """
        if name not in self._primitives:
            raise UnknownNameError(
                f"no primitive named {name!r}; library has {sorted(self._primitives)}"
            )
        return self._primitives[name]

    def find(self, label: str, **context) -> list[MotionPrimitive]:
        """Primitives with ``label`` whose context matches every given key.

        Args:
            label: Semantic label.
            **context: Context keys and required values.
        """
        if label not in LABELS:
            raise RepertoireError(f"label must be one of {LABELS}, got {label!r}")
        context = {k: _query_value(v) for k, v in context.items()}
        return [
            p
            for p in self._primitives.values()
            if p.label == label and all(p.context.get(k) == v for k, v in context.items())
        ]

    def select(self, label: str, **context) -> MotionPrimitive:
        """The first primitive with ``label`` matching ``context``; raises if there is none.

        Args:
            label: Semantic label.
            **context: Context constraints.
        """
        found = self.find(label, **context)
        if not found:
            if not self._primitives:
                raise RepertoireError("the motion library is empty")
            raise UnknownNameError(
                f"no {label!r} primitive with context {context}; labels in the library: "
                f"{sorted({p.label for p in self._primitives.values()})}"
            )
        return found[0]

    def compose(self, task: str | list[str], **context) -> list[MotionPrimitive]:
        """Recall one primitive per label of a task (e.g. pick_and_place).

        Args:
            task: A name in TASKS or an explicit list of labels.
            **context: Context constraints applied to every step.
        """
        if isinstance(task, str):
            if task not in TASKS:
                raise UnknownNameError(f"unknown task {task!r}; known: {sorted(TASKS)}")
            labels = TASKS[task]
        else:
            labels = list(task)
        return [self.select(label, **context) for label in labels]

    def to_dict(self) -> dict:
        return {
            "type": "MotionLibrary",
            "format_version": FORMAT_VERSION,
            "primitives": [p.to_dict() for p in self._primitives.values()],
        }

    def save(self, path: str | Path) -> Path:
        """Write the library as JSON (exact), with its ``format_version``.

        Args:
            path: Output file; its suffix must be ``.json`` (the file is JSON, so another
                suffix such as ``.npz`` would misname it).

        Raises:
            RepertoireError: the suffix is not ``.json`` (the message names the path).
        """
        path = Path(path)
        if path.suffix != ".json":
            raise RepertoireError(
                f"a motion library is saved as JSON: {path} must end in '.json', "
                f"not {path.suffix or 'no suffix'!r}"
            )
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(self.to_dict(), indent=1))
        return path

    @classmethod
    def load(cls, path: str | Path) -> "MotionLibrary":
        """Read a library saved by :meth:`save`.

        The file's JSON content is read whatever its name, so files written before
        :meth:`save` refused suffixes other than ``.json`` still load. A file without
        ``format_version`` is version 1 (files saved before the field existed).

        Args:
            path: JSON file.

        Raises:
            RepertoireError: the file is missing, not JSON, of a format version not in
                :data:`READ_VERSIONS`, or not a well-formed library (the message names the
                file and the version, missing key, bad type or non-numeric field).
        """
        try:
            d = json.loads(Path(path).read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
            raise RepertoireError(f"cannot read a motion library from {path}: {err}") from err
        if not isinstance(d, dict):
            raise RepertoireError(
                f"{path} is not a MotionLibrary file: expected a JSON object, got "
                f"{type(d).__name__}"
            )
        if d.get("type") != "MotionLibrary":
            raise RepertoireError(
                f"{path} is not a MotionLibrary file: 'type' is {d.get('type')!r}, "
                "expected 'MotionLibrary'"
            )
        version = d.get("format_version", 1)
        if not (is_whole(version) and version in READ_VERSIONS):
            raise RepertoireError(
                f"{path} has motion library format version {version!r}; this code reads "
                f"versions {', '.join(map(str, READ_VERSIONS))}"
            )
        if "primitives" not in d:
            raise RepertoireError(f"{path}: MotionLibrary file has no 'primitives' key")
        refuse_unknown_keys(d, LIBRARY_KEYS, f"{path}: MotionLibrary file")
        records = d["primitives"]
        if not isinstance(records, list):
            raise RepertoireError(
                f"{path}: 'primitives' must be a list, got {type(records).__name__}"
            )
        primitives = []
        for k, record in enumerate(records):
            where = f"{path}: primitives[{k}]"
            if not isinstance(record, dict):
                raise RepertoireError(f"{where} must be a JSON object, got {type(record).__name__}")
            missing = [key for key in ("name", "label", "dmp") if key not in record]
            if missing:
                keys = "key" if len(missing) == 1 else "keys"
                raise RepertoireError(f"{where} is missing {keys} {', '.join(map(repr, missing))}")
            refuse_unknown_keys(record, PRIMITIVE_KEYS, where)
            if not isinstance(record.get("context", {}), dict):
                raise RepertoireError(
                    f"{where}: 'context' must be a JSON object, got "
                    f"{type(record['context']).__name__}"
                )
            try:
                primitives.append(MotionPrimitive.from_dict(record))
            except (KeyError, TypeError, ValueError, IndexError) as err:
                what = f"missing key {err}" if isinstance(err, KeyError) else str(err)
                raise RepertoireError(f"{where} ({record['name']!r}) is malformed: {what}") from err
        try:
            return cls(primitives)
        except RepertoireError as err:
            raise RepertoireError(f"{path}: {err}") from err


MOVING_SPEED_FRACTION = 0.05  # "still moving": speed above this fraction of the peak speed


def approach_direction(
    dmp: DmpParameters,
    goal: np.ndarray,
    start: np.ndarray | None = None,
    *,
    fraction=0.2,
    dt: float | None = None,
) -> np.ndarray:
    """Unit approach direction at the end of a 3-D position DMP propagated to ``goal``.

    Averages the velocity vectors over the last ``fraction`` of the movement (sec. IV-C).
    The movement is where the rollout (over tau) still moves, its speed above
    :data:`MOVING_SPEED_FRACTION` of the peak: a demonstration that comes to rest before
    its end (a held final pose) would otherwise average only the small settling motion at
    the goal, whose direction is arbitrary (often backwards).

    Args:
        dmp: 3-D position DMP.
        goal: Goal position, shape (3,).
        start: Start position; default the learned start.
        fraction: Final fraction of the movement to average over, in (0, 1]: the last
            ``int(fraction * m)`` samples of the ``m`` moving ones, and the last of them.
        dt: Rollout step (s); default ``tau / 500``.
    """
    if dmp.n_dims != 3:
        raise RepertoireError(f"approach direction needs a 3-D position DMP, got {dmp.n_dims}")
    if not 0.0 < fraction <= 1.0:
        raise RepertoireError(f"fraction must be in (0, 1], got {fraction}")
    r = dmp.rollout(goal=np.asarray(goal, float), x0=start, dt=dmp.tau / 500 if dt is None else dt)
    speed = np.linalg.norm(r.xd, axis=1)
    if not speed.max() > 1e-9:
        raise RepertoireError("the movement does not move; no approach direction")
    moving = np.flatnonzero(speed > MOVING_SPEED_FRACTION * speed.max())
    last = int(moving[-1])
    mean_v = r.xd[max(0, last - int(fraction * len(moving))) : last + 1].mean(axis=0)
    n = np.linalg.norm(mean_v)
    if n < 1e-9:
        raise RepertoireError("the movement does not move at its end; no approach direction")
    return mean_v / n


def _shortest_arc(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Unit quaternion of the smallest rotation taking unit vector a to unit vector b."""
    c = float(a @ b)
    if c < -1.0 + 1e-12:
        axis = np.cross(a, [1.0, 0.0, 0.0])
        if np.linalg.norm(axis) < 1e-6:
            axis = np.cross(a, [0.0, 1.0, 0.0])
        axis /= np.linalg.norm(axis)
        return np.concatenate([[0.0], axis])
    q = np.concatenate([[1.0 + c], np.cross(a, b)])
    return q / np.linalg.norm(q)


def grasp_orientation(
    dmp: TaskSpaceDmp,
    goal_position: np.ndarray,
    start_position: np.ndarray | None = None,
    *,
    fraction: float = 0.2,
    yaw_only: bool = True,
) -> np.ndarray:
    """Automatic final grasp orientation for a new goal (sec. IV-C).

    The approach direction of the demonstration and of the DMP propagated to the new goal
    are computed by averaging velocity vectors at the end of the movement; the
    demonstrated final orientation is turned by the rotation between the two directions
    (about the world z axis only with ``yaw_only``, which keeps the gripper's tilt).

    Args:
        dmp: A TaskSpaceDmp learned from a grasp.
        goal_position: New goal position, shape (3,).
        start_position: New start; default the learned start.
        fraction: Final fraction of the movement used for the average.
        yaw_only: Rotate about world z only (horizontal approach directions).

    Returns:
        Unit quaternion (w, x, y, z) for the goal_orientation input.
    """
    demo = approach_direction(dmp.position, dmp.position.goal, dmp.position.x0, fraction=fraction)
    new = approach_direction(dmp.position, goal_position, start_position, fraction=fraction)
    if yaw_only:
        a, b = demo[:2], new[:2]
        if np.linalg.norm(a) < 1e-6 or np.linalg.norm(b) < 1e-6:
            rot = np.array([1.0, 0.0, 0.0, 0.0])  # vertical approach: keep the demo's yaw
        else:
            yaw = np.arctan2(b[1], b[0]) - np.arctan2(a[1], a[0])
            rot = np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])
    else:
        rot = _shortest_arc(demo, new)
    q = quat_multiply(rot, dmp.orientation.goal)
    q = q / np.linalg.norm(q)
    check_unit_quaternions(q[None], name="grasp orientation")
    return q


def instantiate(
    primitive: MotionPrimitive,
    *,
    position: np.ndarray | None = None,
    orientation: np.ndarray | None = None,
    fingers: np.ndarray | None = None,
    auto_grasp_orientation: bool = True,
) -> TaskSpaceDmp:
    """Set a task-space primitive's goals for a new situation (sec. IV-C).

    For a grasp with ``orientation=None`` and ``auto_grasp_orientation`` the final
    orientation is computed from the approach direction; otherwise the demonstrated one
    is kept (place, release).

    Args:
        primitive: A primitive holding a TaskSpaceDmp.
        position: Goal position.
        orientation: Goal orientation (w, x, y, z).
        fingers: Goal finger positions.
        auto_grasp_orientation: Compute grasp orientations automatically.
    """
    if not isinstance(primitive.dmp, TaskSpaceDmp):
        raise RepertoireError(f"{primitive.name!r} does not hold a TaskSpaceDmp")
    if (
        orientation is None
        and position is not None
        and auto_grasp_orientation
        and primitive.label == "grasp"
    ):
        orientation = grasp_orientation(primitive.dmp, position)
    return primitive.dmp.with_goal(position=position, orientation=orientation, fingers=fingers)


__all__ = [
    "LABELS",
    "TASKS",
    "MotionLibrary",
    "MotionPrimitive",
    "approach_direction",
    "grasp_orientation",
    "instantiate",
]
