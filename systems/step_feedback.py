"""World-frame feedback for the walker: each step lands on its planned world pose.

The walking controller (:mod:`repertoire.systems.walking`) holds the soles, the CoM and
the pelvis in its own frame; the joint PD tracks leg angles relative to the pelvis. When
a stance sole turns or slides a little under load, the whole robot moves with it and the
next step lands correctly *relative to that sole* but off in the world. Open loop these
errors add up: 102 steps landed up to 0.27 m from their targets (session 32; about
0.07 deg and 0.1 mm per stance phase, 2.3 deg of heading over the walk).

A footstep executor on a real robot places each step from the measured stance foot.
Here, at each step's lift-off, the stance sole is measured in the world (``S_W``); the
controller holds it at ``S_C``. The world target ``T_W`` (the plan's pose of the step)
becomes the controller-frame landing ``T_C = S_C (S_W)^-1 T_W`` (:func:`retarget`), so
the swing sole, placed relative to the real stance sole, lands at ``T_W``. The same
transform re-expresses every later target (:func:`retarget_sequence`), so the next
correction is only the drift of one more step, and the CoM plan, replanned on the new
footsteps, moves by that much. Errors no longer add up from step to step.

A corrected step must stay within the step model's reach (:func:`check_step_reach`):
the step from the measured stance sole to the target may differ from the step the
command realizes open loop (the stepping rule) by at most :class:`StepReach`'s bounds
(the rule's step is what the timing and swing were made for; a plan made with a table
of other steps, such as the nominal table of commanded displacements, is not this
controller's), and the biped must be able to stand on both soles
(:func:`check_stance`). Out of reach, it raises instead of taking another step.
"""

import dataclasses
import math

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import (
    BasicVector,
    Context,
    DiscreteValues,
    EventStatus,
    LeafSystem,
)
from repertoire.models.biped import FOOT_WIDTH, SOLE_FRAMES, leg_ik, rotation_rpy
from repertoire.planning.footstep.types import FootstepPlan, wrap_angle
from repertoire.systems.walking import (
    FootstepSequence,
    SteppingRule,
    _empty_plan,
    _rounded,
    compose,
    feet_at_step,
    realize_plan,
    relative,
    whole_body_ik,
)

from repertoire.errors import RepertoireError


