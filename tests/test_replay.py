"""Simulation helpers and HTML replays (self-contained, loads in headless Chromium)."""

import gc
import math
import re
import shutil
import subprocess
import sys
import urllib.request

import numpy as np
import pytest
from conftest import PendulumScenario, build_pendulum
from pydrake.geometry import Meshcat
from pydrake.systems.framework import BasicVector, DiagramBuilder, LeafSystem
from repertoire.diagrams.replay import record_replay
from repertoire.diagrams.simulate import (
    MAX_DURATION_S,
    MAX_RECORDED_FRAMES,
    RECORDING_FPS,
    SimulationDivergedError,
    check_duration,
    nonfinite_derivative_systems,
    nonfinite_state_systems,
    recording_fps,
    simulate,
    simulate_registered,
)
from scipy.integrate import solve_ivp

from repertoire.errors import RepertoireError, ScenarioError, UnknownNameError

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
needs_chromium = pytest.mark.skipif(
    CHROMIUM is None, reason="chromium is not installed (make test installs it when root)"
)

# The test pendulum: 1 kg box of side 0.1 m whose centre is 0.5 m below the pin.
MASS, ARM, SIDE, G = 1.0, 0.5, 0.1, 9.81
I_PIN = MASS * (ARM**2 + SIDE**2 / 6.0)


class Multiplier(LeafSystem):
    """x[n+1] = factor * x[n] every ``period`` seconds; no ports."""

    def __init__(self, factor: float, period: float = 0.01):
        super().__init__()
        self._factor = factor
        self.DeclareDiscreteState(BasicVector([1.0]))
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)

    def _update(self, context, discrete_state):
        x = context.get_discrete_state_vector().GetAtIndex(0)
        discrete_state.get_mutable_vector().SetAtIndex(0, self._factor * x)


def diverging_diagram():
    """Two multipliers: "steady" (x -> x) and "blowup" (x -> 1e100 x).

    Updates happen at t = 0, 0.01, 0.02, ...; the 4th (at t = 0.03) overflows to inf,
    so the state is first non-finite at the end of that step, t = 0.04.
    """
    builder = DiagramBuilder()
    builder.AddNamedSystem("steady", Multiplier(1.0))
    builder.AddNamedSystem("blowup", Multiplier(1e100))
    diagram = builder.Build()
    diagram.set_name("diverging")
    return diagram


def pendulum_angle_closed_form(theta0: float, t: float) -> float:
    """Angle of the rigid pendulum I theta'' = -m g L sin(theta), released at rest."""
    sol = solve_ivp(
        lambda _, y: [y[1], -MASS * G * ARM / I_PIN * math.sin(y[0])],
        (0.0, t),
        [theta0, 0.0],
        rtol=1e-10,
        atol=1e-12,
    )
    return float(sol.y[0, -1])


def test_simulate_pendulum_follows_the_rigid_pendulum_ode():
    diagram = build_pendulum(PendulumScenario(angle=0.5))
    simulator, context = simulate(diagram, 0.5)
    assert context.get_time() == pytest.approx(0.5)
    plant = diagram.GetSubsystemByName("plant")
    angle = plant.GetJointByName("pin").get_angle(plant.GetMyContextFromRoot(context))
    assert angle == pytest.approx(pendulum_angle_closed_form(0.5, 0.5), abs=0.01)
    # Simulating again continues from the same context for another `duration`.
    _, context = simulate(diagram, 0.25, context=context)
    assert context.get_time() == pytest.approx(0.75)


def test_nan_state_stops_the_run_and_names_the_system_and_time():
    diagram = diverging_diagram()
    with pytest.raises(
        SimulationDivergedError,
        match=r"state of ::diverging::blowup became non-finite .* at t = 0\.04 s",
    ):
        simulate(diagram, 1.0)
    context = diagram.CreateDefaultContext()
    assert nonfinite_state_systems(diagram, context) == []
    diagram.GetSubsystemByName("steady").GetMyMutableContextFromRoot(
        context
    ).get_mutable_discrete_state_vector().SetAtIndex(0, np.nan)
    assert nonfinite_state_systems(diagram, context) == ["::diverging::steady"]


