"""Differential-drive robot, its worlds, the drive diagram and bad input."""

import math
from pathlib import Path

import numpy as np
import pytest
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.analysis import Simulator
from repertoire.diagrams.diffdrive import (
    MIN_RATIO_TRAVEL_M,
    TRACK,
    WHEEL_RADIUS,
    DiffDriveScenario,
    add_diffdrive,
    add_world,
    build_diffdrive_drive,
    check_diffdrive,
    check_wheel_speeds,
    twist_from_wheel_speeds,
    wheel_speeds_for_twist,
)
from repertoire.diagrams.registry import get_diagram_entry
from repertoire.diagrams.scenario import load_scenario

from repertoire.errors import RepertoireError, ScenarioError

SCENARIOS = Path(__file__).resolve().parents[1] / "diagrams" / "scenarios"


def test_robot_and_worlds_parse():
    plant = MultibodyPlant(1e-3)
    parser = Parser(plant)
    robot = add_diffdrive(plant, parser, wheel_kd=2.0)
    soccer = add_world(plant, parser, "soccer")
    kitchen_plant = MultibodyPlant(1e-3)
    kitchen = add_world(kitchen_plant, Parser(kitchen_plant), "kitchen")
    plant.Finalize()
    kitchen_plant.Finalize()
    context = plant.CreateDefaultContext()
    assert plant.CalcTotalMass(context, [robot]) == pytest.approx(9.0)
    assert plant.num_actuators() == 2
    names = {plant.GetModelInstanceName(m) for m in soccer}
    assert names == {"soccer_field", "goal_blue", "goal_yellow", "ball"}
    assert plant.GetBodyByName("ball").default_mass() == pytest.approx(0.43)
    names = {kitchen_plant.GetModelInstanceName(m) for m in kitchen}
    assert {"table_0", "table_1", "cup_0", "cup_4", "counter"} <= names
    assert add_world(plant, parser, "empty") == []


def test_twist_closed_forms():
    w = wheel_speeds_for_twist(0.5, 1.0)
    np.testing.assert_allclose(
        w, [(0.5 - TRACK / 2) / WHEEL_RADIUS, (0.5 + TRACK / 2) / WHEEL_RADIUS]
    )
    v, omega = twist_from_wheel_speeds(w)
    assert v == pytest.approx(0.5) and omega == pytest.approx(1.0)


def test_drives_straight_two_metres():
    scenario = load_scenario(DiffDriveScenario, filename=SCENARIOS / "diffdrive_empty.yaml")
    diagram = build_diffdrive_drive(scenario)
    simulator = Simulator(diagram)
    v, _ = twist_from_wheel_speeds(scenario.wheel_speeds)
    simulator.AdvanceTo(2.0 / v + 0.2)
    figures = check_diffdrive(diagram, simulator.get_context())
    assert figures["distance_m"] >= 2.0
    assert abs(figures["heading_change_deg"]) < 1.0
    assert 0.9 < figures["speed_ratio"] <= 1.0
    assert figures["tilt_rad"] < 0.01


def test_speed_ratio_is_not_reported_for_a_run_too_short_to_measure():
    scenario = load_scenario(DiffDriveScenario, filename=SCENARIOS / "diffdrive_empty.yaml")
    diagram = build_diffdrive_drive(scenario)
    simulator = Simulator(diagram)
    v, _ = twist_from_wheel_speeds(scenario.wheel_speeds)
    simulator.AdvanceTo(0.5 * MIN_RATIO_TRAVEL_M / v)  # half a centimetre of ideal travel
    figures = check_diffdrive(diagram, simulator.get_context())
    assert math.isnan(figures["speed_ratio"])
    assert math.isfinite(figures["distance_m"])


def test_ideal_displacement_is_the_chord_of_the_arc():
    from repertoire.diagrams.diffdrive import ideal_displacement, wrap_angle

    assert ideal_displacement(0.5, 0.0, 2.0) == 1.0
    assert ideal_displacement(-0.5, 0.0, 2.0) == 1.0
    # radius v / omega = 1 m, a half turn: the chord is the diameter
    assert ideal_displacement(1.0, 1.0, math.pi) == pytest.approx(2.0, rel=1e-15)
    assert ideal_displacement(1.0, -1.0, math.pi / 2) == pytest.approx(math.sqrt(2.0), rel=1e-15)
    assert ideal_displacement(1.0, 1.0, 2 * math.pi) == pytest.approx(0.0, abs=1e-15)
    assert wrap_angle(-5.0) == pytest.approx(2 * math.pi - 5.0, rel=1e-15)
    assert wrap_angle(0.25) == 0.25


