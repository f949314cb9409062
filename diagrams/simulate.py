"""Simulation helpers: run a Diagram with NaN detection, or run a registered world.

``simulate`` wraps :class:`pydrake.systems.analysis.Simulator` with a per-step
monitor that stops the run the moment any state of the diagram becomes
non-finite and reports the time and the system whose state diverged.
``simulate_registered`` builds a diagram from the registry, simulates it for its
registered duration and returns the figures of the world's ``check()``.
"""

import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Context, Diagram, EventStatus, System
from repertoire.diagrams.registry import DiagramEntry, get_diagram_entry
from repertoire.diagrams.scenario import load_scenario

from repertoire.errors import RepertoireError, ScenarioError


class SimulationDivergedError(RepertoireError):
    """A state of the simulated diagram became NaN or infinite."""


def leaf_systems(system: System) -> list[System]:
    """Every leaf system of ``system`` (depth first); a leaf returns itself."""
    if isinstance(system, Diagram):
        leaves = []
        for sub in system.GetSystems():
            leaves.extend(leaf_systems(sub))
        return leaves
    return [system]


def _state_values(context: Context) -> np.ndarray:
    """The continuous and discrete state of ``context`` as one flat vector."""
    parts = [context.get_continuous_state_vector().CopyToVector()]
    if context.num_discrete_state_groups() > 0:
        discrete = context.get_discrete_state()
        parts.extend(discrete.get_vector(i).CopyToVector() for i in range(discrete.num_groups()))
    return np.concatenate(parts) if parts else np.zeros(0)


def _state_finite_check(diagram: System, root_context: Context) -> Callable[[], bool]:
    """A cheap per-step test that every state of ``root_context`` and its rate is finite.

    The leaf contexts that hold state are looked up once (they live as long as the root
    context), so each call only reads their vectors. With continuous states it also
    evaluates the diagram's time derivatives: a NaN derivative makes Drake's
    error-controlled integrators shrink their step forever (RobotLocomotion/drake#12647),
    so it must stop the run before the next step. Where no discrete update follows, the
    integrator's first stage reuses these cached derivatives; where one does (the arm
    worlds' plant steps every 1 ms), they are evaluated once more per step: 7.75 s of
    ``arm_pick_and_place`` took 2.96-3.10 s of wall time instead of 2.57-2.71 s.
    """
    holders = []
    for leaf in leaf_systems(diagram):
        context = leaf.GetMyContextFromRoot(root_context) if leaf is not diagram else root_context
        n_groups = context.num_discrete_state_groups()
        if context.num_continuous_states() > 0 or n_groups > 0:
            holders.append((context, context.num_continuous_states() > 0, range(n_groups)))

    has_continuous = root_context.num_continuous_states() > 0

    def all_finite() -> bool:
        if (
            has_continuous
            and not np.isfinite(diagram.EvalTimeDerivatives(root_context).CopyToVector()).all()
        ):
            return False
        for context, continuous, groups in holders:
            if (
                continuous
                and not np.isfinite(context.get_continuous_state_vector().CopyToVector()).all()
            ):
                return False
            for i in groups:
                if not np.isfinite(context.get_discrete_state(i).value()).all():
                    return False
        return True

    return all_finite


def nonfinite_state_systems(diagram: System, root_context: Context) -> list[str]:
    """Path names of the leaf systems whose continuous or discrete state is not finite.

    Args:
        diagram: the root system that owns ``root_context``.
        root_context: a context of ``diagram``.

    Returns:
        System path names such as ``::arm_hold::plant`` (empty when all states are finite).
    """
    bad = []
    for leaf in leaf_systems(diagram):
        context = leaf.GetMyContextFromRoot(root_context) if leaf is not diagram else root_context
        values = _state_values(context)
        if values.size and not np.all(np.isfinite(values)):
            bad.append(leaf.GetSystemPathname())
    return bad


