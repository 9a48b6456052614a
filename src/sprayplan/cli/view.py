"""``sprayplan view OUTDIR``: draw a plan folder (plan.html and report/, ``sprayplan.view``)."""

from __future__ import annotations

import os

from sprayplan.cli.common import ProgressDisplay, check_folder_outputs, output_option, stage
from sprayplan.errors import ConfigError


def cmd_view(args) -> int:
    from sprayplan.export.job_files import VIEW_FILES
    from sprayplan.view.files import write_views
    from sprayplan.view.scene import scene_from_folder

    output_option(args.outdir, "OUTDIR")
    viewer, report = not args.no_viewer, not args.no_report
    if not (viewer or report):
        raise ConfigError("--no-viewer and --no-report: nothing left to draw")
    outdir = os.fspath(args.outdir)
    if not os.path.exists(os.path.join(outdir, "plan.json")) and os.path.exists(os.path.join(outdir, "cell_plan.json")):
        from sprayplan.errors import PartFileError

        raise PartFileError(
            outdir, "a cell plan folder: its 3D viewer is cell.html, written with the plan (plan --cell)"
        )
    with stage("scene"):
        scene = scene_from_folder(outdir)  # the whole folder is read and checked before anything is written
    own = [name for name, on in zip(VIEW_FILES, (viewer, report)) if on]
    check_folder_outputs(outdir, own, "OUTDIR", [(os.path.join(outdir, "plan.json"), "plan.json")])
    display = ProgressDisplay(quiet=getattr(args, "quiet", False))
    try:
        with stage("pictures"):
            display("pictures", 0, 0)
            written = write_views(outdir, scene, viewer, report, lambda done, total: display("pictures", done, total))
    except BaseException:
        display.close(finished=False)
        raise
    display.close()
    for note in scene.notes:
        print(f"note: {note}")
    print("wrote " + ", ".join(p + ("/" if os.path.isdir(p) else "") for p in written))
    return 0
