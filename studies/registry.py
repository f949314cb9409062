"""The registry of named Monte-Carlo studies.

A study is a config dataclass, a record dataclass and a module-level
``run_episode(config, seed) -> record`` that builds its own diagram from the
config. Each study module in ``repertoire.studies`` calls
:func:`register_study` at import; :func:`study_names` and :func:`get_study`
import every module of the package first (auto-discovery), so a study module
registers itself just by existing.

This module is imported by the engine and by every worker process, so it
imports nothing heavy (no pydrake, no dask).
"""

import dataclasses
import importlib
import sys
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

from repertoire.criteria import Bound
from repertoire.errors import RepertoireError, UnknownNameError
from repertoire.registry import add_entry, discover, lookup

# Modules of repertoire.studies that are the engine itself, not studies.
ENGINE_MODULES = frozenset(
    {"engine", "engine_dask", "engine_pool", "engine_summary", "store", "registry"}
)


@dataclasses.dataclass
class StudyEntry:
    """One registered study.

    Attributes:
        name: unique registered name (snake_case).
        description: one line for ``repertoire list``.
        config_type: the config dataclass ``run_episode`` takes.
        record_type: the record dataclass ``run_episode`` returns.
        run_episode: module-level ``run_episode(config, seed) -> record``.
        module: the importable module that defines ``run_episode`` (what
            worker processes import to rebuild the study).
        summarize: optional ``summarize(records, config, out_dir) -> {label: path}``
            that writes figures (PNG) or extra tables.
        demo_config: optional factory of the config ``repertoire demo`` runs.
        demo_episodes: how many episodes the demo runs.
        smoke_config: optional factory of a tiny config for tests.
        criteria: what a passing study looks like: summary figure name -> Bound
            (a summary figure is ``mean_<field>``, ``std_<field>``, ``min_<field>``,
            ``max_<field>`` of a numeric record field or ``rate_<field>`` of a bool
            one, over the demo's episodes; see engine.summary_figures).
    """

    name: str
    description: str
    config_type: type
    record_type: type
    run_episode: Callable[[Any, int], Any]
    module: str
    summarize: Callable[[list, Any, Path], dict[str, Path]] | None = None
    demo_config: Callable[[], Any] | None = None
    demo_episodes: int = 4
    smoke_config: Callable[[], Any] | None = None
    criteria: dict[str, Bound] = dataclasses.field(default_factory=dict)

    def default_config(self) -> Any:
        """The demo config if the study has one, otherwise ``config_type()``."""
        return self.demo_config() if self.demo_config is not None else self.config_type()

    def main(self, argv: list[str] | None = None) -> int:
        """Runs this study from the command line (``python -m <module>``).

        Returns:
            The process exit code (2 with a one-line message on bad input).
        """
        from repertoire.studies.engine import study_main

        doc = getattr(sys.modules.get(self.module), "__doc__", None) or self.description
        return study_main(self.name, argv, description=doc.split("\n\n")[0])

    def run_if_main(self, module_name: str) -> "StudyEntry":
        """Ends a study module: runs :meth:`main` and exits when the module is run as a script.

        A study module's last statement is ``register_study(...).run_if_main(__name__)``.

        Args:
            module_name: the calling module's ``__name__``.

        Returns:
            This entry (when the module was imported, not run).
        """
        if module_name == "__main__":
            from repertoire.interrupts import exit_process

            exit_process(self.main())
        return self


_REGISTRY: dict[str, StudyEntry] = {}
_LOADED = False
_IMPORT_FAILURES: dict[str, str] = {}


