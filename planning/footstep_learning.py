"""Learning the footstep table T from measured steps, as Chestnutt et al. did with motion capture.

The robot (here: the simulated biped, run by ``studies/footstep_table.py``) performs
every sequence of three commanded actions from standing (7^3 = 343 sequences).
Each measured step becomes a sample ``(a_prev2, a_prev1, stance_foot, a, dx, dy,
dyaw, duration)``: the landed swing sole expressed in the frame of the *measured*
stance sole, and the step time (touch-down to touch-down, :func:`step_periods`).
:func:`learn_action_table` builds the ``ActionTable`` from them
(``ActionTable.from_samples``; keys measured with one stance foot are mirrored to the
other). Everything here is pure: no simulation.
"""

import itertools
import math
from collections.abc import Sequence

import numpy as np
from repertoire.planning.footstep.actions import (
    ACTIONS,
    MIRROR,
    STEP_COST,
    nominal_action_table,
    relative_displacement,
)
from repertoire.planning.footstep.types import ActionTable, Foot, parse_foot

from repertoire.errors import RepertoireError

REST_ACTION = "stop"


def command_sequences(actions: Sequence[str] = tuple(ACTIONS), length: int = 3) -> list[tuple]:
    """Every sequence of ``length`` commands, in lexicographic order of action indices.

    Args:
        actions: the action names.
        length: commands per sequence (the paper: 3, so 7^3 = 343 sequences).
    """
    if length < 1:
        raise RepertoireError(f"sequence length must be >= 1, got {length}")
    if len(actions) == 0:
        raise RepertoireError("command_sequences needs at least one action")
    return list(itertools.product(actions, repeat=length))


def sequence_for_index(
    index: int, actions: Sequence[str] = tuple(ACTIONS), length: int = 3
) -> tuple:
    """The ``index``-th sequence of :func:`command_sequences` (without building the list).

    Raises:
        RepertoireError: index outside ``[0, len(actions) ** length)``.
    """
    n = len(actions)
    if not 0 <= index < n**length:
        raise RepertoireError(
            f"sequence index {index} out of range [0, {n**length}) for {n} actions and "
            f"length {length}"
        )
    digits = []
    for _ in range(length):
        digits.append(index % n)
        index //= n
    return tuple(actions[d] for d in reversed(digits))


def step_periods(command_times: Sequence[float], durations: Sequence[float]) -> list[float]:
    """Step times on a plan's time axis from each step's command-to-touch-down time.

    A plan's ``times[k]`` is when step k's swing foot lands (it becomes the stance foot),
    so the table's step time must add up to the touch-downs: the first step's time from
    its command to its touch-down, each later one's from the previous touch-down to its
    own. The walker commands each step at the previous step's *scheduled* landing, not
    its touch-down, so the command-to-touch-down times (0.1-0.2 s longer than the
    schedule) would drift a plan's clock by that much per step.

    Args:
        command_times: when each step was commanded [s].
        durations: each step's time from its command to its touch-down [s] (NaN: none).

    Returns:
        ``[d0, (c1 + d1) - (c0 + d0), (c2 + d2) - (c1 + d1), ...]``.

    Raises:
        RepertoireError: fewer command times than durations.
    """
    if len(command_times) < len(durations):
        raise RepertoireError(
            f"step_periods: {len(durations)} durations but only {len(command_times)} command times"
        )
    touch = [float(c) + float(d) for c, d in zip(command_times, durations)]
    return [float(d) for d in durations[:1]] + [b - a for a, b in zip(touch, touch[1:])]


