"""Order the strokes of a station: which stroke to paint next, and which way round, to spray-off travel least.

A stroke is painted from one end to the other with the gun on; between strokes the gun travels with the spray off
(the *transfer*). Each stroke may be run either way. :func:`order_strokes` minimises the total transfer length
(straight lines, mm): from ``start_point`` (if given) to the first stroke's entry, then from each stroke's exit to
the next one's entry. There is no return edge.

Three solvers:

- small stations (``m <= EXACT_MAX_STROKES`` with ``method="auto"`` or ``"exact"``): Held-Karp over (stroke,
  direction) pairs (:func:`~sprayplan.ordering.exact.held_karp` with two nodes per group), exact;
- otherwise the standard ``2m``-node construction: one node per stroke end, the two ends of a stroke joined by an
  edge of cost 0 and every other edge priced ``M = max(d) + 1`` above its length, so that any tour through the
  ends pays exactly ``m`` times ``M`` when it runs every stroke whole and more when it does not; the tour solver
  of :mod:`sprayplan.ordering.tour` then orders the ends (an open path, from ``start_point`` when given).
  The stroke order is read off the path (first visit of each stroke), the directions are then chosen optimally
  for that order by dynamic programming;
- ``method="ga"``: the seed's genetic algorithm over stroke orders, each order priced with its best directions.

The result is finally compared with the input order (with its best directions, which include running it as
given or in zig-zag) and the better of the two is returned, so ordering never lengthens the transfer of the
order the strokes came in, and keeps that order when it is already optimal.
"""

from __future__ import annotations

import logging

import numpy as np

from sprayplan.checks import check_points
from sprayplan.errors import ConfigError, InputError
from sprayplan.ordering.exact import held_karp
from sprayplan.ordering.genetic import GA_DEFAULT, evolve_permutations
from sprayplan.ordering.metrics import check_time_limit, distance_matrix, pair_distances
from sprayplan.ordering.tour import METHODS, solve_tour_matrix

logger = logging.getLogger(__name__)

#: Largest station ordered exactly by ``method="auto"`` or ``"exact"`` (2**12 subsets x 24 oriented strokes).
EXACT_MAX_STROKES = 12
STROKE_METHODS = METHODS


def _check_strokes(starts, ends, start_point):
    s = check_points(starts, "starts", dim=(2, 3), empty_list=True)
    e = check_points(ends, "ends", dim=(2, 3), empty_list=True)
    if s.shape != e.shape:
        raise InputError(f"starts and ends must have the same shape, got {s.shape} and {e.shape}")
    p = None
    if start_point is not None:
        p = np.array(start_point, dtype=float).reshape(-1)
        if p.shape != (s.shape[1],) or not np.all(np.isfinite(p)):
            raise InputError(f"start_point must be a finite ({s.shape[1]},) point, got shape {p.shape}")
    return s, e, p


def _entry_exit(starts, ends, order, rev):
    """Entry and exit points of the strokes run in ``order`` with directions ``rev`` (aligned with order)."""
    rev = np.asarray(rev, dtype=bool)[:, None]
    s, e = starts[order], ends[order]
    return np.where(rev, e, s), np.where(rev, s, e)


def stroke_transfer(starts, ends, order, reversed_, start_point=None) -> float:
    """Total spray-off travel of running strokes in a given order and directions.

    Parameters
    ----------
    starts, ends : (m, 3) float
        First and last point of each stroke as planned, mm.
    order : (m,) int
        A permutation: the k-th stroke run is ``order[k]``.
    reversed_ : (m,) bool
        ``reversed_[k]``: the k-th stroke run (stroke ``order[k]``) goes from its end to its start.
    start_point : (3,) float or None
        Where the gun is before the first stroke.

    Returns
    -------
    transfer : float
        Sum of the straight-line distances from each exit to the next entry (and from ``start_point``), mm.
    """
    s, e, p = _check_strokes(starts, ends, start_point)
    order = np.asarray(order, dtype=np.intp)
    if len(order) == 0:
        return 0.0
    entry, exit_ = _entry_exit(s, e, order, reversed_)
    total = float(pair_distances(exit_[:-1], entry[1:]).sum())
    if p is not None:
        total += float(pair_distances(p, entry[0]))
    return total


