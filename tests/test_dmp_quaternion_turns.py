"""Quaternion DMPs that turn past 180 deg: both modes, NumPy and Drake, the learned way round."""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource
from repertoire.planning.dmp import TaskSpaceDmp
from repertoire.planning.dmp_demos import slerp_minimum_jerk
from repertoire.planning.dmp_learn import learn_dmp, learn_quaternion_dmp
from repertoire.planning.dmp_math import (
    minimum_jerk,
)
from repertoire.planning.dmp_quaternion import (
    lift_quaternion_goal,
    manifold_growth_exponent,
    quat_error,
    quat_exp,
    quat_log_error,
    quat_multiply,
)
from repertoire.systems.dmp_compose import add_dmp
from repertoire.systems.dmp_sequencer import DmpSequencer

from repertoire.errors import RepertoireError

N, T = 1000, 1.0
TIMES = np.linspace(0.0, T, N)


def yaw_demo(deg: float) -> np.ndarray:
    """Rest-to-rest (minimum-jerk) rotation about z from identity by ``deg`` degrees."""
    s, _, _ = minimum_jerk(np.zeros(1), np.ones(1), T, TIMES)
    return quat_exp(s * np.array([0.0, 0.0, np.deg2rad(deg) / 2.0]))


def max_angle(q_a: np.ndarray, q_b: np.ndarray) -> float:
    """Largest rotation angle between two quaternion sequences (sign-blind)."""
    return float(np.linalg.norm(quat_error(q_a, q_b), axis=-1).max())


def test_quat_log_error_is_the_unflipped_rotation_vector():
    identity = np.array([1.0, 0.0, 0.0, 0.0])
    for deg in (10.0, 170.0, 190.0, 270.0, 350.0):
        g = quat_exp(np.array([0.0, 0.0, np.deg2rad(deg) / 2]))
        np.testing.assert_allclose(
            quat_log_error(g, identity), [0, 0, np.deg2rad(deg)], rtol=0, atol=1e-12
        )
        # the other sign is the same orientation reached the other way round
        np.testing.assert_allclose(
            quat_log_error(-g, identity), [0, 0, np.deg2rad(deg) - 2 * np.pi], atol=1e-12
        )
        # the shortest arc differs from it exactly past 180 deg
        short = np.deg2rad(deg) - (2 * np.pi if deg > 180 else 0.0)
        np.testing.assert_allclose(quat_error(g, identity), [0, 0, short], atol=1e-12)


def test_lift_quaternion_goal_carries_the_learned_rotation_to_the_start():
    q0 = np.array([1.0, 0.0, 0.0, 0.0])
    g = quat_exp(np.array([0.0, 0.0, np.deg2rad(200) / 2]))  # 200 deg: g . q0 < 0
    assert g @ q0 < 0
    np.testing.assert_array_equal(lift_quaternion_goal(g, q0, g, q0), g)
    np.testing.assert_array_equal(lift_quaternion_goal(-g, q0, g, q0), g)
    np.testing.assert_array_equal(lift_quaternion_goal(g, -q0, g, q0), -g)
    # a goal 10 deg past the learned one keeps the learned goal's sign
    g2 = quat_exp(np.array([0.0, 0.0, np.deg2rad(210) / 2]))
    np.testing.assert_array_equal(lift_quaternion_goal(-g2, q0, g, q0), g2)


@pytest.mark.parametrize("mode", ["component", "manifold"])
@pytest.mark.parametrize("deg", [170.0, 200.0, 270.0])
def test_large_rotations_are_reproduced_in_both_modes(mode, deg):
    q = yaw_demo(deg)
    p = learn_quaternion_dmp(TIMES, q, mode=mode, n_basis=50)
    assert (p.goal @ p.q0 < 0) == (deg > 180)  # learning kept the signs continuous
    _, Q, _ = p.rollout(dt=TIMES[1], n_steps=N - 1)
    assert max_angle(q, Q) < 5e-5  # was 3.14 rad (component) / 3e-2 rad (manifold, 270)
    yaw = np.unwrap(2 * np.arctan2(Q[:, 3], Q[:, 0]))
    assert abs(np.rad2deg(yaw[-1]) - deg) < 1e-3  # turned the demonstrated way round
    # the goal's sign does not matter: the learned way round is taken
    _, Q_neg, _ = p.rollout(goal=-p.goal, dt=TIMES[1], n_steps=N - 1)
    np.testing.assert_allclose(Q_neg, Q, rtol=0, atol=1e-14)


