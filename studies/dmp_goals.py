"""DMP goal generalisation, old (eq. 1-5) vs new (eq. 6-8) formulation (Pastor et al., Fig. 2).

Each episode draws a 2-D demonstration like Fig. 2 (Y1 moves 1 m; Y2 ends a few cm above
its start but bulges upwards on the way), learns it with both formulations and runs the
learned DMPs in a Drake diagram (DmpSystem, 1 kHz exact discrete update) for four cases:

* before: the goal is moved before movement onset;
* during: the goal jumps to a new place during the movement;
* flip: the Y2 goal is moved below the start, flipping the sign of g - x0;
* near_start: the demonstration's Y2 ends delta (log-uniform 1e-12 .. 1e-2 m) from its
  start (g ~ x0, a placing movement), and the DMP is sent to a goal 10 cm higher.

It records peak accelerations (relative to the demonstration's), final goal errors and
whether the Y2 bulge is mirrored. Run ``python -m repertoire.studies.dmp_goals --help``.
"""

import dataclasses
import math
import time
from pathlib import Path

import numpy as np
from repertoire.studies._dmp_common import register_dmp_study, write_table

from repertoire.checks import is_whole
from repertoire.errors import RepertoireError


@dataclasses.dataclass
class DmpGoalsConfig:
    """What every episode shares.

    Attributes:
        n_basis: basis functions per DOF.
        duration_s: demonstration duration (tau).
        n_samples: demonstration samples.
        time_step_s: DmpSystem update period.
        sim_factor: simulated time as a multiple of tau.
        bulge_min_m: smallest Y2 bulge of the demonstration.
        bulge_max_m: largest Y2 bulge.
        rise_min_m: smallest Y2 goal - start of the demonstration.
        rise_max_m: largest.
        goal_shift_m: goal shifts are uniform in [-goal_shift_m, goal_shift_m] per axis.
        switch_min: earliest goal jump, fraction of tau.
        switch_max: latest goal jump.
        near_start_log10_min: log10 of the smallest delta for the g ~ x0 case.
        near_start_log10_max: log10 of the largest delta.
        near_start_goal_m: Y2 goal offset used to generalise the g ~ x0 demonstration.
    """

    n_basis: int = 30
    duration_s: float = 1.0
    n_samples: int = 500
    time_step_s: float = 1e-3
    sim_factor: float = 2.0
    bulge_min_m: float = 0.2
    bulge_max_m: float = 0.4
    rise_min_m: float = 0.02
    rise_max_m: float = 0.1
    goal_shift_m: float = 0.3
    switch_min: float = 0.2
    switch_max: float = 0.6
    near_start_log10_min: float = -12.0
    near_start_log10_max: float = -2.0
    near_start_goal_m: float = 0.1

    def validate(self) -> None:
        """Raises RepertoireError if a field is out of range."""
        for name in ("duration_s", "time_step_s", "sim_factor", "near_start_goal_m"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise RepertoireError(f"DmpGoalsConfig.{name} must be finite and > 0, got {v}")
        for lo, hi in (
            ("bulge_min_m", "bulge_max_m"),
            ("rise_min_m", "rise_max_m"),
            ("near_start_log10_min", "near_start_log10_max"),
        ):
            a, b = getattr(self, lo), getattr(self, hi)
            if not (math.isfinite(a) and math.isfinite(b) and a <= b):
                raise RepertoireError(f"DmpGoalsConfig needs finite {lo} <= {hi}, got {a}, {b}")
        if not (math.isfinite(self.goal_shift_m) and self.goal_shift_m >= 0):
            # the shifts are uniform in [-goal_shift_m, goal_shift_m]: a negative one was
            # numpy's "high - low < 0" from inside every episode
            raise RepertoireError(
                f"DmpGoalsConfig.goal_shift_m must be finite and >= 0, got {self.goal_shift_m}"
            )
        if not (is_whole(self.n_basis) and is_whole(self.n_samples)):
            raise RepertoireError(
                "DmpGoalsConfig.n_basis and n_samples must be integers, got "
                f"{self.n_basis}, {self.n_samples}"
            )
        if self.n_basis < 1 or self.n_samples < 3:
            raise RepertoireError("DmpGoalsConfig needs n_basis >= 1 and n_samples >= 3")
        if not 0 < self.switch_min <= self.switch_max < 1:
            raise RepertoireError("DmpGoalsConfig needs 0 < switch_min <= switch_max < 1")


@dataclasses.dataclass
class DmpGoalsRecord:
    """One episode: per case, old vs new.

    Attributes:
        demo_peak_acc: peak |acceleration| of the demonstration (m/s^2).
        before_peak_acc_old: peak |acc| / demo peak, goal moved before onset, old form.
        before_peak_acc_new: same, new form.
        before_final_err_old: |x(T_sim) - g| (m), old form.
        before_final_err_new: same, new form.
        during_peak_acc_old: peak |acc| / demo peak, goal jump during the movement, old.
        during_peak_acc_new: same, new.
        during_final_err_old: final error after the jump, old.
        during_final_err_new: same, new.
        flip_mirrored_old: the Y2 bulge points down after flipping sign(g - x0), old.
        flip_mirrored_new: same, new.
        flip_bulge_old_m: signed extreme Y2 deviation from the start-goal line, old.
        flip_bulge_new_m: same, new.
        near_start_log10_delta: log10 of the demonstration's |g - x0| in Y2.
        near_start_peak_acc_old: peak |acc| / demo peak, g ~ x0 demo sent 10 cm up, old.
        near_start_peak_acc_new: same, new.
        near_start_final_err_old: final error, old (inf/NaN shown as 1e300).
        near_start_final_err_new: final error, new.
        seed: the episode's seed (the Fig. 2 panels redraw the first stored episode's demo).
        wall_time_s: episode wall time.
    """

    demo_peak_acc: float
    before_peak_acc_old: float
    before_peak_acc_new: float
    before_final_err_old: float
    before_final_err_new: float
    during_peak_acc_old: float
    during_peak_acc_new: float
    during_final_err_old: float
    during_final_err_new: float
    flip_mirrored_old: bool
    flip_mirrored_new: bool
    flip_bulge_old_m: float
    flip_bulge_new_m: float
    near_start_log10_delta: float
    near_start_peak_acc_old: float
    near_start_peak_acc_new: float
    near_start_final_err_old: float
    near_start_final_err_new: float
    seed: int
    wall_time_s: float


def demonstration(config: DmpGoalsConfig, rise: float, bulge: float):
    """The Fig. 2-like 2-D demonstration: Y1 0 -> 1 m, Y2 0 -> rise with an upward bulge.

    Args:
        config: Study config.
        rise: Y2 goal - start [m].
        bulge: Height of the Y2 bulge [m].

    Returns:
        ``(t, Y, Ydd)`` with Y of shape (n_samples, 2).
    """
    from repertoire.planning.dmp_math import minimum_jerk

    T = config.duration_s
    t = np.linspace(0.0, T, config.n_samples)
    x, _, xdd = minimum_jerk(np.zeros(2), np.array([1.0, rise]), T, t)
    s = t / T
    # Bulge 64 s^3 (1 - s)^3: zero velocity and acceleration at both ends, height 1 at s=1/2.
    x[:, 1] += bulge * 64 * s**3 * (1 - s) ** 3
    xdd[:, 1] += bulge * 64 * (6 * s - 36 * s**2 + 60 * s**3 - 30 * s**4) / T**2
    return t, x, xdd


def simulate_dmp(
    dmp,
    goal_times: list[float],
    goals: list[np.ndarray],
    duration: float,
    *,
    time_step: float = 1e-3,
    obstacle: np.ndarray | None = None,
    gamma: float = 1000.0,
    beta: float = 20.0 / np.pi,
):
    """Run a vector DMP in a Drake diagram with a piecewise-constant goal.

    Args:
        dmp: DmpParameters.
        goal_times: Times at which ``goals[i]`` becomes the goal (first 0).
        goals: Goals.
        duration: Simulated time [s].
        time_step: DmpSystem update period.
        obstacle: Obstacle position (enables eq. 10 coupling) or None.
        gamma: Coupling gain.
        beta: Coupling decay.

    Returns:
        ``(t, x, xd, xdd)`` logged every time step.
    """
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.primitives import ConstantVectorSource, TrajectorySource, VectorLogSink
    from pydrake.trajectories import PiecewisePolynomial
    from repertoire.systems.dmp_compose import add_dmp

    builder = DiagramBuilder()
    sys = add_dmp(
        builder,
        dmp,
        name="dmp",
        time_step=time_step,
        obstacle_avoidance=obstacle is not None,
        gamma=gamma,
        beta=beta,
    )
    if len(goals) == 1:
        src = builder.AddSystem(ConstantVectorSource(np.asarray(goals[0], float)))
    else:
        times = list(goal_times) + [max(duration, goal_times[-1]) + 1.0]
        values = np.column_stack([np.asarray(g, float) for g in goals] + [goals[-1]])
        src = builder.AddSystem(TrajectorySource(PiecewisePolynomial.ZeroOrderHold(times, values)))
    builder.Connect(src.get_output_port(), sys.GetInputPort("goal"))
    if obstacle is not None:
        obs = builder.AddSystem(ConstantVectorSource(np.asarray(obstacle, float)))
        builder.Connect(obs.get_output_port(), sys.GetInputPort("obstacle"))
    logs = {}
    n = dmp.n_dims
    for name in ("position", "velocity", "acceleration"):
        logs[name] = builder.AddSystem(VectorLogSink(n, publish_period=time_step))
        builder.Connect(sys.GetOutputPort(name), logs[name].get_input_port())
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.AdvanceTo(duration)
    ctx = simulator.get_context()
    data = {k: v.FindLog(ctx) for k, v in logs.items()}
    t = data["position"].sample_times()
    return (
        t,
        data["position"].data().T,
        data["velocity"].data().T,
        data["acceleration"].data().T,
    )


def _peak(a: np.ndarray) -> float:
    v = float(np.max(np.abs(a))) if np.all(np.isfinite(a)) else 1e300
    return min(v, 1e300)


def _final_err(x: np.ndarray, goal: np.ndarray) -> float:
    e = float(np.max(np.abs(x[-1] - goal)))
    return e if math.isfinite(e) else 1e300


def _signed_bulge(x: np.ndarray) -> float:
    """Signed extreme deviation of Y2 from the straight line between start and end."""
    s = np.linspace(0.0, 1.0, len(x))
    line = x[0, 1] + (x[-1, 1] - x[0, 1]) * s
    d = x[:, 1] - line
    return float(d[np.argmax(np.abs(d))])


def sample_episode(config: DmpGoalsConfig, seed: int) -> dict:
    """The seeded random quantities of an episode.

    Args:
        config: Study config.
        seed: Episode seed.
    """
    rng = np.random.default_rng(seed)
    return {
        "rise": float(rng.uniform(config.rise_min_m, config.rise_max_m)),
        "bulge": float(rng.uniform(config.bulge_min_m, config.bulge_max_m)),
        "shift_before": rng.uniform(-config.goal_shift_m, config.goal_shift_m, 2),
        "shift_during": rng.uniform(-config.goal_shift_m, config.goal_shift_m, 2),
        "switch": float(rng.uniform(config.switch_min, config.switch_max)),
        "log10_delta": float(rng.uniform(config.near_start_log10_min, config.near_start_log10_max)),
    }


def run_episode(config: DmpGoalsConfig, seed: int) -> DmpGoalsRecord:
    """Learns both formulations from the seeded demo and runs the four goal cases."""
    from repertoire.planning.dmp_learn import learn_dmp

    t0 = time.perf_counter()
    config.validate()
    ep = sample_episode(config, seed)
    T = config.duration_s
    sim_t = config.sim_factor * T
    t, Y, Ydd = demonstration(config, ep["rise"], ep["bulge"])
    demo_peak = float(np.abs(Ydd).max())
    dmps = {f: learn_dmp(t, Y, n_basis=config.n_basis, formulation=f) for f in ("old", "new")}
    g = Y[-1]
    out: dict = {"demo_peak_acc": demo_peak}
    for f, dmp in dmps.items():
        run = simulate_dmp  # same diagram for every case
        g1 = g + ep["shift_before"]
        _, x, _, a = run(dmp, [0.0], [g1], sim_t, time_step=config.time_step_s)
        out[f"before_peak_acc_{f}"] = _peak(a) / demo_peak
        out[f"before_final_err_{f}"] = _final_err(x, g1)
        g2 = g + ep["shift_during"]
        _, x, _, a = run(dmp, [0.0, ep["switch"] * T], [g, g2], sim_t, time_step=config.time_step_s)
        out[f"during_peak_acc_{f}"] = _peak(a) / demo_peak
        out[f"during_final_err_{f}"] = _final_err(x, g2)
        gf = np.array([g[0], -ep["rise"]])
        _, x, _, _ = run(dmp, [0.0], [gf], sim_t, time_step=config.time_step_s)
        bulge = _signed_bulge(x)
        out[f"flip_bulge_{f}_m"] = bulge
        out[f"flip_mirrored_{f}"] = bool(bulge < 0)
    delta = 10.0 ** ep["log10_delta"]
    tn, Yn, _ = demonstration(config, delta, ep["bulge"])
    gn = np.array([1.0, config.near_start_goal_m])
    for f in ("old", "new"):
        dmp = learn_dmp(tn, Yn, n_basis=config.n_basis, formulation=f, min_displacement=0.0)
        with np.errstate(all="ignore"):
            _, x, _, a = simulate_dmp(dmp, [0.0], [gn], sim_t, time_step=config.time_step_s)
        out[f"near_start_peak_acc_{f}"] = _peak(a) / demo_peak
        out[f"near_start_final_err_{f}"] = _final_err(x, gn)
    out["near_start_log10_delta"] = ep["log10_delta"]
    return DmpGoalsRecord(**out, seed=int(seed), wall_time_s=time.perf_counter() - t0)


def summarize(records: list[DmpGoalsRecord], config: DmpGoalsConfig, out_dir: Path):
    """Fig. 2 panels for the first episode's demo, peak acceleration vs delta, and a table.

    Raises:
        RepertoireError: no records (Fig. 2 draws the first record's seeded demonstration).
    """
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from repertoire.planning.dmp_learn import learn_dmp

    out_dir = Path(out_dir)
    if not records:
        raise RepertoireError("dmp_goals: no episodes to summarise (Fig. 2 draws the first)")
    seed = records[0].seed
    ep = sample_episode(config, seed)
    T = config.duration_s
    t, Y, _ = demonstration(config, ep["rise"], ep["bulge"])
    fig = Figure(figsize=(9, 10), layout="constrained")
    axes = fig.subplots(2, 2, sharex=True, sharey=True)
    goals = [np.array([gx, gy]) for gx in (0.7, 1.0, 1.3) for gy in (-0.15, 0.05, 0.25)]
    for col, f in enumerate(("old", "new")):
        dmp = learn_dmp(t, Y, n_basis=config.n_basis, formulation=f)
        for row, during in enumerate((False, True)):
            ax = axes[row, col]
            ax.plot(Y[:, 0], Y[:, 1], "k-", lw=2.5, label="demonstration")
            for g in goals:
                # NumPy rollout (identical to the DmpSystem to rounding, see the tests).
                n_steps = int(round(1.5 * T / config.time_step_s))
                G = np.tile(g, (n_steps + 1, 1))
                if during:
                    k = int(round(0.4 * T / config.time_step_s))
                    G[:k] = Y[-1]
                x = dmp.rollout(goal=G, dt=config.time_step_s, n_steps=n_steps).x
                ax.plot(x[:, 0], x[:, 1], "--", lw=1.2)
                ax.plot(*g, "ko", ms=4)
            ax.set_title(
                f"{f} formulation,\ngoal changed {'during (t = 0.4 tau)' if during else 'before'}"
            )
            ax.set_xlabel("Y1 (m)")
            ax.set_ylabel("Y2 (m)")
            ax.set_aspect("equal")  # Y1, Y2 are both positions: keep the path's shape
            ax.grid(alpha=0.3)
    handles = [
        Line2D([], [], c="k", lw=2.5, label="demonstration (to its own goal)"),
        Line2D([], [], ls="--", c="0.4", lw=1.2, label="DMP to a new goal (one colour per goal)"),
        Line2D([], [], ls="", marker="o", c="k", ms=4, label="new goal"),
    ]
    fig.legend(handles=handles, loc="outside lower center", ncols=3)
    fig.suptitle(
        f"Fig. 2: seed {seed}'s demonstration sent to 9 new goals, old (eq. 1-5) vs new "
        "(eq. 6-8) DMP"
    )
    p1 = out_dir / "dmp_goals_fig2.png"
    fig.savefig(p1, dpi=100)

    fig = Figure(figsize=(6.5, 4.2), layout="constrained")
    ax = fig.add_subplot()
    d = [r.near_start_log10_delta for r in records]
    ax.semilogy(
        d, [r.near_start_peak_acc_old for r in records], "o", c="tab:red", label="old (eq. 1)"
    )
    ax.semilogy(
        d, [r.near_start_peak_acc_new for r in records], "s", c="tab:blue", label="new (eq. 6)"
    )
    ax.set_xlabel("log10 |g - x0| of the demonstrated Y2 (m)")
    ax.set_ylabel("peak |acceleration| / demonstration's")
    ax.set_title(f"g ~ x0 demo sent {config.near_start_goal_m * 100:g} cm up ({len(records)} runs)")
    ax.grid(alpha=0.3, which="both")
    ax.legend()
    p2 = out_dir / "dmp_goals_near_start.png"
    fig.savefig(p2, dpi=100)

    p4 = orientation_figure(config, out_dir)
    p5 = sparse_demo_figure(out_dir)
    p6 = start_velocity_figure(out_dir)
    p7 = tau_invariance_figure(config, seed, out_dir)

    def stats(vals):
        v = np.asarray(vals, float)
        return f"{np.median(v):.3g}", f"{np.max(v):.3g}"

    lines = [
        f"# DMP goal generalisation, old vs new ({len(records)} episodes)",
        "",
        "| case | figure | old: median | old: max | new: median | new: max |",
        "|---|---|---|---|---|---|",
    ]
    for case, label in (
        ("before", "goal moved before onset"),
        ("during", "goal jump during movement"),
        ("near_start", "demo with g ~ x0, goal moved 10 cm"),
    ):
        for fig_name, key in (("peak acc / demo", "peak_acc"), ("final error (m)", "final_err")):
            o = stats([getattr(r, f"{case}_{key}_old") for r in records])
            n = stats([getattr(r, f"{case}_{key}_new") for r in records])
            lines.append(f"| {label} | {fig_name} | {o[0]} | {o[1]} | {n[0]} | {n[1]} |")
    mo = np.mean([r.flip_mirrored_old for r in records])
    mn = np.mean([r.flip_mirrored_new for r in records])
    lines.append(f"| sign of g - x0 flipped | fraction mirrored | {mo:.2f} |  | {mn:.2f} |  |")
    p3 = write_table(out_dir, "dmp_goals_table.md", lines)
    return {
        "fig2": p1,
        "near_start": p2,
        "table": p3,
        "orientation": p4,
        "sparse": p5,
        "start_velocity": p6,
        "tau_invariance": p7,
    }


def orientation_figure(config: DmpGoalsConfig, out_dir: Path) -> Path:
    """Quaternion DMPs of yaw turns up to 270 deg: reproduced the learned way, and new goals.

    Rest-to-rest (minimum-jerk) yaw turns of 90, 200 and 270 deg are learned in both forms
    (per-component, sec. IV-B, and on-manifold); each is rolled out to its own goal and to
    a goal 40 deg further. The yaw is unwrapped, so a DMP turning back the short way (what a
    goal flipped to the start's hemisphere did past 180 deg) would show as a curve going
    down.
    """
    from matplotlib.figure import Figure
    from repertoire.planning.dmp_learn import learn_quaternion_dmp
    from repertoire.planning.dmp_math import minimum_jerk
    from repertoire.planning.dmp_quaternion import quat_exp

    T, n = config.duration_s, config.n_samples
    t = np.linspace(0.0, T, n)
    s, _, _ = minimum_jerk(np.zeros(1), np.ones(1), T, t)
    steps = int(round(1.5 * T / config.time_step_s))  # half a tau more: the DMP settles

    def yaw_quat(deg):
        return quat_exp(np.outer(np.ravel(deg), [0.0, 0.0, 0.5]) * np.pi / 180.0)

    def yaw_deg(q):
        return np.rad2deg(np.unwrap(2.0 * np.arctan2(q[:, 3], q[:, 0])))

    fig = Figure(figsize=(10, 4.8), layout="constrained")
    axes = fig.subplots(1, 2, sharey=True)
    colours = {90: "tab:blue", 200: "tab:orange", 270: "tab:green"}
    for ax, mode in zip(axes, ("component", "manifold"), strict=True):
        for turn, colour in colours.items():
            demo = yaw_quat(s[:, 0] * turn)
            dmp = learn_quaternion_dmp(t, demo, mode=mode, n_basis=config.n_basis)
            ax.plot(t, yaw_deg(demo), "-", c="0.6", lw=4)
            tt, q, _ = dmp.rollout(dt=config.time_step_s, n_steps=steps)
            ax.plot(tt, yaw_deg(q), "--", c=colour, lw=1.6, label=f"{turn} deg: own goal")
            tt, q, _ = dmp.rollout(
                goal=yaw_quat(turn + 40)[0], dt=config.time_step_s, n_steps=steps
            )
            ax.plot(tt, yaw_deg(q), ":", c=colour, lw=1.6, label=f"{turn} deg: goal + 40 deg")
        ax.plot([], [], "-", c="0.6", lw=4, label="demonstration")
        ax.set_title(f"{mode} quaternion DMP, yaw turns")
        ax.set_xlabel("t (s)")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("yaw, unwrapped (deg)")
    # below the panels: in the upper left it covered the 270 deg + 40 deg curve
    fig.legend(
        *axes[1].get_legend_handles_labels(), loc="outside lower center", ncols=4, fontsize=8
    )
    fig.suptitle(
        "Yaw turns learned as quaternion DMPs, rolled out to their own goal and 40 deg further"
    )
    path = out_dir / "dmp_goals_orientation.png"
    fig.savefig(path, dpi=100)
    return path


SPARSE_SEEDS = range(40)
"""Seeds of the sparse noisy demonstrations in :func:`sparse_demo_figure`."""


def sparse_demo_figure(out_dir: Path) -> Path:
    """Learning from sparse, noisy, unevenly stamped demonstrations: gaps bridged or not.

    Each demonstration is a unit minimum-jerk move over 2 s at 101 random stamps with 2 mm
    noise (:func:`~repertoire.planning.dmp_demos.noisy_sparse_minimum_jerk`), learned with
    50 basis functions and the default derivative estimate: on the samples alone
    (``bridge_gaps=False``) with ``ridge=0`` and with ``ridge="gcv"``, and with the
    defaults (gaps bridged, :mod:`repertoire.planning.dmp_gaps`; ``ridge="auto"``). Left:
    the samples, the true move and the reproductions for the seed at the samples-alone
    ridge-0 fit's 90th-percentile error. Right: every seed's largest reproduction error,
    log scale.
    """
    import warnings

    from matplotlib.figure import Figure
    from repertoire.planning.dmp_demos import noisy_sparse_minimum_jerk
    from repertoire.planning.dmp_learn import learn_dmp
    from repertoire.planning.dmp_math import minimum_jerk

    fits = {
        "samples alone, ridge=0": {"ridge": 0.0, "bridge_gaps": False},
        'samples alone, ridge="gcv"': {"ridge": "gcv", "bridge_gaps": False},
        "default (gaps bridged)": {},
    }
    colours = dict(zip(fits, ("tab:red", "tab:orange", "tab:blue")))
    errors = {k: [] for k in fits}
    runs = []  # per seed: the demonstration and each fit's rollout
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # ridge=0 on the samples alone warns here
        for seed in SPARSE_SEEDS:
            t, x, _, _ = noisy_sparse_minimum_jerk(seed)
            rolls = {label: learn_dmp(t, x, **kw).rollout(dt=1e-3) for label, kw in fits.items()}
            for label, r in rolls.items():
                truth = minimum_jerk(np.zeros(1), np.ones(1), 2.0, r.t)[0]
                errors[label].append(float(np.abs(r.x - truth).max()))
            runs.append((t, x, rolls))
    # left: the seed at ridge 0's 90th-percentile error (a typical bad case, not the worst)
    worst = errors["samples alone, ridge=0"]
    k90 = int(np.argsort(worst)[int(0.9 * (len(SPARSE_SEEDS) - 1))])
    fig = Figure(figsize=(10, 4.2), layout="constrained")
    left, right = fig.subplots(1, 2)
    t, x, rolls = runs[k90]
    for label, r in rolls.items():
        left.plot(r.t, r.x[:, 0], c=colours[label], lw=1.5, label=label)
    truth = minimum_jerk(np.zeros(1), np.ones(1), 2.0, r.t)[0]
    left.plot(r.t, truth[:, 0], c="0.5", lw=4, alpha=0.5, label="true move")
    left.plot(t, x[:, 0], ".", c="k", ms=4, label="demonstration (101 samples)")
    left.set_title(
        f"seed {SPARSE_SEEDS[k90]}: 90th percentile of ridge 0 alone, 50 basis functions"
    )
    left.set_xlabel("t (s)")
    left.set_ylabel("x (unit move from 0 to 1)")
    left.grid(alpha=0.3)
    left.legend(fontsize=8)
    for k, (label, e) in enumerate(errors.items()):
        right.plot(np.array(SPARSE_SEEDS) + 0.15 * k, e, "o", c=colours[label], label=label)
    right.set_yscale("log")
    right.set_xlabel("seed")
    right.set_ylabel("max |reproduction - true move| (amplitude 1)")
    right.set_title(f"largest reproduction error of each of {len(SPARSE_SEEDS)} seeds")
    right.grid(alpha=0.3, which="both")
    right.legend(fontsize=8)
    fig.suptitle(
        "Sparse, noisy, unevenly stamped demonstrations (101 samples, 2 mm noise): "
        "gaps bridged or not"
    )
    path = out_dir / "dmp_goals_sparse_demos.png"
    fig.savefig(path, dpi=100)
    return path


START_VELOCITY_SEED = 0
"""Seed of the demonstration in motion in :func:`start_velocity_figure`."""

#: The old-formulation run of :func:`start_velocity_runs` goes this many times as far.
OLD_GOAL_FACTOR = 2.0


def start_velocity_runs(seed: int = START_VELOCITY_SEED) -> dict:
    """A 1-DOF demonstration that starts in motion, learned and reproduced two ways.

    The demonstration is :func:`~repertoire.planning.dmp_demos.sines_in_motion` (1.5 s,
    751 samples), learned with the defaults. It is rolled out at its own time step from the
    learned initial velocity ``v0`` (the default) and from rest (``v0 = 0``). The same
    demonstration learned in the old formulation (eq. 1) is also sent to a goal
    :data:`OLD_GOAL_FACTOR` times as far, in the study's Drake diagram (:func:`simulate_dmp`)
    and by ``rollout``: eq. 1 scales the whole run, its start velocity too, by
    ``(g - x0) / (learned g - learned x0)``, and the DmpSystem scales ``v0`` to its goal
    input at the onset as ``rollout`` does.

    Args:
        seed: Seed of the demonstration.

    Returns:
        ``t``, ``x``, ``xd`` (the demonstration, 1-D arrays), ``v0`` (the learned initial
        velocity [m/s]) and ``runs``: ``"v0"`` / ``"rest"`` -> ``(xt, xdt, rms)``, the
        rollout's positions and velocities at the demonstration's stamps and its RMS
        position error against the demonstration [m]; ``old``: ``goal``, ``system`` and
        ``rollout`` (each ``(x, xd)`` at the demonstration's stamps, the DmpSystem's and
        the NumPy rollout's), ``unscaled`` (the rollout's positions started from the
        learned ``v0`` unscaled) and ``gap`` (the largest |system - rollout| position [m]).
    """
    from repertoire.planning.dmp_demos import sines_in_motion
    from repertoire.planning.dmp_learn import learn_dmp

    t, x, xd = sines_in_motion(seed)
    dmp = learn_dmp(t, x)
    runs = {}
    for key, v0 in (("v0", None), ("rest", np.zeros(1))):
        r = dmp.rollout(dt=float(t[1] - t[0]), n_steps=len(t) - 1, v0=v0)
        runs[key] = (r.x[:, 0], r.xd[:, 0], float(np.sqrt(np.mean((r.x - x) ** 2))))
    dt = float(t[1] - t[0])
    old = learn_dmp(t, x, formulation="old")
    goal = old.x0 + OLD_GOAL_FACTOR * (old.goal - old.x0)
    _, xs, xds, _ = simulate_dmp(old, [0.0], [goal], float(t[-1] - t[0]), time_step=dt)
    r = old.rollout(goal=goal, dt=dt, n_steps=len(t) - 1)
    unscaled = old.rollout(goal=goal, dt=dt, n_steps=len(t) - 1, v0=old.v0)
    runs_old = {
        "goal": float(goal[0]),
        "system": (xs[: len(t), 0], xds[: len(t), 0]),
        "rollout": (r.x[:, 0], r.xd[:, 0]),
        "unscaled": unscaled.x[:, 0],
        "gap": float(np.max(np.abs(xs[: len(t), 0] - r.x[:, 0]))),
    }
    v0 = float(dmp.v0[0])
    return {"t": t, "x": x[:, 0], "xd": xd[:, 0], "v0": v0, "runs": runs, "old": runs_old}


def start_velocity_figure(out_dir: Path, seed: int = START_VELOCITY_SEED) -> Path:
    """A demonstration that starts in motion: reproduced from its ``v0``, and from rest.

    Left the position, middle the velocity, of :func:`start_velocity_runs`; the legend
    gives each reproduction's RMS position error against the demonstration. Right: the
    old formulation sent to a goal twice as far, in the DmpSystem and by ``rollout``, and
    the rollout from the learned ``v0`` unscaled (where the DmpSystem started before
    session 37).

    Args:
        out_dir: Output folder.
        seed: Seed of the demonstration.
    """
    from matplotlib.figure import Figure

    d = start_velocity_runs(seed)
    t = d["t"]
    fig = Figure(figsize=(15, 4.6), layout="constrained")
    pos, vel, far = fig.subplots(1, 3, sharex=True)
    pos.plot(t, d["x"], c="0.6", lw=4, label="demonstration")
    vel.plot(t, d["xd"], c="0.6", lw=4)
    styles = {
        "v0": ("--", "tab:blue", f"DMP from the learned v0 = {d['v0']:.2f} m/s (default)"),
        "rest": (":", "tab:red", "DMP started from rest (v0 = 0)"),
    }
    for key, (xt, xdt, rms) in d["runs"].items():
        ls, colour, label = styles[key]
        pos.plot(t, xt, ls, c=colour, lw=1.8, label=f"{label}: RMS error {rms:.1e} m")
        vel.plot(t, xdt, ls, c=colour, lw=1.8)
    vel.plot(0.0, d["v0"], "o", c="k", ms=5, label="learned v0 (t = 0)")
    for ax, what in ((pos, "position x (m)"), (vel, "velocity dx/dt (m/s)")):
        ax.set_xlabel("t (s)")
        ax.set_ylabel(what)
        ax.grid(alpha=0.3)
    pos.set_title("position")
    vel.set_title("velocity")
    o = d["old"]
    far.plot(t, d["x"], c="0.6", lw=4, label="demonstration")
    far.axhline(o["goal"], c="k", lw=0.8, ls="-.", label=f"goal x0 + {OLD_GOAL_FACTOR:g} (g - x0)")
    far.plot(t, o["system"][0], c="tab:green", lw=3, label="old form (eq. 1) in the DmpSystem")
    far.plot(t, o["rollout"][0], "--", c="k", lw=1.2, label=f"its rollout: within {o['gap']:.0e} m")
    far.plot(t, o["unscaled"], ":", c="tab:red", lw=1.8, label="rollout from the unscaled v0")
    far.set_xlabel("t (s)")
    far.set_ylabel("position x (m)")
    far.grid(alpha=0.3)
    far.set_title(f"old formulation to a goal {OLD_GOAL_FACTOR:g}x as far: v0 scaled too")
    far.legend(fontsize=7)
    fig.suptitle(
        f"A demonstration that starts in motion (seed {seed}, sum of sines): "
        "the DMP keeps its initial velocity"
    )
    handles = pos.get_legend_handles_labels()[0] + vel.get_legend_handles_labels()[0]
    fig.legend(handles=handles, loc="outside lower center", ncols=2, fontsize=8)
    path = Path(out_dir) / "dmp_goals_start_velocity.png"
    fig.savefig(path, dpi=100)
    return path


#: Durations of :func:`tau_invariance_figure`, as multiples of the demonstration's.
TAU_FACTORS = (0.5, 1.0, 2.0)


def tau_invariance_runs(config: DmpGoalsConfig, seed: int) -> dict:
    """The episode's demonstration (new formulation) re-timed to :data:`TAU_FACTORS` durations.

    Each re-timed DMP (:meth:`~repertoire.planning.dmp.DmpParameters.with_tau`) runs in the
    study's Drake diagram (:func:`simulate_dmp`, the config's time step) to the learned
    goal for ``sim_factor`` of its duration, once free and once around a ball
    (eq. 10, ``v = tau dx/dt``) put 3 cm above the demonstration's midpoint.

    Args:
        config: Study config.
        seed: Episode seed (its demonstration).

    Returns:
        ``demo`` (samples, 2), ``obstacle`` (2) and ``runs``: ``(factor, coupled)`` ->
        ``(t, x, gap)``, with ``gap`` the largest distance [m] from the duration-1 run of
        the same kind at the same phase ``t / tau`` (linear interpolation between samples).
    """
    from repertoire.planning.dmp_learn import learn_dmp

    ep = sample_episode(config, seed)
    t, Y, _ = demonstration(config, ep["rise"], ep["bulge"])
    dmp = learn_dmp(t, Y, n_basis=config.n_basis, formulation="new")
    obstacle = Y[len(Y) // 2] + np.array([0.0, 0.03])
    runs = {}
    for coupled in (False, True):
        for factor in TAU_FACTORS:
            tau = factor * dmp.tau
            ts, x, _, _ = simulate_dmp(
                dmp.with_tau(tau),
                [0.0],
                [dmp.goal],
                config.sim_factor * tau,
                time_step=config.time_step_s,
                obstacle=obstacle if coupled else None,
            )
            runs[factor, coupled] = (ts, x)
    out = {}
    for (factor, coupled), (ts, x) in runs.items():
        t1, x1 = runs[1.0, coupled]
        phase = t1[t1 <= ts[-1] / factor]  # the reference's samples this run reaches
        xi = np.column_stack([np.interp(factor * phase, ts, x[:, d]) for d in range(2)])
        gap = float(np.max(np.linalg.norm(xi - x1[: len(phase)], axis=1)))
        out[factor, coupled] = (ts, x, gap)
    return {"demo": Y, "obstacle": obstacle, "runs": out}


def tau_invariance_figure(config: DmpGoalsConfig, seed: int, out_dir: Path) -> Path:
    """One demonstration at three durations: the same path in space (eq. 4, 6-7, 9-10).

    Left: the paths of :func:`tau_invariance_runs` overlaid (free and around the ball);
    right: Y1 against time, the durations told apart. The legend gives each run's largest
    distance from the demonstration-duration run at the same phase.

    Args:
        config: Study config.
        seed: Episode seed (its demonstration).
        out_dir: Output folder.
    """
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle

    d = tau_invariance_runs(config, seed)
    fig = Figure(figsize=(11, 4.6), layout="constrained")
    space, time_ax = fig.subplots(1, 2)
    space.plot(*d["demo"].T, c="0.7", lw=5, label="demonstration")
    space.add_patch(Circle(d["obstacle"], 0.01, color="tab:gray", label="obstacle o of eq. 10"))
    colours = dict(zip(TAU_FACTORS, ("tab:blue", "tab:orange", "tab:green"), strict=True))
    widths = dict(zip(TAU_FACTORS, (3.0, 2.0, 1.0), strict=True))
    T = config.duration_s
    for (factor, coupled), (ts, x, gap) in d["runs"].items():
        kind = "around the ball (eq. 10)" if coupled else "free"
        label = f"tau = {factor * T:g} s, {kind}: " + (
            "the reference" if factor == 1.0 else f"{gap * 1e3:.2g} mm off the {T:g} s path"
        )
        ls = "--" if coupled else "-"
        space.plot(*x.T, ls, c=colours[factor], lw=widths[factor], label=label)
        if not coupled:
            time_ax.plot(ts, x[:, 0], c=colours[factor], lw=2, label=f"tau = {factor * T:g} s")
    space.set_xlabel("Y1 (m)")
    space.set_ylabel("Y2 (m)")
    space.set_aspect("equal")
    space.set_title("path in space: the same at every duration")
    space.grid(alpha=0.3)
    time_ax.set_xlabel("t (s)")
    time_ax.set_ylabel("Y1 (m)")
    time_ax.set_title("Y1 over time: the durations differ")
    time_ax.grid(alpha=0.3)
    time_ax.legend(fontsize=8)
    fig.legend(*space.get_legend_handles_labels(), loc="outside lower center", ncols=2, fontsize=8)
    fig.suptitle(
        f"Seed {seed}'s demonstration re-timed (DmpParameters.with_tau), run in the DmpSystem "
        f"at {config.time_step_s * 1e3:g} ms steps"
    )
    path = Path(out_dir) / "dmp_goals_tau_invariance.png"
    fig.savefig(path, dpi=100)
    return path


register_dmp_study(
    __name__,
    DmpGoalsConfig,
    DmpGoalsRecord,
    description="DMP goal generalisation, old vs new formulation: blow-up and mirroring",
    demo_episodes=20,
    # a tiny config for tests: fewer samples and basis functions
    smoke=dict(n_basis=10, n_samples=100, sim_factor=1.2, time_step_s=2e-3),
)
