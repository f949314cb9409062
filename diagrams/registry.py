"""A registry of named diagrams.

Each world module in ``repertoire.diagrams`` registers its builders with
:func:`register_diagram`. A builder has the signature
``build(scenario, *, meshcat=None) -> pydrake.systems.framework.Diagram`` and
returns a Diagram whose name is the registered name. The CLI (``repertoire
list | render | simulate``) and the demo work only through this registry.
"""

import dataclasses
from collections.abc import Callable
from typing import Any

from repertoire.criteria import Bound
from repertoire.registry import add_entry, discover, lookup


@dataclasses.dataclass
class DiagramEntry:
    """One registered diagram.

    Attributes:
        name: unique registered name (snake_case), also the Diagram's name.
        description: one line for ``repertoire list``.
        scenario_type: the typed Scenario dataclass the builder takes.
        build: ``build(scenario, *, meshcat=None) -> Diagram``.
        duration: default simulated seconds for ``simulate`` and the demo.
        check: optional ``check(diagram, context) -> dict[str, float]`` run after
            a simulation; returns named figures (for example a height error).
        criteria: what a passing run looks like: figure name -> Bound on the
            figures ``check`` returns (see repertoire.criteria).
        initialize: optional ``initialize(diagram, context, scenario)`` that sets the
            scenario's start values a Diagram cannot hold as defaults (velocities) in a
            new root context, before a simulation of the world starts.
    """

    name: str
    description: str
    scenario_type: type
    build: Callable[..., Any]
    duration: float = 1.0
    check: Callable[..., dict] | None = None
    criteria: dict[str, Bound] = dataclasses.field(default_factory=dict)
    initialize: Callable[..., None] | None = None


_REGISTRY: dict[str, DiagramEntry] = {}
_BROKEN: dict[str, str] = {}
_LOADED = False


def register_diagram(
    name: str,
    *,
    scenario_type: type,
    description: str,
    duration: float = 1.0,
    check: Callable[..., dict] | None = None,
    criteria: dict[str, Bound] | None = None,
    initialize: Callable[..., None] | None = None,
):
    """Decorator registering a diagram builder under ``name``.

    ``criteria`` (figure name -> Bound) says what a passing run of the world
    looks like, in terms of the figures ``check`` returns.

    Raises:
        RepertoireError: an empty name, or a name registered by two modules.
    """

    def decorator(build):
        entry = DiagramEntry(
            name, description, scenario_type, build, duration, check, dict(criteria or {}),
            initialize,
        )  # fmt: skip
        add_entry("diagram", _REGISTRY, name, entry, _owner)
        return build

    return decorator


def _owner(entry: DiagramEntry) -> str:
    """The module that registered ``entry`` (the builder's module)."""
    return f"{getattr(entry.build, '__module__', '?')}.{getattr(entry.build, '__qualname__', '?')}"


def _load_all() -> None:
    """Imports every module of repertoire.diagrams so that they register."""
    global _LOADED
    if _LOADED:
        return
    discover("repertoire.diagrams", (), _BROKEN)
    _LOADED = True


def broken_modules() -> dict[str, str]:
    """Diagram modules that failed to import, with the error each raised."""
    _load_all()
    return dict(_BROKEN)


def diagram_names() -> list[str]:
    """Sorted names of every registered diagram."""
    _load_all()
    return sorted(_REGISTRY)


def get_diagram_entry(name: str) -> DiagramEntry:
    """Looks up a registered diagram.

    Raises:
        UnknownNameError: with the list of known names.
    """
    _load_all()
    return lookup("diagram", _REGISTRY, name, _BROKEN)