def test_component_start_of_the_other_sign_is_the_same_movement():
    p = learn_quaternion_dmp(TIMES, yaw_demo(200.0), mode="component", n_basis=50)
    _, Q, raw = p.rollout(dt=TIMES[1], n_steps=N - 1)
    _, Q_neg, raw_neg = p.rollout(q0=-p.q0, dt=TIMES[1], n_steps=N - 1)
    np.testing.assert_allclose(Q_neg, -Q, rtol=0, atol=1e-14)
    np.testing.assert_allclose(raw_neg, -raw, rtol=0, atol=1e-14)


def test_manifold_detour_through_the_goal_antipode_is_reproduced():
    # start ~180 deg from the goal with a detour: the shortest-arc error jumped here
    rng = np.random.default_rng(26)
    q0 = rng.normal(size=4)
    q0 /= np.linalg.norm(q0)
    q1 = quat_multiply(quat_exp(np.array([0, 0, 1.0]) * (np.pi / 2 - 1e-3)), q0)
    bump = np.sin(np.pi * TIMES / T)[:, None] ** 2 * np.array([0.029, 0.081, -0.198])
    q = quat_multiply(quat_exp(bump), slerp_minimum_jerk(q0, q1, TIMES))
    assert np.abs(q @ q1).min() < 1e-3  # passes (within 0.1 deg) 180 deg from the goal
    p = learn_quaternion_dmp(TIMES, q, mode="manifold", n_basis=30)
    _, Q, _ = p.rollout(dt=TIMES[1], n_steps=N - 1)
    assert max_angle(q, Q) < 2e-4  # was 3.14 rad


def test_manifold_mode_refuses_a_full_turn():
    match = r"from demonstration sample \d+ to the goal \(last sample\) is 359\.9\d+ deg"
    with pytest.raises(RepertoireError, match=match):
        learn_quaternion_dmp(TIMES, yaw_demo(370.0), mode="manifold", n_basis=20)
    # the component mode has no such limit
    p = learn_quaternion_dmp(TIMES, yaw_demo(370.0), mode="component", n_basis=50)
    _, Q, _ = p.rollout(dt=TIMES[1], n_steps=N - 1)
    assert max_angle(yaw_demo(370.0), Q) < 5e-5
    # a rollout whose goal sits a full turn from the start that way is refused too
    p = learn_quaternion_dmp(TIMES, yaw_demo(200.0), mode="manifold", n_basis=20)
    far = quat_multiply(p.goal, quat_exp(np.array([0, 0, np.deg2rad(159.99) / 2])))
    with pytest.raises(RepertoireError, match=r"from the start to the goal is 359\.99\d+ deg"):
        p.rollout(goal=far)


def _task_space(deg: float, mode: str, position_basis: int = 20) -> tuple[TaskSpaceDmp, np.ndarray]:
    q = yaw_demo(deg)
    position = np.c_[np.linspace(0.0, 0.1, N), np.zeros(N), np.zeros(N)]
    pos = learn_dmp(TIMES, position, n_basis=position_basis)
    ori = learn_quaternion_dmp(TIMES, q, mode=mode, n_basis=50)
    return TaskSpaceDmp(pos, ori), q


