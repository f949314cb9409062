"""Monitors of the arm worlds: logged body points, the ball clearance, the grasp slip, the placing.

:class:`BodyPointAndAxis` gives a body-fixed point and axis in the world (for named loggers);
:class:`ObstacleClearanceMonitor` keeps the smallest gap between the ball obstacle and the
arm or its load, from SceneGraph signed distances; :class:`GraspSlipMonitor` keeps the
largest distance a held object moved in the hand; :class:`PlacementMonitor` says when a
placed object stands on its target at rest (the release's start gate) and records where it
stood when the release began.
"""

from collections.abc import Sequence

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.geometry import QueryObject
from pydrake.math import RigidTransform
from pydrake.multibody.math import SpatialVelocity
from pydrake.systems.framework import BasicVector, Context, LeafSystem
from repertoire.systems.arm_goals import check_body_index
from repertoire.systems.task_space_reach import finite_3vector

from repertoire.errors import RepertoireError


class BodyPointAndAxis(LeafSystem):
    """The origin and z axis of a frame Q fixed to a body, in the world (for logging).

    Input ports:
        body_poses: the plant's body poses (abstract).

    Output ports:
        point_and_axis: [p_WQ (3), z axis of Q in W (3)] (6).
    """

    def __init__(self, body: int, X_BQ: RigidTransform):
        """Builds the system.

        Args:
            body: index of the body in the plant's body poses (>= 0).
            X_BQ: pose of the frame Q in the body's frame.

        Raises:
            RepertoireError: a body that is not an index >= 0.
        """
        super().__init__()
        self._body = check_body_index(body, "body")
        self._X_BQ = X_BQ
        self._poses = self.DeclareAbstractInputPort(
            "body_poses", AbstractValue.Make([RigidTransform()])
        )
        self.DeclareVectorOutputPort("point_and_axis", 6, self._calc)

    def _calc(self, context: Context, output: BasicVector) -> None:
        poses = self._poses.Eval(context)
        if self._body >= len(poses):
            raise RepertoireError(
                f"body {self._body} is not in body_poses, which holds {len(poses)} poses"
            )
        X = poses[self._body] @ self._X_BQ
        output.SetFromVector(np.concatenate([X.translation(), X.rotation().matrix()[:, 2]]))


class ObstacleClearanceMonitor(LeafSystem):
    """Running minimum of the signed distance between the ball and the robot or its load.

    Every ``period`` it asks SceneGraph for the signed distance from the ball's
    centre to each watched collision geometry (``ComputeSignedDistanceToPoint``:
    exact for the spheres, capsules, boxes and cylinders of arm7 and the cup) and
    subtracts the ball's radius: the gap between the ball's surface and the
    geometry, negative when they overlap.

    Input ports:
        geometry_query: SceneGraph's query object.

    Output ports:
        clearance: [running minimum gap (m), time of the minimum (s)] (2).
    """

    def __init__(
        self,
        centre_W: np.ndarray,
        radius: float,
        geometries: list,
        *,
        period: float,
        horizon: float = 0.5,
    ) -> None:
        """Builds the monitor.

        Args:
            centre_W: the ball's centre (fixed) in W.
            radius: the ball's radius.
            geometries: GeometryIds watched (the arm's and the carried object's).
            period: update period [s].
            horizon: geometries farther than this from the centre are not reported; the
                gap then reads ``horizon - radius``.

        Raises:
            RepertoireError: a centre that is not a finite 3-vector, a radius < 0, a
                period <= 0 or a horizon not beyond the radius.
        """
        super().__init__()
        centre = finite_3vector("centre_W", centre_W)
        if not (np.isfinite(radius) and radius >= 0.0):
            raise RepertoireError(f"radius must be finite and >= 0 m, got {radius}")
        if not (np.isfinite(period) and period > 0.0):
            raise RepertoireError(f"period must be finite and > 0 s, got {period}")
        if not (np.isfinite(horizon) and horizon > radius):
            raise RepertoireError(
                f"horizon must be finite and beyond the radius {radius} m, got {horizon}"
            )
        self._centre = centre
        self._radius = float(radius)
        self._ids = set(geometries)
        self._horizon = float(horizon)
        self._query = self.DeclareAbstractInputPort(
            "geometry_query", AbstractValue.Make(QueryObject())
        )
        self._state = self.DeclareDiscreteState([self._horizon - self._radius, 0.0])
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        self.DeclareStateOutputPort("clearance", self._state)

    def gap(self, context: Context) -> float:
        """The current gap between the ball and the nearest watched geometry [m]."""
        query = self._query.Eval(context)
        gaps = [
            d.distance
            for d in query.ComputeSignedDistanceToPoint(self._centre, self._horizon)
            if d.id_G in self._ids
        ]
        return float(min(gaps, default=self._horizon)) - self._radius

    def _update(self, context: Context, state) -> None:
        gap = self.gap(context)
        best = context.get_discrete_state(self._state).value()
        if gap < best[0]:
            state.get_mutable_vector(self._state).SetFromVector([gap, context.get_time()])