def step_samples(
    actions: Sequence[str],
    first_stance: "Foot | int | str",
    stance_poses: Sequence[Sequence[float]],
    landed_poses: Sequence[Sequence[float]],
    durations: Sequence[float],
    *,
    history: Sequence[str] = (REST_ACTION, REST_ACTION),
) -> list[tuple]:
    """Samples for ``ActionTable.from_samples`` from one measured walk.

    Args:
        actions: the commanded actions, one per step.
        first_stance: the stance foot of the first step (stance alternates).
        stance_poses: measured stance sole ``(x, y, yaw)`` at each landing.
        landed_poses: measured landed swing sole ``(x, y, yaw)`` of each step.
        durations: step times [s].
        history: the two actions before the first.

    Returns:
        One sample per measured step (a walk that fell has fewer landings; only those count).

    Raises:
        RepertoireError: mismatched lengths or non-finite measurements.
    """
    n = len(landed_poses)
    if len(stance_poses) != n or n > len(actions) or len(durations) < n:
        raise RepertoireError(
            f"step_samples: {len(actions)} actions, {len(stance_poses)} stance poses, "
            f"{n} landings and {len(durations)} durations do not match"
        )
    hist = list(history)
    if len(hist) != 2:
        raise RepertoireError(f"history must have 2 actions, got {hist}")
    foot = parse_foot(first_stance)
    samples = []
    for k in range(n):
        s = np.asarray(stance_poses[k], float)
        p = np.asarray(landed_poses[k], float)
        if not (np.all(np.isfinite(s)) and np.all(np.isfinite(p)) and math.isfinite(durations[k])):
            raise RepertoireError(f"step {k} has non-finite measurements {s}, {p}, {durations[k]}")
        dx, dy, dyaw = relative_displacement(s, p)
        samples.append(
            (hist[-2], hist[-1], foot.name.lower(), actions[k], dx, dy, dyaw, float(durations[k]))
        )
        hist.append(actions[k])
        foot = foot.other()
    return samples


def covered_keys(samples: Sequence[Sequence], actions: Sequence[str] = tuple(ACTIONS)) -> set:
    """Keys ``(i2, i1, foot, a)`` (indices) a set of samples fills, mirror included."""
    idx = {a: k for k, a in enumerate(actions)}
    keys = set()
    for s in samples:
        key = (idx[s[0]], idx[s[1]], int(parse_foot(s[2])), idx[s[3]])
        keys.add(key)
        m = [idx[MIRROR.get(actions[k], actions[k])] for k in (key[0], key[1], key[3])]
        keys.add((m[0], m[1], 1 - key[2], m[2]))
    return keys


def learn_action_table(
    samples: Sequence[Sequence], *, fill_from: ActionTable | None = None
) -> tuple[ActionTable, int]:
    """Builds T from measured samples.

    Args:
        samples: ``(a_prev2, a_prev1, foot, a, dx, dy, dyaw, duration)`` tuples.
        fill_from: a table whose entries fill keys no sample covers (for a subset of the
            343 sequences); None requires complete coverage.

    Returns:
        ``(table, filled)``: the table and how many keys came from ``fill_from``.

    Raises:
        ActionTableError: (from ``ActionTable``) missing keys without ``fill_from``, or
            non-finite samples.
    """
    samples = list(samples)
    filled = 0
    if fill_from is not None:
        have = covered_keys(samples)
        n = len(ACTIONS)
        for key in itertools.product(range(n), range(n), (0, 1), range(n)):
            if key not in have:
                names = [ACTIONS[key[0]], ACTIONS[key[1]], ACTIONS[key[3]]]
                dx, dy, dyaw, dur = fill_from.lookup(names[0], names[1], key[2], names[2])
                samples.append((names[0], names[1], key[2], names[2], dx, dy, dyaw, dur))
                filled += 1
    table = ActionTable.from_samples(
        samples,
        actions=list(ACTIONS),
        rest_action=REST_ACTION,
        step_cost=[STEP_COST[a] for a in ACTIONS],
        mirror=dict(MIRROR),
    )
    return table, filled


def table_differences(learned: ActionTable, reference: ActionTable | None = None) -> dict:
    """How far a learned table is from the commanded displacements (the nominal table).

    Args:
        learned: the learned table.
        reference: the table to compare with (default: ``nominal_action_table()``).

    Returns:
        A dict with ``position_diff`` (array (n, n, 2, n) of distances [m]), ``yaw_diff``
        [rad], ``duration_diff`` [s], and summary numbers ``max_position_diff_m``,
        ``mean_position_diff_m``, ``fraction_over_2cm``, ``max_duration_diff_s``.
    """
    reference = reference or nominal_action_table()
    if learned.actions != reference.actions:
        raise RepertoireError(
            f"tables have different actions: {learned.actions} vs {reference.actions}"
        )
    d = learned.displacement - reference.displacement
    pos = np.hypot(d[..., 0], d[..., 1])
    yaw = np.abs((d[..., 2] + np.pi) % (2 * np.pi) - np.pi)
    dur = learned.duration - reference.duration
    return {
        "position_diff": pos,
        "yaw_diff": yaw,
        "duration_diff": dur,
        "max_position_diff_m": float(pos.max()),
        "mean_position_diff_m": float(pos.mean()),
        "fraction_over_2cm": float(np.mean(pos > 0.02)),
        "max_duration_diff_s": float(np.abs(dur).max()),
    }
