"""The paint's flow fitted to the speeds a cell's robots make (``[timing] fit_flow``).

With a film target the gun speed follows from the paint's flow (``coating.stage.meet_thickness``: the film
is flow over speed times the spacing), and the tuning sets each waypoint's speed around it. Whether the arms
can move the gun that fast along the body is known only once the plan is timed within their limits
(:mod:`sprayplan.cells.timing`): where a robot is slower than planned, it leaves more paint than the plan
predicts. On the BMW body in ``line3`` at the default flow (200 mL/min, 466 mm/s) the robots make about half
the planned speed on average (they start and stop every stretch at rest, and their tracks accelerate at
0.5 m/s^2): the film at the timed speeds came out 122 um on average, 28 % in spec, against the plan's 95 %.

A painter in that place lowers the flow, so that the gun can go slower for the same film. Here the flow and
the gun speed are scaled together by each share of :data:`FLOW_SHARES` (the film the plan predicts, deposit
over the time factors, does not change: only the speed the robots are asked for), the robots are timed again
at each, and the film at the timed speeds is found from the tuning's deposit matrix. Slower always brings the
timed film nearer the plan's, at a longer cycle, so the share kept is the one with the most surface in spec at
the timed speeds among those whose timed cycle is within ``[timing] fit_cycle_budget`` times the cycle at the
flow as set (1.5 by default: half as long again). Every share tried is reported (``report["flow_fit"]``), so
that a user can set ``[coating] flow_ml_min`` from the table and turn the fit off, or set the budget.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

from sprayplan.config import JobConfig

#: The shares of the flow (and of the gun speed with it) tried, the job's own first.
FLOW_SHARES = (1.0, 0.7, 0.5, 0.35, 0.25)


def scaled_job(job: JobConfig, share: float, flow_ml_min: float) -> JobConfig:
    """The job with the paint's flow (``flow_ml_min``: the job's own, :func:`coating.stage.job_paint`) and
    the gun speed both times ``share``."""
    coating = dataclasses.replace(job.coating, flow_ml_min=flow_ml_min * share)
    motion = dataclasses.replace(job.motion, gun_speed_mm_s=job.motion.gun_speed_mm_s * share)
    return dataclasses.replace(job, coating=coating, motion=motion)


def fit_flow(job: JobConfig, time_at: Callable, in_spec_at: Callable) -> tuple[JobConfig, object, dict]:
    """The share of :data:`FLOW_SHARES` with the most surface in spec at the timed speeds among those whose
    timed cycle is within ``job.timing.fit_cycle_budget`` times the first's (module docstring): ``time_at(job)``
    times the robots for a job (their ``WorkTiming`` list), ``in_spec_at(job, timed)`` is the share of the
    painted area in spec at those timed speeds. Returns the job at the share kept, its timing, and the report:
    the flow and speed, timed cycle and share in spec of every share tried."""
    from sprayplan.coating.stage import job_paint

    flow = float(job_paint(job).flow_ml_min)
    budget = float(job.timing.fit_cycle_budget)
    tried, best, limit = [], None, None
    for share in FLOW_SHARES:
        scaled = scaled_job(job, share, flow)
        timed = time_at(scaled)
        cycle = max((t.cycle_s for t in timed), default=0.0)
        limit = cycle * budget if limit is None else limit
        entry = {
            "flow_share": share,
            "flow_ml_min": round(flow * share, 4),
            "gun_speed_mm_s": round(scaled.motion.gun_speed_mm_s, 4),
            "timed_cycle_s": round(cycle, 3),
        }
        tried.append(entry)
        if cycle > limit * (1.0 + 1e-9):
            entry["over_budget"] = True
            break  # a lower flow only takes longer still
        in_spec = float(in_spec_at(scaled, timed))
        entry["timed_share_in_spec"] = round(in_spec, 6)
        if best is None or in_spec > best[0]:
            best = (in_spec, share, scaled, timed)
    _, share, scaled, timed = best
    report = {
        "rule": f"flow and gun speed scaled together; kept: the most surface in spec at the timed speeds with "
        f"the timed cycle within {budget:g} times the first's",
        "cycle_budget_s": round(limit, 3),
        "flow_share": share,
        "flow_ml_min": round(flow * share, 4),
        "gun_speed_mm_s": round(scaled.motion.gun_speed_mm_s, 4),
        "tried": tried,
    }
    return scaled, timed, report


def fit_cell_flow(plan, job: JobConfig, tuning, owners, everything, coating, report: dict):
    """:func:`fit_flow` on a cell plan's robots (``cells.plan.CellPlan``: its film tuned and reported, its robots
    not yet timed; ``owners`` and ``everything`` its reached runs, as ``cells.plan.reached_strokes`` gave
    them), and what changes with the flow kept: the job, the robots' timings at it, the process, the film (the
    same thicknesses; its stroke times and flows at that process), and the report's chosen speed and flow,
    its lengths over speed and its ``flow_fit``."""
    from sprayplan.cells.film import film_at_timed_speeds
    from sprayplan.cells.timing import time_cell, with_times
    from sprayplan.coating.report import weighted_stats
    from sprayplan.coating.stage import process_for
    from sprayplan.refine.tuning import tuned_film

    target, tol = job.coating.thickness_um, job.coating.tolerance
    robots = plan.robots

    def in_spec_at(job_, timed):
        at = dataclasses.replace(plan, robots=with_times(robots, timed), job=job_)
        film_ = film_at_timed_speeds(at, owners, tuning, everything, process_for(job_), coating)
        return weighted_stats(film_.thickness_um, film_.area_mm2, target - tol, target + tol)["share_in_spec"]

    backs: dict = {}  # the programs' back-offs, the same at every speed
    job, timed, report["flow_fit"] = fit_flow(job, lambda job_: time_cell(plan.cell, robots, job_, backs), in_spec_at)
    process = process_for(job)
    chosen = report.get("chosen_for_thickness") or {}
    chosen.update(
        {"gun_speed_mm_s": job.motion.gun_speed_mm_s, "flow_ml_min": process.flow_ml_min, "fitted_to_robots": True}
    )
    speed, transfer = job.motion.gun_speed_mm_s, job.motion.transfer_speed_mm_s
    for r in robots:
        report["robots"][r.name]["cycle_time_s"] = round(r.cycle_time_s(speed, transfer), 3)
    report["cycle_time_s"] = max((e["cycle_time_s"] for e in report["robots"].values()), default=0.0)
    return job, timed, process, tuned_film(tuning, process, coating)
