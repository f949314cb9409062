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
import pkgutil
import sys
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

from repertoire.errors import RepertoireError, UnknownNameError

# Modules of repertoire.studies that are the engine itself, not studies.
ENGINE_MODULES = frozenset({"engine", "store", "registry"})
_MAIN_MODULES = frozenset({"__main__", "__mp_main__"})


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

    def default_config(self) -> Any:
        """The demo config if the study has one, otherwise ``config_type()``."""
        return self.demo_config() if self.demo_config is not None else self.config_type()


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

    Returns:
        The registered entry.

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
    )
    old = _REGISTRY.get(name)
    if old is not None and old.module != module:
        if module in _MAIN_MODULES:
            # A study module run as a script registers again as __main__; keep
            # the importable registration that worker processes can rebuild.
            return old
        if old.module not in _MAIN_MODULES:
            raise RepertoireError(
                f"study name '{name}' registered twice, by {old.module} and {module}"
            )
    _REGISTRY[name] = entry
    return entry


def _load_all() -> None:
    """Imports every study module of repertoire.studies so that they register.

    A module that fails to import is reported with a warning and remembered, so
    one broken study does not hide the others; :func:`get_study` names it.
    """
    global _LOADED
    if _LOADED:
        return
    import repertoire.studies as pkg

    for info in pkgutil.iter_modules(pkg.__path__):
        if info.name.startswith("_") or info.name in ENGINE_MODULES:
            continue
        qualified = f"{pkg.__name__}.{info.name}"
        try:
            importlib.import_module(qualified)
        except Exception as e:  # a broken study must not hide the others
            _IMPORT_FAILURES[qualified] = f"{type(e).__name__}: {e}"
            warnings.warn(f"study module {qualified} failed to import: {e}", stacklevel=2)
    _LOADED = True


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
    if name not in _REGISTRY:
        msg = f"unknown study '{name}'; registered studies: {study_names()}"
        if _IMPORT_FAILURES:
            msg += f"; study modules that failed to import: {_IMPORT_FAILURES}"
        raise UnknownNameError(msg)
    return _REGISTRY[name]


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
