"""The files of a finished job: plan.json and waypoints.csv, the film files when the plan has a film (whose
summary plan.json keeps), and the pictures (plan.html and report/, unless ``[output]`` turns them off); written
all or nothing (``export.files.staged_folder``)."""

from __future__ import annotations

import os

from sprayplan.view.files import VIEW_FILES

#: The files a job writes into its output folder (plan.json and waypoints.csv always, the rest with a film).
PLAN_FILES = ("plan.json", "waypoints.csv")
FILM_FILES = ("thickness.ply", "thickness.csv", "coating.json")
#: The robot programs' folder (``programs.stage``): an earlier run's goes with it, so that no program of an
#: older plan is left beside a new plan.json.
PROGRAMS_FOLDER = "programs"
JOB_FILES = PLAN_FILES + FILM_FILES + VIEW_FILES + (PROGRAMS_FOLDER,)
#: Of those, the folders.
OUTPUT_FOLDERS = ("report", PROGRAMS_FOLDER)


def write_job(
    outdir, result, part_file: str | os.PathLike | None = None, own: tuple[str, ...] = JOB_FILES, progress=None
) -> list[str]:
    """Write a job's files into ``outdir``, all or nothing; returns the paths written.

    The files are written into a temporary folder beside ``outdir`` and moved in only when every one is
    written: a missing ``outdir`` is created then; an ``outdir`` holding only an earlier job's files (named in
    ``own``) is replaced as a whole; in one holding other files too, the job's files replace their namesakes
    and the other files are left alone. When anything fails, ``outdir`` is left as it was.

    Parameters
    ----------
    outdir : str or os.PathLike
    result : job.JobResult
        The plan, its settings and totals, and its film (None: no film files).
    part_file : str or os.PathLike, optional
        The part's file as plan.json names it (default: the file the job read).
    own : tuple of str
        The names of the files a run writes in ``outdir`` (an earlier run's are replaced, not kept).
    progress : callable, optional
        ``progress(done, total)`` while the report's images are drawn.

    Raises
    ------
    OutputError
        ``outdir`` cannot be written (naming it and the OS's reason), or the part is one of its files.
    """
    from sprayplan.export.files import refuse_inputs, staged_folder

    part_file = result.part_file if part_file is None else os.fspath(part_file)
    refuse_inputs([(os.path.join(outdir, name), "a job output") for name in own], [(part_file, "part")])
    report = None
    if result.film is not None:  # computed before any file is written: a failure leaves nothing behind
        from sprayplan.export.film import film_report

        report = film_report(result.film, result.job, result.job.output.samples, result.chosen)
    with staged_folder(outdir, own) as stage:
        names = [os.path.basename(p) for p in write_job_files(stage, result, part_file, report, progress)]
    return [os.path.join(outdir, name) for name in names]


def write_job_files(
    folder, result, part_file: str | None = None, report: dict | None = None, progress=None
) -> list[str]:
    """Write a job's files straight into ``folder`` (an existing folder: the staging folder of :func:`write_job`).

    ``report``: the film's report when already computed (``export.film.film_report``).
    """
    from sprayplan.export.film import film_report, write_coating
    from sprayplan.export.plan_json import write_plan

    job = result.job
    if result.film is not None and report is None:
        report = film_report(result.film, job, job.output.samples, result.chosen)
    pictures = None
    if job.output.viewer or job.output.report:
        from sprayplan.parallel import process_count
        from sprayplan.view.files import begin_view_files
        from sprayplan.view.scene import scene_from_result

        # the report's pictures begin first: a helper process draws them while the plan's files are written
        scene = scene_from_result(result, report)
        processes = process_count(job.kinematics.processes)
        view = dict(viewer=job.output.viewer, report=job.output.report, progress=progress, processes=processes)
        pictures = begin_view_files(folder, scene, **view)
    from sprayplan.parallel import finished_on_error

    with finished_on_error(pictures):
        written = write_plan(
            folder, result.plan, job, result.totals, part_file, report, getattr(result, "timing", None)
        )
        if report is not None:
            written += write_coating(folder, result.film, job, report)
    if pictures is not None:
        written += pictures()
    return written
