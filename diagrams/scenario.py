"""Typed scenario loading shared by every diagram builder.

Scenario dataclasses follow Drake's ``yaml_load_typed`` rules: plain
``dataclasses.dataclass`` (not frozen), list fields instead of tuples, and no
``from __future__ import annotations`` in the module that defines them.
"""

import dataclasses
from pathlib import Path
from typing import TypeVar

from pydrake.common.yaml import yaml_dump_typed, yaml_load_typed

from repertoire.errors import ScenarioError

T = TypeVar("T")


def load_scenario(
    schema: type[T],
    *,
    filename: str | Path | None = None,
    data: str | None = None,
    defaults: T | None = None,
    what: str = "scenario",
) -> T:
    """Loads a typed scenario from a YAML file or string; unknown keys are errors.

    Args:
        schema: the scenario dataclass type.
        filename: a YAML file to read (exactly one of ``filename`` and ``data``).
        data: YAML text.
        defaults: values for keys the YAML omits (default: ``schema()``).
        what: what the file is called in messages ("scenario" or "config").

    Raises:
        ScenarioError: missing file, malformed YAML, unknown keys, wrong types
            (a wrong type names its field).
    """
    if (filename is None) == (data is None):
        raise ScenarioError("load_scenario needs exactly one of filename= or data=")
    if not dataclasses.is_dataclass(schema):
        raise ScenarioError(f"scenario schema must be a dataclass type, got {schema!r}")
    if filename is not None and not Path(filename).is_file():
        state = "is a folder, not a file" if Path(filename).is_dir() else "does not exist"
        raise ScenarioError(f"{what} file '{filename}' {state}")
    if defaults is None:
        defaults = schema()
    try:
        kwargs = dict(schema=schema, defaults=defaults, allow_yaml_with_no_schema=False)
        if filename is not None:
            scenario = yaml_load_typed(filename=str(filename), **kwargs)
        else:
            scenario = yaml_load_typed(data=data, **kwargs)
    except Exception as e:  # pydrake raises RuntimeError / yaml.YAMLError / TypeError
        where = f"{what} file '{filename}'" if filename is not None else f"{what} YAML text"
        text = Path(filename).read_text(errors="replace") if filename is not None else data
        reason = _wrong_field(schema, text) or str(e)
        raise ScenarioError(
            f"could not load {schema.__name__} from {where}: {reason}. Expected keys: "
            f"{[f.name for f in dataclasses.fields(schema)]}"
        ) from e
    validate = getattr(scenario, "validate", None)
    if callable(validate):
        validate()
    return scenario


_SCALARS = {int: "a whole number", float: "a number", bool: "true or false", str: "a string"}


def _fits(tp: type, value) -> bool:
    if tp is int:
        return isinstance(value, int) and not isinstance(value, bool)
    if tp is float:
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    return isinstance(value, tp)


def _wrong_field(schema: type, text: str | None) -> str | None:
    """Names the first top-level scalar field whose YAML value has the wrong type.

    Drake's loader says ``invalid literal for int()`` without the field; this
    finds it. Returns None when no such field is found (the loader's message
    then stands).
    """
    try:
        import yaml

        raw = yaml.safe_load(text or "")
    except Exception:
        return None
    if not isinstance(raw, dict):
        return None
    for field in dataclasses.fields(schema):
        if field.name in raw and field.type in _SCALARS and not _fits(field.type, raw[field.name]):
            value = raw[field.name]
            return (
                f"field '{field.name}' expects {_SCALARS[field.type]} ({field.type.__name__}), "
                f"got {value!r} ({type(value).__name__})"
            )
    return None


def dump_scenario(scenario) -> str:
    """Returns the YAML text of a scenario dataclass (round-trips through load_scenario)."""
    return yaml_dump_typed(scenario)
