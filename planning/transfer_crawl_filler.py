"""Gap filler for the transfer search from the footstep planner's quadruped crawl model.

Adapts :func:`repertoire.planning.footstep.quadruped.plan_crawl` (the
second-generation footstep planner, issue 9) to the :class:`GapFiller` protocol of
:mod:`repertoire.planning.transfer_search`: one planner, not a second copy.

The crawl planner's goal is a point for the feet's centroid (within its
``goal_radius``), not a whole stance, so a filled gap ends with the feet's centroid
near the target stance's centroid; the remaining foot offsets (up to the goal
radius plus the lattice's offsets) are left to the executor that starts the next
recorded step. Planned footholds (ground points) are raised by the foot radius to
foot centres, like library stances. The planner's statuses map to the protocol's:
SUCCESS -> reached, TIME_LIMIT -> time_limit, NODE_LIMIT with steps -> partial,
anything else -> failed.
"""

import dataclasses

import numpy as np
from repertoire.models.littledog import FOOT_RADIUS
from repertoire.planning.footstep.quadruped import (
    CrawlParams,
    HeightMap,
    plan_crawl,
)
from repertoire.planning.footstep.types import PlanStatus
from repertoire.planning.transfer_search import GapFill, PlannedStep, TransferSearchError


@dataclasses.dataclass
class CrawlGapFiller:
    """A :class:`GapFiller` planning crawl steps on a height map.

    Attributes:
        height_map: the terrain (``height_map_from_board`` of the new terrain).
        params: crawl model parameters.
        weight: heuristic weight of the planner's search.
        max_expansions: expansion budget per gap.
    """

    height_map: HeightMap
    params: CrawlParams = dataclasses.field(default_factory=CrawlParams)
    weight: float = 3.0
    max_expansions: int = 50_000

    def __call__(self, start: np.ndarray, target: np.ndarray, time_limit: float) -> GapFill:
        """Plans crawl steps from ``start`` (4, 3) towards ``target``'s centroid."""
        start = np.asarray(start, dtype=float)
        target = np.asarray(target, dtype=float)
        if start.shape != (4, 3) or target.shape != (4, 3):
            raise TransferSearchError(
                f"crawl gap filler needs (4, 3) stances, got {start.shape} and {target.shape}"
            )
        plan = plan_crawl(
            self.height_map,
            start[:, :2],
            target[:, :2].mean(axis=0),
            self.params,
            time_limit=max(float(time_limit), 1e-3),
            max_expansions=self.max_expansions,
            weight=self.weight,
        )
        steps: list[PlannedStep] = []
        cur = start.copy()
        for s in plan.steps:
            # The planner's footholds are ground contact points; stances here are foot centres.
            nxt = np.asarray(s.stance, dtype=float) + np.array([0.0, 0.0, FOOT_RADIUS])
            steps.append(PlannedStep(cur, nxt, int(s.foot)))
            cur = nxt
        if plan.status is PlanStatus.SUCCESS:
            status = "reached"
        elif plan.status is PlanStatus.TIME_LIMIT:
            status = "time_limit"
        elif plan.status is PlanStatus.NODE_LIMIT and steps:
            status = "partial"
        else:
            status = "failed"
        return GapFill(steps, status)
