"""Savitzky-Golay derivatives of long uniform demonstrations (tens of thousands of samples).

GCV's windows grow with the demonstration (about N / 40 and up to N / 4). scipy's
``savgol_coeffs`` fits powers of unscaled offsets and lost every digit from windows of about
1000 samples (order 5), and the edge operators were (w/2, w) matrices (1.4 GB for N = 30001):
a 6 s demonstration at 10 kHz had derivatives 94 % / 100 % off and was reproduced 21 % of its
range off; 60 s at 10 kHz did not fit in memory.
"""

import numpy as np
import pytest
from repertoire.planning.dmp_derivatives import (
    DIRECT_WINDOW,
    fit_demonstration,
    savgol_operators,
    window_dot,
)
from repertoire.planning.dmp_learn import learn_dmp
from repertoire.planning.dmp_math import minimum_jerk


@pytest.mark.parametrize("w", [7, 25, 201, 1001, 11417])
def test_savgol_operators_are_exact_on_quintics_for_any_window(w):
    # p(u) = 1 + u^2 + u^5 on u = (s - half) / half: p(0) = 1, p'(0) = 0, p''(0) = 2 (per u).
    half, h = w // 2, 1e-4
    u = (np.arange(w) - half) / half
    p = 1.0 + u**2 + u**5
    ops = savgol_operators(w, 5, h)
    scale = half * h  # d/dt = d/du / (half h)
    assert ops.interior[0] @ p == pytest.approx(1.0, abs=1e-13)
    assert ops.interior[1] @ p * scale == pytest.approx(0.0, abs=1e-13)
    assert ops.interior[2] @ p * scale**2 == pytest.approx(2.0, abs=1e-12)
    # Edge samples: the same polynomial's value and derivatives there.
    x = p[:, None]
    for k, exact in enumerate((p, 2 * u + 5 * u**4, 2 + 20 * u**3)):
        first, last = ops.edges(x, k)
        assert np.abs(first[:, 0] * scale**k - exact[:half]).max() <= 1e-11
        assert np.abs(last[:, 0] * scale**k - exact[w - half :]).max() <= 1e-11
    # O(w) storage: nothing of shape (w/2, w).
    assert ops.fit.shape == (6, w) and ops.first.shape == ops.last.shape == (3, half, 6)


def test_a_long_clean_minimum_jerk_demo_gets_exact_derivatives_and_is_reproduced():
    # 6 s at 10 kHz (60001 samples, GCV keeps the 1501-sample window): a quintic is exact.
    t = np.linspace(0.0, 6.0, 60001)
    x0, g = np.array([0.2, -1.0]), np.array([1.0, 0.5])
    x, xd, xdd = minimum_jerk(x0, g, 6.0, t)
    _, xd_e, xdd_e = fit_demonstration(t, x)
    assert np.abs(xd_e - xd).max() <= 1e-9 * np.abs(xd).max()  # was all of it
    assert np.abs(xdd_e - xdd).max() <= 1e-7 * np.abs(xdd).max()  # was all of it
    dmp = learn_dmp(t, x)
    r = dmp.rollout(dt=1e-3)
    ref = minimum_jerk(x0, g, 6.0, r.t)[0]
    exact = learn_dmp(t, x, xd=xd, xdd=xdd).rollout(dt=1e-3)
    assert np.abs(r.x - exact.x).max() <= 1e-8  # as with the exact derivatives
    assert (
        np.abs(r.x - ref).max() <= 1e-4 * np.ptp(x, axis=0).max()
    )  # with a sine added: 0.21 before


@pytest.mark.parametrize("w", [DIRECT_WINDOW, DIRECT_WINDOW + 1, 1501])
def test_window_dot_is_the_sliding_dot_product(w):
    x = np.random.default_rng(w).standard_normal((5000, 2)).cumsum(axis=0)
    c = np.random.default_rng(w + 1).standard_normal(w)
    ref = np.array([[c @ x[k : k + w, d] for d in range(2)] for k in range(5000 - w + 1)])
    got = window_dot(x, c)
    assert got.shape == ref.shape
    assert np.abs(got - ref).max() <= 1e-12 * np.abs(ref).max()
