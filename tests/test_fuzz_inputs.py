"""Property-based bad-input suite (hypothesis): thousands of generated inputs, no traceback.

Each public entry point fed generated input must either return a valid result or
raise the project's exception type (RepertoireError, a ValueError) with a
message; never another exception, never a hang (every call is cheap and the
planner runs under a time limit and an expansion budget).

Examples per test: ``REPERTOIRE_FUZZ_EXAMPLES`` (default 120, kept small for
``make test``). With ``REPERTOIRE_FUZZ_REPORT=path.json`` the tests append what
they tried (inputs, outcomes, distinct messages) to that file.
"""

import dataclasses
import json
import math
import os
import re

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from repertoire.diagrams.registry import diagram_names, get_diagram_entry
from repertoire.diagrams.scenario import load_scenario
from repertoire.models.littledog.kinematics import nominal_foot_positions
from repertoire.models.terrain import TerrainParams, generate_board
from repertoire.planning.dmp_learn import learn_dmp
from repertoire.planning.footstep import (
    OccupancyGrid,
    PlannerOptions,
    nominal_action_table,
    plan_footsteps,
)
from repertoire.planning.footstep.height_map import height_map_from_board
from repertoire.planning.footstep.quadruped import CrawlParams, plan_crawl
from repertoire.studies.registry import get_study, study_names

from repertoire.cli import build_parser, main
from repertoire.errors import RepertoireError, SolverError

EXAMPLES = int(os.environ.get("REPERTOIRE_FUZZ_EXAMPLES", "120"))
FUZZ = settings(
    max_examples=EXAMPLES,
    deadline=None,
    derandomize=True,  # the same inputs every run: a test suite, not a lottery
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
    database=None,
)

SCHEMAS = {n: get_diagram_entry(n).scenario_type for n in diagram_names()} | {
    n: get_study(n).config_type for n in study_names()
}

_TALLY: dict[str, dict] = {}


def _record(test: str, outcome: str, message: str = "") -> None:
    """Counts one tried input of ``test`` and the shape of its error message."""
    t = _TALLY.setdefault(test, {"tried": 0, "outcomes": {}, "messages": set()})
    t["tried"] += 1
    t["outcomes"][outcome] = t["outcomes"].get(outcome, 0) + 1
    if message:
        # numbers and quoted values vary; the message's shape is what we count
        shape = re.sub(r"'[^']*'|-?\d+(\.\d+)?(e[-+]?\d+)?|\[[^\]]*\]", "_", message)[:160]
        t["messages"].add(shape)


@pytest.fixture(scope="module", autouse=True)
def _report():
    yield
    path = os.environ.get("REPERTOIRE_FUZZ_REPORT")
    if path:
        old = json.load(open(path)) if os.path.exists(path) else {}
        for test, t in _TALLY.items():
            old[test] = {
                "tried": t["tried"],
                "outcomes": t["outcomes"],
                "distinct_messages": len(t["messages"]),
                "messages": sorted(t["messages"]),
            }
        with open(path, "w") as fh:
            json.dump(old, fh, indent=1)


def _call(test: str, fn, *args, _solver_error_ok: bool = True, **kwargs):
    """Runs ``fn``; a RepertoireError with a message is fine, anything else fails the test.

    A SolverError (a program that did not solve, named with its solver) is accepted unless
    ``_solver_error_ok`` is False: then bad input must be refused before the solver runs.
    """
    try:
        result = fn(*args, **kwargs)
    except SolverError as e:
        if not _solver_error_ok:
            raise AssertionError(f"{test}: bad input reached the solver: {e}") from e
        assert str(e).strip(), f"{test}: SolverError without a message"
        _record(test, "SolverError", str(e))
        return None
    except RepertoireError as e:
        assert str(e).strip(), f"{test}: RepertoireError without a message"
        _record(test, "RepertoireError", str(e))
        return None
    _record(test, "ok")
    return result


# ---------------------------------------------------------------------------
# Scenario and config loaders: every registered world and study.

scalars = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(10**12), 10**12),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=12),
)
values = st.recursive(
    scalars,
    lambda inner: (
        st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner, max_size=3)
    ),
    max_leaves=8,
)


