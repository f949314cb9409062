"""The ``repertoire`` command line: list, show, render, simulate, study, demo.

Everything goes through the diagram registry (``repertoire.diagrams.registry``)
and the study registry (``repertoire.studies.engine``), so a world or study
added to the package shows up here without touching this file. Heavy imports
(pydrake) happen inside the sub-commands so that ``--help`` is instant.

Exit codes: 0 success, 1 a run failed (diverged simulation, failed demo part),
2 bad input (unknown name, bad scenario/config YAML, bad option); on exit code 2
nothing has been written; 130 interrupted (Ctrl-C); 141 the reader of its output
went away (``repertoire list | head``), without a traceback.
"""

import argparse
import math
import sys
import textwrap
import time
from collections.abc import Sequence
from pathlib import Path

from repertoire.limits import path_argument

EPILOG = """\
examples:
  repertoire list                                   what diagrams and studies exist
  repertoire show biped_walk > walk.yaml            its settings, commented, to edit
  repertoire render arm_hold --out out/graphs       out/graphs/arm_hold.{dot,svg,png}
  repertoire render littledog_stand --max-depth 1   top level only
  repertoire simulate littledog_stand               run it, print its check figures
  repertoire simulate arm_hold --duration 2 --scenario my_arm.yaml
  repertoire simulate biped_stand --replay          also write out/simulate/biped_stand.html
  repertoire simulate diffdrive_drive --live        watch at http://localhost:7000 (Ctrl-C stops)
  repertoire study NAME --episodes 200 --workers 2  Monte-Carlo study, resumable
  repertoire study NAME --executor dask --scheduler tcp://host:8786
  repertoire demo                                   everything above, into out/demo

Scenario and config files are YAML with the fields of the world's Scenario (or
the study's Config) dataclass; unknown keys are errors. `repertoire CMD --help`
explains each command. Exit codes: 0 ok, 1 a run failed, 2 bad input.
"""


def _wrap(text: str) -> str:
    """``text`` wrapped at 79 columns (RawDescriptionHelpFormatter keeps line breaks)."""
    return textwrap.fill(text, 79)


def _add_scenario(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--scenario",
        metavar="YAML",
        type=path_argument,
        help="scenario YAML file (fields of the world's Scenario dataclass; "
        "default: the built-in scenario)",
    )


def _add_out(p: argparse.ArgumentParser, default: str, what: str = "output folder") -> None:
    p.add_argument(
        "--out",
        metavar="DIR",
        type=path_argument,
        default=Path(default),
        help=f"{what} (default: {default})",
    )


def _add_diagram_name(p: argparse.ArgumentParser) -> None:
    """The NAME of a registered diagram and its optional --scenario YAML."""
    p.add_argument("name", metavar="NAME", help="registered diagram name")
    _add_scenario(p)


