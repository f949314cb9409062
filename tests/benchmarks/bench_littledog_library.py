"""LittleDog step library: policy lookup speed, closed-loop real-time factor, recording time.

Prints (no assertions):

- nearest-step lookups per second on a 170-step library (the recorded library
  plus transformed copies of its first steps, or random steps when it is not
  cached), single queries through ``StepIndex.query`` (brute force and cKDTree)
  and batched queries through ``StepIndex.query_batch`` (target >= 50,000 single
  queries per second);
- the real-time factor of the ``littledog_library`` closed loop at a 1 ms plant
  step on one CPU, with repertoire's ``simulate`` (per-step NaN monitor) and with a
  bare ``Simulator`` (target >= 1);
- the wall time of recording the whole library (seven crossings, one process),
  unless ``--skip-record``.
"""

import argparse
import os
import time

import numpy as np
from pydrake.systems.analysis import Simulator
from repertoire.diagrams.littledog_library import (
    DEFAULT_LIBRARY,
    LittleDogLibraryScenario,
    build_littledog_library,
    check_littledog_library,
    load_library,
)
from repertoire.diagrams.simulate import simulate
from repertoire.planning.step_library import StepLibrary
from repertoire.systems.library_policy import StepIndex


def library_of(n: int, base: StepLibrary) -> StepLibrary:
    """``base`` grown (by shifted copies) or cut to ``n`` steps."""
    lib = base
    k = 1
    while len(lib) < n:
        lib = lib + base.transformed(0.01 * k, 0.0, 0.0)
        k += 1
    return StepLibrary(lib.steps[:n])


def bench_lookup(library: StepLibrary, queries: int = 20000) -> None:
    rng = np.random.default_rng(0)
    feet = library.keys[rng.integers(len(library), size=queries)] + rng.normal(
        0, 0.02, (queries, 12)
    )
    for label, below in (("brute force", 10**9), ("cKDTree", 0)):
        index = StepIndex(library, brute_force_below=below)
        start = time.perf_counter()
        for f in feet:
            index.query(f)
        rate = queries / (time.perf_counter() - start)
        print(f"  single queries, {label:11s}: {rate:10,.0f} /s")
    index = StepIndex(library)
    start = time.perf_counter()
    index.query_batch(feet)
    print(f"  batched ({queries} at once)  : {queries / (time.perf_counter() - start):10,.0f} /s")


def bench_loop(library: StepLibrary, duration: float) -> None:
    for label, raw in (("simulate (NaN monitor)", False), ("bare Simulator", True)):
        diagram = build_littledog_library(LittleDogLibraryScenario(), library=library)
        start, cpu = time.perf_counter(), time.process_time()
        if raw:
            simulator = Simulator(diagram)
            simulator.AdvanceTo(duration)
            context = simulator.get_context()
        else:
            _, context = simulate(diagram, duration)
        wall, cpu = time.perf_counter() - start, time.process_time() - cpu
        steps = check_littledog_library(diagram, context)["steps_started"]
        print(
            f"  {label:24s}: RTF {duration / wall:5.2f} (per CPU second {duration / cpu:5.2f}), "
            f"{steps:.0f} steps in {duration:g} s"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--duration", type=float, default=10.0, help="simulated s per run")
    parser.add_argument("--skip-record", action="store_true", help="skip the recording timing")
    parser.add_argument("--no-pin", action="store_true", help="do not pin to one CPU")
    args = parser.parse_args()
    if not args.no_pin and hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    if not args.skip_record:
        from repertoire.diagrams.littledog_demos import record_library

        start = time.perf_counter()
        recorded, summaries = record_library()
        wall = time.perf_counter() - start
        sim = sum(s["wall_s"] for s in summaries)
        print(
            f"recording the whole library: {len(recorded)} steps in {len(summaries)} crossings, "
            f"{wall:.1f} s wall ({sim:.1f} s of it simulating)"
        )
    library = load_library("")
    print(f"policy lookup on a 170-step library (from {DEFAULT_LIBRARY}):")
    bench_lookup(library_of(170, library))
    print(f"closed loop at a 1 ms plant step, {args.duration:g} s simulated, one CPU:")
    bench_loop(library, args.duration)


if __name__ == "__main__":
    main()
