"""The coating stage of the main job: choose spacing and speed for a film target, and simulate a plan's film.

Bridges ``sprayplan.coating`` (the physics) and the plan (``pipeline``, ``io.plan_files``).
"""

from __future__ import annotations

import dataclasses
import json
import os

import numpy as np
from scipy import sparse

from sprayplan.config import JobConfig
from sprayplan.types import Paths, Plan


def process_for(job: JobConfig):
    """The spray process of a job: its preset, at the job's gun speed."""
    from sprayplan.coating import load_preset

    process = load_preset(job.plan.process)
    return dataclasses.replace(process, speed_mm_s=job.plan.gun_speed_mm_s)


def meet_thickness(job: JobConfig) -> tuple[JobConfig, dict]:
    """With a film target set, the job with the spacing and gun speed chosen to meet it (and what was chosen).

    The spacing minimises the film's ripple across parallel strokes on a flat panel for the process's pattern,
    the speed puts the film's mean on the target; both replace the job's own values. Without a target the job
    is returned unchanged.
    """
    if job.plan.thickness_um is None:
        return job, {}
    from sprayplan.coating import choose_spacing_and_speed, load_preset

    process = load_preset(job.plan.process)
    choice = choose_spacing_and_speed(process, job.plan.thickness_um, standoff_mm=job.paths.standoff_mm)
    paths = dataclasses.replace(job.paths, spacing_mm=float(choice.spacing_mm), layers=None)
    plan = dataclasses.replace(job.plan, gun_speed_mm_s=float(choice.speed_mm_s))
    chosen = {
        "spacing_mm": float(choice.spacing_mm),
        "gun_speed_mm_s": float(choice.speed_mm_s),
        "flat_panel_ripple_cv": float(choice.cv),
        "overlap": float(choice.overlap),
        "target_um": float(job.plan.thickness_um),
    }
    return dataclasses.replace(job, paths=paths, plan=plan), chosen


def plan_paths_in_order(plan: Plan, standoff_mm: float, spacing_mm: float) -> Paths:
    """All strokes of a plan, station after station, as one Paths (what the gun does, in order)."""
    strokes = tuple(s for st in plan.stations for s in st.strokes)
    return Paths(strokes, standoff_mm, spacing_mm, plan.name)


def simulate_plan(part, plan: Plan, job: JobConfig):
    """The film a plan leaves on the part (``coating.simulate`` with the job's process and speeds)."""
    from sprayplan.coating import CoatingConfig, simulate

    paths = plan_paths_in_order(plan, job.paths.standoff_mm, job.paths.spacing or 0.0)
    config = CoatingConfig(speed_along=job.plan.speed_along, max_speed_ratio=job.plan.max_speed_ratio)
    return simulate(part, paths, process_for(job), config=config)


def tune_plan(part, plan: Plan, job: JobConfig) -> tuple[Plan, dict, object]:
    """With a film target and ``tune_speed``: the plan with a time factor at every waypoint chosen from the
    simulated film (``coating.tune_speeds``), and, for ``touch_up_rounds`` rounds, touch-up strokes aimed at
    the patches still under-painted (``coating.touchup``), run from the nearest station, after which all
    speeds are tuned again. Returns the plan and a summary (the film predicted before and after, the
    factors' range, the touch-up strokes added) and the tuned plan's film (a ``CoatingResult``, what
    :func:`simulate_plan` gives for it, taken from the tuning's deposit matrix). The plan's own strokes keep
    their geometry and joints. Without a target or with ``tune_speed`` off: the plan unchanged, {} and None."""
    settings = job.plan
    if settings.thickness_um is None or not settings.tune_speed or not plan.stations:
        return plan, {}, None
    from sprayplan.coating import CoatingConfig, TuningConfig, tune_speeds
    from sprayplan.coating.touchup import TOUCH_UP_LAYER, TOUCH_UP_MIN_DWELL, aim_touch_ups, touch_up_strokes
    from sprayplan.coating.tuning import tuned_film
    from sprayplan.pipeline import with_added_strokes

    target = settings.thickness_um
    tolerance = settings.tolerance_um if settings.tolerance_um > 0 else 0.05 * target
    process = process_for(job)
    config = TuningConfig(min_dwell=settings.min_dwell, max_dwell=settings.max_dwell, band=settings.tune_band)
    coating = CoatingConfig(speed_along=settings.speed_along, max_speed_ratio=settings.max_speed_ratio)
    radius = process.pattern.radius_mm

    def tuned(plan_, earlier=None):
        paths = plan_paths_in_order(plan_, job.paths.standoff_mm, job.paths.spacing or 0.0)
        lower = np.concatenate(
            [
                np.full(len(s), TOUCH_UP_MIN_DWELL if s.layer == TOUCH_UP_LAYER else settings.min_dwell)
                for s in paths.strokes
            ]
        )
        deposit = None if earlier is None else extended_deposit(part, plan_, *earlier, process, coating)
        return tune_speeds(
            part, paths, process, target, tolerance, config=config, coating=coating, lower=lower, deposit=deposit
        )

    tuning = tuned(plan)
    first = tuning.summary(target, tolerance)
    planned_stations = len(plan.stations)
    for _ in range(settings.touch_up_rounds):
        extra = touch_up_strokes(
            tuning.samples,
            tuning.after_um,
            tuning.tuned,
            target,
            tolerance,
            standoff_mm=job.paths.standoff_mm,
            step_mm=job.paths.step_mm,
            lead_mm=radius,
            min_area_mm2=radius * radius / 4.0,
        )
        if not extra:
            break
        spare = settings.touch_up_stations - (len(plan.stations) - planned_stations)
        if settings.touch_up_aim:
            extra = aim_touch_ups(
                part,
                extra,
                tuning.samples,
                tuning.after_um,
                tuning.tuned,
                target,
                tolerance,
                process=process,
                coating=coating,
                standoff_mm=job.paths.standoff_mm,
                reach=_reach_from(plan, job, spare > 0),
            )
        before = len(tuning.paths.strokes)
        previous, plan = plan, with_added_strokes(plan, extra, job, new_stations=spare)
        if sum(len(st.strokes) for st in plan.stations) == before:
            break  # the arm reaches none of them
        tuning = tuned(plan, (previous, tuning.samples, tuning.deposit_mm))
    strokes = iter(tuning.paths.strokes)
    stations = tuple(dataclasses.replace(st, strokes=tuple(next(strokes) for _ in st.strokes)) for st in plan.stations)
    summary = tuning.summary(target, tolerance)
    summary["before"] = first["before"]
    summary["touch_up_strokes"] = sum(1 for s in tuning.paths.strokes if s.layer == TOUCH_UP_LAYER)
    film = dataclasses.replace(tuned_film(tuning, process, coating), name=plan.name)
    return dataclasses.replace(plan, stations=stations), summary, film


