"""sprayplan's own tour improvement: nearest neighbour, 2-opt + Or-opt with neighbour lists, iterated local search.

The fallback of :func:`sprayplan.ordering.solve_tour` when the ``fast-tsp`` library is missing, and the methods
``"nearest"``, ``"2opt"`` and ``"local"``. Written from the textbook descriptions (Johnson and McGeoch, "The
traveling salesman problem: a case study in local optimization", 1997; Bentley 1992 for neighbour lists and
don't-look bits; Lourenco, Martin and Stuetzle 2003 for iterated local search with double-bridge kicks).

All routines work on a closed tour over a dense distance matrix (open paths are reduced to closed tours by the
caller, see :mod:`sprayplan.ordering.tour`). The tour is a Python list with the inverse list ``pos``; the matrix is
read through a flat memoryview, which gives Python floats quickly. A node listed in ``pinned`` keeps its two tour
edges through the kicks (the dummy node of a reduced open path; local moves never break its edges because they
are priced to be kept).
"""

from __future__ import annotations

import logging
import random
import time
from collections import deque

import numpy as np

logger = logging.getLogger(__name__)

#: Improvements smaller than this (in distance units) are ignored, so that rounding cannot cycle.
_EPS = 1e-9
#: Neighbour list length for 2-opt and Or-opt.
NEIGHBOURS = 10
#: Longest segment Or-opt moves.
OR_OPT_MAX = 3
#: Longest segment a double-bridge kick swaps.
KICK_SEGMENT_MAX = 100


def nearest_neighbour(dist: np.ndarray, first: int = 0, last: int | None = None) -> np.ndarray:
    """Nearest-neighbour tour: from ``first``, always go to the closest unvisited node.

    Parameters
    ----------
    dist : (n, n) float
    first : int
        Node the tour starts from.
    last : int or None
        Node kept for the end (the path then runs ``first -> ... -> last``).

    Returns
    -------
    order : (n,) int
    """
    n = len(dist)
    if n == 0:
        return np.zeros(0, dtype=np.intp)
    visited = np.zeros(n, dtype=bool)
    order = np.empty(n, dtype=np.intp)
    order[0] = first
    visited[first] = True
    count = 1
    if last is not None and last != first:
        visited[last] = True
        order[n - 1] = last
        count += 1
    cur = first
    for k in range(1, n - (count - 1)):
        row = np.where(visited, np.inf, dist[cur])
        cur = int(np.argmin(row))
        order[k] = cur
        visited[cur] = True
    return order


