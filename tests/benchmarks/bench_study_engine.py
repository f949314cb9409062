"""Benchmark of the study engine on the pendulum study (a short simulation-bound episode).

Prints episodes/s for the bare loop (run_episode called directly, no engine),
inline, a 1- and a 2-process pool and a Dask LocalCluster with 2 single-thread
worker processes; the 2-worker / 1-worker ratio (target >= 1.7); and the
engine's per-episode overhead (target < 5 ms): engine wall time minus the sum
of the run_episode times of the same episodes, per episode.

"total" rates include pool start-up (spawning workers, importing pydrake) and
store writes; "steady" rates are measured between the first and the last
stored row, so they exclude start-up. "cores" is the CPU time this process and
its finished worker processes got, divided by the wall time: on a machine that
other jobs share, a 2-worker run that got only ~1 core cannot be 2x faster.
Summaries (tables, figures) are not timed except once, in their own line. Each
engine run is repeated (``--repeats``, default 2) and the fastest kept.

Run: .venv/bin/python tests/benchmarks/bench_study_engine.py [--episodes 60]
"""

import argparse
import os
import resource
import sqlite3
import tempfile
import time
from pathlib import Path

from repertoire.studies.engine import get_study, run_study


def _cpu_s() -> float:
    """CPU seconds of this process plus its reaped children (pool workers)."""
    total = 0.0
    for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN):
        usage = resource.getrusage(who)
        total += usage.ru_utime + usage.ru_stime
    return total


def _stored_timing(store: Path) -> tuple[float, float, float, int]:
    """From the store: (sum of engine-timed run_episode times, the same without the first
    finished episode, first-to-last finish span, rows)."""
    with sqlite3.connect(store) as db:
        rows = db.execute("SELECT episode_s, finished_unix FROM episodes ORDER BY finished_unix")
        rows = list(rows)
    total = sum(r[0] for r in rows)
    return total, total - rows[0][0], rows[-1][1] - rows[0][1], len(rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--episodes", "-n", type=int, default=60)
    parser.add_argument("--repeats", type=int, default=2, help="runs per executor; best kept")
    parser.add_argument("--no-dask", action="store_true", help="skip the Dask LocalCluster row")
    args = parser.parse_args()
    n = args.episodes
    entry = get_study("pendulum")
    config = entry.demo_config()
    print(
        f"pendulum study, demo config ({config.duration_s:g} s simulated at "
        f"{config.time_step_s:g} s steps), {n} episodes, {os.cpu_count()} cores, "
        f"load average {os.getloadavg()[0]:.2f} at start (other processes share the cores)"
    )

    # Bare loop: what the episodes cost without the engine.
    cpu0, t0 = _cpu_s(), time.perf_counter()
    for seed in range(n):
        entry.run_episode(config, seed)
    bare_s = time.perf_counter() - t0
    rows = [
        dict(
            label="bare run_episode loop",
            total=n / bare_s,
            steady=None,
            wall=bare_s,
            cores=(_cpu_s() - cpu0) / bare_s,
            overhead_ms=None,
        )
    ]
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        runs = [
            ("inline", "inline", None),
            ("process, 1 worker", "process", 1),
            ("process, 2 workers", "process", 2),
        ]
        cluster = None
        if not args.no_dask:
            from distributed import LocalCluster

            cluster = LocalCluster(
                n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
            )
            runs.append(("dask LocalCluster, 2 workers", "dask", None))
        try:
            for i, (label, executor, workers) in enumerate(runs):
                best = None
                for rep in range(args.repeats):
                    store = tmp / f"run{i}_{rep}.sqlite"
                    cpu0 = _cpu_s()
                    result = run_study(
                        "pendulum",
                        config,
                        episodes=n,
                        store=store,
                        out_dir=tmp / f"out{i}",
                        executor=executor,
                        workers=workers,
                        progress=False,
                        summarize=False,
                        scheduler_address=(
                            cluster.scheduler_address if executor == "dask" else None
                        ),
                    )
                    cores = (_cpu_s() - cpu0) / result.elapsed_s if executor != "dask" else None
                    episode_sum, after_first, span, count = _stored_timing(store)
                    assert count == n
                    if best is None or result.elapsed_s < best[0].elapsed_s:
                        best = (result, episode_sum, after_first, span, cores)
                result, episode_sum, after_first, span, cores = best
                if executor == "inline":  # whole run: engine time minus episode time
                    overhead_ms = 1e3 * (result.elapsed_s - episode_sum) / n
                elif workers == 1:  # sequential: time between rows beyond the episodes' own
                    overhead_ms = 1e3 * (span - after_first) / (n - 1)
                else:
                    overhead_ms = None
                rows.append(
                    dict(
                        label=label,
                        total=n / result.elapsed_s,
                        steady=(n - 1) / span if span > 0 else float("nan"),
                        wall=result.elapsed_s,
                        cores=cores,
                        overhead_ms=overhead_ms,
                    )
                )
        finally:
            if cluster is not None:
                cluster.close()

        t0 = time.perf_counter()
        summary = run_study(
            "pendulum",
            config,
            episodes=n,
            store=tmp / "run0_0.sqlite",
            out_dir=tmp / "summary",
            executor="inline",
            progress=False,
        )
        summary_s = time.perf_counter() - t0
        assert summary.n_run == 0

    print()
    print(
        f"| {'executor':<30} | {'ep/s total':>10} | {'ep/s steady':>11} | {'wall s':>7} "
        f"| {'cores':>5} |"
    )
    print(f"|{'-' * 32}|{'-' * 12}|{'-' * 13}|{'-' * 9}|{'-' * 7}|")
    for r in rows:
        steady = f"{r['steady']:11.2f}" if r["steady"] is not None else f"{'':>11}"
        cores = f"{r['cores']:5.2f}" if r["cores"] is not None else f"{'n/a':>5}"
        print(f"| {r['label']:<30} | {r['total']:10.2f} | {steady} | {r['wall']:7.2f} | {cores} |")
    print()
    by_label = {r["label"]: r for r in rows}
    one, two = by_label["process, 1 worker"], by_label["process, 2 workers"]
    print(
        f"2 workers / 1 worker (target >= 1.7): total {two['total'] / one['total']:.2f}, "
        f"steady {two['steady'] / one['steady']:.2f}"
    )
    dask = by_label.get("dask LocalCluster, 2 workers")
    if dask is not None:
        print(
            f"dask 2 workers / process 1 worker: total {dask['total'] / one['total']:.2f}, "
            f"steady {dask['steady'] / one['steady']:.2f}"
        )
    inline = by_label["inline"]
    print(
        f"engine overhead per episode (target < 5 ms): inline {inline['overhead_ms']:.3f} ms "
        "(engine wall time minus the engine-timed run_episode calls, per episode); "
        f"1-process pool {one['overhead_ms']:.3f} ms (first-to-last stored row span minus the "
        "run_episode times in it, per episode)"
    )
    print(
        f"inline against the separate bare loop: {1e3 * (inline['wall'] - bare_s) / n:.3f} ms "
        "per episode (includes run-to-run noise of a shared machine)"
    )
    print(f"load average at the end: {os.getloadavg()[0]:.2f}")
    print(
        f"summary tables + figure for {n} stored episodes: {summary_s:.2f} s "
        "(once per study, not per episode)"
    )


if __name__ == "__main__":
    main()
