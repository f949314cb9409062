"""Monitors of the arm worlds: logged body points and the ball-clearance running minimum.

:class:`BodyPointAndAxis` gives a body-fixed point and axis in the world (for named loggers);
:class:`ObstacleClearanceMonitor` keeps the smallest gap between the ball obstacle and the
arm or its load, from SceneGraph signed distances.
"""

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.geometry import QueryObject
from pydrake.math import RigidTransform
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