def test_nan_time_derivative_stops_the_run_and_names_the_system():
    """A NaN rate with finite states: Drake's RK3 alone would shrink its step forever."""
    from pydrake.systems.primitives import ConstantVectorSource, Integrator

    inner = DiagramBuilder()
    integrator = inner.AddSystem(Integrator(2))  # unnamed, inside an unnamed diagram
    inner.ExportInput(integrator.get_input_port(0))
    inner_diagram = inner.Build()
    builder = DiagramBuilder()
    nested = builder.AddSystem(inner_diagram)
    source = builder.AddNamedSystem("rate", ConstantVectorSource([1.0, np.nan]))
    builder.Connect(source.get_output_port(0), nested.get_input_port(0))
    diagram = builder.Build()
    diagram.set_name("nan_rate")
    path = integrator.GetSystemPathname()
    assert path.startswith("::nan_rate::") and path.endswith(integrator.get_name())
    with pytest.raises(SimulationDivergedError) as error:
        simulate(diagram, 1.0)
    assert str(error.value) == (
        f"diagram 'nan_rate' diverged: the time derivative of {path} became non-finite "
        "(NaN/inf) at t = 0 s of a run to t = 1 s. Check gains, time step and initial "
        "conditions."
    )
    assert nonfinite_derivative_systems(diagram, diagram.CreateDefaultContext()) == [path]


@pytest.mark.parametrize("duration", [0.0, -1.0, math.nan, math.inf, "abc"])
def test_bad_duration_is_refused(duration):
    with pytest.raises(RepertoireError, match="duration must be a"):
        simulate(build_pendulum(PendulumScenario()), duration)


def test_duration_above_one_simulated_hour_is_refused_before_any_step():
    assert MAX_DURATION_S == 3600.0
    assert check_duration(MAX_DURATION_S) == 3600.0
    assert check_duration("12.5") == 12.5
    diagram = build_pendulum(PendulumScenario())
    for duration in (3600.001, 1e12):
        with pytest.raises(RepertoireError, match=r"duration must be at most 3600 s .* got "):
            simulate(diagram, duration)
    with pytest.raises(RepertoireError, match=r"at most 3600 s .* got 1e\+12"):
        record_replay(build_pendulum, 1e12, None, live=True)  # refused before any Meshcat


def test_long_recordings_keep_a_bounded_number_of_frames(monkeypatch):
    """Up to 2 minutes at 64 frames per second; a longer run at fewer, the same count."""
    assert (RECORDING_FPS, MAX_RECORDED_FRAMES) == (64.0, 7680)
    assert recording_fps(0.2) == recording_fps(120.0) == 64.0
    assert recording_fps(240.0) == 32.0
    assert recording_fps(3600.0) == pytest.approx(7680 / 3600)
    # A pendulum recorded for 4 s, with room for 64 frames (16 per second) and at the full
    # rate: the capped replay is the smaller file.
    import repertoire.diagrams.simulate as sim

    sizes = []
    for frames in (64, MAX_RECORDED_FRAMES):
        monkeypatch.setattr(sim, "MAX_RECORDED_FRAMES", frames)
        meshcat = Meshcat()
        diagram = build_pendulum(PendulumScenario(), meshcat=meshcat)
        simulate(diagram, 4.0, meshcat=meshcat, record=True)
        animation = meshcat.get_mutable_recording()
        assert animation.frames_per_second() == min(64.0, frames / 4.0)
        assert animation.frame(4.0) == min(256, frames)
        sizes.append(len(meshcat.StaticHtml()))
        del diagram, meshcat
        gc.collect()  # destroy the Meshcat on this thread (see record_replay)
    assert sizes[0] < sizes[1]


def test_bad_simulate_options_are_refused():
    diagram = build_pendulum(PendulumScenario())
    with pytest.raises(RepertoireError, match="record=True needs meshcat="):
        simulate(diagram, 0.1, record=True)
    with pytest.raises(RepertoireError, match="realtime_rate must be finite and >= 0"):
        simulate(diagram, 0.1, realtime_rate=-1.0)
    with pytest.raises(RepertoireError, match="does not belong to diagram 'test_pendulum'"):
        simulate(diagram, 0.1, context=diverging_diagram().CreateDefaultContext())
    with pytest.raises(RepertoireError, match="needs a pydrake Diagram, got str"):
        simulate("test_pendulum", 0.1)


