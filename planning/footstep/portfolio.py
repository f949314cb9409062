"""The anytime planner's second search: one weighted A* in a second thread beside it.

:func:`~repertoire.planning.footstep.planner.plan_footsteps_anytime` with
``second_search=True`` runs, beside its own searches (ARA*, restarts, the admissible
search), ONE fresh weighted A* at :data:`SECOND_WEIGHT` on the next finer lattice (the
first refinement's: half the cell, twice the yaw bins; 2.5 cm / 72 from the defaults), with
the same cost-to-go heuristic, in a second thread with its own time limit and expansion
budget (the options'). The compiled search loop releases the GIL, so on a machine with two
free cores both run at full speed; :func:`merge_second` adds its plan to the anytime results
where it is cheaper than the best plan found by then.

On 114 12 m floors at 30 % occupancy the two, each with 1.6 M expansions (about 1 s on one
core), left 3 plans above 1.05 of the admissible mode's where the anytime pipeline alone
left 10, and 0 of 27 unseen floors where it left 1; with 1 s of wall time on an otherwise
idle 2-core machine, 4 of 114 where it left 11 (docs/results/footstep.md). Two searches at
once each run about 5-10 % slower than alone (memory): a plan the pipeline alone finds just
before the limit can come too late (one floor of 141 had no plan by 1 s). With fewer than two
free cores the threads take time from each other (not measured). With the default Dijkstra
cost-to-go (inadmissible) the weight bounds nothing; the result's ``bound`` is the search's
weight, as for the pipeline's own searches
(:class:`~repertoire.planning.footstep.planner.AnytimePlan`).
"""

from __future__ import annotations

import copy
import dataclasses
import threading
import time
from typing import TYPE_CHECKING

from repertoire.planning.footstep.biped_model import BipedStepModel
from repertoire.planning.footstep.search import SearchResult
from repertoire.planning.footstep.types import FootstepError, PlanStatus

if TYPE_CHECKING:
    from repertoire.planning.footstep.planner import AnytimePlan, PlannerOptions

SECOND_WEIGHT = 1.5
"""The second search's heuristic weight."""


def second_options(opts: PlannerOptions) -> PlannerOptions:
    """The second search's options: the first refinement's lattice, weight 1.5, one search."""
    return dataclasses.replace(
        opts,
        heuristic_weight=SECOND_WEIGHT,
        xy_resolution=opts.xy_resolution / 2,
        yaw_bins=int(opts.yaw_bins) * 2,
        refinements=0,
    )


class SecondSearch:
    """The second search, started in a thread at construction; :meth:`merge` joins it.

    The step model is built in the calling thread (its cost-to-go field, shared with the
    pipeline's models, is built once); the search gets a private copy of the field's
    arrays, which a lazily settled field writes into.

    Args:
        world, start, start_foot, goal, table, kwargs: as in ``plan_footsteps``.
        opts: the anytime call's validated options (its time limit and expansion budget
            are the second search's own).
        t_begin: the anytime call's clock (``time.perf_counter``) its results count from.

    Raises:
        FootstepError: the compiled core does not apply (a dynamic world, footprint masks
            too wide, or ``backend="python"``): without it the second search would hold the
            GIL.
    """

    def __init__(self, world, start, start_foot, goal, table, opts, kwargs, t_begin) -> None:
        from repertoire.planning.footstep.cores import _backend

        self.t_begin = t_begin
        self.model = BipedStepModel(world, start, start_foot, goal, table, second_options(opts),
                                    **kwargs)  # fmt: skip
        if _backend(self.model.opts, self.model) != "compiled":
            raise FootstepError(
                "second_search runs on the compiled core only (static grids, footprint masks "
                "up to 64 cells across)"
            )
        if self.model.h_lazy is not None:
            field = copy.copy(self.model.h_lazy)
            # every array the resumable search writes: values, heap, sizes, and the
            # parameters (a retarget rewrites the target cell p[6], p[7])
            field.f, field.i, field.size = field.f.copy(), field.i.copy(), field.size.copy()
            field.p = field.p.copy()
            self.model.h_lazy = field
        self.result: SearchResult | None = None
        self.t_found = t_begin
        self.error: BaseException | None = None
        budget = int(opts.max_expansions) if opts.max_expansions > 0 else 2**62
        left = max(opts.time_limit - (time.perf_counter() - t_begin), 1e-9)
        self.thread = threading.Thread(target=self._run, args=(budget, left), daemon=True)
        self.thread.start()

    def _run(self, budget: int, left: float) -> None:
        from repertoire.planning.footstep.fastcore import compiled_search

        try:
            self.result = compiled_search(self.model, SECOND_WEIGHT, budget, left)
            self.t_found = time.perf_counter()
        except BaseException as exc:  # re-raised in the caller's thread by merge
            self.error = exc

    def merge(self, results: list[AnytimePlan]) -> list[AnytimePlan]:
        """Wait for the second search; the pipeline's ``results`` with its plan merged in."""
        from repertoire.planning.footstep.planner import AnytimePlan, _to_plan

        self.thread.join()
        if self.error is not None:
            raise self.error
        r = self.result
        if r is None or r.status is not PlanStatus.SUCCESS:
            return results
        elapsed = self.t_found - self.t_begin
        extra = AnytimePlan(_to_plan(self.model, r, elapsed), r.weight, r.bound, elapsed, 0.0)
        return merge_second(results, extra)


def merge_second(results: list[AnytimePlan], extra: AnytimePlan) -> list[AnytimePlan]:
    """The anytime ``results`` with the plan ``extra`` of a search that ran beside them.

    ``extra`` joins where it is cheaper (beyond rounding, as the pipeline's own plans) than
    every successful plan found no later than it (``elapsed_s``); the plans found after it
    stay only when cheaper than it, or as cheap with a tighter bound, so the costs stay
    non-increasing; once it joins, the results' partial plans (no plan found) are dropped.
    A plan ``extra`` that is not cheaper leaves ``results`` as they are.

    Args:
        results: the pipeline's results in order (costs non-increasing).
        extra: a successful plan, its ``elapsed_s`` on the same clock.
    """
    done = [p for p in results if p.plan.status is PlanStatus.SUCCESS]
    cost = extra.plan.cost
    before = [p for p in done if p.elapsed_s <= extra.elapsed_s]
    if before and not cost < min(p.plan.cost for p in before) * (1.0 - 1e-9):
        return list(results)
    after = [
        p
        for p in done
        if p.elapsed_s > extra.elapsed_s
        and (
            p.plan.cost < cost * (1.0 - 1e-9)
            or (p.plan.cost <= cost * (1.0 + 1e-9) and p.bound < extra.bound)
        )
    ]
    return [*before, extra, *after]


__all__ = ["SECOND_WEIGHT", "SecondSearch", "merge_second", "second_options"]