def nonfinite_derivative_systems(diagram: System, root_context: Context) -> list[str]:
    """Path names of the leaf systems whose continuous-state time derivative is not finite.

    Args:
        diagram: the root system that owns ``root_context``.
        root_context: a context of ``diagram`` (its inputs, if any, must be connected).

    Returns:
        System path names such as ``::my_diagram::integrator`` (empty when all are finite).
    """
    bad = []
    for leaf in leaf_systems(diagram):
        context = leaf.GetMyContextFromRoot(root_context) if leaf is not diagram else root_context
        if context.num_continuous_states() == 0:
            continue
        rates = leaf.EvalTimeDerivatives(context).CopyToVector()
        if not np.all(np.isfinite(rates)):
            bad.append(leaf.GetSystemPathname())
    return bad


# The longest span one call simulates: one simulated hour. The registered worlds
# run at about 0.4 s wall per simulated second (littledog_stand, biped_stand,
# diffdrive_drive), so an hour is ~25 min of wall time and the heavier worlds
# longer; a finite but huge duration (1e12 s) would otherwise start a run that never
# ends. Longer runs continue in further calls: ``simulate(..., context=context)``
# counts ``duration`` from the context's time.
MAX_DURATION_S = 3600.0

RECORDING_FPS = 64.0
"""Frames per simulated second of a recording (Meshcat's default), for runs up to
``MAX_RECORDED_FRAMES / RECORDING_FPS`` s."""
MAX_RECORDED_FRAMES = 7680
"""A recording keeps at most about this many frames: a longer run is recorded at
``MAX_RECORDED_FRAMES / duration`` frames per second. An HTML replay grows with its frames
(about 140 kB per simulated second of ``biped_stand`` at 64 frames per second), so an hour
at the full rate would write about half a gigabyte, more than a browser opens; capped, any
run stays under about 20 MB for that world."""


def recording_fps(duration: float) -> float:
    """Frames per second to record a run of ``duration`` s (see ``MAX_RECORDED_FRAMES``)."""
    return min(RECORDING_FPS, MAX_RECORDED_FRAMES / check_duration(duration))


def check_duration(duration: float) -> float:
    """``duration`` as a float after checking it is a number of seconds in (0, MAX_DURATION_S].

    Raises:
        RepertoireError: not a number, not finite, <= 0, or above ``MAX_DURATION_S``
            (one simulated hour; continue a longer run with ``context=``).
    """
    try:
        value = float(duration)
    except (TypeError, ValueError) as e:
        raise RepertoireError(f"duration must be a number of seconds, got {duration!r}") from e
    if not math.isfinite(value) or value <= 0.0:
        raise RepertoireError(f"duration must be a finite number of seconds > 0, got {duration!r}")
    if value > MAX_DURATION_S:
        raise RepertoireError(
            f"duration must be at most {MAX_DURATION_S:g} s (one simulated hour per run), "
            f"got {value:g}; simulate a longer span in several calls, each continuing "
            "from the previous context"
        )
    return value


def validate_control_period(
    period: float, time_step: float, longest: float = MAX_DURATION_S
) -> None:
    """Checks a discrete controller's update period against the plant step and the run.

    A controller updates at ``t = 0, period, 2 period, ...``: a period longer than the
    run it controls never updates again after the start, so the run holds the first
    command throughout. No scenario knows how long it will be simulated, but no run is
    longer than ``MAX_DURATION_S`` (``simulate``'s limit), which bounds every scenario's
    ``validate``; ``resolve_scenario`` given a run's duration (``simulate_registered``,
    ``record_replay``, ``repertoire simulate``) checks again against that duration.

    Args:
        period: the ``control_period`` field [s].
        time_step: the plant step [s] (the controller cannot update faster).
        longest: the longest run the controller serves [s].

    Raises:
        ScenarioError: naming ``control_period``, its value and the allowed range.
    """
    if not (np.isfinite(period) and time_step <= period <= longest):
        raise ScenarioError(
            f"control_period must be in [time_step, {longest:g}] s = [{time_step:g}, "
            f"{longest:g}] s (a longer period never updates the controller after t = 0 "
            f"within a run of at most {longest:g} s), got {period:g}"
        )


_CARRY_ON = (EventStatus.Severity.kDidNothing, EventStatus.Severity.kSucceeded)