def test_simulate_registered_returns_check_figures(isolated_registry, tmp_path):
    figures = simulate_registered("test_pendulum")
    assert set(figures) == {"sim_time_s", "angle_rad", "energy_J"}
    assert figures["sim_time_s"] == pytest.approx(0.2)
    assert figures["angle_rad"] == pytest.approx(pendulum_angle_closed_form(0.5, 0.2), abs=0.01)
    scenario = tmp_path / "down.yaml"
    scenario.write_text("angle: 0.0\n")
    figures = simulate_registered("test_pendulum", scenario=scenario, duration=0.1)
    assert figures["sim_time_s"] == pytest.approx(0.1)
    assert figures["angle_rad"] == pytest.approx(0.0, abs=1e-9)
    assert figures["energy_J"] == pytest.approx(-MASS * G * ARM, abs=1e-6)  # at rest, hanging


def test_simulate_registered_bad_input(isolated_registry, tmp_path):
    with pytest.raises(UnknownNameError, match=r"unknown diagram 'nope'.*\['test_pendulum'\]"):
        simulate_registered("nope")
    bad = tmp_path / "bad.yaml"
    bad.write_text("angle: 0.1\nlength: 2.0\n")
    with pytest.raises(ScenarioError, match="length"):
        simulate_registered("test_pendulum", scenario=bad)
    with pytest.raises(ScenarioError, match="does not exist"):
        simulate_registered("test_pendulum", scenario=tmp_path / "missing.yaml")
    with pytest.raises(RepertoireError, match="takes a PendulumScenario scenario"):
        simulate_registered("test_pendulum", scenario=42)
    with pytest.raises(RepertoireError, match="duration must be"):
        simulate_registered("test_pendulum", duration=-0.5)


def assert_self_contained(html: str) -> None:
    """No tag of the page fetches anything over the network."""
    tags = re.findall(r"<(?:script|link|img|iframe|source|video|audio)\b[^>]*>", html, re.I)
    assert tags, "the replay has no script tags at all"
    for tag in tags:
        assert not re.search(r"""(?:src|href)\s*=\s*["']?(?:https?:)?//""", tag, re.I), tag
    assert not re.search(r"""@import\s+(?:url\()?["']?(?:https?:)?//""", html)


def run_chromium(tmp_path, url: str, *args: str) -> subprocess.CompletedProcess:
    """Headless Chromium with every host name unresolvable (so nothing reaches a network)."""
    cmd = [
        CHROMIUM,
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--enable-unsafe-swiftshader",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--host-resolver-rules=MAP * ~NOTFOUND",
        f"--user-data-dir={tmp_path / 'chromium-profile'}",
        "--virtual-time-budget=4000",
        "--window-size=800,600",
        *args,
        url,
    ]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120)


def test_replay_html_is_self_contained(isolated_registry, tmp_path):
    html_path = tmp_path / "replays" / "pendulum.html"
    result = record_replay("test_pendulum", None, html_path)
    assert result.html_path == html_path
    assert result.sim_time_s == pytest.approx(0.2)
    assert set(result.figures) == {"angle_rad", "energy_J"}
    html = html_path.read_text()
    assert_self_contained(html)
    assert "three" in html.lower() and "animation" in html.lower()


@needs_chromium
def test_replay_loads_and_draws_in_headless_chromium(tmp_path):
    html_path = tmp_path / "pendulum.html"
    record_replay(
        lambda meshcat: build_pendulum(PendulumScenario(), meshcat=meshcat), 0.3, html_path
    )
    url = html_path.resolve().as_uri()
    dom = run_chromium(tmp_path, url, "--dump-dom")
    assert dom.returncode == 0, dom.stderr[-2000:]
    # meshcat's viewer created its three.js canvas and its controls pane, and has the
    # recorded animation (play/pause controls) loaded.
    assert re.search(r'<canvas data-engine="three\.js', dom.stdout)
    assert 'class="dg main' in dom.stdout
    for control in ("play", "pause", "reset", "timeScale"):
        assert f'class="property-name">{control}<' in dom.stdout
    shot = tmp_path / "replay.png"
    run = run_chromium(tmp_path, url, f"--screenshot={shot}")
    assert run.returncode == 0 and shot.is_file(), run.stderr[-2000:]
    import matplotlib.image

    rgb = matplotlib.image.imread(shot)[..., :3]
    red = (rgb[..., 0] > 0.5) & (rgb[..., 1] < 0.3) & (rgb[..., 2] < 0.3)
    assert red.sum() > 20, "the red pendulum bob is not visible in the screenshot"


