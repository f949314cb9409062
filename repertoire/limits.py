"""Resource limits checked before work starts.

A grid sized from user input (a map size, a resolution, a number of headings)
can ask for more memory than the machine has; allocating it would run until
the kernel kills the process. :func:`require_memory` refuses such a request
up front, with the figure, in the project's exception type.
"""

import os

from repertoire.errors import RepertoireError

# Default ceiling for one allocation request: 4 GiB, or REPERTOIRE_MAX_MEMORY_BYTES.
DEFAULT_LIMIT_BYTES = 4 * 1024**3


class ResourceLimitError(RepertoireError):
    """A request would exceed a resource limit (memory); the message gives the figure."""


def memory_limit_bytes() -> int:
    """The per-request memory ceiling: ``REPERTOIRE_MAX_MEMORY_BYTES`` or 4 GiB."""
    raw = os.environ.get("REPERTOIRE_MAX_MEMORY_BYTES")
    if raw is None:
        return DEFAULT_LIMIT_BYTES
    try:
        value = int(raw)
    except ValueError:
        raise ResourceLimitError(
            f"REPERTOIRE_MAX_MEMORY_BYTES={raw!r} is not a whole number of bytes"
        ) from None
    if value <= 0:
        raise ResourceLimitError(f"REPERTOIRE_MAX_MEMORY_BYTES={value} must be positive")
    return value


def format_bytes(nbytes: float) -> str:
    """``1536`` -> ``'1.5 KiB'``; binary units up to TiB."""
    value = float(nbytes)
    for unit in ("B", "KiB", "MiB", "GiB"):
        if abs(value) < 1024.0:
            return f"{value:.1f} {unit}" if unit != "B" else f"{int(value)} B"
        value /= 1024.0
    return f"{value:.1f} TiB"


def require_memory(nbytes: float, what: str, *, limit_bytes: int | None = None) -> None:
    """Raises ResourceLimitError when ``nbytes`` exceeds the limit.

    Args:
        nbytes: the estimated size of the allocation.
        what: what would be allocated, with the inputs that size it (for
            example ``"occupancy grid for map_size=1000 m at 0.025 m"``).
        limit_bytes: the ceiling; default :func:`memory_limit_bytes`.

    Raises:
        ResourceLimitError: naming ``what``, the estimate and the limit.
    """
    limit = memory_limit_bytes() if limit_bytes is None else int(limit_bytes)
    if nbytes > limit:
        raise ResourceLimitError(
            f"{what} would need about {format_bytes(nbytes)}, over the "
            f"{format_bytes(limit)} limit (set REPERTOIRE_MAX_MEMORY_BYTES to change it)"
        )


# Conservative bytes per cell of a footstep grid: float64 x 40 layers (terrain,
# cost, obstacle distance and the per-heading maps a planner keeps).
GRID_BYTES_PER_CELL = 8 * 40


def require_grid_memory(size_m: float, resolution_m: float, what: str) -> None:
    """Refuses a square grid of side ``size_m`` at ``resolution_m`` above the memory limit.

    Args:
        size_m: side of the square map [m].
        resolution_m: cell side [m] (> 0).
        what: the input that sized it, for example ``"biped_walk map_size=1000"``.

    Raises:
        ResourceLimitError: the estimate (cells x GRID_BYTES_PER_CELL) exceeds the limit.
    """
    cells = (float(size_m) / float(resolution_m)) ** 2
    require_memory(
        cells * GRID_BYTES_PER_CELL,
        f"a {size_m:g} m grid at {resolution_m:g} m cells ({cells:.3g} cells) for {what}",
    )


def _probe_folder(folder, shown, what: str) -> None:
    """Creates and removes a file in ``folder``; raises RepertoireError when that fails.

    Permission bits do not tell (root may write anywhere they forbid; /proc and
    read-only mounts refuse even root), so the folder is tried for real.
    """
    import tempfile

    try:
        fd, probe = tempfile.mkstemp(dir=folder, prefix=".repertoire-write-probe-")
    except OSError as e:
        reason = e.strerror or type(e).__name__
        raise RepertoireError(
            f"{what} '{shown}': cannot write in folder '{folder}' (creating a file there "
            f"failed: {reason})"
        ) from None
    os.close(fd)
    os.unlink(probe)


def path_argument(text: str):
    """An argparse ``type=`` for path options: the text as a Path, refusing an empty one.

    ``Path("")`` is the current folder, so ``--out-dir "$OUT"`` with ``OUT`` unset would
    scatter a study's store, tables and figures into wherever the command ran.

    Raises:
        argparse.ArgumentTypeError: ``text`` is empty or only whitespace.
    """
    import argparse
    from pathlib import Path

    if not text.strip():
        raise argparse.ArgumentTypeError(
            f"empty path {text!r}; give a folder or file name ('.' for the current folder)"
        )
    return Path(text)


def require_writable_dir(path, what: str) -> None:
    """Checks, before any work, that ``path`` is or can become a writable folder.

    Nothing is created: the nearest existing folder is probed with a file that
    is removed at once.

    Args:
        path: the output folder (may not exist yet).
        what: the option that named it, for example ``"--out-dir"``.

    Raises:
        RepertoireError: ``path`` or one of its parents is a file, or a file
            cannot be created in the nearest existing folder.
    """
    from pathlib import Path

    p = Path(path)
    for parent in (p, *p.parents):
        if parent.exists():
            if not parent.is_dir():
                raise RepertoireError(f"{what} '{p}': '{parent}' is a file, expected a folder")
            _probe_folder(parent, p, what)
            return


def require_writable_file(path, what: str, *, folder_too: bool = False) -> None:
    """Checks, before any work, that ``path`` can be written as a file.

    Args:
        path: the file (may not exist yet).
        what: the option that named it, for example ``"--store"``.
        folder_too: an existing file's folder must be writable as well (an
            SQLite file in WAL mode: its ``-wal`` and ``-shm`` files go there).

    Raises:
        RepertoireError: ``path`` is a folder, an existing file that cannot be
            opened for writing, or its folder cannot be written.
    """
    from pathlib import Path

    p = Path(path)
    if p.is_dir():
        raise RepertoireError(f"{what} '{p}' is a folder, expected a file path")
    if p.exists():
        try:
            with p.open("ab"):  # appends nothing: contents and size stay as they were
                pass
        except OSError as e:
            raise RepertoireError(
                f"{what} '{p}' is not writable ({e.strerror or type(e).__name__})"
            ) from None
        if folder_too:
            _probe_folder(p.parent, p, what)
        return
    require_writable_dir(p.parent, what)
