"""Summaries of a study's records: tables, default histograms, comparable records.

``summary.csv`` / ``summary.md`` hold one row per numeric or bool record field
over every stored episode of the config; identifier fields (``seed``,
``*_id``) and missing values (None, NaN) are left out. ``episodes.csv`` lists
every record. A study without its own ``summarize`` gets one histogram per
numeric field. Part of :mod:`repertoire.studies.engine`, which re-exports
these names.
"""

import csv
import dataclasses
import json
import math
from pathlib import Path
from typing import Any

from repertoire.studies.store import to_plain


def is_timing_field(name: str) -> bool:
    """True for timing fields (``wall*_s``), which may differ between runs."""
    return name.startswith("wall") and name.endswith("_s")


def _nan_safe(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return repr(value)  # 'nan', 'inf', '-inf': equal to themselves
    if isinstance(value, list):
        return [_nan_safe(v) for v in value]
    if isinstance(value, dict):
        return {k: _nan_safe(v) for k, v in value.items()}
    return value


def comparable(record: Any) -> dict[str, Any]:
    """A record as plain data without its timing fields, for determinism checks.

    Non-finite floats become the strings ``'nan'``, ``'inf'``, ``'-inf'`` so that
    two runs that both produced NaN compare equal.
    """
    plain = to_plain(record, type(record).__name__)
    return {k: _nan_safe(v) for k, v in plain.items() if not is_timing_field(k)}


# ---------------------------------------------------------------------------
# Summaries.


def is_identifier_field(name: str) -> bool:
    """Fields that name an episode rather than measure it (``seed``, ``*_seed``, ``*_id``)."""
    return name in ("seed", "id", "index") or name.endswith(("_seed", "_id", "_index"))


def _numeric_fields(record_type: type, records: list) -> tuple[list[str], list[str]]:
    """(numeric field names, bool field names) of the record type, in field order.

    None is a missing value (for example "no path"); identifiers are skipped.
    """
    numeric, boolean = [], []
    for f in dataclasses.fields(record_type):
        if is_identifier_field(f.name):
            continue
        values = [getattr(r, f.name) for r in records if getattr(r, f.name) is not None]
        if values and all(isinstance(v, bool) for v in values):
            boolean.append(f.name)
        elif values and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in values
        ):
            numeric.append(f.name)
    return numeric, boolean


def _present(value: Any) -> bool:
    """False for a missing value: None or NaN."""
    return value is not None and not (isinstance(value, float) and math.isnan(value))


def summary_rows(record_type: type, records: list) -> list[dict[str, Any]]:
    """One summary row per numeric or bool record field.

    Numeric fields get ``n`` (finite values), ``mean``, ``std`` (population),
    ``min``, ``max``; yes/no (bool) fields get ``n`` and ``true_rate``, the fraction
    of those episodes in which the field is true (a success for ``success``, a
    failure for ``failed`` or ``fell``: the field's name says which). Missing values
    (None, NaN) and identifier fields (``seed``) are left out.
    """
    numeric, boolean = _numeric_fields(record_type, records)
    rows = []
    for name in numeric:
        vals = [float(v) for r in records if _present(v := getattr(r, name))]
        finite = [v for v in vals if math.isfinite(v)]
        n = len(finite)
        mean = sum(finite) / n if n else math.nan
        std = math.sqrt(sum((v - mean) ** 2 for v in finite) / n) if n else math.nan
        rows.append(
            {
                "field": name,
                "n": n,
                "mean": mean,
                "std": std,
                "min": min(finite) if n else math.nan,
                "max": max(finite) if n else math.nan,
                "true_rate": "",
            }
        )
    for name in boolean:
        vals = [bool(v) for r in records if _present(v := getattr(r, name))]
        rows.append(
            {
                "field": name,
                "n": len(vals),
                "mean": "",
                "std": "",
                "min": "",
                "max": "",
                "true_rate": sum(vals) / len(vals) if vals else math.nan,
            }
        )
    return rows


def summary_figures(record_type: type, records: list) -> dict[str, float]:
    """The summary as named figures, the ones study criteria bound.

    ``mean_<field>``, ``std_<field>``, ``min_<field>``, ``max_<field>`` of numeric
    fields and ``rate_<field>`` of bool fields.
    """
    figures: dict[str, float] = {}
    for row in summary_rows(record_type, records):
        if row["true_rate"] != "":
            figures[f"rate_{row['field']}"] = float(row["true_rate"])
        else:
            for key in ("mean", "std", "min", "max"):
                figures[f"{key}_{row['field']}"] = float(row[key])
    return figures


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)


def seed_ranges(seeds: list[int], most: int = 6) -> str:
    """Sorted seeds as ranges: ``[0, 1, 2, 10, 11]`` -> ``'0..2, 10..11'`` (``most`` ranges)."""
    runs: list[list[int]] = []
    for seed in sorted(seeds):
        if runs and seed == runs[-1][1] + 1:
            runs[-1][1] = seed
        else:
            runs.append([seed, seed])
    text = ", ".join(f"{a}..{b}" if b > a else f"{a}" for a, b in runs[:most])
    return text + (f", ... ({len(runs)} ranges)" if len(runs) > most else "")


