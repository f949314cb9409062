"""A footstep plan as a signal source: the plan, and over time the stance and swing targets.

The math is :func:`plan_phase_at` (plain function); :class:`FootstepPlanSource` wraps it.
Timing follows :class:`~repertoire.planning.footstep.types.FootstepPlan`: step k (1..N)
swings the foot that stood at ``poses[k-2]`` (``initial_swing_pose`` for k = 1) to
``poses[k]`` during ``[times[k-1], times[k])`` while ``poses[k-1]`` is the stance foot.
"""

import bisect
import dataclasses
import math

from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, Context, LeafSystem
from repertoire.planning.footstep.types import FootstepError, FootstepPlan

from repertoire.checks import is_real


@dataclasses.dataclass
class PlanPhase:
    """Where the robot is in a plan at one time.

    Attributes:
        step_index: k: 0 before the first step, 1..N while (or after) step k swings.
        stance_pose: ``[x, y, yaw]`` of the stance foot.
        swing_start_pose: where the swing foot lifted off.
        swing_target_pose: where the swing foot lands.
        swing_phase: fraction of the step done, in [0, 1].
        swing_foot: 0 left, 1 right.
    """

    step_index: int
    stance_pose: list[float]
    swing_start_pose: list[float]
    swing_target_pose: list[float]
    swing_phase: float
    swing_foot: int


def plan_phase_at(plan: FootstepPlan, t: float) -> PlanPhase:
    """The step of ``plan`` under way at time ``t``.

    Before ``times[0]`` the robot stands (k = 0, phase 0, target = the initial swing foot);
    during ``[times[k-1], times[k])`` step k swings with phase
    ``(t - times[k-1]) / (times[k] - times[k-1])``; from ``times[N]`` on the last step
    is complete (k = N, phase 1). A plan without steps always gives k = 0, phase 0.

    Args:
        plan: the footstep plan.
        t: time (s).

    Raises:
        FootstepError: ``t`` not a number (NaN has no step: it fell through to an index
            past the plan's end).
    """
    if not (is_real(t) and not math.isnan(t)):
        raise FootstepError(f"plan_phase_at needs a time in seconds, got {t!r}")
    times = plan.times
    n = plan.num_steps
    other = 1 - int(plan.feet[0])
    if n == 0 or t < times[0]:
        return PlanPhase(
            0,
            list(plan.poses[0]),
            list(plan.initial_swing_pose),
            list(plan.initial_swing_pose),
            0.0,
            other,
        )
    if t >= times[n]:
        k, phase = n, 1.0
    else:
        k = bisect.bisect_right(times, t)  # times[k-1] <= t < times[k]
        phase = (t - times[k - 1]) / (times[k] - times[k - 1])
    start = plan.initial_swing_pose if k == 1 else plan.poses[k - 2]
    return PlanPhase(
        step_index=k,
        stance_pose=list(plan.poses[k - 1]),
        swing_start_pose=list(start),
        swing_target_pose=list(plan.poses[k]),
        swing_phase=float(phase),
        swing_foot=int(plan.feet[k]),
    )


class FootstepPlanSource(LeafSystem):
    """Outputs a footstep plan and, over time, the step under way.

    The plan is an abstract parameter (``SetPlan`` replaces it in a context), so a
    Monte-Carlo run can vary it without rebuilding the diagram. The outputs follow the
    plan's own ``times``. In the walking biped (``biped_walk``) the robot is placed on
    the start soles of the plan it was built with, and its ``CommandStepper`` refuses a
    different plan once the first step is commanded: set a plan there before the walk
    starts, with the same start soles (``execute_plan`` checks both).

    Output ports:
        plan: abstract :class:`FootstepPlan`.
        stance_foot_pose: ``[x, y, yaw]`` of the stance foot.
        swing_start_pose: ``[x, y, yaw]`` where the swing foot lifted off.
        swing_target_pose: ``[x, y, yaw]`` where the swing foot lands.
        step_index: ``[k]``.
        swing_phase: ``[phase]`` in [0, 1].
        swing_foot: ``[0]`` left or ``[1]`` right.

    Args:
        plan: the default plan.
    """

    def __init__(self, plan: FootstepPlan) -> None:
        super().__init__()
        self._check(plan)
        self._plan_index = self.DeclareAbstractParameter(AbstractValue.Make(plan))
        deps = {self.time_ticket(), self.all_parameters_ticket()}
        self._plan_port = self.DeclareAbstractOutputPort(
            "plan",
            lambda: AbstractValue.Make(plan),
            self._calc_plan,
            prerequisites_of_calc={self.all_parameters_ticket()},
        )
        self._stance_port = self.DeclareVectorOutputPort(
            "stance_foot_pose", 3, self._calc_stance, prerequisites_of_calc=deps
        )
        self._start_port = self.DeclareVectorOutputPort(
            "swing_start_pose", 3, self._calc_start, prerequisites_of_calc=deps
        )
        self._target_port = self.DeclareVectorOutputPort(
            "swing_target_pose", 3, self._calc_target, prerequisites_of_calc=deps
        )
        self._index_port = self.DeclareVectorOutputPort(
            "step_index", 1, self._calc_index, prerequisites_of_calc=deps
        )
        self._phase_port = self.DeclareVectorOutputPort(
            "swing_phase", 1, self._calc_phase, prerequisites_of_calc=deps
        )
        self._foot_port = self.DeclareVectorOutputPort(
            "swing_foot", 1, self._calc_foot, prerequisites_of_calc=deps
        )

    @staticmethod
    def _check(plan: FootstepPlan) -> None:
        if not isinstance(plan, FootstepPlan):
            raise FootstepError(
                f"FootstepPlanSource needs a FootstepPlan, got {type(plan).__name__}"
            )
        times = plan.times  # finite (the plan checks that)
        if not all(b > a for a, b in zip(times[:-1], times[1:])):
            raise FootstepError(f"plan times must increase strictly, got {times}")

    def SetPlan(self, context: Context, plan: FootstepPlan) -> None:
        """Replace the plan in ``context``.

        Args:
            context: this system's context.
            plan: the new plan.
        """
        self._check(plan)
        context.get_mutable_abstract_parameter(self._plan_index).set_value(plan)

    def get_plan(self, context: Context) -> FootstepPlan:
        """The plan held by ``context``.

        Args:
            context: this system's context.
        """
        return context.get_abstract_parameter(self._plan_index).get_value()

    def _phase(self, context: Context) -> PlanPhase:
        return plan_phase_at(self.get_plan(context), context.get_time())

    def _calc_plan(self, context: Context, output: AbstractValue) -> None:
        output.set_value(self.get_plan(context))

    def _calc_stance(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._phase(context).stance_pose)

    def _calc_start(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._phase(context).swing_start_pose)

    def _calc_target(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._phase(context).swing_target_pose)

    def _calc_index(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector([float(self._phase(context).step_index)])

    def _calc_phase(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector([self._phase(context).swing_phase])

    def _calc_foot(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector([float(self._phase(context).swing_foot)])
