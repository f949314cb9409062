"""Tabulated exact discrete DMP steps (first-order hold), shared by the discrete systems.

The discrete DMP LeafSystems (``DiscreteDmpSystem``, ``DmpSequencer`` with a time step)
advance ``z = [x, v]`` by the exact first-order-hold discretisation that
:func:`repertoire.planning.dmp_math.rollout` uses; the phase after k steps is known in
closed form, so each step's coefficients are computed from it.

The coefficients are tabulated a block of ``CHUNK_ROWS`` steps at a time, when a step
of that block is first asked for, and only the latest block is kept: memory is fixed
(about ``CHUNK_ROWS * (6 n + n_basis + 2) * 8`` bytes at the peak) whatever ``tau /
dt``. A whole table would have ``ln(1e12) tau / (alpha dt)`` rows (until theta <
1e-12): for tau = 1000 s, dt = 1e-4 s, alpha = 4.6 that is 6e7 rows, some 10 GiB kept
and 44 GiB while building it. Each row depends only on its own step number, so a block
holds the same values a whole table would.
"""

import numpy as np
from repertoire.planning.dmp import DmpParameters
from repertoire.planning.dmp_math import foh_matrices, forcing_term

# Steps tabulated at a time (~1.5 MiB for 3 DOF and 30 basis functions).
CHUNK_ROWS = 2048


class DiscreteDmpTables:
    """Per-step coefficients of the exact discrete DMP update (``DiscreteDmpSystem``).

    ``y_{k+1} = y_k @ bigT + (a[k] * (g - x0) + c[k] + d * p).ravel()`` with
    ``y = [x - x0, v]`` (v = tau dx/dt): the update in the displacement from x0, as the
    NumPy rollout takes it, so positions far from the origin keep their digits (the
    equations see positions only through g - x, g - x0 and x - x0); from step ``last`` on,
    theta = 0 and f = 0. The rows ``a[k], c[k]`` are built in blocks of ``CHUNK_ROWS`` on
    demand.
    """

    def __init__(self, dmp: DmpParameters, dt: float) -> None:
        n = dmp.n_dims
        self.n, self.dt, self.tau = n, dt, dmp.tau
        self._dmp = dmp
        self._decay = dmp.alpha * self.dt / dmp.tau
        # Rows 0 .. last-1 follow the phase; theta[last] = 0 (below 1e-12), f = 0 from there.
        self.last = int(np.ceil(np.log(1e12) / self._decay)) + 1
        K = dmp.K
        Phi, Gu, Gd = foh_matrices(K, dmp.D, dmp.tau, self.dt)
        self._G0 = (Gu - Gd).T[None]  # (1, 2, n), weight of the step's start input
        self._G1 = Gd.T[None]  # weight of the step's end input
        self._a_last = self._G0[0] * K + self._G1[0] * K
        self._zero = np.zeros((2, n))
        self.d = Gu.T.copy()
        big = np.zeros((2 * n, 2 * n))
        idx = np.arange(n)
        big[idx, idx] = Phi[:, 0, 0]
        big[idx, n + idx] = Phi[:, 0, 1]
        big[n + idx, idx] = Phi[:, 1, 0]
        big[n + idx, n + idx] = Phi[:, 1, 1]
        self.bigT = big.T.copy()
        # First step and length of the block held in _a, _c, _theta, _F.
        self._start, self._rows = -1, 0
        self._block(0)

    def _block(self, k: int) -> int:
        """Makes the block holding step ``k`` (< last) current; returns k's row in it."""
        start = (k // CHUNK_ROWS) * CHUNK_ROWS
        if start != self._start:
            dmp = self._dmp
            stop = min(start + CHUNK_ROWS, self.last)
            j = np.arange(start, stop + 1)  # the block's steps and the next one
            theta = np.exp(-self._decay * j)
            F = forcing_term(theta, dmp.weights, dmp.centres, dmp.widths)
            if stop == self.last:
                theta[-1] = 0.0  # beyond the table: theta = 0, f = 0
                F[-1] = 0.0
            K, G0, G1 = dmp.K, self._G0, self._G1
            th0, th1 = theta[:-1, None, None], theta[1:, None, None]
            F0, F1 = F[:-1, None, :], F[1:, None, :]
            if dmp.formulation == "new":
                # U = K (1 - theta) (g - x0) + K f + p in the displacement from x0
                self._a = G0 * K * (1 - th0) + G1 * K * (1 - th1)
                self._c = G0 * K * F0 + G1 * K * F1
            else:
                # U = (K + f) (g - x0) + p in the displacement from x0
                self._a = G0 * (K + F0) + G1 * (K + F1)
                self._c = np.zeros_like(self._a)
            self._theta, self._F = theta[:-1], F[:-1]
            self._start, self._rows = start, stop - start
        return k - start

    def step(self, z: np.ndarray, k: int, goal: np.ndarray, x0: np.ndarray, p=None) -> np.ndarray:
        """One exact step of the flattened state ``z = [x, v]``.

        Args:
            z: State, shape (2n,).
            k: Steps since onset.
            goal: Goal, shape (n,).
            x0: Start, shape (n,).
            p: Coupling term held over the step, or None.
        """
        g = goal - x0  # in the displacement from x0 the start is 0
        if k >= self.last:
            u = self._a_last * g
        else:
            i = int(k) - self._start
            if not 0 <= i < self._rows:
                i = self._block(int(k))
            u = self._a[i] * g + self._c[i]
        if p is not None:
            u += self.d * p
        z = z.copy()
        z[: self.n] -= x0
        out = z @ self.bigT + u.ravel()
        out[: self.n] += x0
        return out

    def phase_and_f(self, k: float) -> tuple[float, np.ndarray]:
        """Phase and forcing term after k steps.

        Args:
            k: Steps since onset.
        """
        k = int(k)
        if k < self.last:
            i = k - self._start
            if not 0 <= i < self._rows:
                i = self._block(k)
            return float(self._theta[i]), self._F[i]
        return 0.0, np.zeros(self.n)


__all__ = ["CHUNK_ROWS", "DiscreteDmpTables"]
