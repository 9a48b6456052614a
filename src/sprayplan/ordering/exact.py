"""Exact tours by Held-Karp dynamic programming (Bellman 1962, Held and Karp 1962), vectorised with numpy.

One routine, :func:`held_karp`, solves the *grouped* problem: nodes are partitioned into groups, and the best
sequence visits exactly one node of every group, once. A plain tour is the case of one node per group; ordering
strokes that can run either way is the case of two nodes ("stroke i run forwards", "stroke i run backwards") per
group. Start and end costs (``init``, ``final``) express open paths, fixed end points and the closing edge.

Work and memory grow as ``2**G * N`` (``G`` groups, ``N`` nodes): :data:`EXACT_MAX_N` bounds the tour size
accepted by :func:`sprayplan.ordering.solve_tour` with ``method="exact"``.
"""

from __future__ import annotations

import numpy as np

from sprayplan.errors import ConfigError

#: Largest number of points ``solve_tour(method="exact")`` accepts (an open path of 16 points is a DP over 2**16
#: subsets: about 0.1 s and 12 MB; each further point doubles time and memory).
EXACT_MAX_N = 16
#: Largest number of groups :func:`held_karp` accepts at all (memory: 2**G * N floats).
MAX_GROUPS = 16


def held_karp(cost: np.ndarray, groups: np.ndarray, init: np.ndarray, final: np.ndarray) -> tuple[np.ndarray, float]:
    """Cheapest sequence visiting one node of every group, by dynamic programming over subsets of groups.

    Minimises ``init[u0] + cost[u0, u1] + ... + cost[u_{G-2}, u_{G-1}] + final[u_{G-1}]`` over sequences
    ``u0..u_{G-1}`` that hold exactly one node of each group.

    Parameters
    ----------
    cost : (N, N) float
        Cost of going from node ``u`` to node ``v`` (need not be symmetric). Nodes of one group are never
        consecutive, so entries within a group are not read.
    groups : (N,) int
        Group of each node, values ``0..G-1``, every group non-empty.
    init : (N,) float
        Cost of starting at each node (``inf`` forbids it).
    final : (N,) float
        Cost of ending at each node (``inf`` forbids it).

    Returns
    -------
    sequence : (G,) int
        Node indices, in order.
    cost : float
        Its total cost (``inf`` if every sequence is forbidden).

    Raises
    ------
    ConfigError
        If there are more than :data:`MAX_GROUPS` groups.
    """
    cost = np.asarray(cost, dtype=float)
    groups = np.asarray(groups, dtype=np.intp)
    n_nodes = len(groups)
    n_groups = int(groups.max()) + 1 if n_nodes else 0
    if n_groups == 0:
        return np.zeros(0, dtype=np.intp), 0.0
    if n_groups > MAX_GROUPS:
        raise ConfigError(f"exact ordering handles at most {MAX_GROUPS} groups, got {n_groups}")
    full = (1 << n_groups) - 1
    bit = (1 << groups).astype(np.int64)
    dp = np.full((full + 1, n_nodes), np.inf)
    parent = np.full((full + 1, n_nodes), -1, dtype=np.int32)
    dp[bit, np.arange(n_nodes)] = init
    masks = np.arange(full + 1, dtype=np.int64)
    popcount = np.zeros(full + 1, dtype=np.int64)
    for g in range(n_groups):
        popcount += (masks >> g) & 1
    for size in range(2, n_groups + 1):
        layer = masks[popcount == size]
        for v in range(n_nodes):
            sel = layer[(layer & bit[v]) != 0]
            prev = sel ^ bit[v]
            cand = dp[prev] + cost[:, v][None, :]
            best = np.argmin(cand, axis=1)
            dp[sel, v] = cand[np.arange(len(sel)), best]
            parent[sel, v] = best
    total = dp[full] + final
    last = int(np.argmin(total))
    best_cost = float(total[last])
    sequence = np.empty(n_groups, dtype=np.intp)
    mask, node = full, last
    for k in range(n_groups - 1, -1, -1):
        sequence[k] = node
        prev_node = int(parent[mask, node])
        mask ^= int(bit[node])
        node = prev_node
    return sequence, best_cost


def exact_tour(dist: np.ndarray, closed: bool, start: int | None, end: int | None) -> np.ndarray:
    """Optimal tour or path on a distance matrix by :func:`held_karp`.

    Parameters
    ----------
    dist : (n, n) float
        Distance matrix (symmetric or not).
    closed : bool
        Closed tour (the order may then only be rotated to begin with ``start`` / end with ``end``; with both, the
        tour is the best path from ``start`` to ``end`` plus the edge back) or open path.
    start, end : int or None
        Fixed first / last index. With ``closed=True`` and both given, ``end -> start`` is the closing edge.

    Returns
    -------
    order : (n,) int
        An optimal order.

    Raises
    ------
    ConfigError
        If ``n`` exceeds :data:`EXACT_MAX_N`.
    """
    n = len(dist)
    if n > EXACT_MAX_N:
        raise ConfigError(f"method 'exact' handles at most {EXACT_MAX_N} points, got {n}: use 'auto'")
    if n == 0:
        return np.zeros(0, dtype=np.intp)
    if closed and (start is None or end is None):
        # A closed tour: fix node 0 first, then rotate to the requested start or end.
        rest = np.arange(1, n)
        if len(rest) == 0:
            return np.zeros(1, dtype=np.intp)
        sub = dist[np.ix_(rest, rest)]
        seq, _ = held_karp(sub, np.arange(len(rest)), dist[0, rest], dist[rest, 0])
        order = np.concatenate([[0], rest[seq]]).astype(np.intp)
        if start is not None:
            order = np.roll(order, -int(np.flatnonzero(order == start)[0]))
        elif end is not None:
            order = np.roll(order, n - 1 - int(np.flatnonzero(order == end)[0]))
        return order
    fixed = [i for i in (start, end) if i is not None]
    rest = np.setdiff1d(np.arange(n), fixed)
    if len(rest) == 0:
        return np.array(fixed, dtype=np.intp)
    init = dist[start, rest] if start is not None else np.zeros(len(rest))
    final = dist[rest, end] if end is not None else np.zeros(len(rest))
    seq, _ = held_karp(dist[np.ix_(rest, rest)], np.arange(len(rest)), init, final)
    head = [start] if start is not None else []
    tail = [end] if end is not None else []
    return np.concatenate([head, rest[seq], tail]).astype(np.intp)