def test_live_view_serves_the_scene_on_localhost(isolated_registry):
    fetched = {}

    def printer(line: str) -> None:
        if "live view at" in line and not fetched:
            url = re.search(r"(http://[\w.]+:\d+)", line).group(1)
            with urllib.request.urlopen(url, timeout=10) as response:
                fetched["status"] = response.status
                fetched["body"] = response.read().decode("utf-8", "replace")

    meshcat = Meshcat()
    result = record_replay(
        "test_pendulum", 0.05, None, meshcat=meshcat, live=True, live_seconds=0.2, printer=printer
    )
    assert result.html_path is None and result.web_url == meshcat.web_url()
    assert fetched["status"] == 200 and "meshcat" in fetched["body"].lower()


def test_record_replay_bad_input(isolated_registry, tmp_path):
    with pytest.raises(RepertoireError, match="needs html_path=, live=True or meshcat="):
        record_replay("test_pendulum", 0.1, None)
    with pytest.raises(RepertoireError, match="builder function needs a duration"):
        record_replay(
            lambda meshcat: build_pendulum(PendulumScenario(), meshcat=meshcat),
            None,
            tmp_path / "x.html",
        )
    with pytest.raises(RepertoireError, match="registered diagram name or a builder function"):
        record_replay(42, 0.1, tmp_path / "x.html")
    with pytest.raises(UnknownNameError, match="test_pendulum"):
        record_replay("nope", 0.1, tmp_path / "x.html")
    with pytest.raises(RepertoireError, match="returned int, expected a pydrake Diagram"):
        record_replay(lambda meshcat: 3, 0.1, tmp_path / "x.html")
    assert list(tmp_path.iterdir()) == []


def test_camera_frames_the_moving_bodies():
    from repertoire.diagrams.replay import camera_for, moving_body_positions

    assert camera_for(np.zeros((0, 3))) is None
    assert camera_for(np.array([[0.0, 0.0, np.nan]])) is None
    camera, target = camera_for(np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]))
    np.testing.assert_allclose(target, [0.5, 0.0, 0.0])
    assert np.linalg.norm(camera - target) == pytest.approx(1.5 * 1.0 + 0.4)
    assert camera[0] > target[0] and camera[1] < target[1] and camera[2] > target[2]
    # A single point is framed as a 0.3 m scene.
    camera, target = camera_for(np.array([[0.0, 0.0, 1.0]]))
    assert np.linalg.norm(camera - target) == pytest.approx(1.5 * 0.3 + 0.4)
    diagram = build_pendulum(PendulumScenario())
    points = moving_body_positions(diagram, diagram.CreateDefaultContext())
    np.testing.assert_allclose(points, [[0.0, 0.0, 0.0]])  # the bob's frame is on the pin


@pytest.mark.parametrize(
    "scenario, match",
    [
        (
            PendulumScenario(angle=math.nan),
            r"state of ::test_pendulum::plant became non-finite "
            r"\(NaN/inf\) at t = 0 s",
        ),
        (PendulumScenario(torque=1e200), r"state of ::test_pendulum::plant became non-finite"),
        (PendulumScenario(torque=math.nan), r"stopped at t = 0 s on a NaN: .*actuation input"),
    ],
)
def test_plant_divergence_is_reported(scenario, match):
    with pytest.raises(SimulationDivergedError, match=match):
        simulate(build_pendulum(scenario), 1.0)


def test_replay_meshcat_is_released_on_the_calling_thread(tmp_path):
    # Drake aborts the process when a Meshcat is destroyed off the thread that made it;
    # record_replay must not leave its own Meshcat for a later garbage collection to
    # destroy on another thread. Run in a subprocess: the failure mode is an abort.
    code = (
        "import gc, threading\n"
        "from repertoire.diagrams.replay import record_replay\n"
        f"record_replay('arm_hold', 0.02, {str(tmp_path / 'r.html')!r})\n"
        "worker = threading.Thread(target=gc.collect)\n"
        "worker.start()\n"
        "worker.join()\n"
        "print('survived')\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 0, result.stderr[-2000:]
    assert "survived" in result.stdout
