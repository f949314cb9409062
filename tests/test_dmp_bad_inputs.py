"""Bad inputs to the DMP API raise RepertoireError naming the argument and its value."""

import re

import numpy as np
import pytest
from repertoire.planning.dmp import DmpParameters, QuaternionDmpParameters, save_dmp
from repertoire.planning.dmp_chain import chain_rollout
from repertoire.planning.dmp_learn import (
    learn_dmp,
    learn_dmp_from_demonstrations,
    learn_quaternion_dmp,
)
from repertoire.planning.dmp_math import minimum_jerk_via_points

from repertoire.errors import RepertoireError

T = np.linspace(0, 1, 200)
_, X = minimum_jerk_via_points(np.array([[0, 0.0], [1, 2.0], [0.5, -1]]), 1.0, 200)
A = np.linspace(0, 0.5, 200)
QUATS = np.c_[np.cos(A), 0 * A, 0 * A, np.sin(A)]
THREE_FOR_TWO = "must be a scalar or have one entry per DOF (2), got shape (3,): [1.0, 2.0, 3.0]"


@pytest.fixture(scope="module")
def p():
    return learn_dmp(T, X, n_basis=20)


@pytest.fixture(scope="module")
def qp():
    return learn_quaternion_dmp(T, QUATS, n_basis=20)


def raises(message: str):
    """pytest.raises(RepertoireError) matching ``message`` literally."""
    return pytest.raises(RepertoireError, match=re.escape(message))


@pytest.mark.parametrize("arg", ["goal", "x0", "v0"])
def test_rollout_refuses_nan_vectors(p, arg):
    with raises(f"{arg} contains NaN or inf: [nan  0.]"):
        p.rollout(**{arg: np.array([np.nan, 0.0])})


def test_rollout_refuses_nan_in_a_per_sample_goal(p):
    goals = np.tile(p.goal, (11, 1))
    goals[4, 1] = np.inf
    with raises("goal contains NaN or inf"):
        p.rollout(goal=goals, n_steps=10)


@pytest.mark.parametrize("n_steps", [0, -5, 2.5, float("nan")])
def test_rollout_refuses_bad_step_counts(p, qp, n_steps):
    for dmp in (p, qp):
        with raises(f"n_steps must be an integer >= 1, got {n_steps!r}"):
            dmp.rollout(n_steps=n_steps)


def test_rollout_refuses_a_dt_longer_than_twice_tau(p):
    with raises("dt = 3.0 is longer than twice tau = 0.99"):
        p.rollout(tau=0.99, dt=3.0)


def test_rollout_refuses_a_velocity_of_the_wrong_length(p):
    with raises("v0 must have 2 entries, got 3: [0. 0. 0.]"):
        p.rollout(v0=np.zeros(3))


@pytest.mark.parametrize("dt", [0.0, -1e-3, float("nan")])
def test_quaternion_rollout_refuses_bad_dt(qp, dt):
    with raises(f"dt must be a finite number > 0, got {dt}"):
        qp.rollout(dt=dt)
    component = learn_quaternion_dmp(T, QUATS, mode="component", n_basis=20)
    with raises(f"dt must be a finite number > 0, got {dt}"):
        component.rollout(dt=dt)


@pytest.mark.parametrize("arg", ["goal", "q0"])
def test_quaternion_rollout_refuses_a_non_quaternion(qp, arg):
    with raises(f"{arg} must be a unit quaternion (w, x, y, z) of shape (4,), got shape (3,)"):
        qp.rollout(**{arg: np.array([1.0, 0, 0])})
    with raises(f"{arg} are not unit: | |q| - 1 | = 1"):
        qp.rollout(**{arg: np.array([2.0, 0, 0, 0])})
    with raises(f"{arg} contains NaN or inf"):
        qp.rollout(**{arg: np.array([np.nan, 0, 0, 0])})


def test_learn_dmp_refuses_gains_of_the_wrong_length():
    with raises("K " + THREE_FOR_TWO):
        learn_dmp(T, X, K=[1.0, 2.0, 3.0])
    with raises("D " + THREE_FOR_TWO):
        learn_dmp(T, X, D=[1.0, 2.0, 3.0])


