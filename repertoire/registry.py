"""The one registry mechanism behind registered diagrams and registered studies.

Both ``repertoire.diagrams.registry`` and ``repertoire.studies.registry`` keep
a name -> entry dict filled by modules that register themselves at import, and
discover those modules by importing every public module of their package. The
functions here are that shared mechanism, so both registries raise the same
errors with the same wording and discover modules the same way: a module that
fails to import is remembered (never hides the others) and named in the error
of a failed look-up and by ``broken_modules()``.

This module imports nothing heavy (worker processes import it).
"""

import importlib
import pkgutil
from collections.abc import Callable, Iterable, MutableMapping
from typing import Any

from repertoire.errors import RepertoireError, UnknownNameError
from repertoire.interrupts import check_interrupted

# A module run as a script (``python -m``) registers again under these names.
MAIN_MODULES = frozenset({"__main__", "__mp_main__"})


def add_entry(
    kind: str,
    entries: MutableMapping[str, Any],
    name: str,
    entry: Any,
    owner: Callable[[Any], str],
) -> Any:
    """Adds ``entry`` under ``name``; the same owner registering again replaces it.

    Args:
        kind: "diagram" or "study", for messages.
        entries: the registry's name -> entry dict.
        name: the name to register.
        entry: the entry.
        owner: entry -> the module that registered it.

    Returns:
        The entry now registered under ``name``: a module run as a script
        (``__main__``) keeps the importable registration that worker processes
        can rebuild.

    Raises:
        RepertoireError: an empty name, or a name registered by two modules.
    """
    if not isinstance(name, str) or not name:
        raise RepertoireError(f"{kind} name must be a non-empty string, got {name!r}")
    old = entries.get(name)
    if old is not None and owner(old) != owner(entry):
        if owner(entry) in MAIN_MODULES:
            return old
        if owner(old) not in MAIN_MODULES:
            raise RepertoireError(
                f"{kind} name '{name}' registered twice, by {owner(old)} and {owner(entry)}"
            )
    entries[name] = entry
    return entry


def discover(package: str, skip: Iterable[str], failures: MutableMapping[str, str]) -> None:
    """Imports every public module of ``package`` (not ``_x`` nor those in ``skip``).

    Args:
        package: the package whose modules register themselves at import.
        skip: module names that are not registrants (the engine itself).
        failures: filled with module -> "ExceptionType: message" for each
            module that failed to import.
    """
    pkg = importlib.import_module(package)
    skip = frozenset(skip)
    for info in pkgutil.iter_modules(pkg.__path__):
        if info.name.startswith("_") or info.name in skip:
            continue
        qualified = f"{package}.{info.name}"
        try:
            importlib.import_module(qualified)
        except Exception as e:  # one broken module must not hide the others
            check_interrupted()  # not broken: Ctrl-C landed in its import (pydrake's)
            failures[qualified] = f"{type(e).__name__}: {e}"


def lookup(kind: str, entries: dict[str, Any], name: str, failures: dict[str, str]) -> Any:
    """The entry registered as ``name``.

    Raises:
        UnknownNameError: with the registered names and the modules that failed
            to import, if any.
    """
    if name not in entries:
        msg = f"unknown {kind} '{name}'; registered {kind} names: {sorted(entries)}"
        if failures:
            msg += f"; {kind} modules that failed to import: {failures}"
        raise UnknownNameError(msg)
    return entries[name]
