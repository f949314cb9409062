"""Footstep planning for a biped (Chestnutt et al.): A* over state-dependent actions.

Public API: :class:`ActionTable`, :func:`nominal_action_table`, :class:`OccupancyGrid`,
:class:`DynamicEnvironment`, :class:`PlannerOptions`, :func:`plan_footsteps`,
:class:`FootstepPlan`, :func:`plan_mobile2d`; a generic weighted A* core
(:mod:`.search`) and a LittleDog crawl step model (:mod:`.quadruped`).
"""

from repertoire.planning.footstep.actions import (
    ACTIONS,
    ASIMO_LIKE,
    MIRROR,
    STEP_COST,
    BipedGeometry,
    apply_displacement,
    commanded_displacement,
    nominal_action_table,
    relative_displacement,
    state_dependent_example_table,
)
from repertoire.planning.footstep.environment import (
    DynamicEnvironment,
    MovingRectObstacle,
    OccupancyGrid,
    RectObstacle,
)
from repertoire.planning.footstep.mobile2d import Mobile2DPlan, plan_mobile2d
from repertoire.planning.footstep.planner import (
    AnytimePlan,
    PlannerOptions,
    plan_footsteps,
    plan_footsteps_anytime,
)
from repertoire.planning.footstep.receding import RecedingResult, plan_receding_horizon
from repertoire.planning.footstep.types import (
    ActionTable,
    ActionTableError,
    Foot,
    FootstepError,
    FootstepPlan,
    GridError,
    PlanStatus,
    parse_foot,
)

__all__ = [
    "ACTIONS",
    "ASIMO_LIKE",
    "MIRROR",
    "STEP_COST",
    "ActionTable",
    "ActionTableError",
    "BipedGeometry",
    "DynamicEnvironment",
    "Foot",
    "FootstepError",
    "FootstepPlan",
    "GridError",
    "Mobile2DPlan",
    "MovingRectObstacle",
    "OccupancyGrid",
    "PlanStatus",
    "PlannerOptions",
    "RecedingResult",
    "RectObstacle",
    "apply_displacement",
    "commanded_displacement",
    "nominal_action_table",
    "parse_foot",
    "plan_footsteps",
    "plan_footsteps_anytime",
    "AnytimePlan",
    "plan_mobile2d",
    "plan_receding_horizon",
    "relative_displacement",
    "state_dependent_example_table",
]
