"""Pass criteria: named bounds on the figures a world or study reports.

A registered diagram's ``check(diagram, context)`` and a study's summary return
named figures (``{"height_error_m": -0.0007, ...}``). A world or study declares
what a passing run looks like as bounds on some of those figures::

    criteria = {"height_error_m": Bound(-0.01, 0.01), "success": Bound(lo=1.0)}

:func:`evaluate_criteria` compares figures with their bounds and says, per
criterion, whether it passed and why not. This module imports nothing heavy.
"""

import dataclasses
import math
from collections.abc import Mapping


@dataclasses.dataclass
class Bound:
    """Closed interval [lo, hi] a figure must lie in; None leaves that side open.

    Attributes:
        lo: smallest passing value, or None.
        hi: largest passing value, or None.
    """

    lo: float | None = None
    hi: float | None = None

    def __post_init__(self) -> None:
        if self.lo is None and self.hi is None:
            raise ValueError("a Bound needs lo, hi or both")
        if self.lo is not None and self.hi is not None and self.lo > self.hi:
            raise ValueError(f"Bound lo={self.lo} is above hi={self.hi}")

    def describe(self) -> str:
        """The bound as text, for example ``in [-0.01, 0.01]`` or ``>= 1``."""
        if self.lo is None:
            return f"<= {self.hi:g}"
        if self.hi is None:
            return f">= {self.lo:g}"
        return f"in [{self.lo:g}, {self.hi:g}]"


@dataclasses.dataclass
class CriterionResult:
    """The outcome of one criterion.

    Attributes:
        name: the figure's name.
        value: the figure (NaN when the figure was missing).
        bound: the bound it was held to.
        passed: whether the figure was present, finite and within the bound.
        reason: empty when passed, else a one-line explanation.
    """

    name: str
    value: float
    bound: Bound
    passed: bool
    reason: str = ""


def evaluate_criteria(
    figures: Mapping[str, float], criteria: Mapping[str, Bound]
) -> list[CriterionResult]:
    """Holds ``figures`` to ``criteria``; a missing or non-finite figure fails.

    Args:
        figures: named figures a run reported.
        criteria: figure name -> Bound.

    Returns:
        One CriterionResult per criterion, in the criteria's order.
    """
    results = []
    for name, bound in criteria.items():
        if name not in figures:
            results.append(
                CriterionResult(name, math.nan, bound, False, f"{name} was not reported")
            )
            continue
        value = float(figures[name])
        ok = math.isfinite(value)
        ok = ok and (bound.lo is None or value >= bound.lo)
        ok = ok and (bound.hi is None or value <= bound.hi)
        reason = "" if ok else f"{name} = {value:.6g}, expected {bound.describe()}"
        results.append(CriterionResult(name, value, bound, ok, reason))
    return results
