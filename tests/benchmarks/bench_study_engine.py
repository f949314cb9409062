"""Benchmark of the study engine on the pendulum study (a short simulation-bound episode).

For each episode count (``--episodes``, default 40 and 400) it prints episodes/s
for inline, a 1- and a 2-process pool (and, with ``--dask``, a Dask
LocalCluster of 2 single-thread workers), the 2-worker speed-ups over inline
and over 1 worker (target >= 1.7 over inline at 40 episodes of ~50 ms), and
the engine's per-episode overhead (target < 5 ms). Before them: the bare loop
(run_episode called directly) and the cost of the first pool of a process,
which starts multiprocessing's fork server and imports pydrake there once.

"total" rates are whole run_study calls (pool start-up and store writes
included); "steady" rates run from the first to the last stored row. "cores"
is the CPU time the episodes got (the store's per-episode ``cpu_s``) plus this
process's own, over the wall time: on a machine other jobs share, a 2-worker
run that got ~1 core cannot be 2x faster, so the load average is printed too,
and "ep/s per core" (total rate over cores) shows what the engine makes of the
CPU it got. (Linux's autogroup scheduling gives all processes of one session
one share: on a busy machine a 2-worker pool then gets no more CPU than inline.)
Runs of the executors are interleaved (inline, 1, 2, inline, 1, 2, ...) so
that load changes hit them alike; the fastest of ``--repeats`` is kept.
Summaries (tables, figures) are timed once, on their own line.

Run: .venv/bin/python tests/benchmarks/bench_study_engine.py [--episodes 40 400]
"""

import argparse
import os
import sqlite3
import tempfile
import time
from pathlib import Path

from repertoire.studies.engine import get_study, run_study


def _stored(store: Path) -> dict:
    """From the store: episode times, CPU times and the first-to-last finish span."""
    with sqlite3.connect(store) as db:
        rows = list(
            db.execute(
                "SELECT episode_s, cpu_s, finished_unix FROM episodes ORDER BY finished_unix"
            )
        )
    return dict(
        count=len(rows),
        episode_sum=sum(r[0] for r in rows),
        after_first=sum(r[0] for r in rows[1:]),
        cpu_sum=sum(r[1] for r in rows),
        span=rows[-1][2] - rows[0][2],
    )


def _run(label, executor, workers, n, config, tmp, tag, scheduler=None) -> dict:
    store = tmp / f"{tag}.sqlite"
    cpu0 = time.process_time()
    result = run_study(
        "pendulum",
        config,
        episodes=n,
        store=store,
        out_dir=tmp / f"out_{tag}",
        executor=executor,
        workers=workers,
        progress=False,
        summarize=False,
        scheduler_address=scheduler,
    )
    own_cpu = time.process_time() - cpu0
    st = _stored(store)
    assert st["count"] == n
    # Inline: the episodes ran in this process, so its CPU time already holds theirs.
    cpu = own_cpu if executor == "inline" else own_cpu + st["cpu_sum"]
    if executor == "inline":  # whole run: engine time minus episode time
        overhead_ms = 1e3 * (result.elapsed_s - st["episode_sum"]) / n
    elif workers == 1:  # sequential: time between rows beyond the episodes' own
        overhead_ms = 1e3 * (st["span"] - st["after_first"]) / (n - 1)
    else:
        overhead_ms = None
    return dict(
        label=label,
        total=n / result.elapsed_s,
        steady=(n - 1) / st["span"] if st["span"] > 0 else float("nan"),
        wall=result.elapsed_s,
        cores=cpu / result.elapsed_s,
        overhead_ms=overhead_ms,
        load=os.getloadavg()[0],
    )


