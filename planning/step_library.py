"""The StepLibrary artefact: LittleDog steps (start state + joint-angle action), saved exactly.

Stolle et al. (section III) store each demonstrated step as the state at its start
(global foot positions and body pose) and the action: the joint angles from lift
off until all four feet are down again. A :class:`LibraryStep` holds that plus the
recorded body pose along the step (the integral foot controller's ideal body
frame, section IV), the recorded stance labels, which foot moves, the source
terrain, the direction and whether the step was recorded or planned.

:class:`StepLibrary` is an immutable list of steps with the stacked 12-vector of
start foot positions (the lookup key), a planar rigid transform of every step's
start state and body poses (``transformed``: the action, joint angles, is
unchanged), concatenation, and exact save/load: ``<name>.npz`` (numpy arrays,
loaded with ``allow_pickle=False``) next to ``<name>.json`` (metadata and the
format version), validated on load. :func:`segment_recording` cuts a recording
into steps by stance configuration.
"""

import dataclasses
import json
import math
import os
from pathlib import Path

import numpy as np
from repertoire.models.littledog import LEGS
from repertoire.models.littledog.kinematics import LEG_GEOMETRY
from repertoire.models.littledog.pose import rotation_from_rpy, rpy_from_rotation, wrap_angle

from repertoire.checks import is_real
from repertoire.errors import RepertoireError

FORMAT_VERSION = 1
"""Version of the saved library format; files of another version are refused."""

STEP_KINDS: list[str] = ["recorded", "planned"]

_LOWER = np.concatenate([LEG_GEOMETRY[leg].lower for leg in LEGS])
_UPPER = np.concatenate([LEG_GEOMETRY[leg].upper for leg in LEGS])


class StepLibraryError(RepertoireError):
    """A step or library is malformed, or a library file cannot be read."""


@dataclasses.dataclass(frozen=True)
class LibraryStep:
    """One step of the library.

    Attributes:
        start_feet: world foot centres at the step's start (4 x 3, ``LEGS`` order).
        start_pose: body pose [x, y, z, roll, pitch, yaw] at the start.
        times: action sample times from 0 (s), shape (T,), strictly increasing.
        q: joint angles of the action (T x 12, ``JOINT_NAMES`` order), within limits.
        body_pose: recorded body pose at each sample (T x 6), the ideal body frame.
        stance: stance labels (T x 4 bool, True = foot down); all four down at the start.
        foot: index of the moving foot in ``LEGS``.
        terrain: name of the source terrain.
        direction: crossing direction (yaw of the crossing, rad).
        kind: ``recorded`` (demonstrated) or ``planned`` (from a footstep planner).
    """

    start_feet: np.ndarray
    start_pose: np.ndarray
    times: np.ndarray
    q: np.ndarray
    body_pose: np.ndarray
    stance: np.ndarray
    foot: int
    terrain: str
    direction: float
    kind: str = "recorded"

    def __post_init__(self) -> None:
        validate_step(self)

    @property
    def duration(self) -> float:
        return float(self.times[-1])


def _is_real(value) -> bool:
    """True for a finite real number (not a string, None or array)."""
    return is_real(value) and math.isfinite(value)


