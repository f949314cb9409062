"""Refinement horizons 1-4 in simulation: a tour of four waypoints with GoToPose (Table 4).

Section 6.3.1 of Stulp & Beetz (JAIR 2008): "a simulated soccer scenario in which the
robot has to traverse four waypoints with the goToPose action". Each episode samples a
start and four waypoints (each ``leg_range`` from the previous one, on the half of the
field away from the ball); the heading and speed at the first three are free (six
parameters), the last is a full pose. The sequence is refined with horizons 1-4 (the
receding horizon of :func:`~repertoire.planning.refinement.refine_sequence`) using the
GoToPose duration tree (``refinement_explore``'s approach model: Table 7 features are
relative, so it predicts any GoToPose leg within its training ranges) and every refined
tour is executed in the ``soccer_plan`` world. The plan is built directly as a
refinement problem: like the paper's arm domain, a fixed tour needs no PDDL planner.

Every leg is refined inside the model's training box on the features its free headings
and speeds drive (:func:`tour_problem`). ``summarize`` writes Table 4 (mean executed tour
time per horizon, the improvement over the previous horizon and its paired t-test) beside
the paper's soccer column, and per horizon how many tours query the model outside its
training box on each leg (the last leg, ending at rest with ``v_g = 0``, always does: the
models never saw a stop).

Run it with ``python -m repertoire.studies.refinement_horizons --help``.
"""

import dataclasses
import math
import time
from pathlib import Path

import numpy as np
from repertoire.studies._refinement_common import (
    SoccerPlanConfig,
    document_shared_fields,
    run_plan,
    trained_range,
)
from repertoire.studies.engine import register_study

from repertoire.checks import check_range
from repertoire.errors import RepertoireError

N_LEGS = 4
PAPER_TABLE4_SOCCER = {1: (22.7, None, None), 2: (20.3, 0.106, 0.000), 3: (20.2, 0.007, 0.001),
                       4: (20.2, 0.002, 0.053)}  # fmt: skip


@document_shared_fields
@dataclasses.dataclass
class RefinementHorizonsConfig(SoccerPlanConfig):
    """The shared soccer plan settings plus the tour.

    Attributes:
        leg_range: distance between consecutive waypoints [m].
        tour_x_range: x range of the start and waypoints (away from the ball at x = 1).
        tour_y_range: y range of the start and waypoints.
        models_dir: folder with ``approach_duration.json`` (empty: the shipped models).
        solver: ``"ga"`` or ``"de"``.
    """

    leg_range: list[float] = dataclasses.field(default_factory=lambda: [0.8, 1.4])
    tour_x_range: list[float] = dataclasses.field(default_factory=lambda: [-2.6, 0.2])
    tour_y_range: list[float] = dataclasses.field(default_factory=lambda: [-1.6, 1.6])
    models_dir: str = ""
    solver: str = "ga"

    def validate(self) -> None:
        """Raises RepertoireError naming the first bad field."""
        super().validate()
        from repertoire.diagrams.soccer import FIELD

        check_range("leg_range", self.leg_range)
        check_range("tour_x_range", self.tour_x_range, FIELD[:2])
        check_range("tour_y_range", self.tour_y_range, FIELD[2:])
        if self.leg_range[0] <= 0.1:
            raise RepertoireError(f"leg_range must start above 0.1 m, got {self.leg_range}")
        if self.solver not in ("ga", "de"):
            raise RepertoireError(f"solver must be 'ga' or 'de' (angles), got {self.solver!r}")


@dataclasses.dataclass
class RefinementHorizonsRecord:
    """One tour executed with each horizon.

    Attributes:
        start: ``[x, y, phi, v]``.
        waypoints: the four waypoints' ``[x, y]``, flattened.
        final_phi: the heading at the last waypoint.
        params_h: the six refined values (phi, v at waypoints 1-3) of horizons 1-4, flattened.
        predicted_h: per horizon the predicted tour time [s].
        time_h: per horizon the executed tour time [s] (NaN unless it succeeded).
        status_h: per horizon the plan status.
        wall_refine_s: wall time of the four refinements (timing field).
        wall_time_s: wall time of the episode (timing field).
    """

    start: list[float]
    waypoints: list[float]
    final_phi: float
    params_h: list[float]
    predicted_h: list[float]
    time_h: list[float]
    status_h: list[str]
    wall_refine_s: float
    wall_time_s: float


