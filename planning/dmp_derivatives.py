"""Derivatives of recorded demonstrations (Pastor et al. 2009, sec. II-A needs xd and xdd).

Savitzky-Golay filters of order 5 on uniform time stamps, with the window chosen by
generalised cross-validation when the data are noisy and the exact small window when they
are clean; kernel-weighted, ridged local polynomials with windows in time on non-uniform
stamps (half-width and ridge chosen for the second derivative: among the fits that
generalised cross-validation cannot tell apart, the one with the smallest estimated
second-derivative error); a smoothing spline. Used by the learning in
:mod:`repertoire.planning.dmp_learn`.
"""

import functools
from typing import NamedTuple

import numba
import numpy as np
from repertoire.planning.dmp import check_demonstration

from repertoire.checks import is_whole
from repertoire.errors import RepertoireError


# --------------------------------------------------------------------------- derivatives
def estimate_derivatives(
    t: np.ndarray,
    x: np.ndarray,
    *,
    method: str = "auto",
    window: int | None = None,
    smoothing: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """First and second time derivatives of recorded positions (fit_demonstration's).

    Args:
        t: Time stamps, strictly increasing, shape (N,).
        x: Samples, shape (N, n).
        method: ``"auto"``, ``"savgol"``, ``"local_poly"`` or ``"spline"``.
        window: Savitzky-Golay / local-polynomial window (odd), or None.
        smoothing: Smoothing-spline lambda (``"spline"`` only).
    """
    return fit_demonstration(t, x, method=method, window=window, smoothing=smoothing)[1:]


def fit_demonstration(
    t: np.ndarray,
    x: np.ndarray,
    *,
    method: str = "auto",
    window: int | None = None,
    smoothing: float | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Smoothed positions and first and second time derivatives of recorded positions.

    The smoothed positions are the fitted values of the same local fits (or spline) whose
    derivatives are returned, so the three agree (on clean data they are the samples).

    ``"savgol"`` (uniform time stamps): Savitzky-Golay filter of polynomial order 5 (exact
    for minimum-jerk segments), edge samples from a polynomial fit of the edge window.
    ``"local_poly"`` (any time stamps): local polynomials of order 5 on non-uniform stamps;
    by default tricube-weighted with windows in time and a small ridge on the cubic and
    higher coefficients, the half-width and ridge chosen for the second derivative (among
    the fits generalised cross-validation cannot tell apart, the smallest estimated error;
    kernel_polynomial_choice: clustered stamps and gaps cannot blow the fit up, and
    clean data keep no ridge, exact for minimum-jerk segments); with ``window``, a plain
    least-squares fit to the ``window`` nearest samples (local_polynomial_fit).
    ``"spline"`` (any time stamps): a smoothing spline (``scipy`` ``make_smoothing_spline``;
    ``smoothing`` is its lambda, None = generalised cross-validation, which can over-smooth
    noise-free data) differentiated analytically. ``"auto"`` picks savgol when the stamps
    are uniform to 1e-6 relative, local_poly otherwise.

    Args:
        t: Time stamps, strictly increasing, shape (N,).
        x: Samples, shape (N, n).
        method: ``"auto"``, ``"savgol"``, ``"local_poly"`` or ``"spline"``.
        window: Savitzky-Golay / local-polynomial window (odd). Default: savgol chooses it
            by generalised cross-validation (see gcv_savgol_window), so noisy
            demonstrations are smoothed and clean ones keep about N/40 (>= 7);
            local_poly chooses a window in time instead (see above).
        smoothing: Smoothing-spline lambda (``"spline"`` only; given with another method it
            is refused rather than ignored, as is a ``window`` with ``"spline"``).

    Derivatives do not depend on where the samples sit, only on how they move, so each DOF
    is first centred on the middle of its range: the polynomial fits, their power sums and
    the GCV choices then see the movement, not its offset (a 0.3 mm movement 1000 units from
    the origin had second derivatives 6e-4 (uniform stamps) and 5 % (non-uniform) of its peak
    off from the same movement at the origin, and GCV compared noise with a round-off floor
    set by the offset).
    """
    t, x = check_demonstration(t, x)
    centre = 0.5 * (x.max(axis=0) + x.min(axis=0))
    smooth, xd, xdd = _fit_centred(t, x - centre, method, window, smoothing)
    return smooth + centre, xd, xdd


def _fit_centred(t, x, method, window, smoothing) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """fit_demonstration's fits on samples centred on their range."""
    if window is not None and not is_whole(window):
        raise RepertoireError(f"window must be an odd integer >= 3 or None, got {window!r}")
    n = t.size
    if window is not None and window > n:
        raise RepertoireError(
            f"window = {window} is longer than the demonstration's {n} samples; use an odd "
            f"window <= {n if n % 2 else n - 1}"
        )
    if smoothing is not None and method != "spline":
        raise RepertoireError(
            f"smoothing = {smoothing!r} is the smoothing spline's lambda and needs "
            f"method='spline' (derivatives='spline' when learning), got method={method!r}"
        )
    if window is not None and method == "spline":
        raise RepertoireError(
            f"window = {window!r} is the Savitzky-Golay / local-polynomial window; "
            "method='spline' has none (its smoothing is the lambda 'smoothing')"
        )
    dt = np.diff(t)
    uniform = np.ptp(dt) <= 1e-6 * dt.mean()
    if method == "auto":
        method = "savgol" if uniform else "local_poly"
    if method == "savgol":
        if not uniform:
            raise RepertoireError("method='savgol' needs uniform time stamps; use 'spline'")
        h = float(dt.mean())
        max_w = n if n % 2 else n - 1
        if window is None:
            w = gcv_savgol_window(x, h, max_w)
        else:
            w = min(window, max_w)
        if w % 2 == 0 or w < 3:
            raise RepertoireError(f"Savitzky-Golay window must be odd and >= 3, got {w}")
        order = min(5, w - 1)
        return (savgol_smooth(x, w, order, h), *savgol_derivatives(x, w, order, h))
    if method == "local_poly":
        if window is None:
            return kernel_polynomial_choice(t, x)
        return local_polynomial_fit(t, x, window)
    if method == "spline":
        if smoothing is not None and not (np.isfinite(smoothing) and smoothing >= 0):
            raise RepertoireError(
                f"smoothing (the spline's lambda) must be a finite number >= 0 or None, got "
                f"{smoothing}"
            )
        if n < 5:
            from scipy.interpolate import make_interp_spline

            spline = make_interp_spline(t, x, k=2)
        else:
            from scipy.interpolate import make_smoothing_spline

            spline = make_smoothing_spline(t, x, lam=smoothing, axis=0)
        return spline(t), spline.derivative(1)(t), spline.derivative(2)(t)
    raise RepertoireError(
        f"method must be 'auto', 'savgol', 'local_poly' or 'spline', got {method!r}"
    )


class SavgolOperators(NamedTuple):
    """Savitzky-Golay operators of one window, order and step (:func:`savgol_operators`).

    The edge operators stay factored (samples -> polynomial coefficients -> values at the
    edge samples), O(w) numbers instead of the (w/2, w) matrices of their product: with a
    window of about N / 4 those were 1.4 GB for N = 30001 and did not fit in memory for a
    60 s demonstration at 10 kHz.

    Attributes:
        interior: Dot-product coefficients of the smoothed value and the first and second
            derivative at a window's centre, shape (3, w).
        fit: Least-squares fit of an edge window's samples to polynomial coefficients,
            shape (order + 1, w).
        first: Value, first and second derivative of those polynomials at the first
            ``w // 2`` samples, shape (3, w // 2, order + 1).
        last: The same at the last ``w // 2`` samples.
    """

    interior: np.ndarray
    fit: np.ndarray
    first: np.ndarray
    last: np.ndarray

    def edges(self, x: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
        """The k-th derivative (0: smoothed value) at the first and last ``w // 2`` samples.

        Args:
            x: Samples, shape (N, dims), N >= w.
            k: 0, 1 or 2.
        """
        w = self.fit.shape[1]
        return self.first[k] @ (self.fit @ x[:w]), self.last[k] @ (self.fit @ x[-w:])

    def smoother_trace(self, n: int) -> float:
        """Trace of the smoothing (k = 0) operator on N = n samples."""
        half = self.first.shape[1]
        w = self.fit.shape[1]
        edge_first = np.einsum("ij,ji->", self.first[0], self.fit[:, :half])
        edge_last = np.einsum("ij,ji->", self.last[0], self.fit[:, w - half :])
        return float(self.interior[0, half] * (n - 2 * half) + edge_first + edge_last)


@functools.lru_cache(maxsize=16)
def savgol_operators(w: int, order: int, h: float) -> SavgolOperators:
    """Savitzky-Golay smoothing and derivative operators for uniform samples, cached.

    Every sample gets the value and derivatives of the order-``order`` polynomial fitted
    by least squares to a window of ``w`` samples: interior samples to the window centred
    on them (scipy's ``savgol_coeffs``), the ``w // 2`` samples at each edge to the edge
    window (scipy's ``mode="interp"``). The fit is on offsets scaled to [-1, 1], so long
    windows keep their digits.

    Args:
        w: Window length (odd).
        order: Polynomial order, < w.
        h: Sample spacing [s].
    """
    half = w // 2
    s = np.arange(w, dtype=float)
    u = (s - half) / half  # window positions scaled to [-1, 1]: a well-conditioned fit
    fit = np.linalg.pinv(np.vander(u, order + 1, increasing=True))  # samples -> coefficients
    j = np.arange(order + 1)

    def evaluate(points: np.ndarray) -> np.ndarray:
        out = np.empty((3, points.size, order + 1))
        falling = np.ones(order + 1)
        for k in range(3):
            powers = np.where(j >= k, points[:, None] ** np.maximum(j - k, 0), 0.0)
            out[k] = falling * powers / (half * h) ** k
            falling = falling * (j - k)
        return out

    # The interior coefficients are the same fit evaluated at the window's centre (u = 0).
    # scipy's savgol_coeffs fits powers of the unscaled offsets (up to (w/2)^order) and
    # loses every digit for long windows (order 5: 7.7e-9 of the value at w = 201, all of it
    # from w ~ 1000, which GCV picks for demonstrations of 40000 samples and more).
    interior = evaluate(np.zeros(1))[:, 0, :] @ fit
    return SavgolOperators(interior, fit, evaluate(u[:half]), evaluate(u[w - half :]))


def _gcv_window(x: np.ndarray, max_w: int, smoother) -> int:
    """The window whose smoother ``smoother(x, w) -> (S_w x, tr(S_w))`` minimises GCV.

    Candidates grow geometrically (x1.5) from ``max(7, 2 (N // 80) + 1)`` to about N / 4,
    scored by :func:`gcv_choice`.
    """
    n = x.shape[0]
    w = min(max(7, 2 * (n // 80) + 1), max_w)
    candidates = [w]
    while True:
        nxt = int(round(candidates[-1] * 1.5)) | 1
        if nxt > min(max_w, n // 4):
            break
        candidates.append(nxt)
    return gcv_choice(x, candidates, smoother)


def gcv_choice(x: np.ndarray, candidates: list, smoother) -> object:
    """The candidate whose linear smoother minimises generalised cross-validation.

    ``smoother(x, c) -> (S_c x, tr(S_c))``; ``GCV(c) = RSS / (1 - tr(S_c) / N)^2`` (summed
    over DOF). The first candidate within 1e-6 of the minimum (or of a round-off floor)
    wins, so list the smoothest-for-clean-data candidate first: noise-free demonstrations
    keep it (exact for minimum-jerk segments) and noisy ones get the candidate that
    averages the noise out. Scoring stops at the first candidate on the floor (no later
    one could be chosen).
    """
    n = x.shape[0]
    x = x / _gcv_scale(x)
    floor = _gcv_floor(x)
    scores = []
    for c in candidates:
        smooth, trace = smoother(x, c)
        rss = float(np.sum((smooth - x) ** 2))
        scores.append(rss / max(1.0 - trace / n, 1e-12) ** 2)
        if scores[-1] <= floor:
            break
    return candidates[_first_near_minimum(np.array(scores), floor)]


def _gcv_scale(x: np.ndarray) -> float:
    """The largest magnitude of ``x`` (1 if none): the scale GCV divides by.

    GCV's argmin does not change with the data's scale; scaling keeps huge coordinates
    from overflowing the residual sums.
    """
    scale = float(np.max(np.abs(x))) if x.size else 0.0
    return scale if scale > 0.0 and np.isfinite(scale) else 1.0


def _gcv_floor(x: np.ndarray) -> float:
    """Round-off floor of a GCV score of (scaled) samples ``x``, with GCV's 1e-6 slack."""
    return x.size * (1e-10 * max(1.0, float(np.max(np.abs(x))))) ** 2 * (1.0 + 1e-6)


def _first_near_minimum(scores: np.ndarray, floor: float) -> int:
    """Index of the first score within 1e-6 of the minimum, or on the round-off floor."""
    best = max(float(np.min(scores)), floor / (1.0 + 1e-6)) * (1.0 + 1e-6)
    return int(np.flatnonzero(scores <= best)[0])


def gcv_savgol_window(x: np.ndarray, h: float, max_w: int) -> int:
    """Savitzky-Golay window (order 5) chosen by generalised cross-validation (_gcv_window)."""

    def smoother(x: np.ndarray, w: int) -> tuple[np.ndarray, float]:
        n = x.shape[0]
        trace = savgol_operators(w, min(5, w - 1), h).smoother_trace(n)
        return savgol_smooth(x, w, min(5, w - 1), h), trace

    return _gcv_window(x, max_w, smoother)


DIRECT_WINDOW = 64
"""Windows up to this many samples are applied as dot products, longer ones by FFT."""


def window_dot(x: np.ndarray, c: np.ndarray) -> np.ndarray:
    """``y[k] = c @ x[k : k + w]`` for every full window of ``x`` along axis 0.

    Short windows as direct dot products; longer ones by overlap-add FFT convolution,
    O(N log w) instead of O(N w) (a 60 s demonstration at 10 kHz has windows of 15001
    samples; same values to about 1e-14 of their magnitude).

    Args:
        x: Samples, shape (N, dims).
        c: Coefficients, shape (w,), w <= N.

    Returns:
        Shape (N - w + 1, dims).
    """
    if c.size <= DIRECT_WINDOW:
        return np.lib.stride_tricks.sliding_window_view(x, c.size, axis=0) @ c
    from scipy.signal import oaconvolve

    return oaconvolve(x, c[::-1, None], mode="valid", axes=0)


def savgol_smooth(x: np.ndarray, w: int, order: int, h: float) -> np.ndarray:
    """``savgol_filter(x, w, order, deriv=0, axis=0, mode="interp")``: the fitted values."""
    ops = savgol_operators(w, order, h)
    half = w // 2
    smooth = np.empty_like(x)
    smooth[half : x.shape[0] - half] = window_dot(x, ops.interior[0])
    smooth[:half], smooth[x.shape[0] - half :] = ops.edges(x, 0)
    return smooth


def savgol_derivatives(
    x: np.ndarray, w: int, order: int, h: float
) -> tuple[np.ndarray, np.ndarray]:
    """``savgol_filter(x, w, order, deriv=1|2, delta=h, axis=0, mode="interp")``, both at once."""
    ops = savgol_operators(w, order, h)
    half = w // 2
    xd, xdd = np.empty_like(x), np.empty_like(x)
    xd[half : x.shape[0] - half] = window_dot(x, ops.interior[1])
    xdd[half : x.shape[0] - half] = window_dot(x, ops.interior[2])
    xd[:half], xd[x.shape[0] - half :] = ops.edges(x, 1)
    xdd[:half], xdd[x.shape[0] - half :] = ops.edges(x, 2)
    return xd, xdd


LOCAL_RIDGES = (1e-4, 1e-3, 1e-2)
"""Ridge weights (relative to each local fit's kernel mass) tried by local_poly's GCV on
data that a local polynomial does not fit to round-off."""

_GCV_CENTRES = 1024  # samples that kernel_scan evaluates at most


def kernel_half_widths(t: np.ndarray, bandwidth: float, order: int) -> np.ndarray:
    """Per-sample half-widths: ``bandwidth``, widened to hold ``order + 2`` samples.

    Each sample's window reaches at least 1.2x as far as the ``order + 2`` consecutive
    samples around it (shifted inwards at the ends; all N if fewer), so every local fit has
    more distinct stamps than coefficients (as many on a demonstration of order + 1
    samples), all with a positive tricube weight, however the stamps cluster or leave gaps.
    """
    n = t.size
    m = min(order + 2, n)
    i = np.arange(n)
    start = np.clip(i - m // 2, 0, n - m)
    reach = np.maximum(t - t[start], t[start + m - 1] - t)
    return np.maximum(float(bandwidth), 1.2 * reach)


@numba.njit(cache=True, fastmath=True)
def _window_buffers(lo, hi, dims):
    """Work rows for the widest window ``[lo, hi)``: u, weights, and (dims, width)."""
    width = 1
    for r in range(lo.size):
        width = max(width, hi[r] - lo[r])
    return np.empty(width), np.empty(width), np.empty((dims, width))


@numba.njit(cache=True, fastmath=True)
def _tricube_window(t, b, i, start, m, u, w):
    """``u[:m] = (t_j - t_i) / b_i``, ``w[:m] = tricube(u)``: the ``m`` samples from ``start``."""
    for j in range(m):
        u[j] = (t[start + j] - t[i]) / b[i]
        a = 1.0 - min(abs(u[j]), 1.0) ** 3
        w[j] = a * a * a


@numba.njit(cache=True, fastmath=True)
def _weighted_rows(w, rows, m, out):
    """``out[d] = sum_j w[j] rows[d, j]`` over the first ``m`` columns."""
    for d in range(rows.shape[0]):
        total = 0.0
        for j in range(m):
            total += w[j] * rows[d, j]
        out[d] = total


@numba.njit(cache=True, fastmath=True)
def _kernel_sums(t, x, b, centres, lo, hi, n_powers, n_squares, p):
    """Kernel power sums over the windows ``[lo, hi)`` of the samples ``centres``.

    With ``u_j = (t_j - t_i) / b_i`` and ``K_j = tricube(u_j) = (1 - |u_j|^3)^3`` (0 for
    ``|u_j| >= 1``): ``S[r, k] = sum_j K_j u_j^k`` (k < n_powers), ``Q[r, k] = sum_j K_j^2
    u_j^k`` (k < n_squares) and ``T[r, k, d] = sum_j K_j u_j^k x_jd`` (k < p). Compiled:
    per window, the weights in a buffer and one vectorised sum per power (numba's own
    cache is safe here: nothing compiled is inlined from another file).
    """
    r_count, dims = centres.size, x.shape[1]
    S = np.zeros((r_count, n_powers))
    Q = np.zeros((r_count, max(n_squares, 1)))
    T = np.zeros((r_count, p, dims))
    u, w, xs = _window_buffers(lo, hi, dims)
    for r in range(r_count):
        i, start, m = centres[r], lo[r], hi[r] - lo[r]
        _tricube_window(t, b, i, start, m, u, w)
        for j in range(m):
            for d in range(dims):
                xs[d, j] = x[start + j, d]
        for k in range(n_powers):
            total = 0.0
            for j in range(m):
                total += w[j]
            S[r, k] = total
            if k < p:
                _weighted_rows(w, xs, m, T[r, k])
            for j in range(m):
                w[j] *= u[j]
        if n_squares:
            for j in range(m):
                a = 1.0 - min(abs(u[j]), 1.0) ** 3
                w[j] = a**6
            for k in range(n_squares):
                total = 0.0
                for j in range(m):
                    total += w[j]
                Q[r, k] = total
                for j in range(m):
                    w[j] *= u[j]
    return S, Q, T


@numba.njit(cache=True, fastmath=True)
def _kernel_residual_sums(t, x, b, centres, lo, hi, coef):
    """``sum_j K_j u_j^k (x_j - sum_m coef[r, m] u_j^m)``, shape (r, p, dims) (as _kernel_sums)."""
    r_count, p, dims = coef.shape
    R = np.zeros((r_count, p, dims))
    u, w, res = _window_buffers(lo, hi, dims)
    for r in range(r_count):
        i, start, m = centres[r], lo[r], hi[r] - lo[r]
        _tricube_window(t, b, i, start, m, u, w)
        for d in range(dims):  # Horner: the fitted polynomial on the window
            for j in range(m):
                res[d, j] = coef[r, p - 1, d]
            for k in range(p - 2, -1, -1):
                c = coef[r, k, d]
                for j in range(m):
                    res[d, j] = res[d, j] * u[j] + c
            for j in range(m):
                res[d, j] = x[start + j, d] - res[d, j]
        for k in range(p):
            _weighted_rows(w, res, m, R[r, k])
            for j in range(m):
                w[j] *= u[j]
    return R


def _kernel_moments(
    t: np.ndarray, x: np.ndarray, b: np.ndarray, centres: np.ndarray, p: int, *, squares=False
) -> tuple[np.ndarray, ...]:
    """``(lo, hi, S, Q, T)``: the windows and _kernel_sums of order ``p - 1`` fits at ``centres``.

    S holds the Gram matrix's power sums (up to ``2p - 2``); Q, with ``squares``, the
    squared-kernel sums (up to ``2p - 2``) that give the norms of the smoother's rows.
    """
    lo = np.searchsorted(t, t[centres] - b[centres], side="left")
    hi = np.searchsorted(t, t[centres] + b[centres], side="right")
    x = np.ascontiguousarray(x, dtype=float)
    n_squares = 2 * p - 1 if squares else 0
    return (lo, hi, *_kernel_sums(t, x, b, centres, lo, hi, 2 * p - 1, n_squares, p))


def _kernel_order(n: int, order: int) -> int:
    """The local order: ``order``, lowered to N - 1 for demonstrations of N <= order samples."""
    return max(1, min(order, n - 1))


def kernel_polynomial_fit(
    t: np.ndarray, x: np.ndarray, bandwidth: float, ridge: float = 0.0, *, order: int = 5
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Tricube-weighted local polynomials with a window in time, ridged on high orders.

    At each sample ``t_i``, with ``u = (t - t_i) / b_i`` (``b_i`` from kernel_half_widths),
    the coefficients ``c`` minimise ``sum_j K(u_j) (sum_k c_k u_j^k - x_j)^2 + ridge *
    sum_j K(u_j) * sum_{k >= 3} c_k^2`` (Seifert & Gasser 1996: a ridge keeps the local
    fit's variance finite where clustered stamps or a gap leave it one-sided; it shrinks
    towards a local quadratic, so the second derivative survives). ``ridge = 0`` is exact
    for polynomials of degree <= ``order``. Solved by the normal equations on kernel-weighted
    power sums (in the scaled ``u``, summed by compiled loops) with one step of iterative
    refinement.

    Args:
        t: Time stamps, strictly increasing, shape (N,).
        x: Samples, shape (N, n).
        bandwidth: Half-width of the windows [s] (widened per sample, see above).
        ridge: Ridge weight relative to each window's kernel mass, >= 0.
        order: Polynomial order (lowered to N - 1 for tiny demonstrations).

    Returns:
        ``(smooth, xd, xdd)``: the fitted values and first and second derivatives.
    """
    if not (np.isfinite(bandwidth) and bandwidth > 0.0):
        raise RepertoireError(f"bandwidth must be a finite number > 0 [s], got {bandwidth!r}")
    if not (np.isfinite(ridge) and ridge >= 0.0):
        raise RepertoireError(f"ridge must be a finite number >= 0, got {ridge!r}")
    order = _kernel_order(t.size, order)
    p = order + 1
    b = kernel_half_widths(t, bandwidth, order)
    penalty = ridge * (np.arange(p) >= 3)
    centres = np.arange(t.size)
    lo, hi, S, _, T = _kernel_moments(t, x, b, centres, p)
    A = S[:, _hankel(p)] + S[:, :1, None] * np.diag(penalty)
    coef = np.linalg.solve(A, T)  # (N, p, n_dims)
    # one step of iterative refinement: the residual of the weighted fit, re-solved
    x = np.ascontiguousarray(x, dtype=float)
    correction = _kernel_residual_sums(t, x, b, centres, lo, hi, coef)
    correction -= S[:, :1, None] * penalty[:, None] * coef
    coef = coef + np.linalg.solve(A, correction)
    h = b[:, None]
    return coef[:, 0], coef[:, 1] / h, 2.0 * coef[:, 2] / h**2


def _hankel(p: int) -> np.ndarray:
    """Index matrix ``j + k`` that builds a Gram matrix from power sums."""
    return np.add.outer(np.arange(p), np.arange(p))


class KernelScan(NamedTuple):
    """What kernel_scan measures per (ridge, bandwidth), shape (len(ridges), len(bandwidths)).

    Sums over the N samples (estimated from the scan's centres above _GCV_CENTRES samples),
    on ``x`` scaled by its largest magnitude; "the lightest" is the fit of the same
    bandwidth with the smallest ridge.

    Attributes:
        rss: Residual sum of squares of the smoothed positions (summed over DOF).
        trace: ``tr(S)`` of the position smoother ``S``.
        trace_ss: ``tr(S^T S)``, the sum of its rows' squared norms.
        variance_2: Sum of the squared norms of the second-derivative smoother's rows: the
            second derivative's variance summed over the samples, per unit noise variance.
        ridge_change: Sum of squares (over samples and DOF) of the second derivative's
            difference from the lightest fit's.
        ridge_change_variance: Sum of the squared norms of that difference's smoother rows.
        residuals: The squared residuals (summed over DOF) at the scan's centres, shape
            (len(ridges), len(bandwidths), centres).
    """

    rss: np.ndarray
    trace: np.ndarray
    trace_ss: np.ndarray
    variance_2: np.ndarray
    ridge_change: np.ndarray
    ridge_change_variance: np.ndarray
    residuals: np.ndarray


def kernel_scan(
    t: np.ndarray,
    x: np.ndarray,
    bandwidths: list[float],
    ridges: tuple[float, ...] = LOCAL_RIDGES,
    *,
    order: int = 5,
) -> KernelScan:
    """The smoothers of kernel_polynomial_fit on a (ridge, bandwidth) grid (KernelScan).

    Values and smoother rows come from the normal equations on kernel-weighted power sums,
    shared by all ridges of one bandwidth. Above _GCV_CENTRES samples, the sums are
    estimated from that many evenly indexed samples (``N / c`` times their sums; every fit
    still uses all samples in its window), so the scan costs O(c x window), not O(N x window).
    """
    n = t.size
    order = _kernel_order(n, order)
    p = order + 1
    x = x / _gcv_scale(x)
    penalty = np.diag((np.arange(p) >= 3).astype(float))
    centres = np.unique(np.round(np.linspace(0, n - 1, min(n, _GCV_CENTRES))).astype(int))
    shape = (len(ridges), len(bandwidths))
    out = KernelScan(*(np.empty(shape) for _ in range(6)), np.empty(shape + (centres.size,)))
    per = n / centres.size
    units = np.zeros((centres.size, p, 2))
    units[:, 0, 0] = units[:, 2, 1] = 1.0
    lightest = int(np.argmin(ridges))

    def norms(rows: np.ndarray, gram: np.ndarray) -> float:
        return per * float(np.einsum("rj,rjk,rk->", rows, gram, rows))

    for k, bandwidth in enumerate(bandwidths):
        b = kernel_half_widths(t, bandwidth, order)
        _, _, S, Q, T = _kernel_moments(t, x, b, centres, p, squares=True)
        G, G2 = S[:, _hankel(p)], Q[:, _hankel(p)]
        rows = []
        for ridge in ridges:
            Z = np.linalg.solve(G + ridge * S[:, :1, None] * penalty, units)
            rows.append((Z[..., 0], Z[..., 1] * (2.0 / b[centres, None] ** 2)))  # of A^-1
        y_ref = rows[lightest][1]
        xdd_ref = np.einsum("rk,rkd->rd", y_ref, T)
        for q, (z, y) in enumerate(rows):
            out.residuals[q, k] = np.sum((np.einsum("rk,rkd->rd", z, T) - x[centres]) ** 2, 1)
            out.rss[q, k] = per * float(out.residuals[q, k].sum())
            out.trace[q, k] = per * float(z[:, 0].sum())  # K(0) (A^-1)_00: own weight
            out.trace_ss[q, k] = norms(z, G2)
            out.variance_2[q, k] = norms(y, G2)
            change = np.einsum("rk,rkd->rd", y, T) - xdd_ref
            out.ridge_change[q, k] = per * float(np.sum(change**2))
            out.ridge_change_variance[q, k] = norms(y - y_ref, G2)
    return out


def kernel_gcv_scores(scan: KernelScan, n: int) -> np.ndarray:
    """GCV scores ``RSS / (1 - tr(S) / N)^2`` of a kernel_scan of N samples.

    Shape (len(ridges), len(bandwidths)), summed over DOF, on ``x`` scaled by its largest
    magnitude (as gcv_choice).
    """
    return scan.rss / np.maximum(1.0 - scan.trace / n, 1e-12) ** 2


def second_derivative_choice(scan: KernelScan, n: int, floor: float) -> tuple[int, int]:
    """The (ridge, bandwidth) indices of local_poly's fit, chosen for the second derivative.

    Among the candidates whose GCV score exceeds the smallest by at most one standard
    error of the difference (the one-standard-error rule, Breiman et al. 1984; Hastie,
    Tibshirani & Friedman 2009, sec. 7.10: fits of the positions that the data cannot
    tell from the best), the one whose second derivative has the smallest estimated mean
    squared error ``s2 variance_2 + B``: ``s2 = RSS / (N - 2 tr(S) + tr(S^T S))`` at GCV's
    minimum (the noise variance, Buckley, Eagleson & Silverman 1988) and ``B =
    max(ridge_change - s2 ridge_change_variance, 0)``, the unbiased estimate of the
    squared shrinkage of the ridge against the lightest fit of the same bandwidth (the
    bandwidth's own bias is what GCV's rule guards). The standard error is ``sqrt(N)``
    times the standard deviation, over the scan's centres, of the per-sample difference
    of the two scores' terms (paired: the same noise in both).

    Args:
        scan: kernel_scan's measures.
        n: Number of samples N.
        floor: GCV's round-off floor (see gcv_choice).
    """
    gcv = kernel_gcv_scores(scan, n)
    best = np.unravel_index(_first_near_minimum(gcv.ravel(), floor), gcv.shape)
    terms = scan.residuals / np.maximum(1.0 - scan.trace / n, 1e-12)[..., None] ** 2
    se = np.sqrt(n) * np.std(terms - terms[best], axis=-1)
    dof = n - 2.0 * scan.trace[best] + scan.trace_ss[best]
    s2 = scan.rss[best] / max(dof, 1e-12)
    shrinkage = np.maximum(scan.ridge_change - s2 * scan.ridge_change_variance, 0.0)
    risk = np.where(gcv - gcv[best] <= se, s2 * scan.variance_2 + shrinkage, np.inf)
    return divmod(int(np.argmin(risk)), gcv.shape[1])


def local_bandwidths(t: np.ndarray, order: int = 5) -> list[float]:
    """local_poly's candidate half-widths [s], smallest first.

    x1.3 steps to a quarter of the duration (windows of half the demonstration) from the
    reach of ``order + 2`` evenly spaced samples (3.6 mean spacings for order 5) or, if
    longer, 1/80 of the duration (as savgol's smallest window holds about N/40 samples:
    on dense clean data a window of a few samples loses digits to round-off).
    """
    span = float(t[-1] - t[0])
    b = max(1.2 * (min(order + 2, t.size) // 2) * span / (t.size - 1), span / 80.0)
    out = [b]
    while out[-1] * 1.3 <= span / 4.0:
        out.append(out[-1] * 1.3)
    return out


def kernel_polynomial_choice(
    t: np.ndarray, x: np.ndarray, *, ridges: tuple[float, ...] = LOCAL_RIDGES
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """local_poly's default: kernel_polynomial_fit with (ridge, bandwidth) chosen for xdd.

    Data that the unridged fit with the narrowest window reproduces to round-off (residual
    sum of squares on GCV's floor, see gcv_choice) keep that fit: exact for minimum-jerk
    segments. Otherwise every ridge in ``ridges`` with every half-width of
    local_bandwidths is scanned (kernel_scan) and second_derivative_choice picks the pair:
    of those whose GCV score is within one standard error of the smallest, the one whose
    second derivative has the smallest estimated error (its noise variance plus the
    ridge's squared shrinkage). GCV alone scores the positions, whose variance grows as
    1/h as the half-width h shrinks while the second derivative's grows as 1/h^5 (Fan &
    Gijbels 1996, Thm 3.1): where the bias is small its score is flat and its minimum
    falls anywhere in the flat part; on a sparse noisy minimum-jerk move
    (noisy_sparse_minimum_jerk, seed 2018) it chose the narrowest half-width by 2 % over
    the widest, and the second derivative's RMS error was 2.1x the peak acceleration
    (0.20x with this choice). The rule still trusts GCV where it rises by more than one
    standard error by chance (seed 5043: wider fits 1.4-2.3 standard errors above the
    minimum, RMS error 1.06x the peak at the ends, 1.34x with GCV alone). Noisy data
    always keep a ridge: without one, the one-sided fits at the ends of a demonstration
    whose first samples leave a gap are unbounded (101 random stamps, 2 mm noise: a
    second-derivative error of 108 at the first sample against an amplitude of 1.44).

    Args:
        t: Time stamps, strictly increasing, shape (N,).
        x: Samples, shape (N, n).
        ridges: Ridge weights tried on noisy data (see kernel_polynomial_fit), > 0.

    Returns:
        ``(smooth, xd, xdd)``: fitted values and derivatives, each of shape (N, n).
    """
    for ridge in ridges:
        if not (np.isfinite(ridge) and ridge > 0.0):
            raise RepertoireError(f"ridges must be finite numbers > 0, got {ridge!r}")
    bandwidths = local_bandwidths(t)
    scale = _gcv_scale(x)
    floor = _gcv_floor(x / scale)
    fit = kernel_polynomial_fit(t, x, bandwidths[0], 0.0)
    if np.sum(((fit[0] - x) / scale) ** 2) <= floor:
        return fit
    scan = kernel_scan(t, x, bandwidths, ridges)
    q, k = second_derivative_choice(scan, t.size, floor)
    return kernel_polynomial_fit(t, x, bandwidths[k], ridges[q])


_ROWS = 256  # samples per batch of local fits: bounds the (rows, w, order+1) designs


def _local_polynomial_design(
    t: np.ndarray, w: int, rows: slice
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Polynomial designs (order ``min(5, w - 1)``) on ``w`` samples for the samples ``rows``.

    Returns ``(idx, V, scale)``: the window indices (r, w), the Vandermonde matrices
    (r, w, order + 1) in ``(t - t_i) / scale_i`` and the scales (r,).
    """
    n = t.size
    order = min(5, w - 1)
    i = np.arange(n)[rows]
    start = np.clip(i - w // 2, 0, n - w)
    idx = start[:, None] + np.arange(w)[None, :]
    dt = t[idx] - t[i][:, None]
    scale = np.abs(dt).max(axis=1, keepdims=True)
    u = dt / scale
    V = np.empty(u.shape + (order + 1,))
    V[..., 0] = 1.0
    for k in range(1, order + 1):
        V[..., k] = V[..., k - 1] * u
    return idx, V, scale[:, 0]


def local_polynomial_fit(
    t: np.ndarray, x: np.ndarray, window: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Savitzky-Golay on non-uniform stamps: least-squares polynomials on ``window`` samples.

    Returns ``(smooth, xd, xdd)``.

    Per sample, order ``min(5, window - 1)`` fitted to a fixed count of samples around it.

    local_poly's estimator when a ``window`` is given; without one, local_poly uses
    kernel_polynomial_choice (windows in time), since a window counted in samples
    spans very different times on clustered stamps: on 101 random stamps with 2 mm noise
    two samples 0.2 ms apart beside an 88 ms gap gave a second-derivative error of 857
    against an amplitude of 1.44.
    """
    n = t.size
    max_w = n if n % 2 else n - 1
    batches = [slice(k, min(k + _ROWS, n)) for k in range(0, n, _ROWS)]
    w = min(window, max_w)
    if w % 2 == 0 or w < 3:
        raise RepertoireError(f"local-polynomial window must be odd and >= 3, got {w}")
    smooth, xd, xdd = np.empty_like(x), np.empty_like(x), np.empty_like(x)
    for rows in batches:
        idx, V, scale = _local_polynomial_design(t, w, rows)
        Q, R = np.linalg.qr(V)
        coef = np.linalg.solve(R, np.swapaxes(Q, 1, 2) @ x[idx])  # (r, order+1, n_dims)
        s = scale[:, None]
        smooth[rows], xd[rows], xdd[rows] = coef[:, 0], coef[:, 1] / s, 2.0 * coef[:, 2] / s**2
    return smooth, xd, xdd