def register_study(
    name: str,
    *,
    config_type: type,
    record_type: type,
    run_episode: Callable[[Any, int], Any],
    description: str,
    summarize: Callable[[list, Any, Path], dict[str, Path]] | None = None,
    demo_config: Callable[[], Any] | None = None,
    demo_episodes: int = 4,
    smoke_config: Callable[[], Any] | None = None,
    criteria: dict[str, Bound] | None = None,
) -> StudyEntry:
    """Registers a study under ``name``.

    Args:
        name: unique study name.
        config_type: a plain (not frozen) dataclass, loadable with
            ``yaml_load_typed``.
        record_type: a dataclass whose fields are float/int/str/bool or
            lists/dicts of those. Fields named ``wall*_s`` are timing fields.
        run_episode: a module-level function ``(config, seed) -> record``,
            deterministic for a seed, that builds its own diagram.
        description: one line saying what the study measures.
        summarize: optional ``(records, config, out_dir) -> {label: path}``.
        demo_config: optional factory of the demo config.
        demo_episodes: number of episodes for the demo.
        smoke_config: optional factory of a tiny config for tests.
        criteria: optional summary figure name -> Bound a passing study meets
            (``repertoire demo`` holds the study's summary figures to them).

    Returns:
        The registered entry; end the module with ``.run_if_main(__name__)``.

    Raises:
        RepertoireError: non-dataclass types, a run_episode that workers cannot
            import by name, or a name registered twice by different modules.
    """
    if not isinstance(name, str) or not name:
        raise RepertoireError(f"study name must be a non-empty string, got {name!r}")
    for label, tp in (("config_type", config_type), ("record_type", record_type)):
        if not (isinstance(tp, type) and dataclasses.is_dataclass(tp)):
            raise RepertoireError(f"study '{name}': {label} must be a dataclass type, got {tp!r}")
    if not callable(run_episode):
        raise RepertoireError(f"study '{name}': run_episode must be callable")
    module = getattr(run_episode, "__module__", None)
    qualname = getattr(run_episode, "__qualname__", "")
    mod = sys.modules.get(module) if module else None
    if mod is None or "." in qualname or getattr(mod, qualname, None) is not run_episode:
        raise RepertoireError(
            f"study '{name}': run_episode must be a module-level function that worker "
            f"processes can import by name (got {module}.{qualname})"
        )
    if not isinstance(demo_episodes, int) or demo_episodes <= 0:
        raise RepertoireError(f"study '{name}': demo_episodes must be a positive int")
    entry = StudyEntry(
        name=name,
        description=description,
        config_type=config_type,
        record_type=record_type,
        run_episode=run_episode,
        module=module,
        summarize=summarize,
        demo_config=demo_config,
        demo_episodes=demo_episodes,
        smoke_config=smoke_config,
        criteria=dict(criteria or {}),
    )
    return add_entry("study", _REGISTRY, name, entry, lambda e: e.module)


def _load_all() -> None:
    """Imports every study module of repertoire.studies so that they register.

    A module that fails to import is reported with a warning and remembered, so
    one broken study does not hide the others; :func:`get_study` names it.
    """
    global _LOADED
    if _LOADED:
        return
    before = set(_IMPORT_FAILURES)
    discover("repertoire.studies", ENGINE_MODULES, _IMPORT_FAILURES)
    for module in sorted(set(_IMPORT_FAILURES) - before):
        warnings.warn(
            f"study module {module} failed to import: {_IMPORT_FAILURES[module]}", stacklevel=2
        )
    _LOADED = True


def broken_modules() -> dict[str, str]:
    """Study modules that failed to import, with the error each raised."""
    _load_all()
    return dict(_IMPORT_FAILURES)


def study_names() -> list[str]:
    """Sorted names of every registered study (after auto-discovery)."""
    _load_all()
    return sorted(_REGISTRY)


def get_study(name: str) -> StudyEntry:
    """Looks up a registered study (after auto-discovery).

    Raises:
        UnknownNameError: with the list of known names (and of study modules
            that failed to import, if any).
    """
    _load_all()
    return lookup("study", _REGISTRY, name, _IMPORT_FAILURES)


def lookup_in_module(module: str, name: str) -> StudyEntry:
    """Imports ``module`` and returns the study ``name`` it registered.

    Used by worker processes: it imports only the one study module, not the
    whole package.

    Raises:
        UnknownNameError: the module did not register ``name``.
    """
    if name not in _REGISTRY or _REGISTRY[name].module != module:
        importlib.import_module(module)
    if name not in _REGISTRY:
        raise UnknownNameError(f"module {module} did not register a study named '{name}'")
    return _REGISTRY[name]