def neighbour_lists(dist: np.ndarray, k: int = NEIGHBOURS) -> list[list[int]]:
    """The ``k`` nearest other nodes of every node, closest first (row blocks keep memory small)."""
    n = len(dist)
    k = max(0, min(k, n - 1))
    if k == 0:
        return [[] for _ in range(n)]
    out: list[list[int]] = []
    block = max(1, 4_000_000 // max(n, 1))
    for lo in range(0, n, block):
        rows = np.array(dist[lo : lo + block], dtype=float)
        rows[np.arange(len(rows)), np.arange(lo, lo + len(rows))] = np.inf
        part = np.argpartition(rows, k - 1, axis=1)[:, :k] if k < n else np.argsort(rows, axis=1)[:, :k]
        near = np.take_along_axis(rows, part, axis=1)
        part = np.take_along_axis(part, np.argsort(near, axis=1, kind="stable"), axis=1)
        out.extend(part.tolist())
    return out


class _Tour:
    """A closed tour as a list plus its inverse, with the two primitive edits (reversal, block swap)."""

    def __init__(self, order, dist: np.ndarray):
        self.n = len(order)
        self.t = [int(v) for v in order]
        self.pos = [0] * self.n
        for i, v in enumerate(self.t):
            self.pos[v] = i
        self.flat = memoryview(np.ascontiguousarray(dist, dtype=float).reshape(-1))

    def reverse(self, i: int, j: int) -> None:
        """Reverse the tour from position i forwards to position j (or the complement, if that is shorter)."""
        n, t, pos = self.n, self.t, self.pos
        length = (j - i) % n + 1
        if 2 * length > n:
            i, j, length = (j + 1) % n, (i - 1) % n, n - length
        for _ in range(length // 2):
            a, b = t[i], t[j]
            t[i], t[j] = b, a
            pos[b], pos[a] = i, j
            i = i + 1 if i + 1 < n else 0
            j = j - 1 if j > 0 else n - 1

    def swap_blocks(self, start: int, la: int, lb: int, rev_a: bool, rev_b: bool) -> None:
        """Replace blocks X (la nodes from ``start``) and Y (lb nodes after it) by Y then X (each maybe reversed)."""
        n, t, pos = self.n, self.t, self.pos
        idx = [(start + k) % n for k in range(la + lb)]
        x = [t[p] for p in idx[:la]]
        y = [t[p] for p in idx[la:]]
        if rev_a:
            x.reverse()
        if rev_b:
            y.reverse()
        for p, v in zip(idx, y + x):
            t[p] = v
            pos[v] = p

    def length(self) -> float:
        t, n, f = self.t, self.n, self.flat
        return sum(f[t[i - 1] * n + t[i]] for i in range(n))


def _improve(tour: _Tour, neigh: list[list[int]], active: deque) -> float:
    """2-opt and Or-opt first-improvement descent from the nodes in ``active``; returns the total gain."""
    n, t, pos, f = tour.n, tour.t, tour.pos, tour.flat
    if n < 5:
        return 0.0
    queued = bytearray(n)
    for a in active:
        queued[a] = 1
    total = 0.0
    seg_max = min(OR_OPT_MAX, n - 4)

    def wake(*nodes):
        for v in nodes:
            if not queued[v]:
                queued[v] = 1
                active.append(v)

    while active:
        a = active.popleft()
        queued[a] = 0
        moved = False
        # 2-opt, both tour neighbours of a.
        for succ in (True, False):
            pa = pos[a]
            b = t[pa + 1 if pa + 1 < n else 0] if succ else t[pa - 1]
            dab = f[a * n + b]
            for c in neigh[a]:
                g1 = dab - f[a * n + c]
                if g1 <= _EPS:
                    break
                pc = pos[c]
                d = t[pc + 1 if pc + 1 < n else 0] if succ else t[pc - 1]
                if c == b or d == a:
                    continue
                gain = g1 + f[c * n + d] - f[b * n + d]
                if gain > _EPS:
                    if succ:
                        tour.reverse(pos[b], pos[c])
                    else:
                        tour.reverse(pos[a], pos[d])
                    total += gain
                    wake(a, b, c, d)
                    moved = True
                    break
            if moved:
                break
        if moved:
            continue
        # Or-opt: move a segment of 1..3 nodes that ends at a elsewhere, either way round.
        for seg_len in range(1, seg_max + 1):
            for a_first in (True, False) if seg_len > 1 else (True,):
                pa = pos[a]
                i = pa if a_first else (pa - seg_len + 1) % n
                s1, s2 = t[i], t[(i + seg_len - 1) % n]
                p, nx = t[i - 1], t[(i + seg_len) % n]
                g_rem = f[p * n + s1] + f[s2 * n + nx] - f[p * n + nx]
                if g_rem <= _EPS:
                    continue
                for end in (s1, s2):
                    for c in neigh[end]:
                        if f[end * n + c] >= g_rem:
                            break
                        pc = pos[c]
                        if (pc - i) % n < seg_len:
                            continue
                        for x, y in ((c, t[pc + 1 if pc + 1 < n else 0]), (t[pc - 1], c)):
                            if (pos[x] - i) % n < seg_len or (pos[y] - i) % n < seg_len:
                                continue
                            dxy = f[x * n + y]
                            add_fwd = f[x * n + s1] + f[s2 * n + y] - dxy
                            add_rev = f[x * n + s2] + f[s1 * n + y] - dxy
                            rev = add_rev < add_fwd
                            gain = g_rem - (add_rev if rev else add_fwd)
                            if gain > _EPS:
                                la = (pos[x] - (i + seg_len - 1)) % n
                                lb = n - seg_len - la
                                if la <= lb:
                                    tour.swap_blocks(i, seg_len, la, rev, False)
                                else:
                                    tour.swap_blocks(pos[y], lb, seg_len, False, rev)
                                total += gain
                                wake(p, nx, s1, s2, x, y)
                                moved = True
                                break
                        if moved:
                            break
                    if moved:
                        break
                if moved:
                    break
            if moved:
                break
    return total


def two_opt(dist: np.ndarray, order: np.ndarray) -> np.ndarray:
    """Improve a closed tour by 2-opt and Or-opt moves until no neighbour-list move improves it.

    Parameters
    ----------
    dist : (n, n) float
        Symmetric distance matrix.
    order : (n,) int
        Start tour (not changed).

    Returns
    -------
    order : (n,) int
        A local optimum, as a new array.
    """
    tour = _Tour(order, dist)
    _improve(tour, neighbour_lists(dist), deque(tour.t))
    return np.array(tour.t, dtype=np.intp)


def iterated_local_search(
    dist: np.ndarray,
    order: np.ndarray,
    *,
    time_limit_s: float,
    seed: int = 0,
    max_kicks: int | None = None,
    pinned: tuple[int, ...] = (),
) -> np.ndarray:
    """Iterated local search: 2-opt + Or-opt, then random local double-bridge kicks, each kept if it helps.

    Parameters
    ----------
    dist : (n, n) float
        Symmetric distance matrix.
    order : (n,) int
        Start tour (not changed).
    time_limit_s : float
        Wall-clock budget in seconds; the search stops at the first kick after it.
    seed : int
        Seed of the kicks. A run that stops on ``max_kicks`` before the clock repeats exactly.
    max_kicks : int or None
        Number of kicks; None: until the time limit.
    pinned : tuple of int
        Nodes whose tour edges the kicks never cut.

    Returns
    -------
    order : (n,) int
        The best tour found, as a new array.
    """
    deadline = time.perf_counter() + time_limit_s
    tour = _Tour(order, dist)
    n, t, f = tour.n, tour.t, tour.flat
    neigh = neighbour_lists(dist)
    _improve(tour, neigh, deque(t))
    if n < 8:
        return np.array(t, dtype=np.intp)
    rng = random.Random(seed)
    pin = set(pinned)
    max_seg = max(1, min(KICK_SEGMENT_MAX, (n - 2) // 3))
    kicks = accepted = 0
    while (max_kicks is None or kicks < max_kicks) and time.perf_counter() < deadline:
        kicks += 1
        la, lb = rng.randint(1, max_seg), rng.randint(1, max_seg)
        i = rng.randrange(n)
        j = (i + la + lb + 1) % n
        a, x1, x2 = t[i], t[(i + 1) % n], t[(i + la) % n]
        y1, y2, b = t[(i + la + 1) % n], t[(i + la + lb) % n], t[j]
        if pin & {a, x1, x2, y1, y2, b}:
            continue
        delta = (f[a * n + y1] + f[y2 * n + x1] + f[x2 * n + b]) - (f[a * n + x1] + f[x2 * n + y1] + f[y2 * n + b])
        saved_t, saved_pos = t[:], tour.pos[:]
        tour.swap_blocks((i + 1) % n, la, lb, False, False)
        gain = _improve(tour, neigh, deque((a, x1, x2, y1, y2, b)))
        if gain - delta > _EPS:
            accepted += 1
        else:
            tour.t[:], tour.pos[:] = saved_t, saved_pos
    logger.debug("iterated local search: %d kicks, %d improved the tour", kicks, accepted)
    return np.array(t, dtype=np.intp)