def build_parser() -> argparse.ArgumentParser:
    """The argparse parser of the ``repertoire`` command (sub-commands and their options)."""
    parser = argparse.ArgumentParser(
        prog="repertoire",
        description=_wrap(
            "repertoire: Drake worlds (named diagrams) and Monte-Carlo studies of robots "
            "that reuse a repertoire of skills. Pick a command; NAME is a registered "
            "diagram or study (see `repertoire list`)."
        ),
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    raw = argparse.RawDescriptionHelpFormatter

    sub.add_parser(
        "list",
        help="list registered diagrams and studies",
        description=_wrap(
            "List every registered diagram (world) and study with a one-line description."
        ),
        formatter_class=raw,
    )

    p = sub.add_parser(
        "show",
        help="print a world's scenario or a study's config as commented YAML",
        description=_wrap(
            "Print the default scenario of world NAME (or the default config of study "
            "NAME) as YAML with each field's meaning and unit in a comment above it. "
            "Save it, edit it, and pass it back with --scenario (simulate, render) or "
            "--config (study)."
        ),
        epilog="example: repertoire show biped_walk > walk.yaml\n"
        "         repertoire simulate biped_walk --scenario walk.yaml",
        formatter_class=raw,
    )
    p.add_argument("name", metavar="NAME", help="registered diagram or study name")

    p = sub.add_parser(
        "render",
        help="draw a diagram's graph (SVG/PNG, .dot text)",
        description=_wrap(
            "Build diagram NAME and draw its system graph with Graphviz. "
            "Writes DIR/NAME.dot always, and DIR/NAME.svg/.png when the "
            "'dot' program is installed."
        ),
        epilog="example: repertoire render arm_hold --out out/graphs --max-depth 1",
        formatter_class=raw,
    )
    _add_diagram_name(p)
    _add_out(p, "out/render")
    p.add_argument(
        "--max-depth",
        metavar="N",
        type=int,
        default=None,
        help="levels of nested diagrams to expand (default: all)",
    )
    p.add_argument(
        "--format",
        dest="formats",
        nargs="+",
        default=["svg", "png"],
        choices=["svg", "png", "pdf"],
        help="image formats (default: svg png)",
    )

    p = sub.add_parser(
        "simulate",
        help="simulate a diagram and print its check figures",
        description=_wrap(
            "Build diagram NAME, simulate it (its registered duration "
            "unless --duration), stop with an error if any state turns "
            "NaN, and print the world's check figures (e.g. height "
            "error). --replay writes a self-contained HTML replay; "
            "--live serves a Meshcat view on localhost."
        ),
        epilog="examples:\n  repertoire simulate arm_hold --duration 2\n"
        "  repertoire simulate littledog_stand --replay --out out/sim\n"
        "  repertoire simulate biped_stand --live --live-seconds 60",
        formatter_class=raw,
    )
    _add_diagram_name(p)
    p.add_argument(
        "--duration",
        metavar="S",
        type=float,
        default=None,
        help="simulated seconds, at most 3600 (default: the diagram's registered duration)",
    )
    _add_out(p, "out/simulate", "folder for the --replay HTML")
    p.add_argument(
        "--replay",
        action="store_true",
        help="record in Meshcat and write DIR/NAME.html (opens offline)",
    )
    p.add_argument(
        "--live",
        action="store_true",
        help="run at real time, print the Meshcat URL and keep serving until "
        "Ctrl-C (or --live-seconds)",
    )
    p.add_argument(
        "--live-seconds",
        metavar="S",
        type=float,
        default=None,
        help="with --live: stop serving after S seconds",
    )

    p = sub.add_parser(
        "study",
        help="run a Monte-Carlo study (resumable, parallel)",
        description=_wrap(
            "Run study NAME for --episodes seeds (default: the study's demo episode count) "
            "with its demo config, or --config YAML. Every episode is stored in the SQLite "
            "store as it finishes; running again runs only missing seeds, and a changed "
            "config is refused for an existing store unless --fresh. Tables (CSV, Markdown) "
            "and figures (PNG) go to --out-dir (default out/studies/NAME)."
        ),
        epilog="examples:\n  repertoire study NAME --episodes 200 --workers 2\n"
        "  repertoire study NAME --smoke --executor inline\n"
        "  repertoire study NAME --config my_config.yaml --fresh\n"
        "  repertoire study NAME --executor dask --scheduler tcp://127.0.0.1:8786",
        formatter_class=raw,
    )
    try:
        from repertoire.studies.engine import add_study_arguments
    except Exception as e:  # keep `repertoire --help` and the other commands usable
        p.add_argument("name", metavar="NAME", help="registered study name")
        p.epilog = f"(the study engine failed to import: {type(e).__name__}: {e})"
    else:
        add_study_arguments(p)

    p = sub.add_parser(
        "demo",
        help="render, simulate, replay every world; run every study",
        description=_wrap(
            "Render every registered diagram (SVG/PNG), simulate each "
            "briefly printing its check figures, write HTML replays, run "
            "every registered study with its demo config, and write "
            "DIR/index.md listing every file. Exits 1 if any part "
            "failed (the others still run)."
        ),
        epilog="example: repertoire demo --out out/demo",
        formatter_class=raw,
    )
    _add_out(p, "out/demo")
    p.add_argument(
        "--quick",
        action="store_true",
        help="shorter simulations and smoke-size studies (a quick check)",
    )
    return parser


def _print_figures(figures: dict[str, float], indent: str = "  ") -> None:
    for key, value in figures.items():
        print(f"{indent}{key} = {value:.6g}")


def _cmd_list(args: argparse.Namespace) -> int:
    from repertoire.diagrams.registry import diagram_names, get_diagram_entry

    print("diagrams (repertoire render|simulate NAME):")
    for name in diagram_names():
        entry = get_diagram_entry(name)
        print(f"  {name:<24} {entry.description} [{entry.duration:g} s]")
    from repertoire.studies.engine import get_study, study_names

    print("studies (repertoire study NAME):")
    names = study_names()
    for name in names:
        print(f"  {name:<24} {getattr(get_study(name), 'description', '')}")
    if not names:
        print("  (none registered)")
    return 0


def _cmd_show(args: argparse.Namespace) -> int:
    from repertoire.show import show_text

    sys.stdout.write(show_text(args.name))
    return 0


def _cmd_render(args: argparse.Namespace) -> int:
    from repertoire.diagrams.registry import get_diagram_entry
    from repertoire.diagrams.render import render_diagram
    from repertoire.diagrams.simulate import build_registered, resolve_scenario
    from repertoire.errors import RepertoireError
    from repertoire.limits import require_writable_dir, require_writable_file

    if args.max_depth is not None and args.max_depth < 0:
        raise RepertoireError(f"--max-depth must be >= 0, got {args.max_depth}")
    require_writable_dir(args.out, "--out")
    for fmt in ("dot", *args.formats):
        require_writable_file(args.out / f"{args.name}.{fmt}", "--out")
    entry = get_diagram_entry(args.name)
    scenario = resolve_scenario(entry, args.scenario)
    diagram = build_registered(args.name, scenario=scenario)
    result = render_diagram(
        diagram, args.out / args.name, max_depth=args.max_depth, formats=args.formats
    )
    for path in result.files.values():
        print(f"wrote {path}")
    if result.reason:
        print(f"note: no {'/'.join(result.skipped)} images: {result.reason}", file=sys.stderr)
    return 0


def _cmd_simulate(args: argparse.Namespace) -> int:
    from repertoire.diagrams.registry import get_diagram_entry
    from repertoire.diagrams.simulate import (
        SimulationDivergedError,
        check_duration,
        resolve_scenario,
        simulate_registered,
    )
    from repertoire.errors import RepertoireError
    from repertoire.limits import require_writable_dir, require_writable_file

    entry = get_diagram_entry(args.name)
    if args.replay:
        require_writable_dir(args.out, "--out")
        require_writable_file(args.out / f"{args.name}.html", "--out")
    duration = check_duration(entry.duration if args.duration is None else args.duration)
    if args.live_seconds is not None and not args.live:
        raise RepertoireError("--live-seconds needs --live")
    if args.live_seconds is not None and not (
        math.isfinite(args.live_seconds) and args.live_seconds >= 0
    ):
        raise RepertoireError(
            f"--live-seconds must be a finite number >= 0, got {args.live_seconds}"
        )
    scenario = resolve_scenario(entry, args.scenario, duration)
    start = time.perf_counter()
    meshcat = None
    try:
        if args.replay or args.live:
            from repertoire.diagrams.replay import record_replay, serve_live

            if args.live:
                from pydrake.geometry import Meshcat

                meshcat = Meshcat()
                print(
                    f"live view at {meshcat.web_url()}: open it in a browser now; "
                    f"simulating {duration:g} s at real time"
                )
            html = args.out / f"{args.name}.html" if args.replay else None
            result = record_replay(
                args.name,
                duration,
                html,
                scenario=scenario,
                meshcat=meshcat,
                realtime_rate=1.0 if args.live else 0.0,
            )
            figures = {"sim_time_s": result.sim_time_s, **result.figures}
        else:
            figures = simulate_registered(args.name, scenario=scenario, duration=duration)
    except SimulationDivergedError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    wall = time.perf_counter() - start
    print(f"{args.name}: simulated {figures['sim_time_s']:.3g} s in {wall:.2f} s wall")
    _print_figures({k: v for k, v in figures.items() if k != "sim_time_s"})
    if args.replay:
        print(f"wrote {result.html_path} (self-contained; open it in a browser)")
    if meshcat is not None:
        serve_live(meshcat, args.live_seconds)
    return 0


def _cmd_study(args: argparse.Namespace) -> int:
    from repertoire.studies.engine import run_study_command

    return run_study_command(args, prog="repertoire study")


def _cmd_demo(args: argparse.Namespace) -> int:
    from repertoire.demo import run_demo
    from repertoire.limits import require_writable_dir

    require_writable_dir(args.out, "--out")
    result = run_demo(args.out, quick=args.quick)
    return 0 if result.ok else 1


_COMMANDS = {
    "list": _cmd_list,
    "show": _cmd_show,
    "render": _cmd_render,
    "simulate": _cmd_simulate,
    "study": _cmd_study,
    "demo": _cmd_demo,
}


def main(argv: Sequence[str] | None = None) -> int:
    """Runs the ``repertoire`` command line; returns the exit code.

    Args:
        argv: the arguments after the program name (default: ``sys.argv[1:]``).
    """
    parser = build_parser()
    args = parser.parse_args(argv)
    from repertoire.errors import RepertoireError
    from repertoire.interrupts import interruptible

    try:  # Ctrl-C: "interrupted", 130 (finished episodes of a study stay stored)
        return interruptible(lambda: _COMMANDS[args.command](args))
    except RepertoireError as e:
        print(f"repertoire {args.command}: error: {e}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # `repertoire list | head`: the reader has all it wanted
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no flush error at exit
        return 141  # as a shell reports a command ended by SIGPIPE


if __name__ == "__main__":
    from repertoire.interrupts import exit_process

    exit_process(main())
