"""Benchmark: the forcing fit's ridge, 0, ``"gcv"`` and ``"auto"`` (the default), same run.

Sparse noisy case: a unit minimum-jerk move over 2 s at 101 random time stamps (ends kept)
with 2 mm Gaussian noise, 50 (and 20) basis functions, default derivative estimation, and
the move's exact derivatives given (the forcing fit judged alone). Error: max |rollout - true
move| on a 1 ms grid over the amplitude. Clean cases: the change in the reproduced
trajectories of the arm library's demonstrations (component and manifold quaternions, 30
and 50 basis functions; ``"auto"`` must give ridge 0's bit for bit there). Timing: median
fit time of a 5001-sample 3-DOF demonstration.

``--part derivatives``: the default derivative estimate on non-uniform stamps before
(``--before``: the git revision whose planning/dmp_derivatives.py is loaded, by default the
sample-count local polynomial) and after (this tree), same run: the second derivative's
RMS error over the peak acceleration and the reproduction error with ridge 0 and "gcv" on
the sparse seed sets (``--derivative-seeds``), controls (clean uniform, clean random
stamps, 1001 random stamps with 1 mm noise, the arm library's demonstrations) and the
estimate's time on 5001 and 10001 random stamps (also alone: ``--part speed``, with the
time to learn from the noisy 10001-sample demonstration). ``--before a8292a6`` compares
with the kernel estimate whose half-width and ridge GCV alone chose (numpy sums).

Run: ``OPENBLAS_NUM_THREADS=1 .venv/bin/python tests/benchmarks/bench_dmp_ridge.py --seeds 0 40``
(on a shared machine multi-threaded BLAS oversubscribes the cores and the fit times mean
nothing: 210 ms instead of 12.5 ms here).
"""

import argparse
import atexit
import functools
import importlib.util
import pathlib
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
import warnings

import numpy as np


def error(params, duration: float = 2.0) -> float:
    from repertoire.planning.dmp_math import minimum_jerk

    r = params.rollout(dt=1e-3)
    return float(np.abs(r.x - minimum_jerk(np.zeros(1), np.ones(1), duration, r.t)[0]).max())


def random_stamps(seed: int, n: int, duration: float = 2.0) -> np.ndarray:
    """n sorted uniform random stamps over [0, duration], ends kept (as the sparse demo's)."""
    rng = np.random.default_rng(seed)
    return np.concatenate([[0.0], np.sort(rng.uniform(0.0, duration, n - 2)), [duration]])