def _best_directions(starts, ends, order, start_point) -> tuple[np.ndarray, float]:
    """Optimal directions for a fixed order, by dynamic programming over (stroke, direction)."""
    m = len(order)
    ends2 = np.stack([starts[order], ends[order]], axis=1)  # (m, 2, d): [k, 0] = start, [k, 1] = end
    # Entry of direction r is ends2[k, r]; its exit is ends2[k, 1 - r].
    if start_point is not None:
        cost = pair_distances(start_point[None, :], ends2[0]).tolist()
    else:
        cost = [0.0, 0.0]
    # hop[k, a, b]: exit of stroke k in direction a -> entry of stroke k+1 in direction b.
    hop = pair_distances(ends2[:-1, ::-1, None, :], ends2[1:, None, :, :]).tolist()
    back = []
    for k in range(m - 1):
        h = hop[k]
        new, arg = [], []
        for b in (0, 1):
            c0, c1 = cost[0] + h[0][b], cost[1] + h[1][b]
            arg.append(0 if c0 <= c1 else 1)
            new.append(min(c0, c1))
        back.append(arg)
        cost = new
    last = 0 if cost[0] <= cost[1] else 1
    rev = np.empty(m, dtype=bool)
    rev[m - 1] = bool(last)
    for k in range(m - 2, -1, -1):
        last = back[k][last]
        rev[k] = bool(last)
    return rev, float(min(cost))


def _exact_order(starts, ends, start_point) -> np.ndarray:
    m = len(starts)
    entry = np.concatenate([starts, ends])  # node u < m: stroke u forwards; u >= m: stroke u - m backwards
    exit_ = np.concatenate([ends, starts])
    cost = distance_matrix(np.concatenate([exit_, entry]))[: 2 * m, 2 * m :]
    init = pair_distances(start_point[None, :], entry) if start_point is not None else np.zeros(2 * m)
    seq, _ = held_karp(cost, np.tile(np.arange(m), 2), init, np.zeros(2 * m))
    return seq % m


def _ga_order(starts, ends, start_point, time_limit_s, seed) -> np.ndarray:
    """The seed's GA over stroke orders; each chromosome is priced with its best directions (DP, vectorised)."""
    m = len(starts)
    entry = np.stack([starts, ends], axis=1)  # entry[i, r]: entry of stroke i run in direction r
    exit_ = entry[:, ::-1]
    hop = pair_distances(exit_[:, None, :, None, :], entry[None, :, None, :, :])  # (m, m, 2, 2)
    init = pair_distances(start_point, entry) if start_point is not None else np.zeros((m, 2))

    # Columns of hop4: exit direction a -> entry direction b, as (a, b) = (0, 0), (0, 1), (1, 0), (1, 1).
    hop4 = hop.reshape(m * m, 4).T.copy()
    init0, init1 = init[:, 0].copy(), init[:, 1].copy()

    def lengths(pop: np.ndarray) -> np.ndarray:
        c0, c1 = init0[pop[:, 0]], init1[pop[:, 0]]
        pair = pop[:, :-1] * m + pop[:, 1:]
        for k in range(m - 1):
            h = hop4[:, pair[:, k]]
            c0, c1 = np.minimum(c0 + h[0], c1 + h[2]), np.minimum(c0 + h[1], c1 + h[3])
        return np.minimum(c0, c1)

    best, _, _ = evolve_permutations(
        m, lengths, GA_DEFAULT, check_time_limit(time_limit_s), np.random.default_rng(seed)
    )
    return best