def validate_step(step: LibraryStep, where: str = "step") -> None:
    """Checks shapes, finiteness, joint limits and stance labels of one step.

    Raises:
        StepLibraryError: naming the step and what is wrong.
    """

    def arr(name, shape_tail, dtype=float):
        try:
            a = np.asarray(getattr(step, name), dtype=dtype)
        except (TypeError, ValueError) as e:
            raise StepLibraryError(f"{where}: {name} must hold numbers, got {e}") from e
        if a.ndim != len(shape_tail) or any(
            s is not None and a.shape[i] != s for i, s in enumerate(shape_tail)
        ):
            raise StepLibraryError(
                f"{where}: {name} must have shape "
                f"{tuple('T' if s is None else s for s in shape_tail)}, got {a.shape}"
            )
        return a

    feet = arr("start_feet", (4, 3))
    pose = arr("start_pose", (6,))
    times = arr("times", (None,))
    q = arr("q", (None, 12))
    body = arr("body_pose", (None, 6))
    if step.stance is None:
        raise StepLibraryError(f"{where}: stance labels are missing (expected T x 4 booleans)")
    stance = np.asarray(step.stance)
    n = len(times)
    if n < 2:
        raise StepLibraryError(f"{where}: the action needs at least 2 samples, got {n}")
    if stance.shape != (n, 4):
        raise StepLibraryError(
            f"{where}: stance labels must be T x 4 with T = {n} samples, got shape {stance.shape}"
        )
    if stance.dtype != bool:
        raise StepLibraryError(f"{where}: stance labels must be booleans, got {stance.dtype}")
    if q.shape[0] != n or body.shape[0] != n:
        raise StepLibraryError(
            f"{where}: q ({q.shape[0]}), body_pose ({body.shape[0]}) and times ({n}) must have "
            f"the same number of samples"
        )
    for name, a in (
        ("start_feet", feet),
        ("start_pose", pose),
        ("times", times),
        ("q", q),
        ("body_pose", body),
    ):
        if not np.all(np.isfinite(a)):
            raise StepLibraryError(f"{where}: {name} contains NaN or infinite values")
    if times[0] != 0.0 or np.any(np.diff(times) <= 0.0):
        raise StepLibraryError(f"{where}: times must start at 0 and strictly increase")
    out = (q < _LOWER - 1e-9) | (q > _UPPER + 1e-9)
    if np.any(out):
        t, j = np.argwhere(out)[0]
        raise StepLibraryError(
            f"{where}: joint angle {j} ({LEGS[j // 3]}) = {q[t, j]:.3f} rad at sample {t} is "
            f"outside the joint limits [{_LOWER[j]}, {_UPPER[j]}] rad"
        )
    if not stance[0].all():
        raise StepLibraryError(f"{where}: a step must start with all four feet down")
    if not (_is_real(step.foot) and int(step.foot) == step.foot and 0 <= step.foot < 4):
        raise StepLibraryError(f"{where}: foot must be 0..3 (LEGS {LEGS}), got {step.foot!r}")
    if not isinstance(step.terrain, str) or not step.terrain:
        raise StepLibraryError(f"{where}: terrain must be a non-empty name, got {step.terrain!r}")
    if not _is_real(step.direction):
        raise StepLibraryError(
            f"{where}: direction must be a finite number (rad), got {step.direction!r}"
        )
    if step.kind not in STEP_KINDS:
        raise StepLibraryError(f"{where}: kind must be one of {STEP_KINDS}, got {step.kind!r}")


def planar_transform(x: float, y: float, yaw: float):
    """Functions mapping world points and body poses by a planar rigid transform.

    Returns:
        ``(apply_points, apply_poses)``: ``apply_points(p)`` for (..., 3) points and
        ``apply_poses(pose)`` for (..., 6) poses (yaw added, roll and pitch rotated).
    """
    c, s = math.cos(yaw), math.sin(yaw)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    t = np.array([x, y, 0.0])

    def points(p):
        return np.asarray(p, dtype=float) @ R.T + t

    def poses(pose):
        pose = np.asarray(pose, dtype=float)
        out = pose.copy()
        out[..., :3] = points(pose[..., :3])
        out[..., 3:] = rpy_from_rotation(R @ rotation_from_rpy(pose[..., 3:]))
        return out

    return points, poses