def simulate(
    diagram: Diagram,
    duration: float,
    *,
    context: Context | None = None,
    realtime_rate: float = 0.0,
    meshcat: Any = None,
    record: bool = False,
    monitors: Sequence[Callable[[Context], EventStatus]] = (),
) -> tuple[Simulator, Context]:
    """Simulates ``diagram`` for ``duration`` seconds, stopping on non-finite state.

    Args:
        diagram: the Diagram to simulate.
        duration: simulated seconds to advance (> 0), counted from the context's time.
        context: a context of ``diagram`` to start from (default: a fresh default one).
        realtime_rate: target real-time rate (0 = as fast as possible, 1 = wall clock).
        meshcat: the ``pydrake.geometry.Meshcat`` the diagram's visualizer publishes
            to; needed only when ``record`` is true.
        record: record the run on ``meshcat`` (``StartRecording`` before,
            ``PublishRecording`` after, so the animation can be replayed or saved), at
            :func:`recording_fps` frames per second (64, fewer for runs over 2 minutes).
        monitors: extra per-step monitors ``f(root_context) -> EventStatus``, called in
            order after the finiteness check; the first status that is not
            ``Succeeded`` is returned (``ReachedTermination`` ends the run early and
            normally, ``Failed`` raises from the simulator).

    Returns:
        The simulator and its (root) context at the final time.

    Raises:
        RepertoireError: bad duration / rate, ``record`` without a meshcat, or a
            context that does not belong to ``diagram``.
        SimulationDivergedError: a state (or a continuous state's time derivative) became
            NaN or infinite; the message gives the simulated time and the systems whose
            state diverged.
    """
    if not isinstance(diagram, Diagram):
        raise RepertoireError(f"simulate needs a pydrake Diagram, got {type(diagram).__name__}")
    duration = check_duration(duration)
    if not math.isfinite(realtime_rate) or realtime_rate < 0.0:
        raise RepertoireError(f"realtime_rate must be finite and >= 0, got {realtime_rate!r}")
    if record and meshcat is None:
        raise RepertoireError("record=True needs meshcat= (the Meshcat the diagram publishes to)")
    if context is None:
        simulator = Simulator(diagram)
    else:
        try:
            diagram.ValidateContext(context)
        except RuntimeError as e:
            raise RepertoireError(
                f"the context given does not belong to diagram '{diagram.get_name()}': {e}"
            ) from e
        simulator = Simulator(diagram, context)
    simulator.set_target_realtime_rate(realtime_rate)

    diverged: dict[str, Any] = {}

    all_finite = _state_finite_check(diagram, simulator.get_context())

    extra = list(monitors)
    for m in extra:
        if not callable(m):
            raise RepertoireError(
                f"monitors must be callables f(context) -> EventStatus, got {m!r}"
            )

    def monitor(root_context: Context) -> EventStatus:
        if all_finite():
            for m in extra:
                status = m(root_context)
                if status.severity() not in _CARRY_ON:
                    return status
            return EventStatus.Succeeded()
        diverged["time"] = root_context.get_time()
        diverged["systems"] = nonfinite_state_systems(diagram, root_context)
        if not diverged["systems"]:  # finite states, a non-finite rate
            diverged["what"] = "time derivative"
            diverged["systems"] = nonfinite_derivative_systems(diagram, root_context)
        return EventStatus.Failed(diagram, "non-finite state")

    simulator.set_monitor(monitor)
    root_context = simulator.get_mutable_context()
    end_time = root_context.get_time() + duration
    if record:
        meshcat.StartRecording(frames_per_second=recording_fps(duration))
    try:
        simulator.Initialize()
        simulator.AdvanceTo(end_time)
    except RuntimeError as e:
        if not diverged:
            bad = nonfinite_state_systems(diagram, root_context)
            if not bad and "nan" in str(e).lower():
                raise SimulationDivergedError(
                    f"diagram '{diagram.get_name()}' stopped at t = {root_context.get_time():.6g}"
                    f" s on a NaN: {e}"
                ) from e
            if not bad:
                raise
            diverged.update(time=root_context.get_time(), systems=bad)
        raise SimulationDivergedError(
            f"diagram '{diagram.get_name()}' diverged: the "
            f"{diverged.get('what', 'state')} of "
            f"{', '.join(diverged['systems']) or 'the diagram'} became non-finite (NaN/inf) at "
            f"t = {diverged['time']:.6g} s of a run to t = {end_time:.6g} s. Check gains, time "
            f"step and initial conditions."
        ) from e
    finally:
        if record:
            meshcat.StopRecording()
            meshcat.PublishRecording()
    return simulator, root_context