def _tour_order(starts, ends, start_point, method, time_limit_s, seed) -> np.ndarray:
    m = len(starts)
    pts = np.concatenate([starts, ends] + ([start_point[None, :]] if start_point is not None else []))
    d = distance_matrix(pts)
    weights = d + (float(d.max()) + 1.0)
    np.fill_diagonal(weights, 0.0)
    ties = np.arange(m)
    weights[ties, ties + m] = weights[ties + m, ties] = 0.0
    first = 2 * m if start_point is not None else None
    path = solve_tour_matrix(
        weights, method=method, closed=False, start=first, time_limit_s=time_limit_s, seed=seed
    ).order
    path = path[path < 2 * m]
    stroke = path % m
    if not np.all(stroke[0::2] == stroke[1::2]):
        logger.debug("the end-point tour split a stroke: its order is taken from the first visits")
    _, first_seen = np.unique(stroke, return_index=True)
    return stroke[np.sort(first_seen)]


def order_strokes(
    starts, ends, *, start_point=None, method: str = "auto", time_limit_s: float | None = None, seed: int = 0
) -> tuple[np.ndarray, np.ndarray, float]:
    """Order and orient the strokes of a station to minimise the spray-off transfer between them.

    Parameters
    ----------
    starts, ends : (m, 3) float
        First and last point of each stroke as planned, mm (``(m, 2)`` works too).
    start_point : (3,) float or None
        Where the gun is before the first stroke (its travel to the first stroke is counted); None: free start.
    method : {"auto", "exact", "fast-tsp", "local", "2opt", "nearest", "ga"}
        ``"auto"``: exact up to :data:`EXACT_MAX_STROKES` strokes, else the end-point tour with the default tour
        solver. ``"exact"``: Held-Karp, at most :data:`EXACT_MAX_STROKES` strokes. ``"ga"``: the seed's GA
        (:data:`~sprayplan.ordering.genetic.GA_DEFAULT`) over stroke orders, each priced with its best directions
        (slow for many strokes: 2000 generations of m vectorised steps). Others: the end-point tour with that tour
        method (see :func:`~sprayplan.ordering.tour.solve_tour`).
    time_limit_s : float or None
        Budget of the tour solver; None: its default for ``2m (+1)`` nodes (for ``"ga"``: all generations).
    seed : int
        Seed of the random tour methods.

    Returns
    -------
    order : (m,) int
        Permutation: the k-th stroke to run is ``order[k]``.
    reversed : (m,) bool
        ``reversed[k]``: stroke ``order[k]`` runs from its end to its start.
    transfer_length : float
        The total transfer, mm (see :func:`stroke_transfer`); never more than that of the input order run with
        its best directions.

    Raises
    ------
    InputError
        For arrays of the wrong shape.
    ConfigError
        For an unknown method, or ``"exact"`` with too many strokes.
    """
    s, e, p = _check_strokes(starts, ends, start_point)
    if method not in STROKE_METHODS:
        raise ConfigError(f"method must be one of {STROKE_METHODS}, got {method!r}")
    m = len(s)
    if m == 0:
        return np.zeros(0, dtype=np.intp), np.zeros(0, dtype=bool), 0.0
    if method == "exact" and m > EXACT_MAX_STROKES:
        raise ConfigError(f"method 'exact' orders at most {EXACT_MAX_STROKES} strokes, got {m}: use 'auto'")
    identity = np.arange(m)
    base_rev, base_len = _best_directions(s, e, identity, p)
    if m == 1:
        return identity, base_rev, base_len
    if method in ("auto", "exact") and m <= EXACT_MAX_STROKES:
        order = _exact_order(s, e, p)
    elif method == "ga":
        order = _ga_order(s, e, p, time_limit_s, seed)
    else:
        order = _tour_order(s, e, p, method, time_limit_s, seed)
    rev, length = _best_directions(s, e, order, p)
    if length < base_len - 1e-9 * max(1.0, base_len):
        return order.astype(np.intp), rev, length
    return identity, base_rev, base_len
