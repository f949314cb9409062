"""Terrain features and PCA matching for library transfer (Stolle et al., section V).

A step's local terrain is the height profile around the centroid of its four
feet at the step's start: 464 samples on a regular grid of 0.35 m x 0.20 m at
0.012 m, in a frame whose x axis points from the centre of the rear feet to the
centre of the front feet and whose z axis is the world's, with the mean of the
464 heights subtracted. The count: ``floor(0.35 / 0.012) = 29`` samples along x
(spanning 0.336 m) times ``floor(0.20 / 0.012) = 16`` along y (0.18 m) gives
29 x 16 = 464, the paper's length; a 0.012 m grid that covered the full 0.35 m
would need 30 x 17 = 510 samples.

On a new terrain the same profile is computed for candidate frames over a grid
of positions and yaws in [-pi/4, pi/4] (all frames in one vectorised call),
projected with a PCA fitted on board features (components up to 95 % of the
variance; the paper kept 32), and each step is matched to the frame nearest in
PCA space; matches above a threshold are discarded. A step may also match more
than once: local minima of its match cost at least ``min_spacing`` apart (the
paper's section VII asks for it). Steps are re-expressed in the matched frame by
a planar rigid transform (plus the difference of the profiles' mean heights);
joint-angle actions do not change.

Frames (``(N, 3)`` arrays) are ``[x, y, yaw]`` in the world; the frame's height
is the mean terrain height of its profile.
"""

import dataclasses
import math
import time

import numpy as np
from repertoire.models.terrain import TerrainBoard

from repertoire.errors import RepertoireError
from repertoire.limits import require_memory

PROFILE_LENGTH = 0.35
PROFILE_WIDTH = 0.20
PROFILE_RESOLUTION = 0.012
PROFILE_NX = int(math.floor(PROFILE_LENGTH / PROFILE_RESOLUTION + 1e-9))
PROFILE_NY = int(math.floor(PROFILE_WIDTH / PROFILE_RESOLUTION + 1e-9))
PROFILE_SIZE = PROFILE_NX * PROFILE_NY
"""Samples per profile: 29 x 16 = 464."""

FRONT_FEET = (0, 1)
REAR_FEET = (2, 3)
"""Indices of the front (lf, rf) and rear (lh, rh) feet in ``LEGS`` order."""

_CHUNK_POINTS = 100_000
"""Profile samples per chunk of :func:`terrain_features` (small chunks stay in cache:
2.5x faster than 500k on the 160-match refinement)."""


class TransferError(RepertoireError):
    """Bad input to terrain features, matching or transfer."""


def profile_offsets() -> np.ndarray:
    """Local (u, v) of the 464 profile samples, shape (464, 2), row-major over (v, u).

    The grid is centred on the frame origin, spaced ``PROFILE_RESOLUTION``.
    """
    u = (np.arange(PROFILE_NX) - 0.5 * (PROFILE_NX - 1)) * PROFILE_RESOLUTION
    v = (np.arange(PROFILE_NY) - 0.5 * (PROFILE_NY - 1)) * PROFILE_RESOLUTION
    U, V = np.meshgrid(u, v)
    return np.stack([U.ravel(), V.ravel()], axis=-1)


def _as_frames(frames) -> np.ndarray:
    f = np.asarray(frames, dtype=float)
    if f.ndim == 1:
        f = f[None, :]
    if f.ndim != 2 or f.shape[1] != 3 or not np.all(np.isfinite(f)):
        raise TransferError(
            f"frames must be a finite (N, 3) array of [x, y, yaw], got shape {np.shape(frames)}"
        )
    return f


def stance_frame(feet) -> np.ndarray:
    """The local feature frame of a stance (or of many stances at once).

    Args:
        feet: foot centres in the world, shape (4, 3) or (N, 4, 3), ``LEGS`` order
            (lf, rf, lh, rh).

    Returns:
        ``[x, y, yaw]`` (shape (3,) or (N, 3)): the feet's xy centroid and the heading
        of the vector from the rear-feet centre to the front-feet centre.

    Raises:
        TransferError: wrong shape, non-finite values, or front and rear centres
            coinciding (no heading).
    """
    p = np.asarray(feet, dtype=float)
    single = p.ndim == 2
    if single:
        p = p[None]
    if p.ndim != 3 or p.shape[1:] != (4, 3) or not np.all(np.isfinite(p)):
        raise TransferError(
            f"feet must be finite (4, 3) or (N, 4, 3) arrays, got shape {np.shape(feet)}"
        )
    centroid = p[:, :, :2].mean(axis=1)
    axis = p[:, FRONT_FEET, :2].mean(axis=1) - p[:, REAR_FEET, :2].mean(axis=1)
    if np.any(np.hypot(axis[:, 0], axis[:, 1]) < 1e-6):
        raise TransferError("front and rear feet centres coincide: the stance has no heading")
    out = np.column_stack([centroid, np.arctan2(axis[:, 1], axis[:, 0])])
    return out[0] if single else out


