"""numba's on-disk cache, keyed by every source the compiled planner is built from.

numba's ``cache=True`` tells a stale cache entry by the time stamp and size of the one
file that defines the function. The search core inlines kernels from other modules
(:mod:`~repertoire.planning.footstep.fastcore` calls into ``fastkernels``, ``heuristic``
and ``footprint``), so an edit to a kernel alone would leave the old machine code in use
without a word. :func:`njit` puts the cache of every compiled planner function in a folder
named by a hash of all these sources (``__pycache__/numba-<key>`` beside them, or
``$NUMBA_CACHE_DIR/numba-<key>`` when that is set), so any edit to any of them compiles
afresh. Where that folder cannot be written numba falls back to its own locations.
"""

import functools
import hashlib
import os
from pathlib import Path

import numba

_HERE = Path(__file__).resolve().parent
SOURCES = (
    "fastcore.py",
    "fastkernels.py",
    "footprint.py",
    "heuristic.py",
    "jitcache.py",
    "reachability.py",
)
"""The files whose compiled functions call one another (this one included)."""


@functools.cache
def source_key(folder: Path = _HERE) -> str:
    """Hash (16 hex digits) of the contents of :data:`SOURCES` in ``folder``."""
    digest = hashlib.sha256()
    for name in SOURCES:
        digest.update(name.encode())
        digest.update((Path(folder) / name).read_bytes())
    return digest.hexdigest()[:16]


def cache_dir() -> Path:
    """The folder the compiled planner functions are cached in."""
    base = os.environ.get("NUMBA_CACHE_DIR") or _HERE / "__pycache__"
    return Path(base) / f"numba-{source_key()}"


def njit(**options):
    """``numba.njit(cache=True, **options)`` with the cache in :func:`cache_dir`."""

    def decorate(fn):
        saved = numba.config.CACHE_DIR
        numba.config.CACHE_DIR = str(cache_dir())
        try:
            return numba.njit(cache=True, **options)(fn)
        finally:
            numba.config.CACHE_DIR = saved

    return decorate


__all__ = ["SOURCES", "cache_dir", "njit", "source_key"]