def test_learn_dmp_refuses_bad_known_derivatives():
    with raises("xd must have the demonstration's shape (200, 2), got (10, 2)"):
        learn_dmp(T, X, xd=np.zeros((10, 2)), xdd=np.zeros((200, 2)))
    with raises("xdd must have the demonstration's shape (200, 2), got (200, 3)"):
        learn_dmp(T, X, xd=np.zeros((200, 2)), xdd=np.zeros((200, 3)))
    xdd = np.zeros((200, 2))
    xdd[7, 1] = np.nan
    with raises("xdd contains NaN or inf (first at sample 7)"):
        learn_dmp(T, X, xd=np.zeros((200, 2)), xdd=xdd)


def test_dmp_parameters_refuse_bad_gains_and_widths(p):
    args = [p.weights, p.centres, p.widths, p.K, p.D, p.alpha, 1.0, p.x0, p.goal]
    with raises("K " + THREE_FOR_TWO):
        DmpParameters(*args[:3], [1.0, 2.0, 3.0], *args[4:])
    with raises(f"widths must be > 0, got widths[0] = {-p.widths[0]} (20 of 20 not > 0)"):
        DmpParameters(*args[:2], -p.widths, *args[3:])
    widths = p.widths.copy()
    widths[5] = 0.0
    with raises("widths must be > 0, got widths[5] = 0.0 (1 of 20 not > 0)"):
        DmpParameters(*args[:2], widths, *args[3:])


def test_quaternion_dmp_parameters_refuse_bad_damping_weights_and_widths(qp):
    def make(**kw):
        fields = dict(
            weights=qp.weights,
            centres=qp.centres,
            widths=qp.widths,
            K=qp.K,
            D=qp.D,
            alpha=qp.alpha,
            tau=qp.tau,
            q0=qp.q0,
            goal=qp.goal,
        )
        return QuaternionDmpParameters(**(fields | kw))

    with raises("D must be a finite number >= 0, got nan"):
        make(D=np.nan)
    with raises("D must be a finite number >= 0, got -5.0"):
        make(D=-5.0)
    with raises("weights contains NaN or inf"):
        make(weights=qp.weights * np.nan)
    with raises("centres contains NaN or inf"):
        make(centres=qp.centres + np.inf)
    with raises(f"widths must be > 0, got widths[0] = {-qp.widths[0]} (20 of 20 not > 0)"):
        make(widths=-qp.widths)
    assert make(D=0.0).D == 0.0  # undamped is allowed, as for DmpParameters


def test_chain_rollout_refuses_bad_durations_and_steps(p):
    segs, goals, times = [p, p], [p.goal, p.goal], [0.0, 0.5]
    for duration in (0.1, 0.5, 0.5004):
        with raises(
            f"duration = {duration} must be more than one step (dt = 0.001) past the last "
            "switch time 0.5"
        ):
            chain_rollout(segs, goals, times, duration=duration)
    assert chain_rollout(segs, goals, times, duration=0.502).x.shape == (503, 2)
    for duration in (float("nan"), -1.0, float("inf")):
        with raises(f"duration must be a finite number > 0, got {duration}"):
            chain_rollout(segs, goals, times, duration=duration)
    for dt in (0.0, -1e-3, float("nan")):
        with raises(f"dt must be a finite number > 0, got {dt}"):
            chain_rollout(segs, goals, times, dt=dt)


def test_obstacle_coupling_refuses_bad_vectors_and_gains():
    from repertoire.planning.dmp_math import obstacle_coupling

    x, v, o = np.zeros(3), np.ones(3), np.array([1.0, 0.5, 0.0])
    with raises("obstacle contains NaN or inf: [nan  0.  0.]"):
        obstacle_coupling(x, v, np.array([np.nan, 0, 0]), 1.0, 1.0)
    with raises("xd must have 2 entries (x, y), got 3: [1. 1. 1.]"):
        obstacle_coupling(np.zeros(2), v, o, 1.0, 1.0)  # a 2-D position, 3-D velocity
    with raises("x must have 2 or 3 entries (x, y[, z]), got 4: [0. 0. 0. 0.]"):
        obstacle_coupling(np.zeros(4), v, o, 1.0, 1.0)
    with raises("gamma and beta must be finite and >= 0, got -1.0, 1.0"):
        obstacle_coupling(x, v, o, -1.0, 1.0)


