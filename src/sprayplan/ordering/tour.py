"""Tours and open paths through points: one entry point, :func:`solve_tour`, over several methods.

Methods
-------
``"auto"`` (default)
    Exact for ``n <= AUTO_EXACT_N``; otherwise the ``fast-tsp`` library if it is installed, else ``"local"``.
    Within 1% of the optimum (float distances) on every TSPLIB instance of ``shared/testdata`` with the default
    time budget :func:`default_time_limit` (measured: at most 0.2% above it, see ``bench/bench_tours.py``).
``"exact"``
    Held-Karp dynamic programming (:mod:`~sprayplan.ordering.exact`), ``n <= EXACT_MAX_N``.
``"fast-tsp"``
    The library (:mod:`~sprayplan.ordering.backends`); ``"local"`` if it is missing.
``"local"``
    sprayplan's own iterated local search (2-opt + Or-opt, double-bridge kicks) until the time budget.
``"2opt"``
    Nearest neighbour, then one 2-opt + Or-opt descent: fast, deterministic, typically 2-8% above the optimum.
``"nearest"``
    Nearest neighbour only (20-26% above the optimum on the TSPLIB instances).
``"ga"``
    The genetic algorithm of seed 000 with :data:`~sprayplan.ordering.genetic.GA_DEFAULT`; use
    :func:`~sprayplan.ordering.genetic.ga_tour` for other parameters and the convergence history.

Tiny problems (``n <= 3``) are always solved exactly. Open paths (``closed=False``) and closed tours with both
``start`` and ``end`` fixed reach the closed-tour heuristics through one dummy node joined to the path's ends:
at distance 0 from every point when the ends are free (a tour through the dummy is a path plus two free edges),
and, when an end is fixed, at distance 0 from that end and ``2 * max(d) + 1`` from every other point, a price
that no 2-opt, Or-opt or 3-opt move can pay back, so the fixed ends stay at the dummy. The path is checked
anyway: should fast-tsp's deeper moves ever break it, the own local search redoes the problem (logged).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from sprayplan.checks import check_points
from sprayplan.errors import ConfigError
from sprayplan.ordering.backends import fast_tsp_available, fast_tsp_tour
from sprayplan.ordering.exact import EXACT_MAX_N, exact_tour
from sprayplan.ordering.genetic import GA_DEFAULT, ga_tour_matrix
from sprayplan.ordering.local import iterated_local_search, nearest_neighbour, two_opt
from sprayplan.ordering.metrics import (
    check_distance_matrix,
    check_ends,
    check_metric,
    check_time_limit,
    distance_matrix,
    matrix_path_length,
)

logger = logging.getLogger(__name__)

METHODS = ("auto", "exact", "fast-tsp", "local", "2opt", "nearest", "ga")
#: ``"auto"`` solves problems up to this size exactly (Held-Karp takes a few milliseconds there).
AUTO_EXACT_N = 12

__all__ = [
    "AUTO_EXACT_N",
    "EXACT_MAX_N",
    "METHODS",
    "TourResult",
    "default_time_limit",
    "solve_tour",
    "solve_tour_matrix",
]


@dataclass(frozen=True)
class TourResult:
    """A tour or path found by :func:`solve_tour`.

    Attributes
    ----------
    order : (n,) int
        A permutation of ``range(n)``: begins with ``start`` and ends with ``end`` when they are given.
    length : float
        Its length in the metric asked for, including the closing edge when closed.
    method : str
        The method that produced it (``"exact"`` for tiny problems, ``"local"`` when fast-tsp was asked for but
        is missing, ...).
    """

    order: np.ndarray
    length: float
    method: str


def default_time_limit(n: int, library: bool = True) -> float:
    """Default time budget of the time-bounded methods for ``n`` points, in seconds.

    With the fast-tsp library, ``min(3.5, 0.1 + 0.0011 n)``: it reaches the optimum of pr1002 in 0.3 s on this
    project's machines, and 3000 points take about 4 s in all (matrix building and checks included), under the 5 s
    target. For sprayplan's own local search (``library=False``), ``min(5, 0.5 + 0.004 n)``: pure Python needs
    about ten times longer for the same quality.
    """
    if library:
        return min(3.5, 0.1 + 0.0011 * n)
    return min(5.0, 0.5 + 0.004 * n)


def _with_dummy(dist: np.ndarray, start: int | None, end: int | None) -> np.ndarray:
    """The matrix plus one dummy node (last) that turns a path problem into a closed tour (module docstring)."""
    n = len(dist)
    out = np.zeros((n + 1, n + 1))
    out[:n, :n] = dist
    if start is not None or end is not None:
        row = np.full(n, 2.0 * float(dist.max()) + 1.0)
        for i in (start, end):
            if i is not None:
                row[i] = 0.0
        out[n, :n] = row
        out[:n, n] = row
    return out


def _open_at_dummy(tour: np.ndarray, dummy: int, start: int | None, end: int | None) -> np.ndarray | None:
    """The path left when the dummy is cut out of a closed tour, oriented to the fixed ends (None if they fail)."""
    k = int(np.flatnonzero(tour == dummy)[0])
    path = np.roll(tour, -k)[1:]
    if (start is not None and path[0] != start) or (start is None and end is not None and path[-1] != end):
        path = path[::-1]
    if (start is not None and path[0] != start) or (end is not None and path[-1] != end):
        return None
    return path.astype(np.intp)


def _first_path(dist: np.ndarray, start: int | None, end: int | None) -> np.ndarray:
    """A nearest-neighbour path that respects the fixed ends."""
    if start is None and end is not None:
        return nearest_neighbour(dist, first=end)[::-1].copy()
    return nearest_neighbour(dist, first=0 if start is None else start, last=end)


def _own_heuristic(
    work: np.ndarray, first: np.ndarray, method: str, budget: float, seed: int, pinned: tuple[int, ...]
) -> np.ndarray:
    if method == "nearest":
        return first
    if method == "2opt":
        return two_opt(work, first)
    return iterated_local_search(work, first, time_limit_s=budget, seed=seed, pinned=pinned)


def _heuristic(dist, method, closed, start, end, budget, seed) -> tuple[np.ndarray, str]:
    """The closed-tour heuristics, through the dummy-node reduction for paths."""
    n = len(dist)
    as_path = not closed or (start is not None and end is not None)
    if as_path:
        work = _with_dummy(dist, start, end)
        first = np.append(_first_path(dist, start, end), n)
        pinned = (n,) if (start is not None or end is not None) else ()
    else:
        work, first, pinned = dist, nearest_neighbour(dist), ()
    tour = None
    if method == "fast-tsp":
        tour = fast_tsp_tour(work, budget)
        if as_path and _open_at_dummy(tour, n, start, end) is None:
            logger.warning("fast-tsp moved a fixed end of the path: using sprayplan's own local search instead")
            tour, method = None, "local"
    if tour is None:
        tour = _own_heuristic(work, first, method, budget, seed, pinned)
    if as_path:
        order = _open_at_dummy(tour, n, start, end)
        if order is None:  # cannot happen with the dummy's pricing; kept as a guard for the invariant
            raise RuntimeError("internal error: the local search moved a fixed end of the path")
        return order, method
    if start is not None:
        tour = np.roll(tour, -int(np.flatnonzero(tour == start)[0]))
    elif end is not None:
        tour = np.roll(tour, n - 1 - int(np.flatnonzero(tour == end)[0]))
    return tour.astype(np.intp), method


def _solve(dist, method, closed, start, end, time_limit_s, seed) -> TourResult:
    if method not in METHODS:
        raise ConfigError(f"method must be one of {METHODS}, got {method!r}")
    limit = check_time_limit(time_limit_s)
    n = len(dist)
    start, end = check_ends(n, closed, start, end)
    if n <= 3 or method == "exact" or (method == "auto" and n <= AUTO_EXACT_N):
        order, used = exact_tour(dist, closed, start, end), "exact"
    elif method == "ga":
        order = ga_tour_matrix(
            dist, params=GA_DEFAULT, closed=closed, start=start, end=end, time_limit_s=limit, seed=seed
        ).order
        used = "ga"
    else:
        if method in ("auto", "fast-tsp"):
            method = "fast-tsp" if fast_tsp_available() else "local"
        budget = default_time_limit(n, library=method == "fast-tsp") if limit is None else limit
        order, used = _heuristic(dist, method, closed, start, end, budget, seed)
    return TourResult(order=order, length=matrix_path_length(dist, order, closed), method=used)


def solve_tour(
    points,
    *,
    method: str = "auto",
    closed: bool = True,
    start: int | None = None,
    end: int | None = None,
    metric: str = "euclidean",
    time_limit_s: float | None = None,
    seed: int = 0,
) -> TourResult:
    """Shortest tour (or open path) through points.

    Parameters
    ----------
    points : (n, 2) or (n, 3) float
        Points to visit; any ``n >= 0``. The full distance matrix is built (``8 n**2`` bytes).
    method : {"auto", "exact", "fast-tsp", "local", "2opt", "nearest", "ga"}
        See the module docstring.
    closed : bool
        True: a closed tour, whose length includes the edge from the last point back to the first. False: an
        open path.
    start, end : int or None
        Index of the point the order must begin / end with. For a closed tour with only one of them, the best
        tour is rotated; with both, the edge ``end -> start`` closes it.
    metric : {"euclidean", "manhattan"}
        Distance between points (manhattan: a gantry with one motor per axis, seed 000 s5.1.3).
    time_limit_s : float or None
        Budget of the time-bounded methods (``"auto"``, ``"fast-tsp"``, ``"local"``, ``"ga"``); None:
        :func:`default_time_limit` (the GA then runs all its generations).
    seed : int
        Seed of the random methods (``"local"``, ``"ga"``). fast-tsp has no seed and stops on the clock: its
        tours can differ from run to run (rarely in length).

    Returns
    -------
    TourResult
        ``order``, ``length`` (in the metric asked for) and the ``method`` used.

    Raises
    ------
    InputError
        If ``points`` is not a finite (n, 2) or (n, 3) array.
    ConfigError
        For an unknown method or metric, bad ``start`` / ``end`` / ``time_limit_s``, or ``method="exact"``
        with more than :data:`EXACT_MAX_N` points.
    """
    pts = check_points(points, dim=(2, 3), empty_list=True)
    check_metric(metric)
    return _solve(distance_matrix(pts, metric), method, closed, start, end, time_limit_s, seed)


def solve_tour_matrix(
    dist,
    *,
    method: str = "auto",
    closed: bool = True,
    start: int | None = None,
    end: int | None = None,
    time_limit_s: float | None = None,
    seed: int = 0,
) -> TourResult:
    """:func:`solve_tour` on a given symmetric distance matrix (costs other than point distances).

    Parameters
    ----------
    dist : (n, n) float
        Symmetric, finite, non-negative.

    Other parameters are those of :func:`solve_tour`; ``length`` is measured on ``dist``.
    """
    return _solve(check_distance_matrix(dist), method, closed, start, end, time_limit_s, seed)
