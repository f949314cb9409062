"""Benchmark of the kitchen actions: episode throughput per action, and per-update cost.

Prints (1) kitchen GoToPose and Reach episodes per second with the study engine
on 1 and 2 workers (the 1-worker figure is the peer: the ratio is the parallel
speed-up), with the simulated seconds per wall second, and (2) the cost of one
discrete update of the Reach, Grip and Put LeafSystems (FixValue inputs), the
peer being GoToPose's update in the same run.
"""

import tempfile
import time
from pathlib import Path

import numpy as np
from repertoire.diagrams.kitchen import KITCHEN_OBSTACLES
from repertoire.studies.actions_kitchen import KitchenEpisodesConfig
from repertoire.studies.engine import load_records, run_study
from repertoire.systems.go_to_pose import GoToPose
from repertoire.systems.kitchen_actions import Grip, Put, Reach


def episodes_per_second(action: str, workers: int, episodes: int) -> tuple[float, float]:
    """(episodes per wall second, simulated seconds per wall second)."""
    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()
        run_study(
            "actions_kitchen",
            KitchenEpisodesConfig(actions=[action]),
            episodes=episodes,
            workers=workers,
            store=Path(tmp) / "s.sqlite",
            out_dir=tmp,
            fresh=True,
            progress=False,
        )
        wall = time.perf_counter() - t
        _, records = load_records(Path(tmp) / "s.sqlite", "actions_kitchen")
        return episodes / wall, sum(r.duration for r in records.values()) / wall


def update_cost_us(system, ports: dict, n: int = 2000) -> float:
    ctx = system.CreateDefaultContext()
    for name, value in ports.items():
        system.GetInputPort(name).FixValue(ctx, np.asarray(value, dtype=float))
    t = time.perf_counter()
    for k in range(n):
        ctx.SetTime(k * 1e-3)
        system.EvalUniquePeriodicDiscreteUpdate(ctx)
    return 1e6 * (time.perf_counter() - t) / n


def main() -> None:
    for action in ("reach", "goto_pose"):
        e1, s1 = episodes_per_second(action, 1, 6)
        e2, s2 = episodes_per_second(action, 2, 12)
        print(
            f"kitchen {action} episodes: {e1:.2f}/s on 1 worker ({s1:.1f} sim s/s), "
            f"{e2:.2f}/s on 2 workers ({s2:.1f} sim s/s; {e2 / e1:.2f}x)"
        )
    base = [2.0, 0.55, np.pi / 2, 0.0]
    arm = dict(arm_position=[0.62, 0.0, 0.25], target=[0.85, 0.0, 0.7036], base_state=base)
    costs = {
        "Reach": update_cost_us(Reach(obstacles=KITCHEN_OBSTACLES), arm),
        "Grip": update_cost_us(Grip(), dict(finger_position=[0.075] * 2, base_state=base)),
        "Put": update_cost_us(
            Put(obstacles=KITCHEN_OBSTACLES), arm | dict(finger_position=[0.05, 0.05])
        ),
        "GoToPose (peer)": update_cost_us(GoToPose(), dict(state=base, target=[1, 1, 0, 0])),
    }
    for name, us in costs.items():
        print(f"{name}: {us:.0f} us per discrete update")


if __name__ == "__main__":
    main()