@pytest.mark.parametrize("fused", [False, True])
@pytest.mark.parametrize("mode", ["component", "manifold"])
def test_drake_dmp_system_turns_200_deg_the_demonstrated_way(mode, fused):
    # with the orientation's 50 basis functions the vector parts fuse into one system
    dmp, q = _task_space(200.0, mode, position_basis=50 if fused else 20)
    goal_q = -dmp.orientation.goal  # either sign: the learned way round is taken
    builder = DiagramBuilder()
    sys = add_dmp(builder, dmp, name="turn")
    for port, val in (("goal_position", dmp.position.goal), ("goal_orientation", goal_q)):
        src = builder.AddSystem(ConstantVectorSource(np.asarray(val, float)))
        builder.Connect(src.get_output_port(), sys.GetInputPort(port))
    sim = Simulator(builder.Build())
    if mode == "component":  # (a manifold orientation is its own system either way)
        assert (sys._fused is not None) == fused
    ctx = sys.GetMyMutableContextFromRoot(sim.get_mutable_context())
    sys.set_start(ctx, position=dmp.position.x0, orientation=dmp.orientation.q0)
    _, Q_np, _ = dmp.orientation.rollout(dt=1e-3, n_steps=3000)
    for k in (250, 500, 1000, 3000):
        sim.AdvanceTo(k * 1e-3)
        q_sys = sys.GetOutputPort("orientation").Eval(ctx)
        assert max_angle(q_sys, Q_np[k]) < 1e-11  # the NumPy rollout, to rounding
    # which follows the demonstration (its grid is 1/999 s, not 1 ms; wrong way: 3 rad)
    assert max_angle(Q_np[:1000], q[:1000]) < 1e-2
    assert max_angle(q_sys, q[-1]) < 1e-5  # settled at the demonstrated goal


def test_sequencer_quaternion_block_turns_200_deg_the_demonstrated_way():
    dmp, q = _task_space(200.0, "component")
    comp = dmp.orientation.component_parameters()
    _, Q_np, _ = dmp.orientation.rollout(dt=1e-3, n_steps=3000)
    for goal in (comp.goal, -comp.goal):  # the start's hemisphere used to turn it back
        seq = DmpSequencer([comp], [0.0], goals=[goal], time_step=1e-3, quaternion_at=0)
        sim = Simulator(seq)
        ctx = sim.get_mutable_context()
        for k in (500, 999, 3000):
            sim.AdvanceTo(k * 1e-3)
            q_seq = seq.GetOutputPort("orientation").Eval(ctx)
            assert max_angle(q_seq, Q_np[k]) < 1e-11  # the NumPy rollout, to rounding
        assert max_angle(q_seq, q[-1]) < 1e-5


def _detour_demo() -> np.ndarray:
    """A curved rest-to-rest turn from identity: 70 deg about y (late) after 40 deg about x."""
    s, _, _ = minimum_jerk(np.zeros(1), np.ones(1), T, TIMES)
    about_x = quat_exp(s * np.array([np.deg2rad(40.0) / 2, 0.0, 0.0]))
    return quat_multiply(quat_exp(s**2 * np.array([0.0, np.deg2rad(70.0) / 2, 0.0])), about_x)


@pytest.mark.parametrize("time_step", [1e-3, None])
def test_sequencer_start_and_hand_off_of_the_other_sign_are_the_same_movement(time_step):
    # Segment 1 turns the demonstration; segment 2 (learned from the same movement seen from
    # segment 1's goal, its samples stored with the other sign) takes over at 0.6 s. Starting
    # at -q0, or handing over to a segment whose learned start is -q, must not change the
    # orientations: the R^4 state runs on each segment's learned side (it used to leave the
    # demonstrated path by about 1 rad).
    q = yaw_demo(80.0) if time_step is None else _detour_demo()
    first = learn_quaternion_dmp(TIMES, q, mode="component", n_basis=30)
    q2 = quat_multiply(q, first.goal)  # the same turn from first.goal
    seconds = [
        learn_quaternion_dmp(TIMES, sign * q2, mode="component", n_basis=30).component_parameters()
        for sign in (1.0, -1.0)
    ]
    comp = first.component_parameters()
    runs = []
    for x_start, second in ((comp.x0, seconds[0]), (-comp.x0, seconds[1])):
        seq = DmpSequencer(
            [comp, second], [0.0, 0.6], goals=[comp.goal, second.goal], x_start=x_start,
            time_step=time_step, quaternion_at=0,
        )  # fmt: skip
        sim = Simulator(seq)
        out = []
        for k in (300, 600, 900, 1500, 3000):
            sim.AdvanceTo(k * 1e-3)
            out.append(seq.GetOutputPort("orientation").Eval(sim.get_context()).copy())
        runs.append(np.array(out))
    tol = 1e-11 if time_step else 1e-6  # continuous: the integrator's error control
    assert max_angle(runs[0], runs[1]) < tol
    # the first segment follows its NumPy rollout, the chain ends at the second's goal
    _, Q_np, _ = first.rollout(dt=1e-3, n_steps=300)
    assert max_angle(runs[0][0], Q_np[300]) < max(tol, 1e-11)
    assert max_angle(runs[1][-1], seconds[1].goal) < 1e-4


