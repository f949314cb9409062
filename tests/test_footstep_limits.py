"""Step-up/down limits on the exact ground under each sole; swing lines by exact traversal.

Two defects a fuzz campaign found: the step limits compared the highest ground over each
sole's *outer* mask (cells it may overlap, up to ~8 mm beyond it), so a step from a 10 cm
terrace to a sole wholly on the floor beside it passed ``max_step_down=0.05``; and the
swing line was sampled every half cell, so a line clipping a tall cell's corner passed.
"""

import itertools
import math
from fractions import Fraction

import numpy as np
import pytest
from repertoire.planning.footstep import (
    OccupancyGrid,
    PlannerOptions,
    PlanStatus,
    nominal_action_table,
    plan_footsteps,
    plan_footsteps_anytime,
)
from repertoire.planning.footstep.biped_model import BipedStepModel
from repertoire.planning.footstep.environment import rect_overlaps_cells
from repertoire.planning.footstep.fastcore import compiled_tables
from repertoire.planning.footstep.fastkernels import _cell_height, _top_height, swing_crosses
from repertoire.planning.footstep.footprint import FootprintChecker, footprint_masks
from repertoire.planning.footstep.types import FootstepError

HL, HW = 0.08, 0.05  # the ASIMO-like sole's half length and half width
RES = 0.025


def _both(grid, start, foot, goal, **opts):
    """The plan of both backends, asserted identical (poses, costs, statuses, expansions)."""
    opts.setdefault("time_limit", 60.0)
    table = nominal_action_table()
    py, cc = (
        plan_footsteps(grid, start, foot, goal, table, PlannerOptions(backend=b, **opts))
        for b in ("python", "compiled")
    )
    assert py.status is cc.status
    assert py.poses == cc.poses and py.actions == cc.actions and py.times == cc.times
    assert py.cost == cc.cost and py.cost_to_go == cc.cost_to_go
    assert (py.nodes_expanded, py.nodes_generated) == (cc.nodes_expanded, cc.nodes_generated)
    return cc


def _terrace() -> OccupancyGrid:
    """A free 10 cm terrace for x < 1.25 m, the floor (0) beyond; 2.5 m x 1 m, all free."""
    heights = np.zeros((100, 40))
    heights[:50, :] = 0.10
    return OccupancyGrid(np.zeros((100, 40), bool), RES, (0.0, 0.0), heights)


def _top_reference(grid: OccupancyGrid, pose) -> float:
    """Max height over the cells the sole overlaps with positive area, every cell tested."""
    centers = grid.cell_centers().reshape(-1, 2)
    cells = rect_overlaps_cells(pose[:2], (HL, HW), pose[2], centers, RES / 2)
    return float(grid.heights.ravel()[cells.ravel()].max())


def test_top_height_is_the_ground_under_the_sole_not_the_outer_mask():
    grid = _terrace()
    chk = FootprintChecker(grid, footprint_masks(2 * HL, 2 * HW, RES))
    # yaw 0, wholly on the floor 4 mm from the terrace edge (x = 1.25): the outer mask
    # reaches the terrace, the sole does not
    on_floor = (1.25 + HL + 0.004, 0.5, 0.0)
    assert chk.top_height(*on_floor) == 0.0
    assert chk.height_bounds(*on_floor) == (0.0, 0.10)  # the conservative bounds
    # 1 mm onto the terrace, and 1 mm short of it
    assert chk.top_height(1.25 + HL - 0.001, 0.5, 0.0) == 0.10
    assert chk.top_height(1.25 + HL + 0.001, 0.5, 0.0) == 0.0
    # yawed by 0.35 rad: the extent along x is HL cos + HW sin = 0.0923 m
    ext = HL * math.cos(0.35) + HW * math.sin(0.35)
    assert chk.top_height(1.25 + ext - 0.001, 0.5, 0.35) == 0.10
    assert chk.top_height(1.25 + ext + 0.001, 0.5, 0.35) == 0.0
    assert chk.top_height(1.0, 0.5, 1.0) == 0.10  # wholly on the terrace


def _random_heights_model(seed: int):
    """A free 48 x 40 grid of random heights, a compiled-backend model on it, its tables."""
    rng = np.random.default_rng(seed)
    heights = np.round(rng.uniform(0.0, 0.2, (48, 40)), 3)
    grid = OccupancyGrid(np.zeros((48, 40), bool), RES, (0.1, -0.2), heights)
    opts = PlannerOptions(max_step_up=0.05, backend="compiled")
    model = BipedStepModel(grid, (0.5, 0.3, 0.0), "left", (0.9, 0.5), nominal_action_table(), opts)
    return rng, grid, model, compiled_tables(model)