def terrain_bounds(board: TerrainBoard) -> tuple[float, float, float, float]:
    """The board's extent ``(x_min, x_max, y_min, y_max)`` in the world (m).

    :meth:`TerrainBoard.bounds`: the bounding rectangle of the board's boxes, so a
    joined (:func:`~repertoire.models.terrain.join_boards`) or moved board gets its true
    extent, not the one its ``params`` give a board centred on the origin.

    Raises:
        TransferError: the board has no boxes.
    """
    try:
        return board.bounds()
    except RepertoireError as e:
        raise TransferError(str(e)) from e


@dataclasses.dataclass
class Features:
    """Profiles of a set of frames.

    Attributes:
        frames: the frames, (N, 3) ``[x, y, yaw]``.
        values: mean-subtracted heights, (N, 464); rows of off-terrain frames are NaN
            (not computed).
        mean_height: mean terrain height of each profile (m), (N,); NaN off the terrain.
        on_terrain: True where every sample of the profile lies on the board, (N,).
    """

    frames: np.ndarray
    values: np.ndarray
    mean_height: np.ndarray
    on_terrain: np.ndarray

    @property
    def off_terrain_count(self) -> int:
        """Number of frames whose profile leaves the board."""
        return int(np.count_nonzero(~self.on_terrain))


