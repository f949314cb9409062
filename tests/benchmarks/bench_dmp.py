"""Benchmark: repertoire DMPs against movement_primitives 0.9.1, same demo, same machine.

Setting (issue 3): 7 DOF, a 1000-sample minimum-jerk demonstration at 1 ms, 50 basis
functions, 1000 rollout steps at dt = 1 ms. Timings are medians over repetitions run
interleaved (the machine is shared), ratios are ours / theirs.

Noisy case (issue 7): 6 DOF, 800 samples over 2 s, a seeded random smooth (quintic spline,
at rest at both ends) trajectory the tests never use, plus 1 mm Gaussian noise; both
libraries learn with default settings from the noisy samples; errors are against the clean
trajectory; the peak-acceleration ratio is the rollout's peak (second differences) over the
clean demo's.

Run: ``.venv/bin/python tests/benchmarks/bench_dmp.py``.
"""

import argparse
import statistics
import time

import numpy as np

N_DOF, N_SAMPLES, N_BASIS, DT = 7, 1000, 50, 1e-3


def median_time(fn, repeats: int) -> tuple[float, object]:
    times, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=15)
    args = parser.parse_args()

    from movement_primitives.dmp import DMP
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.primitives import ConstantVectorSource
    from repertoire.planning.dmp_demos import slerp_minimum_jerk
    from repertoire.planning.dmp_learn import learn_dmp, learn_quaternion_dmp
    from repertoire.planning.dmp_math import (
        minimum_jerk,
    )
    from repertoire.planning.dmp_quaternion import (
        quat_exp,
    )
    from repertoire.systems.dmp import CanonicalSystem, ManifoldQuaternionSystem
    from repertoire.systems.dmp_discrete import DiscreteDmpSystem

    rng = np.random.default_rng(0)
    T = np.arange(N_SAMPLES) * DT
    duration = T[-1]
    x0, g = rng.uniform(-1, 1, N_DOF), rng.uniform(-1, 1, N_DOF)
    Y, _, _ = minimum_jerk(x0, g, duration, T)
    n_steps = N_SAMPLES - 1  # 999 steps cover the demo; 1000 steps run 1 ms past it
    rows = []

    # ---- learning
    def mp_learn():
        d = DMP(n_dims=N_DOF, execution_time=duration, dt=DT, n_weights_per_dim=N_BASIS, int_dt=DT)
        d.imitate(T, Y)
        d.configure(start_y=Y[0], goal_y=Y[-1])
        return d

    def our_learn():
        return learn_dmp(T, Y, n_basis=N_BASIS)

    mp_learn(), our_learn()  # warm-up
    t_mp, t_our = [], []
    for _ in range(args.repeats):
        t_mp.append(median_time(mp_learn, 1)[0])
        t_our.append(median_time(our_learn, 1)[0])
    mp_dmp, ours = mp_learn(), our_learn()
    learn_mp, learn_our = statistics.median(t_mp), statistics.median(t_our)
    rows.append(("learn (ms)", learn_mp * 1e3, learn_our * 1e3, learn_our / learn_mp, "<= 1"))

    # ---- rollouts (1000 steps at 1 ms)
    def mp_roll():
        return mp_dmp.open_loop(run_t=1000 * DT, step_function="euler-cython")

    def our_roll():
        return ours.rollout(dt=DT, n_steps=1000)

    mp_roll(), our_roll()
    r_mp, r_our = [], []
    for _ in range(args.repeats):
        r_mp.append(median_time(mp_roll, 1)[0])
        r_our.append(median_time(our_roll, 1)[0])
    roll_mp, roll_our = statistics.median(r_mp), statistics.median(r_our)
    rows.append(("NumPy rollout (ms)", roll_mp * 1e3, roll_our * 1e3, roll_our / roll_mp, "<= 1"))

    builder = DiagramBuilder()
    ds = builder.AddSystem(DiscreteDmpSystem(ours, time_step=DT))
    src = builder.AddSystem(ConstantVectorSource(ours.goal))
    builder.Connect(src.get_output_port(), ds.get_goal_input_port())
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    default = diagram.CreateDefaultContext()

    def drake_roll():
        context.SetTimeStateAndParametersFrom(default)
        simulator.Initialize()
        simulator.AdvanceTo(1000 * DT)
        return ds.get_position_output_port().Eval(ds.GetMyContextFromRoot(context))

    drake_roll()
    d_mp, d_our = [], []
    for _ in range(args.repeats):
        d_mp.append(median_time(mp_roll, 1)[0])
        d_our.append(median_time(drake_roll, 1)[0])
    sim_mp, sim_our = statistics.median(d_mp), statistics.median(d_our)
    rows.append(
        ("Drake Simulator 1 kHz (ms)", sim_mp * 1e3, sim_our * 1e3, sim_our / sim_mp, "<= 3")
    )

    # Continuous CanonicalSystem + TransformationSystem, RK2 fixed step 1 ms (information).
    from pydrake.systems.analysis import ResetIntegratorFromFlags
    from repertoire.systems.dmp import TransformationSystem

    b3 = DiagramBuilder()
    cs3 = b3.AddSystem(CanonicalSystem(ours.tau, ours.alpha))
    ts3 = b3.AddSystem(TransformationSystem(ours))
    s3 = b3.AddSystem(ConstantVectorSource(ours.goal))
    b3.Connect(cs3.get_phase_output_port(), ts3.get_phase_input_port())
    b3.Connect(s3.get_output_port(), ts3.get_goal_input_port())
    d3 = b3.Build()
    sim3 = Simulator(d3)
    ResetIntegratorFromFlags(sim3, "runge_kutta2", DT)
    sim3.get_mutable_integrator().set_fixed_step_mode(True)
    ctx3, default3 = sim3.get_mutable_context(), d3.CreateDefaultContext()

    def continuous_roll():
        ctx3.SetTimeStateAndParametersFrom(default3)
        sim3.Initialize()
        sim3.AdvanceTo(1000 * DT)

    continuous_roll()
    c_mp, c_our = [], []
    for _ in range(max(3, args.repeats // 3)):
        c_mp.append(median_time(mp_roll, 1)[0])
        c_our.append(median_time(continuous_roll, 1)[0])
    rows.append(
        (
            "Drake continuous RK2 1 kHz (ms, info)",
            statistics.median(c_mp) * 1e3,
            statistics.median(c_our) * 1e3,
            statistics.median(c_our) / statistics.median(c_mp),
            "info",
        )
    )

    # ---- accuracy
    _, Y_mp = mp_dmp.open_loop(run_t=duration, step_function="euler-cython")
    k = min(len(Y_mp), N_SAMPLES)
    err_mp = float(np.abs(Y_mp[:k] - Y[:k]).max())
    ro = ours.rollout(dt=DT, n_steps=n_steps)
    err_our = float(np.abs(ro.x - Y).max())
    rows.append(
        ("reproduction error (max abs)", err_mp, err_our, err_mp / err_our, ">= 10 (theirs/ours)")
    )
    goal_mp = float(np.abs(Y_mp[k - 1] - g).max())
    goal_our = float(np.abs(ro.x[-1] - g).max())
    rows.append(("final goal error at T", goal_mp, goal_our, float("nan"), "ours < 1e-5"))
    x_drake = drake_roll()
    r1000 = ours.rollout(dt=DT, n_steps=1000)
    rows.append(
        (
            "Drake vs NumPy rollout",
            float("nan"),
            float(np.abs(x_drake - r1000.x[-1]).max()),
            float("nan"),
            "rounding",
        )
    )

    # ---- quaternions
    tq = T
    q = slerp_minimum_jerk(
        quat_exp(np.array([0.1, -0.2, 0.3])), quat_exp(np.array([-0.6, 0.5, 0.4])), tq
    )
    man = learn_quaternion_dmp(tq, q, mode="manifold", n_basis=N_BASIS)
    comp = learn_quaternion_dmp(tq, q, mode="component", n_basis=N_BASIS)
    goal_q = quat_exp(np.array([0.4, 0.9, -0.3]))
    _, Qm, _ = man.rollout(goal=goal_q, dt=DT, n_steps=1000)
    _, Qc, raw = comp.rollout(
        goal=goal_q if goal_q @ comp.q0 >= 0 else -goal_q, dt=DT, n_steps=1000
    )
    norm_m = float(np.abs(np.linalg.norm(Qm, axis=1) - 1).max())
    norm_raw = float(np.abs(np.linalg.norm(raw, axis=1) - 1).max())
    b2 = DiagramBuilder()
    cs = b2.AddSystem(CanonicalSystem(man.tau, man.alpha))
    ms = b2.AddSystem(ManifoldQuaternionSystem(man, time_step=DT))
    s2 = b2.AddSystem(ConstantVectorSource(goal_q))
    b2.Connect(cs.get_phase_output_port(), ms.get_phase_input_port())
    b2.Connect(s2.get_output_port(), ms.get_goal_input_port())
    sim2 = Simulator(b2.Build())
    sim2.AdvanceTo(1000 * DT)
    qd = ms.get_orientation_output_port().Eval(ms.GetMyContextFromRoot(sim2.get_context()))
    rows.append(
        ("quat norm error, on-manifold (NumPy)", float("nan"), norm_m, float("nan"), "< 1e-12")
    )
    rows.append(
        (
            "quat norm error, on-manifold (Drake)",
            float("nan"),
            abs(float(np.linalg.norm(qd)) - 1),
            float("nan"),
            "< 1e-12",
        )
    )
    rows.append(
        (
            "quat |q|-1 before post-normalisation (paper)",
            float("nan"),
            norm_raw,
            float("nan"),
            "info",
        )
    )
    _, Qr, _ = man.rollout(dt=DT, n_steps=n_steps)
    rows.append(
        (
            "quat reproduction error (manifold)",
            float("nan"),
            float(np.abs(Qr - q).max()),
            float("nan"),
            "info",
        )
    )

    rows.extend(noisy_rows(args.repeats))

    print(
        f"repertoire DMP vs movement_primitives 0.9.1 ({N_DOF} DOF, {N_SAMPLES} samples, "
        f"{N_BASIS} basis functions, dt = 1 ms, medians of {args.repeats})"
    )
    print()
    print("| figure | movement_primitives | repertoire | ratio | target |")
    print("|---|---|---|---|---|")
    for name, a, b, r, target in rows:
        fa = "" if np.isnan(a) else f"{a:.4g}"
        fr = "" if np.isnan(r) else f"{r:.3g}"
        print(f"| {name} | {fa} | {b:.4g} | {fr} | {target} |")
    return 0


def noisy_rows(repeats: int, n_basis: int = 30) -> list[tuple]:
    """Noisy-demonstration figures (see the module docstring), ours against theirs."""
    from movement_primitives.dmp import DMP
    from repertoire.planning.dmp_learn import learn_dmp
    from scipy.interpolate import make_interp_spline

    n_dof, n, sigma = 6, 800, 1e-3
    rng = np.random.default_rng(20261123)
    T = np.linspace(0.0, 2.0, n)
    dt = float(T[1] - T[0])
    rest = [(1, np.zeros(n_dof)), (2, np.zeros(n_dof))]
    spline = make_interp_spline(
        np.linspace(0.0, 2.0, 7), rng.uniform(-0.5, 0.5, (7, n_dof)), k=5, bc_type=(rest, rest)
    )
    Y, Ydd = spline(T), spline.derivative(2)(T)
    Yn = Y + rng.normal(0.0, sigma, Y.shape)
    peak = float(np.abs(Ydd).max())

    def mp_learn():
        d = DMP(n_dims=n_dof, execution_time=T[-1], dt=dt, n_weights_per_dim=n_basis, int_dt=dt)
        d.imitate(T, Yn)
        d.configure(start_y=Yn[0], goal_y=Yn[-1])
        return d

    def our_learn():
        return learn_dmp(T, Yn, n_basis=n_basis)

    mp_learn(), our_learn()
    t_mp, t_our = [], []
    for _ in range(repeats):
        t_mp.append(median_time(mp_learn, 1)[0])
        t_our.append(median_time(our_learn, 1)[0])
    X_mp = mp_learn().open_loop(run_t=T[-1], step_function="euler-cython")[1][:n]
    X_our = our_learn().rollout(dt=dt, n_steps=n - 1).x

    def rms(X):
        return float(np.sqrt(np.mean((X - Y) ** 2)))

    def peak_ratio(X):
        return float(np.abs(np.diff(X, 2, axis=0)).max() / dt**2 / peak)

    def goal_error(X):
        return float(np.abs(X[-1] - Y[-1]).max())

    tag = f"noisy demo {n_dof} DOF, 1 mm, {n_basis} basis:"
    lm, lo = statistics.median(t_mp), statistics.median(t_our)
    return [
        (f"{tag} learn (ms)", lm * 1e3, lo * 1e3, lo / lm, "<= 1"),
        (f"{tag} reproduction RMS", rms(X_mp), rms(X_our), rms(X_mp) / rms(X_our), "> 1"),
        (f"{tag} goal error (max abs)", goal_error(X_mp), goal_error(X_our), float("nan"), "info"),
        (
            f"{tag} peak acc / demo's",
            peak_ratio(X_mp),
            peak_ratio(X_our),
            peak_ratio(X_mp) / peak_ratio(X_our),
            "> 1",
        ),
    ]


if __name__ == "__main__":
    raise SystemExit(main())