def test_top_height_compiled_equals_python_equals_reference():
    rng, grid, model, tab = _random_heights_model(5)
    args = (tab["grid"], tab["ex"], tab["heights"], tab["ex_off"], tab["ex_ptr"])
    for _ in range(3000):
        pose = (rng.uniform(0.25, 1.05), rng.uniform(-0.05, 0.6), rng.uniform(-4.0, 4.0))
        py = model.exact.top_height(*pose)
        assert _top_height(*pose, *args) == py
        assert py == _top_reference(grid, pose)
        assert py <= model.exact.height_bounds(*pose)[1]


@pytest.mark.parametrize("down", [0.05, 0.0])
def test_terrace_is_unreachable_when_the_drop_exceeds_max_step_down(down):
    # Every sole within the goal tolerance (0.15 m of (1.5, 0.595)) lies wholly on the
    # floor (its centre x >= 1.35, its extent <= hypot(HL, HW) = 0.0943 m), so reaching it
    # needs a step down of 0.10 m at some point. The outer-mask rule returned SUCCESS here.
    plan = _both(
        _terrace(), (0.335, 0.595, 0.0), "left", (1.5, 0.595),
        max_step_down=down, max_step_up=0.05, refinements=0,
    )  # fmt: skip
    assert plan.status is PlanStatus.UNREACHABLE
    grid = _terrace()
    assert all(_top_reference(grid, p) == 0.10 for p in plan.poses)  # never left the terrace


def test_terrace_is_reached_when_max_step_down_allows_the_drop():
    grid = _terrace()
    plan = _both(
        grid, (0.335, 0.595, 0.0), "left", (1.5, 0.595),
        max_step_down=0.10, max_step_up=0.05, refinements=0,
    )  # fmt: skip
    assert plan.status is PlanStatus.SUCCESS
    tops = [_top_reference(grid, p) for p in plan.poses]
    assert tops[0] == 0.10 and tops[-1] == 0.0
    assert all(-0.10 <= b - a <= 0.05 for a, b in zip(tops, tops[1:]))


# ---------------------------------------------------------------- swing line traversal


def _sampled_old(tall, x0, y0, x1, y1, ox, oy, inv):
    """The sampler swing_crosses replaced: points every <= res / 2 (misses corner clips)."""
    n = int(math.hypot(x1 - x0, y1 - y0) * inv * 2.0) + 2
    for k in range(n + 1):
        u = k / n
        i = int(((x0 + u * (x1 - x0)) - ox) * inv)
        j = int(((y0 + u * (y1 - y0)) - oy) * inv)
        if 0 <= i < tall.shape[0] and 0 <= j < tall.shape[1] and tall[i, j]:
            return True
    return False


def test_swing_line_clipping_a_corner_by_1mm_is_refused_and_1mm_outside_accepted():
    tall = np.zeros((10, 10), bool)
    tall[4, 4] = True  # the square [0.1, 0.125]^2
    inv = 1.0 / RES
    d = 0.001 * math.sqrt(2.0)  # lines x + y = 0.2 +- d pass 1 mm from the corner (0.1, 0.1)
    clip = (0.05, 0.15 + d, 0.15 + d, 0.05)  # 1 mm inside: a 2 mm chord through the cell
    miss = (0.05, 0.15 - d, 0.15 - d, 0.05)  # 1 mm outside
    assert swing_crosses(tall, 0.5, *clip, 0.0, 0.0, inv)
    assert not swing_crosses(tall, 0.5, *miss, 0.0, 0.0, inv)
    assert not _sampled_old(tall, *clip, 0.0, 0.0, inv)  # what the fuzz campaign found
    # reversed, and shifted with the map origin
    assert swing_crosses(tall, 0.5, clip[2], clip[3], clip[0], clip[1], 0.0, 0.0, inv)
    assert swing_crosses(tall, 0.5, *(v + 0.3 for v in clip), 0.3, 0.3, inv)
    assert not swing_crosses(tall, 0.5, *(v + 0.3 for v in miss), 0.3, 0.3, inv)


