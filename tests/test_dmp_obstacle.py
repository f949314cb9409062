"""Eq. 10 (obstacle coupling): the paper's formula, and the straight-at-the-obstacle case."""

import numpy as np
import pytest
from repertoire.planning.dmp_learn import learn_dmp
from repertoire.planning.dmp_math import minimum_jerk
from repertoire.planning.dmp_obstacle import (
    STRAIGHT_TOLERANCE,
    fallback_axis,
    obstacle_coupling,
)

from repertoire.errors import RepertoireError

GAMMA, BETA = 1000.0, 20.0 / np.pi


def _paper(x, v, o, gamma=GAMMA, beta=BETA):
    """Eq. 10 written out: Rodrigues' rotation by pi/2 about (o - x) x v, phi from acos."""
    d = o - x
    phi = np.arccos(d @ v / (np.linalg.norm(d) * np.linalg.norm(v)))
    r = np.cross(d, v)
    k = r / np.linalg.norm(r)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    R = np.eye(3) + K + K @ K  # sin(pi/2) = 1, 1 - cos(pi/2) = 1
    return gamma * (R @ v) * phi * np.exp(-beta * phi)


def test_term_is_the_papers_formula_wherever_the_axis_is_defined():
    rng = np.random.default_rng(7)
    for _ in range(200):
        x, v, o = rng.normal(size=(3, 3))
        gamma, beta = rng.uniform(0, 2000), rng.uniform(0, 10)
        np.testing.assert_allclose(
            obstacle_coupling(x, v, o, gamma, beta),
            _paper(x, v, o, gamma, beta),
            rtol=1e-10,
            atol=1e-12 * gamma * np.linalg.norm(v),
        )


@pytest.mark.parametrize("phi", [1e-3, 1e-7, 1e-10, np.pi - 1e-7])
def test_small_angles_are_exact(phi):
    # x = 0, o on +x, v at angle phi in the xy-plane: r along +z, R v = z x v,
    # p = gamma phi exp(-beta phi) (-sin phi, cos phi, 0) |v|. (acos of the cosine, used
    # before, read every angle below 1.5e-8 rad as 0.)
    v = 2.0 * np.array([np.cos(phi), np.sin(phi), 0.0])
    p = obstacle_coupling(np.zeros(3), v, np.array([0.7, 0.0, 0.0]), GAMMA, BETA)
    expected = GAMMA * phi * np.exp(-BETA * phi) * 2.0 * np.array([-np.sin(phi), np.cos(phi), 0])
    np.testing.assert_allclose(p, expected, rtol=1e-9, atol=1e-300)


def test_two_d_is_the_plane_z_0_of_three_d():
    rng = np.random.default_rng(8)
    for _ in range(50):
        x, v, o, vo = rng.normal(size=(4, 2))
        three = obstacle_coupling(np.r_[x, 0], np.r_[v, 0], np.r_[o, 0], GAMMA, BETA, np.r_[vo, 0])
        assert three[2] == 0.0
        np.testing.assert_array_equal(obstacle_coupling(x, v, o, GAMMA, BETA, vo), three[:2])


def test_heading_straight_at_the_obstacle_turns_left_by_the_fallback_axis():
    small = GAMMA * STRAIGHT_TOLERANCE * np.exp(-BETA * STRAIGHT_TOLERANCE)
    # in the xy-plane the axis is +z: R v = z x v, a turn to the left (counter-clockwise)
    v = np.array([0.6, 0.8, 0.0])
    np.testing.assert_array_equal(fallback_axis(v), [0.0, 0.0, 1.0])
    p = obstacle_coupling(np.zeros(3), v, 2.0 * v, GAMMA, BETA)
    np.testing.assert_allclose(p, small * np.array([-0.8, 0.6, 0.0]), rtol=1e-12)
    np.testing.assert_array_equal(
        obstacle_coupling(np.zeros(2), v[:2], 2 * v[:2], GAMMA, BETA), p[:2]
    )
    # moving along z (|v_z| > 0.9 |v|): world x's perpendicular part, x x (0, 0, 2) = (0, -2, 0)
    v = np.array([0.0, 0.0, 2.0])
    np.testing.assert_array_equal(fallback_axis(v), [1.0, 0.0, 0.0])
    p = obstacle_coupling(np.zeros(3), v, np.array([0.0, 0.0, 0.3]), GAMMA, BETA)
    np.testing.assert_allclose(p, small * np.array([0.0, -2.0, 0.0]), rtol=1e-12)
    # a general direction: the axis is z's part perpendicular to v, and R v is perpendicular
    v = np.array([0.3, -0.4, 0.5])
    a = fallback_axis(v)
    # z - (z . v) v / |v|^2 = (0, 0, 1) - (0.5 / 0.5) v = (-0.3, 0.4, 0.5), norm sqrt(0.5)
    np.testing.assert_allclose(a, np.array([-0.3, 0.4, 0.5]) / np.sqrt(0.5), rtol=1e-12)
    assert abs(a @ v) < 1e-15
    p = obstacle_coupling(np.ones(3), v, np.ones(3) + 3 * v, GAMMA, BETA)
    np.testing.assert_allclose(p, small * np.cross(a, v), rtol=1e-12)