def load_before(rev: str):
    """planning/dmp_derivatives.py at git revision ``rev``, imported as a module."""
    root = pathlib.Path(__file__).resolve().parents[2]
    source = subprocess.run(
        ["git", "-C", str(root), "show", f"{rev}:planning/dmp_derivatives.py"],
        check=True, capture_output=True, text=True,
    ).stdout  # fmt: skip
    # a real file (numba's cache of compiled revisions needs one), fresh for this run
    folder = tempfile.mkdtemp(prefix="bench_before_")
    atexit.register(shutil.rmtree, folder, True)
    path = pathlib.Path(folder, "dmp_derivatives_before.py")
    path.write_text(source)
    spec = importlib.util.spec_from_file_location("dmp_derivatives_before", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def _quantiles(values) -> str:
    q = np.percentile(100.0 * np.asarray(values), [50, 90, 100])
    return f"median {q[0]:.3g} %, 90th {q[1]:.3g} %, max {q[2]:.4g} %"


def derivatives_part(args) -> None:
    """The derivative estimate before -> after (see the module docstring)."""
    from repertoire.planning.arm_library import synthetic_demonstrations
    from repertoire.planning.dmp_demos import noisy_sparse_minimum_jerk
    from repertoire.planning.dmp_derivatives import estimate_derivatives
    from repertoire.planning.dmp_learn import learn_dmp
    from repertoire.planning.dmp_math import minimum_jerk

    estimators = {"before": load_before(args.before).estimate_derivatives}
    estimators["after"] = estimate_derivatives
    learn = functools.partial(learn_dmp, bridge_gaps=not args.samples_alone)
    seed_sets = [tuple(args.derivative_seeds[i : i + 2]) for i in range(0, 6, 2)]

    def scores(cases):
        """cases: (t, x, xd, xdd) -> per estimator lists of acc RMS, ridge-0, gcv errors."""
        out = {k: ([], [], []) for k in estimators}
        for t, x, _, xdd in cases:
            for k, estimate in estimators.items():
                d1, d2 = estimate(t, x)
                out[k][0].append(np.sqrt(np.mean((d2 - xdd) ** 2)) / np.abs(xdd).max())
                for ridge, errors in ((0.0, out[k][1]), ("gcv", out[k][2])):
                    errors.append(error(learn(t, x, xd=d1, xdd=d2, ridge=ridge)))
        return out

    def report(label, out):
        print(label)
        for k, (acc, r0, rg) in out.items():
            print(f"  {k:6} xdd RMS / peak: {_quantiles(acc)}")
            print(f"  {'':6} reproduction, ridge=0:   {_quantiles(r0)}")
            print(f"  {'':6} reproduction, ridge=gcv: {_quantiles(rg)}")

    for first, end in seed_sets:
        cases = [noisy_sparse_minimum_jerk(seed) for seed in range(first, end)]
        report(f"sparse noisy (101 random stamps, 2 mm), seeds {first}-{end - 1}:", scores(cases))

    def move(t, noise=0.0, seed=0):
        x, xd, xdd = minimum_jerk(np.zeros(1), np.ones(1), 2.0, t)
        return t, x + np.random.default_rng(seed).normal(scale=noise, size=x.shape), xd, xdd

    controls = {
        "clean uniform, 101 and 1001 stamps": [move(np.linspace(0, 2, n)) for n in (101, 1001)],
        "clean random stamps, 101 and 1001, seeds 0-9": [
            move(random_stamps(seed, n)) for n in (101, 1001) for seed in range(10)
        ],
        "1001 random stamps, 1 mm noise, seeds 0-9": [
            move(random_stamps(seed, 1001), 1e-3, seed) for seed in range(10)
        ],
    }
    for label, cases in controls.items():
        report(label + ":", scores(cases))
    change = 0.0
    for d in synthetic_demonstrations().values():
        for part in (d.position, d.orientation, d.fingers):
            if part.shape[1]:
                a = estimators["before"](d.t, part)[1]
                b = estimators["after"](d.t, part)[1]
                change = max(change, float(np.abs(a - b).max()))
    print(f"arm library demonstrations: max change of the second derivative {change:.3g}")

    speed_part(args, estimators)


def speed_part(args, estimators=None) -> None:
    """The derivative estimate's time before -> after on dense random stamps, same run.

    5001 and 10001 random stamps over 2 s (seed 1), a 3-DOF minimum-jerk move, clean and
    with 1 mm noise (seed 2): the median time of each estimator (interleaved repeats, after
    one warm-up call each, so numba's compilation is not timed), the largest difference of
    their second derivatives over its peak, and the time to learn a DMP from the noisy
    10001-sample demonstration (each estimate, then learn_dmp given it).
    """
    from repertoire.planning.dmp_derivatives import estimate_derivatives
    from repertoire.planning.dmp_learn import learn_dmp
    from repertoire.planning.dmp_math import minimum_jerk

    if estimators is None:
        estimators = {"before": load_before(args.before).estimate_derivatives}
        estimators["after"] = estimate_derivatives
    for n in (5001, 10001):
        t = random_stamps(1, n)
        clean = minimum_jerk(np.zeros(3), np.array([1.0, -0.5, 0.2]), 2.0, t)[0]
        noisy = clean + np.random.default_rng(2).normal(scale=1e-3, size=clean.shape)
        for label, x in (("clean", clean), ("1 mm noise", noisy)):
            times = {k: [] for k in estimators}
            out = {k: estimate(t, x)[1] for k, estimate in estimators.items()}  # warm up
            for _ in range(args.derivative_repeats):  # interleaved: the machine is shared
                for k, estimate in estimators.items():
                    t0 = time.perf_counter()
                    estimate(t, x)
                    times[k].append(time.perf_counter() - t0)
            a, b = out.values()
            change = float(np.abs(a - b).max() / np.abs(a).max())
            print(
                f"derivative estimate, {n} random stamps x 3 DOF, {label}: "
                + ", ".join(f"{k} {1e3 * statistics.median(v):.0f} ms" for k, v in times.items())
                + f"; max xdd change {change:.2g} of its peak"
            )
    times = {k: [] for k in estimators}
    for _ in range(args.derivative_repeats):
        for k, estimate in estimators.items():
            t0 = time.perf_counter()
            xd, xdd = estimate(t, noisy)  # what learn_dmp does with derivatives="auto"
            learn_dmp(t, noisy, xd=xd, xdd=xdd, bridge_gaps=not args.samples_alone)
            times[k].append(time.perf_counter() - t0)
    print(
        "learning a DMP from the noisy 10001-sample demonstration: "
        + ", ".join(f"{k} {1e3 * statistics.median(v):.0f} ms" for k, v in times.items())
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, nargs=2, default=[0, 40], metavar=("FIRST", "END"))
    parser.add_argument("--repeats", type=int, default=9)
    parser.add_argument("--part", choices=("ridge", "derivatives", "speed", "all"), default="all")
    parser.add_argument("--before", default="47266c4", help="git revision (derivatives part)")
    parser.add_argument(
        "--derivative-seeds", type=int, nargs=6, default=[0, 40, 2000, 2100, 5000, 5050]
    )
    parser.add_argument("--derivative-repeats", type=int, default=3)
    parser.add_argument(
        "--samples-alone",
        action="store_true",
        help="learn without bridging gaps in the stamps (bridge_gaps=False), as before session 29",
    )
    args = parser.parse_args()
    warnings.simplefilter("ignore")  # ridge=0 warns on every sparse demo here
    if args.part in ("derivatives", "all"):
        derivatives_part(args)
    if args.part == "speed":
        speed_part(args)
    if args.part in ("derivatives", "speed"):
        return 0

    from repertoire.planning.arm_library import synthetic_demonstrations
    from repertoire.planning.dmp_demos import noisy_sparse_minimum_jerk
    from repertoire.planning.dmp_learn import learn_dmp, learn_task_space_dmp
    from repertoire.planning.dmp_math import minimum_jerk

    learn = functools.partial(learn_dmp, bridge_gaps=not args.samples_alone)
    seeds = range(*args.seeds)
    for n_basis in (50, 20):
        for label, exact in (("estimated derivatives", False), ("exact derivatives", True)):
            errors = {0.0: [], "gcv": [], "auto": []}
            for seed in seeds:
                t, x, xd, xdd = noisy_sparse_minimum_jerk(seed)
                known = {"xd": xd, "xdd": xdd} if exact else {}
                for ridge, out in errors.items():
                    out.append(error(learn(t, x, n_basis=n_basis, ridge=ridge, **known)))
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