def _crosses_exact(cell, a, b) -> bool:
    """Brute force in exact arithmetic: does the closed segment a-b meet the open square
    (i, i + 1) x (j, j + 1)? (Cell coordinates, the grid's origin at 0 and side 1.)"""
    lo, hi = Fraction(0), Fraction(1)  # the segment's parameters t, closed [0, 1]
    strict_lo, strict_hi = False, False
    for k in range(2):
        p, d = Fraction(a[k]), Fraction(b[k]) - Fraction(a[k])
        c0 = Fraction(int(cell[k]))
        c1 = c0 + 1
        if d == 0:
            if not c0 < p < c1:
                return False
            continue
        t0, t1 = sorted(((c0 - p) / d, (c1 - p) / d))  # open: c0 < p + t d < c1
        if t0 >= lo:
            lo, strict_lo = t0, True
        if t1 <= hi:
            hi, strict_hi = t1, True
    return lo < hi or (lo == hi and not strict_lo and not strict_hi)


def _along_tall_pair(tall, a, b) -> bool:
    """Brute force: does a segment on a grid line run beside a cell tall on both sides of
    it (inside the tall region, though in no single cell's interior)?"""
    n0, n1 = tall.shape
    for k in range(2):  # k: the axis whose coordinate is the same integer at both ends
        if a[k] != b[k] or a[k] != int(a[k]):
            continue
        line, lo, hi = int(a[k]), min(a[1 - k], b[1 - k]), max(a[1 - k], b[1 - k])
        for c in range(math.floor(lo), math.ceil(hi)):
            pair = [(line - 1, c), (line, c)] if k == 0 else [(c, line - 1), (c, line)]
            if all(0 <= p < n0 and 0 <= q < n1 and tall[p, q] for p, q in pair):
                return True
    return False


def _segments(rng, n):
    """Random segments in a 12 x 12 grid, a third of them on grid lines and corners."""
    for k in range(n):
        if k % 3 == 0:  # exact degenerate cases: integer and half-integer coordinates
            a = rng.integers(0, 25, 2) / 2.0
            b = rng.integers(0, 25, 2) / 2.0
        elif k % 3 == 1:  # short swings, as in a plan (a few cells)
            a = rng.uniform(0.0, 12.0, 2)
            b = a + rng.uniform(-4.0, 4.0, 2)
        else:
            a, b = rng.uniform(-1.0, 13.0, 2), rng.uniform(-1.0, 13.0, 2)
        yield (float(a[0]), float(a[1])), (float(b[0]), float(b[1]))


def test_traversal_visits_exactly_the_cells_whose_interior_the_segment_meets():
    rng = np.random.default_rng(11)
    n = 12
    for a, b in _segments(rng, 400):
        for i in range(n):
            for j in range(n):
                tall = np.zeros((n, n), bool)
                tall[i, j] = True
                got = swing_crosses(tall, 0.5, a[0], a[1], b[0], b[1], 0.0, 0.0, 1.0)
                assert got == _crosses_exact((i, j), a, b), (a, b, (i, j))


def test_traversal_against_brute_force_on_random_tall_cells():
    rng = np.random.default_rng(12)
    n = 12
    hits = 0
    for a, b in _segments(rng, 4000):
        tall = rng.random((n, n)) < 0.08
        want = any(_crosses_exact(c, a, b) for c in zip(*np.nonzero(tall)))
        want = want or _along_tall_pair(tall, a, b)
        assert swing_crosses(tall, 0.5, a[0], a[1], b[0], b[1], 0.0, 0.0, 1.0) == want, (a, b)
        hits += want
    assert 1000 < hits < 3000  # both answers well represented


