"""Writing the pictures of a plan: plan.html and report/ into a plan folder (all or nothing)."""

from __future__ import annotations

import logging
import os

from sprayplan.view.scene import Scene

log = logging.getLogger(__name__)

#: What the pictures add to a plan folder.
VIEW_FILES = ("plan.html", "report")


def write_view_files(
    folder, scene: Scene, viewer: bool = True, report: bool = True, progress=None, processes: int = 1
) -> list[str]:
    """Write ``folder/plan.html`` and ``folder/report/`` (an existing folder: a staging folder, whose
    ``report`` must not exist yet); returns the paths written (the report's folder once).
    ``progress(done, total)``: as the report's images are done; ``processes``: 2 shares them with a helper
    process (``parallel.shared_map``)."""
    return begin_view_files(folder, scene, viewer, report, progress, processes)()


def begin_view_files(folder, scene: Scene, viewer=True, report=True, progress=None, processes: int = 1):
    """:func:`write_view_files` begun: with ``processes`` = 2 the helper starts on the report's pictures now,
    while this process writes other files; the function returned writes plan.html, takes part in the rest of
    the pictures and returns the paths (it must be called)."""
    from sprayplan.view.report import begin_report_files

    folder = os.fspath(folder)
    pictures = None
    if report:
        os.mkdir(os.path.join(folder, "report"))
        pictures = begin_report_files(os.path.join(folder, "report"), scene, progress=progress, processes=processes)

    def finish() -> list[str]:
        from sprayplan.parallel import finished_on_error
        from sprayplan.view.html import write_viewer

        written = []
        with finished_on_error(pictures):
            if viewer:
                path = os.path.join(folder, "plan.html")
                drawn = write_viewer(path, scene)
                log.info("%s: viewer written (%s)", path, drawn)
                written.append(path)
        if pictures is not None:
            pictures()
            written.append(os.path.join(folder, "report"))
        return written

    return finish


def write_views(outdir, scene: Scene, viewer: bool = True, report: bool = True, progress=None) -> list[str]:
    """Write plan.html and report/ into an existing plan folder ``outdir``, all or nothing: both are drawn into
    a temporary folder beside it and moved in together, replacing earlier ones; the plan's other files are
    left alone. Returns the paths written."""
    from sprayplan.export.files import staged_folder

    with staged_folder(outdir, VIEW_FILES, whole=False) as stage:
        names = [os.path.basename(p) for p in write_view_files(stage, scene, viewer, report, progress)]
    return [os.path.join(os.fspath(outdir), name) for name in names]
