"""Translation invariance: a DMP's equations (eq. 1-8) see positions only through g - x,
g - x0 and their derivatives, so a movement far from the origin must be learned and rolled
out as the same movement at the origin (only the offset's own rounding may differ)."""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from repertoire.planning.dmp_derivatives import estimate_derivatives
from repertoire.planning.dmp_learn import learn_dmp
from repertoire.planning.dmp_math import (
    basis_centres,
    basis_widths,
    minimum_jerk,
    minimum_jerk_via_points,
    rollout,
)
from repertoire.systems.dmp_discrete import DiscreteDmpSystem

OFFSET = 1e3
AMPLITUDE = 3e-4  # a 0.3 mm movement 1000 units (mm, or m) from the origin


def _stamps(kind: str) -> np.ndarray:
    if kind == "uniform":
        return np.linspace(0.0, 2.0, 1001)
    rng = np.random.default_rng(3)
    return np.concatenate([[0.0], np.sort(rng.uniform(0.0, 2.0, 999)), [2.0]])


@pytest.mark.parametrize("kind", ["uniform", "random"])
def test_derivatives_of_a_movement_far_from_the_origin_are_those_at_the_origin(kind):
    t = _stamps(kind)
    start, end = np.array([0.0, AMPLITUDE]), np.array([AMPLITUDE, -AMPLITUDE])
    x, xd, xdd = minimum_jerk(start, end, 2.0, t)
    far = x + OFFSET
    near = far - OFFSET  # exact (Sterbenz): the same samples, rounding and all, at the origin
    d1_near, d2_near = estimate_derivatives(t, near)
    d1, d2 = estimate_derivatives(t, far)
    peak = np.abs(xdd).max()
    # exact for minimum-jerk (quintic) segments, up to the samples' own rounding
    assert np.abs(d2_near - xdd).max() / peak < 2e-4
    # the offset itself changes nothing: the fits on the offset samples were 3.3e-3
    # (uniform) and 6.7e-5 (these random stamps; 5e-2 on others) of the peak off
    assert np.abs(d2 - d2_near).max() / peak < 1e-9
    assert np.abs(d1 - d1_near).max() / np.abs(xd).max() < 1e-10


def test_learning_and_rollout_far_from_the_origin_equal_the_same_at_the_origin():
    t, x = minimum_jerk_via_points(
        np.array([[0.0, 0.0], [1.0, -0.5], [-0.3, 0.8], [0.6, 0.2]]) * AMPLITUDE, 2.0, 1001
    )
    far = learn_dmp(t, x + OFFSET)
    near = learn_dmp(t, x + OFFSET - OFFSET)
    scale = np.abs(near.weights).max()
    assert np.abs(far.weights - near.weights).max() / scale < 1e-9  # was 1.9e-3
    for dt in (1e-3, 1e-4):
        r_near = near.rollout(dt=dt)
        r_far = far.rollout(dt=dt)
        # was 3e-4 of the range at 0.1 ms steps (the recurrence integrated 1000 + 3e-4)
        assert np.abs(r_far.x - OFFSET - r_near.x).max() / AMPLITUDE < 1e-8
        np.testing.assert_allclose(r_far.xd, r_near.xd, rtol=0, atol=1e-8 * AMPLITUDE)


def test_rollout_is_translation_equivariant_to_the_offset_rounding():
    """x(t; x0 + c, g + c) = x(t; x0, g) + c for both formulations and the euler path."""
    rng = np.random.default_rng(8)
    w = rng.normal(size=(3, 20)) * 1e-4
    c = basis_centres(20, 4.6)
    h = basis_widths(c, 4.6)
    x0, g = np.array([0.0, 1e-4, -2e-4]), np.array([3e-4, -1e-4, 1e-4])
    for formulation in ("new", "old"):
        for method in ("exact", "euler"):
            kw = dict(dt=1e-4, formulation=formulation, method=method, v0=np.full(3, 1e-4))
            a = rollout(w, c, h, 156.25, 25.0, 4.6, 1.0, x0, g, **kw)
            b = rollout(w, c, h, 156.25, 25.0, 4.6, 1.0, x0 + OFFSET, g + OFFSET, **kw)
            # the offset's own rounding (eps 1e3 = 2e-13) is 1e-9 of the range; was 1.8e-4
            assert np.abs(b.x - OFFSET - a.x).max() < 1e-8 * AMPLITUDE
            np.testing.assert_allclose(b.xdd, a.xdd, rtol=0, atol=1e-6 * np.abs(a.xdd).max())


@pytest.mark.parametrize(("offset", "bound"), [(1e3, 1.5e-8), (1e5, 1.5e-6)])
def test_the_discrete_system_far_from_the_origin_follows_the_rollout(offset, bound):
    """DiscreteDmpTables.step works in the displacement from x0, as the rollout does."""
    t, x = minimum_jerk_via_points(
        np.array([[0.0, 0.0], [1.0, -0.5], [-0.3, 0.8], [0.6, 0.2]]) * AMPLITUDE, 2.0, 1001
    )
    dmp = learn_dmp(t, x + offset)
    system = DiscreteDmpSystem(dmp, time_step=1e-3)
    context = system.CreateDefaultContext()
    simulator = Simulator(system, context)
    reference = dmp.rollout(dt=1e-3, n_steps=3000)
    for k in (500, 1000, 2000, 3000):
        simulator.AdvanceTo(k * 1e-3)
        x_k = system.GetOutputPort("position").Eval(context)
        # absolute positions: 4.4e-8 (1e3) and 4.6e-6 (1e5) of the range; now 3e-9 / 4.4e-7
        assert np.abs(x_k - reference.x[k]).max() / AMPLITUDE < bound