@st.composite
def yaml_documents(draw):
    name = draw(st.sampled_from(sorted(SCHEMAS)))
    schema = SCHEMAS[name]
    fields = [f.name for f in dataclasses.fields(schema)]
    kind = draw(st.sampled_from(["fields", "fields", "fields", "unknown_key", "garbage"]))
    if kind == "garbage":
        return name, draw(st.text(max_size=60))
    chosen = draw(st.lists(st.sampled_from(fields), min_size=1, max_size=3, unique=True))
    doc = {f: draw(values) for f in chosen}
    if kind == "unknown_key":
        doc[draw(st.text(min_size=1, max_size=8))] = draw(scalars)
    try:
        return name, yaml.safe_dump(doc)
    except yaml.YAMLError:
        return name, str(doc)


@FUZZ
@given(yaml_documents())
def test_scenario_and_config_loaders_reject_bad_yaml_clearly(case):
    name, text = case
    _call("scenario/config loaders", load_scenario, SCHEMAS[name], data=text)


_BAD_FOR = {int: "zero", float: "one point five", bool: [1, 2], str: [1, 2]}


@pytest.mark.parametrize("name", sorted(SCHEMAS))
def test_a_wrong_scalar_type_names_its_field(name):
    schema = SCHEMAS[name]
    for f in dataclasses.fields(schema):
        if f.type not in _BAD_FOR:
            continue
        with pytest.raises(RepertoireError) as e:
            load_scenario(schema, data=yaml.safe_dump({f.name: _BAD_FOR[f.type]}))
        _record("field-naming type errors", "RepertoireError", str(e.value))
        assert f"'{f.name}'" in str(e.value), str(e.value)


# ---------------------------------------------------------------------------
# The CLI's argument parser, and the cheap commands end to end.

TOKENS = [
    "list", "show", "render", "simulate", "study", "demo", "--out", "--scenario", "--config",
    "--duration", "--episodes", "-n", "--workers", "-j", "--executor", "dask", "process",
    "inline", "--scheduler", "--fresh", "--smoke", "--live", "--replay", "--live-seconds",
    "--max-depth", "--formats", "--first-seed", "--store", "--out-dir", "--quick", "-1", "0",
    "nan", "1e9", "pendulum", "biped_walk", "nope", "",
]  # fmt: skip


@FUZZ
@given(st.lists(st.sampled_from(TOKENS) | st.text(max_size=8), max_size=6))
def test_the_cli_parser_exits_2_with_usage_or_parses(argv):
    try:
        build_parser().parse_args(argv)
    except SystemExit as e:
        assert e.code in (0, 2), (argv, e.code)  # 0 only for --help
        _record("CLI argument parser", f"exit {e.code}")
        return
    _record("CLI argument parser", "parsed")


@FUZZ
@given(st.text(max_size=20))
def test_show_exits_0_or_2_for_any_name(name):
    try:
        code = main(["show", name])
    except SystemExit as e:  # argparse: a name that looks like an option is a usage error
        code = e.code
    assert code in (0, 2)
    assert code == 0 or name not in SCHEMAS
    _record("repertoire show NAME", f"exit {code}")


# ---------------------------------------------------------------------------
# The DMP learner.

finite_or_not = st.floats(allow_nan=True, allow_infinity=True, width=64)


@st.composite
def dmp_inputs(draw):
    n = draw(st.integers(0, 12))
    dof = draw(st.integers(0, 3))
    kind = draw(st.sampled_from(["good_t", "any_t"]))
    if kind == "good_t" and n > 0:
        t = np.cumsum(draw(st.lists(st.floats(1e-3, 1.0), min_size=n, max_size=n)))
    else:
        t = np.array(draw(st.lists(finite_or_not, min_size=n, max_size=n)), dtype=float)
    shape = draw(st.sampled_from(["match", "1d", "wrong"]))
    rows = n if shape != "wrong" else n + draw(st.integers(1, 3))
    vals = draw(st.lists(finite_or_not, min_size=rows * max(dof, 1), max_size=rows * max(dof, 1)))
    x = np.array(vals, dtype=float)
    x = x if shape == "1d" else x.reshape(rows, max(dof, 1))
    kwargs = {}
    if draw(st.booleans()):
        kwargs["n_basis"] = draw(st.integers(-2, 60) | st.sampled_from([1.5, "5", None]))
    if draw(st.booleans()):
        kwargs["K"] = draw(finite_or_not)
    if draw(st.booleans()):
        kwargs["alpha"] = draw(finite_or_not)
    if draw(st.booleans()):
        kwargs["formulation"] = draw(st.sampled_from(["new", "old", "bogus", ""]))
    if draw(st.booleans()):
        kwargs["ridge"] = draw(finite_or_not)
    if draw(st.booleans()):
        kwargs["derivatives"] = draw(st.sampled_from(["auto", "savgol", "gradient", "x"]))
    return t, x, kwargs


