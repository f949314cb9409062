"""Benchmark: subgoal refinement back-ends side by side (time and optimum).

Setting (issue 13): sequences like the paper's largest kitchen one, 4 actions with
more than 10 free parameters (3 intermediate subgoals x 4 parameters = 12), each
action's duration a seeded synthetic model tree of realistic size (depth 5-6: 25-64
leaves; the paper's trees had tens of leaves) over the features of the subgoals it
touches. Two kinds of trees: "fitted" (leaves least-squares fitted to a smooth duration,
nearly continuous like learned models) and "random" (independent random hyperplanes per
leaf: a harsh, discontinuous landscape for the black-box searches).

For each sequence: exact corner enumeration (median of repeated runs), the
Drake MILP (MixedIntegerBranchAndBound + Clp, exact via the incumbent-relative scaled
cost) and the plain MILP (cost unscaled: Drake's 1% gap), the paper's GA and scipy's
differential evolution. Targets on one core: corners < 10 ms median, GA < 0.5 s; MILP
and DE reported. The machine is shared: the load average is printed with the figures.

Run: ``.venv/bin/python tests/benchmarks/bench_refinement.py``.
"""

import argparse
import itertools
import os
import statistics
import time


def _timed(fn, repeats: int = 1):
    times, result = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - t0)
    return result, statistics.median(times)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sequences", type=int, default=6, help="seeded sequences")
    parser.add_argument("--depth", type=int, nargs="+", default=[5, 6], help="tree depths")
    parser.add_argument(
        "--kinds", nargs="+", default=["fitted", "random"], choices=["fitted", "random"]
    )
    parser.add_argument("--no-milp", action="store_true", help="skip the (slow) MILP")
    args = parser.parse_args()

    from pydrake.solvers import ClpSolver, MixedIntegerBranchAndBound
    from repertoire.planning.black_box import solve_de, solve_ga
    from repertoire.planning.refinement_exact import (
        build_refinement_milp,
        solve_corners,
        solve_milp,
    )
    from repertoire.planning.synthetic_models import chain_problem

    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    header = (
        f"{'kind':>6} {'depth':>5} {'seed':>4} {'leaves':>15} {'corners ms':>10} {'optimum':>9} "
        f"{'milp s':>7} {'milp-opt':>9} {'plain-opt':>9} {'ga s':>6} {'ga-opt':>8} "
        f"{'de s':>6} {'de-opt':>8}"
    )
    print(header)
    summary: dict[str, list[float]] = {k: [] for k in ("corners", "milp", "ga", "de")}
    gaps: dict[str, list[float]] = {f"{k} {b}": [] for k in args.kinds for b in ("ga", "de")}
    for kind, depth, seed in itertools.product(args.kinds, args.depth, range(args.sequences)):
        problem = chain_problem(seed, 4, 4, depth, fitted=kind == "fitted")
        leaves = "/".join(str(t.model.n_leaves) for t in problem.terms)
        exact, t_c = _timed(lambda p=problem: solve_corners(p), repeats=11)
        summary["corners"].append(t_c)
        milp_gap = plain_gap = float("nan")
        t_m = float("nan")
        if not args.no_milp:
            milp, t_m = _timed(lambda p=problem: solve_milp(p))
            summary["milp"].append(t_m)
            milp_gap = milp.cost - exact.cost
            prog = build_refinement_milp(problem)
            bnb = MixedIntegerBranchAndBound(prog.prog, ClpSolver.id())
            bnb.Solve()
            plain_gap = bnb.GetOptimalCost() - exact.cost
        ga, t_g = _timed(lambda p=problem, s=seed: solve_ga(p, seed=s))
        de, t_d = _timed(lambda p=problem, s=seed: solve_de(p, seed=s))
        summary["ga"].append(t_g)
        summary["de"].append(t_d)
        gaps[f"{kind} ga"].append((ga.cost - exact.cost) / exact.cost)
        gaps[f"{kind} de"].append((de.cost - exact.cost) / exact.cost)
        print(
            f"{kind:>6} {depth:>5} {seed:>4} {leaves:>15} {1e3 * t_c:>10.2f} "
            f"{exact.cost:>9.4f} {t_m:>7.2f} {milp_gap:>+9.1e} {plain_gap:>+9.1e} {t_g:>6.3f} "
            f"{ga.cost - exact.cost:>+8.4f} {t_d:>6.3f} {de.cost - exact.cost:>+8.4f}"
        )
    print("(*-opt columns: back-end optimum minus the exact corner optimum, seconds)")
    for name, times in summary.items():
        if times:
            print(f"{name:>8}: median {statistics.median(times):.4f} s, max {max(times):.4f} s")
    for name, rel in gaps.items():
        print(f"{name:>9}: optimum above exact by median {100 * statistics.median(rel):.2f}%")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
