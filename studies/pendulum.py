"""Pendulum study: a damped pendulum released from a seeded random angle.

Each episode builds a MultibodyPlant with one revolute body (a solid sphere bob
on a massless rod, built through the plant API, no model file), draws the
release angle and the joint damping from the seed, simulates a short time and
records the initial and final angle, the mechanical energy lost, the peak
angular speed and the wall time. It is the engine's example and benchmark
study: short, simulation-bound and deterministic for a seed.

Run it with ``python -m repertoire.studies.pendulum --help``.
"""

import dataclasses
import math
import time
from pathlib import Path

import numpy as np
from repertoire.studies.engine import register_study

from repertoire.errors import RepertoireError

GRAVITY_M_S2 = 9.81


@dataclasses.dataclass
class PendulumConfig:
    """What every episode of the pendulum study shares.

    Attributes:
        length_m: pivot to bob centre.
        mass_kg: bob mass.
        bob_radius_m: bob radius (a uniform solid sphere).
        max_initial_angle_rad: release angles are uniform in [-max, max].
        damping_min: lower bound of the joint's viscous damping, N*m*s.
        damping_max: upper bound of the joint's viscous damping, N*m*s.
        duration_s: simulated time per episode.
        time_step_s: the plant's discrete time step (0 for continuous, error
            controlled integration).
    """

    length_m: float = 0.5
    mass_kg: float = 1.0
    bob_radius_m: float = 0.05
    max_initial_angle_rad: float = 2.5
    damping_min: float = 0.0
    damping_max: float = 0.2
    duration_s: float = 2.0
    time_step_s: float = 2.5e-4

    def validate(self) -> None:
        """Raises RepertoireError if a field is out of range."""
        for name in ("length_m", "mass_kg", "bob_radius_m", "duration_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise RepertoireError(f"PendulumConfig.{name} must be finite and > 0, got {v}")
        if not 0 < self.max_initial_angle_rad <= math.pi:
            raise RepertoireError(
                f"PendulumConfig.max_initial_angle_rad must be in (0, pi], "
                f"got {self.max_initial_angle_rad}"
            )
        # Finite too: an infinite damping_max passed and every episode then died in the
        # damping draw (numpy's OverflowError), after its store was made.
        if not 0 <= self.damping_min <= self.damping_max < math.inf:
            raise RepertoireError(
                f"PendulumConfig needs 0 <= damping_min <= damping_max < inf, got "
                f"{self.damping_min}, {self.damping_max}"
            )
        if not (0 <= self.time_step_s < self.duration_s):
            raise RepertoireError(
                f"PendulumConfig.time_step_s must be in [0, duration_s), got {self.time_step_s}"
            )


@dataclasses.dataclass
class PendulumRecord:
    """One pendulum episode.

    Attributes:
        initial_angle_rad: release angle from the downward vertical.
        damping: the joint's viscous damping, N*m*s.
        final_angle_rad: angle at the end of the episode.
        final_speed_rad_s: angular rate at the end.
        energy_lost_j: initial minus final mechanical energy.
        energy_lost_fraction: ``energy_lost_j`` over the initial energy above rest.
        max_speed_rad_s: the largest |angular rate| seen at any step.
        lost_half_energy: True if the pendulum lost at least half its energy.
        wall_time_s: wall time of the episode (timing field).
    """

    initial_angle_rad: float
    damping: float
    final_angle_rad: float
    final_speed_rad_s: float
    energy_lost_j: float
    energy_lost_fraction: float
    max_speed_rad_s: float
    lost_half_energy: bool
    wall_time_s: float


def pendulum_inertia(config: PendulumConfig) -> float:
    """Moment of inertia about the pivot, kg*m^2 (solid sphere + parallel axis)."""
    m, r, length = config.mass_kg, config.bob_radius_m, config.length_m
    return m * length**2 + 0.4 * m * r**2


def undamped_max_speed(config: PendulumConfig, angle_rad: float) -> float:
    """Peak angular speed of the undamped pendulum released at rest from ``angle_rad``."""
    drop = config.mass_kg * GRAVITY_M_S2 * config.length_m * (1.0 - math.cos(angle_rad))
    return math.sqrt(2.0 * drop / pendulum_inertia(config))


def sample_episode(config: PendulumConfig, seed: int) -> tuple[float, float]:
    """The seeded (release angle, damping) of an episode."""
    rng = np.random.default_rng(seed)
    angle = float(rng.uniform(-config.max_initial_angle_rad, config.max_initial_angle_rad))
    damping = float(rng.uniform(config.damping_min, config.damping_max))
    return angle, damping


def run_episode(config: PendulumConfig, seed: int) -> PendulumRecord:
    """Builds the pendulum diagram, releases it from the seeded angle, simulates.

    Args:
        config: the study config.
        seed: the episode seed.

    Returns:
        The episode's record.
    """
    from pydrake.multibody.plant import MultibodyPlant
    from pydrake.multibody.tree import RevoluteJoint, SpatialInertia
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder, EventStatus

    t0 = time.perf_counter()
    angle0, damping = sample_episode(config, seed)
    builder = DiagramBuilder()
    plant = builder.AddSystem(MultibodyPlant(config.time_step_s))
    plant.set_name("plant")
    # Bob frame B at the pivot; the sphere's centre sits length_m below it.
    M_BBo_B = SpatialInertia.SolidSphereWithMass(config.mass_kg, config.bob_radius_m).Shift(
        [0.0, 0.0, config.length_m]
    )
    bob = plant.AddRigidBody("bob", M_BBo_B)
    pivot = plant.AddJoint(
        RevoluteJoint("pivot", plant.world_frame(), bob.body_frame(), [0.0, 1.0, 0.0], damping)
    )
    plant.Finalize()
    diagram = builder.Build()
    diagram.set_name("pendulum")

    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    plant_context = plant.GetMyMutableContextFromRoot(context)
    pivot.set_angle(plant_context, angle0)
    pivot.set_angular_rate(plant_context, 0.0)

    def energy() -> float:
        return plant.CalcKineticEnergy(plant_context) + plant.CalcPotentialEnergy(plant_context)

    e_rest = -config.mass_kg * GRAVITY_M_S2 * config.length_m
    e0 = energy()
    peak = [0.0]

    def monitor(_root_context) -> EventStatus:
        peak[0] = max(peak[0], abs(pivot.get_angular_rate(plant_context)))
        return EventStatus.Succeeded()

    simulator.set_monitor(monitor)
    if config.time_step_s == 0.0:
        simulator.get_mutable_integrator().set_target_accuracy(1e-6)
    simulator.AdvanceTo(config.duration_s)
    e1 = energy()
    lost = e0 - e1
    above_rest = e0 - e_rest
    fraction = lost / above_rest if above_rest > 0 else 0.0
    return PendulumRecord(
        initial_angle_rad=angle0,
        damping=damping,
        final_angle_rad=float(pivot.get_angle(plant_context)),
        final_speed_rad_s=float(pivot.get_angular_rate(plant_context)),
        energy_lost_j=float(lost),
        energy_lost_fraction=float(fraction),
        max_speed_rad_s=float(peak[0]),
        lost_half_energy=bool(fraction >= 0.5),
        wall_time_s=time.perf_counter() - t0,
    )


def summarize(
    records: list[PendulumRecord], config: PendulumConfig, out_dir: Path
) -> dict[str, Path]:
    """Writes a scatter of energy lost against damping, coloured by release angle.

    The small-angle closed form ``1 - exp(-b T / I)`` is drawn over the points.

    Returns:
        ``{"energy_vs_damping": png_path}``.
    """
    from matplotlib.figure import Figure

    damping = [r.damping for r in records]
    lost = [r.energy_lost_fraction for r in records]
    angle = [abs(r.initial_angle_rad) for r in records]
    fig = Figure(figsize=(6.5, 4.2), layout="constrained")
    ax = fig.add_subplot()
    sc = ax.scatter(
        damping,
        lost,
        c=angle,
        cmap="viridis",
        vmin=0.0,
        vmax=config.max_initial_angle_rad,
        s=28,
        edgecolors="k",
        linewidths=0.3,
        label="one episode (colour: |release angle|)",
    )
    fig.colorbar(sc, ax=ax, label="|release angle| (rad)")
    b = np.linspace(0.0, max(config.damping_max, max(damping, default=0.0)), 100)
    closed_form = 1.0 - np.exp(-b * config.duration_s / pendulum_inertia(config))
    ax.plot(b, closed_form, color="tab:red", lw=1.2, label=r"small-angle $1-e^{-bT/I}$")
    ax.axhline(0.5, color="0.5", lw=0.8, ls="--", label="half the energy")
    ax.set_xlabel("joint damping (N·m·s)")
    ax.set_ylabel("fraction of energy lost")
    ax.set_title(f"Pendulum: energy lost in {config.duration_s:g} s ({len(records)} episodes)")
    ax.set_ylim(bottom=min(0.0, min(lost, default=0.0)))
    ax.legend(loc="best")
    path = Path(out_dir) / "pendulum_energy_vs_damping.png"
    fig.savefig(path, dpi=110)
    return {"energy_vs_damping": path}


def demo_config() -> PendulumConfig:
    """The demo and benchmark config: 2 s at a 0.25 ms step (tens of ms per episode)."""
    return PendulumConfig()


def smoke_config() -> PendulumConfig:
    """A tiny config for tests: 0.5 s at a 1 ms step."""
    return PendulumConfig(duration_s=0.5, time_step_s=1e-3)


register_study(
    "pendulum",
    config_type=PendulumConfig,
    record_type=PendulumRecord,
    run_episode=run_episode,
    description="damped pendulum from a seeded angle: energy lost and peak speed",
    summarize=summarize,
    demo_config=demo_config,
    demo_episodes=40,
    smoke_config=smoke_config,
).run_if_main(__name__)
