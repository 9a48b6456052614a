"""The coating stages of the main job: spacing and speed for a film target, and the film a plan leaves.

Bridges ``sprayplan.coating`` (the physics) and the plan.
"""

from __future__ import annotations

import dataclasses

from sprayplan.config import JobConfig
from sprayplan.progress import Progress, per_stage
from sprayplan.types import Paths, Plan


def job_paint(job: JobConfig):
    """The job's spray process as set: its preset (``[coating] process``) with ``[coating] flow_ml_min`` when
    given, at the preset's own speed."""
    from sprayplan.coating.process import load_preset

    process = load_preset(job.coating.process, "coating.process")
    if job.coating.flow_ml_min is not None:
        process = dataclasses.replace(process, flow_ml_min=float(job.coating.flow_ml_min))
    return process


def process_for(job: JobConfig):
    """The spray process of a job: :func:`job_paint` at the job's gun speed."""
    return dataclasses.replace(job_paint(job), speed_mm_s=job.motion.gun_speed_mm_s)


def meet_thickness(job: JobConfig) -> tuple[JobConfig, dict]:
    """With a film target set, the job with the spacing and gun speed chosen to meet it (and what was chosen).

    The spacing minimises the film's ripple across parallel strokes on a flat panel for the process's pattern,
    the speed puts the film's mean on the target; both replace the job's own values. Without a target the job
    is returned unchanged, with {}.
    """
    if job.coating.thickness_um is None:
        return job, {}
    from sprayplan.coating.spacing import choose_spacing_and_speed

    process = job_paint(job)
    choice = choose_spacing_and_speed(process, job.coating.thickness_um, standoff_mm=job.paths.standoff_mm)
    chosen = {
        "spacing_mm": float(choice.spacing_mm),
        "gun_speed_mm_s": float(choice.speed_mm_s),
        "flow_ml_min": float(process.flow_ml_min),
        "flat_panel_ripple_cv": float(choice.cv),
        "overlap": float(choice.overlap),
        "target_um": float(job.coating.thickness_um),
    }
    paths = dataclasses.replace(job.paths, spacing_mm=chosen["spacing_mm"], layers=None)
    motion = dataclasses.replace(job.motion, gun_speed_mm_s=chosen["gun_speed_mm_s"])
    return dataclasses.replace(job, paths=paths, motion=motion), chosen


def plan_paths_in_order(plan: Plan, standoff_mm: float, spacing_mm: float) -> Paths:
    """All strokes of a plan, station after station, as one Paths (what the gun does, in order)."""
    return Paths(plan.strokes, standoff_mm, spacing_mm, plan.name)


def simulate_plan(part, plan: Plan, job: JobConfig, progress: Progress | None = None):
    """The film a plan leaves on the part (``coating.simulate`` with the job's process and speeds); progress
    per batch of gun samples under the stage ``film``."""
    from sprayplan.coating.thickness import simulate

    paths = plan_paths_in_order(plan, job.paths.standoff_mm, job.paths.spacing or 0.0)
    return simulate(
        part, paths, process_for(job), config=job.coating.simulation(job.motion), progress=per_stage(progress, "film")
    )
