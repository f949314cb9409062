"""Gaps in a demonstration's time stamps, bridged for the forcing-term fit.

The forcing term's basis functions are spaced equally in time; a basis function over a gap
between two samples rests only on the tails of its Gaussian, and least squares then sets its
weight to whatever fits the samples on either side, however the movement went in between
(a 5-D via-point demonstration, 122 random stamps over 0.61 s with a 51 ms gap near the
end: 5 % of the range off between samples from clean data with exact derivatives, 16 %
with 0.25 % noise). The learner fills such gaps with points on the quintic Hermite bridge
through the fitted position, velocity and acceleration at both ends (exact for
minimum-jerk segments, the shape the derivative estimates already assume), so that no step
is longer than half the basis spacing (:func:`repertoire.planning.dmp_learn.learn_dmp`).
"""

import numpy as np

from repertoire.errors import RepertoireError


def quintic_bridge(
    t: np.ndarray,
    x: np.ndarray,
    xd: np.ndarray,
    xdd: np.ndarray,
    gap: np.ndarray,
    tq: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The quintic Hermite interpolant between samples ``gap`` and ``gap + 1``, at ``tq``.

    The one quintic that matches position, velocity and acceleration at both samples (so
    exact for minimum-jerk segments): with ``h = t[gap + 1] - t[gap]`` and ``s = (tq -
    t[gap]) / h``, ``x(s) = sum_k c_k s^k`` with ``c_0 = x_0``, ``c_1 = h xd_0``, ``c_2 = h^2
    xdd_0 / 2`` and, from the end conditions ``p = x_1 - c_0 - c_1 - c_2``, ``q = h xd_1 - c_1
    - 2 c_2``, ``r = h^2 xdd_1 - 2 c_2``: ``c_3 = 10 p - 4 q + r / 2``, ``c_4 = -15 p + 7 q -
    r``, ``c_5 = 6 p - 3 q + r / 2``.

    Args:
        t: Sample times, shape (N,).
        x: Positions, shape (N, n).
        xd: Velocities, shape (N, n).
        xdd: Accelerations, shape (N, n).
        gap: Index of each query's left sample, shape (r,), in [0, N - 2].
        tq: Query times, shape (r,), within their gaps.

    Returns:
        ``(x, xd, xdd)`` at the queries, each of shape (r, n).
    """
    h = (t[gap + 1] - t[gap])[:, None]
    c0, c1, c2 = x[gap], h * xd[gap], 0.5 * h**2 * xdd[gap]
    p = x[gap + 1] - c0 - c1 - c2
    q = h * xd[gap + 1] - c1 - 2.0 * c2
    r = h**2 * xdd[gap + 1] - 2.0 * c2
    c3, c4, c5 = 10.0 * p - 4.0 * q + 0.5 * r, -15.0 * p + 7.0 * q - r, 6.0 * p - 3.0 * q + 0.5 * r
    s = (tq[:, None] - t[gap][:, None]) / h
    pos = c0 + s * (c1 + s * (c2 + s * (c3 + s * (c4 + s * c5))))
    vel = (c1 + s * (2.0 * c2 + s * (3.0 * c3 + s * (4.0 * c4 + s * 5.0 * c5)))) / h
    acc = (2.0 * c2 + s * (6.0 * c3 + s * (12.0 * c4 + s * 20.0 * c5))) / h**2
    return pos, vel, acc


def gap_rows(
    t: np.ndarray, x: np.ndarray, xd: np.ndarray, xdd: np.ndarray, max_step: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Points inside the gaps longer than ``max_step``, on the quintic_bridge across each.

    A gap of length L gets ``ceil(L / max_step) - 1`` equally spaced interior points, so no
    step of the filled demonstration exceeds ``max_step``; gaps no longer than it get none.

    Args:
        t: Sample times, strictly increasing, shape (N,).
        x: Positions (the fitted values of fit_demonstration on noisy data), shape (N, n).
        xd: Velocities, shape (N, n).
        xdd: Accelerations, shape (N, n).
        max_step: The longest step left, > 0 [s].

    Returns:
        ``(t, x, xd, xdd)`` of the interior points (shapes (r,) and (r, n); r may be 0).
    """
    if not max_step > 0.0:  # inf: no gaps to fill
        raise RepertoireError(f"max_step must be a number > 0 [s], got {max_step!r}")
    steps = np.diff(t)
    gap = np.flatnonzero(steps > max_step)
    inner = np.ceil(steps[gap] / max_step).astype(int) - 1
    gap, inner = gap[inner > 0], inner[inner > 0]
    left = np.repeat(gap, inner)
    k = np.arange(left.size) - np.repeat(np.cumsum(inner) - inner, inner) + 1  # 1..inner
    tq = t[left] + steps[left] * k / np.repeat(inner + 1, inner)
    return (tq, *quintic_bridge(t, x, xd, xdd, left, tq))