@pytest.mark.parametrize("fused", [False, True])
def test_component_dmp_system_started_at_the_other_sign_is_the_same_movement(fused):
    dmp, _ = _task_space(80.0, "component", position_basis=50 if fused else 20)
    dmp.orientation = learn_quaternion_dmp(TIMES, _detour_demo(), mode="component", n_basis=50)
    _, Q_np, _ = dmp.orientation.rollout(dt=1e-3, n_steps=1500)
    builder = DiagramBuilder()
    sys = add_dmp(builder, dmp, name="turn")
    for port, val in (
        ("goal_position", dmp.position.goal),
        ("goal_orientation", dmp.orientation.goal),
    ):
        src = builder.AddSystem(ConstantVectorSource(np.asarray(val, float)))
        builder.Connect(src.get_output_port(), sys.GetInputPort(port))
    sim = Simulator(builder.Build())
    assert (sys._fused is not None) == fused
    ctx = sys.GetMyMutableContextFromRoot(sim.get_mutable_context())
    sys.set_start(ctx, position=dmp.position.x0, orientation=-dmp.orientation.q0)
    for k in (250, 500, 1000, 1500):
        sim.AdvanceTo(k * 1e-3)
        q_sys = sys.GetOutputPort("orientation").Eval(ctx)
        assert max_angle(q_sys, Q_np[k]) < 1e-11  # it was up to 0.32 rad off


@pytest.mark.parametrize("fused", [False, True])
def test_component_dmp_system_lifts_the_goal_from_its_start(fused):
    # Learned: a 90 deg yaw from identity. Started 120 deg about x away with the goal
    # g = D (s - q0) (D = learned rotation), g . (D s) = 0.5 but g . g_learned = -0.5: the
    # learned rotation carried to the start says +g; the sign nearest the learned goal (what
    # QuaternionGoalSign took, ignoring the start) said -g, the turn the other way round.
    dmp, _ = _task_space(90.0, "component", position_basis=50 if fused else 20)
    ori = dmp.orientation
    s = quat_exp(np.array([np.deg2rad(120.0) / 2, 0.0, 0.0]))
    g = quat_multiply(ori.goal, s - ori.q0)
    assert g @ quat_multiply(ori.goal, s) > 0.4 and g @ ori.goal < -0.4
    _, Q_np, _ = ori.rollout(goal=g, q0=s, dt=1e-3, n_steps=2000)
    builder = DiagramBuilder()
    sys = add_dmp(builder, dmp, name="turn")
    for port, val in (("goal_position", dmp.position.goal), ("goal_orientation", -g)):
        src = builder.AddSystem(ConstantVectorSource(np.asarray(val, float)))
        builder.Connect(src.get_output_port(), sys.GetInputPort(port))
    sim = Simulator(builder.Build())
    assert (sys._fused is not None) == fused
    ctx = sys.GetMyMutableContextFromRoot(sim.get_mutable_context())
    sys.set_start(ctx, position=dmp.position.x0, orientation=s)
    for k in (250, 500, 1000, 2000):
        sim.AdvanceTo(k * 1e-3)
        q_sys = sys.GetOutputPort("orientation").Eval(ctx)
        assert max_angle(q_sys, Q_np[k]) < 1e-11