def sample_tour(config: RefinementHorizonsConfig, rng: np.random.Generator):
    """A start state, four waypoints ``(4, 2)`` and the final heading (none in a goal)."""
    from repertoire.diagrams.soccer import clear_of_goals

    xr, yr = config.tour_x_range, config.tour_y_range
    for _ in range(1000):
        p = [np.array([rng.uniform(*xr), rng.uniform(*yr)])]
        for _ in range(N_LEGS):
            d, a = rng.uniform(*config.leg_range), rng.uniform(-math.pi, math.pi)
            p.append(p[-1] + d * np.array([math.cos(a), math.sin(a)]))
        pts = np.array(p)
        if (
            np.all((pts[:, 0] >= xr[0]) & (pts[:, 0] <= xr[1]))
            and np.all((pts[:, 1] >= yr[0]) & (pts[:, 1] <= yr[1]))
            and np.all(clear_of_goals(pts[:, 0], pts[:, 1]))
        ):
            break
    else:
        raise RepertoireError(
            "no tour inside tour_x_range x tour_y_range, clear of the goals, with these legs"
        )
    start = np.array([*pts[0], rng.uniform(-math.pi, math.pi), rng.uniform(*config.v_range)])
    return start, pts[1:], float(rng.uniform(-math.pi, math.pi))


def tour_states(start, waypoints, final_phi: float, params: np.ndarray) -> np.ndarray:
    """``(n, 5, 4)`` states: start, waypoints 1-3 with ``params`` (n, 6), the final pose."""
    p = np.atleast_2d(params)
    n = p.shape[0]
    states = np.zeros((n, N_LEGS + 1, 4))
    states[:, 0] = start
    for k in range(1, N_LEGS):
        states[:, k, :2] = waypoints[k - 1]
        states[:, k, 2] = p[:, 2 * (k - 1)]
        states[:, k, 3] = p[:, 2 * (k - 1) + 1]
    states[:, N_LEGS, :2] = waypoints[-1]
    states[:, N_LEGS, 2] = final_phi
    return states


def leg_features(start, waypoints, final_phi: float, params: np.ndarray, leg: int) -> np.ndarray:
    """``(n, 5)`` GoToPose features of tour leg ``leg`` (0-3) for parameter rows ``params``.

    Un-mirrored, as the shipped models were fitted. The last leg's goal speed ``v_g`` is 0:
    the tour ends at rest at its last waypoint.
    """
    from repertoire.planning.action_models.features import goto_pose_features

    s = tour_states(start, waypoints, final_phi, params)
    return np.atleast_2d(goto_pose_features(s[:, leg], s[:, leg + 1], mirrored=False))


def tour_out_of_range(model, start, waypoints, final_phi: float, params) -> np.ndarray:
    """``(n, 4)``: True where a leg's features lie outside ``model``'s training box.

    Every leg is a query of the duration model (its term in :func:`tour_problem`),
    the last one too: it is predicted with ``v_g = 0``.
    """
    n = np.atleast_2d(params).shape[0]
    flags = [model.out_of_range(leg_features(start, waypoints, final_phi, params, leg))
             for leg in range(N_LEGS)]  # fmt: skip
    return np.column_stack(flags).reshape(n, N_LEGS)


