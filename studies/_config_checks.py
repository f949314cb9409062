"""Config checks shared by the studies, with errors naming the field.

The leading underscore keeps the study registry from importing this module as a study.
"""

from collections.abc import Sequence

import numpy as np

from repertoire.errors import RepertoireError


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
