"""Small input checks shared across the packages (numbers, seeds, ranges), with named errors."""

import numbers
from collections.abc import Sequence

import numpy as np

from repertoire.errors import RepertoireError

MAX_SEED = 2**32 - 1
"""Largest seed every consumer takes (numpy's legacy, scipy's and scikit-learn's range)."""


def is_real(value) -> bool:
    """True for a real number (a Python or numpy int or float), not a bool, str or array."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def is_whole(value) -> bool:
    """True for a whole number (a Python or numpy int), not a bool, float or array."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def check_seed(seed, name: str = "seed") -> int:
    """``seed`` as an int in ``0..MAX_SEED``, or a RepertoireError naming it."""
    if not (is_whole(seed) and 0 <= seed <= MAX_SEED):
        raise RepertoireError(f"{name} must be a whole number in 0..2**32 - 1, got {seed!r}")
    return int(seed)


def refuse_unknown_keys(record: dict, known: Sequence[str], where: str) -> None:
    """Raises RepertoireError naming the keys of ``record`` not in ``known`` (a misspelt key).

    A misspelt optional key (``"contxt"``, ``"fingrs"``) would otherwise be dropped without
    a word, and the record would load without it.

    Args:
        record: the mapping read from a file.
        known: the keys it may have.
        where: what the record is, for the message (``"primitives[0]"``).
    """
    unknown = sorted(set(record) - set(known))
    if unknown:
        raise RepertoireError(f"{where} has unknown keys {unknown}; expected only {list(known)}")


def check_range(name: str, r: Sequence[float], within: tuple[float, float] | None = None) -> None:
    """Raises RepertoireError unless ``r`` is a finite ``[lo, hi]`` with ``lo <= hi``.

    Args:
        name: the config field, for the message.
        r: its value.
        within: ``(lo, hi)`` the range must lie in (to 1e-9), if any.
    """
    if len(r) != 2 or not np.all(np.isfinite(r)) or r[0] > r[1]:
        raise RepertoireError(f"{name} must be finite [lo, hi] with lo <= hi, got {r}")
    if within is not None:
        lo, hi = within
        if r[0] < lo - 1e-9 or r[1] > hi + 1e-9:
            raise RepertoireError(f"{name} must lie within [{lo}, {hi}], got {r}")


__all__ = ["MAX_SEED", "check_range", "check_seed", "is_real", "is_whole"]