def tour_problem(model, start, waypoints, final_phi: float, v_max: float, *, v_min: float = 0.0):
    """The refinement problem of the tour: one GoToPose term per leg, six free parameters.

    Each waypoint's heading is free in ``[-pi, pi]``, its speed in ``[v_min, v_max]``.
    Every leg's term searches only inside ``model``'s training box (``train_min`` /
    ``train_max``) on the features the free parameters drive (:class:`DurationTerm`'s
    ``domain``): a heading is ``angle_at`` of the leg that ends there and ``angle_to`` of
    the next one, a speed their ``v_g`` and ``v``. A heading range cannot express this:
    ``angle_at`` wraps, and the headings outside its data (seen: -2.99 to 3.07 rad) are
    an arc of 0.22 rad at the leg's direction + pi, anywhere in ``[-pi, pi]``. Features
    the parameters cannot change (the legs' lengths, the start's speed, the last leg's
    stop) are not constrained.
    """
    from repertoire.planning.refinement import (
        DurationTerm,
        PiecewiseLinearModel,
        RefinementProblem,
    )

    waypoints = np.asarray(waypoints, dtype=float)
    if waypoints.shape != (N_LEGS, 2) or not np.isfinite(waypoints).all():
        raise RepertoireError(
            f"waypoints must be {N_LEGS} finite [x, y] rows, got {waypoints.tolist()!r}"
        )
    pl = PiecewiseLinearModel.from_leaves(model.leaves)
    box = (model.train_min, model.train_max)
    terms = []
    for leg in range(N_LEGS):

        def features(params, leg=leg):
            return leg_features(start, waypoints, final_phi, params, leg)

        def at(k: int, q: int) -> tuple[int, ...]:  # waypoint k's heading (q 0) or speed (1)
            return (2 * k - 2 + q,) if 1 <= k < N_LEGS else ()

        # dist, angle_to, angle_at, v, v_g: the start's heading, the goal's heading, ...
        reads = ((), at(leg, 0), at(leg + 1, 0), at(leg, 1), at(leg + 1, 1))
        uses = tuple(sorted({i for r in reads for i in r}))
        terms.append(DurationTerm(pl, features, uses, f"{leg}:goToPose", box, reads))
    lower = np.tile([-math.pi, v_min], N_LEGS - 1)
    upper = np.tile([math.pi, v_max], N_LEGS - 1)
    names = tuple(f"w{k}.{q}" for k in range(1, N_LEGS) for q in ("phi", "v"))
    return RefinementProblem(tuple(terms), lower, upper, names)


def run_episode(config: RefinementHorizonsConfig, seed: int) -> RefinementHorizonsRecord:
    """Refines the tour with horizons 1-4 and executes each."""
    from repertoire.planning.refinement import refine_sequence
    from repertoire.studies.refinement_soccer import load_models

    config.validate()
    t0 = time.perf_counter()
    start, waypoints, final_phi = sample_tour(config, np.random.default_rng(seed))
    (model,) = load_models(config.models_dir, ("approach_duration",))
    # a waypoint's speed is one leg's v_g and the next one's v: search it where the model saw data
    v_min, v_max = trained_range(0.0, config.approach_v_max, ((model, "v"), (model, "v_g")))
    problem = tour_problem(model, start, waypoints, final_phi, v_max, v_min=v_min)
    results = [refine_sequence(problem, h, config.solver, seed=seed) for h in range(1, N_LEGS + 1)]
    wall_refine = time.perf_counter() - t0
    times, statuses = [], []
    for result in results:
        states = tour_states(start, waypoints, final_phi, result.params)[0]
        run = run_plan(config, start, states[1:])
        statuses.append(run.status)
        times.append(float(run.finish_times[-1]) if run.status == "SUCCEEDED" else math.nan)
    return RefinementHorizonsRecord(
        start=[float(s) for s in start],
        waypoints=[float(w) for w in waypoints.reshape(-1)],
        final_phi=final_phi,
        params_h=[float(p) for r in results for p in r.params],
        predicted_h=[float(r.cost) for r in results],
        time_h=times,
        status_h=statuses,
        wall_refine_s=wall_refine,
        wall_time_s=time.perf_counter() - t0,
    )


