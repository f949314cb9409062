"""Fit an action model on any study's stored episodes (the generic ``fit_action_model``).

Reads a study store with the engine's ``load_records``, builds the features
from record fields (``name`` or ``name.i`` for element ``i`` of a list field),
fits a duration model tree (numeric target; a negative one is refused unless
``--signed-target``, for a target such as a clearance) or a pessimistic failure tree
(boolean target) on 3/4 of the episodes and reports the held-out quarter:
MAE, or the confusion matrix and accuracy. Writes the report (Markdown) and
the model (JSON).

Example (DMP pick-and-place episodes)::

    python -m repertoire.studies.dmp_pick_place -n 60 -j 2
    python -m repertoire.studies.actions_fit --target success
        --store out/studies/dmp_pick_place/episodes.sqlite
        --features cup_xy.0 cup_xy.1 coaster_xy.0 coaster_xy.1 obstacle_xyz.0 obstacle_xyz.1

(one command line).
"""

import argparse
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from repertoire.planning.action_models import FittedModel, fit_action_model, save_model
from repertoire.studies.engine import load_records

from repertoire.errors import RepertoireError


def field_getters(names: Sequence[str]) -> dict[str, Callable[[Any], float]]:
    """Feature functions for ``field`` or ``field.i`` (element ``i`` of a list field)."""
    getters = {}
    for name in names:
        field, _, index = name.partition(".")
        if index:
            if not index.isdigit():
                raise RepertoireError(f"feature {name!r}: the part after '.' must be an index")
            getters[name] = lambda r, f=field, i=int(index): float(getattr(r, f)[i])
        else:
            getters[name] = lambda r, f=field: float(getattr(r, f))
    return getters


def report(fitted: FittedModel, title: str) -> str:
    """The held-out evaluation as Markdown."""
    lines = [f"## {title}", "", f"train {fitted.n_train}, held out {fitted.n_test}", ""]
    if fitted.model.kind == "duration":
        lines.append(f"held-out MAE: {fitted.mae:.4g} (target mean {fitted.mean_target:.4g})")
    else:
        (tn, fp), (fn, tp) = fitted.confusion
        lines += [
            "| | predicted negative | predicted positive |",
            "|---|---|---|",
            f"| actual negative | {tn} | {fp} |",
            f"| actual positive | {fn} | {tp} |",
            "",
            f"held-out accuracy: {fitted.accuracy:.1%} (positive rate {fitted.mean_target:.1%})",
        ]
    lines += ["", "```", fitted.model.rules(), "```"]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    """Command-line entry point."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--store", required=True, help="a study's SQLite store")
    parser.add_argument("--features", nargs="+", required=True, help="field or field.i names")
    parser.add_argument("--target", required=True, help="record field to predict")
    parser.add_argument("--out-dir", default="out/action_models", help="report and model folder")
    parser.add_argument("--seed", type=int, default=0, help="shuffle seed")
    parser.add_argument(
        "--signed-target",
        action="store_true",
        help="a numeric target may be negative (a clearance; a duration never is)",
    )
    args = parser.parse_args(argv)
    try:
        _, records = load_records(args.store)
        recs = [records[s] for s in sorted(records)]
        getters = field_getters(args.features)
        fitted = fit_action_model(
            recs, getters, args.target, seed=args.seed, nonnegative=not args.signed_target
        )
    except RepertoireError as e:
        print(f"error: {e}")
        return 2
    out = Path(args.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    stem = f"{Path(args.store).parent.name}_{args.target}"
    text = report(fitted, f"{stem}: {args.target} from {', '.join(args.features)}")
    (out / f"{stem}.md").write_text(text)
    save_model(fitted.model, out / f"{stem}.json")
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
