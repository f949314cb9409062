"""Replay: record a simulation in Meshcat and save it as one self-contained HTML file.

``record_replay`` builds a diagram with a :class:`pydrake.geometry.Meshcat`
(builders add ``MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat)``
when given a meshcat), records the simulation, publishes the recording and
writes ``meshcat.StaticHtml()``: the three.js viewer, the scene and the
animation in one file that opens offline in any browser. On request it also
keeps a live view on localhost (``meshcat.web_url()``) until Ctrl-C or a timeout.
"""

import dataclasses
import gc
import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from pydrake.geometry import Meshcat
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import BodyIndex
from pydrake.systems.framework import Context, Diagram
from repertoire.diagrams.registry import get_diagram_entry
from repertoire.diagrams.simulate import (
    build_registered,
    check_duration,
    leaf_systems,
    resolve_scenario,
    run_check,
    simulate,
    start_context,
)

from repertoire.errors import RepertoireError


@dataclasses.dataclass
class ReplayResult:
    """What ``record_replay`` produced.

    Attributes:
        html_path: the self-contained HTML replay (None if not asked for).
        web_url: the live Meshcat URL used while recording.
        sim_time_s: final simulated time.
        figures: the registered world's check() figures (empty for a builder function).
    """

    html_path: Path | None
    web_url: str
    sim_time_s: float
    figures: dict[str, float]


def moving_body_positions(diagram: Diagram, context: Context) -> np.ndarray:
    """World positions (n x 3) of every body not welded to the world, over all plants.

    Args:
        diagram: a diagram containing MultibodyPlants.
        context: a context of ``diagram``.
    """
    points = []
    for system in leaf_systems(diagram):
        if not isinstance(system, MultibodyPlant):
            continue
        plant_context = system.GetMyContextFromRoot(context)
        welded = {b.index() for b in system.GetBodiesWeldedTo(system.world_body())}
        for i in range(system.num_bodies()):
            body = system.get_body(BodyIndex(i))
            if body.index() not in welded:
                points.append(system.EvalBodyPoseInWorld(plant_context, body).translation())
    return np.array(points).reshape(-1, 3)