def test_corner_points_grid_lines_and_end_points_touch_no_interior():
    tall = np.ones((4, 4), bool)
    only = np.zeros((4, 4), bool)

    def cells(a, b):
        out = set()
        for i in range(4):
            for j in range(4):
                only[:] = False
                only[i, j] = True
                if swing_crosses(only, 0.5, *a, *b, 0.0, 0.0, 1.0):
                    out.add((i, j))
        return out

    # the diagonal through the corners (1, 1) and (2, 2) enters the diagonal cells only
    assert cells((0.5, 0.5), (2.5, 2.5)) == {(0, 0), (1, 1), (2, 2)}
    assert cells((2.5, 2.5), (0.5, 0.5)) == {(0, 0), (1, 1), (2, 2)}
    assert cells((0.5, 3.5), (3.5, 0.5)) == {(0, 3), (1, 2), (2, 1), (3, 0)}
    # along a grid line: on the boundary of two columns of cells, inside none of them
    assert cells((1.0, 0.2), (1.0, 3.7)) == set()
    assert cells((0.2, 2.0), (3.9, 2.0)) == set()
    # but inside the tall region where both columns are tall (before: a straight walk on a
    # grid line swung through walls of any height)
    assert swing_crosses(tall, 0.5, 1.0, 0.2, 1.0, 3.7, 0.0, 0.0, 1.0)
    assert swing_crosses(tall, 0.5, 0.2, 2.0, 3.9, 2.0, 0.0, 0.0, 1.0)
    wall = np.zeros((4, 4), bool)
    wall[2, 1:3] = True  # beside a tall cell on one side only: touched, not crossed
    assert not swing_crosses(wall, 0.5, 2.0, 0.2, 2.0, 3.7, 0.0, 0.0, 1.0)
    wall[1, 2] = True  # cells (1, 2) and (2, 2) on both sides of x = 2 for 2 < y < 3
    assert swing_crosses(wall, 0.5, 2.0, 0.2, 2.0, 3.7, 0.0, 0.0, 1.0)
    assert not swing_crosses(wall, 0.5, 2.0, 0.2, 2.0, 2.0, 0.0, 0.0, 1.0)  # ends below it
    wall[:] = False
    wall[1:3, 1] = True  # a wall across the line y = 1 ... and its row beyond
    wall[1:3, 0] = True
    assert swing_crosses(wall, 0.5, 0.2, 1.0, 3.5, 1.0, 0.0, 0.0, 1.0)
    assert not swing_crosses(wall, 0.5, 0.2, 2.0, 3.5, 2.0, 0.0, 0.0, 1.0)
    # ending (or starting) on a boundary does not enter the cell beyond it
    assert cells((0.5, 0.5), (1.0, 0.5)) == {(0, 0)}
    assert cells((1.0, 0.5), (1.5, 0.5)) == {(1, 0)}
    assert cells((1.0, 1.0), (2.0, 2.0)) == {(1, 1)}
    # a point strictly inside a cell is in its interior; one on a corner is not
    assert cells((1.5, 2.5), (1.5, 2.5)) == {(1, 2)}
    assert cells((1.0, 2.0), (1.0, 2.0)) == set()
    # outside the grid counts as not tall
    assert not swing_crosses(tall, 0.5, -3.0, -1.0, -0.5, 5.0, 0.0, 0.0, 1.0)


def test_fuzz_scene_swing_lines_cross_no_tall_cell():
    from repertoire.planning.footstep.scenes import random_floor_scene

    sc = random_floor_scene(279829, size=8.0, occupancy=0.3)
    g = sc.grid
    tall = g.occupied & (g.heights > 0.1)
    plan = _both(
        g, sc.start, "left", sc.goal, time_limit=120.0, swing_clearance=0.1,
        max_expansions=200000, heuristic_weight=5.0, footprint_margin_m=0.0,
    )  # fmt: skip
    assert plan.status is PlanStatus.SUCCESS
    swing = [plan.initial_swing_pose] + plan.poses[:-2]
    inv = 1.0 / g.resolution
    ox, oy = g.origin
    for k in range(len(plan.poses) - 1):
        (x0, y0), (x1, y1) = swing[k][:2], plan.poses[k + 1][:2]
        a, b = ((x0 - ox) * inv, (y0 - oy) * inv), ((x1 - ox) * inv, (y1 - oy) * inv)
        lo_i, hi_i = int(min(a[0], b[0])) - 1, int(max(a[0], b[0])) + 2
        lo_j, hi_j = int(min(a[1], b[1])) - 1, int(max(a[1], b[1])) + 2
        for i in range(max(lo_i, 0), min(hi_i, tall.shape[0])):
            for j in range(max(lo_j, 0), min(hi_j, tall.shape[1])):
                assert not (tall[i, j] and _crosses_exact((i, j), a, b)), (k, (i, j))


@pytest.mark.parametrize("backend", ["python", "compiled"])
def test_a_tiny_time_limit_ends_within_64_expansions(backend):
    from repertoire.planning.footstep.scenes import random_floor_scene

    sc = random_floor_scene(3)  # a 12 m floor: thousands of expansions to a plan
    args = (sc.grid, sc.start, sc.start_foot, sc.goal, nominal_action_table())
    plan = plan_footsteps(*args, PlannerOptions(time_limit=1e-6, backend=backend))
    assert plan.status is PlanStatus.TIME_LIMIT and plan.nodes_expanded == 64
    assert len(plan.poses) >= 1  # the best partial plan


