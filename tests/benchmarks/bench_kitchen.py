"""Benchmark of the kitchen actions: episode throughput before -> after, and per-update cost.

Prints (1) kitchen GoToPose and Reach episodes per second with the study engine
on 2 workers, for the old episode settings (all five cups in the world, reach
plant step 5 ms, the world built for every episode) and the current ones (no
cups, reach step 10 ms, the world built once per worker and reset), on the
same seeds in the same run, with the machine load; beside each rate the
simulated seconds per wall second and the mean wall time of one episode inside
its worker (without the engine's start-up). (2) How much the outcome moved:
per seed, how many statuses changed and the largest change of a succeeded
episode's duration, and the mean duration of both. (3) The cost of one discrete
update of the Reach, Grip and Put LeafSystems (FixValue inputs), the peer
being GoToPose's update in the same run.

Run: ``nice -n 10 python tests/benchmarks/bench_kitchen.py [--episodes 60]``.
"""

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np
from repertoire.diagrams.kitchen import KITCHEN_CUPS, KITCHEN_OBSTACLES
from repertoire.studies.actions_kitchen import KitchenEpisodesConfig
from repertoire.studies.engine import load_records, run_study
from repertoire.systems.go_to_pose import GoToPose
from repertoire.systems.kitchen_actions import Grip, Put, Reach


def timed_study(study: str, config, workers: int, episodes: int) -> tuple[float, list]:
    """(wall seconds, records in seed order) of a fresh run of ``study`` on ``workers``."""
    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()
        run_study(
            study,
            config,
            episodes=episodes,
            workers=workers,
            store=Path(tmp) / "s.sqlite",
            out_dir=tmp,
            fresh=True,
            progress=False,
            summarize=False,
        )
        wall = time.perf_counter() - t
        _, records = load_records(Path(tmp) / "s.sqlite", study)
        return wall, [records[k] for k in sorted(records)]


def update_cost_us(system, ports: dict, n: int = 2000) -> float:
    ctx = system.CreateDefaultContext()
    for name, value in ports.items():
        system.GetInputPort(name).FixValue(ctx, np.asarray(value, dtype=float))
    t = time.perf_counter()
    for k in range(n):
        ctx.SetTime(k * 1e-3)
        system.EvalUniquePeriodicDiscreteUpdate(ctx)
    return 1e6 * (time.perf_counter() - t) / n


def before_after(study: str, label: str, settings: dict, n: int) -> None:
    """Prints episodes/s on 2 workers for each config of ``settings`` and how the outcome moved.

    Args:
        study: a registered study whose records have ``duration``, ``status``, ``wall_time_s``.
        label: what the lines start with.
        settings: ``{"before": config, "after": config}``, run on the same seeds.
        n: episodes per setting.
    """
    runs = {}
    for name, config in settings.items():
        wall, records = timed_study(study, config, 2, n)
        runs[name] = records
        sim = sum(r.duration for r in records)
        per_episode = np.mean([r.wall_time_s for r in records])
        print(
            f"{label} {name}: {n / wall:.2f} episodes/s on 2 workers "
            f"({sim / wall:.1f} sim s/s; {1e3 * per_episode:.0f} ms wall per episode in a "
            f"worker; load {os.getloadavg()[0]:.2f})"
        )
    before, after = runs["before"], runs["after"]
    changed = sum(a.status != b.status for a, b in zip(before, after))
    both = [(a.duration, b.duration) for a, b in zip(before, after)
            if a.status == b.status == "SUCCEEDED"]  # fmt: skip
    d = np.array(both).reshape(-1, 2)
    moved = f"{np.max(np.abs(d[:, 1] - d[:, 0])):.3f} s" if len(d) else "-"
    print(
        f"  outcome: {changed} of {n} statuses changed; {len(d)} succeeded in both: mean "
        f"duration {d[:, 0].mean():.3f} -> {d[:, 1].mean():.3f} s, largest change {moved}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--episodes", type=int, default=60, help="episodes per action and setting")
    args = parser.parse_args()
    n = args.episodes
    print(f"load average at start: {os.getloadavg()[0]:.2f} (2 workers, {n} episodes each)")
    for action in ("goto_pose", "reach"):
        settings = {
            "before": KitchenEpisodesConfig(
                actions=[action],
                cups=list(KITCHEN_CUPS),
                reach_time_step=5e-3,
                reuse_diagram=False,
            ),  # fmt: skip
            "after": KitchenEpisodesConfig(actions=[action]),
        }
        before_after("actions_kitchen", f"kitchen {action}", settings, n)
    base = [2.0, 0.55, np.pi / 2, 0.0]
    arm = dict(arm_position=[0.62, 0.0, 0.25], target=[0.85, 0.0, 0.7036], base_state=base)
    costs = {
        "Reach": update_cost_us(
            Reach(obstacles=KITCHEN_OBSTACLES), arm | dict(finger_position=[0.075] * 2)
        ),
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
