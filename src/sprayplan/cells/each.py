"""The robots of a cell worked on side by side: one forked process a robot (``[collision] workers``).

A cell plan's collision work is per robot and independent: each robot's strokes are checked, repaired, cut and
routed against the body with its own arm (:func:`~sprayplan.cells.collide.freed_cell`), checked again after the
film (:func:`~sprayplan.cells.collide.check_cell`), and given run-ups (:mod:`~sprayplan.cells.runups`); no robot
reads another's. On the BMW in ``line3`` these steps took 35 minutes one robot after the other, almost all of it
numpy and coal calls made from Python, which hold the interpreter lock, so threads would not overlap them.
:func:`each_robot` runs the calls in processes forked from the planner: a child inherits the arms' collision
models (coal's BVH and the surface samples, which do not pickle) as they are, and only each call's result is
sent back. Each call is the same function on the same inputs as in one process, so the results are the same
(``tests/test_cell_each.py``). Where the platform cannot fork (Windows), or one worker is asked for, the calls
run one after the other in this process; so they do, with a warning, when a child is killed (out of memory,
say). The memory a plan takes is then the planner's and its children's together: each child holds its copy of
what it changes of the planner's memory, and its robot's work.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool

log = logging.getLogger(__name__)

#: The calls of the running :func:`each_robot`, read by the forked children (inherited, never pickled).
_CALLS: list = []


def _run(index: int):
    fn, args = _CALLS[index]
    return fn(*args)


def cores() -> int:
    """The cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def worker_count(workers: int | None, calls: int) -> int:
    """``workers`` (None: the cores), at most one per call, at least 1."""
    count = cores() if workers is None else int(workers)
    return max(1, min(count, calls))


def each_robot(calls: list, workers: int | None = None, sizes=None) -> list:
    """``[fn(*args) for fn, args in calls]``, up to ``workers`` at a time in forked processes (None: the cores).

    ``sizes``: the work of each call (waypoints, say); the largest are started first, so that with fewer
    workers than calls the small ones fill in at the end. The results come back in the order of ``calls``. An
    exception in a call is raised here, as in one process."""
    count = worker_count(workers, len(calls))
    if count <= 1 or "fork" not in multiprocessing.get_all_start_methods():
        return [fn(*args) for fn, args in calls]
    order = list(range(len(calls)))
    if sizes is not None:
        order.sort(key=lambda i: -sizes[i])
    _CALLS[:] = calls
    try:
        log.debug("%d robots on %d processes", len(calls), count)
        with ProcessPoolExecutor(count, mp_context=multiprocessing.get_context("fork")) as pool:
            futures = {i: pool.submit(_run, i) for i in order}
            return [futures[i].result() for i in range(len(calls))]
    except BrokenProcessPool:
        # a child was killed (out of memory, a signal): the robots' work again, one after the other, here
        log.warning("a robot's process ended abruptly; its work is done again in the planner's process")
        return [fn(*args) for fn, args in calls]
    finally:
        _CALLS.clear()
