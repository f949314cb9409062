"""The duplicate test asked before a successor's checks: same searches, fewer checks."""

import numpy as np
import pytest
from repertoire.planning.footstep import OccupancyGrid, PlannerOptions, nominal_action_table
from repertoire.planning.footstep.biped_model import BipedStepModel
from repertoire.planning.footstep.scenes import random_static_scene, stepping_stones_grid
from repertoire.planning.footstep.search import anytime_search, search, successor_function


class Unpruned:
    """The same step model with a ``successors`` that takes no ``dominated`` test."""

    def __init__(self, model):
        self.model = model

    def successors(self, state):
        return self.model.successors(state)

    def __getattr__(self, name):
        return getattr(self.model, name)


def _models(grid, start, goal, **options):
    opts = PlannerOptions(**options)
    model = BipedStepModel(grid, start, "left", goal, nominal_action_table(), opts)
    return model, Unpruned(model)


def _scenes():
    sc = random_static_scene(3)
    yield sc.grid, sc.start, sc.goal
    yield stepping_stones_grid(1, 0.08), (0.2, 0.45, 0.0), (1.8, 0.4)
    rng = np.random.default_rng(7)
    occ = rng.random((80, 80)) < 0.3  # 2 m of 30 % clutter in 2.5 cm cells
    occ[:24, :24] = occ[-16:, -16:] = False
    yield OccupancyGrid(occ, 0.025), (0.3, 0.3, 0.8), (1.8, 1.8)


@pytest.mark.parametrize("case", range(3))
def test_pruned_search_expands_the_same_states(case):
    grid, start, goal = list(_scenes())[case]
    pruned, plain = _models(grid, start, goal, heuristic="euclidean")
    a = search(pruned, weight=1.5, max_expansions=20_000, time_limit=60.0)
    b = search(plain, weight=1.5, max_expansions=20_000, time_limit=60.0)
    assert a.status is b.status
    assert a.path == b.path and a.cost == b.cost and a.expansions == b.expansions
    # the successors dropped before their checks are no longer counted as generated
    assert a.generated < b.generated
    assert a.merged > 0 and a.generated + a.merged >= b.generated - b.merged


@pytest.mark.parametrize("case", range(3))
def test_pruned_anytime_search_gives_the_same_plans(case):
    grid, start, goal = list(_scenes())[case]
    pruned, plain = _models(grid, start, goal)
    budget = {"weights": [3.0, 2.0, 1.5, 1.0], "max_expansions": 30_000, "time_limit": 60.0}
    runs_a = anytime_search(pruned, **budget)
    runs_b = anytime_search(plain, **budget)
    assert [(r.status, r.cost, r.bound, r.expansions) for r in runs_a] == [
        (r.status, r.cost, r.bound, r.expansions) for r in runs_b
    ]
    assert all(ra.path == rb.path for ra, rb in zip(runs_a, runs_b, strict=True))
    assert runs_a[-1].generated < runs_b[-1].generated


def test_no_pruning_when_a_landing_cost_depends_on_its_heights():
    occ = np.zeros((60, 60), dtype=bool)
    heights = np.where(np.random.default_rng(2).random((60, 60)) < 0.2, 0.01, 0.0)
    grid = OccupancyGrid(occ, 0.025, heights=heights)
    pruned, plain = _models(grid, (0.3, 0.3, 0.0), (1.2, 1.2), height_cost_weight=2.0)
    a = search(pruned, weight=1.0, max_expansions=5_000, time_limit=60.0)
    b = search(plain, weight=1.0, max_expansions=5_000, time_limit=60.0)
    assert b.merged > 0
    assert (a.path, a.expansions, a.generated, a.merged) == (
        b.path,
        b.expansions,
        b.generated,
        b.merged,
    )


def test_successor_function_passes_the_test_only_to_models_that_take_it():
    grid, start, goal = next(_scenes())
    pruned, plain = _models(grid, start, goal)
    asked = []

    def dominated(key, cost):
        asked.append((key, cost))
        return True  # every landing dominated: none is returned

    assert list(successor_function(pruned)(pruned.start(), dominated)) == []
    assert asked and all(cost > 0.0 for _, cost in asked)
    n = len(asked)
    assert list(successor_function(plain)(plain.start(), dominated)) == list(
        pruned.successors(pruned.start())
    )
    assert len(asked) == n
