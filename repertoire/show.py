"""``repertoire show NAME``: a world's default scenario or a study's default config as YAML.

Each top-level field is preceded by a comment with its documentation (and unit)
taken from the dataclass docstring's ``Attributes:`` section, so the printed
text is ready to edit and pass back with ``--scenario`` / ``--config``.
"""

import dataclasses
import inspect
import re
from typing import Any

from repertoire.errors import UnknownNameError

_SECTION = re.compile(r"^\s*(Attributes|Args|Returns|Raises|Example|Examples|Note|Notes):\s*$")
_FIELD = re.compile(r"^(\s*)([A-Za-z_][A-Za-z0-9_]*)(?:\s*\([^)]*\))?:\s*(.*)$")


def attribute_docs(schema: type) -> dict[str, str]:
    """Field name -> one-line doc from the ``Attributes:`` section of ``schema``'s docstring.

    Args:
        schema: a dataclass type with a Google-style docstring.

    Returns:
        The documented fields (continuation lines joined with spaces). Fields
        inherited from a base dataclass keep the base's documentation unless
        the subclass documents them again.
    """
    docs: dict[str, str] = {}
    for cls in reversed(inspect.getmro(schema)):
        own = cls.__dict__.get("__doc__")
        if cls is not object and own:
            docs.update(_docstring_attributes(inspect.cleandoc(own)))
    return docs


def _docstring_attributes(doc: str) -> dict[str, str]:
    """Field name -> doc from one docstring's ``Attributes:`` section."""
    docs: dict[str, str] = {}
    inside = False
    indent = None
    current = None
    for line in doc.splitlines():
        section = _SECTION.match(line)
        if section:
            inside = section.group(1) == "Attributes"
            indent, current = None, None
            continue
        if not inside:
            continue
        if not line.strip():
            continue
        m = _FIELD.match(line)
        width = len(line) - len(line.lstrip())
        if m and (indent is None or width == indent):
            indent = width
            current = m.group(2)
            docs[current] = m.group(3).strip()
        elif current is not None and indent is not None and width > indent:
            docs[current] = f"{docs[current]} {line.strip()}".strip()
        else:
            inside = False
    return docs


def undocumented_fields(schema: type) -> list[str]:
    """The fields of ``schema`` its docstring's ``Attributes:`` section does not document."""
    docs = attribute_docs(schema)
    return [f.name for f in dataclasses.fields(schema) if f.name not in docs]


def commented_yaml(value: Any, header: str) -> str:
    """``value`` (a scenario/config dataclass) as YAML with a comment above each field.

    Args:
        value: the dataclass instance to print.
        header: comment lines put first (how to use the file).

    Returns:
        YAML text that ``load_scenario(type(value), data=text)`` loads back equal to ``value``.
    """
    from repertoire.diagrams.scenario import dump_scenario

    docs = attribute_docs(type(value))
    lines = [f"# {h}" if h else "#" for h in header.splitlines()]
    for line in dump_scenario(value).splitlines():
        key = line.split(":", 1)[0]
        if line and not line[0].isspace() and key in docs:
            lines.append(f"# {key}: {docs[key]}")
        lines.append(line)
    return "\n".join(lines) + "\n"


def show_text(name: str) -> str:
    """The commented default YAML of the registered world or study ``name``.

    Raises:
        UnknownNameError: ``name`` is neither a registered diagram nor a study.
    """
    from repertoire.diagrams.registry import diagram_names, get_diagram_entry
    from repertoire.studies.registry import get_study, study_names

    if name in diagram_names():
        entry = get_diagram_entry(name)
        value, verb, option = entry.scenario_type(), "simulate", "--scenario"
    elif name in study_names():
        entry = get_study(name)
        value, verb, option = entry.default_config(), "study", "--config"
    else:
        raise UnknownNameError(
            f"unknown name '{name}'; registered diagrams: {diagram_names()}; "
            f"registered studies: {study_names()}"
        )
    header = (
        f"{name}: {entry.description}\n"
        f"Default {type(value).__name__}. Save, edit, then:\n"
        f"  repertoire {verb} {name} {option} FILE.yaml\n"
        "Keys you leave out keep these defaults; unknown keys are errors.\n"
    )
    return commented_yaml(value, header)


__all__ = ["attribute_docs", "commented_yaml", "show_text"]
