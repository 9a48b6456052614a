"""The coating stage of the main job: choose spacing and speed for a film target, and simulate a plan's film.

Bridges ``sprayplan.coating`` (the physics) and the plan (``pipeline``, ``io.plan_files``).
"""

from __future__ import annotations

import dataclasses
import json
import os

import numpy as np

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


def tune_plan(part, plan: Plan, job: JobConfig) -> tuple[Plan, dict]:
    """With a film target and ``tune_speed``: the plan with a time factor at every waypoint, chosen from the
    simulated film (``coating.tune_speeds``), and a summary of the film predicted before and after. The
    strokes keep their geometry and the joints; only their speeds change. Otherwise the plan unchanged."""
    settings = job.plan
    if settings.thickness_um is None or not settings.tune_speed or not plan.stations:
        return plan, {}
    from sprayplan.coating import CoatingConfig, TuningConfig, tune_speeds

    paths = plan_paths_in_order(plan, job.paths.standoff_mm, job.paths.spacing or 0.0)
    tolerance = settings.tolerance_um if settings.tolerance_um > 0 else 0.05 * settings.thickness_um
    tuning = tune_speeds(
        part,
        paths,
        process_for(job),
        settings.thickness_um,
        tolerance,
        config=TuningConfig(min_dwell=settings.min_dwell, max_dwell=settings.max_dwell),
        coating=CoatingConfig(speed_along=settings.speed_along, max_speed_ratio=settings.max_speed_ratio),
    )
    strokes = iter(tuning.paths.strokes)
    stations = tuple(dataclasses.replace(st, strokes=tuple(next(strokes) for _ in st.strokes)) for st in plan.stations)
    return dataclasses.replace(plan, stations=stations), tuning.summary(settings.thickness_um, tolerance)


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