class GraspSlipMonitor(LeafSystem):
    """Running maximum of how far a held object moved in the hand (grasp slip).

    Every ``period``, while the active segment is one of ``held_segments``, it reads the
    object's origin O in the tcp frame T, ``p_TO = X_WT^-1 p_WO`` with ``X_WT = X_WH X_HT``.
    The first reading of a hold is the hold's reference; the slip is ``|p_TO - reference|``.
    Leaving the held segments ends the hold (the maximum is kept; a later hold takes a new
    reference). A firm grasp keeps ``p_TO`` fixed whatever the hand does, so the slip
    measures the object sliding or rolling between the fingers, which the tcp's tracking
    cannot show.

    Input ports:
        body_poses: the plant's body poses (abstract).
        segment: the active segment's index (1).

    Output ports:
        slip: [running maximum slip (m), time of the maximum (s)] (2).
        hold_reference: p_TO at the start of the latest hold [m] (3; zeros before any):
            where the grasp put the object in the hand.
    """

    def __init__(
        self,
        hand: int,
        held_object: int,
        X_HT: RigidTransform,
        held_segments: Sequence[int],
        *,
        period: float,
    ) -> None:
        """Builds the monitor.

        Args:
            hand: index of the hand body in the body poses.
            held_object: index of the held object's body.
            X_HT: pose of the tcp frame in the hand's frame.
            held_segments: indices of the segments during which the object is held.
            period: update period [s].

        Raises:
            RepertoireError: a body that is not an index >= 0, the same body twice, no
                held segment or one that is not a whole number >= 0, or a period <= 0.
        """
        super().__init__()
        self._hand = check_body_index(hand, "hand")
        self._object = check_body_index(held_object, "held_object")
        if self._hand == self._object:
            raise RepertoireError(f"hand and held_object must differ, both are {self._hand}")
        held = list(held_segments)
        if not held or not all(
            isinstance(k, (int, np.integer)) and not isinstance(k, bool) and k >= 0 for k in held
        ):
            raise RepertoireError(
                f"held_segments must list one or more segment indices >= 0, got {held_segments}"
            )
        if not (np.isfinite(period) and period > 0.0):
            raise RepertoireError(f"period must be finite and > 0 s, got {period}")
        self._held = {int(k) for k in held}
        self._X_HT = X_HT
        self._poses = self.DeclareAbstractInputPort(
            "body_poses", AbstractValue.Make([RigidTransform()])
        )
        self._segment = self.DeclareVectorInputPort("segment", 1)
        # [max slip, its time, holding (0/1), reference p_TO (3)]
        self._state = self.DeclareDiscreteState(6)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        self.DeclareVectorOutputPort(
            "slip",
            2,
            lambda c, o: o.SetFromVector(c.get_discrete_state(self._state).value()[:2]),
            prerequisites_of_calc={self.discrete_state_ticket(self._state)},
        )
        self.DeclareVectorOutputPort(
            "hold_reference",
            3,
            lambda c, o: o.SetFromVector(c.get_discrete_state(self._state).value()[3:]),
            prerequisites_of_calc={self.discrete_state_ticket(self._state)},
        )

    def object_in_tcp(self, context: Context) -> np.ndarray:
        """The held object's origin in the tcp frame, p_TO [m] (3)."""
        poses = self._poses.Eval(context)
        top = max(self._hand, self._object)
        if top >= len(poses):
            raise RepertoireError(
                f"body {top} is not in body_poses, which holds {len(poses)} poses"
            )
        X_WT = poses[self._hand] @ self._X_HT
        return X_WT.inverse() @ poses[self._object].translation()

    def _update(self, context: Context, state) -> None:
        x = context.get_discrete_state(self._state).value().copy()
        if int(round(self._segment.Eval(context)[0])) not in self._held:
            x[2] = 0.0
        elif x[2] == 0.0:
            x[2], x[3:] = 1.0, self.object_in_tcp(context)
        else:
            slip = float(np.linalg.norm(self.object_in_tcp(context) - x[3:]))
            if slip > x[0]:
                x[0], x[1] = slip, context.get_time()
        state.get_mutable_vector(self._state).SetFromVector(x)


