"""The ball of the soccer worlds: its position read from the plant, its rolling resistance.

Two systems the dribbling worlds (``soccer_dribble``, ``soccer_plan``) wire beside
:class:`~repertoire.systems.dribble_ball.DribbleBall`.
"""

import math

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, Context, LeafSystem

from repertoire.errors import RepertoireError


class BodyXYReader(LeafSystem):
    """Reads the ``[x, y]`` position of a floating body (the ball) from the plant's state.

    Input ports:
        plant_state: the MultibodyPlant's full state ``[q, v]``.

    Output ports:
        xy: the body's world ``[x, y]``.
    """

    def __init__(self, plant, body_name: str = "ball"):
        """Creates the reader.

        Args:
            plant: the finalized plant (read for indices only).
            body_name: a floating body.
        """
        super().__init__()
        body = plant.GetBodyByName(body_name)
        if not body.is_floating_base_body():
            raise RepertoireError(f"body {body_name!r} is not a floating base body")
        # floating positions are [qw, qx, qy, qz, x, y, z]
        self._i = body.floating_positions_start() + 4
        self._in = self.DeclareVectorInputPort(
            "plant_state", plant.num_positions() + plant.num_velocities()
        )
        self.DeclareVectorOutputPort("xy", 2, self._calc)

    def _calc(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._in.Eval(context)[self._i : self._i + 2])


class RollingResistance(LeafSystem):
    """Rolling resistance of a ball on grass as a force at its centre.

    Point contact has no rolling friction, so a pushed ball would roll on for
    ever. This applies ``F = -m * decel * u`` in the horizontal plane with
    ``u = v_xy / max(|v_xy|, v_smooth)`` (a Coulomb-like resistance, linear
    below ``v_smooth`` so the ball comes to rest without chatter).

    Input ports:
        plant_state: the MultibodyPlant's full state ``[q, v]``.

    Output ports:
        spatial_forces: a list of one ``ExternallyAppliedSpatialForce`` (abstract),
            for the plant's ``applied_spatial_force`` input.
    """

    def __init__(self, plant, body_name: str = "ball", decel: float = 0.8, v_smooth: float = 0.05):
        """Creates the force element.

        Args:
            plant: the finalized plant (read for indices and mass only).
            body_name: a floating body.
            decel: deceleration of a freely rolling ball [m/s^2] (grass: ~0.5-1).
            v_smooth: speed below which the resistance is linear [m/s].
        """
        from pydrake.multibody.plant import ExternallyAppliedSpatialForce

        super().__init__()
        if not (math.isfinite(decel) and decel >= 0 and math.isfinite(v_smooth) and v_smooth > 0):
            raise RepertoireError(
                f"decel must be >= 0 and v_smooth > 0 (finite), got {decel}, {v_smooth}"
            )
        body = plant.GetBodyByName(body_name)
        if not body.is_floating_base_body():
            raise RepertoireError(f"body {body_name!r} is not a floating base body")
        self._body = body.index()
        self._v0 = plant.num_positions() + body.floating_velocities_start_in_v() + 3
        self._force = body.default_mass() * decel
        self._v_smooth = v_smooth
        self._in = self.DeclareVectorInputPort(
            "plant_state", plant.num_positions() + plant.num_velocities()
        )
        from pydrake.multibody.math import SpatialForce

        self._spatial_force, self._zero = SpatialForce, np.zeros(3)
        self._applied = ExternallyAppliedSpatialForce()
        self._applied.body_index = self._body
        self._applied.p_BoBq_B = np.zeros(3)
        self.DeclareAbstractOutputPort(
            "spatial_forces",
            lambda: AbstractValue.Make([ExternallyAppliedSpatialForce()]),
            self._calc,
        )

    def force(self, v_xy) -> np.ndarray:
        """The horizontal force [N] for a ball velocity ``[vx, vy]``."""
        vx, vy = float(v_xy[0]), float(v_xy[1])
        speed = max(float(np.hypot(vx, vy)), self._v_smooth)
        return np.array([-self._force * vx / speed, -self._force * vy / speed])

    def _calc(self, context: Context, output: AbstractValue) -> None:
        # evaluated on every plant step: one force object reused, its force replaced
        v = self._in.Eval(context)[self._v0 : self._v0 + 2]
        fx, fy = self.force(v)
        self._applied.F_Bq_W = self._spatial_force(self._zero, [fx, fy, 0.0])
        output.set_value([self._applied])
