"""``sprayplan export OUT --format FORMAT``: a plan folder's robot programs (see ``cli.main``; docs/programs.md)."""

from __future__ import annotations

import os
import sys
from pathlib import Path

from sprayplan.cli.common import check_outputs, output_option, stage
from sprayplan.config import PROGRAM_FORMATS
from sprayplan.errors import ConfigError, PartFileError


def program_format(text: str) -> str:
    """``--format`` / ``--program``: one of the program formats (a one-line error naming them otherwise)."""
    import argparse

    if text not in PROGRAM_FORMATS:
        raise argparse.ArgumentTypeError(f"{text!r} is not a program format: use {', '.join(PROGRAM_FORMATS)}")
    return text


def add_export_parser(sub, common) -> None:
    export = sub.add_parser(
        "export",
        parents=[common],
        help="robot programs of a planned OUTDIR: URScript, ABB RAPID or KUKA KRL",
        description="Write a plan's robot programs (docs/programs.md) into OUTDIR/programs/FORMAT/ (or -o DIR/"
        "FORMAT/), all or nothing, with summary.json; every program is read back by its own strict reader and "
        "checked against the plan first. "
        "Settings: the plan's [export] table, or -c FILE.toml's.",
    )
    export.add_argument("outdir", help="a folder written by 'sprayplan plan'")
    export.add_argument(
        "--format",
        dest="formats",
        action="append",
        type=program_format,
        required=True,
        metavar="FORMAT",
        help=f"{', '.join(PROGRAM_FORMATS)} (repeat for several)",
    )
    export.add_argument("-o", "--output", help="the programs' parent folder (default OUTDIR/programs)")
    export.add_argument("-c", "--config", help="a process TOML file whose [export] table replaces the plan's")
    export.add_argument(
        "--strict",
        action="store_true",
        help="a spray waypoint the program would leave out is an error (nothing written)",
    )
    export.set_defaults(func=cmd_export)


def cmd_export(args) -> int:
    from sprayplan.export.plan_read import read_plan_file
    from sprayplan.programs.stage import default_folder, export_plan, warnings_of

    output_option(args.outdir, "OUTDIR")
    outdir = Path(args.outdir)
    if not outdir.is_dir():
        raise PartFileError(args.outdir, "not a folder (give a plan folder written by 'sprayplan plan')")
    plan_file = outdir / "plan.json"
    if not plan_file.exists() and (outdir / "cell_plan.json").exists():
        return _export_cell(args, outdir / "cell_plan.json")
    if not plan_file.exists():
        raise PartFileError(args.outdir, "holds no plan.json: not a plan folder (written by 'sprayplan plan')")
    folder = args.output if args.output is not None else default_folder(args.outdir)
    inputs = [(plan_file, "plan.json"), (args.config, "-c")]
    check_outputs([(folder, "-o")], inputs, folder=True)
    formats = list(dict.fromkeys(args.formats))
    check_outputs([(os.path.join(folder, f), "-o") for f in formats], inputs, folder=True)
    read = read_plan_file(plan_file)
    job = read.job
    if args.config:
        from sprayplan.config import job_from_toml

        job = job.replace(export=job_from_toml(args.config).export)
    if args.strict:
        job = job.replace(export={"strict": True})
    plan = read.plan
    if read.timing is not None:  # the programs carry the speeds the robot makes, as `plan --program` writes them
        from sprayplan.timing.stage import real_plan

        plan = real_plan(plan, read.timing, read.job)
    with stage("export"):
        builts, summaries = export_plan(plan, job, formats, folder, os.path.abspath(plan_file))
    for built in builts:
        for line in warnings_of(built):
            print(f"sprayplan: warning: {line}", file=sys.stderr)
    for data in summaries:
        print(summary_text(data, os.path.join(folder, data["program_format"])))
    return 0


def _export_cell(args, plan_file) -> int:
    """``sprayplan export OUT`` of a cell plan folder: one program per robot into OUT/programs/<robot>/<format>/
    (``programs.arms``), built before anything is written, then each read back and checked."""
    from sprayplan.cells.files import cell_plan_from_file
    from sprayplan.export.files import staged_folder
    from sprayplan.programs.arms import build_cell_programs, write_cell_programs
    from sprayplan.programs.stage import default_folder, warnings_of

    folder = args.output if args.output is not None else default_folder(args.outdir)
    inputs = [(plan_file, "cell_plan.json"), (args.config, "-c")]
    check_outputs([(folder, "-o")], inputs, folder=True)
    formats = tuple(dict.fromkeys(args.formats))
    plan = cell_plan_from_file(plan_file)
    from sprayplan.programs.arms import format_refusal

    for r in plan.cell.robots:
        for fmt in formats:
            why = format_refusal(r.name, r.model, fmt)
            if why:
                raise ConfigError(f"--format {fmt}: {why}")
    job = plan.job
    if args.config:
        from sprayplan.config import job_from_toml

        job = job.replace(export=job_from_toml(args.config).export)
    if args.strict:
        job = job.replace(export={"strict": True})
    robots = [r.name for r in plan.cell.robots]
    with stage("export"):
        built = build_cell_programs(plan, job, formats)
        with staged_folder(folder, tuple(robots), whole=False) as tmp:
            summaries = write_cell_programs(tmp, built, job)
    for robot in built:
        for b in robot.builts:
            for line in warnings_of(b):
                print(f"sprayplan: warning: {robot.robot}: {line}", file=sys.stderr)
    for data in summaries:
        print(f"{data['robot']} " + summary_text(data, os.path.join(folder, data["robot"], data["program_format"])))
    return 0


def summary_text(data: dict, folder) -> str:
    """The line the command line prints for one format's programs (from its summary.json)."""
    left = sum(len(v) for v in data["left_out"].values())
    return (
        f"{data['program_format']}: {len(data['files'])} files, {data['moves']} moves, {data['bytes']} bytes, "
        f"{left} spray waypoints left out, read back and checked -> {folder}"
    )