def _reach_from(plan: Plan, job: JobConfig, new_stations: bool):
    """A function of a stroke: the largest share of its waypoints the arm reaches exactly from one of the
    stations ``pipeline.with_added_strokes`` offers it to (the nearest ``ADDED_STROKE_STATIONS``) or, with
    ``new_stations``, from a new station at the plan's gantry height (whether the budget of new stations
    then runs out is not foreseen)."""
    from sprayplan.pipeline import ADDED_STROKE_STATIONS, gun_poses
    from sprayplan.robots.gantry import Gantry, load_gun
    from sprayplan.robots.model import load_robot
    from sprayplan.stations.added import reach_share

    gantry = Gantry(robot=load_robot("ur5"), gun=load_gun(job.plan.tool))
    platforms = np.array([st.platform_mm for st in plan.stations])
    height = float(np.median(platforms[:, 2])) if new_stations else None
    to_flange = np.linalg.inv(gantry.gun.gun2flange)

    def reach(stroke):
        poses = gun_poses(stroke)
        # the stations with_added_strokes offers the stroke to: the nearest to its flange positions
        centre = (poses @ to_flange)[:, :2, 3].mean(axis=0)
        order = np.argsort(np.linalg.norm(platforms[:, :2] - centre, axis=1), kind="stable")
        return reach_share(gantry, poses, platforms[order[:ADDED_STROKE_STATIONS]], height)

    return reach


def extended_deposit(part, plan: Plan, earlier: Plan, samples, deposit_mm, process, coating):
    """The deposit matrix of ``plan`` (``coating.deposit_matrix``) from that of ``earlier``, a plan whose
    stations ``plan`` extends with strokes appended at their ends and new stations inserted into the visiting
    order (stations matched by ``index``): only the added strokes' columns are computed, on the earlier
    samples (the film of a time step does not depend on the other strokes). Returns (samples, matrix)."""
    from sprayplan.coating import deposit_matrix

    added, is_new = [], []
    before = {st.index: len(st.strokes) for st in earlier.stations}
    for st in plan.stations:
        for j, stroke in enumerate(st.strokes):
            appended = j >= before.get(st.index, 0)
            is_new.append(np.full(len(stroke), appended))
            if appended:
                added.append(stroke)
    is_new = np.concatenate(is_new)
    if not added:
        return samples, deposit_mm
    _, new_mm = deposit_matrix(part, Paths(tuple(added), 0.0, 0.0, plan.name), process, config=coating, samples=samples)
    # columns: the earlier plan's waypoints, then the appended ones; put each where it is in the new plan
    position = np.concatenate([np.flatnonzero(~is_new), np.flatnonzero(is_new)])
    stacked = sparse.hstack([deposit_mm, new_mm]).tocsc()
    return samples, stacked[:, np.argsort(position)].tocsr()


def write_coating(outdir, result, job: JobConfig, samples: int | None = None, chosen: dict | None = None) -> dict:
    """Write OUTDIR/thickness.ply, thickness.csv and coating.json; returns the report."""
    from sprayplan.coating import coating_report, write_thickness_csv, write_thickness_ply
    from sprayplan.io.writers import atomic_output

    target = job.plan.thickness_um if job.plan.thickness_um is not None else 50.0
    report = coating_report(result, target_um=target, tolerance_um=job.plan.tolerance_um, samples=samples)
    report["process"] = job.plan.process
    if chosen:
        report["chosen"] = chosen
    outdir = os.fspath(outdir)
    write_thickness_ply(os.path.join(outdir, "thickness.ply"), result, target, job.plan.tolerance_um)
    write_thickness_csv(os.path.join(outdir, "thickness.csv"), result)
    with atomic_output(os.path.join(outdir, "coating.json"), "w", encoding="utf-8") as handle:
        json.dump(_finite(report), handle, indent=1)
        handle.write("\n")
    return report


def _finite(value):
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    if isinstance(value, (float, np.floating)):
        return float(value) if np.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.ndarray):
        return _finite(value.tolist())
    return value