def test_a_turning_run_is_judged_against_the_arc_and_wrapped_headings():
    # wheels 3 and 8 rad/s for 2 s: a 170 deg arc; against the path length |v| t a run
    # rolling well gave speed_ratio 0.66, now 0.98 (criterion 0.9-1.1); in-place turn [5, -5] for
    # 2 s: the ideal -339 deg was printed unwrapped beside the measured (wrapped) +57 deg
    scenario = DiffDriveScenario(world="empty", wheel_speeds=[3.0, 8.0])
    diagram = build_diffdrive_drive(scenario)
    simulator = Simulator(diagram)
    simulator.AdvanceTo(2.0)
    figures = check_diffdrive(diagram, simulator.get_context())
    v, omega = twist_from_wheel_speeds([3.0, 8.0])
    assert math.degrees(omega * 2.0) == pytest.approx(169.3, abs=0.05)
    assert figures["distance_m"] / (v * 2.0) < 0.7  # the old figure
    assert 0.9 < figures["speed_ratio"] <= 1.0
    diagram = build_diffdrive_drive(DiffDriveScenario(world="empty", wheel_speeds=[5.0, -5.0]))
    simulator = Simulator(diagram)
    simulator.AdvanceTo(2.0)
    figures = check_diffdrive(diagram, simulator.get_context())
    assert figures["expected_heading_change_deg"] == pytest.approx(
        math.degrees(2 * math.pi - 2.0 * 10.0 * WHEEL_RADIUS / TRACK), rel=1e-12
    )
    assert -180.0 <= figures["heading_change_deg"] <= 180.0
    assert math.isnan(figures["speed_ratio"])  # no forward speed: nothing to compare


@pytest.mark.parametrize("name", ["diffdrive_soccer.yaml", "diffdrive_kitchen.yaml"])
def test_worlds_simulate_one_second(name):
    scenario = load_scenario(DiffDriveScenario, filename=SCENARIOS / name)
    diagram = build_diffdrive_drive(scenario)
    simulator = Simulator(diagram)
    simulator.AdvanceTo(1.0)
    context = simulator.get_context()
    assert np.all(np.isfinite(context.get_discrete_state_vector().CopyToVector()))
    figures = check_diffdrive(diagram, context)
    # Measured (deterministic): 94% of the ideal rolling distance r (w_l + w_r) / 2 * 1 s.
    expected = {"diffdrive_soccer.yaml": 0.458957, "diffdrive_kitchen.yaml": 0.413271}[name]
    assert figures["distance_m"] == pytest.approx(expected, rel=1e-5)
    # Turning left when the right wheel is faster, at most the ideal rolling rate.
    if scenario.wheel_speeds[1] > scenario.wheel_speeds[0]:
        assert 0 < figures["heading_change_deg"] <= figures["expected_heading_change_deg"]
    assert get_diagram_entry("diffdrive_drive").build is build_diffdrive_drive


def test_bad_input():
    with pytest.raises(ScenarioError, match="unknown world 'moon'.*kitchen"):
        load_scenario(DiffDriveScenario, data="world: moon\n")
    with pytest.raises(ScenarioError, match="could not load"):
        load_scenario(DiffDriveScenario, data="world: [soccer\n")
    with pytest.raises(ScenarioError, match="could not load"):
        load_scenario(DiffDriveScenario, data="wheels: [1.0, 1.0]\n")
    with pytest.raises(ScenarioError, match="2 values"):
        load_scenario(DiffDriveScenario, data="wheel_speeds: [1.0, 1.0, 1.0]\n")
    with pytest.raises(ScenarioError, match="within"):
        build_diffdrive_drive(DiffDriveScenario(wheel_speeds=[100.0, 1.0]))
    with pytest.raises(ScenarioError, match="initial_pose"):
        build_diffdrive_drive(DiffDriveScenario(initial_pose=[0.0, 0.0]))
    with pytest.raises(RepertoireError, match="2 values"):
        check_wheel_speeds([1.0])
    with pytest.raises(RepertoireError, match="finite"):
        check_wheel_speeds([np.nan, 1.0])
