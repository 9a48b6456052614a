"""Writing the pictures of a plan: plan.html and report/ into a plan folder (all or nothing)."""

from __future__ import annotations

import logging
import os

from sprayplan.view.scene import Scene

log = logging.getLogger(__name__)

#: What the pictures add to a plan folder.
VIEW_FILES = ("plan.html", "report")


def write_view_files(folder, scene: Scene, viewer: bool = True, report: bool = True, progress=None) -> list[str]:
    """Write ``folder/plan.html`` and ``folder/report/`` (an existing folder: a staging folder, whose
    ``report`` must not exist yet); returns the paths written (the report's folder once).
    ``progress(done, total)``: after each of the report's images."""
    from sprayplan.view.html import write_viewer
    from sprayplan.view.report import write_report_files

    folder = os.fspath(folder)
    written = []
    if viewer:
        path = os.path.join(folder, "plan.html")
        drawn = write_viewer(path, scene)
        log.info("%s: viewer written (%s)", path, drawn)
        written.append(path)
    if report:
        path = os.path.join(folder, "report")
        os.mkdir(path)
        write_report_files(path, scene, progress=progress)
        written.append(path)
    return written


def write_views(outdir, scene: Scene, viewer: bool = True, report: bool = True, progress=None) -> list[str]:
    """Write plan.html and report/ into an existing plan folder ``outdir``, all or nothing: both are drawn into
    a temporary folder beside it and moved in together, replacing earlier ones; the plan's other files are
    left alone. Returns the paths written."""
    from sprayplan.export.files import staged_folder

    with staged_folder(outdir, VIEW_FILES, whole=False) as stage:
        names = [os.path.basename(p) for p in write_view_files(stage, scene, viewer, report, progress)]
    return [os.path.join(os.fspath(outdir), name) for name in names]
