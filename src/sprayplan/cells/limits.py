"""A cell plan's speeds tuned within what its robots make (``[tuning] limit_rounds`` with ``--cell``).

The cell's form of :mod:`sprayplan.refine.limits` (the gantry plan's rounds; the rule is the same, the
bookkeeping is the cell's): the tuning's columns are the reached runs of the robots' spray strokes
(``cells.plan.reached_strokes``' owners), the timing is each robot's (:func:`sprayplan.cells.timing.time_cell`)
and the timed time factors come from its time stamps (:func:`~sprayplan.cells.timing.timed_factors`).

1. where a waypoint's timed factor exceeds its tuned one (by more than ``refine.limits.CAP_SLACK``), the robot
   cannot go faster there than the planned speed over the timed factor: that becomes the waypoint's lower
   bound (the bounds only rise);
2. the speeds are tuned again with those bounds (the same deposit matrix, from the last factors), so the other
   waypoints' speeds are spent on the film the capped ones make; where a bound is active the robot is asked for
   the speed the first tuning wanted (it makes what it can, as in the timing the bound came from);
3. timed again; up to ``limit_rounds`` rounds, until no waypoint is slower than tuned or the film at the timed
   speeds is the tuning's prediction (within a tenth of the tolerance) on all but 1 % of the tuned area.

After the last round the plan's factors are set to the timed ones wherever the robot is slower than tuned or a
bound is active, so the plan's own film is the one its robots leave at their timed speeds (up to the ends of
the stretches, which the timing of those factors starts and stops at rest again).
"""

from __future__ import annotations

import dataclasses
import logging

import numpy as np

from sprayplan.cells.timing import timed_factors, with_times
from sprayplan.cells.work import owned, runs_with_dwell, with_tuned_dwell
from sprayplan.refine.limits import CAP_SLACK, SETTLED_SHARE, SETTLED_TOLERANCES, _off_share, bounded_tuning
from sprayplan.refine.stage import lower_dwell, tuning_settings

log = logging.getLogger(__name__)


def _timed_columns(robots, timed, owners, job) -> np.ndarray:
    """The timed time factors of the robots' reached runs (``timed``: their ``WorkTiming``), in the tuning's
    column order."""
    return owned(timed_factors(with_times(robots, timed), job), robots, owners)


def _with_columns(robots, tuning, owners, dwell):
    """The robots with the factors ``dwell`` (the tuning's column order) on their reached runs."""
    return with_tuned_dwell(robots, runs_with_dwell(tuning.paths.strokes, dwell), owners)


def tune_cell_within_limits(part, robots, tuning, owners, job, process, coating, time_at, timed=None):
    """The robots' speeds tuned again within the speeds they make (module docstring).

    ``robots``: the tuned robots' work; ``tuning``: the last tuning over their reached runs (``owners``);
    ``time_at(robots)``: their timing (``time_cell`` with the job); ``timed``: that timing already made for
    ``robots``. Returns the robots (the last factors, raised to the timed ones where slower), the last round's
    timing (where a bound is active, of the speed the first tuning wanted: the speed the robot makes there), the
    last tuning (its runs at the robots' factors) and a summary: ``rounds``, ``capped_waypoints``, ``slower_than_tuned_waypoints``.
    """
    settings = job.tuning
    target, tol = float(job.coating.thickness_um), float(job.coating.tolerance)
    config = tuning_settings(settings)
    base_lower = lower_dwell(tuning.paths, settings)
    lower = base_lower.copy()
    dwell = np.concatenate([s.dwell for s in tuning.paths.strokes] or [np.zeros(0)])
    wanted = dwell.copy()
    timed = time_at(robots) if timed is None else timed
    rounds = 0
    for _ in range(settings.limit_rounds):
        at = _timed_columns(robots, timed, owners, job)
        slower = at > np.maximum(dwell, lower) * (1.0 + CAP_SLACK)
        if not slower.any():
            break
        lower[slower] = at[slower]
        tuning = bounded_tuning(part, tuning, process, (target, tol), config, coating, lower, dwell, settings.max_dwell)
        dwell = np.concatenate([s.dwell for s in tuning.paths.strokes])
        robots = _with_columns(robots, tuning, owners, dwell)
        active = (lower > base_lower * (1.0 + CAP_SLACK)) & (dwell <= lower * (1.0 + CAP_SLACK))
        timed = time_at(_with_columns(robots, tuning, owners, np.where(active, np.minimum(dwell, wanted), dwell)))
        rounds += 1
        off = _off_share(tuning, dwell, _timed_columns(robots, timed, owners, job), SETTLED_TOLERANCES * tol)
        log.info(
            "cell speeds tuned within the limits, round %d: %d waypoints capped, %.2f %% of the tuned area off "
            "the prediction at the timed speeds",
            rounds,
            int((lower > base_lower * (1.0 + CAP_SLACK)).sum()),
            100 * off,
        )
        if off < SETTLED_SHARE:
            break
    at = _timed_columns(robots, timed, owners, job)
    slower = at > dwell
    active = (lower > base_lower * (1.0 + CAP_SLACK)) & (dwell <= lower * (1.0 + CAP_SLACK))
    final = np.where(slower | active, at, dwell)
    strokes = runs_with_dwell(tuning.paths.strokes, final)
    robots = with_tuned_dwell(robots, strokes, owners)
    tuning = dataclasses.replace(tuning, paths=dataclasses.replace(tuning.paths, strokes=strokes))
    summary = {
        "rounds": rounds,
        "capped_waypoints": int((lower > base_lower * (1.0 + CAP_SLACK)).sum()),
        "slower_than_tuned_waypoints": int((slower & (at > dwell * (1.0 + CAP_SLACK))).sum()),
    }
    return robots, timed, tuning, summary
