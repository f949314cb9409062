"""LittleDog crossing a terrain with its step library (registered as ``littledog_library``).

The closed loop of Stolle et al. (sections III-IV) in physics::

    plant state -> BodyStateSensor -> body_pose, joint_angles, feet
    contact results -> FootContactSensor -> contact
    feet, contact -> LibraryPolicy -> choice (nearest step when all four feet are down)
    choice, body_pose, contact -> StepExecutor -> q_playback, ideal_pose (blend, then
        playback; a foot left unloaded after a step is lowered until it touches down)
    q_playback, ideal_pose, body_pose, joint_angles, contact -> IntegralFootController
        -> q_desired -> desired_state (actuator order, zero velocities) -> plant PD

The scenario names the source terrain
(:data:`~repertoire.diagrams.littledog_demos.LIBRARY_TERRAINS`),
the crossing direction, the start offsets, the controller gains and the library
file. With ``library: ""`` the library of all demonstrations is loaded from
``out/littledog/step_library.{npz,json}`` and, if that file does not exist yet,
recorded in physics and saved there first (about two minutes of wall time: each crossing
is kept as it is recorded, so an interrupted recording resumes where it stopped).
"""

import dataclasses
import fcntl
import functools
import math
import operator
import sys
from pathlib import Path

import numpy as np
from pydrake.systems.framework import Context, Diagram, DiagramBuilder
from pydrake.systems.primitives import MatrixGain, VectorLogSink
from repertoire.diagrams.littledog_demos import (
    crossing_start,
    flat_start,
    library_crossings,
    library_terrain,
    record_crossing,
)
from repertoire.diagrams.littledog_worlds import (
    PlantSettings,
    actuator_order,
    add_littledog_on_terrain,
)
from repertoire.diagrams.registry import register_diagram
from repertoire.planning.littledog_crawl import CrawlParams
from repertoire.planning.step_library import StepLibrary
from repertoire.systems.integral_foot_controller import IntegralFootController
from repertoire.systems.library_policy import LibraryPolicy, front_progress
from repertoire.systems.littledog_sensors import BodyStateSensor, FootContactSensor
from repertoire.systems.step_executor import StepExecutor

from repertoire.criteria import Bound
from repertoire.errors import RepertoireError, ScenarioError

DEFAULT_LIBRARY = Path("out") / "littledog" / "step_library"
"""Where the default library is cached (relative to the working directory)."""

LOG_PERIOD = 0.01


@dataclasses.dataclass
class LibraryLoopFields:
    """Start perturbation, library file, loop gains and physics of a LittleDog library run.

    The fields every scenario running a step library in the closed loop of
    :func:`add_library_loop` shares (checked by :func:`validate_loop_fields`).

    Attributes:
        start_offset: [dx, dy] added to the nominal start position (m).
        start_yaw_offset: added to the start heading (rad).
        library: step library path (npz + JSON; ``""`` = the cached default library).
        gain: integral controller gain k (0 = no integral correction).
        decay: per-update decay of a flying foot's integrator.
        integrator_limit: saturation of each integrator (m).
        blend_speed: body distance per second of the executor's blend (m/s).
        plant: physics settings.
    """

    start_offset: list[float] = dataclasses.field(default_factory=lambda: [0.0, 0.0])
    start_yaw_offset: float = 0.0
    library: str = ""
    gain: float = 0.05
    decay: float = 0.9
    integrator_limit: float = 0.04
    blend_speed: float = 0.1
    plant: PlantSettings = dataclasses.field(default_factory=PlantSettings)


@dataclasses.dataclass
class LittleDogLibraryScenario(LibraryLoopFields):
    """LittleDog crossing a library terrain with the step library.

    Attributes:
        terrain: name of a library terrain (``terrain_a`` or ``terrain_b``).
        direction_deg: crossing direction (degrees); the start and goal follow from it.
            The default library holds crossings at 0, 90, 180 and 270 (terrain_a) and 0,
            90 and 180 (terrain_b); elsewhere its nearest steps were recorded for another
            direction (at 45 on terrain_b the robot did not cross in 34 s). New terrains are
            the littledog_transfer world's (library steps transferred, gaps planned).
    """

    terrain: str = "terrain_a"
    direction_deg: float = 0.0

    def validate(self) -> None:
        """Raises ScenarioError naming a bad field."""
        try:
            library_terrain(self.terrain)
            self.plant.validate()
        except RepertoireError as e:
            raise ScenarioError(f"LittleDogLibraryScenario: {e}") from e
        if not math.isfinite(self.direction_deg):
            raise ScenarioError(f"direction_deg must be finite, got {self.direction_deg}")
        validate_loop_fields(self)