class StepLibrary:
    """An immutable list of :class:`LibraryStep` s with the stacked lookup keys.

    Args:
        steps: at least one step (each validated).

    Raises:
        StepLibraryError: for an empty library or a malformed step.
    """

    def __init__(self, steps: list[LibraryStep]) -> None:
        steps = list(steps)
        if not steps:
            raise StepLibraryError("a StepLibrary needs at least one step; got an empty list")
        for i, step in enumerate(steps):
            if not isinstance(step, LibraryStep):
                raise StepLibraryError(f"steps[{i}] must be a LibraryStep, got {type(step)}")
        self._steps = steps
        self._keys = np.stack([s.start_feet.reshape(12) for s in steps])
        self._keys.setflags(write=False)

    def __len__(self) -> int:
        return len(self._steps)

    def __getitem__(self, i: int) -> LibraryStep:
        return self._steps[i]

    def __iter__(self):
        return iter(self._steps)

    @property
    def steps(self) -> list[LibraryStep]:
        return list(self._steps)

    @property
    def keys(self) -> np.ndarray:
        """Start foot positions of every step stacked as (S, 12) (read-only)."""
        return self._keys

    def transformed(self, x: float, y: float, yaw: float) -> "StepLibrary":
        """Every step's start state and body poses moved by a planar rigid transform.

        The world is rotated by ``yaw`` about z and then shifted by ``(x, y)``; joint
        angles, times and stance labels are unchanged; directions gain ``yaw``.
        """
        if not all(math.isfinite(v) for v in (x, y, yaw)):
            raise StepLibraryError(f"transform must be finite, got ({x}, {y}, {yaw})")
        points, poses = planar_transform(x, y, yaw)
        return StepLibrary(
            [
                dataclasses.replace(
                    s,
                    start_feet=points(s.start_feet),
                    start_pose=poses(s.start_pose),
                    body_pose=poses(s.body_pose),
                    direction=float(wrap_angle(s.direction + yaw)),
                )
                for s in self._steps
            ]
        )

    def __add__(self, other: "StepLibrary") -> "StepLibrary":
        if not isinstance(other, StepLibrary):
            raise StepLibraryError(f"can only concatenate StepLibrary, got {type(other)}")
        return StepLibrary(self._steps + other._steps)

    def appended(self, steps: list[LibraryStep]) -> "StepLibrary":
        """A new library with ``steps`` added at the end."""
        return StepLibrary(self._steps + list(steps))

    def counts(self) -> dict[str, int]:
        """Number of steps per ``terrain/direction_deg`` (directions rounded to degrees)."""
        out: dict[str, int] = {}
        for s in self._steps:
            key = f"{s.terrain}/{round(math.degrees(s.direction)) % 360}"
            out[key] = out.get(key, 0) + 1
        return out

    def save(self, path: str | Path) -> tuple[Path, Path]:
        """Writes ``<path>.npz`` and ``<path>.json`` (any suffix of ``path`` is dropped).

        The arrays are written to temporary files first and renamed, so a failure
        leaves no half-written library.

        Returns:
            The two paths written.
        """
        base = Path(path)
        base = base.with_suffix("") if base.suffix in (".npz", ".json") else base
        base.parent.mkdir(parents=True, exist_ok=True)
        lengths = np.array([len(s.times) for s in self._steps])
        arrays = {
            "start_feet": np.stack([s.start_feet for s in self._steps]),
            "start_pose": np.stack([s.start_pose for s in self._steps]),
            "offsets": np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64),
            "times": np.concatenate([s.times for s in self._steps]),
            "q": np.concatenate([s.q for s in self._steps]),
            "body_pose": np.concatenate([s.body_pose for s in self._steps]),
            "stance": np.concatenate([s.stance for s in self._steps]).astype(bool),
            "foot": np.array([s.foot for s in self._steps], dtype=np.int64),
            "direction": np.array([s.direction for s in self._steps]),
        }
        meta = {
            "format": "repertoire.step_library",
            "format_version": FORMAT_VERSION,
            "num_steps": len(self._steps),
            "terrain": [s.terrain for s in self._steps],
            "kind": [s.kind for s in self._steps],
            "legs": LEGS,
        }
        npz, js = base.with_suffix(".npz"), base.with_suffix(".json")
        tag = f".{os.getpid()}.tmp"  # unique per process: parallel writers never share a file
        tmp_npz, tmp_js = base.with_suffix(".npz" + tag), base.with_suffix(".json" + tag)
        with open(tmp_npz, "wb") as f:
            np.savez(f, **arrays)
        tmp_js.write_text(json.dumps(meta, indent=1))
        tmp_npz.replace(npz)
        tmp_js.replace(js)
        return npz, js

    @classmethod
    def load(cls, path: str | Path) -> "StepLibrary":
        """Reads a library written by :meth:`save` and validates every step.

        Raises:
            StepLibraryError: missing files, another format version, or malformed contents.
        """
        base = Path(path)
        base = base.with_suffix("") if base.suffix in (".npz", ".json") else base
        npz, js = base.with_suffix(".npz"), base.with_suffix(".json")
        for p in (npz, js):
            if not p.is_file():
                raise StepLibraryError(f"step library file {p} does not exist")
        try:
            meta = json.loads(js.read_text())
        except json.JSONDecodeError as e:
            raise StepLibraryError(f"{js} is not valid JSON: {e}") from e
        if not isinstance(meta, dict) or meta.get("format") != "repertoire.step_library":
            raise StepLibraryError(f"{js} is not a repertoire step library (no format tag)")
        if meta.get("format_version") != FORMAT_VERSION:
            raise StepLibraryError(
                f"{js} has format version {meta.get('format_version')!r}; this code reads "
                f"version {FORMAT_VERSION} only (regenerate the library)"
            )
        try:
            with np.load(npz, allow_pickle=False) as data:
                a = {k: data[k] for k in data.files}
        except (ValueError, OSError) as e:
            raise StepLibraryError(f"cannot read {npz}: {e}") from e
        need = [
            "start_feet",
            "start_pose",
            "offsets",
            "times",
            "q",
            "body_pose",
            "stance",
            "foot",
            "direction",
        ]
        missing = [k for k in need if k not in a]
        if missing:
            raise StepLibraryError(f"{npz} lacks the arrays {missing}")
        text = [
            k for k in need if k not in ("offsets", "stance", "foot") and a[k].dtype.kind != "f"
        ]
        if text:
            raise StepLibraryError(f"{npz}: the arrays {text} must hold floating-point numbers")
        n = meta.get("num_steps")
        off = a["offsets"]
        per_step = ("start_feet", "start_pose", "foot", "direction")
        if (
            not isinstance(n, int)
            or n < 1
            or off.ndim != 1
            or len(off) != n + 1
            or not np.issubdtype(off.dtype, np.integer)
            or not np.issubdtype(a["foot"].dtype, np.integer)
            or any(a[k].ndim < 1 or len(a[k]) != n for k in per_step)
            or not isinstance(meta.get("terrain"), list)
            or not isinstance(meta.get("kind"), list)
            or len(meta["terrain"]) != n
            or len(meta["kind"]) != n
            or off[0] != 0
            or np.any(np.diff(off) < 1)
            or off[-1] != len(a["times"])
        ):
            raise StepLibraryError(
                f"{npz}/{js}: inconsistent step counts or offsets (num_steps={n!r}; expected "
                f"one offset more than steps, one start state, integer foot, direction, terrain "
                f"and kind per step)"
            )
        steps = []
        for i in range(n):
            sl = slice(int(off[i]), int(off[i + 1]))
            step = LibraryStep.__new__(LibraryStep)
            fields = dict(
                start_feet=a["start_feet"][i],
                start_pose=a["start_pose"][i],
                times=a["times"][sl],
                q=a["q"][sl],
                body_pose=a["body_pose"][sl],
                stance=a["stance"][sl],
                foot=int(a["foot"][i]),
                terrain=meta["terrain"][i],
                direction=float(a["direction"][i]),
                kind=meta["kind"][i],
            )
            for k, v in fields.items():
                object.__setattr__(step, k, v)
            validate_step(step, f"{npz} step {i}")
            steps.append(step)
        return cls(steps)