def resolve_scenario(
    entry: DiagramEntry, scenario: Any = None, duration: float | None = None
) -> Any:
    """The scenario object for a registered diagram.

    Args:
        entry: the registry entry.
        scenario: None (the scenario type's defaults), a YAML file path (str or Path),
            or an instance of ``entry.scenario_type``.
        duration: the run's length [s], if it will be simulated: a scenario's
            ``control_period`` must not exceed it (see :func:`validate_control_period`).

    Raises:
        ScenarioError: the YAML file is missing, malformed or mistyped, or its
            ``control_period`` is longer than ``duration``.
        RepertoireError: ``scenario`` is an object of the wrong type.
    """
    if scenario is None:
        scenario = entry.scenario_type()
    elif isinstance(scenario, str | Path):
        scenario = load_scenario(entry.scenario_type, filename=scenario)
    elif not isinstance(scenario, entry.scenario_type):
        raise RepertoireError(
            f"diagram '{entry.name}' takes a {entry.scenario_type.__name__} scenario (or a YAML "
            f"file of one), got {type(scenario).__name__}"
        )
    if duration is not None and hasattr(scenario, "control_period"):
        validate_control_period(scenario.control_period, scenario.time_step, duration)
    return scenario


def build_registered(name: str, *, scenario: Any = None, meshcat: Any = None) -> Diagram:
    """Builds the registered diagram ``name`` from its scenario.

    Args:
        name: a registered diagram name (see ``repertoire list``).
        scenario: None, a YAML file path, or a scenario instance (see ``resolve_scenario``).
        meshcat: passed to the builder, which then adds a MeshcatVisualizer.

    Raises:
        UnknownNameError: ``name`` is not registered (the message lists known names).
        ScenarioError: the scenario YAML is bad.
    """
    entry = get_diagram_entry(name)
    diagram = entry.build(resolve_scenario(entry, scenario), meshcat=meshcat)
    if not isinstance(diagram, Diagram):
        raise RepertoireError(
            f"builder of '{name}' returned {type(diagram).__name__}, expected a pydrake Diagram"
        )
    return diagram


def start_context(entry: DiagramEntry | None, diagram: Diagram, scenario: Any) -> Context:
    """A new root context of ``diagram`` with the entry's start values (``initialize``) set.

    ``scenario``: the scenario instance the diagram was built from.
    """
    context = diagram.CreateDefaultContext()
    if entry is not None and entry.initialize is not None:
        entry.initialize(diagram, context, scenario)
    return context


def start_overlaps(diagram: Diagram, plant, tolerance: float) -> list[tuple]:
    """Pairs of bodies overlapping by more than ``tolerance`` (m) in the default context.

    Returns ``((model, name), (model, name), depth)`` per pair, SceneGraph's order; a body
    is named by its model instance and its name (the world's geometries, such as the
    ground, by their own names).
    """
    context = plant.GetMyContextFromRoot(diagram.CreateDefaultContext())
    query = plant.get_geometry_query_input_port().Eval(context)
    inspector = query.inspector()
    out = []
    for pair in query.ComputePointPairPenetration():
        if pair.depth <= tolerance:
            continue
        names = []
        for g in (pair.id_A, pair.id_B):
            body = plant.GetBodyFromFrameId(inspector.GetFrameId(g))
            model = plant.GetModelInstanceName(body.model_instance())
            names.append((model, inspector.GetName(g) if body.index() == 0 else body.name()))
        out.append((names[0], names[1], float(pair.depth)))
    return out


def run_check(entry: DiagramEntry, diagram: Diagram, context: Context) -> dict[str, float]:
    """Runs the entry's ``check(diagram, context)`` (empty dict when it has none)."""
    if entry.check is None:
        return {}
    return {str(k): float(v) for k, v in entry.check(diagram, context).items()}