def validate_loop_fields(scenario) -> None:
    """Checks the start perturbation and loop gains a LittleDog library scenario shares.

    Args:
        scenario: a :class:`LibraryLoopFields` (any scenario with its fields).

    Raises:
        ScenarioError: naming the first bad field.
    """
    if len(scenario.start_offset) != 2 or not all(math.isfinite(v) for v in scenario.start_offset):
        raise ScenarioError(f"start_offset must be 2 finite numbers, got {scenario.start_offset}")
    if max(abs(v) for v in scenario.start_offset) > 0.1:
        raise ScenarioError(f"start_offset must be within +-0.1 m, got {scenario.start_offset}")
    if not (math.isfinite(scenario.start_yaw_offset) and abs(scenario.start_yaw_offset) <= 0.5):
        raise ScenarioError(
            f"start_yaw_offset must be within +-0.5 rad, got {scenario.start_yaw_offset}"
        )
    if not (0.0 <= scenario.gain <= 1.0 and 0.0 <= scenario.decay < 1.0):
        raise ScenarioError(
            f"gain must be in [0, 1] and decay in [0, 1), got {scenario.gain}, {scenario.decay}"
        )
    if not (0.0 < scenario.integrator_limit <= 0.1 and 0.0 < scenario.blend_speed <= 1.0):
        raise ScenarioError(
            f"integrator_limit must be in (0, 0.1] m and blend_speed in (0, 1] m/s, got "
            f"{scenario.integrator_limit}, {scenario.blend_speed}"
        )


def load_library(path: str = "") -> StepLibrary:
    """The library at ``path``; ``""`` = the default, recorded and cached on first use.

    Raises:
        ScenarioError: a given path that does not exist or is not a valid library.
    """
    if path:
        try:
            return StepLibrary.load(path)
        except RepertoireError as e:
            raise ScenarioError(f"library {path!r}: {e}") from e
    if not DEFAULT_LIBRARY.with_suffix(".json").is_file():
        DEFAULT_LIBRARY.parent.mkdir(parents=True, exist_ok=True)
        with open(DEFAULT_LIBRARY.parent / "step_library.lock", "w") as lock:
            # one recording at a time: a process that waited here finds the library that
            # the other one recorded (study workers on a fresh machine would each record it)
            fcntl.flock(lock, fcntl.LOCK_EX)
            if not DEFAULT_LIBRARY.with_suffix(".json").is_file():
                _record_default_library().save(DEFAULT_LIBRARY)
    return StepLibrary.load(DEFAULT_LIBRARY)


_CROSSINGS = DEFAULT_LIBRARY.parent / "step_library_crossings"
"""Where each crossing of the default library is kept as it is recorded (a library each; they
stay after the whole library is saved, so that removing them can never race a reader)."""


def _record_default_library() -> StepLibrary:
    """The library of every crossing of every library terrain, recorded in physics.

    The same steps, in the same order, as
    :func:`~repertoire.diagrams.littledog_demos.record_library` (checked: all 160 steps
    equal); each crossing (about 15 s) is saved under :data:`_CROSSINGS` as soon as it is
    recorded and read back from there on a later call, so an interrupted recording resumes
    where it stopped. A line on standard error tells each crossing as it starts.
    """
    jobs = library_crossings()
    parts = []
    for k, (name, direction) in enumerate(jobs, 1):
        tag = f"{name}_{direction:g}deg".replace(".", "p").replace("-", "m")
        path = _CROSSINGS / tag
        if path.with_suffix(".json").is_file() and path.with_suffix(".npz").is_file():
            parts.append(StepLibrary.load(path))
            continue
        print(
            f"recording the default LittleDog step library: crossing {k} of {len(jobs)} "
            f"({name}, {direction:g} deg)",
            file=sys.stderr,
            flush=True,
        )
        part = StepLibrary(record_crossing(library_terrain(name), direction).steps)
        part.save(path)
        parts.append(part)
    return functools.reduce(operator.add, parts)


def crossing_geometry(scenario: LittleDogLibraryScenario):
    """``(board, pose0, feet0, q0, heading, goal)`` of the scenario's crossing."""
    terrain = library_terrain(scenario.terrain)
    board = terrain.build()
    heading = math.radians(scenario.direction_deg)
    params = CrawlParams()
    offset = flat_start(board, heading, terrain.half_extent, params)
    pose0, feet0, q0 = crossing_start(
        board,
        heading,
        terrain.half_extent,
        params.standing_height,
        offset + np.asarray(scenario.start_offset),
        scenario.start_yaw_offset,
    )
    return board, pose0, feet0, q0, heading, terrain.half_extent - 0.02