@dataclasses.dataclass
class StepReach:
    """How far a corrected step may differ from the step its command realizes.

    Attributes:
        max_correction_m: largest distance [m] between the corrected landing and the
            open-loop one, both relative to the stance sole. Default a quarter of the
            sole's length (0.16 m): drift corrections are millimetres per step.
        max_correction_rad: largest yaw difference [rad] (default about 6 deg).
    """

    max_correction_m: float = 0.04
    max_correction_rad: float = 0.10

    def validate(self) -> None:
        """Raises RepertoireError unless both bounds are finite and > 0."""
        for name in ("max_correction_m", "max_correction_rad"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise RepertoireError(f"StepReach.{name} must be finite and > 0, got {v!r}")


def retarget(stance_controller, stance_measured, target_world) -> np.ndarray:
    """The controller-frame landing that puts the swing sole on ``target_world``.

    ``compose(stance_controller, relative(stance_measured, target_world))``: the target
    taken from the measured stance sole, applied to where the controller holds it.

    Args:
        stance_controller: ``(x, y, yaw)`` of the stance sole in the controller's frame.
        stance_measured: ``(x, y, yaw)`` of the stance sole measured in the world.
        target_world: ``(x, y, yaw)`` world target of the swing sole.
    """
    return compose(
        np.asarray(stance_controller, float),
        relative(np.asarray(stance_measured, float), np.asarray(target_world, float)),
    )


def retarget_sequence(
    seq: FootstepSequence, k: int, stance_measured, targets_world
) -> FootstepSequence:
    """``seq`` with steps ``k..`` re-expressed from the stance sole measured at step ``k``.

    Steps before ``k`` (already landed) keep their poses; step ``j >= k`` gets
    :func:`retarget` of ``targets_world[j]`` with the stance sole of step ``k``.

    Args:
        seq: the sequence the controller walks now (controller frame).
        k: the step about to swing, ``0 <= k < seq.num_steps``.
        stance_measured: world ``(x, y, yaw)`` of step ``k``'s stance sole.
        targets_world: world ``(x, y, yaw)`` of every step's landing (``num_steps`` rows).
    """
    if not 0 <= k < seq.num_steps:
        raise RepertoireError(f"step {k} is not in 0..{seq.num_steps - 1}")
    if len(targets_world) != seq.num_steps:
        raise RepertoireError(
            f"{len(targets_world)} world targets for a sequence of {seq.num_steps} steps"
        )
    stance_c = feet_at_step(seq, k)[1 - seq.swing_feet[k]]
    poses = [list(p) for p in seq.poses[:k]]
    poses += [retarget(stance_c, stance_measured, t).tolist() for t in targets_world[k:]]
    return dataclasses.replace(seq, poses=poses)


def _xy_yaw(pose) -> list[float]:
    return _rounded((pose[0], pose[1], pose[-1]))


def check_stance(left, right, com, pelvis_height: float, *, what: str = "start soles") -> None:
    """Checks that the biped can stand on two soles.

    The walking IK bends joints past their limits or stretches a knee rather than stop,
    so soles it cannot stand on would be simulated anyway. The left sole must stand at
    least a sole's width (``FOOT_WIDTH``) to the left of the right one across the soles'
    mean heading (the soles would otherwise overlap or the legs cross), and both legs
    must reach their soles within the joint limits with the pelvis over ``com`` at
    ``pelvis_height``.

    Args:
        left: left sole ``[x, y, yaw]`` (or ``[x, y, z, yaw]``).
        right: right sole, the same form.
        com: desired CoM ``(x, y)``.
        pelvis_height: pelvis height [m].
        what: what the soles are, for the message.

    Raises:
        RepertoireError: naming both soles (rounded to 0.1 mm / 0.1 mrad) and what is
            wrong.
    """
    left = np.asarray(left, dtype=float)
    right = np.asarray(right, dtype=float)
    lp, rp = np.array([*left[:2], 0.0, left[-1]]), np.array([*right[:2], 0.0, right[-1]])
    yaw = math.atan2(math.sin(lp[3]) + math.sin(rp[3]), math.cos(lp[3]) + math.cos(rp[3]))
    gap = float(np.dot(lp[:2] - rp[:2], [-math.sin(yaw), math.cos(yaw)]))
    soles = f"left sole {_xy_yaw(lp)}, right sole {_xy_yaw(rp)} as [x, y, yaw]"
    if not gap >= FOOT_WIDTH - 1e-9:
        raise RepertoireError(
            f"the biped cannot stand on the {what} ({soles}): the left sole is "
            f"{gap:.3f} m left of the right one across their heading, needs >= "
            f"{FOOT_WIDTH} m (a sole's width)"
        )
    _, pelvis = whole_body_ik(np.asarray(com, float)[:2], lp, rp, pelvis_height, iterations=6)
    R_WP = rotation_rpy(0.0, 0.0, pelvis[3])
    for foot, side in ((lp, "left"), (rp, "right")):
        try:
            leg_ik(R_WP.T @ (foot[:3] - pelvis[:3]), R_WP.T @ rotation_rpy(0.0, 0.0, foot[3]), side)
        except RepertoireError as e:
            raise RepertoireError(f"the biped cannot stand on the {what} ({soles}): {e}") from e


def check_step_reach(
    k: int,
    action: str,
    swing_foot: int,
    stance_world,
    target_world,
    step_open_loop,
    reach: StepReach,
    pelvis_height: float,
) -> None:
    """Checks that step ``k``'s world target is within reach of its stance sole.

    Args:
        k: the step's index (for the message).
        action: the step's command (for the message).
        swing_foot: 0 left, 1 right.
        stance_world: world ``(x, y, yaw)`` of the stance sole.
        target_world: world ``(x, y, yaw)`` of the landing.
        step_open_loop: ``(dx, dy, dyaw)`` the command realizes, in the stance sole's frame.
        reach: the correction bounds.
        pelvis_height: pelvis height [m].

    Raises:
        RepertoireError: the step differs from the command's by more than ``reach``, or
            the biped cannot stand on the two soles; naming the step, both poses and by
            how much.
    """
    d = relative(np.asarray(stance_world, float), np.asarray(target_world, float))
    d0 = np.asarray(step_open_loop, float)
    off = float(np.hypot(*(d[:2] - d0[:2])))
    turn = abs(wrap_angle(d[2] - d0[2]))
    where = (
        f"step {k} ({action}, {('left', 'right')[swing_foot]} foot) to world target "
        f"{_xy_yaw(target_world)} from the stance sole at {_xy_yaw(stance_world)}"
    )
    if not (off <= reach.max_correction_m and turn <= reach.max_correction_rad):
        raise RepertoireError(
            f"{where} is out of the step model's reach: as a step [dx, dy, dyaw] "
            f"{_xy_yaw(d)} it is {off:.4f} m and {turn:.4f} rad from the step the command "
            f"realizes ({_xy_yaw(d0)}), bounds {reach.max_correction_m} m and "
            f"{reach.max_correction_rad} rad (a plan made with another table than this "
            "controller's, or a stance sole that slipped)"
        )
    stance, target = np.asarray(stance_world, float), np.asarray(target_world, float)
    left, right = (target, stance) if swing_foot == 0 else (stance, target)
    check_stance(left, right, 0.5 * (left[:2] + right[:2]), pelvis_height, what=f"soles of {where}")


def open_loop_steps(seq: FootstepSequence) -> list[np.ndarray]:
    """Each step's landing relative to its stance sole, as the stepping rule realizes it."""
    feet, out = feet_at_step(seq, 0), []
    for k in range(seq.num_steps):  # one pass (feet_at_step per step made it quadratic)
        pose = np.asarray(seq.poses[k], float)
        out.append(relative(feet[1 - seq.swing_feet[k]], pose))
        feet[seq.swing_feet[k]] = pose
    return out


def check_plan_reach(
    plan: FootstepPlan, rule: SteppingRule, reach: StepReach, pelvis_height: float
) -> None:
    """Checks every step of ``plan`` (stance at its planned pose) with :func:`check_step_reach`.

    Args:
        plan: the plan whose poses are the world targets.
        rule: the controller's stepping rule.
        reach: the correction bounds.
        pelvis_height: pelvis height [m].
    """
    reach.validate()
    seq = realize_plan(plan, rule)
    steps = open_loop_steps(seq)
    for k in range(seq.num_steps):
        check_step_reach(
            k,
            seq.actions[k],
            seq.swing_feet[k],
            plan.poses[k],
            plan.poses[k + 1],
            steps[k],
            reach,
            pelvis_height,
        )


class FootstepFeedback(LeafSystem):
    """Retargets each step at its lift-off so that it lands on the plan's world pose.

    At the first update at or after step k's lift-off (``command_times[k] +
    double_support``), the stance sole's measured world pose retargets steps k.. of the
    sequence (:func:`retarget_sequence`) to the plan's poses, after
    :func:`check_step_reach` (RepertoireError out of reach). Updates that retarget
    nothing leave the state untouched, so the CoM plan downstream is recomputed once per
    step.

    Input ports:
        footsteps: abstract :class:`FootstepSequence` (the stepping rule's, open loop).
        plan: abstract ``FootstepPlan`` (its poses are the world targets).
        soles: (6,) measured ``[x, y, yaw]`` of the left and the right sole.

    Output ports:
        footsteps: abstract :class:`FootstepSequence`, retargeted (controller frame).

    Discrete state: the next step to retarget and every step's landing (controller frame),
    sized for the plan it is built for: a plan of another length raises; one of the same
    length set before the first lift-off is walked as set.
    """

    def __init__(
        self,
        num_steps: int,
        pelvis_height: float,
        *,
        reach: StepReach | None = None,
        period: float = 0.005,
    ):
        """Creates the system.

        Args:
            num_steps: steps of the plan it will walk (the state holds each landing).
            pelvis_height: pelvis height [m] (for the stance check).
            reach: correction bounds (default :class:`StepReach`).
            period: update period [s] (a lift-off is seen at most this late).
        """
        super().__init__()
        if not (isinstance(num_steps, int) and num_steps >= 0):
            raise RepertoireError(f"num_steps must be an int >= 0, got {num_steps!r}")
        if not (math.isfinite(period) and period > 0):
            raise RepertoireError(f"period must be finite and > 0, got {period!r}")
        self._n = num_steps
        self._reach = reach or StepReach()
        self._reach.validate()
        self._pelvis_height = float(pelvis_height)
        empty = realize_plan(_empty_plan(), SteppingRule())
        self._footsteps = self.DeclareAbstractInputPort("footsteps", AbstractValue.Make(empty))
        self._plan = self.DeclareAbstractInputPort("plan", AbstractValue.Make(_empty_plan()))
        self._soles = self.DeclareVectorInputPort("soles", 6)
        # [next step to retarget, landing (x, y, yaw) of each step in the controller frame]
        self._state = self.DeclareDiscreteState(1 + 3 * num_steps)
        self.DeclareInitializationDiscreteUpdateEvent(self._initialize)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        self.DeclareAbstractOutputPort(
            "footsteps",
            lambda: AbstractValue.Make(empty),
            self._calc_footsteps,
            prerequisites_of_calc={
                self.discrete_state_ticket(self._state),
                self.input_port_ticket(self._footsteps.get_index()),
            },
        )

    def _inputs(self, context: Context) -> tuple[FootstepSequence, FootstepPlan]:
        seq, plan = self._footsteps.Eval(context), self._plan.Eval(context)
        if not isinstance(seq, FootstepSequence) or not isinstance(plan, FootstepPlan):
            raise RepertoireError(
                "FootstepFeedback needs a FootstepSequence and a FootstepPlan, got "
                f"{type(seq).__name__} and {type(plan).__name__}"
            )
        if not plan.num_steps == seq.num_steps == self._n:
            raise RepertoireError(
                f"FootstepFeedback was built for {self._n} steps; its plan has "
                f"{plan.num_steps} steps, its footsteps {seq.num_steps}: build it for the "
                "plan it walks"
            )
        return seq, plan

    def _walked(self, context: Context, x: np.ndarray) -> FootstepSequence:
        seq, _ = self._inputs(context)
        if x[0] == 0:  # nothing retargeted yet: the input's steps (a plan set before the
            return seq  # first command, which the CommandStepper allows, is walked as set)
        return dataclasses.replace(seq, poses=x[1:].reshape(-1, 3).tolist())

    def _initialize(self, context: Context, discrete_state: DiscreteValues) -> None:
        seq, _ = self._inputs(context)
        poses = np.asarray(seq.poses, float).reshape(-1)
        discrete_state.set_value(self._state, np.concatenate([[0.0], poses]))

    def _update(self, context: Context, discrete_state: DiscreteValues) -> EventStatus:
        x = context.get_discrete_state(self._state).get_value()
        k = int(x[0])
        if k >= self._n:
            return EventStatus.DidNothing()
        open_seq, plan = self._inputs(context)
        t = context.get_time()
        if t < open_seq.command_times[k] + open_seq.double_support:
            return EventStatus.DidNothing()
        seq = self._walked(context, x)
        steps = open_loop_steps(open_seq)
        soles = np.asarray(self._soles.Eval(context), float).reshape(2, 3)
        if not np.all(np.isfinite(soles)):
            raise RepertoireError(f"FootstepFeedback's soles must be finite, got {soles.tolist()}")
        targets = [list(p) for p in plan.poses[1:]]
        while k < seq.num_steps and t >= seq.command_times[k] + seq.double_support:
            stance = soles[1 - seq.swing_feet[k]]
            check_step_reach(
                k,
                seq.actions[k],
                seq.swing_feet[k],
                stance,
                targets[k],
                steps[k],
                self._reach,
                self._pelvis_height,
            )
            seq = retarget_sequence(seq, k, stance, targets)
            k += 1
        poses = np.asarray(seq.poses, float).reshape(-1)
        discrete_state.set_value(self._state, np.concatenate([[float(k)], poses]))
        return EventStatus.Succeeded()

    def _calc_footsteps(self, context: Context, output: AbstractValue) -> None:
        output.set_value(self._walked(context, context.get_discrete_state(self._state).get_value()))


class SolePoseSensor(LeafSystem):
    """Measured ``[x, y, yaw]`` of both soles from the plant's body poses.

    Input ports:
        body_poses: the plant's ``body_poses`` output (abstract).

    Output ports:
        soles: (6,) ``[x, y, yaw]`` of the left and the right sole frame in the world.
    """

    def __init__(self, plant, instance):
        """Creates the sensor.

        Args:
            plant: the finalized MultibodyPlant with the biped.
            instance: the biped's model instance.
        """
        super().__init__()
        frames = [plant.GetFrameByName(SOLE_FRAMES[s], instance) for s in ("left", "right")]
        self._bodies = [int(f.body().index()) for f in frames]
        self._X_BS = [f.GetFixedPoseInBodyFrame() for f in frames]
        self._poses = self.DeclareAbstractInputPort(
            "body_poses", plant.get_body_poses_output_port().Allocate()
        )
        self.DeclareVectorOutputPort("soles", 6, self._calc)

    def _calc(self, context: Context, output: BasicVector) -> None:
        poses = self._poses.Eval(context)
        out = []
        for b, X_BS in zip(self._bodies, self._X_BS):
            X = poses[b].multiply(X_BS)
            R = X.rotation().matrix()
            out += [X.translation()[0], X.translation()[1], math.atan2(R[1, 0], R[0, 0])]
        output.SetFromVector(out)


class ComSensor(LeafSystem):
    """The biped's whole-body centre of mass from the plant's state.

    Input ports:
        state: the plant's ``state`` output.

    Output ports:
        com: (3,) CoM of the model instance in the world [m].
    """

    def __init__(self, plant, instance):
        """Creates the sensor.

        Args:
            plant: the finalized MultibodyPlant with the biped.
            instance: the biped's model instance.
        """
        super().__init__()
        self._plant, self._instances = plant, [instance]
        self._plant_context = plant.CreateDefaultContext()  # scratch: positions set per call
        self._state = self.DeclareVectorInputPort("state", plant.num_multibody_states())
        self.DeclareVectorOutputPort("com", 3, self._calc)

    def _calc(self, context: Context, output: BasicVector) -> None:
        self._plant.SetPositionsAndVelocities(self._plant_context, self._state.Eval(context))
        com = self._plant.CalcCenterOfMassPositionInWorld(self._plant_context, self._instances)
        output.SetFromVector(com)


__all__ = [
    "ComSensor",
    "FootstepFeedback",
    "SolePoseSensor",
    "StepReach",
    "check_plan_reach",
    "check_stance",
    "check_step_reach",
    "open_loop_steps",
    "retarget",
    "retarget_sequence",
]
