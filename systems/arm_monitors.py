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


class BodyPointAndAxis(LeafSystem):
    """The origin and z axis of a frame Q fixed to a body, in the world (for logging).

    Input ports:
        body_poses: the plant's body poses (abstract).

    Output ports:
        point_and_axis: [p_WQ (3), z axis of Q in W (3)] (6).
    """

    def __init__(self, body: int, X_BQ: RigidTransform):
        super().__init__()
        self._body = int(body)
        self._X_BQ = X_BQ
        self._poses = self.DeclareAbstractInputPort(
            "body_poses", AbstractValue.Make([RigidTransform()])
        )
        self.DeclareVectorOutputPort("point_and_axis", 6, self._calc)

    def _calc(self, context: Context, output: BasicVector) -> None:
        X = self._poses.Eval(context)[self._body] @ self._X_BQ
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
        """
        super().__init__()
        self._centre = np.asarray(centre_W, dtype=float).reshape(3)
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