def add_library_loop(
    builder: DiagramBuilder,
    plant,
    instance,
    library: StepLibrary,
    q0: np.ndarray,
    *,
    blend_speed: float,
    gain: float,
    decay: float,
    integrator_limit: float,
    log_period: float = LOG_PERIOD,
    goal_line: "tuple[float, float] | None" = None,
) -> dict[str, object]:
    """Adds the closed loop that replays a step library on a LittleDog in ``builder``.

    Sensors (body state, foot contact), nearest-step policy, step executor,
    integral foot controller and the desired-state gain into the plant's PD
    input, plus the loggers ``body_log``, ``feet_log``, ``integrator_log``,
    ``ideal_log``, ``step_log`` and ``contact_log``.

    Args:
        builder: the builder holding ``plant``.
        plant: the MultibodyPlant (with PD-controlled actuators).
        instance: the LittleDog model instance in ``plant``.
        library: the step library the policy chooses from and the executor plays.
        q0: the initial joint angles (start of the executor's first blend).
        blend_speed: body distance per second of the executor's blend (m/s).
        gain: integral controller gain k (0 = no integral correction).
        decay: per-update decay of a flying foot's integrator.
        integrator_limit: saturation of each integrator (m).
        log_period: the loggers' period (s).
        goal_line: ``(heading, goal)`` of the crossing: the policy stops choosing steps
            once both front feet are past it (see :class:`LibraryPolicy`); None: never.

    Returns:
        The added systems by name: ``sensor``, ``contact``, ``policy``,
        ``executor``, ``integral``, ``desired_state`` and the six loggers.
    """
    sensor = builder.AddNamedSystem("sensor", BodyStateSensor(plant, instance))
    builder.Connect(plant.get_state_output_port(), sensor.state_input)
    contact = builder.AddNamedSystem("contact", FootContactSensor(plant, instance))
    builder.Connect(plant.get_contact_results_output_port(), contact.contact_results_input)
    policy = builder.AddNamedSystem("policy", LibraryPolicy(library, goal_line=goal_line))
    builder.Connect(sensor.feet_output, policy.feet_input)
    builder.Connect(contact.contact_output, policy.contact_input)
    executor = builder.AddNamedSystem("executor", StepExecutor(library, q0, speed=blend_speed))
    builder.Connect(policy.choice_output, executor.choice_input)
    builder.Connect(sensor.body_pose_output, executor.body_pose_input)
    builder.Connect(contact.contact_output, executor.contact_input)
    integral = builder.AddNamedSystem(
        "integral",
        IntegralFootController(gain=gain, decay=decay, limit=integrator_limit),
    )
    builder.Connect(executor.q_playback_output, integral.q_playback_input)
    builder.Connect(executor.ideal_pose_output, integral.ideal_pose_input)
    builder.Connect(sensor.body_pose_output, integral.body_pose_input)
    builder.Connect(sensor.joint_angles_output, integral.joint_angles_input)
    builder.Connect(contact.contact_output, integral.contact_input)
    P = np.zeros((24, 12))
    P[np.arange(12), actuator_order(plant, instance)] = 1.0
    desired = builder.AddNamedSystem("desired_state", MatrixGain(P))
    builder.Connect(integral.q_desired_output, desired.get_input_port())
    builder.Connect(desired.get_output_port(), plant.get_desired_state_input_port(instance))
    systems = {
        "sensor": sensor,
        "contact": contact,
        "policy": policy,
        "executor": executor,
        "integral": integral,
        "desired_state": desired,
    }
    for name, port, size in [
        ("body_log", sensor.body_pose_output, 6),
        ("feet_log", sensor.feet_output, 12),
        ("integrator_log", integral.integrators_output, 12),
        ("ideal_log", executor.ideal_pose_output, 6),
        ("step_log", executor.step_index_output, 1),
        ("contact_log", contact.contact_output, 4),
    ]:
        log = builder.AddNamedSystem(name, VectorLogSink(size, log_period))
        builder.Connect(port, log.get_input_port())
        systems[name] = log
    return systems


@register_diagram(
    "littledog_library",
    scenario_type=LittleDogLibraryScenario,
    description="LittleDog crossing a rough two-board terrain by replaying its step library "
    "(nearest-step policy, spline blend, integral foot controller)",
    duration=34.0,
    check=lambda diagram, context: check_littledog_library(diagram, context),
    criteria={"crossed": Bound(lo=1.0), "min_clearance_m": Bound(lo=0.04), "fell": Bound(hi=0.0)},
)
def build_littledog_library(
    scenario: LittleDogLibraryScenario, *, meshcat=None, library: StepLibrary | None = None
) -> Diagram:
    """Builds the closed loop.

    Args:
        scenario: the scenario (validated here).
        meshcat: optional Meshcat for a visualizer.
        library: an already loaded library (else ``scenario.library`` is loaded).

    Returns:
        The Diagram ``littledog_library`` with subsystems ``plant``, ``scene_graph``,
        ``sensor``, ``contact``, ``policy``, ``executor``, ``integral``,
        ``desired_state`` and the loggers ``body_log``, ``feet_log``, ``integrator_log``,
        ``ideal_log``, ``step_log`` and ``contact_log`` (every 10 ms).
    """
    if not isinstance(scenario, LittleDogLibraryScenario):
        raise ScenarioError(
            f"littledog_library takes a LittleDogLibraryScenario, got {type(scenario).__name__}"
        )
    scenario.validate()
    library = load_library(scenario.library) if library is None else library
    board, pose0, _, q0, heading, goal = crossing_geometry(scenario)
    return build_library_crossing(
        "littledog_library", scenario, board, pose0, q0, library, heading, goal, meshcat
    )


