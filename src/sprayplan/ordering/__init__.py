"""Ordering: the order in which a station's points or strokes are visited (seed 000 s5.1.3 and s5.2).

- :func:`solve_tour` / :func:`solve_tour_matrix`: shortest closed tour or open path (fixed ends optional),
  Euclidean or Manhattan, by Held-Karp (small), the ``fast-tsp`` library (default; sprayplan's own iterated
  local search if it is missing), nearest neighbour + 2-opt, or the seed's genetic algorithm.
- :func:`ga_tour`: the seed's GA with its parameters (:data:`GA_SEED`) or everyday ones (:data:`GA_DEFAULT`),
  with the best-length history.
- :func:`order_strokes`: order and orient strokes to minimise the spray-off transfer between them.
- :func:`read_tsplib`, :func:`tour_length`: TSPLIB instances for tests and benchmarks, tour lengths.
"""

from __future__ import annotations

from sprayplan.ordering.exact import EXACT_MAX_N
from sprayplan.ordering.genetic import GA_DEFAULT, GA_SEED, GAParams, GAResult, ga_tour, ga_tour_matrix
from sprayplan.ordering.metrics import METRICS, distance_matrix, tour_length
from sprayplan.ordering.strokes import EXACT_MAX_STROKES, order_strokes, stroke_transfer
from sprayplan.ordering.tour import METHODS, TourResult, default_time_limit, solve_tour, solve_tour_matrix
from sprayplan.ordering.tsplib import read_tsplib

__all__ = [
    "EXACT_MAX_N",
    "EXACT_MAX_STROKES",
    "GA_DEFAULT",
    "GA_SEED",
    "METHODS",
    "METRICS",
    "GAParams",
    "GAResult",
    "TourResult",
    "default_time_limit",
    "distance_matrix",
    "ga_tour",
    "ga_tour_matrix",
    "order_strokes",
    "read_tsplib",
    "solve_tour",
    "solve_tour_matrix",
    "stroke_transfer",
    "tour_length",
]
