"""local_poly's default derivative estimator: tricube-weighted local polynomials with windows
in time, a ridge on the cubic and higher coefficients, half-width and ridge chosen for the
second derivative (among the fits GCV cannot tell apart, the smallest estimated error)."""

import numpy as np
import pytest
from repertoire.planning.dmp_demos import noisy_sparse_minimum_jerk
from repertoire.planning.dmp_derivatives import (
    LOCAL_RIDGES,
    estimate_derivatives,
    kernel_gcv_scores,
    kernel_half_widths,
    kernel_polynomial_choice,
    kernel_polynomial_fit,
    kernel_scan,
    local_bandwidths,
    second_derivative_choice,
)
from repertoire.planning.dmp_math import minimum_jerk

from repertoire.errors import RepertoireError


def _clustered_stamps(seed: int = 11) -> np.ndarray:
    """102 stamps over 2 s: jittered, a 97 ms gap, and a pair 0.2 ms apart beside it."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 2.0, 105) + rng.uniform(-5e-3, 5e-3, 105)
    t[0], t[-1] = 0.0, 2.0
    t = t[(t < 0.9) | (t > 0.988)]  # the gap
    t = np.sort(np.r_[t, t[t < 0.9][-1] - 2e-4])  # the pair beside it
    return t


def _quintic(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    c = np.array([0.3, -1.0, 2.0, -0.7, 0.25, -0.04])
    p = np.polynomial.Polynomial(c)
    return p(t)[:, None], p.deriv(1)(t)[:, None], p.deriv(2)(t)[:, None]


def test_polynomials_are_recovered_exactly_on_clustered_stamps():
    t = _clustered_stamps()
    x, xd, xdd = _quintic(t)
    for method in ("auto", "local_poly"):
        d1, d2 = estimate_derivatives(t, x, method=method)
        np.testing.assert_allclose(d1, xd, rtol=0, atol=1e-9)
        np.testing.assert_allclose(d2, xdd, rtol=0, atol=1e-7)
    # any half-width: the unridged fit is exact for degree <= 5 ...
    for bandwidth in (1e-3, 0.1, 0.5):
        _, d1, d2 = kernel_polynomial_fit(t, x, bandwidth, 0.0)
        np.testing.assert_allclose(d2, xdd, rtol=0, atol=1e-6)
    # ... and the ridge (on coefficients of order >= 3 only) keeps quadratics exact
    q = 0.5 - 2.0 * t + 3.0 * t**2
    smooth, d1, d2 = kernel_polynomial_fit(t, q[:, None], 0.3, 1e-2)
    np.testing.assert_allclose(smooth[:, 0], q, atol=1e-12)
    np.testing.assert_allclose(d1[:, 0], -2.0 + 6.0 * t, atol=1e-10)
    np.testing.assert_allclose(d2[:, 0], 6.0, atol=1e-9)


@pytest.mark.parametrize("n", [3, 4, 6, 7])
def test_tiny_demonstrations_are_fitted_exactly_at_the_order_they_allow(n):
    t = np.r_[0.0, np.cumsum(np.linspace(0.1, 0.3, n - 1))]
    k = min(n - 1, 5)  # a polynomial of degree n - 1 (up to 5) through n samples
    c = np.arange(1.0, k + 2.0) / 4.0
    p = np.polynomial.Polynomial(c)
    d1, d2 = estimate_derivatives(t, p(t), method="local_poly")
    np.testing.assert_allclose(d1[:, 0], p.deriv(1)(t), atol=1e-9)
    np.testing.assert_allclose(d2[:, 0], p.deriv(2)(t), atol=1e-8)


def test_clustered_noisy_stamps_do_not_blow_the_second_derivative_up():
    """A unit minimum-jerk move (peak acceleration 1.44) with 2 mm noise on the clustered
    stamps: a window of 7 samples (the old default's smallest) puts the close pair's
    noise into the derivatives, the time windows do not."""
    t = _clustered_stamps()
    x, _, xdd = minimum_jerk(np.zeros(1), np.ones(1), 2.0, t)
    noisy = x + np.random.default_rng(0).normal(scale=2e-3, size=x.shape)
    _, counted = estimate_derivatives(t, noisy, method="local_poly", window=7)
    _, timed = estimate_derivatives(t, noisy)
    assert np.abs(counted - xdd).max() > 30.0  # measured 42 (42-174 on noise seeds 0-4)
    assert np.abs(timed - xdd).max() < 1.0  # measured 0.53 (0.53-0.94)
    assert np.sqrt(np.mean((timed - xdd) ** 2)) < 0.3  # measured 0.16 (0.16-0.24)


def test_gcv_flat_below_its_minimum_no_longer_picks_a_noisy_second_derivative():
    """Defect of GCV alone: 101 random stamps with a few close pairs, 2 mm noise on a unit
    minimum-jerk move (noisy_sparse_minimum_jerk, seed 2018): GCV's score, flat below its
    minimum, was 2 % lower at the narrowest half-width than at the widest, and that fit's
    second derivative is noise (RMS error 3.1 against a peak acceleration of 1.44). An
    order-5 fit is unbiased on the (quintic) move, so the chosen fit's error is its noise
    plus the ridge's shrinkage, which the choice estimates and minimises: bounded by the
    peak acceleration's half, where the narrowest fit's noise alone (2 mm times the norm
    of its second-derivative weights) exceeds the peak."""
    t, x, _, xdd = noisy_sparse_minimum_jerk(2018)
    peak = np.abs(xdd).max()
    bandwidths = local_bandwidths(t)
    scan = kernel_scan(t, x, bandwidths)
    gcv = kernel_gcv_scores(scan, t.size)
    q, k = np.unravel_index(np.argmin(gcv), gcv.shape)
    assert k == 0  # GCV's choice: the narrowest half-width
    assert 2e-3 * np.sqrt(scan.variance_2[q, k] / t.size) > peak  # measured 2.5
    _, narrow = kernel_polynomial_fit(t, x, bandwidths[k], LOCAL_RIDGES[q])[1:]
    assert np.sqrt(np.mean((narrow - xdd) ** 2)) > 2.0 * peak  # measured 3.1
    _, chosen = estimate_derivatives(t, x)
    assert np.sqrt(np.mean((chosen - xdd) ** 2)) < 0.5 * peak  # measured 0.29 (0.20 peak)


def _fit_by_definition(t, x, bandwidth, ridge):
    """kernel_polynomial_fit sample by sample: a weighted least-squares problem per window."""
    b = kernel_half_widths(t, bandwidth, 5)
    out = np.empty((3,) + x.shape)
    for i in range(t.size):
        u = (t - t[i]) / b[i]
        K = np.clip(1.0 - np.abs(u) ** 3, 0.0, None) ** 3
        V = u[:, None] ** np.arange(6)
        ridge_rows = np.sqrt(ridge * K.sum()) * np.eye(6)[3:]
        design = np.vstack([np.sqrt(K)[:, None] * V, ridge_rows])
        target = np.vstack([np.sqrt(K)[:, None] * x, np.zeros((3, x.shape[1]))])
        c = np.linalg.lstsq(design, target, rcond=None)[0]
        out[:, i] = c[0], c[1] / b[i], 2.0 * c[2] / b[i] ** 2
    return out


def test_the_compiled_fit_equals_weighted_least_squares_per_window():
    rng = np.random.default_rng(7)
    t = np.sort(np.r_[0.0, rng.uniform(0.0, 1.5, 78), 1.5])
    x = np.column_stack([np.sin(3.0 * t), np.exp(-t)]) + rng.normal(scale=1e-3, size=(80, 2))
    for bandwidth, ridge in ((0.05, 0.0), (0.2, 1e-3), (0.6, 1e-2)):
        fast = kernel_polynomial_fit(t, x, bandwidth, ridge)
        want = _fit_by_definition(t, x, bandwidth, ridge)
        for got, ref in zip(fast, want, strict=True):
            np.testing.assert_allclose(got, ref, rtol=0, atol=1e-10 * np.abs(ref).max())


def _smoothers(t, bandwidth, ridge):
    """The position and second-derivative smoother matrices, built column by column."""
    fits = [kernel_polynomial_fit(t, e[:, None], bandwidth, ridge) for e in np.eye(t.size)]
    return tuple(np.column_stack([f[k][:, 0] for f in fits]) for k in (0, 2))


def test_the_scan_and_the_choice_match_their_definitions():
    """kernel_scan's measures from the explicit smoothers; the choice: of the fits within
    one standard error of GCV's minimum, the smallest estimated xdd error (noise variance
    plus the ridge's estimated squared shrinkage against the lightest ridge)."""
    t = _clustered_stamps()[::2]  # 51 stamps
    n = t.size
    x, _, _ = minimum_jerk(np.zeros(2), np.array([1.0, -0.4]), 2.0, t)
    x = x + np.random.default_rng(3).normal(scale=2e-3, size=x.shape)
    bandwidths = local_bandwidths(t)
    scan = kernel_scan(t, x, bandwidths)
    y = x / np.abs(x).max()
    want = {f: np.empty(scan.rss.shape) for f in scan._fields if f != "residuals"}
    terms = np.empty(scan.rss.shape + (n,))
    for k, bandwidth in enumerate(bandwidths):
        smoothers = [_smoothers(t, bandwidth, ridge) for ridge in LOCAL_RIDGES]
        for q, (S, D2) in enumerate(smoothers):
            residuals = np.sum((S @ y - y) ** 2, axis=1)
            np.testing.assert_allclose(scan.residuals[q, k], residuals, rtol=1e-7, atol=1e-15)
            terms[q, k] = residuals / (1.0 - np.trace(S) / n) ** 2
            change = D2 - smoothers[0][1]  # against the lightest ridge (1e-4)
            values = (residuals.sum(), np.trace(S), np.sum(S**2), np.sum(D2**2),
                      np.sum((change @ y) ** 2), np.sum(change**2))  # fmt: skip
            for f, v in zip(want, values, strict=True):
                want[f][q, k] = v
    for f, v in want.items():
        np.testing.assert_allclose(getattr(scan, f), v, rtol=1e-7, atol=1e-12, err_msg=f)
    gcv = terms.sum(axis=-1)
    np.testing.assert_allclose(kernel_gcv_scores(scan, n), gcv, rtol=1e-8)
    best = np.unravel_index(np.argmin(gcv), gcv.shape)
    eligible = gcv <= gcv[best] + np.sqrt(n) * np.std(terms - terms[best], axis=-1)
    assert 1 < eligible.sum() < eligible.size  # the rule has a choice to make
    s2 = want["rss"][best] / (n - 2.0 * want["trace"][best] + want["trace_ss"][best])
    shrinkage = np.maximum(want["ridge_change"] - s2 * want["ridge_change_variance"], 0.0)
    risk = np.where(eligible, s2 * want["variance_2"] + shrinkage, np.inf)
    q, k = np.unravel_index(np.argmin(risk), risk.shape)
    assert second_derivative_choice(scan, n, 0.0) == (q, k)
    chosen = kernel_polynomial_choice(t, x)[1:]
    fit = kernel_polynomial_fit(t, x, bandwidths[k], LOCAL_RIDGES[q])[1:]
    for a, b in zip(chosen, fit, strict=True):
        np.testing.assert_array_equal(a, b)


def test_the_bandwidth_grid_runs_from_a_few_samples_to_half_the_demonstration():
    t = np.linspace(0.0, 2.0, 101)
    b = local_bandwidths(t)
    assert b[0] == pytest.approx(1.2 * 3 * 0.02)  # the reach of 7 evenly spaced samples
    np.testing.assert_allclose(np.diff(b) / b[:-1], 0.3)
    assert b[-1] <= 0.5 < 1.3 * b[-1]  # a quarter of the duration
    assert local_bandwidths(np.linspace(0.0, 2.0, 10001))[0] == pytest.approx(2.0 / 80)


def test_bad_bandwidths_and_ridges_are_named():
    t = np.linspace(0.0, 1.0, 20)
    x = np.sin(t)[:, None]
    for bandwidth in (0.0, -0.1, np.nan, np.inf):
        with pytest.raises(RepertoireError, match=f"bandwidth must be .* got {bandwidth!r}"):
            kernel_polynomial_fit(t, x, bandwidth)
    for ridge in (-1e-3, np.nan, np.inf):
        with pytest.raises(RepertoireError, match=f"ridge must be .* got {ridge!r}"):
            kernel_polynomial_fit(t, x, 0.1, ridge)
    for ridge in (0.0, -1.0, np.nan):
        with pytest.raises(RepertoireError, match=f"ridges must be .* > 0, got {ridge!r}"):
            kernel_polynomial_choice(t, x + 1e-3 * np.cos(40 * t)[:, None], ridges=(ridge,))
