"""``repertoire demo``: render, simulate and replay every world; run every study.

For each registered diagram: draw its graph (``diagrams/NAME.svg|png|dot``),
simulate it for its registered duration while recording in Meshcat, print its
check() figures and write the HTML replay (``replays/NAME.html``). Then run
every registered study with its demo config and demo episode count on the
process pool (``studies/NAME/``). Finally print an index and write
``index.md``. A failure in one part is reported and the rest still runs; the
result says which parts failed (and the CLI then exits 1).
"""

import dataclasses
import time
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Any

from repertoire.criteria import evaluate_criteria

QUICK_DURATION_S = 0.25
QUICK_EPISODES = 2


@dataclasses.dataclass
class DemoItem:
    """One world or study of the demo.

    Attributes:
        kind: "diagram" or "study".
        name: the registered name.
        files: label -> path of every file written for it.
        figures: named figures (check() figures, or episodes / elapsed for a study).
        notes: remarks for the index (for example images that could not be drawn).
        error: None when it ran, else what raised.
        elapsed_s: wall seconds spent on it.
        failed_criteria: one line per pass criterion the figures missed
            (``"success = 0, expected >= 1"``).
    """

    kind: str
    name: str
    files: dict[str, Path] = dataclasses.field(default_factory=dict)
    figures: dict[str, float] = dataclasses.field(default_factory=dict)
    notes: list[str] = dataclasses.field(default_factory=list)
    error: str | None = None
    elapsed_s: float = 0.0
    failed_criteria: list[str] = dataclasses.field(default_factory=list)

    @property
    def status(self) -> str:
        """The outcome: "errored" (it raised), "failed" (a criterion missed) or "passed"."""
        if self.error:
            return "errored"
        return "failed" if self.failed_criteria else "passed"


@dataclasses.dataclass
class DemoResult:
    """Everything the demo did.

    Attributes:
        out_dir: the demo's output folder.
        items: one DemoItem per world and study, in the order run.
        failures: "kind name: error" for every part that failed (including a
            registry that could not be loaded).
        index_path: the index.md written.
    """

    out_dir: Path
    items: list[DemoItem]
    failures: list[str]
    index_path: Path

    @property
    def ok(self) -> bool:
        """True when nothing failed."""
        return not self.failures


def _study_api() -> tuple[Callable[[], list[str]], Callable[[str], Any], Callable[..., Any]]:
    """(study_names, get_study, run_study) of the study engine (imported lazily)."""
    from repertoire.studies.engine import get_study, run_study, study_names

    return study_names, get_study, run_study


def _short_error(e: BaseException) -> str:
    return f"{type(e).__name__}: {e}".strip().splitlines()[0][:500]


def _demo_diagram(name: str, out: Path, quick: bool, say: Callable[[str], None]) -> DemoItem:
    from repertoire.diagrams.registry import get_diagram_entry
    from repertoire.diagrams.render import render_diagram
    from repertoire.diagrams.replay import record_replay
    from repertoire.diagrams.simulate import build_registered

    item = DemoItem("diagram", name)
    start = time.perf_counter()
    errors = []
    try:
        result = render_diagram(build_registered(name), out / "diagrams" / name)
        item.files.update({f"graph {k}": v for k, v in result.files.items()})
        if result.reason:
            item.notes.append(f"no {'/'.join(result.skipped)} images: {result.reason}")
    except Exception as e:
        errors.append(f"render: {_short_error(e)}")
        say(f"  render failed:\n{traceback.format_exc()}")
    try:
        entry = get_diagram_entry(name)
        duration = entry.duration
        if quick and not entry.criteria:  # a world with criteria runs long enough to pass
            duration = min(duration, QUICK_DURATION_S)
        sim_start = time.perf_counter()
        replay = record_replay(name, duration, out / "replays" / f"{name}.html")
        item.files["replay html"] = replay.html_path
        item.figures = {
            "sim_time_s": replay.sim_time_s,
            "wall_time_s": time.perf_counter() - sim_start,
            **replay.figures,
        }
        item.failed_criteria = [
            r.reason for r in evaluate_criteria(replay.figures, entry.criteria) if not r.passed
        ]
    except Exception as e:
        errors.append(f"simulate/replay: {_short_error(e)}")
        say(f"  simulate/replay failed:\n{traceback.format_exc()}")
        partial = out / "replays" / f"{name}.html"
        if partial.is_file():  # record_replay saves what was recorded before the failure
            item.files["replay html (up to the failure)"] = partial
    item.error = "; ".join(errors) or None
    item.elapsed_s = time.perf_counter() - start
    return item


def _demo_study(name: str, out: Path, quick: bool, say: Callable[[str], None]) -> DemoItem:
    _, get_study, run_study = _study_api()
    item = DemoItem("study", name)
    start = time.perf_counter()
    try:
        entry = get_study(name)
        make_config = getattr(entry, "smoke_config", None) if quick else None
        make_config = make_config or getattr(entry, "demo_config", None)
        config = make_config() if make_config is not None else None
        episodes = int(getattr(entry, "demo_episodes", 4) or 4)
        if quick:
            episodes = min(episodes, QUICK_EPISODES)
        study_dir = out / "studies" / name
        result = run_study(
            name,
            config,
            episodes=episodes,
            first_seed=0,
            out_dir=study_dir,
            executor="inline" if quick else "process",
            fresh=True,
            progress=True,
        )
        item.files["store"] = Path(result.store)
        item.files.update({str(k): Path(v) for k, v in result.tables.items()})
        item.files.update({str(k): Path(v) for k, v in result.figures.items()})
        item.figures = {"episodes": float(len(result.records)), "wall_time_s": result.elapsed_s}
        criteria = getattr(entry, "criteria", None) or {}
        if criteria:
            from repertoire.studies.engine import summary_figures

            summary = summary_figures(entry.record_type, result.records)
            item.figures.update({k: summary[k] for k in criteria if k in summary})
            item.failed_criteria = [
                r.reason for r in evaluate_criteria(summary, criteria) if not r.passed
            ]
    except Exception as e:
        item.error = _short_error(e)
        say(f"  study failed:\n{traceback.format_exc()}")
    item.elapsed_s = time.perf_counter() - start
    return item