# ---------------------------------------------------------------- swing clearance on terraces


def _terraces(kerb: float | None, ridge: float | None = None) -> OccupancyGrid:
    """3 m x 1 m: stairs of 0.1 m at x = 0.8, 1.1, 1.4 up to a 0.3 m platform; across it at
    x = 2.0-2.05 an occupied kerb ``kerb`` m high (above 0) or a free ridge ``ridge`` m high."""
    occ, h = np.zeros((120, 40), bool), np.zeros((120, 40))
    for k, x0 in enumerate((0.8, 1.1, 1.4)):
        h[round(x0 / RES) :] = (0.1, 0.2, 0.3)[k]
    wall = slice(round(2.0 / RES), round(2.05 / RES))
    if kerb is not None:
        occ[wall], h[wall] = True, kerb
    if ridge is not None:
        h[wall] = ridge
    return OccupancyGrid(occ, RES, heights=h)


@pytest.mark.parametrize(
    ("kerb", "ridge", "crosses"),
    [
        (0.35, None, True),  # 5 cm above the platform: under the 10 cm clearance
        (0.39, None, True),
        (0.41, None, False),  # 11 cm above it
        (0.8, None, False),
        (None, 0.35, True),  # free ground, as a kerb of the same height
        (None, 0.8, False),  # a 0.5 m ridge of free cells is no less in the swing's way
    ],
)
def test_swing_clearance_is_measured_from_the_ground_the_feet_stand_on(kerb, ridge, crosses):
    # before: a kerb cell taller than the clearance above level 0 (0.35 > 0.1) blocked every
    # swing although it stands 5 cm above the platform, and free cells never blocked one
    grid = _terraces(kerb, ridge)
    opts = dict(
        swing_clearance=0.1, max_step_up=0.12, max_step_down=0.12, max_height_range=0.02,
        refinements=0, heuristic="euclidean",
    )  # fmt: skip
    plan = _both(grid, (0.3, 0.5, 0.0), "left", (2.6, 0.5), **opts)
    if crosses:
        assert plan.status is PlanStatus.SUCCESS
        assert plan.poses[-1][0] > 2.05
        tops = [float(grid.heights[grid.cell_of(p[0], p[1])]) for p in plan.poses]
        assert sorted(set(tops)) == [0.0, 0.1, 0.2, 0.3]  # every tread, then the platform
    else:  # the wall spans the map: the lattice is exhausted on the near side
        assert plan.status is PlanStatus.UNREACHABLE
        assert max(p[0] for p in plan.poses) < 2.0


@pytest.mark.parametrize(("kerb", "crosses"), [(0.39, True), (0.41, False)])
def test_swing_clearance_on_a_raised_level_floor(kerb, crosses):
    # one ground level for every sole (0.3 m): both cores take it without measuring soles
    grid = _terraces(kerb)
    grid.heights[~grid.occupied] = 0.3
    opts = dict(swing_clearance=0.1, refinements=0, heuristic="euclidean")
    plan = _both(grid, (0.3, 0.5, 0.0), "left", (2.6, 0.5), **opts)
    assert (plan.status is PlanStatus.SUCCESS) is crosses
    model = BipedStepModel(
        grid, (0.3, 0.5, 0.0), "left", (2.6, 0.5), nominal_action_table(), PlannerOptions(**opts)
    )
    assert model.ground_level == 0.3
    grid.heights[0, 0] = 0.31  # one free cell higher: the soles' ground is measured
    model = BipedStepModel(
        grid, (0.3, 0.5, 0.0), "left", (2.6, 0.5), nominal_action_table(), PlannerOptions(**opts)
    )
    assert model.ground_level is None


