"""LittleDog in physics: a short recorded crossing, the closed-loop library diagram and the
two studies at smoke size through the study engine."""

import math

import numpy as np
import pytest
from repertoire.diagrams.littledog_demos import library_terrain, record_crossing
from repertoire.diagrams.littledog_library import (
    LittleDogLibraryScenario,
    build_littledog_library,
    check_littledog_library,
    crossing_logs,
    load_library,
)
from repertoire.diagrams.registry import get_diagram_entry
from repertoire.diagrams.simulate import simulate
from repertoire.planning.step_library import StepLibrary
from repertoire.studies import littledog_demos, littledog_execution
from repertoire.studies.engine import run_study

from repertoire.errors import RepertoireError, ScenarioError


@pytest.fixture(scope="module")
def short_library(tmp_path_factory):
    """The first three steps of terrain_a's 0-degree crossing, recorded in physics."""
    rec = record_crossing(library_terrain("terrain_a"), 0.0, max_steps=3)
    path = tmp_path_factory.mktemp("library") / "short"
    StepLibrary(rec.steps).save(path)
    return rec, str(path)


def test_recorded_crossing_steps(short_library):
    rec, _ = short_library
    assert [s.foot for s in rec.steps] == [2, 0, 3]  # lh, lf, rh: the crawl order
    assert rec.slip_m < 0.01 and not rec.fell and rec.min_clearance_m > 0.1
    for a, b in zip(rec.steps, rec.steps[1:]):
        # A step starts where the previous one ended, all four feet down.
        assert np.allclose(a.body_pose[-1], b.start_pose) and b.stance[0].all()
    moved = rec.steps[-1].start_feet[2, 0] - rec.steps[0].start_feet[2, 0]
    assert 0.03 < moved < 0.07  # the first lh step: 5/8 of the 7 cm stride (4.4 cm)


def test_library_diagram_replays_steps(short_library):
    _, path = short_library
    scenario = LittleDogLibraryScenario(library=path)
    diagram = build_littledog_library(scenario)
    _, context = simulate(diagram, 3.0)
    figures = check_littledog_library(diagram, context)
    logs = crossing_logs(diagram, context)
    assert figures["steps_started"] >= 2 and figures["fell"] == 0.0
    assert figures["min_clearance_m"] > 0.1 and figures["crossed"] == 0.0
    # The first step chosen is the library's first (the robot starts where it started).
    assert logs["step_log"][5, 0] == 0
    pos_err = np.linalg.norm(logs["body_log"][:, :3] - logs["ideal_log"][:, :3], axis=1)
    assert np.max(pos_err) < 0.02
    entry = get_diagram_entry("littledog_library")
    assert set(entry.criteria) == {"crossed", "min_clearance_m", "fell"}


def test_library_scenario_bad_input(tmp_path):
    with pytest.raises(ScenarioError, match="unknown library terrain 'nowhere'"):
        LittleDogLibraryScenario(terrain="nowhere").validate()
    with pytest.raises(ScenarioError, match="start_offset must be within"):
        LittleDogLibraryScenario(start_offset=[0.5, 0.0]).validate()
    with pytest.raises(ScenarioError, match="does not exist"):
        load_library(str(tmp_path / "missing"))


def test_demo_study_smoke(tmp_path):
    result = run_study(
        "littledog_demos",
        littledog_demos.smoke_config(),
        episodes=1,
        store=tmp_path / "demos.sqlite",
        out_dir=tmp_path,
        executor="inline",
        progress=False,
    )
    (record,) = result.records
    assert record.steps == 2 and record.moving_foot == [2, 0]
    assert len(record.start_feet) == 2 * 12 and record.slip_m < 0.01 and not record.fell
    assert result.figures["footholds"].is_file()
    assert "| terrain_a | 0 | 2 |" in result.figures["table"].read_text()


def test_execution_study_smoke(tmp_path, short_library):
    _, path = short_library
    config = littledog_execution.smoke_config()
    config.library = path
    result = run_study(
        "littledog_execution",
        config,
        episodes=1,
        store=tmp_path / "exec.sqlite",
        out_dir=tmp_path,
        executor="inline",
        progress=False,
    )
    (record,) = result.records
    assert abs(record.offset_x_m) <= 0.03 and abs(record.offset_yaw_deg) <= 10.0
    assert not record.success and math.isnan(record.time_to_cross_s)  # 2 s cannot cross
    assert len(record.integrators_m) == 12 * len(record.position_error_m)
    assert len(record.position_error_m) == len(record.position_error_ablation_m)
    assert set(result.figures) >= {"table", "pose_error", "integrators"}
    with pytest.raises(RepertoireError, match="max_offset_m"):
        littledog_execution.LittleDogExecutionConfig(max_offset_m=1.0).validate()


def test_body_state_sensor_matches_the_plant():
    from pydrake.math import RigidTransform, RollPitchYaw
    from pydrake.systems.framework import DiagramBuilder
    from repertoire.diagrams.littledog_worlds import (
        PlantSettings,
        add_littledog_on_terrain,
        world_foot_positions,
    )
    from repertoire.models.littledog import JOINT_NAMES, standing_configuration
    from repertoire.models.terrain import generate_board
    from repertoire.systems.littledog_sensors import BodyStateSensor

    builder = DiagramBuilder()
    q0 = standing_configuration(0.14)
    plant, _, instance = add_littledog_on_terrain(
        builder, generate_board(), [0, 0, 0.2, 0, 0, 0], q0, PlantSettings()
    )
    plant_context = plant.CreateDefaultContext()
    rng = np.random.default_rng(7)
    q = q0 + rng.uniform(-0.2, 0.2, 12)
    for name, v in zip(JOINT_NAMES, q):
        plant.GetJointByName(name, instance).set_angle(plant_context, v)
    rpy = [0.1, -0.05, 2.0]
    plant.SetFreeBodyPose(
        plant_context,
        plant.GetBodyByName("body"),
        RigidTransform(RollPitchYaw(rpy), [0.1, 0.2, 0.3]),
    )
    sensor = BodyStateSensor(plant, instance)
    context = sensor.CreateDefaultContext()
    sensor.state_input.FixValue(context, plant.GetPositionsAndVelocities(plant_context))
    assert np.allclose(sensor.body_pose_output.Eval(context), [0.1, 0.2, 0.3, *rpy])
    assert np.allclose(sensor.joint_angles_output.Eval(context), q)
    assert np.allclose(
        sensor.feet_output.Eval(context).reshape(4, 3), world_foot_positions(plant, plant_context)
    )
    with pytest.raises(ScenarioError, match="kp must be > 0"):
        PlantSettings(kp=[0.0, 1.0, 1.0]).validate()
