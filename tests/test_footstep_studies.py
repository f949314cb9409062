"""Footstep studies: smoke configs through the study engine, records, summaries, validation."""

import dataclasses

import pytest
from repertoire.studies import footstep_dynamic, footstep_static
from repertoire.studies.engine import run_study

from repertoire.errors import RepertoireError


def _strip_wall(record) -> dict:
    return {k: v for k, v in dataclasses.asdict(record).items() if not k.startswith("wall")}


def _smoke_run(name: str, config, episodes: int, tmp_path):
    """An inline run of a study through the engine, tables and figures into ``tmp_path``."""
    return run_study(
        name,
        config,
        episodes=episodes,
        store=tmp_path / f"{name}.sqlite",
        out_dir=tmp_path,
        executor="inline",
        progress=False,
    )


def test_static_study_smoke(tmp_path):
    cfg = footstep_static.smoke_config()
    result = _smoke_run("footstep_static", cfg, 3, tmp_path)
    assert [r.seed for r in result.records] == [0, 1, 2]
    for r in result.records:
        assert r.status in ("SUCCESS", "NODE_LIMIT", "UNREACHABLE")
        assert r.success == (r.status == "SUCCESS")
        assert r.biped_only == (r.success and not r.mobile2d_success)
        assert r.nodes_expanded <= cfg.max_expansions
    again = footstep_static.run_episode(cfg, 1)
    assert _strip_wall(again) == _strip_wall(result.records[1])
    table = (tmp_path / "footstep_static.md").read_text()
    assert "| footstep planner success |" in table and "| maps | 3 |" in table
    assert result.figures["examples"].stat().st_size > 0
    assert result.figures["distributions"].stat().st_size > 0
    assert result.figures["action_effects"].stat().st_size > 0
    assert result.figures["cut_off"].read_bytes()[:4] == b"\x89PNG"
    assert result.figures["anytime"].read_bytes()[:4] == b"\x89PNG"
    assert result.figures["anytime_maze"].read_bytes()[:4] == b"\x89PNG"
    assert result.figures["anytime_two_cores"].read_bytes()[:4] == b"\x89PNG"


def test_static_paper_setting_episode():
    # the paper's setting: 3 m floor, start and goal in opposite corners
    cfg = footstep_static.FootstepStaticConfig()
    around = footstep_static.run_episode(cfg, 0)  # the circle goes around, the biped steps over
    assert around.success and 10 <= around.steps <= 30 and around.steps_over >= 1
    assert around.mobile2d_success and around.mobile2d_length_m > 1.2 * around.body_path_m
    blocked = footstep_static.run_episode(cfg, 2)  # the circle cannot pass at all
    assert blocked.success and blocked.steps_over >= 1
    assert not blocked.mobile2d_success and blocked.biped_only


def test_dynamic_study_smoke(tmp_path):
    cfg = footstep_dynamic.smoke_config()
    result = _smoke_run("footstep_dynamic", cfg, 2, tmp_path)
    for r in result.records:
        assert not r.mobile2d_success  # the strings disconnect start and goal in 2-D
        assert r.success == (r.status == "SUCCESS")
        if r.success:
            assert r.steps_over >= 2 and r.arrival_s > 0
    table = (tmp_path / "footstep_dynamic.md").read_text()
    assert "| phase pairs | 2 |" in table
    assert "| receding horizon (100 expansions per round, 4 steps committed): success |" in table
    assert result.figures["distributions"].stat().st_size > 0


def test_dynamic_study_walks_the_scene_by_receding_horizon_too():
    # seed 4: one plan of 13 steps arrives at 10.4 s; rounds of 100 expansions committing
    # 4 steps each take 12 planner calls, 3 of which prove the end of a partial plan a trap
    # (a shorter prefix is committed), and arrive after 33 steps at 26.4 s
    r = footstep_dynamic.run_episode(footstep_dynamic.FootstepDynamicConfig(), 4)
    assert (r.status, r.steps, round(r.arrival_s, 6)) == ("SUCCESS", 13, 10.4)
    assert (r.receding_status, r.receding_success, r.receding_steps) == ("SUCCESS", True, 33)
    assert round(r.receding_arrival_s, 6) == 26.4
    assert (r.receding_rounds, r.receding_dead_end_rounds) == (12, 3)
    off = dataclasses.replace(footstep_dynamic.smoke_config(), receding_round_expansions=0)
    none = footstep_dynamic.run_episode(off, 0)
    assert (none.receding_status, none.receding_rounds) == ("", 0)


def test_dynamic_study_records_why_a_plan_stops_short():
    # grids ending at 4 s: too short a horizon to cross both rows, and the record says so
    cfg = dataclasses.replace(footstep_dynamic.smoke_config(), horizon_s=4.0)
    r = footstep_dynamic.run_episode(cfg, 0)
    assert r.status == "UNREACHABLE" and not r.success
    assert "past the environment's last grid" in r.reason and "extend t_end" in r.reason
    assert footstep_dynamic.run_episode(footstep_dynamic.smoke_config(), 0).reason == ""


def test_study_configs_validate():
    with pytest.raises(RepertoireError, match="size_m must be > 0"):
        footstep_static.FootstepStaticConfig(size_m=-1.0).validate()
    with pytest.raises(RepertoireError, match="n_strips must be >= 0"):
        footstep_static.FootstepStaticConfig(n_strips=-1).validate()
    with pytest.raises(RepertoireError, match="no gap"):
        footstep_dynamic.FootstepDynamicConfig(block_length_m=1.5).validate()
    with pytest.raises(RepertoireError, match="grid_dt_s must be > 0"):
        footstep_dynamic.FootstepDynamicConfig(grid_dt_s=0.0).validate()
    with pytest.raises(RepertoireError, match="receding_round_expansions must be >= 0, got -1"):
        footstep_dynamic.FootstepDynamicConfig(receding_round_expansions=-1).validate()
    with pytest.raises(RepertoireError, match="receding_execute_steps must be >= 1, got 0"):
        footstep_dynamic.FootstepDynamicConfig(receding_execute_steps=0).validate()


def test_planner_rows_say_so_when_no_plan_succeeded():
    # with no successful plan the steps rows read "nan [0, 0]" and "nan" before
    from types import SimpleNamespace

    from repertoire.studies._footstep_common import NONE_OK, planner_rows

    def rec(success, steps):
        return SimpleNamespace(
            success=success, steps=steps, steps_over=1, nodes_expanded=10, wall_plan_time_s=0.5
        )

    kw = dict(steps_label="steps", steps_over_label="over", time_digits=2)
    failed = planner_rows([rec(False, 0), rec(False, 0)], **kw)
    assert failed["success"][1] == "0/2 (0.0 %)"
    assert failed["steps"][1] == NONE_OK and failed["steps_over"][1] == NONE_OK
    mixed = planner_rows([rec(True, 12), rec(False, 0), rec(True, 20)], **kw)
    assert mixed["steps"][1] == "16 [12, 20]" and mixed["steps_over"][1] == "1.00"