def test_minimum_jerk_via_points_refuses_bad_points_and_sample_counts():
    with raises("points must have shape (m, n) with m >= 2 (start and end), got (1, 2)"):
        minimum_jerk_via_points(np.zeros((1, 2)), 1.0, 10)
    with raises("points contains NaN or inf (first at point 1)"):
        minimum_jerk_via_points(np.array([[0, 0], [np.nan, 1.0]]), 1.0, 10)
    with raises("n_samples must be an integer >= 3, got 10.5"):
        minimum_jerk_via_points(np.array([[0, 0], [1, 1.0]]), 1.0, 10.5)


def test_learning_refuses_a_negative_smoothing_and_a_boolean_basis_count():
    with raises("smoothing (the spline's lambda) must be a finite number >= 0 or None, got -1.0"):
        learn_dmp(T, X, derivatives="spline", smoothing=-1.0)
    with raises("need at least one basis function (n_basis a whole number >= 1), got True"):
        learn_dmp(T, X, n_basis=True)
    # 2.5 is >= 1: the message said only "n_basis >= 1"
    with raises("need at least one basis function (n_basis a whole number >= 1), got 2.5"):
        learn_dmp(T, X, n_basis=2.5)


def test_rollout_refuses_a_coupling_of_the_wrong_size(p):
    with raises("coupling(x, xd) must return 2 entries (one per DOF), got shape (3,)"):
        p.rollout(method="euler", coupling=lambda x, v: np.zeros(3))


def test_dmp_parameters_refuse_weights_that_are_not_a_matrix(p):
    rest = [p.centres, p.widths, p.K, p.D, p.alpha, 1.0, p.x0, p.goal]
    with raises("weights must have shape (n_dims >= 1, n_basis), got (2, 20, 1)"):
        DmpParameters(np.zeros((2, 20, 1)), *rest)
    with raises("weights must have shape (n_dims >= 1, n_basis), got (0, 20)"):
        DmpParameters(np.zeros((0, 20)), p.centres, p.widths, 1.0, 1.0, p.alpha, 1.0, [], [])


@pytest.mark.parametrize("derivatives", ["savgol", "local_poly"])
def test_a_window_longer_than_the_demonstration_is_refused(derivatives):
    # it was cut to the 199 samples silently (one global polynomial)
    with raises("window = 1001 is longer than the demonstration's 200 samples; use an odd "):
        learn_dmp(T, X, n_basis=20, derivatives=derivatives, window=1001)
    learn_dmp(T, X, n_basis=20, derivatives=derivatives, window=199)  # the longest allowed


@pytest.mark.parametrize("derivatives", ["auto", "savgol", "local_poly"])
def test_a_smoothing_without_the_spline_is_refused_not_ignored(derivatives):
    # it was dropped silently: learn_dmp(..., smoothing=1e-4) estimated with Savitzky-Golay
    with raises(
        "smoothing = 0.0001 is the smoothing spline's lambda and needs method='spline' "
        f"(derivatives='spline' when learning), got method={derivatives!r}"
    ):
        learn_dmp(T, X, n_basis=20, derivatives=derivatives, smoothing=1e-4)
    with raises("smoothing = -1.0 is the smoothing spline's lambda and needs method='spline'"):
        learn_dmp(T, X, n_basis=20, derivatives=derivatives, smoothing=-1.0)


def test_a_window_with_the_spline_is_refused_not_ignored():
    with raises("window = 11 is the Savitzky-Golay / local-polynomial window; method='spline'"):
        learn_dmp(T, X, n_basis=20, derivatives="spline", window=11)
    p = learn_dmp(T, X, n_basis=20, derivatives="spline", smoothing=1e-6)
    assert np.all(np.isfinite(p.weights))