@pytest.mark.parametrize("direction", ["down", "up"])
def test_swing_clearance_counts_the_ground_the_swing_foot_lifts_from(direction):
    # stairs of 0.1 m treads 0.3 m deep with a 5 cm swing clearance: going down, the
    # trailing foot stands a tread above the stance and landing soles; its swing line leaves
    # through its own tread's cells, which stand 10 cm above them. Before, the clearance
    # was counted from the stance's and landing's ground only, so those cells blocked every
    # descent (UNREACHABLE on every lattice) while the ascent was planned
    grid = _terraces(None)
    opts = dict(
        swing_clearance=0.05, max_step_up=0.12, max_step_down=0.12, max_height_range=0.02,
        refinements=0, heuristic="euclidean",
    )  # fmt: skip
    start, goal = (
        ((2.6, 0.5, math.pi), (0.3, 0.5)) if direction == "down" else ((0.3, 0.5, 0.0), (2.6, 0.5))
    )
    plan = _both(grid, start, "left", goal, **opts)
    assert plan.status is PlanStatus.SUCCESS
    tops = [float(grid.heights[grid.cell_of(p[0], p[1])]) for p in plan.poses]
    assert sorted(set(tops)) == [0.0, 0.1, 0.2, 0.3]  # every tread
    steps = list(itertools.pairwise(tops))
    assert max(abs(b - a) for a, b in steps) == pytest.approx(0.1)  # one tread a step
    # a 0.3 m wall on the floor is still refused: every ground there is 0
    grid.occupied[round(0.55 / RES) : round(0.6 / RES)] = True
    grid.heights[round(0.55 / RES) : round(0.6 / RES)] = 0.3
    assert _both(grid, start, "left", goal, **opts).status is PlanStatus.UNREACHABLE


def test_cell_height_compiled_equals_python_equals_the_grid():
    rng, grid, model, tab = _random_heights_model(6)
    for _ in range(2000):
        x, y = rng.uniform(0.1, 1.3), rng.uniform(-0.2, 0.8)
        i, j = grid.cell_of(x, y)
        got = model.exact.cell_height(x, y)
        assert got == grid.heights[min(i, 47), min(j, 39)]
        assert _cell_height(x, y, tab["grid"], tab["ex"], tab["heights"]) == got


def _posts(heights: float, seed: int = 7, pieces: tuple[int, int] = (6, 16)):
    """A 1.4 m x 1 m floor of thin posts and wall pieces of ``heights`` m (seeded)."""
    rng = np.random.default_rng(seed)
    occ = np.zeros((56, 40), bool)
    for _ in range(int(rng.integers(*pieces))):
        i, j = rng.integers(12, 46), rng.integers(0, 40)
        if rng.random() < 0.5:
            occ[i, j : j + rng.integers(1, 6)] = True
        else:
            occ[i : i + rng.integers(1, 6), j] = True
    occ[:10, 12:28] = False
    goal = (1.25, float(rng.uniform(0.3, 0.7)))
    gi, gj = int(goal[0] / RES), int(goal[1] / RES)
    occ[gi - 3 : gi + 4, gj - 3 : gj + 4] = False
    return OccupancyGrid(occ, RES, (0.0, 0.0), heights * occ), goal


