"""The search cores the footstep planners run on: the generic Python loop or the compiled one."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

from repertoire.planning.footstep.biped_model import BipedStepModel
from repertoire.planning.footstep.fastkernels import MASK_WORD_CELLS
from repertoire.planning.footstep.search import SearchResult, anytime_search, search
from repertoire.planning.footstep.types import FootstepError

if TYPE_CHECKING:
    from repertoire.planning.footstep.planner import PlannerOptions


def _ara(
    model: BipedStepModel, backend: str, weights: Sequence[float], budget: int, left: float
) -> list[SearchResult]:
    """ARA* over the weights on the chosen core."""
    left = max(left, 1e-9)
    if backend == "compiled":
        from repertoire.planning.footstep.fastcore import compiled_anytime

        return compiled_anytime(model, list(weights), budget, left)
    return anytime_search(
        model, weights=weights, max_expansions=budget, time_limit=left,
        require_successors=False,
    )  # fmt: skip


def _backend(opts: PlannerOptions, model: BipedStepModel) -> str:
    """The search core the options choose for the model.

    ``"auto"``: compiled on static grids whose footprint masks fit the compiled core's
    64-bit rows, else python.
    """
    width = 2 * model.chk0.masks.radius_cells + 1  # cells across a footprint mask
    backend = opts.backend
    if backend == "auto":
        backend = "python" if model.dynamic or width > MASK_WORD_CELLS else "compiled"
    if backend == "compiled" and model.dynamic:
        raise FootstepError("the compiled backend plans on static grids only; use 'python'")
    if backend == "compiled" and width > MASK_WORD_CELLS:
        raise FootstepError(
            f"the compiled backend checks footprints at most {MASK_WORD_CELLS} cells "
            f"across; this foot with footprint_margin_m={opts.footprint_margin_m} m spans "
            f"{width} cells of {model.ref.resolution} m: use 'python' or 'auto', a coarser "
            f"grid or a smaller margin"
        )
    return backend


def _search_once(
    model: BipedStepModel, backend: str, weight: float, budget: int, left: float
) -> SearchResult:
    """One weighted A* on the chosen core."""
    if backend == "compiled":
        from repertoire.planning.footstep.fastcore import compiled_search

        return compiled_search(model, weight, budget, left)
    return search(
        model, weight=weight, max_expansions=budget, time_limit=left, require_successors=False
    )
