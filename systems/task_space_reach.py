"""The arm's reach: a sphere that bounds it and exact attainability of a pose.

:func:`reach_bound` and :func:`check_reachable` give the sphere no configuration of a serial
chain leaves (a cheap, conservative test); :func:`pose_position_residual` is its exact (IK)
counterpart: how close a frame can come to a position with a given orientation within the
joint limits. :class:`repertoire.systems.task_space.ResolvedMotionRateIK` and the arm worlds
use both to refuse or report targets the arm cannot reach.
"""

import numpy as np
from pydrake.math import RotationMatrix
from pydrake.multibody.inverse_kinematics import InverseKinematics
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import Frame
from pydrake.solvers import Solve

from repertoire.errors import RepertoireError


def finite_3vector(name: str, value) -> np.ndarray:
    """``value`` as a float 3-vector, or a RepertoireError naming ``name`` and the value."""
    v = np.asarray(value, dtype=float)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise RepertoireError(f"{name} must be a finite 3-vector, got {v.tolist()}")
    return v


def reach_bound(points: np.ndarray) -> float:
    """Upper bound on the reach of a serial chain: the length of its joint polyline.

    Args:
        points: ``k x 3`` world positions of the shoulder (first row), every joint
            origin down the chain, and the end-effector point (last row).

    Returns:
        The summed segment lengths; no configuration puts the end-effector
        farther than this from the first point (triangle inequality).
    """
    points = np.asarray(points, dtype=float)
    return float(np.sum(np.linalg.norm(np.diff(points, axis=0), axis=1)))


def check_reachable(p_W: np.ndarray, center_W: np.ndarray, reach: float, *, what: str) -> None:
    """Raises a clear error if ``p_W`` is outside the sphere ``center_W``, ``reach``.

    Args:
        p_W: target point in the world frame.
        center_W: shoulder point in the world frame.
        reach: reach radius (see :func:`reach_bound`).
        what: what the target is, for the message (e.g. ``"grasp goal"``).

    Raises:
        RepertoireError: the target is out of reach (says by how much).
    """
    p_W = finite_3vector(what, p_W)
    distance = float(np.linalg.norm(p_W - center_W))
    if distance > reach:
        raise RepertoireError(
            f"IK target out of reach: {what} {np.round(p_W, 4).tolist()} is {distance:.3f} m "
            f"from the shoulder {np.round(center_W, 4).tolist()}, beyond the arm's reach of "
            f"{reach:.3f} m by {distance - reach:.3f} m; move the target closer"
        )


def pose_position_residual(
    plant: MultibodyPlant,
    frame_E: Frame,
    p_W: np.ndarray,
    R_WE: RotationMatrix,
    seeds: list[np.ndarray],
    *,
    orientation_tolerance: float,
    good_enough: float = 0.0,
) -> float:
    """How close the origin of ``frame_E`` can come to ``p_W`` with the orientation ``R_WE``.

    A Drake ``InverseKinematics`` program on ``plant``: the joints within their
    position limits, the angle between ``R_WE`` and the orientation of ``frame_E``
    at most ``orientation_tolerance``, and the cost ``|p_WE - p_W|^2``. It is solved
    locally from each seed in turn, stopping at the first solution within
    ``good_enough`` of ``p_W``; the smallest distance found is returned. Unlike
    :func:`check_reachable` (a sphere that bounds the reach from above), a residual
    above the caller's tolerance means the pose is not attainable, unless every
    seed fell in a worse local minimum than the true one (give several seeds).

    Args:
        plant: finalized plant (the arm alone; every position is free within limits).
        frame_E: the end-effector frame of ``plant``.
        p_W: target position of the frame's origin in W (3).
        R_WE: target orientation of the frame in W.
        seeds: initial guesses of the plant's positions, tried in order (one or more).
        orientation_tolerance: largest angle between the attained and the target
            orientation [rad].
        good_enough: stop at the first seed whose solution comes this close [m].

    Returns:
        The smallest |p_WE - p_W| over the solved seeds [m]; inf if no solve succeeded.

    Raises:
        RepertoireError: a bad target, tolerance or seed.
    """
    p_W = finite_3vector("the target position", p_W)
    if not (np.isfinite(orientation_tolerance) and orientation_tolerance >= 0.0):
        raise RepertoireError(
            f"orientation_tolerance must be finite and >= 0 rad, got {orientation_tolerance}"
        )
    if len(seeds) == 0:
        raise RepertoireError("pose_position_residual needs one or more seeds")
    ik = InverseKinematics(plant, with_joint_limits=True)
    ik.AddOrientationConstraint(
        frame_E, RotationMatrix(), plant.world_frame(), R_WE, orientation_tolerance
    )
    ik.AddPositionCost(frame_E, np.zeros(3), plant.world_frame(), p_W, np.eye(3))
    context = plant.CreateDefaultContext()
    best = np.inf
    for seed in seeds:
        seed = np.asarray(seed, dtype=float)
        if seed.shape != (plant.num_positions(),) or not np.all(np.isfinite(seed)):
            raise RepertoireError(
                f"each seed must be {plant.num_positions()} finite joint positions, got {seed!r}"
            )
        result = Solve(ik.prog(), seed)
        if not result.is_success():
            continue
        plant.SetPositions(context, result.GetSolution(ik.q()))
        distance = float(np.linalg.norm(frame_E.CalcPoseInWorld(context).translation() - p_W))
        best = min(best, distance)
        if best <= good_enough:
            break
    return best