def test_states_whose_swing_feet_stand_apart_are_not_merged_where_swings_are_checked():
    # The swing line starts where the swing foot stood before the last step; the lattice
    # keys the stance pose and one history class (the nominal table's), so the cheaper
    # arrival's swing foot decides the landings of every state on that cell. Here the
    # admissible mode finds 9.0 on that lattice; a tree search over the same steps, nothing
    # merged, finds 8.95, and so does the search with swing_start_states
    table = nominal_action_table()
    start = (0.15, 0.5, 0.0)
    opts = PlannerOptions.admissible(time_limit=30.0, refinements=0, swing_clearance=0.1)
    grid, goal = _posts(0.3)
    merged = plan_footsteps(grid, start, "left", goal, table, opts)
    plan = plan_footsteps(grid, start, "left", goal, table, opts, swing_start_states=True)
    model = BipedStepModel(grid, start, "left", goal, table, opts)
    per_m = float(table.step_cost.min()) / table.max_reach()
    best = [merged.cost + 1e-6]  # the tree search looks only below the merged lattice's plan

    def tree(s, g):
        if model.is_goal(s):
            best[0] = min(best[0], g)
            return
        for s2, c in model.successors(s):
            h = max(0.0, math.dist((s2.x, s2.y), goal) - opts.goal_tolerance) * per_m
            if g + c + h < best[0] - 1e-9:
                tree(s2, g + c)

    tree(model.start(), 0.0)
    assert merged.cost == pytest.approx(9.0, abs=1e-9)
    assert plan.succeeded and plan.cost == pytest.approx(best[0], abs=1e-9)
    assert plan.cost == pytest.approx(8.95, abs=1e-9)
    # the key: one pose, the swing foot beside it (after "stop") or 0.3 m behind (after
    # "forward_long"); apart where some cell blocks a swing, one state where none does
    split = BipedStepModel(grid, start, "left", goal, table, opts, swing_start_states=True)
    s0 = split.start()
    behind = s0._replace(a_prev1=table.index("forward_long"), swing_x=s0.x - 0.3)
    assert split.key(behind) != split.key(s0) and split.n_hist == table.n
    assert model.key(behind) == model.key(s0)  # the default lattice merges them
    low = BipedStepModel(_posts(0.05)[0], start, "left", goal, table, opts, swing_start_states=True)
    assert low.key(behind) == low.key(s0) and low.n_hist == 1
    with pytest.raises(FootstepError, match="swing_start_states must be True or False, got 1"):
        BipedStepModel(grid, start, "left", goal, table, opts, swing_start_states=1)
    # a map where the merge hides every plan: UNREACHABLE on the merged lattice, a plan on
    # the same lattice with swing starts; plan_footsteps' first refinement (keyed, 2.5 cm)
    # finds one (merged, the refinements found one only at 0.625 cm / 288)
    grid, goal = _posts(0.3, seed=182, pieces=(12, 30))
    lost = plan_footsteps(grid, start, "left", goal, table, opts)
    kept = plan_footsteps(grid, start, "left", goal, table, opts, swing_start_states=True)
    assert lost.status is PlanStatus.UNREACHABLE and kept.succeeded
    default = PlannerOptions(time_limit=60.0, swing_clearance=0.1)
    refined = plan_footsteps(grid, start, "left", goal, table, default)
    assert refined.succeeded and (refined.xy_resolution, refined.yaw_bins) == (0.025, 72)


def test_the_refinements_key_swing_starts(monkeypatch):
    # the first lattice merges swing starts (fast first plans); a refinement, run when it
    # ran out of states, keys them: UNREACHABLE is said only when that lattice is exhausted
    import repertoire.planning.footstep.planner as planner_module

    seen = []
    model_init = BipedStepModel.__init__

    def init(self, *a, **k):
        model_init(self, *a, **k)
        seen.append((self.opts.xy_resolution, self.n_hist))

    monkeypatch.setattr(BipedStepModel, "__init__", init)
    monkeypatch.setattr(planner_module, "goal_cut_off", lambda *a: False)
    occ = np.zeros((88, 40), bool)
    occ[40:42, :] = True  # a full wall 0.3 m tall: no swing crosses it
    grid = OccupancyGrid(occ, RES, (0.0, 0.0), 0.3 * occ)
    opts = PlannerOptions(time_limit=60.0, swing_clearance=0.1, refinements=1)
    plan = plan_footsteps(grid, (0.3, 0.5, 0.0), "left", (1.8, 0.5), nominal_action_table(), opts)
    assert plan.status is PlanStatus.UNREACHABLE
    assert seen == [(0.05, 1), (0.025, 7)]
    seen.clear()  # the anytime planner's refinements likewise
    runs = plan_footsteps_anytime(
        grid, (0.3, 0.5, 0.0), "left", (1.8, 0.5), nominal_action_table(), opts
    )
    assert runs[-1].plan.status is PlanStatus.UNREACHABLE
    assert set(seen) == {(0.05, 1), (0.025, 7)} and seen[-1] == (0.025, 7)


def test_the_anytime_refinements_find_the_plans_merged_swing_starts_hide():
    # posts map 182 (the test above): the admissible mode's 2.5 cm lattice, merged, is
    # exhausted; its first refinement (1.25 cm) keys swing starts and finds a plan, as
    # plan_footsteps' does (before, the anytime planner's refinement merged them too and
    # said UNREACHABLE)
    grid, goal = _posts(0.3, seed=182, pieces=(12, 30))
    opts = PlannerOptions.admissible(time_limit=60.0, refinements=1, swing_clearance=0.1)
    args = (grid, (0.15, 0.5, 0.0), "left", goal, nominal_action_table(), opts)
    runs = plan_footsteps_anytime(*args)
    one = plan_footsteps(*args)
    assert one.succeeded and one.xy_resolution == 0.0125
    assert runs[-1].plan.succeeded and runs[-1].plan.xy_resolution == 0.0125
