"""Benchmark of the DMP-driven arm7 worlds: wall and CPU time of one full episode each.

Prints, for arm_pick_and_place and arm_serving_water at their default scenarios
(4 ms plant step, finger-contact grasp), the simulated time, the wall and CPU
seconds of the simulation, the real-time factor and the world's figures
(success, reach errors). The peer in the same run is the same world at a 2 ms
plant step (the ratio says what the 4 ms step saves).
"""

import time

from repertoire.diagrams.arm_dmp import build_pick_and_place, build_serving_water
from repertoire.diagrams.arm_dmp_results import (
    pick_and_place_figures,
    run_arm_world,
    serving_figures,
)
from repertoire.diagrams.arm_dmp_scenarios import (
    PickPlaceScenario,
    ServingScenario,
    plan_pick_and_place,
    plan_serving,
)
from repertoire.planning.arm_library import motion_library


def _episode(build, plan, figures, scenario):
    diagram = build(scenario)
    _, duration = plan(scenario)
    cpu = time.process_time()
    context, wall = run_arm_world(diagram, duration)
    cpu = time.process_time() - cpu
    return duration, wall, cpu, figures(diagram, context)


def main() -> None:
    t = time.perf_counter()
    motion_library()
    print(
        f"learning the motion library (5 DMPs, 10-D, 30 basis functions): "
        f"{time.perf_counter() - t:.2f} s"
    )
    worlds = (
        (
            "arm_pick_and_place",
            build_pick_and_place,
            plan_pick_and_place,
            pick_and_place_figures,
            PickPlaceScenario,
        ),
        ("arm_serving_water", build_serving_water, plan_serving, serving_figures, ServingScenario),
    )
    for name, build, plan, figures, scenario_type in worlds:
        cpus = {}
        for dt in (0.004, 0.002):
            sim, wall, cpu, fig = _episode(build, plan, figures, scenario_type(time_step=dt))
            cpus[dt] = cpu
            print(
                f"{name} dt={dt * 1000:.0f} ms: {sim:.2f} s simulated in {wall:.2f} s wall "
                f"({cpu:.2f} s CPU), real-time factor {sim / wall:.2f}; success "
                f"{fig['success']:.0f}, grasp reach error "
                f"{fig['grasp_reach_error_m'] * 1000:.2f} mm"
            )
        print(f"{name}: CPU ratio 4 ms / 2 ms step = {cpus[0.004] / cpus[0.002]:.2f}")


if __name__ == "__main__":
    main()