def build_library_crossing(
    name: str, fields: LibraryLoopFields, board, pose0, q0, library, heading, goal, meshcat
) -> Diagram:
    """LittleDog on ``board`` replaying ``library`` with the loop of ``add_library_loop``.

    Args:
        name: the diagram's name.
        fields: plant, blend speed and integral-controller gains.
        board, pose0, q0: the terrain and the robot's start pose and joint angles.
        library: the StepLibrary to replay.
        heading, goal: the crossing direction [rad] and goal position, read by
            :func:`check_littledog_library`.
        meshcat: optional Meshcat for a visualizer.
    """
    builder = DiagramBuilder()
    plant, scene_graph, instance = add_littledog_on_terrain(builder, board, pose0, q0, fields.plant)
    add_library_loop(
        builder,
        plant,
        instance,
        library,
        q0,
        blend_speed=fields.blend_speed,
        gain=fields.gain,
        decay=fields.decay,
        integrator_limit=fields.integrator_limit,
        goal_line=(heading, goal),
    )
    if meshcat is not None:
        from pydrake.geometry import MeshcatVisualizer

        MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat)
    diagram = builder.Build()
    diagram.set_name(name)
    diagram._repertoire_crossing = (board, heading, goal)  # read by the check
    return diagram


def crossing_figures(
    times, body_pose, feet, steps, board, heading: float, goal: float
) -> dict[str, float]:
    """Success figures of a crossing from its logs.

    Args:
        times: log times (N,).
        body_pose: body poses (N x 6).
        feet: world foot centres (N x 12).
        steps: executed step index (N,).
        board: the terrain.
        heading: crossing direction (rad).
        goal: goal line along the heading (m).

    Returns:
        ``crossed`` (1.0 when both front feet passed the goal line), ``time_to_cross_s``
        (NaN if never), ``min_clearance_m`` (lowest body height above the terrain under
        it until the goal or the end), ``max_tilt_rad`` (the same span),
        ``fell`` (1.0 on tilt > 0.5 rad or clearance < 4 cm),
        ``steps_started``.
    """
    front = front_progress(np.asarray(feet).reshape(-1, 4, 3), heading)
    past = np.flatnonzero(front >= goal)
    end = past[0] + 1 if len(past) else len(times)  # judge the crossing up to the goal
    clearance = body_pose[:end, 2] - board.height(body_pose[:end, 0], body_pose[:end, 1])
    tilt = float(np.max(np.abs(body_pose[:end, 3:5])))
    changes = int(np.count_nonzero(np.diff(np.asarray(steps).ravel()) != 0))
    min_clear = float(np.min(clearance))
    return {
        "crossed": float(len(past) > 0),
        "time_to_cross_s": float(times[past[0]]) if len(past) else float("nan"),
        "min_clearance_m": min_clear,
        "max_tilt_rad": tilt,
        "fell": float(tilt > 0.5 or min_clear < 0.04),
        "steps_started": float(changes),
    }


def crossing_logs(diagram: Diagram, context: Context) -> dict[str, np.ndarray]:
    """The logs of a simulated ``littledog_library`` diagram as arrays (N rows each)."""
    out = {}
    for name in ("body_log", "feet_log", "integrator_log", "ideal_log", "step_log", "contact_log"):
        log = diagram.GetSubsystemByName(name).FindLog(context)
        out[name] = log.data().T
        out["times"] = log.sample_times()
    n = min(len(v) for v in out.values())
    return {k: v[:n] for k, v in out.items()}


def check_littledog_library(diagram: Diagram, context: Context) -> dict[str, float]:
    """:func:`crossing_figures` of a simulated ``littledog_library`` diagram."""
    board, heading, goal = diagram._repertoire_crossing
    logs = crossing_logs(diagram, context)
    return crossing_figures(
        logs["times"], logs["body_log"], logs["feet_log"], logs["step_log"], board, heading, goal
    )


__all__ = [
    "DEFAULT_LIBRARY",
    "LibraryLoopFields",
    "LittleDogLibraryScenario",
    "add_library_loop",
    "build_littledog_library",
    "check_littledog_library",
    "crossing_figures",
    "crossing_geometry",
    "crossing_logs",
    "load_library",
    "validate_loop_fields",
]