@FUZZ
@given(dmp_inputs())
def test_learn_dmp_rejects_bad_demonstrations_clearly(case):
    t, x, kwargs = case
    params = _call("learn_dmp", learn_dmp, t, x, _solver_error_ok=False, **kwargs)
    if params is not None:
        assert np.all(np.isfinite(np.asarray(params.weights))), "learned non-finite weights"


# ---------------------------------------------------------------------------
# The footstep planner's public entry point (tiny maps, a time limit and a budget).

coords = st.floats(-1.0, 3.0) | finite_or_not


@FUZZ
@given(
    size=st.tuples(st.floats(0.3, 2.0), st.floats(0.3, 2.0)),
    start=st.lists(coords, min_size=0, max_size=4),
    goal=st.lists(coords, min_size=0, max_size=3),
    foot=st.sampled_from(["left", "right", "middle", 0, 1, 7, None]),
    time_limit=st.sampled_from([0.05, 0.0, -1.0, math.nan]),
    max_expansions=st.sampled_from([200, 0, -5]),
)
def test_plan_footsteps_rejects_bad_requests_clearly(
    size, start, goal, foot, time_limit, max_expansions
):
    grid = OccupancyGrid.empty(size)

    def plan():
        options = PlannerOptions(time_limit=time_limit, max_expansions=max_expansions)
        return plan_footsteps(grid, start, foot, goal, nominal_action_table(), options)

    result = _call("plan_footsteps", plan)
    if result is not None:
        assert isinstance(result.succeeded, bool)


# ---------------------------------------------------------------------------
# The LittleDog crawl planner and its height map (small boards, a time limit and a budget).

_CRAWL_FIELDS = sorted(f.name for f in dataclasses.fields(CrawlParams))
_BOARD = generate_board(TerrainParams(kind="rocks", size_x=0.8, size_y=0.5), seed=3)


@FUZZ
@given(
    x_range=st.tuples(coords, coords) | values,
    y_range=st.tuples(coords, coords) | values,
    resolution=st.sampled_from([0.02, 0.0, -0.01, math.nan, "0.01", None, True, [0.01]]),
    board=st.sampled_from(["board", None, "text"]),
)
def test_height_map_from_board_rejects_bad_requests_clearly(x_range, y_range, resolution, board):
    terrain = {"board": _BOARD, None: None, "text": "text"}[board]
    result = _call("height_map_from_board", height_map_from_board, terrain, x_range, y_range,
                   resolution)  # fmt: skip
    if result is not None:
        assert np.all(np.isfinite(result.heights)) and result.resolution > 0


@FUZZ
@given(
    overrides=st.dictionaries(st.sampled_from(_CRAWL_FIELDS), values, max_size=2),
    resolution=st.sampled_from([0.01, 0.02]),
    shift=st.tuples(st.floats(-0.5, 0.5), st.floats(-0.2, 0.2)),
    start=st.none() | values,
    goal=st.tuples(coords, coords) | values,
    ground=st.sampled_from(["board", "map", "text"]),
)
def test_plan_crawl_rejects_bad_requests_clearly(overrides, resolution, shift, start, goal, ground):
    hm = height_map_from_board(_BOARD, (-0.45, 0.45), (-0.3, 0.3), resolution)
    if start is None:  # usually a stance (shifted), else generated garbage
        start = nominal_foot_positions()[:, :2] + np.asarray(shift)

    def plan():
        params = dataclasses.replace(CrawlParams(), **overrides)
        exact = {"board": _BOARD, "map": None, "text": "text"}[ground]
        return plan_crawl(hm, start, goal, params, time_limit=0.05, max_expansions=30, ground=exact)

    result = _call("plan_crawl", plan)
    if result is not None:
        assert result.status.name in ("SUCCESS", "UNREACHABLE", "NODE_LIMIT", "TIME_LIMIT")
        assert all(np.all(np.isfinite(s.p_WF)) for s in result.steps)
