"""Small input checks shared across the packages (numbers and seeds), with named errors."""

import numbers

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


__all__ = ["MAX_SEED", "check_seed", "is_real", "is_whole"]
