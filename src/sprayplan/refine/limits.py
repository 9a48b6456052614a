r"""Speeds tuned within what the robot can make: the speed tuning bounded by the timing, round by round.

The speed tuning (:mod:`sprayplan.refine.tuning`) picks a time factor w_i at every spray waypoint (the gun at
the planned speed over w_i) from the film model alone. The timing (:mod:`sprayplan.timing.stage`) then finds
where the robot's joints cannot make those speeds: its time factors ``PlanTiming.dwell`` (a waypoint's timed
time over its time at the process speed) are larger there. A slower gun leaves more paint, so the film at the
timed speeds is not the film the tuning aimed at. Here the two are brought together:

1. time the tuned plan; where a spray waypoint's timed factor u_i exceeds its tuned w_i (by more than
   :data:`CAP_SLACK`), the robot cannot go faster than the planned speed over u_i: that becomes the waypoint's
   lower bound, ``w_i >= u_i`` (an upper bound of its speed; the bounds only ever rise, round after round);
2. tune again with those bounds (``tune_speeds(lower=..., upper=...)``, a bounded least squares on the same
   deposit matrix, started from the last factors), so the tuning spends the other waypoints' speeds on the
   film the capped ones make;
3. time again; repeat up to ``[tuning] limit_rounds`` times, until no waypoint is slower than tuned, or until
   the film at the timed speeds is the tuning's prediction (within a tenth of the tolerance) on all but 1 % of
   the tuned area.

Where a waypoint's bound is active, the timing is asked for the speed the first (unbounded) tuning wanted
there, so the robot makes what it can, as in the timing the bound came from: asked for the bound itself, its
speed would drop further wherever it accelerates (a segment's speed bound is flat, the robot's speed on a ramp
is not), round after round. Where a stretch starts or ends at rest the robot is slower than any planned speed;
after the last round the plan's factors are raised to the timed ones wherever the robot is still slower (and
set to them where a bound is active), so the plan never asks for more than the robot makes, and what those
ends add to the film is the difference between the tuning's prediction and the film at the timed speeds that
the summary reports.

Where the caps make the target impossible (the gun cannot go fast enough, so a patch gets too much paint
whatever the other speeds do), nothing else is changed to hide it (flow, spacing and the path stay as
planned): the summary's ``over_spec`` says how much of the surface is above the tolerance at the timed speeds,
by how much, and ``places`` names the strokes that paint it (station, stroke, the share of the wanted speed the
robot makes there).
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import sparse

from sprayplan.coating.stage import process_for
from sprayplan.coating.thickness import CoatingResult
from sprayplan.refine.stage import lower_dwell, tuning_settings
from sprayplan.refine.tuning import Tuning, tune_speeds, tuned_film
from sprayplan.types import Paths, Plan

log = logging.getLogger(__name__)

#: A spray waypoint whose timed time factor exceeds its tuned one by more than this share is capped.
CAP_SLACK = 1e-3
#: The rounds stop once less than SETTLED_SHARE of the tuned area has a film at the timed speeds more than
#: SETTLED_TOLERANCES tolerances off the tuning's prediction.
SETTLED_SHARE = 0.01
SETTLED_TOLERANCES = 0.1
#: At most this many strokes are named in ``places``.
MAX_PLACES = 20


@dataclass(frozen=True)
class WithinLimits:
    """What :func:`tune_within_limits` found.

    Attributes
    ----------
    plan : Plan
        The plan with the last tuned time factors (``Stroke.dwell``); geometry and joints unchanged.
    timing : timing.stage.PlanTiming
        Its timing.
    tuning : Tuning
        The last tuning (factors within the caps).
    film : CoatingResult
        The film at the timed speeds (the timing's factors), from the tuning's deposit matrix: what
        ``coating.stage.simulate_plan`` gives for ``timing.stage.real_plan(plan, timing)``.
    summary : dict
        The tuning's ``within_limits`` entry (see :func:`tune_within_limits`).
    """

    plan: Plan
    timing: object
    tuning: Tuning
    film: CoatingResult
    summary: dict


def plan_dwell(plan: Plan) -> np.ndarray:
    """(waypoints,) every stroke's time factors, station after station (the tuning's column order)."""
    parts = [s.dwell for st in plan.stations for s in st.strokes]
    return np.concatenate(parts) if parts else np.zeros(0)


def with_dwell(plan: Plan, dwell: np.ndarray) -> Plan:
    """The plan with the time factors ``dwell`` (in :func:`plan_dwell`'s order) on its spray strokes."""
    stations, start = [], 0
    for st in plan.stations:
        strokes = []
        for s in st.strokes:
            w = dwell[start : start + len(s)]
            start += len(s)
            strokes.append(s.with_dwell(w) if s.spray_on else s)
        stations.append(dataclasses.replace(st, strokes=tuple(strokes)))
    return dataclasses.replace(plan, stations=tuple(stations))


def tune_within_limits(
    part, plan: Plan, tuning: Tuning, job, time_plan: Callable[[Plan], object], progress=None
) -> WithinLimits:
    """The plan's speeds tuned again within the speeds the robot can make (see the module docstring).

    Parameters
    ----------
    part : Part
        The part the tuning ran on.
    plan : Plan
        The tuned plan (its strokes in the order of ``tuning.paths``; joints possibly repaired since).
    tuning : Tuning
        The refine stage's last tuning (``refine.stage.tune_plan``'s fourth result).
    job : JobConfig
    time_plan : callable
        ``time_plan(plan) -> PlanTiming`` (``timing.stage.time_plan`` with the job's robot).
    progress : callable, optional
        ``progress(done, total)`` after each round.

    Returns
    -------
    WithinLimits
        ``summary``: ``rounds`` run, ``capped_waypoints`` (whose lower bound the timing raised),
        ``slower_than_tuned_waypoints`` (still slower after the last round: the ends of the stretches),
        ``predicted`` and ``timed`` (the tuned samples' film, as the tuning predicted it and at the timed
        speeds: mean, cv, share in spec), ``max_difference_um`` between the two, ``over_spec`` and
        ``places`` (where the timed film is above the tolerance because capped waypoints paint it).
    """
    settings = job.tuning
    target, tol = float(job.coating.thickness_um), float(job.coating.tolerance)
    process = process_for(job)
    coating = job.coating.simulation(job.motion)
    config = tuning_settings(settings)
    spray = np.concatenate([np.full(len(s), s.spray_on) for s in tuning.paths.strokes] or [np.zeros(0, bool)])
    base_lower = lower_dwell(tuning.paths, settings)
    lower = base_lower.copy()
    wanted = plan_dwell(plan)  # what the tuning asks for with no bound of the robot's
    timing = time_plan(plan)
    rounds = 0
    for _ in range(settings.limit_rounds):
        dwell, timed = plan_dwell(plan), np.concatenate(timing.dwell or (np.zeros(0),))
        slower = spray & (timed > np.maximum(dwell, lower) * (1.0 + CAP_SLACK))
        if not slower.any():
            break
        lower[slower] = timed[slower]
        tuning = bounded_tuning(part, tuning, process, (target, tol), config, coating, lower, dwell, settings.max_dwell)
        dwell = np.concatenate([s.dwell for s in tuning.paths.strokes])
        plan = with_dwell(plan, dwell)
        # where the robot's speed is the bound, the robot is asked for the speed the tuning wanted (it makes what
        # it can, as in the timing the bound came from): asked for the bound itself, its speed would drop
        # further wherever it accelerates (a segment's speed bound is flat; the robot's speed is not)
        active = (lower > base_lower * (1.0 + CAP_SLACK)) & (dwell <= lower * (1.0 + CAP_SLACK))
        asked = with_dwell(plan, np.where(active, np.minimum(dwell, wanted), dwell))
        timing = time_plan(asked)
        rounds += 1
        if progress is not None:
            progress(rounds, settings.limit_rounds)
        off = _off_share(tuning, dwell, np.concatenate(timing.dwell or (np.zeros(0),)), SETTLED_TOLERANCES * tol)
        log.info(
            "speeds tuned within the limits, round %d: %d waypoints capped, %.2f %% of the tuned area off the "
            "prediction at the timed speeds",
            rounds,
            int((lower > base_lower).sum()),
            100 * off,
        )
        if off < SETTLED_SHARE:
            break
    # where the robot is still slower than tuned after the last round (a stretch's ends, where it accelerates
    # from rest), the tuned factor is raised to the timed one, so the plan's speeds never exceed what the robot
    # makes; where the bound is active the plan takes the timed factor too (the robot was asked for more there,
    # and the plan's speed is then the one it makes, which the programs carry)
    dwell, timed = plan_dwell(plan), np.concatenate(timing.dwell or (np.zeros(0),))
    slower = spray & (timed > dwell)
    active = spray & (lower > base_lower * (1.0 + CAP_SLACK)) & (dwell <= lower * (1.0 + CAP_SLACK))
    plan = with_dwell(plan, np.where(slower | active, timed, dwell))
    film = film_of(tuning, plan, timing, job)
    capped = spray & (lower > base_lower * (1.0 + CAP_SLACK))
    summary = {
        "rounds": rounds,
        "capped_waypoints": int(capped.sum()),
        "slower_than_tuned_waypoints": int((slower & (timed > dwell * (1.0 + CAP_SLACK))).sum()),
        **_compare(tuning, film, target, tol),
        **_over_spec(plan, tuning, film, timed, capped, wanted, lower, target, tol),
    }
    return WithinLimits(plan, timing, tuning, film, summary)


def bounded_tuning(part, tuning: Tuning, process, spec: tuple, config, coating, lower, dwell, max_dwell) -> Tuning:
    """One round's tuning: ``tuning``'s paths tuned again to ``spec`` (target, tolerance um) with the lower
    bounds ``lower`` (the upper ones ``max_dwell``, or the lower where higher), from the factors ``dwell``,
    on the same deposit matrix."""
    upper = np.maximum(max_dwell, lower)
    return tune_speeds(
        part,
        tuning.paths,
        process,
        spec[0],
        spec[1],
        config=config,
        coating=coating,
        lower=lower,
        upper=upper,
        initial=np.clip(dwell, lower, upper),
        deposit=(tuning.samples, tuning.deposit_mm),
    )


def film_of(tuning: Tuning, plan: Plan, timing, job) -> CoatingResult:
    """The film of ``plan`` (whose strokes are ``tuning.paths``'s, in order) from the tuning's deposit matrix:
    at the plan's own time factors, or with ``timing`` (a ``PlanTiming``) at the timed ones (what
    ``coating.stage.simulate_plan`` gives for ``timing.stage.real_plan(plan, timing)``)."""
    dwell = plan_dwell(plan) if timing is None else np.concatenate(timing.dwell or (np.zeros(0),))
    paths = tuning.paths
    starts = np.r_[0, np.cumsum([len(s) for s in paths.strokes])]
    strokes = tuple(s.with_dwell(dwell[a : a + len(s)]) if s.spray_on else s for s, a in zip(paths.strokes, starts))
    at = dataclasses.replace(tuning, paths=Paths(strokes, paths.standoff_mm, paths.spacing_mm, paths.name))
    film = tuned_film(at, process_for(job), job.coating.simulation(job.motion))
    return dataclasses.replace(film, name=plan.name)


def _off_share(tuning: Tuning, dwell: np.ndarray, timed: np.ndarray, by_um: float) -> float:
    """The share of the tuned area whose film at the time factors ``timed`` differs from the film at ``dwell``
    by more than ``by_um``."""
    rows = tuning.tuned
    area = tuning.area_mm2[rows]
    if area.sum() <= 0:
        return 0.0
    diff = np.abs(np.asarray(tuning.deposit_mm @ (timed - dwell)).ravel()[rows]) * 1000.0
    return float(area[diff > by_um].sum() / area.sum())


def _stats(film_um: np.ndarray, area: np.ndarray, target: float, tol: float) -> dict:
    if area.sum() <= 0:
        return {"mean_um": None, "cv": None, "share_in_spec": None}
    mean = float(np.average(film_um, weights=area))
    std = float(np.sqrt(np.average((film_um - mean) ** 2, weights=area)))
    inside = np.abs(film_um - target) <= tol
    return {
        "mean_um": round(mean, 4),
        "cv": round(std / mean, 6) if mean > 0 else None,
        "share_in_spec": round(float(area[inside].sum() / area.sum()), 6),
    }


def _compare(tuning: Tuning, film: CoatingResult, target: float, tol: float) -> dict:
    """The tuned samples' film as the last tuning predicted it and at the timed speeds."""
    rows = tuning.tuned
    area = tuning.area_mm2[rows]
    predicted, timed = tuning.after_um[rows], film.thickness_um[rows]
    return {
        "predicted": _stats(predicted, area, target, tol),
        "timed": _stats(timed, area, target, tol),
        "max_difference_um": round(float(np.abs(timed - predicted).max(initial=0.0)), 4),
    }


def _over_spec(plan, tuning, film, timed, capped, wanted, lower, target, tol) -> dict:
    """The tuned samples above the tolerance at the timed speeds that capped waypoints paint most of (the gun
    cannot go fast enough there), and the strokes that paint them."""
    rows = tuning.tuned
    deposit = tuning.deposit_mm.tocsc() * 1000.0  # um per unit factor
    from_capped = np.asarray(deposit[:, np.flatnonzero(capped)] @ timed[capped]).ravel()
    film_um = film.thickness_um
    over = rows & (film_um > target + tol) & (from_capped > 0.5 * film_um)
    area = tuning.area_mm2
    out = {
        "over_spec": {
            "area_mm2": round(float(area[over].sum()), 3),
            "share": round(float(area[over].sum() / area[rows].sum()), 6) if area[rows].sum() > 0 else None,
            "max_um": round(float(film_um[over].max(initial=0.0)), 4) if over.any() else None,
            "max_excess_um": round(float(film_um[over].max() - target - tol), 4) if over.any() else None,
        },
        "places": [],
    }
    if not over.any():
        return out
    # each such sample's painter: the stroke whose waypoints leave most of its film
    where = [(place, k) for place, st in enumerate(plan.stations) for k, _ in enumerate(st.strokes)]
    sizes = [len(s) for s in tuning.paths.strokes]
    stroke_of = np.repeat(np.arange(len(sizes)), sizes)
    by_stroke = sparse.csr_matrix(
        (np.ones(len(stroke_of)), (np.arange(len(stroke_of)), stroke_of)), shape=(len(stroke_of), len(sizes))
    )
    share = deposit[np.flatnonzero(over)] @ sparse.diags(timed) @ by_stroke
    painter = np.asarray(share.argmax(axis=1)).ravel()
    places = []
    for k in np.unique(painter):
        mine = np.flatnonzero(over)[painter == k]
        cols = np.flatnonzero((stroke_of == k) & capped)
        place, index = where[k]
        places.append(
            {
                "station": place,
                "stroke": index,
                "kind": tuning.paths.strokes[k].kind,
                "capped_waypoints": len(cols),
                # the share of the speed the unbounded tuning wanted that the robot makes (the least one)
                "speed_share": round(float((wanted[cols] / lower[cols]).min()), 4) if len(cols) else None,
                "over_spec_area_mm2": round(float(area[mine].sum()), 3),
                "max_um": round(float(film_um[mine].max()), 4),
            }
        )
    places.sort(key=lambda p: -p["over_spec_area_mm2"])
    out["places"] = places[:MAX_PLACES]
    out["over_spec"]["strokes"] = len(places)
    return out