def test_heading_away_pushes_to_the_same_side_as_heading_at_it():
    # phi = pi: eq. 10's magnitude gamma pi exp(-beta pi) |v| about -a, so the push is to
    # the left of x -> o as when heading at the obstacle.
    o, v = np.array([1.0, 0.0, 0.0]), np.array([-0.5, 0.0, 0.0])
    p = obstacle_coupling(np.zeros(3), v, o, GAMMA, BETA)
    np.testing.assert_allclose(p, GAMMA * np.pi * np.exp(-BETA * np.pi) * np.array([0, 0.5, 0]))
    at = obstacle_coupling(np.zeros(3), -v, o, GAMMA, BETA)
    assert at[1] > 0 and p[1] > 0


def test_the_straight_case_is_the_limit_from_the_right():
    # The obstacle an eps to the right of the line x -> o (here -y): for eps above the
    # round-off tolerance eq. 10 applies and its push is along +y, with a magnitude that
    # shrinks to the fallback's as eps -> 0.
    x, v = np.zeros(3), np.array([1.0, 0.0, 0.0])
    at_line = obstacle_coupling(x, v, np.array([0.5, 0.0, 0.0]), GAMMA, BETA)
    for eps in (1e-6, 1e-9, 2e-12):
        p = obstacle_coupling(x, v, np.array([0.5, -eps, 0.0]), GAMMA, BETA)
        assert p[1] > 0 and abs(p[0]) < 1e-9 * abs(p[1]) and p[2] == 0.0
        np.testing.assert_allclose(p[1], GAMMA * (eps / 0.5) * np.exp(-BETA * eps / 0.5), rtol=1e-9)
    assert at_line[1] == pytest.approx(GAMMA * STRAIGHT_TOLERANCE, rel=1e-9)


def test_fallback_axis_refuses_zero_and_bad_velocities():
    with pytest.raises(RepertoireError, match="v must be non-zero"):
        fallback_axis(np.zeros(3))
    with pytest.raises(RepertoireError, match=r"v must be a finite 3-vector, got \[nan"):
        fallback_axis([np.nan, 0, 0])
    with pytest.raises(RepertoireError, match="v must be a finite 3-vector"):
        fallback_axis([1.0, 0.0])


def _straight_dmp(n_dims: int, axis: int):
    t = np.linspace(0.0, 1.0, 501)
    goal = np.zeros(n_dims)
    goal[axis] = 0.5
    return learn_dmp(t, minimum_jerk(np.zeros(n_dims), goal, 1.0, t)[0], n_basis=30)


def _coupled(dmp, o):
    return dmp.rollout(
        method="euler",
        n_steps=1500,
        coupling=lambda x, xd: obstacle_coupling(x, xd, o, GAMMA, BETA),
    ).x


def test_a_straight_dmp_clears_an_obstacle_on_its_line():
    """Before: 0.28 mm (median over 20 seeded placements), the path went through the centre."""
    dmp = _straight_dmp(2, 0)
    o = np.array([0.25, 0.0])
    assert np.abs(dmp.rollout(n_steps=1500).x[:, 1]).max() == 0.0  # exactly on the line
    x = _coupled(dmp, o)
    d = np.linalg.norm(x - o, axis=1)
    k = int(d.argmin())
    assert d[k] > 0.045 and x[k, 1] > 0  # 49.4 mm, passing on the left
    assert np.linalg.norm(x[-1] - dmp.goal) < 1e-3
    # the one-sided limit: obstacles eps to the right of the line give paths that converge
    # to this one (measured: 9.2e-5, 2.5e-5, 7.0e-8 m)
    gaps = [np.abs(_coupled(dmp, o - [0.0, eps]) - x).max() for eps in (1e-6, 1e-9, 1e-12)]
    assert gaps[0] > gaps[1] > gaps[2] and gaps[2] < 1e-6
    # the same in 3-D, in the plane z = 0 (bit for bit) and along z (rotated)
    x3 = _coupled(_straight_dmp(3, 0), np.array([0.25, 0.0, 0.0]))
    np.testing.assert_array_equal(x3[:, :2], x)
    assert np.all(x3[:, 2] == 0.0)
    xz = _coupled(_straight_dmp(3, 2), np.array([0.0, 0.0, 0.25]))
    assert np.linalg.norm(xz - [0, 0, 0.25], axis=1).min() == pytest.approx(d[k], abs=1e-9)


