"""The shortest route through via points whose legs are checked lazily (the kitchen drives).

:func:`~repertoire.studies._kitchen_arm.route` searches the drives of the kitchen plans
around the furniture with it. The search knows nothing of the kitchen: it is given which
legs may be driven at all and a function that checks a leg.
"""

import numpy as np


def reached_through(seen, on) -> np.ndarray:
    """The via points (``on``'s last axis) from which one of ``on`` is reached by legs of ``seen``.

    The transitive closure of ``on`` over the visibility graph ``seen`` ((m, m)), for ``on``
    of shape (m,) or (n, m).
    """
    on = np.asarray(on, dtype=bool)
    while True:
        more = on | (seen & on[..., None, :]).any(axis=-1)
        if np.array_equal(more, on):
            return on
        on = more


#: Node numbers of :func:`shortest_routes` for a route's start and end (via points: 0..m-1).
START, GOAL = -1, -2


def shortest_routes(a, b, points, seen, from_a, to_b, direct, legs_clear) -> list:
    """Per row the shortest route ``a`` -> via points -> ``b`` whose every leg is clear.

    Dijkstra over a visibility graph: the nodes are the start, the via points and the
    end; ``seen``, ``from_a``, ``to_b`` and ``direct`` say which straight legs may be
    driven at all. A leg's drive also depends on the heading its end takes (a via point
    faces the next point of the route), so a search state is a node with the node it
    goes on to, and a leg ``u -> v`` (v going on to ``w``) is checked with
    ``legs_clear`` when the search first takes it (lazily, shortest routes first; all
    rows' pending legs in one call). Lengths are the straight legs' sums. The search is
    A*: a path is taken in the order of its length plus the straight distance from its
    last node to the end (a consistent bound, as the legs are straight), so it settles
    every state at its shortest length as Dijkstra does and finds the same shortest
    route, while checking the legs of far fewer paths that lead away from the end.

    Args:
        a: (n, >= 2) starts. b: (n, >= 2) ends. points: (m, 2) via points.
        seen: (m, m) True where the leg from via point i to j may be driven.
        from_a: (n, m) the same from each start, to_b: (n, m) to each end.
        direct: (n,) the same from the start to the end.
        legs_clear: ``legs_clear(rows, legs) -> (len(rows),) bool`` for legs
            ``(u, v, w)`` (node numbers; ``w`` the node ``v`` faces, ``GOAL`` for a via
            point facing the end, None for ``v == GOAL``) of rows ``rows``.

    Returns:
        Per row the tuple of via point indices in driving order (empty: straight), or
        None where no route is clear.
    """
    import heapq

    a, b = np.atleast_2d(a)[:, :2], np.atleast_2d(b)[:, :2]
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    n = len(a)
    between = np.hypot(*(points[:, None] - points[None]).transpose(2, 0, 1))
    to_end = np.hypot(*(points[None] - b[:, None]).transpose(2, 0, 1))  # (n, m)
    seen, from_a, to_b = (np.asarray(x, dtype=bool) for x in (seen, from_a, to_b))
    on = reached_through(seen, to_b)  # (n, m): the via points the end is reached from
    heaps: list[list] = [[] for _ in range(n)]
    closed: list[set] = [set() for _ in range(n)]
    tie = 0

    def push(r, length, path):  # in the order of length + the straight rest to the end
        nonlocal tie
        rest = 0.0 if path[-1] == GOAL else to_end[r, path[-1]]
        heapq.heappush(heaps[r], (length + rest, tie, length, path))
        tie += 1

    def extend(r, length, path):  # the legs on from the path's last node
        w = path[-1]
        for x in np.flatnonzero(seen[w] & on[r]):  # on towards the end only
            if x not in path:
                push(r, length + between[w, x], path + (int(x),))
        if to_b[r, w]:
            push(r, length + to_end[r, w], path + (GOAL,))

    for r in range(n):
        if direct[r]:
            push(r, float(np.hypot(*(b[r] - a[r]))), (START, GOAL))
        for p in np.flatnonzero(from_a[r] & on[r]):
            push(r, float(np.hypot(*(points[p] - a[r]))), (START, int(p)))
    routes: list = [None] * n
    known: list[dict] = [{} for _ in range(n)]  # per row the legs checked: clear or not

    def settle(r, length, path):  # a path whose legs are clear: a route, or on from it
        if path[-1] == GOAL:
            routes[r] = path[1:-1]
        else:
            closed[r].add(path[-2:])
            extend(r, length, path)

    active = list(range(n))
    while active:
        pending = {}  # row -> (length, path, legs to check)
        for r in active:
            while heaps[r] and routes[r] is None:
                _, _, length, path = heapq.heappop(heaps[r])
                if path[-2:] in closed[r]:
                    continue
                legs = [(path[-3], path[-2], path[-1])] if len(path) > 2 else []
                if path[-1] == GOAL:
                    legs.append((path[-2], GOAL, None))
                if not all(known[r].get(leg, True) for leg in legs):
                    continue
                unknown = [leg for leg in legs if leg not in known[r]]
                if unknown:
                    pending[r] = (length, path, unknown)
                    break
                settle(r, length, path)
        if not pending:
            break
        rows = [r for r, (_, _, legs) in pending.items() for _ in legs]
        clear = legs_clear(np.array(rows), [leg for _, _, legs in pending.values() for leg in legs])
        at = 0
        for r, (length, path, legs) in pending.items():
            known[r].update(zip(legs, (bool(c) for c in clear[at : at + len(legs)])))
            at += len(legs)
            if all(known[r][leg] for leg in legs):
                settle(r, length, path)
        active = [r for r in active if routes[r] is None and heaps[r]]
    return routes
