"""Figure of transferred steps over a terrain's height map (like Stolle et al.'s Figs. 9-10)."""

from pathlib import Path

import numpy as np
from repertoire.models.terrain import TerrainBoard
from repertoire.planning.terrain_features import TransferError, TransferResult

LEG_MARKS = (("lf", "^"), ("rf", "v"), ("lh", "<"), ("rh", ">"))


def matched_steps_figure(
    board: TerrainBoard,
    result: TransferResult,
    path: str | Path,
    *,
    changed_from: float | None = None,
    title: str = "",
    resolution: float = 0.004,
) -> Path:
    """Writes a PNG of the transferred stances over the board's height map.

    Each placed step is drawn as its four feet (one marker per leg) joined to the
    matched frame's origin, with an arrow along the frame's x axis; colour = match
    cost. An optional dashed line marks where a modified terrain starts to differ.

    Args:
        board: the terrain the steps were placed on.
        result: the transfer result.
        path: PNG file to write (parent folders created).
        changed_from: x (m) from which the terrain was modified, drawn if given.
        title: figure title; default a summary of counts.
        resolution: height-map sampling (m).

    Raises:
        TransferError: not a board / result, or a non-positive resolution.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if not isinstance(board, TerrainBoard) or not isinstance(result, TransferResult):
        raise TransferError("matched_steps_figure needs a TerrainBoard and a TransferResult")
    if not resolution > 0.0:
        raise TransferError(f"resolution must be positive, got {resolution}")
    x0, x1, y0, y1 = board.bounds()  # the boxes' extent (a moved or joined board too)
    hx, hy = 0.5 * (x1 - x0), 0.5 * (y1 - y0)
    x = np.arange(x0, x1 + 1e-9, resolution)
    y = np.arange(y0, y1 + 1e-9, resolution)
    X, Y = np.meshgrid(x, y)
    Z = board.height(X, Y)
    fig, ax = plt.subplots(figsize=(2.0 + 6.0 * hx / max(hx, hy), 1.2 + 6.0 * hy / max(hx, hy)))
    im = ax.imshow(
        Z * 100.0, origin="lower", extent=(x0, x1, y0, y1), cmap="Greys", interpolation="nearest"
    )
    fig.colorbar(im, ax=ax, label="terrain height (cm)", shrink=0.8)
    costs = np.array([s.match.cost for s in result.steps]) if result.steps else np.zeros(0)
    vmax = max(float(costs.max()) if costs.size else 0.0, 1e-9)
    cmap = plt.get_cmap("viridis")
    for s in result.steps:
        color = cmap(s.match.cost / vmax)
        fx, fy, fyaw = s.match.frame
        for i, (_, mark) in enumerate(LEG_MARKS):
            ax.plot(*s.feet[i, :2], mark, color=color, ms=4)
            ax.plot([fx, s.feet[i, 0]], [fy, s.feet[i, 1]], "-", color=color, lw=0.4)
        ax.arrow(fx, fy, 0.04 * np.cos(fyaw), 0.04 * np.sin(fyaw), color=color, width=0.002)
    handles = [
        plt.Line2D([], [], ls="", marker=m, color="k", label=f"{leg} foot") for leg, m in LEG_MARKS
    ]
    handles.append(plt.Line2D([], [], color="k", label="matched frame x axis (arrow)"))
    if changed_from is not None:
        ax.axvline(changed_from, color="tab:red", ls="--", lw=1.0)
        handles.append(plt.Line2D([], [], color="tab:red", ls="--", label="modified from here"))
    if result.steps:
        sm = plt.cm.ScalarMappable(cmap=cmap, norm=plt.Normalize(0.0, vmax))
        fig.colorbar(sm, ax=ax, label="match cost (PCA distance)", shrink=0.8)
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=3, fontsize=6)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_aspect("equal")
    n_steps = len(result.source_frames)
    ax.set_title(
        title
        or f"{len(result.steps)} placements of {n_steps} steps; "
        f"{len(result.matches.discarded)} discarded",
        fontsize=8,
    )
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=130, bbox_inches="tight")
    plt.close(fig)
    return out


def library_path_figure(
    board: TerrainBoard,
    transferred,
    final,
    path: str | Path,
    *,
    changed_from: float | None = None,
    goal: float | None = None,
    title: str = "",
    resolution: float = 0.004,
    links=(),
) -> Path:
    """Writes a PNG of a transferred library and the search's final library over the height map.

    Every transferred step is drawn at its start (feet centroid, arrow along its
    heading, grey-blue), recorded chain links ``links`` (pairs of indices into
    ``transferred``, e.g. ``LibraryTransfer.links``) as cyan lines between their
    starts; the final library's steps are joined in execution order at their starts'
    feet centroids, recorded ones as green circles and planned ones as orange squares
    (like Stolle et al.'s Figs. 11-12), up to the end of the last step (a red cross).
    Either library may be None (nothing transferred / no search).

    Raises:
        TransferError: not a board, or a non-positive resolution.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if not isinstance(board, TerrainBoard):
        raise TransferError("library_path_figure needs a TerrainBoard")
    if not resolution > 0.0:
        raise TransferError(f"resolution must be positive, got {resolution}")
    x0, x1, y0, y1 = board.bounds()  # the boxes' extent (a moved or joined board too)
    hx, hy = 0.5 * (x1 - x0), 0.5 * (y1 - y0)
    x = np.arange(x0, x1 + 1e-9, resolution)
    y = np.arange(y0, y1 + 1e-9, resolution)
    X, Y = np.meshgrid(x, y)
    fig, ax = plt.subplots(figsize=(2.0 + 6.0 * hx / max(hx, hy), 1.4 + 6.0 * hy / max(hx, hy)))
    im = ax.imshow(
        board.height(X, Y) * 100.0,
        origin="lower",
        extent=(x0, x1, y0, y1),
        cmap="Greys",
        interpolation="nearest",
    )
    fig.colorbar(im, ax=ax, label="terrain height (cm)", shrink=0.8)
    handles = []
    if transferred is not None:
        for s in transferred:
            c = s.start_feet[:, :2].mean(axis=0)
            yaw = s.start_pose[5]
            ax.arrow(*c, 0.03 * np.cos(yaw), 0.03 * np.sin(yaw), color="tab:blue", width=0.0015)
        handles.append(
            plt.Line2D([], [], color="tab:blue", label=f"transferred step ({len(transferred)})")
        )
        links = list(links)
        for a, b in links:
            p = np.array([transferred[int(k)].start_feet[:, :2].mean(axis=0) for k in (a, b)])
            ax.plot(p[:, 0], p[:, 1], "-", color="tab:cyan", lw=1.6)
        if links:
            handles.append(
                plt.Line2D([], [], color="tab:cyan", label=f"recorded chain link ({len(links)})")
            )
    if final is not None:
        from repertoire.planning.transfer_library import step_end_feet

        cs = np.array([s.start_feet[:, :2].mean(axis=0) for s in final])
        end = step_end_feet(final[-1])[:, :2].mean(axis=0)
        route = np.vstack([cs, end])
        ax.plot(route[:, 0], route[:, 1], "-", color="tab:red", lw=1.0)
        ax.plot(*end, "x", color="tab:red", ms=9, mew=2.5)
        handles.append(
            plt.Line2D([], [], color="tab:red", label="final library, in order (feet centroid)")
        )
        handles.append(
            plt.Line2D(
                [], [], ls="", marker="x", color="tab:red", mew=2, label="end of the last step"
            )
        )
        for kind, mark, colour in (("recorded", "o", "tab:green"), ("planned", "s", "tab:orange")):
            sel = np.array([s.kind == kind for s in final])
            if sel.any():
                ax.plot(cs[sel, 0], cs[sel, 1], mark, color=colour, ms=4)
            handles.append(
                plt.Line2D(
                    [], [], ls="", marker=mark, color=colour, label=f"{kind} step ({sel.sum()})"
                )
            )
    if changed_from is not None:
        ax.axvline(changed_from, color="tab:red", ls="--", lw=1.0)
        handles.append(plt.Line2D([], [], color="tab:red", ls="--", label="modified from here"))
    if goal is not None:
        ax.axvline(goal, color="tab:purple", ls=":", lw=1.2)
        handles.append(
            plt.Line2D([], [], color="tab:purple", ls=":", label="goal line (front feet)")
        )
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.15), ncol=2, fontsize=7)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_aspect("equal")
    ax.set_title(title, fontsize=8)
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=130, bbox_inches="tight")
    plt.close(fig)
    return out