def terrain_features(board: TerrainBoard, frames) -> Features:
    """Profiles of all ``frames`` on ``board`` in one vectorised call.

    Heights come from the board's exact height function. Distinct frames are processed
    once, sorted, in chunks; each chunk evaluates only the boxes whose footprint can reach it.
    Profiles that leave the board are reported in ``on_terrain`` (their rows NaN, not
    computed), not refused.

    Args:
        board: the terrain.
        frames: (N, 3) or (3,) ``[x, y, yaw]``.

    Raises:
        TransferError: malformed frames or not a board.
        ResourceLimitError: the (N, 464) result would exceed the memory limit.
    """
    if not isinstance(board, TerrainBoard):
        raise TransferError(f"terrain_features needs a TerrainBoard, got {type(board).__name__}")
    f = _as_frames(frames)
    n = f.shape[0]
    require_memory(4 * n * PROFILE_SIZE * 8, f"terrain features of {n} frames")
    offsets = profile_offsets()
    x0, x1, y0, y1 = terrain_bounds(board)
    eps = 1e-9
    # The profile is a convex rectangle and the board a rectangle: the four corner
    # samples decide whether every sample is on the board.
    corners = offsets[[0, PROFILE_NX - 1, PROFILE_SIZE - PROFILE_NX, PROFILE_SIZE - 1]]
    c, s = np.cos(f[:, 2:3]), np.sin(f[:, 2:3])
    cx = f[:, 0:1] + c * corners[:, 0] - s * corners[:, 1]
    cy = f[:, 1:2] + s * corners[:, 0] + c * corners[:, 1]
    on = np.all((cx >= x0 - eps) & (cx <= x1 + eps) & (cy >= y0 - eps) & (cy <= y1 + eps), axis=1)
    # Equal frames have equal profiles: each distinct one once, sorted by x (compact chunks).
    unique, inverse = np.unique(f[on], axis=0, return_inverse=True)
    heights = np.empty((unique.shape[0] + 1, PROFILE_SIZE))
    heights[-1] = np.nan  # the rows of frames off the board
    radii = [0.5 * math.hypot(b.size[0], b.size[1]) for b in board.boxes]
    chunk = max(1, _CHUNK_POINTS // PROFILE_SIZE)
    for a in range(0, unique.shape[0], chunk):
        fc = unique[a : a + chunk]
        c, s = np.cos(fc[:, 2:3]), np.sin(fc[:, 2:3])
        px = fc[:, 0:1] + c * offsets[:, 0] - s * offsets[:, 1]
        py = fc[:, 1:2] + s * offsets[:, 0] + c * offsets[:, 1]
        lo_x, hi_x, lo_y, hi_y = px.min(), px.max(), py.min(), py.max()
        boxes = [
            b
            for b, r in zip(board.boxes, radii)
            if b.center[0] + r >= lo_x
            and b.center[0] - r <= hi_x
            and b.center[1] + r >= lo_y
            and b.center[1] - r <= hi_y
        ]
        local = TerrainBoard(params=board.params, seed=board.seed, boxes=boxes)
        heights[a : a + len(fc)] = local.height(px, py)
    index = np.full(n, unique.shape[0])
    index[on] = inverse.ravel()
    values = heights[index]
    mean = values.mean(axis=1)
    values -= mean[:, None]
    return Features(frames=f, values=values, mean_height=mean, on_terrain=on)


def candidate_frames(
    board: TerrainBoard,
    spacing: float = 0.02,
    yaw_count: int = 13,
    yaw_range: float = math.pi / 4,
    margin: float = 0.5 * PROFILE_NY * PROFILE_RESOLUTION,
) -> np.ndarray:
    """Candidate frames over the board: a position grid times yaws in [-range, range].

    Positions cover the board's extent shrunk by ``margin`` at ``spacing`` (centred);
    the default margin is half the profile's width, closer to the edge than which no
    profile fits at any yaw. Frames are ordered position-major so that neighbouring
    rows are close in space.

    Args:
        board: the terrain.
        spacing: grid spacing of positions (m), > 0.
        yaw_count: number of yaws, evenly spaced over [-yaw_range, yaw_range] (>= 1;
            1 gives yaw 0).
        yaw_range: half range of the yaws (rad), in [0, pi].
        margin: distance kept from the board's edges (m), >= 0.

    Returns:
        (N, 3) ``[x, y, yaw]``.

    Raises:
        TransferError: non-positive spacing, bad yaw count, range or margin.
    """
    if not isinstance(board, TerrainBoard):
        raise TransferError(f"candidate_frames needs a TerrainBoard, got {type(board).__name__}")
    if not (math.isfinite(spacing) and spacing > 0.0):
        raise TransferError(f"candidate frame spacing must be a positive length, got {spacing}")
    if int(yaw_count) != yaw_count or yaw_count < 1:
        raise TransferError(f"yaw_count must be a positive integer, got {yaw_count}")
    if not (math.isfinite(yaw_range) and 0.0 <= yaw_range <= math.pi):
        raise TransferError(f"yaw_range must be in [0, pi], got {yaw_range}")
    x0, x1, y0, y1 = terrain_bounds(board)
    if not (math.isfinite(margin) and 0.0 <= 2.0 * margin < min(x1 - x0, y1 - y0)):
        raise TransferError(
            f"candidate margin must be >= 0 and leave part of the board, got {margin}"
        )
    x0, x1, y0, y1 = x0 + margin, x1 - margin, y0 + margin, y1 - margin
    nx = int(math.floor((x1 - x0) / spacing + 1e-9)) + 1
    ny = int(math.floor((y1 - y0) / spacing + 1e-9)) + 1
    require_memory(nx * ny * int(yaw_count) * 3 * 8, "candidate frames")
    xs = 0.5 * (x0 + x1) + (np.arange(nx) - 0.5 * (nx - 1)) * spacing
    ys = 0.5 * (y0 + y1) + (np.arange(ny) - 0.5 * (ny - 1)) * spacing
    yaws = np.linspace(-yaw_range, yaw_range, int(yaw_count)) if yaw_count > 1 else np.zeros(1)
    X, Y, T = np.meshgrid(xs, ys, yaws, indexing="ij")
    return np.column_stack([X.ravel(), Y.ravel(), T.ravel()])


@dataclasses.dataclass
class FeaturePCA:
    """A PCA basis of profiles (from an SVD of the centred feature matrix).

    Attributes:
        mean: mean profile (464,).
        components: principal directions, (k, 464), rows orthonormal.
        explained: fraction of the variance each kept component explains, (k,).
    """

    mean: np.ndarray
    components: np.ndarray
    explained: np.ndarray

    @property
    def size(self) -> int:
        return int(self.components.shape[0])

    def project(self, values) -> np.ndarray:
        """PCA coordinates of profiles (N, 464) -> (N, k)."""
        v = np.asarray(values, dtype=float)
        if v.ndim != 2 or v.shape[1] != self.mean.shape[0]:
            raise TransferError(
                f"profiles to project must be (N, {self.mean.shape[0]}), got {v.shape}"
            )
        return (v - self.mean) @ self.components.T


def fit_pca(values, variance: float = 0.95, max_components: int | None = None) -> FeaturePCA:
    """Fits the PCA basis keeping the fewest components that reach ``variance``.

    Args:
        values: profiles (N, 464), N >= 2, on-terrain ones.
        variance: fraction of the total variance to keep, in (0, 1].
        max_components: optional cap on the number of components.

    Raises:
        TransferError: too few or non-finite profiles, bad variance, no variance at all.
    """
    v = np.asarray(values, dtype=float)
    if v.ndim != 2 or v.shape[0] < 2 or not np.all(np.isfinite(v)):
        raise TransferError(f"fit_pca needs a finite (N>=2, D) profile matrix, got {v.shape}")
    if not (0.0 < variance <= 1.0):
        raise TransferError(f"PCA variance fraction must be in (0, 1], got {variance}")
    mean = v.mean(axis=0)
    _, s, vt = np.linalg.svd(v - mean, full_matrices=False)
    energy = s**2
    total = energy.sum()
    if total <= 1e-18:
        raise TransferError("fit_pca: the profiles have no variance (all terrain identical)")
    ratio = energy / total
    k = int(np.searchsorted(np.cumsum(ratio), variance - 1e-12) + 1)
    k = min(k, len(s))
    if max_components is not None:
        if int(max_components) != max_components or max_components < 1:
            raise TransferError(f"max_components must be a positive integer, got {max_components}")
        k = min(k, int(max_components))
    return FeaturePCA(mean=mean, components=vt[:k].copy(), explained=ratio[:k].copy())


@dataclasses.dataclass(frozen=True)
class Match:
    """One placement of a step on the new terrain.

    Attributes:
        step: index of the step.
        frame: the matched frame ``[x, y, yaw]``.
        height: mean terrain height of the matched profile (m).
        cost: distance in PCA space.
    """

    step: int
    frame: np.ndarray
    height: float
    cost: float


@dataclasses.dataclass
class MatchResult:
    """Matches of all steps.

    Attributes:
        matches: kept matches, sorted by step then cost.
        discarded: indices of steps with no match under the threshold.
        candidate_count: number of candidate frames considered (on the terrain).
        off_terrain_count: candidate frames dropped because their profile left the board.
    """

    matches: list[Match]
    discarded: list[int]
    candidate_count: int
    off_terrain_count: int


def _pairwise_sq(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    d = (a * a).sum(1)[:, None] + (b * b).sum(1)[None, :] - 2.0 * a @ b.T
    return np.maximum(d, 0.0)


def match_steps(
    step_values,
    candidates: Features,
    pca: FeaturePCA,
    threshold: float,
    *,
    multiple: bool = False,
    min_spacing: float = 0.1,
    max_matches: int = 8,
) -> MatchResult:
    """Matches each step's profile to the candidate frames nearest in PCA space.

    Args:
        step_values: the steps' profiles (S, 464) (``terrain_features(...).values``
            on the source terrain).
        candidates: features of the candidate frames on the new terrain; frames off the
            terrain are skipped and counted.
        pca: the PCA basis.
        threshold: matches with a PCA distance above it are discarded (> 0).
        multiple: keep every local minimum of a step's cost (greedy, best first) at least
            ``min_spacing`` apart in position, up to ``max_matches``; otherwise the best one.
        min_spacing: minimum distance between two matches of one step (m).
        max_matches: cap on matches per step when ``multiple``.

    Raises:
        TransferError: bad shapes, threshold, spacing, or no candidate on the terrain.
    """
    sv = np.asarray(step_values, dtype=float)
    if sv.ndim != 2 or sv.shape[1] != PROFILE_SIZE or not np.all(np.isfinite(sv)):
        raise TransferError(f"step profiles must be finite (S, {PROFILE_SIZE}), got {sv.shape}")
    if not (math.isfinite(threshold) and threshold > 0.0):
        raise TransferError(f"match threshold must be positive, got {threshold}")
    if not (math.isfinite(min_spacing) and min_spacing > 0.0):
        raise TransferError(f"min_spacing must be a positive length, got {min_spacing}")
    if int(max_matches) != max_matches or max_matches < 1:
        raise TransferError(f"max_matches must be a positive integer, got {max_matches}")
    keep = np.flatnonzero(candidates.on_terrain)
    if keep.size == 0:
        raise TransferError(
            f"no candidate frame lies fully on the terrain ({candidates.off_terrain_count} "
            "frames all leave it); use a larger terrain or a finer candidate grid"
        )
    frames = candidates.frames[keep]
    heights = candidates.mean_height[keep]
    require_memory(sv.shape[0] * keep.size * 8 * 2, "step x candidate match costs")
    cost = np.sqrt(_pairwise_sq(pca.project(sv), pca.project(candidates.values[keep])))
    matches: list[Match] = []
    discarded: list[int] = []
    for i in range(sv.shape[0]):
        row = cost[i]
        order = np.argsort(row, kind="stable")
        order = order[row[order] <= threshold]
        if order.size == 0:
            discarded.append(i)
            continue
        if not multiple:
            chosen = [order[0]]
        else:
            chosen = []
            for j in order:
                if (
                    chosen
                    and np.min(np.hypot(*(frames[chosen, :2] - frames[j, :2]).T)) < min_spacing
                ):
                    continue
                chosen.append(j)
                if len(chosen) >= max_matches:
                    break
        for j in chosen:
            matches.append(Match(i, frames[j].copy(), float(heights[j]), float(row[j])))
    return MatchResult(
        matches=matches,
        discarded=discarded,
        candidate_count=int(keep.size),
        off_terrain_count=candidates.off_terrain_count,
    )


def wrap_angle(a):
    """Angle(s) wrapped to [-pi, pi)."""
    return (np.asarray(a, dtype=float) + math.pi) % (2.0 * math.pi) - math.pi


def transfer_stance(feet, body_pose, source_frame, source_height, target_frame, target_height):
    """Re-expresses a stance from its source frame in a target frame (planar + height).

    Points are written in the source frame (local x along the source yaw, z from the
    source profile's mean height) and read back in the target frame. Under a rotation
    about the world z axis, a body pose's roll and pitch (``R = Rz(yaw) Ry(pitch)
    Rx(roll)``) do not change and its yaw gains the frames' yaw difference.

    Args:
        feet: foot centres (..., 3), e.g. (4, 3) or (T, 4, 3).
        body_pose: body poses [x, y, z, roll, pitch, yaw], (..., 6).
        source_frame: ``[x, y, yaw]`` of the step's own frame.
        source_height: mean terrain height of the source profile (m).
        target_frame: ``[x, y, yaw]`` of the matched frame.
        target_height: mean terrain height of the matched profile (m).

    Returns:
        ``(feet, body_pose)`` in the world at the target frame.

    Raises:
        TransferError: wrong shapes or non-finite values.
    """
    p = np.asarray(feet, dtype=float)
    q = np.asarray(body_pose, dtype=float)
    fs = np.asarray(source_frame, dtype=float)
    ft = np.asarray(target_frame, dtype=float)
    if p.shape[-1:] != (3,) or q.shape[-1:] != (6,) or fs.shape != (3,) or ft.shape != (3,):
        raise TransferError(
            "transfer_stance needs feet (..., 3), poses (..., 6) and frames [x, y, yaw]; got "
            f"{p.shape}, {q.shape}, {fs.shape}, {ft.shape}"
        )
    values = [p, q, fs, ft, np.array([source_height, target_height], dtype=float)]
    if not all(np.all(np.isfinite(v)) for v in values):
        raise TransferError("transfer_stance needs finite feet, poses, frames and heights")
    d = ft[2] - fs[2]
    c, s = math.cos(d), math.sin(d)
    R = np.array([[c, -s], [s, c]])
    dz = float(target_height) - float(source_height)

    def move(points):
        out = points.copy()
        out[..., :2] = (points[..., :2] - fs[:2]) @ R.T + ft[:2]
        out[..., 2] = points[..., 2] + dz
        return out

    new_feet = move(p)
    new_pose = q.copy()
    new_pose[..., :3] = move(q[..., :3])
    new_pose[..., 5] = wrap_angle(q[..., 5] + d)
    return new_feet, new_pose


def refine_matches(
    board: TerrainBoard,
    step_values,
    result: MatchResult,
    pca: FeaturePCA,
    spacing: float,
    yaw_step: float,
    levels: int = 3,
    *,
    yaw_range: float | None = None,
) -> MatchResult:
    """Refines each match below the candidate grid's resolution (exact features).

    At each level the 3 x 3 x 3 frames around the current best (steps of half the
    current spacing and yaw step) are evaluated for all matches at once, the best kept,
    and the steps halved again. Costs never increase. (A 7-point pattern search along
    the axes is 3x cheaper but stalls: the cost is piecewise constant where samples
    cross box edges.)

    Args:
        board: the terrain the matches are on.
        step_values: the steps' profiles (S, 464) used for ``result``.
        result: coarse matches.
        pca: the PCA basis used for ``result``.
        spacing: the candidate grid's position spacing (m).
        yaw_step: the candidate grid's yaw step (rad).
        levels: number of halvings (>= 1).
        yaw_range: if given, trial yaws are kept in [-yaw_range, yaw_range] (the
            candidate grid's range), so refinement does not leave it.

    Raises:
        TransferError: bad step sizes, level count or yaw range.
    """
    if not (spacing > 0.0 and yaw_step >= 0.0 and math.isfinite(spacing + yaw_step)):
        raise TransferError(f"refine needs spacing > 0, yaw_step >= 0; got {spacing}, {yaw_step}")
    if int(levels) != levels or levels < 1:
        raise TransferError(f"refine levels must be a positive integer, got {levels}")
    if yaw_range is not None and not (math.isfinite(yaw_range) and yaw_range >= 0.0):
        raise TransferError(f"refine yaw_range must be >= 0 rad, got {yaw_range}")
    if not result.matches:
        return result
    sv = pca.project(np.asarray(step_values, dtype=float))
    steps = np.array([m.step for m in result.matches])
    best = np.array([m.frame for m in result.matches])
    cost = np.array([m.cost for m in result.matches])
    height = np.array([m.height for m in result.matches])
    g = np.array(np.meshgrid([-1, 0, 1], [-1, 0, 1], [-1, 0, 1], indexing="ij")).reshape(3, -1).T
    h = np.array([spacing, spacing, yaw_step], dtype=float)
    for _ in range(int(levels)):
        h = 0.5 * h
        trial = (best[:, None, :] + g[None] * h).reshape(-1, 3)
        if yaw_range is not None:
            trial[:, 2] = np.clip(trial[:, 2], -yaw_range, yaw_range)
        feats = terrain_features(board, trial)
        z = pca.project(feats.values).reshape(len(best), len(g), -1)
        c = np.linalg.norm(z - sv[steps][:, None, :], axis=2)
        c[~feats.on_terrain.reshape(len(best), len(g))] = np.inf
        j = np.argmin(c, axis=1)
        rows = np.arange(len(best))
        better = c[rows, j] < cost
        best[better] = trial.reshape(len(best), len(g), 3)[rows, j][better]
        height[better] = feats.mean_height.reshape(len(best), len(g))[rows, j][better]
        cost[better] = c[rows, j][better]
    matches = [
        Match(int(steps[i]), best[i].copy(), float(height[i]), float(cost[i]))
        for i in range(len(best))
    ]
    return dataclasses.replace(result, matches=matches)


@dataclasses.dataclass
class TransferConfig:
    """Settings of a library transfer (YAML-loadable).

    Attributes:
        spacing: candidate position spacing (m).
        yaw_count: candidate yaws over [-yaw_range, yaw_range].
        yaw_range: half range of candidate yaws (rad).
        threshold: PCA distance above which a match is discarded (after refinement).
        coarse_factor: the candidate-grid match keeps costs up to ``coarse_factor *
            threshold`` (the grid misses the exact place by up to half a cell), then
            refinement and the final threshold decide.
        multiple: keep several matches per step (local minima of the cost).
        min_spacing: minimum distance between two matches of one step (m).
        max_matches: cap on matches per step when ``multiple`` (chain matches included).
        refine_levels: sub-grid refinement levels (0 = none).
        chains: with ``multiple``, also match along the recorded chains: a step that
            continues (or precedes) a matched step in its demonstration is offered at the
            frame that continues the chain (``transfer_library``).
        chain_join: foot-location distance (sum over the feet, m) under which one step's
            end and the next step's start form a chain, in the source library and on the
            new terrain.
        support_tolerance: a placed step is kept only if its terrain supports it the way
            its source did (``transfer_library``): each stance and landing foot stands
            this close (m) to its recorded height above the ground (about half the foot
            radius, 10.3 mm; 0 = exact) on ground flat by the footstep planner's rule
            where its source ground was, and the swing foot sinks no deeper into the
            new ground than into its source (beyond this tolerance).
    """

    spacing: float = 0.02
    yaw_count: int = 13
    yaw_range: float = math.pi / 4
    threshold: float = 0.05
    coarse_factor: float = 5.0
    multiple: bool = False
    min_spacing: float = 0.1
    max_matches: int = 8
    refine_levels: int = 6
    chains: bool = True
    chain_join: float = 0.04
    support_tolerance: float = 0.005

    @property
    def yaw_step(self) -> float:
        """Spacing of the candidate yaws (rad); 0 for a single yaw (yaw 0 only)."""
        return 2.0 * self.yaw_range / (self.yaw_count - 1) if self.yaw_count > 1 else 0.0


@dataclasses.dataclass
class TransferredStep:
    """A step placed on the new terrain.

    Attributes:
        step: index of the source step.
        feet: foot centres at the step's start on the new terrain (4, 3).
        body_pose: body pose [x, y, z, roll, pitch, yaw] at the start on the new terrain.
        match: the match that placed it.
    """

    step: int
    feet: np.ndarray
    body_pose: np.ndarray
    match: Match


@dataclasses.dataclass
class TransferResult:
    """Outcome of :func:`transfer_steps`.

    Attributes:
        steps: the transferred steps (a step may appear more than once).
        matches: the matching result (discarded steps, candidate counts).
        source_frames: each source step's own frame (S, 3).
        source_heights: each source step's profile mean height (S,).
        timings: wall seconds of ``candidates``, ``features``, ``matching``, ``refine``.
        off_source: steps whose profile leaves their own (source) terrain: not matched
            (reported, also listed in ``matches.discarded``).
        step_values: the steps' profiles on their source terrain (S, 464), zeros for
            ``off_source`` steps.
    """

    steps: list[TransferredStep]
    matches: MatchResult
    source_frames: np.ndarray
    source_heights: np.ndarray
    timings: dict[str, float]
    off_source: list[int]
    step_values: np.ndarray | None = None


def target_candidates(target: TerrainBoard, config: TransferConfig) -> tuple[Features, dict]:
    """Candidate frames of ``config`` on ``target`` and their features, with wall times.

    Computed once per target terrain and shared by every source terrain's steps.
    """
    t0 = time.perf_counter()
    cand = candidate_frames(target, config.spacing, config.yaw_count, config.yaw_range)
    t1 = time.perf_counter()
    feats = terrain_features(target, cand)
    return feats, {"candidates": t1 - t0, "features": time.perf_counter() - t1}


def transfer_steps(
    source: TerrainBoard,
    start_feet,
    start_poses,
    target: TerrainBoard,
    pca: FeaturePCA,
    config: TransferConfig | None = None,
    candidates: Features | None = None,
) -> TransferResult:
    """Transfers steps recorded on ``source`` onto ``target`` (section V of the paper).

    Args:
        source: the terrain the steps were recorded on (required: their profiles are
            read from it).
        start_feet: the steps' start foot centres (S, 4, 3), ``LEGS`` order.
        start_poses: the steps' start body poses (S, 6).
        target: the new terrain.
        pca: PCA basis of board profiles (:func:`fit_pca`).
        config: transfer settings.
        candidates: the candidate frames' features on ``target``
            (:func:`target_candidates` with the same ``config``); computed here if None
            (then ``timings`` include their time, else those entries are 0).

    Raises:
        TransferError: missing source terrain, bad shapes or bad settings. Steps whose
            profile leaves their own terrain are reported in ``off_source``, not refused.
    """
    config = TransferConfig() if config is None else config
    if not (math.isfinite(config.coarse_factor) and config.coarse_factor >= 1.0):
        raise TransferError(f"coarse_factor must be >= 1, got {config.coarse_factor}")
    if not isinstance(source, TerrainBoard):
        raise TransferError(
            "transfer_steps needs the steps' source terrain (a TerrainBoard) to read their "
            f"profiles; got {type(source).__name__}"
        )
    feet = np.asarray(start_feet, dtype=float)
    poses = np.asarray(start_poses, dtype=float)
    if feet.ndim != 3 or poses.shape != (feet.shape[0], 6):
        raise TransferError(
            f"start_feet must be (S, 4, 3) and start_poses (S, 6); got {feet.shape}, {poses.shape}"
        )
    frames = stance_frame(feet)
    own = terrain_features(source, frames)
    off_source = np.flatnonzero(~own.on_terrain).tolist()
    # Steps off their own terrain have no profile (NaN rows): matched as flat, then dropped.
    step_values = np.where(own.on_terrain[:, None], own.values, 0.0)
    if candidates is None:
        feats, timings = target_candidates(target, config)
    else:
        feats, timings = candidates, {"candidates": 0.0, "features": 0.0}
    t2 = time.perf_counter()
    result = match_steps(
        step_values,
        feats,
        pca,
        config.threshold * config.coarse_factor,
        multiple=config.multiple,
        min_spacing=config.min_spacing,
        max_matches=config.max_matches,
    )
    t3 = time.perf_counter()
    if config.refine_levels:
        result = refine_matches(
            target,
            step_values,
            result,
            pca,
            config.spacing,
            config.yaw_step,
            config.refine_levels,
            yaw_range=config.yaw_range,
        )
    kept = [m for m in result.matches if m.cost <= config.threshold and m.step not in off_source]
    matched = {m.step for m in kept}
    result = dataclasses.replace(
        result,
        matches=kept,
        discarded=[i for i in range(feet.shape[0]) if i not in matched],
    )
    t4 = time.perf_counter()
    placed = []
    for m in result.matches:
        f, p = transfer_stance(
            feet[m.step], poses[m.step], frames[m.step], own.mean_height[m.step], m.frame, m.height
        )
        placed.append(TransferredStep(m.step, f, p, m))
    timings.update(matching=t3 - t2, refine=t4 - t3)
    return TransferResult(placed, result, frames, own.mean_height, timings, off_source, step_values)


def stances_on_terrain(board: TerrainBoard, poses, stride=None) -> tuple[np.ndarray, np.ndarray]:
    """LittleDog stances standing on ``board`` at planar body poses (no physics).

    Each foot is placed at its nominal xy under the body (``nominal_foot_positions``,
    optionally shifted forward by ``stride[i]`` along the body x axis), its sphere
    resting on the board's exact height; the body sits at the nominal standing height
    above the mean foot height, level.

    Args:
        board: the terrain.
        poses: planar body poses [x, y, yaw], (N, 3).
        stride: forward shift of each foot from nominal (N, 4) in m, default zeros.

    Returns:
        ``(feet, body_poses)``: (N, 4, 3) foot centres and (N, 6) poses
        [x, y, z, roll, pitch, yaw].

    Raises:
        TransferError: malformed poses or strides.
    """
    from repertoire.models.littledog import FOOT_RADIUS, STANDING_HEIGHT, nominal_foot_positions

    q = _as_frames(poses)
    n = q.shape[0]
    shift = np.zeros((n, 4)) if stride is None else np.asarray(stride, dtype=float)
    if shift.shape != (n, 4) or not np.all(np.isfinite(shift)):
        raise TransferError(f"stride must be a finite ({n}, 4) array, got {shift.shape}")
    p_B = nominal_foot_positions()[:, :2]
    local = p_B[None] + np.stack([shift, np.zeros_like(shift)], axis=-1)
    c, s = np.cos(q[:, 2:3]), np.sin(q[:, 2:3])
    x = q[:, 0:1] + c * local[..., 0] - s * local[..., 1]
    y = q[:, 1:2] + s * local[..., 0] + c * local[..., 1]
    z = board.height(x, y) + FOOT_RADIUS
    feet = np.stack([x, y, z], axis=-1)
    body = np.zeros((n, 6))
    body[:, :2] = q[:, :2]
    body[:, 2] = z.mean(axis=1) - FOOT_RADIUS + STANDING_HEIGHT
    body[:, 5] = q[:, 2]
    return feet, body
