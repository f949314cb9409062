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
) -> T:
    """Loads a typed scenario from a YAML file or string; unknown keys are errors.

    Args:
        schema: the scenario dataclass type.
        filename: a YAML file to read (exactly one of ``filename`` and ``data``).
        data: YAML text.
        defaults: values for keys the YAML omits (default: ``schema()``).

    Raises:
        ScenarioError: missing file, malformed YAML, unknown keys, wrong types.
    """
    if (filename is None) == (data is None):
        raise ScenarioError("load_scenario needs exactly one of filename= or data=")
    if not dataclasses.is_dataclass(schema):
        raise ScenarioError(f"scenario schema must be a dataclass type, got {schema!r}")
    if filename is not None and not Path(filename).is_file():
        raise ScenarioError(f"scenario file '{filename}' does not exist")
    if defaults is None:
        defaults = schema()
    try:
        kwargs = dict(schema=schema, defaults=defaults, allow_yaml_with_no_schema=False)
        if filename is not None:
            scenario = yaml_load_typed(filename=str(filename), **kwargs)
        else:
            scenario = yaml_load_typed(data=data, **kwargs)
    except Exception as e:  # pydrake raises RuntimeError / yaml.YAMLError / TypeError
        where = f"file '{filename}'" if filename is not None else "YAML text"
        raise ScenarioError(
            f"could not load {schema.__name__} from {where}: {e}. Expected keys: "
            f"{[f.name for f in dataclasses.fields(schema)]}"
        ) from e
    validate = getattr(scenario, "validate", None)
    if callable(validate):
        validate()
    return scenario


def dump_scenario(scenario) -> str:
    """Returns the YAML text of a scenario dataclass (round-trips through load_scenario)."""
    return yaml_dump_typed(scenario)
