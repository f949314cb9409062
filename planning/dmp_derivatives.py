"""Derivatives of recorded demonstrations (Pastor et al. 2009, sec. II-A needs xd and xdd).

Savitzky-Golay filters of order 5 on uniform time stamps, with the window chosen by
generalised cross-validation when the data are noisy and the exact small window when they
are clean; a local polynomial on non-uniform stamps; a smoothing spline. Used by the
learning in :mod:`repertoire.planning.dmp_learn`.
"""

import functools

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
    """First and second time derivatives of recorded positions.

    ``"savgol"`` (uniform time stamps): Savitzky-Golay filter of polynomial order 5 (exact
    for minimum-jerk segments), edge samples from a polynomial fit of the edge window.
    ``"local_poly"`` (any time stamps): the same idea on non-uniform stamps, a least-squares
    polynomial of order 5 fitted to the ``window`` nearest samples around each sample.
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
            local_poly chooses it likewise.
        smoothing: Smoothing-spline lambda (``"spline"`` only; given with another method it
            is refused rather than ignored, as is a ``window`` with ``"spline"``).
    """
    t, x = check_demonstration(t, x)
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
        return savgol_derivatives(x, w, order, h)
    if method == "local_poly":
        return local_polynomial_derivatives(t, x, window)
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
        return spline.derivative(1)(t), spline.derivative(2)(t)
    raise RepertoireError(
        f"method must be 'auto', 'savgol', 'local_poly' or 'spline', got {method!r}"
    )


@functools.lru_cache(maxsize=16)
def savgol_operators(w: int, order: int, h: float) -> tuple[np.ndarray, ...]:
    """Savitzky-Golay first/second-derivative operators for uniform samples, cached.

    Returns ``(c1, c2, E1_first, E2_first, E1_last, E2_last, c0, E0_first, E0_last)``:
    interior dot-product coefficients, and for the ``w // 2`` samples at each edge the
    derivative of the polynomial fitted to the edge window (scipy's ``mode="interp"``) as a
    matrix on it; the ``0`` entries are the smoothing (zeroth-derivative) operators.
    """
    from scipy.signal import savgol_coeffs

    half = w // 2
    c0 = savgol_coeffs(w, order, deriv=0, use="dot")
    c1 = savgol_coeffs(w, order, deriv=1, delta=h, use="dot")
    c2 = savgol_coeffs(w, order, deriv=2, delta=h, use="dot")
    s = np.arange(w, dtype=float)
    u = (s - half) / half  # window positions scaled to [-1, 1]: a well-conditioned fit
    fit = np.linalg.pinv(np.vander(u, order + 1, increasing=True))  # samples -> coefficients
    j = np.arange(order + 1)

    def evaluate(points: np.ndarray, k: int) -> np.ndarray:
        falling = np.ones(order + 1)
        for m in range(k):
            falling = falling * (j - m)
        powers = np.where(j >= k, points[:, None] ** np.maximum(j - k, 0), 0.0)
        return (falling * powers) @ fit / (half * h) ** k

    first, last = u[:half], u[w - half :]
    return (
        c1,
        c2,
        evaluate(first, 1),
        evaluate(first, 2),
        evaluate(last, 1),
        evaluate(last, 2),
        c0,
        evaluate(first, 0),
        evaluate(last, 0),
    )