def placement_error(
    p_WO: np.ndarray, v_WO: np.ndarray, p_WG: np.ndarray, v_WG: np.ndarray
) -> tuple[float, float]:
    """How far an object is from its target horizontally, and how fast it moves relative to it.

    Args:
        p_WO: the object's origin in W [m] (3).
        v_WO: its velocity in W [m/s] (3).
        p_WG: the target point in W [m] (3).
        v_WG: the target point's velocity in W [m/s] (3).

    Returns:
        (``|(p_WO - p_WG)_xy|`` [m], ``|(v_WO - v_WG)_xy|`` [m/s]).
    """
    d = np.asarray(p_WO, float)[:2] - np.asarray(p_WG, float)[:2]
    v = np.asarray(v_WO, float)[:2] - np.asarray(v_WG, float)[:2]
    return float(np.hypot(*d)), float(np.hypot(*v))


class PlacementMonitor(LeafSystem):
    """Whether a placed object stands on its target at rest, and where it stood at the release.

    The target G is a point ``p_BG`` (world axes) from the origin of a target body B (the
    coaster), or a fixed point in W. The object is settled when its origin O is within
    ``tolerance`` of G horizontally and moves slower than ``speed_tolerance`` relative to B
    horizontally (:func:`placement_error`): the release may let go of it there. Every
    ``period`` it watches the active segment; at the first check of ``release_segment`` it
    records the object's distance, speed and whether it had settled (a release that began
    because the wait ran out, not because the object settled, reads 0 there).

    Input ports:
        body_poses: the plant's body poses (abstract).
        body_spatial_velocities: the plant's body spatial velocities (abstract).
        segment: the active segment's index (1).

    Output ports:
        settled (1): 1 when the object is within both tolerances now, else 0 (a
            :class:`repertoire.systems.dmp_sequencer.DmpSequencer` ``start_gate``).
        placement (2): [distance (m), relative speed (m/s)] now.
        at_release (3): [distance, relative speed, settled] at the first check of
            ``release_segment`` (NaN before it).
    """

    def __init__(
        self,
        held_object: int,
        target_body: int,
        p_BG: np.ndarray,
        *,
        tolerance: float,
        speed_tolerance: float,
        release_segment: int,
        period: float,
    ) -> None:
        """Builds the monitor.

        Args:
            held_object: index of the placed object's body in the body poses.
            target_body: index of the target body, or -1 for a fixed target ``p_BG`` in W.
            p_BG: the target point from the target body's origin, in world axes [m] (3;
                as :class:`repertoire.systems.arm_goals.GoalSchedule`'s tracked goals).
            tolerance: largest horizontal distance of a settled object from G [m] (> 0).
            speed_tolerance: largest horizontal speed of a settled object relative to the
                target body [m/s] (> 0).
            release_segment: the segment that lets go of the object (>= 0).
            period: update period [s].

        Raises:
            RepertoireError: a body that is not an index (>= 0; the target also -1), the
                object as its own target, a target point that is not a finite 3-vector,
                a tolerance, speed tolerance or period that is not > 0, or a release
                segment that is not a whole number >= 0.
        """
        super().__init__()
        self._object = check_body_index(held_object, "held_object")
        self._target = check_body_index(target_body, "target_body", fixed_allowed=True)
        if self._target == self._object:
            raise RepertoireError(
                f"held_object and target_body must differ, both are {self._object}"
            )
        self._p_BG = finite_3vector("p_BG", p_BG)
        for name, value in (
            ("tolerance", tolerance),
            ("speed_tolerance", speed_tolerance),
            ("period", period),
        ):
            if not (isinstance(value, int | float) and np.isfinite(value) and value > 0.0):
                raise RepertoireError(f"{name} must be a finite number > 0, got {value!r}")
        if not (
            isinstance(release_segment, int | np.integer)
            and not isinstance(release_segment, bool)
            and release_segment >= 0
        ):
            raise RepertoireError(
                f"release_segment must be a segment index >= 0, got {release_segment!r}"
            )
        self._tolerance, self._speed_tolerance = float(tolerance), float(speed_tolerance)
        self._release = int(release_segment)
        self._poses = self.DeclareAbstractInputPort(
            "body_poses", AbstractValue.Make([RigidTransform()])
        )
        self._velocities = self.DeclareAbstractInputPort(
            "body_spatial_velocities", AbstractValue.Make([SpatialVelocity()])
        )
        self._segment = self.DeclareVectorInputPort("segment", 1)
        # [recorded (0/1), distance, speed, settled] at the release's first check
        self._state = self.DeclareDiscreteState(np.zeros(4))
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        self.DeclareVectorOutputPort(
            "settled", 1, lambda c, o: o.SetFromVector([float(self._settled(*self.placement(c)))])
        )
        self.DeclareVectorOutputPort(
            "placement", 2, lambda c, o: o.SetFromVector(self.placement(c))
        )
        self.DeclareVectorOutputPort(
            "at_release",
            3,
            self._calc_at_release,
            prerequisites_of_calc={self.discrete_state_ticket(self._state)},
        )

    def placement(self, context: Context) -> np.ndarray:
        """[distance (m), relative speed (m/s)] of the object from its target now."""
        poses = self._poses.Eval(context)
        velocities = self._velocities.Eval(context)
        top = max(self._object, self._target)
        if top >= min(len(poses), len(velocities)):
            raise RepertoireError(
                f"body {top} is not in body_poses and body_spatial_velocities, which hold "
                f"{len(poses)} and {len(velocities)}"
            )
        p_WG, v_WG = self._p_BG, np.zeros(3)
        if self._target >= 0:
            p_WG = poses[self._target].translation() + self._p_BG
            v_WG = velocities[self._target].translational()
        return np.array(
            placement_error(
                poses[self._object].translation(),
                velocities[self._object].translational(),
                p_WG,
                v_WG,
            )
        )

    def _settled(self, distance: float, speed: float) -> bool:
        return distance <= self._tolerance and speed <= self._speed_tolerance

    def _calc_at_release(self, context: Context, output: BasicVector) -> None:
        x = context.get_discrete_state(self._state).value()
        output.SetFromVector(x[1:] if x[0] else np.full(3, np.nan))

    def _update(self, context: Context, state) -> None:
        x = context.get_discrete_state(self._state).value()
        if not x[0] and int(round(self._segment.Eval(context)[0])) == self._release:
            distance, speed = self.placement(context)
            settled = float(self._settled(distance, speed))
            state.get_mutable_vector(self._state).SetFromVector([1.0, distance, speed, settled])
        else:
            state.get_mutable_vector(self._state).SetFromVector(x)
