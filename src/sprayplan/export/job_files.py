"""The files of a finished job: plan.json and waypoints.csv, and the film files when the plan has a film (whose
summary plan.json keeps)."""

from __future__ import annotations

import os


def write_job(outdir, result) -> list[str]:
    """Write a job's files into ``outdir`` (created if missing); returns the paths written.

    Parameters
    ----------
    outdir : str or os.PathLike
    result : job.JobResult
        The plan, its settings and totals, and its film (None: no film files).
    """
    from sprayplan.export.film import film_report, write_coating
    from sprayplan.export.plan_json import write_plan

    os.makedirs(outdir, exist_ok=True)
    job = result.job
    report = None
    if result.film is not None:  # computed before any file is written: a failure leaves nothing behind
        report = film_report(result.film, job, job.output.samples, result.chosen)
    written = write_plan(outdir, result.plan, job, result.totals, result.part_file, report)
    if report is not None:
        written += write_coating(outdir, result.film, job, report)
    return written