def simulate_registered(
    name: str, *, scenario: Any = None, duration: float | None = None, meshcat: Any = None
) -> dict[str, float]:
    """Builds and simulates a registered diagram, then returns its check() figures.

    Args:
        name: a registered diagram name.
        scenario: None (defaults), a YAML file path, or a scenario instance.
        duration: simulated seconds (default: the registered duration).
        meshcat: optional Meshcat to watch the run on (the builder adds a visualizer).

    Returns:
        ``{"sim_time_s": final time, **check figures}``.

    Raises:
        UnknownNameError, ScenarioError, RepertoireError: bad name, scenario or duration
            (also a scenario's ``control_period`` longer than ``duration``).
        SimulationDivergedError: the state became non-finite.
    """
    entry = get_diagram_entry(name)
    duration = check_duration(entry.duration if duration is None else duration)
    scenario = resolve_scenario(entry, scenario, duration)
    diagram = build_registered(name, scenario=scenario, meshcat=meshcat)
    context = start_context(entry, diagram, scenario)
    _, context = simulate(diagram, duration, context=context, meshcat=meshcat)
    return {"sim_time_s": context.get_time(), **run_check(entry, diagram, context)}


class SimulatorCache:
    """One Simulator per diagram structure, reset between episodes instead of rebuilt.

    Episode studies run thousands of episodes of one world that differ only in
    start states and constant-source values; parsing the models and building
    the diagram can cost as much as a short episode. :meth:`get` builds a
    diagram the first time its structure key is asked for and afterwards resets
    it: time, every state and parameter copied from a new context of the
    diagram (also the plant's abstract step memory, which ``SetDefaultContext``
    keeps, so a new episode would otherwise see the last one's contacts), then
    the plant's positions and velocities from its defaults (which the caller
    sets for the episode), the named constant sources' values, the monitor
    cleared. A reset diagram runs bit for bit as a new one (tests in
    test_kitchen_world.py and test_action_dribble.py). Call
    ``simulator.Initialize()`` before advancing (after any change to the
    context). The context handed out is reset by the next :meth:`get` of the
    same key.
    """

    def __init__(self, build: Callable[[Any], Diagram], max_size: int = 8):
        """Creates an empty cache.

        Args:
            build: scenario -> the diagram (with a subsystem named ``plant``).
            max_size: diagrams kept (the oldest is dropped first).
        """
        if max_size < 1:
            raise RepertoireError(f"max_size must be >= 1, got {max_size}")
        self._build, self._max = build, max_size
        self._entries: dict[Any, tuple[Diagram, Simulator, Context]] = {}

    def __len__(self) -> int:
        return len(self._entries)

    def clear(self) -> None:
        """Forgets every diagram."""
        self._entries.clear()

    def get(
        self,
        key,
        scenario,
        set_plant_defaults: Callable[[Any], None],
        sources: dict[str, np.ndarray],
        *,
        reuse: bool = True,
    ) -> tuple[Diagram, Simulator]:
        """``(diagram, simulator)`` for ``scenario`` at time 0 in its start state.

        Args:
            key: hashable; equal keys must build equal diagrams up to the plant's
                default state and the ``sources`` values.
            scenario: passed to ``build`` when the key is new.
            set_plant_defaults: plant -> None, sets the plant's default positions
                and velocities for this episode.
            sources: ConstantVectorSource subsystem name -> its value.
            reuse: False builds a new diagram for the key (forgetting the old one).
        """
        if not reuse:
            self._entries.pop(key, None)
        if key not in self._entries:
            if len(self._entries) >= self._max:
                del self._entries[next(iter(self._entries))]
            diagram = self._build(scenario)
            self._entries[key] = (diagram, Simulator(diagram), diagram.CreateDefaultContext())
        diagram, simulator, pristine = self._entries[key]
        simulator.clear_monitor()
        context = simulator.get_mutable_context()
        context.SetTimeStateAndParametersFrom(pristine)
        plant = diagram.GetSubsystemByName("plant")
        set_plant_defaults(plant)
        plant_context = plant.GetMyMutableContextFromRoot(context)
        plant.SetDefaultState(plant_context, plant_context.get_mutable_state())
        for name, value in sources.items():
            source = diagram.GetSubsystemByName(name)
            value_in_context = source.get_mutable_source_value(
                source.GetMyMutableContextFromRoot(context)
            )
            value_in_context.SetFromVector(np.asarray(value, dtype=float))
        return diagram, simulator