def test_a_chain_names_the_segment_whose_goal_is_bad():
    p = learn_dmp(T, X, n_basis=20)
    ok = [1.0, 0.0]
    # it said "goal must have shape (2,) or (1001, 2), got ()" for None, naming no segment
    with raises("segment 1: goal must be a vector of 2 numbers, got None"):
        chain_rollout([p, p], [ok, None], [0.0, 0.5])
    with raises("segment 1: goal must be 2 numbers, got ['a', 'b']"):
        chain_rollout([p, p], [ok, ["a", "b"]], [0.0, 0.5])
    with raises("segment 1: goal has 3 entries but weights have 2 DOF"):
        chain_rollout([p, p], [ok, [1.0, 2.0, 3.0]], [0.0, 0.5])
    with raises("segment 0: goal contains NaN or inf: [nan  1.]"):
        chain_rollout([p, p], [[np.nan, 1.0], ok], [0.0, 0.5])
    with raises("segment 1: goal must have shape (2,) or (1001, 2), got (5, 2)"):
        chain_rollout([p, p], [ok, np.zeros((5, 2))], [0.0, 0.5])
    # a goal per sample (a moving goal) is still a segment's goal: here a constant one
    fixed = chain_rollout([p, p], [ok, [2.0, 0.5]], [0.0, 0.5])
    moving = chain_rollout([p, p], [ok, np.tile([2.0, 0.5], (1001, 1))], [0.0, 0.5])
    np.testing.assert_array_equal(moving.x, fixed.x)


def test_a_non_numeric_gain_is_named():
    # it was float()'s bare "could not convert string to float: 'a'"
    with raises("K must be a number or one number per DOF (2), got 'a'"):
        learn_dmp(T, X, n_basis=20, K="a")
    with raises("D must be a number or one number per DOF (2), got 'b'"):
        learn_dmp(T, X, n_basis=20, D="b")


def test_joint_learning_names_the_demonstration_that_fails():
    # it said "start equals goal in DOF [0]" without saying which demonstration
    loop = np.stack([np.sin(np.pi * T), T], 1)  # DOF 0 returns to its start
    with raises(
        "demonstration 1: the old formulation (eq. 5) divides by g - x0, but start equals "
        "goal in DOF [0]; use formulation='new'"
    ):
        learn_dmp_from_demonstrations([(T, X), (T, loop)], formulation="old", n_basis=20)
    p = learn_dmp_from_demonstrations([(T, X), (T, loop)], n_basis=20)  # eq. 6-8: fine
    assert np.all(np.isfinite(p.weights))


def test_time_stamps_that_are_not_one_vector_and_samples_that_are_not_numbers_are_named():
    with raises("demonstration time stamps must be one vector (N,), got shape (200, 2)"):
        learn_dmp(np.c_[T, T], X)
    with raises("demonstration time stamps and samples must be numbers"):
        learn_dmp(T, np.array([["a", "b"]] * 200))
    # a column of stamps is one vector
    np.testing.assert_array_equal(learn_dmp(T[:, None], X).weights, learn_dmp(T, X).weights)


@pytest.mark.parametrize(
    "field, value",
    [
        ("weights", "x"),
        ("x0", ["a", 0]),
        ("goal", [[1.0], [2.0, 3.0]]),
        ("v0", "abc"),
        ("centres", {}),
    ],
)
def test_records_with_non_numbers_name_the_field(p, field, value):
    with raises(f"{field} must be numbers, got {value!r}"):
        DmpParameters.from_dict({**p.to_dict(), field: value})


@pytest.mark.parametrize("field, value", [("tau", "1.0"), ("alpha", "4"), ("tau", True)])
def test_records_with_non_number_scalars_name_the_field(p, qp, field, value):
    # float() would take "1.0" and True; a record's scalar must be a number
    with raises(f"{field} must be a number, got {value!r}"):
        DmpParameters.from_dict({**p.to_dict(), field: value})
    with raises(f"{field} must be a number, got {value!r}"):
        QuaternionDmpParameters.from_dict({**qp.to_dict(), field: value})