def _table(rows: list[dict]) -> None:
    print(
        f"| {'executor':<30} | {'ep/s total':>10} | {'ep/s steady':>11} | {'wall s':>7} "
        f"| {'cores':>5} | {'ep/s per core':>13} | {'load':>5} |"
    )
    print(f"|{'-' * 32}|{'-' * 12}|{'-' * 13}|{'-' * 9}|{'-' * 7}|{'-' * 15}|{'-' * 7}|")
    for r in rows:
        steady = f"{r['steady']:11.2f}" if r["steady"] is not None else f"{'':>11}"
        print(
            f"| {r['label']:<30} | {r['total']:10.2f} | {steady} | {r['wall']:7.2f} "
            f"| {r['cores']:5.2f} | {r['total'] / r['cores']:13.2f} | {r['load']:5.2f} |"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--episodes", "-n", type=int, nargs="+", default=[40, 400])
    parser.add_argument("--repeats", type=int, default=3, help="runs per executor; best kept")
    parser.add_argument("--dask", action="store_true", help="add a Dask LocalCluster row")
    args = parser.parse_args()
    entry = get_study("pendulum")
    config = entry.demo_config()
    print(
        f"pendulum study, demo config ({config.duration_s:g} s simulated at "
        f"{config.time_step_s:g} s steps), {os.cpu_count()} cores, load average "
        f"{os.getloadavg()[0]:.2f} at start (other processes share the cores)"
    )
    n_bare = min(min(args.episodes), 40)  # a reference, not a row to compare
    cpu0, t0 = time.process_time(), time.perf_counter()
    for seed in range(n_bare):
        entry.run_episode(config, seed)
    bare_s = time.perf_counter() - t0
    bare_cores = (time.process_time() - cpu0) / bare_s
    print(
        f"bare run_episode loop: {n_bare} episodes in {bare_s:.2f} s, "
        f"{1e3 * bare_s / n_bare:.1f} ms per episode, cores {bare_cores:.2f}"
    )
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        first = _run("first pool, 2 workers", "process", 2, 4, config, tmp, "first")
        print(
            f"first pool of this process (starts the fork server, which imports pydrake once): "
            f"4 episodes in {first['wall']:.2f} s"
        )
        cluster = None
        if args.dask:
            from distributed import LocalCluster

            cluster = LocalCluster(
                n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
            )
        runs = [("inline", "inline", None), ("process, 1 worker", "process", 1)]
        runs.append(("process, 2 workers", "process", 2))
        if cluster is not None:
            runs.append(("dask LocalCluster, 2 workers", "dask", None))
        try:
            for n in args.episodes:
                best: dict[str, dict] = {}
                for rep in range(args.repeats):
                    for i, (label, executor, workers) in enumerate(runs):
                        row = _run(
                            label,
                            executor,
                            workers,
                            n,
                            config,
                            tmp,
                            f"n{n}_{i}_{rep}",
                            cluster.scheduler_address if executor == "dask" else None,
                        )
                        if label not in best or row["wall"] < best[label]["wall"]:
                            best[label] = row
                print(f"\n{n} episodes (best of {args.repeats}):\n")
                _table([best[label] for label, _, _ in runs])
                inline, one = best["inline"], best["process, 1 worker"]
                two = best["process, 2 workers"]
                print(
                    f"\n2 workers / inline (target >= 1.7 at 40): total "
                    f"{two['total'] / inline['total']:.2f}, steady "
                    f"{two['steady'] / inline['steady']:.2f}; 2 workers / 1 worker: total "
                    f"{two['total'] / one['total']:.2f}, steady {two['steady'] / one['steady']:.2f}"
                )
                dask = best.get("dask LocalCluster, 2 workers")
                if dask is not None:
                    print(f"dask 2 workers / inline: total {dask['total'] / inline['total']:.2f}")
                print(
                    f"engine overhead per episode (target < 5 ms): inline "
                    f"{inline['overhead_ms']:.3f} ms (wall time minus the run_episode times); "
                    f"1-worker pool {one['overhead_ms']:.3f} ms (first-to-last row span minus "
                    "the run_episode times in it)"
                )
        finally:
            if cluster is not None:
                cluster.close()

        n_sum = args.episodes[0]
        t0 = time.perf_counter()
        summary = run_study(
            "pendulum",
            config,
            episodes=n_sum,
            store=tmp / f"n{n_sum}_0_0.sqlite",
            out_dir=tmp / "summary",
            executor="inline",
            progress=False,
        )
        summary_s = time.perf_counter() - t0
        assert summary.n_run == 0
    print(f"\nload average at the end: {os.getloadavg()[0]:.2f}")
    print(
        f"summary tables + figure for {n_sum} stored episodes: {summary_s:.2f} s "
        "(once per study, not per episode)"
    )


if __name__ == "__main__":
    main()