def segment_recording(
    times,
    q,
    body_pose,
    feet,
    contact,
    *,
    terrain: str,
    direction: float,
    min_flight: int = 20,
    settle: int = 10,
) -> list[LibraryStep]:
    """Cuts a recording into steps: a step starts whenever all four feet are down.

    A *flight* is a run of at least ``min_flight`` samples with one foot up (shorter
    runs are contact flicker or a foot unloading while the body rocks). Step ``k``
    spans from the first all-down sample after flight ``k - 1`` (or the first
    sample) to the first all-down sample after flight ``k`` plus up to ``settle``
    samples of all four feet down; its start state is the foot positions and body
    pose there.

    Args:
        times: sample times (N,) (s).
        q: commanded joint angles (N x 12).
        body_pose: measured body poses (N x 6).
        feet: measured world foot centres (N x 4 x 3).
        contact: measured contact flags (N x 4, nonzero = down).
        terrain: source terrain name.
        direction: crossing direction (rad).
        min_flight: shortest flight counted (samples).
        settle: up to this many all-down samples after the touchdown end the step.

    Raises:
        StepLibraryError: inconsistent shapes, a flight with two feet up, or no step.
    """
    times = np.asarray(times, dtype=float)
    n = len(times)
    q, body_pose = np.asarray(q, dtype=float), np.asarray(body_pose, dtype=float)
    feet, down = np.asarray(feet, dtype=float), np.asarray(contact) != 0
    if (
        q.shape != (n, 12)
        or body_pose.shape != (n, 6)
        or feet.shape != (n, 4, 3)
        or (down.shape != (n, 4))
    ):
        raise StepLibraryError(
            f"recording arrays must be N x 12, N x 6, N x 4 x 3 and N x 4 with N = {n}; got "
            f"{q.shape}, {body_pose.shape}, {feet.shape}, {down.shape}"
        )
    flights = []  # (start, end, foot): runs of one foot up for >= min_flight samples
    for f in range(4):
        edges = np.flatnonzero(np.diff(np.concatenate([[0], (~down[:, f]).astype(int), [0]])))
        flights += [(a, b, f) for a, b in zip(edges[::2], edges[1::2]) if b - a >= min_flight]
    flights.sort()
    for (_, b0, f0), (a1, _, f1) in zip(flights, flights[1:]):
        if a1 < b0:
            raise StepLibraryError(
                f"recording at t = {times[a1]:.2f} s: feet {LEGS[f0]} and {LEGS[f1]} are in "
                f"flight together; a crawl lifts one foot at a time"
            )
    all_down = down.all(axis=1)
    steps: list[LibraryStep] = []
    start = int(np.argmax(all_down)) if all_down.any() else n
    for a, b, moving in flights:
        if a < start:
            continue
        after = np.flatnonzero(all_down[b:])
        if len(after) == 0:
            break  # the recording ends before the feet are down again
        end = b + int(after[0])
        # Keep the touchdown's settling samples (all four down) in the action, so the
        # landed foot is pressed down as it was in the recording.
        while end + 1 < n and end - (b + int(after[0])) < settle and all_down[end + 1]:
            end += 1
        sl = slice(start, end + 1)  # the first all-down sample closes the step
        steps.append(
            LibraryStep(
                start_feet=feet[start].copy(),
                start_pose=body_pose[start].copy(),
                times=times[sl] - times[start],
                q=q[sl].copy(),
                body_pose=body_pose[sl].copy(),
                stance=down[sl].copy(),
                foot=moving,
                terrain=terrain,
                direction=float(direction),
                kind="recorded",
            )
        )
        start = end
    if not steps:
        raise StepLibraryError("the recording has no complete step (no foot lifted and set down)")
    return steps


__all__ = [
    "FORMAT_VERSION",
    "STEP_KINDS",
    "LibraryStep",
    "StepLibrary",
    "StepLibraryError",
    "planar_transform",
    "segment_recording",
    "validate_step",
]