def test_records_with_names_not_a_list_or_bad_omega0_are_named(p, qp):
    with raises("names must be a list of strings (one per DOF), got None"):
        DmpParameters.from_dict({**p.to_dict(), "names": None})
    with raises("omega0 must be numbers, got 'fast'"):
        QuaternionDmpParameters.from_dict({**qp.to_dict(), "omega0": "fast"})


def test_a_one_entry_array_tau_is_a_number(p, qp):
    # e.g. tau read from a Drake port (shape (1,)): used as a float, not refused by round()
    a, b = p.rollout(tau=np.array([0.5])), p.rollout(tau=0.5)
    np.testing.assert_array_equal(a.x, b.x)
    from repertoire.planning.dmp_quaternion import quaternion_rollout

    _, qa, _ = quaternion_rollout(*qp._dynamics()[:6], np.array([0.5]), qp.q0, qp.goal)
    _, qb, _ = quaternion_rollout(*qp._dynamics()[:6], 0.5, qp.q0, qp.goal)
    np.testing.assert_array_equal(qa, qb)


@pytest.mark.parametrize(
    ("tau", "shown"),
    [("1", "'1'"), (True, "True"), (np.bool_(True), "np.True_"), ([1.0, 2.0], "[1.0, 2.0]")],
)
def test_rollout_refuses_a_tau_that_is_not_a_number(p, tau, shown):
    # a string or a bool was read as a number (tau='1' and tau=True ran a 1 s rollout)
    with raises(f"tau must be a finite number > 0, got {shown}"):
        p.rollout(tau=tau)
    np.testing.assert_array_equal(p.rollout(tau=np.array([p.tau])).x, p.rollout().x)


def test_time_stamps_with_nan_are_named_as_time_stamps():
    t = T.copy()
    t[4] = np.inf
    with raises("demonstration time stamps contain NaN or inf (first at t[4] = inf)"):
        learn_dmp(t, X)
    x = X.copy()
    x[9, 1] = np.nan
    with raises("demonstration contains NaN or inf (first at sample 9)"):
        learn_dmp(T, x)


def test_save_dmp_refuses_a_suffix_other_than_json(p, tmp_path):
    # it wrote JSON into d.npz (MotionLibrary.save already refused that)
    with raises(f"a DMP artefact is saved as JSON: {tmp_path / 'd.npz'} must end in '.json'"):
        save_dmp(p, tmp_path / "d.npz")
    assert not (tmp_path / "d.npz").exists()