def _gcv_window(x: np.ndarray, max_w: int, smoother) -> int:
    """The window whose smoother ``smoother(x, w) -> (S_w x, tr(S_w))`` minimises GCV.

    Candidates grow geometrically (x1.5) from ``max(7, 2 (N // 80) + 1)`` to about N / 4.
    For each, ``GCV(w) = RSS / (1 - tr(S_w) / N)^2`` (summed over DOF); the smallest window
    within 1e-6 of the minimum (or of a round-off floor) wins, so noise-free
    demonstrations keep the smallest window and stay exact for minimum-jerk segments, and
    noisy ones get the window that averages the noise out.
    """
    n = x.shape[0]
    # GCV's argmin does not change with the data's scale; scaling keeps huge
    # coordinates from overflowing the residual sums.
    scale = float(np.max(np.abs(x))) if x.size else 0.0
    if scale > 0.0 and np.isfinite(scale):
        x = x / scale
    w = min(max(7, 2 * (n // 80) + 1), max_w)
    candidates = [w]
    while True:
        nxt = int(round(candidates[-1] * 1.5)) | 1
        if nxt > min(max_w, n // 4):
            break
        candidates.append(nxt)
    scores = []
    for w in candidates:
        smooth, trace = smoother(x, w)
        rss = float(np.sum((smooth - x) ** 2))
        scores.append(rss / max(1.0 - trace / n, 1e-12) ** 2)
    floor = x.size * (1e-10 * max(1.0, float(np.max(np.abs(x))))) ** 2
    best = max(min(scores), floor) * (1.0 + 1e-6)
    return next(w for w, g in zip(candidates, scores, strict=True) if g <= best)


def gcv_savgol_window(x: np.ndarray, h: float, max_w: int) -> int:
    """Savitzky-Golay window (order 5) chosen by generalised cross-validation (_gcv_window)."""

    def smoother(x: np.ndarray, w: int) -> tuple[np.ndarray, float]:
        n = x.shape[0]
        ops = savgol_operators(w, min(5, w - 1), h)
        c0, e0f, e0l = ops[6], ops[7], ops[8]
        half = w // 2
        smooth = np.empty_like(x)
        windows = np.lib.stride_tricks.sliding_window_view(x, w, axis=0)
        smooth[half : n - half] = windows @ c0
        smooth[:half], smooth[n - half :] = e0f @ x[:w], e0l @ x[-w:]
        trace = c0[half] * (n - 2 * half) + np.trace(e0f[:, :half]) + np.trace(e0l[:, w - half :])
        return smooth, trace

    return _gcv_window(x, max_w, smoother)


def savgol_derivatives(
    x: np.ndarray, w: int, order: int, h: float
) -> tuple[np.ndarray, np.ndarray]:
    """``savgol_filter(x, w, order, deriv=1|2, delta=h, axis=0, mode="interp")``, both at once."""
    c1, c2, e1f, e2f, e1l, e2l = savgol_operators(w, order, h)[:6]
    half = w // 2
    windows = np.lib.stride_tricks.sliding_window_view(x, w, axis=0)  # (n - w + 1, dims, w)
    xd, xdd = np.empty_like(x), np.empty_like(x)
    xd[half : x.shape[0] - half], xdd[half : x.shape[0] - half] = windows @ c1, windows @ c2
    xd[:half], xdd[:half] = e1f @ x[:w], e2f @ x[:w]
    xd[x.shape[0] - half :], xdd[x.shape[0] - half :] = e1l @ x[-w:], e2l @ x[-w:]
    return xd, xdd


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


def local_polynomial_derivatives(
    t: np.ndarray, x: np.ndarray, window: int | None
) -> tuple[np.ndarray, np.ndarray]:
    """Savitzky-Golay on non-uniform stamps: per-sample least-squares polynomial fits.

    Without ``window`` it is chosen by generalised cross-validation (as for savgol): a
    clean demonstration keeps about N/40 (>= 7) samples, a noisy one a wider window.
    """
    n = t.size
    max_w = n if n % 2 else n - 1
    batches = [slice(k, min(k + _ROWS, n)) for k in range(0, n, _ROWS)]

    def smoother(x: np.ndarray, w: int) -> tuple[np.ndarray, float]:
        # value at t_i = first row of (V^T V)^-1 V^T: only that row is needed (cheap)
        smooth, trace = np.empty_like(x), 0.0
        for rows in batches:
            idx, V, _ = _local_polynomial_design(t, w, rows)
            p = V.shape[2]
            # Gram matrices from the power sums sum_w u^m, m = 0 .. 2 order
            u = V[..., 1] if p > 1 else np.zeros(V.shape[:2])
            sums = [np.full(len(idx), float(w))]
            power = V[..., -1].copy()
            for m in range(1, 2 * p - 1):
                sums.append((V[..., m] if m < p else (power := power * u)).sum(axis=1))
            S = np.stack(sums, axis=1)
            G = S[:, np.add.outer(np.arange(p), np.arange(p))]
            e0 = np.zeros((len(idx), p, 1))
            e0[:, 0] = 1.0
            row0 = (V @ np.linalg.solve(G, e0))[..., 0]  # (r, w): S's rows on their windows
            smooth[rows] = np.einsum("iw,iwd->id", row0, x[idx])
            r = np.arange(row0.shape[0])
            trace += float(np.sum(row0[r, np.arange(n)[rows] - idx[:, 0]]))
        return smooth, trace

    w = window if window is not None else _gcv_window(x, max_w, smoother)
    w = min(w, max_w)
    if w % 2 == 0 or w < 3:
        raise RepertoireError(f"local-polynomial window must be odd and >= 3, got {w}")
    xd, xdd = np.empty_like(x), np.empty_like(x)
    for rows in batches:
        idx, V, scale = _local_polynomial_design(t, w, rows)
        Q, R = np.linalg.qr(V)
        coef = np.linalg.solve(R, np.swapaxes(Q, 1, 2) @ x[idx])  # (r, order+1, n_dims)
        s = scale[:, None]
        xd[rows], xdd[rows] = coef[:, 1] / s, 2.0 * coef[:, 2] / s**2
    return xd, xdd