def _rel(path: Path, out: Path) -> str:
    try:
        return str(Path(path).resolve().relative_to(out.resolve()))
    except ValueError:
        return str(path)


def write_index(
    out: Path, items: list[DemoItem], failures: list[str], total_s: float, quick: bool = False
) -> Path:
    """Writes ``out/index.md`` listing every file, figure and failure of the demo.

    ``quick``: the run was ``repertoire demo --quick``; the index says its figures show
    truncated runs.
    """
    how = "`repertoire demo --quick`" if quick else "`repertoire demo`"
    lines = [
        "# repertoire demo",
        "",
        f"Written by {how} in {total_s:.0f} s. "
        "Paths are relative to this folder; the HTML replays open offline.",
        "",
    ]
    if quick:
        lines += [
            f"A quick run: simulations capped at {QUICK_DURATION_S} s and studies on their smoke "
            "configs, to check that every part runs. Its figures show truncated runs (an arm "
            "study's paths are a few millimetres, its success 0 %), not results: "
            "`repertoire demo` (`make demo`) gives those.",
            "",
        ]
    for kind, title in (("diagram", "Worlds (diagrams)"), ("study", "Studies")):
        lines += [f"## {title}", ""]
        chosen = [i for i in items if i.kind == kind]
        if not chosen:
            lines += ["(none registered)", ""]
        for item in chosen:
            status = f"{item.status} ({item.elapsed_s:.1f} s)"
            if item.error:
                status = f"errored: {item.error}"
            lines += [f"### {item.name} - {status}", ""]
            lines += [
                f"- {label}: [{_rel(p, out)}]({_rel(p, out)})" for label, p in item.files.items()
            ]
            lines += [f"- {key} = {value:.6g}" for key, value in item.figures.items()]
            lines += [f"- note: {note}" for note in item.notes]
            lines += [f"- FAILED criterion: {reason}" for reason in item.failed_criteria]
            lines.append("")
            lines += [
                f"![{item.name} {label}]({_rel(p, out)})"
                for label, p in item.files.items()
                if Path(p).suffix == ".png"
            ]
            lines.append("")
    lines += ["## Failures", ""]
    lines += [f"- {f}" for f in failures] or ["none"]
    path = out / "index.md"
    path.write_text("\n".join(lines) + "\n")
    return path


def _collect(item: DemoItem, what: str, items: list[DemoItem], failures: list[str]) -> None:
    """Append a finished part, and its failure (``"what: error"``) if it failed."""
    items.append(item)
    if item.error:
        failures.append(f"{what}: errored: {item.error}")
    elif item.failed_criteria:
        failures.append(f"{what}: failed: {'; '.join(item.failed_criteria)}")


def run_demo(
    out_dir: str | Path = "out/demo", *, quick: bool = False, printer: Callable[[str], None] = print
) -> DemoResult:
    """Runs the demo; never raises for a failing world or study (see ``DemoResult``).

    Args:
        out_dir: output folder (created).
        quick: cap simulations at 0.25 s and run studies with their smoke config (if any)
            and at most 2 episodes in-process.
        printer: where progress lines go.

    Returns:
        The DemoResult; ``result.ok`` is False when any part failed.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    items: list[DemoItem] = []
    failures: list[str] = []

    try:
        from repertoire.diagrams.registry import broken_modules, diagram_names

        names = diagram_names()
        for module, error in broken_modules().items():
            failures.append(f"diagram module {module} failed to import: {error}")
            printer(f"diagram module {module} failed to import: {error}")
    except Exception as e:
        names = []
        failures.append(f"diagram registry: {_short_error(e)}")
        printer(f"could not load the diagram registry:\n{traceback.format_exc()}")
    for name in names:
        printer(f"== world {name}")
        item = _demo_diagram(name, out, quick, printer)
        for key, value in item.figures.items():
            printer(f"  {key} = {value:.6g}")
        for note in item.notes:
            printer(f"  note: {note}")
        _collect(item, f"diagram {name}", items, failures)

    try:
        study_names = _study_api()[0]()
    except Exception as e:
        study_names = []
        failures.append(f"study registry: {_short_error(e)}")
        printer(f"could not load the study registry:\n{traceback.format_exc()}")
    for name in study_names:
        printer(f"== study {name}")
        _collect(_demo_study(name, out, quick, printer), f"study {name}", items, failures)

    total = time.perf_counter() - start
    index = write_index(out, items, failures, total, quick)
    printer("")
    printer(f"== repertoire demo: {len(items)} parts in {total:.0f} s; index: {index}")
    for item in items:
        printer(f"{item.kind} {item.name}: {item.status}")
        for reason in item.failed_criteria:
            printer(f"  failed criterion: {reason}")
        for label, path in item.files.items():
            printer(f"  {label}: {path}")
    if failures:
        printer(f"{len(failures)} part(s) FAILED:")
        for failure in failures:
            printer(f"  {failure}")
    else:
        printer("all parts passed")
    return DemoResult(out, items, failures, index)
