import logging
import shutil
import xml.etree.ElementTree as ET

import pytest
from conftest import PendulumScenario, build_pendulum
from pydrake.systems.framework import DiagramBuilder
from repertoire.diagrams import render
from repertoire.diagrams.render import diagram_system_names, render_diagram

from repertoire.errors import RepertoireError

needs_dot = pytest.mark.skipif(
    shutil.which("dot") is None, reason="Graphviz 'dot' is not installed (apt-get install graphviz)"
)

SVG_NS = "{http://www.w3.org/2000/svg}"


def svg_texts(path) -> list[str]:
    """Every <text> string of an SVG file (what a viewer shows)."""
    root = ET.parse(path).getroot()
    return ["".join(t.itertext()) for t in root.iter(f"{SVG_NS}text")]


def nested_diagram():
    builder = DiagramBuilder()
    builder.AddSystem(build_pendulum(PendulumScenario()))
    diagram = builder.Build()
    diagram.set_name("outer")
    return diagram


@needs_dot
def test_svg_names_every_system_of_the_diagram(tmp_path):
    diagram = build_pendulum(PendulumScenario())
    result = render_diagram(diagram, tmp_path / "graphs" / "pendulum.svg")
    stem = tmp_path / "graphs" / "pendulum"
    assert result.files == {
        "dot": stem.with_suffix(".dot"),
        "svg": stem.with_suffix(".svg"),
        "png": stem.with_suffix(".png"),
    }
    assert result.skipped == [] and result.reason is None
    texts = svg_texts(result.files["svg"])
    names = diagram_system_names(diagram)
    assert names == ["plant", "scene_graph", "torque_source"]
    for name in [*names, "test_pendulum"]:
        assert f"name={name}" in texts, name
    for system_class in ("MultibodyPlant", "SceneGraph", "ConstantVectorSource"):
        assert system_class in texts
    assert result.files["png"].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert result.files["dot"].read_text() == diagram.GetGraphvizString()


@needs_dot
def test_max_depth_limits_what_is_drawn(tmp_path):
    diagram = nested_diagram()
    shallow = svg_texts(render_diagram(diagram, tmp_path / "d1", max_depth=1).files["svg"])
    deep = svg_texts(render_diagram(diagram, tmp_path / "dall").files["svg"])
    assert "name=test_pendulum" in shallow and "name=scene_graph" not in shallow
    assert "name=test_pendulum" in deep and "name=scene_graph" in deep
    assert diagram_system_names(diagram, max_depth=0) == []  # the graph is one box
    leaf = diagram.GetSystems()[0].GetSystems()[0]
    with pytest.raises(RepertoireError, match="needs a pydrake Diagram, got MultibodyPlant"):
        diagram_system_names(leaf)  # was AttributeError: no attribute 'GetSystems'

    assert diagram_system_names(diagram, max_depth=1) == ["test_pendulum"]
    for bad in (-1, 1.5, True):
        with pytest.raises(
            RepertoireError, match=f"max_depth must be None or an integer >= 0, got {bad!r}"
        ):
            diagram_system_names(diagram, max_depth=bad)
    assert diagram_system_names(diagram) == [
        "test_pendulum",
        "plant",
        "scene_graph",
        "torque_source",
    ]


def test_a_depth_beyond_the_nesting_draws_everything_even_past_a_cpp_int():
    # --max-depth 99999999999 was a pybind TypeError traceback (Drake takes a C++ int)
    from repertoire.diagrams.render import graphviz_text

    diagram = nested_diagram()  # two levels: outer > test_pendulum > plant, ...
    everything = diagram.GetGraphvizString()
    assert graphviz_text(diagram, 1) != everything
    for depth in (2, 3, 2**31, 10**11):
        assert graphviz_text(diagram, depth) == everything
    assert graphviz_text(diagram.GetSystems()[0].GetSystems()[0], 2**40) == (
        diagram.GetSystems()[0].GetSystems()[0].GetGraphvizString()
    )


def test_without_dot_writes_dot_file_and_says_why(tmp_path, monkeypatch, caplog):
    empty_bin = tmp_path / "empty_bin"
    empty_bin.mkdir()
    monkeypatch.setenv("PATH", str(empty_bin))
    diagram = build_pendulum(PendulumScenario())
    with caplog.at_level(logging.WARNING, logger=render.__name__):
        result = render_diagram(diagram, tmp_path / "out" / "pendulum")
    assert result.files == {"dot": tmp_path / "out" / "pendulum.dot"}
    assert result.skipped == ["svg", "png"]
    assert "'dot' program is not on PATH" in result.reason
    assert "apt-get install graphviz" in result.reason
    assert "not on PATH" in caplog.text
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["pendulum.dot"]
    assert "name=plant" in result.files["dot"].read_text()
    assert "no svg/png" in result.describe()


@needs_dot
def test_dot_failure_keeps_dot_file_and_says_why(tmp_path, monkeypatch, caplog):
    def broken_parser(text):
        raise OSError("dot crashed")

    monkeypatch.setattr(render.pydot, "graph_from_dot_data", broken_parser)
    with caplog.at_level(logging.WARNING, logger=render.__name__):
        result = render_diagram(build_pendulum(PendulumScenario()), tmp_path / "p", formats=["svg"])
    assert list(result.files) == ["dot"] and result.skipped == ["svg"]
    assert result.reason == "the 'dot' program failed (OSError: dot crashed)"
    assert "dot crashed" in caplog.text


def test_only_dot_when_no_formats(tmp_path):
    result = render_diagram(build_pendulum(PendulumScenario()), tmp_path / "p", formats=())
    assert list(result.files) == ["dot"] and result.reason is None


@pytest.mark.parametrize(
    "out, written",
    [("run_0.5", "run_0.5.dot"), ("g.v2.svg", "g.v2.dot"), ("plain.dot", "plain.dot")],
)
def test_a_dot_in_the_output_stem_is_kept(tmp_path, out, written):
    result = render_diagram(build_pendulum(PendulumScenario()), tmp_path / out, formats=())
    assert result.files == {"dot": tmp_path / written}
    assert [p.name for p in tmp_path.iterdir()] == [written]


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(formats=["jpg"]), r"unknown image format\(s\) \['jpg'\]"),
        (dict(max_depth=-1), "max_depth must be None or an integer >= 0"),
        (dict(max_depth=1.5), "max_depth must be None or an integer >= 0"),
    ],
)
def test_bad_options_are_refused_and_write_nothing(tmp_path, kwargs, match):
    with pytest.raises(RepertoireError, match=match):
        render_diagram(build_pendulum(PendulumScenario()), tmp_path / "out" / "p", **kwargs)
    assert not (tmp_path / "out").exists()


def test_not_a_system_is_refused(tmp_path):
    with pytest.raises(RepertoireError, match="needs a pydrake System, got str"):
        render_diagram("test_pendulum", tmp_path / "p")
    assert list(tmp_path.iterdir()) == []
