"""Benchmark of the biped worlds: real-time factor of standing and of ZMP walking.

Prints wall and CPU seconds and the real-time factor (simulated / wall seconds) of
``biped_stand`` (1 ms, lagged contact, joint PD only), of a 10-step walk executed by
the walking controller at its default setting (SAP, 2 ms plant step, IK every 5 ms),
and, as the peer measured in the same run, the same walk at a 1 ms plant step; plus
the time of one three-command sequence of the footstep-table study. CPU time is the
honest figure on a shared machine; wall time includes waiting for the CPU.
"""

import time

from pydrake.systems.analysis import Simulator
from repertoire.diagrams.biped import BipedStandScenario, build_biped_stand
from repertoire.diagrams.biped_walk import execute_plan, plan_from_actions, start_feet
from repertoire.planning.footstep.actions import nominal_action_table
from repertoire.studies.footstep_table import FootstepTableConfig, run_episode

ACTIONS = ["forward_short", "forward_long", "forward_long", "forward_long", "turn_left"]
ACTIONS += ["side_step", "turn_right", "forward_medium", "stop", "stop"]


def _timed(fn):
    wall, cpu = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - wall, time.process_time() - cpu


def main() -> None:
    diagram = build_biped_stand(BipedStandScenario())
    simulator = Simulator(diagram)
    _, wall, cpu = _timed(lambda: simulator.AdvanceTo(5.0))
    print(
        f"biped_stand 5 s: wall {wall:.2f} s, cpu {cpu:.2f} s, real-time factor (cpu) {5 / cpu:.1f}"
    )

    stance, swing = start_feet([0.0, 0.0, 0.0], "left")
    plan = plan_from_actions(ACTIONS, stance, "left", swing, nominal_action_table())
    rtf = {}
    for time_step in (2e-3, 1e-3):
        result, wall, cpu = _timed(lambda ts=time_step: execute_plan(plan, time_step=ts))
        rtf[time_step] = result.final_time / cpu
        print(
            f"biped walk, 10 steps, SAP {1000 * time_step:.0f} ms: simulated "
            f"{result.final_time:.1f} s, wall {wall:.1f} s, cpu {cpu:.1f} s, "
            f"real-time factor (cpu) {rtf[time_step]:.2f}, fell={result.fell}"
        )
    print(f"2 ms / 1 ms real-time factor ratio: {rtf[2e-3] / rtf[1e-3]:.2f}")
    record, wall, cpu = _timed(lambda: run_episode(FootstepTableConfig(), 0))
    print(f"footstep_table episode (3 steps from standing): wall {wall:.2f} s, cpu {cpu:.2f} s")


if __name__ == "__main__":
    main()
