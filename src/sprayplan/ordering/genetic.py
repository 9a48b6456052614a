"""The genetic algorithm of seed 000 (s5.2.2, figures 17-20, eq. 31), vectorised over the population.

How the seed's text was read
----------------------------
- (1) Coding: one chromosome per individual, a permutation of the points to visit.
- (2)-(3) Fitness ``f = N / L`` with ``L`` the tour length in the metric asked for (the seed's sum
  ``sum_{i=2}^{n} d_{i(i+1)}`` lost its bounds in extraction; a TSP tour is read). The gain ``N`` is 1: it scales
  every fitness alike and, with the min-max normalisation below, changes nothing.
- (4) Selection, figure 18: the best individual is kept unchanged (elitism); the other ``population - 1`` places
  are filled by roulette wheel: the fitness values are min-max normalised to ``[0, 1]``
  (``w = (f - f_min) / (f_max - f_min)``, so the worst individual is never drawn; all alike: uniform), their
  cumulative distribution is scaled to end at 1, and each uniform draw ``r`` takes the first individual whose
  cumulative value exceeds ``r``.
- (5) Crossover, figure 19: the non-elite individuals are paired in order (1-2, 3-4, ...); each pair is crossed
  with probability ``Pc``. Order crossover (OX) as the figure's example defines it: both children keep the
  segment ``[start, end]`` of one parent in place and fill the other places *from the left* with the other
  parent's genes in that parent's order (parents 12345 and 54321 with start = 2, end = 3 give 52341 and 14325).
- (6) Mutation, figure 20, eq. 31: each non-elite individual reverses a random segment ``[start, end]`` with the
  adaptive probability of eq. 31. The printed equation mixes K2 and k2 and calls ``f`` "the fitness of the
  individuals to be crossed", and section 6.3 calls K1, K2 "the selection probability"; figure 20 tests
  ``P > P_c``. All of that is the adaptive *mutation* rate of Srinivas and Patnaik (IEEE Trans. SMC 24(4), 1994),
  which this module implements::

      P_m = K1 * (f_max - f) / (f_max - f_avg)   if f >= f_avg
      P_m = K2                                   if f <  f_avg

  with ``f`` the fitness of the individual to be mutated (after crossover) and ``f_max``, ``f_avg`` the largest
  and mean fitness of the population after crossover. Good individuals mutate less (the best: not at all), poor
  ones at the constant rate K2. When ``f_max == f_avg`` (a converged population) the rate is K1, the limit at
  ``f = f_avg``.

The elite survives every generation unchanged, so the best length never grows: :class:`GAResult` keeps the
best length of every generation in ``history``.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from sprayplan.checks import check_points
from sprayplan.errors import ConfigError
from sprayplan.ordering.metrics import (
    check_distance_matrix,
    check_ends,
    check_metric,
    check_time_limit,
    distance_matrix,
    matrix_path_length,
)

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class GAParams:
    """Parameters of the seed's genetic algorithm.

    Parameters
    ----------
    population : int
        Individuals per generation, at least 2.
    generations : int
        Generations to run, at least 0.
    crossover : float
        Crossover probability ``Pc`` of a pair, in ``[0, 1]``.
    k1, k2 : float
        Adaptive mutation parameters of eq. 31, in ``[0, 1]``.
    """

    population: int = 200
    generations: int = 2000
    crossover: float = 0.9
    k1: float = 0.15
    k2: float = 0.2

    def __post_init__(self):
        if isinstance(self.population, bool) or not isinstance(self.population, int) or self.population < 2:
            raise ConfigError(f"population must be an integer >= 2, got {self.population!r}")
        if isinstance(self.generations, bool) or not isinstance(self.generations, int) or self.generations < 0:
            raise ConfigError(f"generations must be an integer >= 0, got {self.generations!r}")
        for name in ("crossover", "k1", "k2"):
            value = getattr(self, name)
            if not isinstance(value, int | float) or not 0.0 <= value <= 1.0:
                raise ConfigError(f"{name} must be a probability in [0, 1], got {value!r}")


#: Seed 000, s6.3: population 5000, 25,000 generations, Pc 0.9, K1 0.15, K2 0.2. In this implementation a
#: generation of 5000 takes about 18 ms for 52 points, 36 ms for 100 and 0.4 s for 1000: 7 min, 15 min and
#: 3 h for the full run. For reproducing the paper, not for everyday use.
GA_SEED = GAParams(population=5000, generations=25000, crossover=0.9, k1=0.15, k2=0.2)
#: Everyday default (``solve_tour(method="ga")``): the seed's rates with population 200 and 2000 generations,
#: about 1-3 s for 50-200 points.
GA_DEFAULT = GAParams()


@dataclass(frozen=True)
class GAResult:
    """Result of :func:`ga_tour`.

    Attributes
    ----------
    order : (n,) int
        Best order found (a permutation; begins with ``start`` / ends with ``end`` when given).
    length : float
        Its length in the metric asked for, with the closing edge when closed.
    history : (g + 1,) float
        Best length after each generation, starting with the random initial population; never increases.
    generations : int
        Generations run (fewer than asked if the time limit stopped the run).
    """

    order: np.ndarray
    length: float
    history: np.ndarray
    generations: int


def order_crossover(parent_a: np.ndarray, parent_b: np.ndarray, cuts: np.ndarray) -> np.ndarray:
    """Order crossover (figure 19) of many pairs at once: segment from ``parent_a``, the rest in ``parent_b``'s order.

    Parameters
    ----------
    parent_a, parent_b : (k, m) int
        Rows are permutations of ``range(m)``.
    cuts : (k, 2) int
        ``start <= end`` positions (0-based, inclusive) of the kept segment of each pair.

    Returns
    -------
    children : (k, m) int
        ``children[i, start:end+1] == parent_a[i, start:end+1]``; the other places, left to right, hold the genes
        of ``parent_b[i]`` that are not in that segment, in ``parent_b``'s order.
    """
    k, m = parent_a.shape
    if k == 0:
        return parent_a.copy()
    j = np.arange(m)[None, :]
    lo, hi = cuts[:, :1], cuts[:, 1:]
    in_seg = (j >= lo) & (j <= hi)
    # Flat indices (row offset + column) are faster than 2-D fancy indexing.
    row = (np.arange(k) * m)[:, None]
    gene_in_seg = np.zeros(k * m, dtype=bool)
    gene_in_seg[row + parent_a] = in_seg
    keep = ~gene_in_seg[row + parent_b]
    # Each kept gene of parent_b goes to its rank among the kept ones; the others to a spare last column.
    dest = np.cumsum(keep, axis=1, dtype=np.int32)
    dest -= 1
    dest[~keep] = m
    row1 = (np.arange(k) * (m + 1))[:, None]
    fill = np.zeros(k * (m + 1), dtype=parent_b.dtype)
    fill[row1 + dest] = parent_b
    # Place j outside the segment takes fill[j] left of it and fill[j - segment length] right of it.
    src = j - (hi - lo + 1)
    np.copyto(src, np.broadcast_to(j, src.shape), where=j < lo)
    np.maximum(src, 0, out=src)
    child = fill[row1 + src]
    np.copyto(child, parent_a, where=in_seg)
    return child


def inversion_mutation(chromosomes: np.ndarray, cuts: np.ndarray) -> np.ndarray:
    """Inversion mutation (figure 20) of many chromosomes at once: reverse the genes from ``start`` to ``end``.

    Parameters
    ----------
    chromosomes : (k, m) int
    cuts : (k, 2) int
        ``start <= end`` positions (0-based, inclusive).

    Returns
    -------
    mutated : (k, m) int
    """
    j = np.arange(chromosomes.shape[1])[None, :]
    lo, hi = cuts[:, :1], cuts[:, 1:]
    idx = np.where((j >= lo) & (j <= hi), lo + hi - j, j)
    return np.take_along_axis(chromosomes, idx, axis=1)


def adaptive_mutation_rate(fitness: np.ndarray, f_max: float, f_avg: float, k1: float, k2: float) -> np.ndarray:
    """Mutation probability of eq. 31 (read as Srinivas and Patnaik's adaptive rate, see the module docstring).

    Parameters
    ----------
    fitness : (k,) float
        Fitness of the individuals to mutate.
    f_max, f_avg : float
        Largest and mean fitness of the population.
    k1, k2 : float

    Returns
    -------
    rate : (k,) float
    """
    fitness = np.asarray(fitness, dtype=float)
    spread = f_max - f_avg
    if spread <= 0:
        above = np.full(fitness.shape, k1)
    else:
        above = k1 * (f_max - fitness) / spread
    return np.where(fitness >= f_avg, np.clip(above, 0.0, k1), k2)


def _random_cuts(rng: np.random.Generator, k: int, m: int) -> np.ndarray:
    return np.sort(rng.integers(0, m, size=(k, 2)), axis=1)


def _matrix_lengths(sub: np.ndarray, head, tail, const: float, cyclic: bool):
    """Vectorised length of chromosomes over ``range(m)`` on a sub-matrix, with fixed head/tail costs."""
    m = len(sub)
    flat = sub.reshape(-1)

    def lengths(pop: np.ndarray) -> np.ndarray:
        out = flat[pop[:, :-1] * m + pop[:, 1:]].sum(axis=1) + const
        if cyclic:
            out += flat[pop[:, -1] * m + pop[:, 0]]
        if head is not None:
            out += head[pop[:, 0]]
        if tail is not None:
            out += tail[pop[:, -1]]
        return out

    return lengths


def evolve_permutations(
    m: int,
    lengths: Callable[[np.ndarray], np.ndarray],
    params: GAParams,
    time_limit_s: float | None,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray, int]:
    """The GA loop (figures 17-20) over permutations of ``range(m)`` with any vectorised cost.

    Parameters
    ----------
    m : int
        Chromosome length, at least 2.
    lengths : callable
        ``lengths(pop (k, m) int) -> (k,) float``, positive: the cost of each chromosome (fitness is 1 / cost).
    params : GAParams
    time_limit_s : float or None
    rng : numpy.random.Generator

    Returns
    -------
    best : (m,) int
        Best chromosome of the last generation.
    history : (g + 1,) float
        Best cost after each generation (non-increasing).
    generations : int
        Generations run.
    """
    size = params.population
    pop = rng.permuted(np.tile(np.arange(m), (size, 1)), axis=1)
    length = lengths(pop)
    # Fitness is 1 / cost; a cost floor keeps it finite when some chromosome costs nothing (strokes end to end).
    floor = 1e-9 * float(length.mean()) + 1e-300
    best = int(np.argmin(length))
    history = [float(length[best])]
    deadline = None if time_limit_s is None else time.perf_counter() + time_limit_s
    done = 0
    n_pairs = (size - 1) // 2
    for _ in range(params.generations):
        if deadline is not None and time.perf_counter() > deadline:
            logger.info("GA stopped by its time limit after %d generations", done)
            break
        # Selection (figure 18): elite kept, roulette on the min-max normalised fitness.
        fitness = 1.0 / np.maximum(length, floor)
        f_lo, f_hi = fitness.min(), fitness.max()
        weight = (fitness - f_lo) / (f_hi - f_lo) if f_hi > f_lo else np.ones(size)
        cdf = np.cumsum(weight)
        cdf /= cdf[-1]
        picks = np.minimum(np.searchsorted(cdf, rng.random(size - 1), side="right"), size - 1)
        elite = pop[best]
        kids = pop[picks]
        # Crossover (figure 19) on pairs of non-elite individuals, in order.
        crossed = np.flatnonzero(rng.random(n_pairs) < params.crossover)
        if len(crossed):
            first, second = kids[2 * crossed], kids[2 * crossed + 1]
            cuts = _random_cuts(rng, len(crossed), m)
            kids[2 * crossed] = order_crossover(first, second, cuts)
            kids[2 * crossed + 1] = order_crossover(second, first, cuts)
        kid_length = lengths(kids)
        # Mutation (figure 20) with the adaptive rate of eq. 31, on the population after crossover.
        all_fit = 1.0 / np.maximum(np.concatenate([[length[best]], kid_length]), floor)
        rate = adaptive_mutation_rate(all_fit[1:], all_fit.max(), all_fit.mean(), params.k1, params.k2)
        mutated = np.flatnonzero(rng.random(size - 1) < rate)
        if len(mutated):
            kids[mutated] = inversion_mutation(kids[mutated], _random_cuts(rng, len(mutated), m))
            kid_length[mutated] = lengths(kids[mutated])
        pop = np.vstack([elite[None, :], kids])
        length = np.concatenate([[length[best]], kid_length])
        best = int(np.argmin(length))
        history.append(float(length[best]))
        done += 1
    return pop[best], np.array(history), done


def ga_tour_matrix(
    dist,
    *,
    params: GAParams = GA_DEFAULT,
    closed: bool = True,
    start: int | None = None,
    end: int | None = None,
    time_limit_s: float | None = None,
    seed: int = 0,
) -> GAResult:
    """The seed's GA on a distance matrix (see :func:`ga_tour` for the arguments and the result)."""
    dist = check_distance_matrix(dist)
    n = len(dist)
    start, end = check_ends(n, closed, start, end)
    time_limit_s = check_time_limit(time_limit_s)
    rng = np.random.default_rng(seed)
    if closed and not (start is not None and end is not None):
        free, head, tail, const, cyclic = np.arange(n), None, None, 0.0, True
    else:
        fixed = [i for i in (start, end) if i is not None]
        free = np.setdiff1d(np.arange(n), fixed)
        head = dist[start, free] if start is not None else None
        tail = dist[free, end] if end is not None else None
        const = float(dist[end, start]) if closed else 0.0
        cyclic = False
    if len(free) < 2:
        chromosome, history, done = np.arange(len(free)), None, 0
    else:
        lengths = _matrix_lengths(dist[np.ix_(free, free)], head, tail, const, cyclic)
        chromosome, history, done = evolve_permutations(len(free), lengths, params, time_limit_s, rng)
    order = free[chromosome]
    if cyclic:
        if start is not None:
            order = np.roll(order, -int(np.flatnonzero(order == start)[0]))
        elif end is not None:
            order = np.roll(order, n - 1 - int(np.flatnonzero(order == end)[0]))
    else:
        order = np.concatenate([[start] if start is not None else [], order, [end] if end is not None else []])
    order = order.astype(np.intp)
    length = matrix_path_length(dist, order, closed)
    if history is None:
        history = np.array([length])
    return GAResult(order=order, length=length, history=history, generations=done)


def ga_tour(
    points,
    *,
    params: GAParams = GA_DEFAULT,
    closed: bool = True,
    start: int | None = None,
    end: int | None = None,
    metric: str = "euclidean",
    time_limit_s: float | None = None,
    seed: int = 0,
) -> GAResult:
    """Order points by the genetic algorithm of seed 000 (s5.2.2; see the module docstring for the reading).

    Parameters
    ----------
    points : (n, 2) or (n, 3) float
    params : GAParams
        :data:`GA_DEFAULT` (everyday) or :data:`GA_SEED` (the paper's, very slow), or your own.
    closed : bool
        Closed tour (length includes the edge back) or open path.
    start, end : int or None
        Fixed first / last point. For an open path the chromosome then holds only the other points; for a closed
        tour with one of them the best tour is rotated; with both, ``end -> start`` is the closing edge.
    metric : {"euclidean", "manhattan"}
    time_limit_s : float or None
        Stop after this many seconds even if generations remain (None: run them all).
    seed : int
        Seed of every random draw: the same seed and parameters give the same result (unless the time limit
        cuts the run).

    Returns
    -------
    GAResult
        Best order, its length, the best-length history and the generations run.
    """
    pts = check_points(points, dim=(2, 3), empty_list=True)
    check_metric(metric)
    return ga_tour_matrix(
        distance_matrix(pts, metric),
        params=params,
        closed=closed,
        start=start,
        end=end,
        time_limit_s=time_limit_s,
        seed=seed,
    )