def camera_for(points: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """A camera position and target that frame ``points`` (None if there are none).

    The camera looks at the centre of the points' bounding box from the front right,
    slightly above, at a distance that grows with the box size (at least 0.3 m).

    Args:
        points: n x 3 world positions.
    """
    if points.size == 0 or not np.all(np.isfinite(points)):
        return None
    low, high = points.min(axis=0), points.max(axis=0)
    target = 0.5 * (low + high)
    extent = max(float(np.linalg.norm(high - low)), 0.3)
    direction = np.array([1.0, -1.2, 0.6]) / np.linalg.norm([1.0, -1.2, 0.6])
    return target + (1.5 * extent + 0.4) * direction, target


def write_static_html(meshcat: Meshcat, html_path: str | Path) -> Path:
    """Writes ``meshcat.StaticHtml()`` (viewer, scene and recording in one file).

    Args:
        meshcat: the Meshcat holding the scene (and a published recording).
        html_path: the file to write; parent folders are created.
    """
    path = Path(html_path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(meshcat.StaticHtml(), encoding="utf-8")
    return path


def serve_live(
    meshcat: Meshcat, seconds: float | None = None, *, printer: Callable[[str], None] = print
) -> None:
    """Keeps the Meshcat server answering until Ctrl-C or ``seconds`` have passed.

    Args:
        meshcat: the Meshcat to keep alive.
        seconds: how long to serve (None = until Ctrl-C).
        printer: where to write the URL and instructions.
    """
    if seconds is not None and (not math.isfinite(seconds) or seconds < 0):
        raise RepertoireError(f"live seconds must be finite and >= 0, got {seconds!r}")
    until = "Ctrl-C" if seconds is None else f"Ctrl-C or {seconds:g} s"
    printer(
        f"serving {meshcat.web_url()} until {until} (press play in the Animation panel "
        f"to replay the recording)"
    )
    deadline = None if seconds is None else time.monotonic() + seconds
    try:
        while deadline is None or time.monotonic() < deadline:
            time.sleep(0.1 if deadline is None else min(0.1, max(0.0, deadline - time.monotonic())))
    except KeyboardInterrupt:
        printer("live view stopped")


def record_replay(
    source: str | Callable[..., Diagram],
    duration: float | None = None,
    html_path: str | Path | None = None,
    *,
    scenario: Any = None,
    meshcat: Meshcat | None = None,
    realtime_rate: float = 0.0,
    live: bool = False,
    live_seconds: float | None = None,
    frame_camera: bool = True,
    printer: Callable[[str], None] = print,
) -> ReplayResult:
    """Simulates a diagram while recording it in Meshcat and writes an HTML replay.

    Args:
        source: a registered diagram name, or a builder function called as
            ``source(meshcat=meshcat)`` that returns a Diagram with a MeshcatVisualizer.
        duration: simulated seconds (default: the registered duration; required for a
            builder function).
        html_path: where to write the self-contained HTML (None: no file; then give
            ``live=True`` or your own ``meshcat`` to look at).
        scenario: for a registered name: None, a YAML path or a scenario instance.
        meshcat: reuse this Meshcat (default: a new one on a free localhost port).
        realtime_rate: 0 = as fast as possible; 1 = wall clock (used for live views).
        live: after the run, print the URL and keep serving (see ``serve_live``).
        live_seconds: how long to keep the live view (None = until Ctrl-C).
        printer: where live-view messages go.
        frame_camera: point the camera at the bodies that move (not welded to the world),
            from their start and end positions, instead of Meshcat's default view.

    Returns:
        A ReplayResult (HTML path, URL, final time, check figures).

    Raises:
        UnknownNameError, ScenarioError, RepertoireError: bad name, scenario, duration,
            or neither an HTML path nor a live view asked for.
        SimulationDivergedError: the state became non-finite (the HTML is still written
            with the part that was recorded).
    """
    if html_path is None and not live and meshcat is None:
        raise RepertoireError(
            "record_replay needs html_path=, live=True or meshcat= (nothing to produce)"
        )
    entry = None
    if isinstance(source, str):
        entry = get_diagram_entry(source)
        duration = check_duration(entry.duration if duration is None else duration)
    elif callable(source):
        if duration is None:
            raise RepertoireError("record_replay with a builder function needs a duration")
        duration = check_duration(duration)
    else:
        raise RepertoireError(
            f"source must be a registered diagram name or a builder function, "
            f"got {type(source).__name__}"
        )

    def record(meshcat):
        return _record(
            entry,
            source,
            duration,
            html_path,
            scenario,
            meshcat,
            realtime_rate,
            live,
            live_seconds,
            frame_camera,
            printer,
        )

    if meshcat is not None:
        return record(meshcat)
    meshcat = Meshcat()
    try:
        return record(meshcat)
    finally:
        # pydrake keeps the diagram and its MeshcatVisualizer in a reference cycle, so the
        # Meshcat made here would be destroyed whenever the garbage collector next runs, on
        # whatever thread runs it; Drake aborts the process when a Meshcat is destroyed off
        # the thread that made it. Collect now, on this thread.
        del meshcat
        gc.collect()


def _record(
    entry,
    source,
    duration,
    html_path,
    scenario,
    meshcat,
    realtime_rate,
    live,
    live_seconds,
    frame_camera,
    printer,
) -> ReplayResult:
    """The body of :func:`record_replay`, with its arguments checked and a Meshcat."""
    if live:
        printer(
            f"live view at {meshcat.web_url()}: open it in a browser now; simulating "
            f"{duration:g} s at real-time rate {realtime_rate:g}"
        )
    if entry is not None:
        scenario = resolve_scenario(entry, scenario, duration)
        diagram = build_registered(entry.name, scenario=scenario, meshcat=meshcat)
    else:
        diagram = source(meshcat=meshcat)
        if not isinstance(diagram, Diagram):
            raise RepertoireError(
                f"the builder function returned {type(diagram).__name__}, "
                f"expected a pydrake Diagram"
            )
    context = start_context(entry, diagram, scenario) if entry is not None else None
    context = context if context is not None else diagram.CreateDefaultContext()
    start_points = moving_body_positions(diagram, context) if frame_camera else np.zeros((0, 3))
    written = None
    try:
        _, context = simulate(
            diagram,
            duration,
            context=context,
            meshcat=meshcat,
            record=True,
            realtime_rate=realtime_rate,
        )
        if frame_camera:
            camera = camera_for(np.vstack([start_points, moving_body_positions(diagram, context)]))
            if camera is not None:
                meshcat.SetCameraPose(*camera)
    finally:
        if html_path is not None:
            written = write_static_html(meshcat, html_path)
    figures = run_check(entry, diagram, context) if entry is not None else {}
    result = ReplayResult(written, meshcat.web_url(), context.get_time(), figures)
    if live:
        serve_live(meshcat, live_seconds, printer=printer)
    return result