@pytest.mark.parametrize("mode", ["component", "manifold"])
def test_quaternion_rollout_takes_tau_like_the_vector_rollout(mode):
    q = learn_quaternion_dmp(T, QUATS, mode=mode, n_basis=20)
    # Time scaling: tau' = 2 tau with dt' = 2 dt passes the same states (exactly scaled steps).
    _, Q1, _ = q.rollout(dt=2e-3, n_steps=400)
    _, Q2, _ = q.rollout(tau=2 * q.tau, dt=4e-3, n_steps=400)
    np.testing.assert_allclose(Q2, Q1, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(q.rollout(tau=q.tau)[1], q.rollout()[1])
    for tau, shown in ((0.0, "0.0"), (-1.0, "-1.0"), ("1", "'1'")):
        with raises(f"tau must be a finite number > 0, got {shown}"):
            q.rollout(tau=tau)


def test_a_string_of_names_is_refused_not_split_into_letters():
    """``names="xy"`` was learned as the names ['x', 'y'] (and "pos" for 3 DOF as p, o, s)."""
    message = "names must be a list of strings (one per DOF), got 'xy'"
    with raises(message):
        learn_dmp(T, X, n_basis=5, names="xy")
    with raises(message):
        learn_dmp_from_demonstrations([(T, X)], n_basis=5, names="xy")
    assert learn_dmp(T, X, n_basis=5, names=("x", "y")).names == ["x", "y"]


def test_handoff_state_checks_the_vectors_against_the_successor(p):
    """A 3-vector x for a 2-DOF successor came back as a 3-entry equation start."""
    from repertoire.planning.dmp_chain import handoff_state

    with raises("x must have 2 entries, got 3: [0, 0, 0]"):
        handoff_state(p, [0, 0, 0], [0, 0], 1.0)
    with raises("v contains NaN or inf"):
        handoff_state(p, [0, 0], [np.nan, 0], 1.0)
    with raises("acceleration must have 2 entries, got 1"):
        handoff_state(p, [0, 0], [0, 0], 1.0, "acceleration", [1.0])


@pytest.mark.parametrize("mode", ["component", "manifold"])
def test_quaternions_within_unit_tolerance_are_learned_as_unit_quaternions(mode):
    """unit_tolerance=1e-3 accepted norms 1 +- 5e-4, and then the artefact refused its own
    q0 (tolerance 1e-6): the parameter did nothing above 1e-6. Now the samples are normalised."""
    norms = 1 + np.random.default_rng(3600).uniform(-5e-4, 5e-4, (T.size, 1))
    dmp = learn_quaternion_dmp(T, QUATS * norms, mode=mode, n_basis=20, unit_tolerance=1e-3)
    exact = learn_quaternion_dmp(T, QUATS, mode=mode, n_basis=20)
    np.testing.assert_allclose(dmp.q0, QUATS[0], rtol=0, atol=1e-15)
    np.testing.assert_allclose(dmp.goal, QUATS[-1], rtol=0, atol=1e-15)
    assert np.abs(dmp.weights - exact.weights).max() < 1e-9 * np.abs(exact.weights).max()
    with raises("quaternion demonstration are not unit: | |q| - 1 | = 0.0005"):
        learn_quaternion_dmp(T, QUATS * norms, mode=mode, n_basis=20)


@pytest.mark.parametrize(
    "value, shown",
    [
        (-1e-9, "-1e-09"),
        (-1.0, "-1.0"),
        (np.nan, "nan"),
        (np.inf, "inf"),
        ("0", "'0'"),
        (True, "True"),
        (None, "None"),
    ],
)
def test_learn_dmp_refuses_a_min_displacement_that_is_not_a_number_at_least_0(value, shown):
    # a negative bound let eq. 5 divide by g - x0 = 0: start equal to goal in a DOF ended
    # in "weights contains NaN or inf" instead of a named error
    x = X.copy()
    x[-1, 1] = x[0, 1]  # start equals goal in DOF 1
    with raises(f"min_displacement must be a finite number >= 0, got {shown}"):
        learn_dmp(T, x, n_basis=20, formulation="old", min_displacement=value)
    with raises(f"min_displacement must be a finite number >= 0, got {shown}"):
        learn_dmp(T, X, n_basis=20, min_displacement=value)  # whatever the formulation
    with raises("start equals goal in DOF [1]"):  # 0 still refuses exactly 0
        learn_dmp(T, x, n_basis=20, formulation="old", min_displacement=0.0)


def test_new_goals_starts_and_artefact_numbers_are_named_with_their_value(p, qp):
    """Session 35: these said "weights contains NaN or inf", float()'s own error or nothing."""
    from repertoire.planning.dmp_chain import directional_primitive
    from repertoire.systems.dmp import TransformationSystem

    with raises("goal contains NaN or inf: [ 1. nan]"):
        p.with_goal([1.0, np.nan])
    with raises("goal must be 2 numbers, got 'ab'"):  # was float()'s ValueError
        p.with_goal("ab")
    with raises("x0 must have 2 entries, got 3: [0, 0, 0]"):  # was accepted, failed later
        p.with_goal(p.goal, x0=[0, 0, 0])
    with raises("start contains NaN or inf: [ 0. nan]"):  # was "weights contains NaN or inf"
        directional_primitive(p, [0.0, np.nan], [1.0, 1.0])
    with raises("goal must have 2 entries, got 3: [1, 1, 1]"):
        directional_primitive(p, [0.0, 0.0], [1, 1, 1])
    weights = p.weights.copy()
    weights[1, 3] = np.nan
    with raises(f"weights contains NaN or inf: weights[1, 3] = nan (1 of {weights.size} not"):
        DmpParameters(weights, p.centres, p.widths, p.K, p.D, p.alpha, p.tau, p.x0, p.goal)
    with raises("goal contains NaN or inf (first at sample 0: [ 1. nan  0.  0.])"):
        qp.rollout(goal=[1.0, np.nan, 0.0, 0.0])
    ts = TransformationSystem(p)
    with raises("x0 contains NaN or inf: [nan  0.]"):  # the systems named no value
        ts.set_start(ts.CreateDefaultContext(), [np.nan, 0.0])
    with raises("x0 must have 2 entries, got 3: [0, 0, 0]"):
        ts.set_start(ts.CreateDefaultContext(), [0, 0, 0])


def test_dmp_system_options_are_checked_and_named(p):
    """Session 35: gamma "1" was taken as 1.0 (float() of a string), a name 3 was Drake's
    TypeError, and obstacle_avoidance="no" switched the coupling on."""
    from pydrake.systems.framework import DiagramBuilder
    from repertoire.planning.dmp_obstacle import check_gains
    from repertoire.systems.dmp import ObstacleCoupling
    from repertoire.systems.dmp_compose import DmpSystem, add_dmp

    with raises("gamma and beta must be finite and >= 0, got '1', 2.0"):
        DmpSystem(p, obstacle_avoidance=True, gamma="1", beta=2.0)
    with raises("gamma and beta must be finite and >= 0, got True, 1.0"):
        ObstacleCoupling(True, 1.0, n_dims=2)
    assert check_gains(500, np.float64(2.0)) == [500.0, 2.0]
    with raises("name must be a non-empty string, got 3"):
        add_dmp(DiagramBuilder(), p, name=3)
    with raises("obstacle_avoidance must be True or False, got 'no'"):
        DmpSystem(p, obstacle_avoidance="no")


@pytest.mark.parametrize("time_step", [1e-3, None])
def test_a_component_orientation_start_must_be_unit(grasp_demo, time_step):
    """Session 35: the component (R^4) part took any 4 numbers as its start and ran off the
    sphere; the on-manifold part refused them."""
    from repertoire.planning.dmp_learn import learn_task_space_dmp
    from repertoire.systems.dmp_compose import DmpSystem

    d = grasp_demo
    dmp = learn_task_space_dmp(
        d.t, d.position, d.orientation, d.fingers, orientation_mode="component", n_basis=10
    )
    system = DmpSystem(dmp, time_step=time_step)
    ctx = system.CreateDefaultContext()
    with raises("start orientation are not unit: | |q| - 1 | = 0.118 at sample 0 (norm 1.11803"):
        system.set_start(ctx, orientation=[1.0, 0.0, 0.0, 0.5])
    system.set_start(ctx, orientation=-d.orientation[0])  # either sign of a unit quaternion


def test_a_sequencer_start_needs_a_unit_quaternion_block(p):
    """Session 35: x_start's quaternion block was any 4 numbers (the chain ran off S^3)."""
    from repertoire.systems.dmp_sequencer import DmpSequencer

    q = learn_quaternion_dmp(T, QUATS, mode="component", n_basis=20).component_parameters()
    seg = DmpParameters(
        np.vstack([p.weights, q.weights]), p.centres, p.widths, 156.25, 25.0, p.alpha, p.tau,
        np.r_[p.x0, q.x0], np.r_[p.goal, q.goal],
    )  # fmt: skip
    bad = np.r_[p.x0, 2.0 * q.x0]
    message = "x_start's quaternion block are not unit: | |q| - 1 | = 1 at sample 0 (norm 2)"
    with raises(message):
        DmpSequencer([seg], [0.0], x_start=bad, quaternion_at=2)
    seq = DmpSequencer([seg], [0.0], x_start=np.r_[p.x0, -q.x0], quaternion_at=2)
    with raises(message):
        seq.set_start(seq.CreateDefaultContext(), bad)
    DmpSequencer([seg], [0.0], x_start=bad)  # no quaternion block: any numbers
