"""The ``fast-tsp`` library (MIT, https://github.com/shmulvad/fast-tsp) behind sprayplan's tour solver.

fast-tsp is a compiled (Rust) local search: a Lin-Kernighan step over neighbour lists (LKH-style alpha-nearness
candidates on larger problems) with don't-look bits, local kicks and restarts, and Held-Karp below 21 nodes. It
reaches the optimum of the TSPLIB instances up to pr1002 in under a second here (``bench/bench_tours.py``). It takes a symmetric matrix of
unsigned 16-bit integer distances, so :func:`fast_tsp_tour` scales the float matrix to use the whole range
(largest entry -> 65535; a relative rounding of at most 1/131070 of the longest distance per edge) and measures
the tour it returns on the float matrix again.

It is optional at run time: :func:`fast_tsp_available` says whether it imports, and the caller falls back to
:mod:`sprayplan.ordering.local`. It is not seeded; it runs until its time budget, so two runs can return
different tours of (nearly always) the same length.
"""

from __future__ import annotations

import functools
import logging

import numpy as np

logger = logging.getLogger(__name__)

_UINT16_MAX = 65535


@functools.cache
def fast_tsp_available() -> bool:
    """Whether the ``fast_tsp`` module imports (checked once, logged once when it does not)."""
    try:
        import fast_tsp  # noqa: F401
    except ImportError as exc:
        logger.warning("fast-tsp is not installed (%s): tours use sprayplan's own local search", exc)
        return False
    return True


def fast_tsp_tour(dist: np.ndarray, time_limit_s: float) -> np.ndarray:
    """A closed tour by ``fast_tsp.find_tour`` on a float distance matrix.

    Parameters
    ----------
    dist : (n, n) float
        Symmetric, non-negative, zero diagonal, ``n >= 2``.
    time_limit_s : float
        fast-tsp's wall-clock budget (it uses all of it, on one thread).

    Returns
    -------
    order : (n,) int
        A closed tour.
    """
    import fast_tsp

    top = float(dist.max())
    if top <= 0.0:
        return np.arange(len(dist), dtype=np.intp)
    scaled = np.rint(dist * (_UINT16_MAX / top)).astype(np.int64)
    scaled = np.minimum(scaled, scaled.T)
    np.fill_diagonal(scaled, 0)
    tour = fast_tsp.find_tour(scaled, duration_seconds=float(time_limit_s), max_threads=1)
    return np.asarray(tour, dtype=np.intp)