def test_two_d_dmp_system_avoids_an_obstacle_on_its_line():
    from repertoire.studies.dmp_goals import simulate_dmp
    from repertoire.systems.dmp import ObstacleCoupling

    oc = ObstacleCoupling(GAMMA, BETA, n_dims=2)
    ctx = oc.CreateDefaultContext()
    x, v, o = np.array([0.1, 0.0]), np.array([1.0, 0.5]), np.array([1.0, 0.6])
    for name, value in (("position", x), ("velocity", v), ("obstacle", o)):
        oc.GetInputPort(name).FixValue(ctx, value)
    np.testing.assert_array_equal(
        oc.GetOutputPort("coupling").Eval(ctx), obstacle_coupling(x, v, o, GAMMA, BETA)
    )
    with pytest.raises(RepertoireError, match="n_dims 2 or 3, got 4"):
        ObstacleCoupling(n_dims=4)
    dmp = _straight_dmp(2, 0)
    o = np.array([0.25, 0.0])
    _, xs, _, _ = simulate_dmp(dmp, [0.0], [dmp.goal], 1.5, obstacle=o)
    assert np.linalg.norm(xs - o, axis=1).min() > 0.045
    assert np.linalg.norm(xs[-1] - dmp.goal) < 1e-3


def test_term_turns_the_papers_scaled_velocity():
    """Eq. 9 adds p(x, v) with v = tau dx/dt (eq. 7): the term is tau times that of dx/dt."""
    from repertoire.systems.dmp import ObstacleCoupling

    x, xd, o, vo = np.array([0.1, 0.0, 0.2]), np.array([1.0, 0.5, -0.2]), np.ones(3), [0, 0.3, 0]
    once = obstacle_coupling(x, xd, o, GAMMA, BETA, vo)
    np.testing.assert_array_equal(obstacle_coupling(x, xd, o, GAMMA, BETA, vo, tau=2.0), 2 * once)
    np.testing.assert_array_equal(obstacle_coupling(x, xd, o, GAMMA, BETA, vo, tau=1.0), once)
    for bad in (0.0, -1.0, np.inf, np.nan, "2"):
        with pytest.raises(RepertoireError, match="tau must be a finite number > 0"):
            obstacle_coupling(x, xd, o, GAMMA, BETA, tau=bad)
    with pytest.raises(RepertoireError, match="gamma and beta must be finite and >= 0, got '1'"):
        obstacle_coupling(x, xd, o, "1", BETA)  # was a TypeError from the comparison
    oc = ObstacleCoupling(GAMMA, BETA, tau=2.5)
    ctx = oc.CreateDefaultContext()
    for name, value in (("position", x), ("velocity", xd), ("obstacle", o)):
        oc.GetInputPort(name).FixValue(ctx, value)
    np.testing.assert_array_equal(
        oc.GetOutputPort("coupling").Eval(ctx), obstacle_coupling(x, xd, o, GAMMA, BETA, tau=2.5)
    )
    oc.set_tau(ctx, 0.5)
    np.testing.assert_array_equal(
        oc.GetOutputPort("coupling").Eval(ctx), obstacle_coupling(x, xd, o, GAMMA, BETA, tau=0.5)
    )
    with pytest.raises(RepertoireError, match="tau must be a finite number > 0, got -1"):
        ObstacleCoupling(tau=-1.0)


@pytest.mark.parametrize("tau", [0.5, 2.0, 4.0])
def test_a_coupled_dmp_takes_the_same_path_at_any_tau(tau):
    """The paper's temporal invariance holds with the coupling term too.

    The same demonstration recorded over ``tau`` seconds instead of 1 s, run in a DmpSystem
    stepped at 1 ms per second of tau (the same steps in phase), goes round the obstacle on
    the same path, bit for bit. Before (eq. 10 turned dx/dt), tau 0.5 / 2 / 4 passed this
    obstacle 76.3 / 55.7 / 47.9 mm from its centre instead of 65.0 mm.
    """
    from repertoire.studies.dmp_goals import simulate_dmp

    t = np.linspace(0.0, 1.0, 501)
    Y, _, _ = minimum_jerk(np.zeros(3), np.array([0.5, 0.2, 0.1]), 1.0, t)
    Y[:, 2] += 0.1 * np.sin(np.pi * t)  # a curved path
    o = Y[250] + np.array([0.0, 0.03, 0.0])
    paths, clearance = [], []
    for scale in (1.0, tau):
        dmp = learn_dmp(scale * t, Y, n_basis=30)
        dt = 1e-3 * scale
        _, x, _, _ = simulate_dmp(dmp, [0.0], [dmp.goal], 1.5 * scale, time_step=dt, obstacle=o)
        paths.append(x)
        clearance.append(np.linalg.norm(x - o, axis=1).min())
    assert clearance[0] == pytest.approx(0.0650, abs=1e-4)
    assert len(paths[0]) == len(paths[1]) == 1501
    np.testing.assert_array_equal(paths[1], paths[0])
