"""The execution study's summary rows: runs without a measured landing do not count as 0 m."""

import dataclasses

import pytest
from repertoire.studies.footstep_execution import FootstepExecutionRecord, execution_rows


def _record(seed, **learned) -> FootstepExecutionRecord:
    fields = {f.name: 0 for f in dataclasses.fields(FootstepExecutionRecord)}
    fields.update(
        seed=seed, learned_status="SUCCESS", nominal_status="", wall_time_s=1.0,
        learned_fell=False, learned_reached=False, nominal_fell=False, nominal_reached=False,
    )  # fmt: skip
    fields.update({f"learned_{k}": v for k, v in learned.items()})
    return FootstepExecutionRecord(**fields)


def test_rows_leave_runs_without_landings_out_of_the_error_figures():
    walked = _record(
        1, steps=10, executed=10, within=9, mean_err_m=0.01, max_err_m=0.03,
        step_err_m=0.002, reached=True,
    )  # fmt: skip
    fell_at_once = _record(2, steps=12, executed=0, fell=True, status="TIME_LIMIT")
    rows = execution_rows([walked, fell_at_once], ("learned",))["learned"]
    # before: the fallen run entered as a perfect 0 m (mean 0.005, median max 0.015)
    assert rows["mean_landing_error_m"] == pytest.approx(0.01)
    assert rows["median_max_landing_error_m"] == pytest.approx(0.03)
    assert rows["mean_step_error_m"] == pytest.approx(0.002)
    assert rows["runs_without_landings"] == 1 and rows["runs_fell"] == 1
    assert rows["steps"] == 22 and rows["steps_within_2cm_5deg"] == pytest.approx(9 / 22)
    assert rows["runs_reached_goal_without_fall"] == 0.5 and rows["plans_success"] == 1
    none = execution_rows([fell_at_once], ("learned",))["learned"]
    assert none["mean_landing_error_m"] is None and none["median_max_landing_error_m"] is None
    assert execution_rows([], ("learned",))["learned"]["runs"] == 0
