"""Typed scenario loading shared by every diagram builder.

Scenario dataclasses follow Drake's ``yaml_load_typed`` rules: plain
``dataclasses.dataclass`` (not frozen), list fields instead of tuples, and no
``from __future__ import annotations`` in the module that defines them.
"""

import dataclasses
import typing
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
        path = Path(filename)
        if path.is_dir():
            state = "is a folder, not a file"
        else:  # /dev/null, a pipe: not "does not exist"
            state = "is not a regular file" if path.exists() else "does not exist"
        raise ScenarioError(f"{what} file '{filename}' {state}")
    if defaults is None:
        defaults = schema()
    text = Path(filename).read_text(errors="replace") if filename is not None else data
    where = f"{what} file '{filename}'" if filename is not None else f"{what} YAML text"
    duplicate = _duplicate_key(text)
    if duplicate:
        raise ScenarioError(f"could not load {schema.__name__} from {where}: {duplicate}")
    if _is_empty_document(text):
        # Blank or only comments (every line of `repertoire show` commented out): every key
        # is left out, so every value is the default. The loader refused such a file
        # ("YAML root was a <class 'NoneType'>").
        filename, data = None, "{}"
    try:
        kwargs = dict(schema=schema, defaults=defaults, allow_yaml_with_no_schema=False)
        if filename is not None:
            scenario = yaml_load_typed(filename=str(filename), **kwargs)
        else:
            scenario = yaml_load_typed(data=data, **kwargs)
    except Exception as e:  # pydrake raises RuntimeError / yaml.YAMLError / TypeError
        reason = _wrong_field(schema, text) or " ".join(str(e).split())  # one line
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
    """Whether Drake's ``yaml_load_typed`` takes YAML scalar ``value`` for a ``tp`` field.

    Its rules: the same type; an int for a float; a whole float for an int; a string
    that ``float()`` / ``int()`` parses for a number (safe_load reads ``1e-3`` and
    ``"0.4"`` as strings); ``"true"`` / ``"false"`` for a bool. A field it takes must
    never be blamed for another field's error.
    """
    if type(value) is tp:
        return True
    if tp is float and type(value) is int:
        return True
    if tp is int and type(value) is float:
        return value.is_integer()
    if tp in (float, int) and type(value) is str:
        try:
            tp(value)
        except ValueError:
            return False
        return True
    return tp is bool and value in ("true", "false")


def _wrong_field(schema: type, text: str | None) -> str | None:
    """Names the first field (nested ones too) whose YAML value has the wrong type or keys.

    Drake's loader says ``invalid literal for int()`` or ``'int' object is not
    iterable`` without the field, and names an unknown key of a nested mapping
    without saying where it is; this finds it. Returns None when no such
    field is found (the loader's message then stands).
    """
    try:
        import yaml

        raw = yaml.safe_load(text or "")
    except Exception:
        return None
    if not isinstance(raw, dict):
        return None
    return _mismatch(schema, raw, "")


def _mismatch(tp, value, where: str) -> str | None:
    """Says how ``value`` (plain YAML data at field path ``where``) does not fit type ``tp``."""
    got = f"got {value!r} ({type(value).__name__})"
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if tp in _SCALARS:
        if _fits(tp, value):
            return None
        return f"field '{where}' expects {_SCALARS[tp]} ({tp.__name__}), {got}"
    if dataclasses.is_dataclass(tp):
        if not isinstance(value, dict):
            return f"field '{where}' expects a mapping of {tp.__name__} fields, {got}"
        names = [f.name for f in dataclasses.fields(tp)]
        unknown = [k for k in value if k not in names]
        if unknown and where:  # the loader names nested unknown keys but not where they are
            return f"field '{where}' has unknown keys {unknown}; {tp.__name__} expects {names}"
        for field in dataclasses.fields(tp):
            if field.name in value:
                inner = f"{where}.{field.name}" if where else field.name
                reason = _mismatch(field.type, value[field.name], inner)
                if reason:
                    return reason
        return None
    if origin is list:
        if not isinstance(value, list):
            return f"field '{where}' expects a list, {got}"
        items = ((f"{where}[{i}]", v) for i, v in enumerate(value))
    elif origin is dict:
        if not isinstance(value, dict):
            return f"field '{where}' expects a mapping, {got}"
        items = ((f"{where}.{k}", v) for k, v in value.items())
    else:
        return None
    item_type = args[-1] if args else None
    for inner, v in items:
        reason = _mismatch(item_type, v, inner)
        if reason:
            return reason
    return None


def _is_empty_document(text: str | None) -> bool:
    """True for YAML text that holds no value at all (blank, or only comments)."""
    try:
        import yaml

        return yaml.compose(text or "", Loader=yaml.SafeLoader) is None
    except Exception:  # malformed: the loader's message stands
        return False


def _duplicate_key(text: str | None) -> str | None:
    """Names the first key given twice in one YAML mapping (the loader keeps only the last).

    Returns None when there is none, or when the text does not parse (the loader's
    message then stands).
    """
    try:
        import yaml

        nodes = [yaml.compose(text or "", Loader=yaml.SafeLoader)]
    except Exception:
        return None
    while nodes:
        node = nodes.pop()
        if isinstance(node, yaml.MappingNode):
            seen = set()
            for key, value in node.value:
                if isinstance(key, yaml.ScalarNode) and key.value != "<<":
                    if key.value in seen:
                        return (
                            f"key '{key.value}' is given twice (again on line "
                            f"{key.start_mark.line + 1}); give each key once"
                        )
                    seen.add(key.value)
                nodes.append(value)
        elif isinstance(node, yaml.SequenceNode):
            nodes.extend(node.value)
    return None


def dump_scenario(scenario) -> str:
    """Returns the YAML text of a scenario dataclass (round-trips through load_scenario)."""
    return yaml_dump_typed(scenario)