def write_tables(
    name: str, record_type: type, records: list, seeds: list[int], out_dir: Path
) -> dict[str, Path]:
    """Writes summary.csv, summary.md and episodes.csv; returns their paths."""
    rows = summary_rows(record_type, records)
    cols = ["field", "n", "mean", "std", "min", "max", "true_rate"]
    csv_path = out_dir / "summary.csv"
    with csv_path.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=cols)
        w.writeheader()
        for row in rows:
            w.writerow({k: (repr(v) if isinstance(v, float) else v) for k, v in row.items()})
    md_path = out_dir / "summary.md"
    lines = [
        f"# Study `{name}`: {len(records)} episodes (seeds {seed_ranges(seeds)})",
        "",
        f"Every one of the {len(records)} episodes stored for this config (the store may hold "
        "more seeds than the last run asked for). `n` counts the finite values of a field; "
        "missing values (no result) are left out. `true_rate` is, for a yes/no field, the "
        "fraction of episodes in which it is true: a success rate for `success`, a failure "
        "rate for `failed` or `fell`.",
        "",
        "| " + " | ".join(cols) + " |",
        "|" + "|".join(["---"] + ["---:"] * (len(cols) - 1)) + "|",
    ]
    lines += ["| " + " | ".join(_fmt(row[c]) for c in cols) + " |" for row in rows]
    md_path.write_text("\n".join(lines) + "\n")
    ep_path = out_dir / "episodes.csv"
    fields = [f.name for f in dataclasses.fields(record_type)]
    # A record that keeps its own seed field gets no second "seed" column (a header naming
    # a column twice reads back as seed.1 or overwrites); the store's seed is kept apart
    # only where a record's seed field says otherwise.
    own_seed = "seed" in fields and all(r.seed == s for s, r in zip(seeds, records))
    seed_column = [] if own_seed else ["stored_seed" if "seed" in fields else "seed"]
    with ep_path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow([*seed_column, *fields])
        for seed, rec in zip(seeds, records):
            row = [] if own_seed else [seed]
            for f in fields:
                v = getattr(rec, f)
                row.append(
                    repr(v)
                    if isinstance(v, float)
                    else (v if isinstance(v, (int, str, bool)) else json.dumps(to_plain(v)))
                )
            w.writerow(row)
    return {"summary.csv": csv_path, "summary.md": md_path, "episodes.csv": ep_path}


def use_agg() -> None:
    import matplotlib

    if matplotlib.get_backend().lower() != "agg":
        try:
            matplotlib.use("Agg")
        except Exception:  # a GUI backend already in use: our figures use Figure() anyway
            pass


def _bin_edges(values: list[float], n: int):
    """``n`` equal histogram bins over finite ``values``; one bin when they cannot have ``n``.

    A spread too small for ``n`` distinct float edges (one value of 1e18) gets a
    single bin around the values instead of numpy's "too many bins" error.
    """
    import numpy as np

    try:
        return np.histogram_bin_edges(values, bins=n)
    except ValueError:
        lo, hi = min(values), max(values)
        pad = max(0.5, 1e-6 * abs(lo)) if lo == hi else 0.0
        return np.array([lo - pad, hi + pad])


def histogram_figure(name: str, values: list, n_records: int):
    """The histogram of a numeric field's finite ``values`` over ``n_records`` episodes.

    A field with no finite value gets a note in an empty frame instead of bars (its
    empty histogram had a count axis from -0.05 to 0.05).

    Returns:
        The matplotlib ``Figure`` (not saved).
    """
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator

    finite = [float(v) for v in values if _present(v) and math.isfinite(v)]
    fig = Figure(figsize=(5, 3.5), layout="constrained")
    ax = fig.add_subplot()
    ax.set_xlabel(name)
    ax.set_ylabel("episodes")
    missing = n_records - len(finite)
    left_out = f" ({missing} missing or non-finite left out)" if missing else ""
    ax.set_title(f"{name} over {len(finite)} episodes{left_out}", fontsize=9)
    if not finite:
        ax.set_ylim(0.0, 1.0)
        ax.set_xticks([])
        ax.set_yticks([])
        ax.text(0.5, 0.5, "no finite value", ha="center", va="center", transform=ax.transAxes)
        return fig
    bins = _bin_edges(finite, min(30, max(5, len(finite) // 3)))
    ax.hist(finite, bins=bins, color="tab:blue", alpha=0.8)
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))  # counts: whole ticks
    return fig


def write_histograms(record_type: type, records: list, out_dir: Path) -> dict[str, Path]:
    """One histogram PNG per numeric record field; returns ``{label: path}``."""
    numeric, _ = _numeric_fields(record_type, records)
    figures = {}
    for name in numeric:
        fig = histogram_figure(name, [getattr(r, name) for r in records], len(records))
        path = out_dir / f"hist_{name}.png"
        fig.savefig(path, dpi=100)
        figures[f"hist_{name}"] = path
    return figures
