"""The ``ordering`` stage of the main job: the order of the work at each station (seed 000 section 5.2).

In paths mode a station's strokes are ordered, each either way round, to shorten the spray-off moves between
them (``order_strokes``; ``keep``: as sliced); in points mode its target points are visited in a
travelling-salesman tour (the seed's GA with ``tour = "ga"``). Spray-off transfers are put between the
strokes (``paths.planner.with_transfers``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sprayplan.config import JobConfig, OrderingConfig
from sprayplan.paths.planner import with_transfers
from sprayplan.progress import Progress, counted
from sprayplan.stations.stage import StationLayout
from sprayplan.types import Stroke

#: Tour method of ``auto``: the deterministic nearest neighbour + 2-opt + Or-opt descent, so that the same
#: part and settings give the same plan on any machine (the time-bounded solvers' results depend on the
#: machine's speed). Order strokes with ``tour="exact"`` (up to 6) for the optimum.
REPRODUCIBLE = "2opt"

#: Most strokes ordered exactly with ``tour = "exact"``.
EXACT_STROKES = 6


@dataclass(frozen=True)
class OrderedStations:
    """The ordering's result: the stations of a layout, each with its strokes in execution order.

    Attributes
    ----------
    layout : StationLayout
        The stations (visiting order, platforms, home, unassigned points).
    strokes : tuple of tuple of Stroke
        For each station, spray strokes and the transfers between them, in execution order.
    """

    layout: StationLayout
    strokes: tuple

    def __post_init__(self):
        strokes = tuple(tuple(s) for s in self.strokes)
        if len(strokes) != len(self.layout.index):
            raise ValueError("strokes must have one entry per station of the layout")
        object.__setattr__(self, "strokes", strokes)


def order_pieces(pieces, config: OrderingConfig, mode: str) -> list[Stroke]:
    """A station's spray pieces in execution order (without transfers).

    Parameters
    ----------
    pieces : sequence of Stroke
    config : OrderingConfig
    mode : {"paths", "points"}
        ``points``: the pieces are target points, visited in one tour (returned as a single stroke).
    """
    from sprayplan.ordering import EXACT_MAX_N, order_strokes, solve_tour

    pieces = list(pieces)
    if mode == "points":
        if len(pieces) == 1:
            return pieces
        tcp = np.concatenate([p.tcp for p in pieces])
        method = {"keep": REPRODUCIBLE, "auto": REPRODUCIBLE}.get(config.tour, config.tour)
        if method == "exact" and len(tcp) > EXACT_MAX_N:
            method = REPRODUCIBLE
        order = solve_tour(tcp, method=method, closed=False, seed=config.seed).order
        points = np.concatenate([p.points for p in pieces])[order]
        normals = np.concatenate([p.normals for p in pieces])[order]
        dwell = np.concatenate([p.dwell for p in pieces])[order]
        return [Stroke(points, normals, tcp[order], True, None, -1, dwell)]
    if config.tour == "keep" or len(pieces) == 1:
        return pieces
    starts = np.array([p.tcp[0] for p in pieces])
    ends = np.array([p.tcp[-1] for p in pieces])
    if config.tour == "exact" and len(pieces) <= EXACT_STROKES:
        method = "exact"
    else:
        method = "ga" if config.tour == "ga" else REPRODUCIBLE
    order, reverse, _ = order_strokes(starts, ends, start_point=None, method=method, seed=config.seed)
    return [pieces[i].reversed() if r else pieces[i] for i, r in zip(order, reverse)]


def ordering_stage(layout: StationLayout, job: JobConfig, progress: Progress | None = None) -> OrderedStations:
    """Every station's strokes in execution order, with the spray-off transfers between them."""
    step = counted(progress, "ordering", len(layout.pieces))
    out = []
    for pieces in layout.pieces:
        out.append(tuple(with_transfers(order_pieces(pieces, job.ordering, job.mode), job.paths)))
        step()
    return OrderedStations(layout, tuple(out))
