"""Which of LittleDog's feet touch the terrain, from the plant's contact results.

Only the foot spheres of LittleDog collide (one per lower leg), so a foot is
down when a contact pair involving its lower-leg body pushes with at least
``min_force``.
"""

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.multibody.plant import ContactResults, MultibodyPlant
from pydrake.multibody.tree import ModelInstanceIndex
from pydrake.systems.framework import BasicVector, Context, LeafSystem

from repertoire.errors import RepertoireError
from repertoire.models.littledog import LEGS


def foot_contact_flags(
    contact_results: ContactResults, foot_bodies: list[int], min_force: float
) -> np.ndarray:
    """1.0 for each foot whose body has a contact pair with force >= ``min_force`` (N), else 0.

    Args:
        contact_results: the plant's contact results.
        foot_bodies: body indices (ints) of the four lower legs, ``LEGS`` order.
        min_force: smallest contact force magnitude counted as contact (N).
    """
    flags = np.zeros(len(foot_bodies))
    for i in range(contact_results.num_point_pair_contacts()):
        info = contact_results.point_pair_contact_info(i)
        if np.linalg.norm(info.contact_force()) < min_force:
            continue
        for body in (int(info.bodyA_index()), int(info.bodyB_index())):
            if body in foot_bodies:
                flags[foot_bodies.index(body)] = 1.0
    return flags


class FootContactSensor(LeafSystem):
    """Contact state of LittleDog's four feet.

    Input ports:
        contact_results: the plant's ``ContactResults`` (abstract).

    Output ports:
        contact: 4 flags (1.0 foot down, 0.0 in flight), ``LEGS`` order.
    """

    def __init__(
        self, plant: MultibodyPlant, instance: ModelInstanceIndex, min_force: float = 0.5
    ) -> None:
        """Args:
        plant: the finalized plant holding LittleDog.
        instance: LittleDog's model instance.
        min_force: smallest contact force counted as contact (N), > 0.
        """
        super().__init__()
        if not (np.isfinite(min_force) and min_force > 0.0):
            raise RepertoireError(f"min_force must be > 0 N, got {min_force}")
        self._bodies = [
            int(plant.GetBodyByName(f"{leg}_lower_leg", instance).index()) for leg in LEGS
        ]
        self._min_force = float(min_force)
        self.contact_results_input = self.DeclareAbstractInputPort(
            "contact_results", AbstractValue.Make(ContactResults())
        )
        self.contact_output = self.DeclareVectorOutputPort("contact", 4, self._calc)

    def _calc(self, context: Context, output: BasicVector) -> None:
        results = self.contact_results_input.Eval(context)
        output.SetFromVector(foot_contact_flags(results, self._bodies, self._min_force))


__all__ = ["FootContactSensor", "foot_contact_flags"]
