"""Tests of the pendulum example study against closed forms."""

import math

import pytest
from repertoire.studies.engine import comparable
from repertoire.studies.pendulum import (
    PendulumConfig,
    pendulum_inertia,
    run_episode,
    sample_episode,
    smoke_config,
    summarize,
    undamped_max_speed,
)

from repertoire.errors import RepertoireError


def test_inertia_and_undamped_peak_speed_closed_forms():
    config = PendulumConfig(length_m=0.5, mass_kg=2.0, bob_radius_m=0.1)
    assert pendulum_inertia(config) == pytest.approx(2.0 * 0.25 + 0.4 * 2.0 * 0.01)
    # Released horizontally: I w^2 / 2 = m g L.
    expected = math.sqrt(2.0 * 2.0 * 9.81 * 0.5 / pendulum_inertia(config))
    assert undamped_max_speed(config, math.pi / 2) == pytest.approx(expected)


def test_undamped_pendulum_keeps_its_energy_and_reaches_the_closed_form_peak_speed():
    config = PendulumConfig(damping_min=0.0, damping_max=0.0, duration_s=1.5, time_step_s=0.0)
    record = run_episode(config, seed=3)
    angle, damping = sample_episode(config, 3)
    assert (record.initial_angle_rad, record.damping) == (angle, 0.0)
    assert abs(record.energy_lost_j) < 1e-4
    assert record.max_speed_rad_s == pytest.approx(undamped_max_speed(config, angle), rel=1e-3)
    assert not record.lost_half_energy


def test_small_swings_lose_energy_as_exp_minus_b_t_over_i():
    b, duration = 0.05, 2.0
    config = PendulumConfig(
        max_initial_angle_rad=0.05,
        damping_min=b,
        damping_max=b,
        duration_s=duration,
        time_step_s=0.0,
    )
    record = run_episode(config, seed=1)
    expected = 1.0 - math.exp(-b * duration / pendulum_inertia(config))
    assert record.energy_lost_fraction == pytest.approx(expected, abs=0.02)
    assert record.energy_lost_j > 0


def test_episodes_are_deterministic_per_seed():
    config = smoke_config()
    first, again, other = run_episode(config, 5), run_episode(config, 5), run_episode(config, 6)
    assert comparable(first) == comparable(again)
    assert comparable(first) != comparable(other)
    assert "wall_time_s" not in comparable(first)
    angle, damping = sample_episode(config, 5)
    assert abs(angle) <= config.max_initial_angle_rad
    assert config.damping_min <= damping <= config.damping_max


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"length_m": 0.0}, r"length_m must be finite and > 0, got 0\.0"),
        ({"duration_s": float("nan")}, r"duration_s must be finite and > 0"),
        ({"max_initial_angle_rad": 4.0}, r"max_initial_angle_rad must be in \(0, pi\]"),
        ({"damping_min": -0.1}, r"0 <= damping_min <= damping_max"),
        ({"damping_max": math.inf}, r"damping_max < inf, got 0\.0, inf$"),
        ({"time_step_s": 5.0}, r"time_step_s must be in \[0, duration_s\)"),
    ],
)
def test_config_validation(changes, message):
    with pytest.raises(RepertoireError, match=message):
        PendulumConfig(**changes).validate()


def test_an_infinite_damping_in_a_config_file_is_bad_input_and_writes_nothing(tmp_path, capsys):
    # It used to pass validation; every episode then died in the damping draw
    # (OverflowError: a failed run, exit 1) and left a store behind.
    from repertoire.studies.engine import study_main

    config = tmp_path / "c.yaml"
    config.write_text("damping_max: .inf\n")
    out = tmp_path / "out"
    argv = ["pendulum", "--config", str(config), "-n", "1", "--executor", "inline"]
    assert study_main(None, [*argv, "--out-dir", str(out), "--no-progress"]) == 2
    assert capsys.readouterr().err == (
        "error: PendulumConfig needs 0 <= damping_min <= damping_max < inf, got 0.0, inf\n"
    )
    assert not out.exists()


def test_summarize_writes_the_scatter_png(tmp_path):
    config = smoke_config()
    records = [run_episode(config, s) for s in range(4)]
    figures = summarize(records, config, tmp_path)
    assert set(figures) == {"energy_vs_damping"}
    assert figures["energy_vs_damping"].read_bytes()[:4] == b"\x89PNG"
