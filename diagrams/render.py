"""Rendering a Diagram's graph: Graphviz text from Drake, images through pydot.

``render_diagram`` always writes the ``.dot`` text of
``diagram.GetGraphvizString(max_depth=...)`` and then, when Graphviz's ``dot``
program is available, SVG/PNG images made by pydot. Without ``dot`` (or when
``dot`` fails) it keeps the ``.dot`` file, logs a warning saying why, and
reports the reason in the returned :class:`RenderResult`; nothing raises, so a
machine without Graphviz still gets the graph text.
"""

import dataclasses
import logging
import shutil
import warnings
from collections.abc import Sequence
from pathlib import Path

import pydot
from pydrake.systems.framework import Diagram, System

from repertoire.errors import RepertoireError
from repertoire.limits import require_writable_file

_LOG = logging.getLogger(__name__)

IMAGE_FORMATS = ("svg", "png", "pdf")


@dataclasses.dataclass
class RenderResult:
    """What ``render_diagram`` wrote.

    Attributes:
        files: format ("dot", "svg", "png", "pdf") -> path written.
        skipped: image formats that were asked for but not written.
        reason: why ``skipped`` is not empty (None when every format was written).
    """

    files: dict[str, Path]
    skipped: list[str]
    reason: str | None = None

    def describe(self) -> str:
        """One line listing the files written and, if any, why images are missing."""
        text = ", ".join(str(p) for p in self.files.values())
        if self.reason:
            text += f" (no {'/'.join(self.skipped)}: {self.reason})"
        return text


def _check_max_depth(max_depth: int | None) -> None:
    """Raises RepertoireError unless ``max_depth`` is None or an integer >= 0."""
    if max_depth is not None and (
        isinstance(max_depth, bool) or not isinstance(max_depth, int) or max_depth < 0
    ):
        raise RepertoireError(f"max_depth must be None or an integer >= 0, got {max_depth!r}")


def graphviz_text(system: System, max_depth: int | None = None) -> str:
    """The Graphviz (dot language) text of ``system``.

    Args:
        system: a Diagram or LeafSystem.
        max_depth: how many levels of nested diagrams to expand (None = all, 0 = the
            system as one box).

    Raises:
        RepertoireError: ``max_depth`` is negative or not an integer.
    """
    _check_max_depth(max_depth)
    if max_depth is not None and max_depth >= _nesting_depth(system):
        max_depth = None  # draws the same; Drake's C++ int refuses depths from 2**31 on
    return system.GetGraphvizString(max_depth=max_depth)


def _nesting_depth(system: System) -> int:
    """Levels of nested diagrams in ``system`` (0 for a LeafSystem, 1 for a flat Diagram)."""
    if not isinstance(system, Diagram):
        return 0
    return 1 + max((_nesting_depth(sub) for sub in system.GetSystems()), default=0)


def _stem(out_path: str | Path) -> Path:
    """``out_path`` without a rendering suffix (``a/b.svg`` -> ``a/b``)."""
    path = Path(out_path)
    if path.suffix.lower().lstrip(".") in (*IMAGE_FORMATS, "dot"):
        path = path.with_suffix("")
    if not path.name:
        raise RepertoireError(f"out_path must name a file, got {str(out_path)!r}")
    return path


def _with_format(stem: Path, fmt: str) -> Path:
    """``stem`` plus ``.fmt``, keeping any dot in the stem (``run_0.5`` -> ``run_0.5.svg``)."""
    return stem.with_name(f"{stem.name}.{fmt}")


def render_diagram(
    diagram: System,
    out_path: str | Path,
    *,
    max_depth: int | None = None,
    formats: Sequence[str] = ("svg", "png"),
) -> RenderResult:
    """Writes the graph of ``diagram`` as ``.dot`` text and SVG/PNG images.

    Args:
        diagram: the Diagram (or LeafSystem) to draw.
        out_path: the output file stem; ``out/arm_hold`` (or ``out/arm_hold.svg``)
            writes ``out/arm_hold.dot``, ``out/arm_hold.svg``, ``out/arm_hold.png``.
            Parent folders are created.
        max_depth: levels of nested diagrams to expand (None = all).
        formats: image formats among "svg", "png", "pdf" (may be empty: only .dot).

    Returns:
        A RenderResult listing the files written, and why images are missing if the
        ``dot`` program is absent or failed (a warning is logged too).

    Raises:
        RepertoireError: not a System, unknown format, bad max_depth or out_path.
    """
    if not isinstance(diagram, System):
        raise RepertoireError(
            f"render_diagram needs a pydrake System, got {type(diagram).__name__}"
        )
    if isinstance(formats, str):
        formats = (formats,)
    formats = [str(f).lower().lstrip(".") for f in formats]
    unknown = [f for f in formats if f not in IMAGE_FORMATS]
    if unknown:
        raise RepertoireError(
            f"unknown image format(s) {unknown}; expected some of {list(IMAGE_FORMATS)}"
        )
    stem = _stem(out_path)
    for fmt in ("dot", *formats):  # a folder in the way fails now, not after the graph
        require_writable_file(_with_format(stem, fmt), "out_path")
    text = graphviz_text(diagram, max_depth)
    stem.parent.mkdir(parents=True, exist_ok=True)
    dot_path = _with_format(stem, "dot")
    dot_path.write_text(text)
    result = RenderResult(files={"dot": dot_path}, skipped=[])
    if not formats:
        return result
    if shutil.which("dot") is None:
        result.skipped = list(formats)
        result.reason = (
            "Graphviz's 'dot' program is not on PATH; install it (for example "
            "'sudo apt-get install graphviz') to get images. The graph text is in "
            f"{dot_path}"
        )
        _LOG.warning("render_diagram: wrote only %s: %s", dot_path, result.reason)
        return result
    try:
        with warnings.catch_warnings():  # pydot's pyparsing grammar uses deprecated names
            warnings.simplefilter("ignore", DeprecationWarning)
            graphs = pydot.graph_from_dot_data(text)
        if not graphs:
            raise RuntimeError("pydot could not parse the Graphviz text")
        graph = graphs[0]
        for fmt in formats:
            path = _with_format(stem, fmt)
            graph.write(str(path), prog="dot", format=fmt)
            result.files[fmt] = path
    except Exception as e:  # pydot raises FileNotFoundError, AssertionError, OSError, ...
        result.skipped = [f for f in formats if f not in result.files]
        result.reason = f"the 'dot' program failed ({type(e).__name__}: {e})"
        _LOG.warning("render_diagram: images %s not written: %s", result.skipped, result.reason)
    return result


def diagram_system_names(diagram: Diagram, max_depth: int | None = None) -> list[str]:
    """Names of the subsystems shown when ``diagram`` is drawn to ``max_depth`` levels.

    Args:
        diagram: the Diagram.
        max_depth: levels expanded (None = all, 0 = none: the graph is the diagram's own
            box); nested diagrams beyond it are one name.

    Raises:
        RepertoireError: ``diagram`` is not a Diagram, or ``max_depth`` is negative or not
            an integer.
    """
    if not isinstance(diagram, Diagram):
        raise RepertoireError(
            f"diagram_system_names needs a pydrake Diagram, got {type(diagram).__name__}"
        )
    _check_max_depth(max_depth)
    if max_depth == 0:
        return []
    names = []
    for sub in diagram.GetSystems():
        names.append(sub.get_name())
        if isinstance(sub, Diagram) and (max_depth is None or max_depth > 1):
            names.extend(diagram_system_names(sub, None if max_depth is None else max_depth - 1))
    return names
