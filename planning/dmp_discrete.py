"""Tabulated exact discrete DMP steps (first-order hold), shared by the discrete systems.

The discrete DMP LeafSystems (``DiscreteDmpSystem``, ``DmpSequencer`` with a time step)
advance ``z = [x, v]`` by the exact first-order-hold discretisation that
:func:`repertoire.planning.dmp_math.rollout` uses; the phase after k steps is known in
closed form, so every step's coefficients are computed once here.
"""

import numpy as np
from repertoire.planning.dmp import DmpParameters
from repertoire.planning.dmp_math import foh_matrices, forcing_term


class DiscreteDmpTables:
    """Per-step coefficients of the exact discrete DMP update (``DiscreteDmpSystem``).

    ``z_{k+1} = z_k @ bigT + (a[k] * g + b[k] * x0 + c[k] + d * p).ravel()`` with
    ``z = [x, v]`` (v = tau dx/dt); row ``k >= last`` uses theta = 0, f = 0.
    """

    def __init__(self, dmp: DmpParameters, dt: float) -> None:
        n = dmp.n_dims
        self.n, self.dt, self.tau = n, dt, dmp.tau
        decay = dmp.alpha * self.dt / dmp.tau
        n_table = int(np.ceil(np.log(1e12) / decay)) + 2  # until theta < 1e-12
        theta = np.exp(-decay * np.arange(n_table))
        theta[-1] = 0.0  # beyond the table: theta = 0, f = 0
        F = forcing_term(theta, dmp.weights, dmp.centres, dmp.widths)
        F[-1] = 0.0
        K = dmp.K
        Phi, Gu, Gd = foh_matrices(K, dmp.D, dmp.tau, self.dt)
        G0 = (Gu - Gd).T[None]  # (1, 2, n), weight of the step's start input
        G1 = Gd.T[None]  # weight of the step's end input
        th0, th1 = theta[:-1, None, None], theta[1:, None, None]
        F0, F1 = F[:-1, None, :], F[1:, None, :]
        if dmp.formulation == "new":
            # U = K (1 - theta) g + K theta x0 + K f + p
            a = G0 * K * (1 - th0) + G1 * K * (1 - th1)
            b = G0 * K * th0 + G1 * K * th1
            c = G0 * K * F0 + G1 * K * F1
        else:
            # U = (K + f) g - f x0 + p
            a = G0 * (K + F0) + G1 * (K + F1)
            b = -(G0 * F0 + G1 * F1)
            c = np.zeros_like(a)
        last = np.stack([G0[0] * K + G1[0] * K, np.zeros((2, n)), np.zeros((2, n))])
        self.a = np.concatenate([a, last[:1]])  # (rows, 2, n)
        self.b = np.concatenate([b, last[1:2]])
        self.c = np.concatenate([c, last[2:]])
        self.d = Gu.T.copy()
        self.theta, self.F = theta, F
        self.last = self.a.shape[0] - 1
        big = np.zeros((2 * n, 2 * n))
        idx = np.arange(n)
        big[idx, idx] = Phi[:, 0, 0]
        big[idx, n + idx] = Phi[:, 0, 1]
        big[n + idx, idx] = Phi[:, 1, 0]
        big[n + idx, n + idx] = Phi[:, 1, 1]
        self.bigT = big.T.copy()

    def step(self, z: np.ndarray, k: int, goal: np.ndarray, x0: np.ndarray, p=None) -> np.ndarray:
        """One exact step of the flattened state ``z = [x, v]``.

        Args:
            z: State, shape (2n,).
            k: Steps since onset.
            goal: Goal, shape (n,).
            x0: Start, shape (n,).
            p: Coupling term held over the step, or None.
        """
        k = min(k, self.last)
        u = self.a[k] * goal + self.b[k] * x0 + self.c[k]
        if p is not None:
            u += self.d * p
        return z @ self.bigT + u.ravel()

    def phase_and_f(self, k: float) -> tuple[float, np.ndarray]:
        """Phase and forcing term after k steps.

        Args:
            k: Steps since onset.
        """
        k = int(k)
        if k < self.last:
            return float(self.theta[k]), self.F[k]
        return 0.0, np.zeros(self.n)


__all__ = ["DiscreteDmpTables"]