def test_sequencer_refuses_a_non_unit_quaternion_goal_input():
    dmp, _ = _task_space(200.0, "component")
    comp = dmp.orientation.component_parameters()
    seq = DmpSequencer([comp], [0.0], goals=[comp.goal], time_step=1e-3, quaternion_at=0)
    ctx = seq.CreateDefaultContext()
    seq.GetInputPort("goal_0").FixValue(ctx, -comp.goal)  # either sign is fine
    seq.GetOutputPort("acceleration").Eval(ctx)
    for bad, norm in ((0.5 * comp.goal, "0.5"), (np.zeros(4), "0.0")):  # ran before
        seq.GetInputPort("goal_0").FixValue(ctx, bad)
        with pytest.raises(RepertoireError, match=f"not a unit quaternion: \\|g\\| = {norm}"):
            seq.GetOutputPort("acceleration").Eval(ctx)


def test_manifold_growth_exponent_closed_form():
    # A demonstration held at a constant turn psi from the goal for tau: E = lambda tau with
    # lambda tau = (-D + sqrt(D^2 + 4 K kappa)) / 2, kappa = -(psi/2) cot(psi/2); at 270 deg
    # cot(135 deg) = -1, so kappa = 3 pi / 4; below 180 deg kappa = 0 and E = 0.
    K, D = 156.25, 25.0
    goal = np.array([1.0, 0.0, 0.0, 0.0])
    times = np.linspace(0.0, 2.0, 7)
    for psi, kappa in ((1.5 * np.pi, 0.75 * np.pi), (np.deg2rad(350.0), None), (np.pi / 2, 0.0)):
        q = np.tile([np.cos(psi / 2), 0.0, 0.0, np.sin(psi / 2)], (7, 1))
        if kappa is None:
            kappa = -(psi / 2) / np.tan(psi / 2)
        expected = (-D + np.sqrt(D * D + 4 * K * kappa)) / 2
        assert manifold_growth_exponent(times, q, goal, K, D) == pytest.approx(expected, rel=1e-12)
    assert manifold_growth_exponent(times, np.tile(goal, (7, 1)), goal, K, D) == 0.0


@pytest.mark.parametrize("seed", [101, 202, 303])
def test_manifold_learning_refuses_a_near_full_turn_whose_detours_it_would_amplify(seed):
    """Before: learned, and reproduced up to 180 deg off (max 3.1 rad at 355 deg)."""
    rng = np.random.default_rng(seed)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    s = 10 * (TIMES / T) ** 3 - 15 * (TIMES / T) ** 4 + 6 * (TIMES / T) ** 5
    q0 = quat_exp(rng.normal(size=3) * 0.5)
    bump = np.sin(np.pi * s)[:, None] ** 2 * rng.normal(size=3) * 0.1

    def demo(deg: float) -> np.ndarray:
        turn = quat_exp(axis[None] * np.deg2rad(deg) / 2 * s[:, None])
        return quat_multiply(quat_exp(bump), quat_multiply(turn, q0))

    with pytest.raises(RepertoireError, match="unstable along this demonstration"):
        learn_quaternion_dmp(TIMES, demo(355.0), mode="manifold", n_basis=30)
    # the component form reproduces it; a 290 deg turn with the same detour is accepted
    p = learn_quaternion_dmp(TIMES, demo(355.0), mode="component", n_basis=30)
    _, Q, _ = p.rollout(dt=TIMES[1], n_steps=N - 1)
    assert max_angle(demo(355.0), Q) < 2e-3
    p = learn_quaternion_dmp(TIMES, demo(290.0), mode="manifold", n_basis=30)
    _, Q, _ = p.rollout(dt=TIMES[1], n_steps=N - 1)
    assert max_angle(demo(290.0), Q) < 2e-3
