"""``repertoire show``: every registered world and study prints commented YAML that loads back."""

import re
from pathlib import Path

import pytest
from repertoire.diagrams.registry import diagram_names, get_diagram_entry
from repertoire.diagrams.scenario import load_scenario
from repertoire.studies.registry import get_study, study_names

from repertoire.cli import main
from repertoire.errors import ScenarioError
from repertoire.show import attribute_docs, show_text, undocumented_fields


def _schema_and_default(name: str):
    if name in diagram_names():
        entry = get_diagram_entry(name)
        return entry.scenario_type, entry.scenario_type()
    entry = get_study(name)
    return entry.config_type, entry.default_config()


@pytest.mark.parametrize("name", diagram_names() + study_names())
def test_show_prints_commented_yaml_that_loads_back_unchanged(name):
    schema, default = _schema_and_default(name)
    text = show_text(name)
    assert load_scenario(schema, data=text) == default
    assert undocumented_fields(schema) == []  # every field has a comment
    for field, doc in attribute_docs(schema).items():
        assert f"# {field}: {doc}\n{field}:" in text


def test_a_config_file_with_every_line_commented_out_loads_the_defaults(tmp_path):
    # Every key is left out, so every key keeps its default; the loader used to refuse
    # such a file ("YAML root was a <class 'NoneType'> but should have been a dict").
    entry = get_study("pendulum")
    commented = "".join(
        line if line.startswith("#") else f"# {line}"
        for line in show_text("pendulum").splitlines(keepends=True)
    )
    for text in (commented, "", "\n  \n", "# nothing\n"):
        path = tmp_path / "c.yaml"
        path.write_text(text)
        default = entry.default_config()
        loaded = load_scenario(entry.config_type, filename=path, defaults=default, what="config")
        assert loaded == default and loaded is not default
        assert load_scenario(entry.config_type, data=text) == entry.config_type()


def test_a_config_path_that_is_no_regular_file_is_named_as_such():
    entry = get_study("pendulum")
    with pytest.raises(ScenarioError, match=r"^config file '/dev/null' is not a regular file$"):
        load_scenario(entry.config_type, filename="/dev/null", what="config")


SHIPPED_CONFIGS = sorted((Path(__file__).parents[1] / "studies" / "configs").glob("*.yaml"))


@pytest.mark.parametrize("path", SHIPPED_CONFIGS, ids=[p.name for p in SHIPPED_CONFIGS])
def test_every_shipped_study_config_loads_for_the_study_its_comment_runs(path):
    # A field renamed in a study's config dataclass would otherwise break the file only
    # when someone runs the command in its comment.
    text = path.read_text()
    (name,) = set(re.findall(r"python -m repertoire\.studies\.(\w+)", text))
    entry = get_study(name)
    config = load_scenario(
        entry.config_type, filename=path, defaults=entry.default_config(), what="config"
    )
    assert isinstance(config, entry.config_type) and config != entry.default_config()


def test_attribute_docs_join_continuation_lines_and_stop_at_the_next_section():
    class Documented:
        """Summary.

        Attributes:
            a: first line
                continued.
            b (float): second [m].

        Raises:
            c: not a field.
        """

    assert attribute_docs(Documented) == {"a": "first line continued.", "b": "second [m]."}


def test_show_cli_prints_and_an_unknown_name_exits_2(capsys):
    assert main(["show", "pendulum"]) == 0
    assert "repertoire study pendulum --config FILE.yaml" in capsys.readouterr().out
    assert main(["show", "nope"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("repertoire show: error: unknown name 'nope'") and "pendulum" in err


def test_attribute_docs_include_fields_documented_on_a_base_dataclass():
    import dataclasses

    @dataclasses.dataclass
    class Base:
        """Base.

        Attributes:
            a: from the base [m].
            b: base doc.
        """

        a: float = 1.0
        b: float = 2.0

    @dataclasses.dataclass
    class Derived(Base):
        """Derived.

        Attributes:
            b: overridden doc.
            c: own field.
        """

        c: float = 3.0

    assert attribute_docs(Derived) == {
        "a": "from the base [m].",
        "b": "overridden doc.",
        "c": "own field.",
    }
    assert undocumented_fields(Derived) == []
