"""The LittleDog quadruped: URDF (``package://repertoire/littledog/littledog.urdf``) and kinematics.

See :mod:`repertoire.models.littledog.kinematics` for the names of legs, joints
and foot frames, and the closed-form leg FK/IK.
"""

from repertoire.models.littledog.kinematics import (
    FOOT_FRAMES,
    FOOT_RADIUS,
    JOINT_NAMES,
    LEGS,
    STANDING_HEIGHT,
    LegGeometry,
    leg_fk,
    leg_geometry,
    leg_ik,
    nominal_foot_positions,
    standing_configuration,
)

URDF_PATH = "littledog/littledog.urdf"
"""Model path below models/ (use with ``repertoire.models.package_url``)."""

__all__ = [
    "FOOT_FRAMES",
    "FOOT_RADIUS",
    "JOINT_NAMES",
    "LEGS",
    "STANDING_HEIGHT",
    "URDF_PATH",
    "LegGeometry",
    "leg_fk",
    "leg_geometry",
    "leg_ik",
    "nominal_foot_positions",
    "standing_configuration",
]