def summarize(
    records: list[RefinementHorizonsRecord], config: RefinementHorizonsConfig, out_dir: Path
) -> dict[str, Path]:
    """Writes Table 4: executed tour time per horizon beside the paper's soccer column."""
    from repertoire.studies.refinement_soccer import paired_cells

    out_dir = Path(out_dir)
    ok = [r for r in records if all(s == "SUCCEEDED" for s in r.status_h)]
    T = np.array([r.time_h for r in ok], dtype=float).reshape(-1, N_LEGS)
    P = np.array([r.predicted_h for r in ok], dtype=float).reshape(-1, N_LEGS)
    md = [
        "## Table 4: refinement horizon, soccer tour of four waypoints (executed)",
        "",
        "| horizon | paper Σ (s) | paper imp. | paper p | ours Σ (s) | ours imp. | ours p | "
        "predicted Σ (s) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for h in range(1, N_LEGS + 1):
        t, imp, p = PAPER_TABLE4_SOCCER[h]
        paper = f"{t} | {'' if imp is None else f'{imp:.1%}'} | {'' if p is None else f'{p:.3f}'}"
        if ok:
            mean = f"{np.mean(T[:, h - 1]):.2f}"
            if h > 1:
                ours_imp, ours_p = paired_cells(T[:, h - 2], T[:, h - 1])[3:]
                ours = f"{mean} | {ours_imp} | {ours_p}"
            else:
                ours = f"{mean} | | "
            pred = f"{np.mean(P[:, h - 1]):.2f}"
        else:
            ours, pred = "- | - | -", "-"
        md.append(f"| h = {h} | {paper} | {ours} | {pred} |")
    fails = {h: sum(r.status_h[h - 1] != "SUCCEEDED" for r in records) for h in range(1, 5)}
    md += [
        "",
        f"{len(records)} tours; {len(ok)} succeeded with every horizon (the table pairs those); "
        f"failed runs per horizon: {fails}. Improvement: mean of 1 - t_h / t_(h-1) per tour; p: "
        "paired t-test against the previous horizon.",
        "",
        *out_of_range_lines(records, config),
    ]
    tables = out_dir / "refinement_horizons_tables.md"
    tables.write_text("\n".join(md) + "\n")
    return {"tables": tables}


def out_of_range_lines(
    records: list[RefinementHorizonsRecord], config: RefinementHorizonsConfig
) -> list[str]:
    """Markdown: per horizon, how many refined tours query the model outside its data, per leg.

    Args:
        records: the study's tours (their refined parameters; executed or not).
        config: gives ``models_dir``, the duration model refined with.

    Returns:
        Lines of a table (horizon x leg) and a sentence on the last leg's stop.
    """
    from repertoire.studies.refinement_soccer import load_models

    (model,) = load_models(config.models_dir, ("approach_duration",))
    md = [
        f"Refined tours (of {len(records)}) with a leg outside the duration model's training "
        "box (`out_of_range`: its prediction there is an extrapolation):",
        "",
        "| horizon | " + " | ".join(f"leg {k + 1}" for k in range(N_LEGS)) + " |",
        "|---|" + "---|" * N_LEGS,
    ]
    for h in range(1, N_LEGS + 1):
        counts = np.zeros(N_LEGS, dtype=int)
        for r in records:
            n = 2 * (N_LEGS - 1)  # phi, v at waypoints 1-3
            params = np.array(r.params_h[n * (h - 1) : n * h])
            waypoints = np.array(r.waypoints).reshape(N_LEGS, 2)
            counts += tour_out_of_range(model, r.start, waypoints, r.final_phi, params)[0]
        md.append(f"| h = {h} | " + " | ".join(str(c) for c in counts) + " |")
    j = model.feature_names.index("v_g")
    lo, hi = model.train_min[j], model.train_max[j]
    if lo > 0.0:
        why = (f"the approaches it was fitted on all ended moving (v_g {lo:.2g}-{hi:.2g} m/s): "
               "a stop is outside its data, so every tour's last leg is flagged")  # fmt: skip
    else:
        why = f"its data include legs ending at rest (v_g {lo:.2g}-{hi:.2g} m/s)"
    return md + ["", f"The last leg ends at rest (v_g = 0), a query of the model too; {why}."]


def demo_config() -> RefinementHorizonsConfig:
    """The demo config (shared defaults, shipped models)."""
    return RefinementHorizonsConfig()


def smoke_config() -> RefinementHorizonsConfig:
    """A tiny config for tests: short legs, a short timeout."""
    return RefinementHorizonsConfig(leg_range=[0.5, 0.6], timeout=8.0)


register_study(
    "refinement_horizons",
    config_type=RefinementHorizonsConfig,
    record_type=RefinementHorizonsRecord,
    run_episode=run_episode,
    description="a four-waypoint GoToPose tour refined with horizons 1-4, executed: Table 4",
    summarize=summarize,
    demo_config=demo_config,
    demo_episodes=4,
    smoke_config=smoke_config,
).run_if_main(__name__)
