"""Benchmark: the forcing fit's ridge, 0, ``"gcv"`` and ``"auto"`` (the default), same run.

Sparse noisy case: a unit minimum-jerk move over 2 s at 101 random time stamps (ends kept)
with 2 mm Gaussian noise, 50 (and 20) basis functions, default derivative estimation, and
the move's exact derivatives given (the forcing fit judged alone). Error: max |rollout - true
move| on a 1 ms grid over the amplitude. Clean cases: the change in the reproduced
trajectories of the arm library's demonstrations (component and manifold quaternions, 30
and 50 basis functions; ``"auto"`` must give ridge 0's bit for bit there). Timing: median fit time of a 5001-sample 3-DOF demonstration.

Run: ``OPENBLAS_NUM_THREADS=1 .venv/bin/python tests/benchmarks/bench_dmp_ridge.py --seeds 0 40``
(on a shared machine multi-threaded BLAS oversubscribes the cores and the fit times mean
nothing: 210 ms instead of 12.5 ms here).
"""

import argparse
import statistics
import time
import warnings

import numpy as np


def error(params, duration: float = 2.0) -> float:
    from repertoire.planning.dmp_math import minimum_jerk

    r = params.rollout(dt=1e-3)
    return float(np.abs(r.x - minimum_jerk(np.zeros(1), np.ones(1), duration, r.t)[0]).max())


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, nargs=2, default=[0, 40], metavar=("FIRST", "END"))
    parser.add_argument("--repeats", type=int, default=9)
    args = parser.parse_args()

    from repertoire.planning.arm_library import synthetic_demonstrations
    from repertoire.planning.dmp_demos import noisy_sparse_minimum_jerk
    from repertoire.planning.dmp_learn import learn_dmp, learn_task_space_dmp
    from repertoire.planning.dmp_math import minimum_jerk

    warnings.simplefilter("ignore")  # ridge=0 warns on every sparse demo here
    seeds = range(*args.seeds)
    for n_basis in (50, 20):
        for label, exact in (("estimated derivatives", False), ("exact derivatives", True)):
            errors = {0.0: [], "gcv": [], "auto": []}
            for seed in seeds:
                t, x, xd, xdd = noisy_sparse_minimum_jerk(seed)
                known = {"xd": xd, "xdd": xdd} if exact else {}
                for ridge, out in errors.items():
                    out.append(error(learn_dmp(t, x, n_basis=n_basis, ridge=ridge, **known)))
            print(f"sparse noisy, {n_basis} basis functions, {label}, seeds {args.seeds}:")
            for ridge, e in errors.items():
                e = 100.0 * np.array(e)
                q = np.percentile(e, [50, 90, 100])
                print(
                    f"  ridge={ridge!s:4}: median {q[0]:.2f} %, 90th {q[1]:.2f} %, max {q[2]:.4g} %"
                )

    worst = {"position [m]": 0.0, "quaternion": 0.0, "fingers": 0.0}
    same = dict.fromkeys(worst, True)
    for d in synthetic_demonstrations().values():
        for mode in ("component", "manifold"):
            for n_basis in (30, 50):
                runs = [
                    learn_task_space_dmp(
                        d.t, d.position, d.orientation, d.fingers,
                        orientation_mode=mode, n_basis=n_basis, ridge=ridge,
                    )
                    for ridge in (0.0, "gcv", "auto")
                ]  # fmt: skip
                parts = [
                    (r.position.rollout().x, r.orientation.rollout()[1], r.fingers.rollout().x)
                    for r in runs
                ]
                for key, a, b in zip(worst, *parts[:2], strict=True):
                    worst[key] = max(worst[key], float(np.abs(a - b).max()))
                for key, a, b in zip(same, parts[0], parts[2], strict=True):
                    same[key] = same[key] and bool(np.array_equal(a, b))
    print("arm library demonstrations, max change 0 -> gcv:", worst)
    print("arm library demonstrations, auto (the default) identical to 0:", same)

    t = np.linspace(0.0, 2.0, 5001)
    x = minimum_jerk(np.zeros(3), np.array([1.0, -0.5, 0.2]), 2.0, t)[0]
    learn_dmp(t, x)  # warm up
    times = {0.0: [], "gcv": [], "auto": []}
    for _ in range(args.repeats):  # interleaved: the machine is shared
        for ridge, out in times.items():
            t0 = time.perf_counter()
            learn_dmp(t, x, ridge=ridge)
            out.append(time.perf_counter() - t0)
    for ridge, ts in times.items():
        print(
            f"fit time, 5001 samples x 3 DOF, ridge={ridge}: {1e3 * statistics.median(ts):.1f} ms"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
