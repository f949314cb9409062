"""Real-time factor of LittleDog standing on a terrain board at a 1 ms time step.

Builds the registered ``littledog_stand`` diagram for several boards and contact
approximations, simulates each for ``--duration`` simulated seconds, and prints
the real-time factor (simulated seconds per wall second; target >= 3 on one
core), and the same per CPU second of this process (what an unshared core would
give when the machine is busy). The process is pinned to one CPU unless
``--no-pin`` is given.
"""

import argparse
import os
import time

from pydrake.systems.analysis import Simulator
from repertoire.diagrams.littledog import (
    LittleDogScenario,
    build_littledog_stand,
    check_littledog_stand,
)
from repertoire.diagrams.simulate import simulate
from repertoire.models.terrain import TerrainParams


def measure(
    kind: str, approximation: str, duration: float, seed: int = 0, *, raw: bool = False
) -> dict:
    """Builds, simulates and returns the wall time, real-time factor and check figures.

    Args:
        kind: board kind.
        approximation: discrete contact approximation.
        duration: simulated seconds.
        seed: board seed.
        raw: use a bare ``Simulator`` instead of repertoire's ``simulate`` (which adds
            a per-step NaN monitor), to show the monitor's cost.
    """
    base_xy = [-0.15, 0.0] if kind == "mixed" else [0.0, 0.0]
    scenario = LittleDogScenario(
        terrain=TerrainParams(kind=kind),
        board_seed=seed,
        time_step=1e-3,
        contact_approximation=approximation,
        base_xy=base_xy,
    )
    diagram = build_littledog_stand(scenario)
    start, start_cpu = time.perf_counter(), time.process_time()
    if raw:
        simulator = Simulator(diagram)
        simulator.AdvanceTo(duration)
        context = simulator.get_context()
    else:
        _, context = simulate(diagram, duration)
    wall = time.perf_counter() - start
    cpu = time.process_time() - start_cpu
    figures = check_littledog_stand(diagram, context)
    return {"wall_s": wall, "rtf": duration / wall, "rtf_cpu": duration / cpu, **figures}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--duration", type=float, default=5.0, help="simulated seconds per run")
    parser.add_argument("--kinds", default="flat,rocks,mixed", help="comma-separated board kinds")
    parser.add_argument("--approximations", default="lagged,sap", help="contact approximations")
    parser.add_argument("--no-pin", action="store_true", help="do not pin to one CPU")
    args = parser.parse_args()
    if not args.no_pin and hasattr(os, "sched_setaffinity"):
        cpu = sorted(os.sched_getaffinity(0))[0]
        os.sched_setaffinity(0, {cpu})
        print(f"pinned to CPU {cpu}")
    print(f"LittleDog standing, time step 1 ms, {args.duration:g} s simulated per run")
    print(
        f"{'board':8s} {'contact':8s} {'wall [s]':>9s} {'RTF':>7s} {'RTF(cpu)':>9s} "
        f"{'height err [mm]':>16s}"
    )
    rtfs = []
    for kind in args.kinds.split(","):
        for approximation in args.approximations.split(","):
            r = measure(kind, approximation, args.duration)
            rtfs.append(r["rtf"])
            print(
                f"{kind:8s} {approximation:8s} {r['wall_s']:9.3f} {r['rtf']:7.2f} "
                f"{r['rtf_cpu']:9.2f} {1e3 * r['height_error_m']:16.3f}"
            )
    print(f"min real-time factor: {min(rtfs):.2f} (target >= 3)")
    print(f"load average (1 min) during the run: {os.getloadavg()[0]:.2f}; RTF(cpu) = simulated")
    print("  seconds per CPU second of this process, what an unshared core would give")
    kind, approximation = args.kinds.split(",")[0], args.approximations.split(",")[0]
    bare = measure(kind, approximation, args.duration, raw=True)
    ours = measure(kind, approximation, args.duration)
    print(
        f"{kind}/{approximation}: bare Simulator RTF {bare['rtf']:.2f}, repertoire simulate() "
        f"RTF {ours['rtf']:.2f} (ratio {ours['rtf'] / bare['rtf']:.2f}; the NaN monitor's cost)"
    )


if __name__ == "__main__":
    main()
