"""The export stage: a plan's robot programs, written all or nothing into ``<folder>/<format>/`` with a
``summary.json`` (what each file holds, what was left out and where).

Every program is built in memory first (so ``--strict`` and every other refusal happen before anything is
written), then written into a temporary folder beside the output, read back there by its own strict reader
(the move counts of the summary come from that reading) and checked against the plan move by move
(``check.check_program``; a difference is a bug, raised as :class:`ProgramCheckError`, and nothing is
written), and moved into place only when every format is complete (``export.files.staged_folder``).
"""

from __future__ import annotations

import json
import logging
import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sprayplan import __version__
from sprayplan.config import PROGRAM_FORMATS
from sprayplan.errors import ConfigError
from sprayplan.programs.model import LINEAR, Cell, CellProgram

log = logging.getLogger(__name__)

SUMMARY = "summary.json"
SUMMARY_FORMAT = "sprayplan.programs"
#: What the report's lists of left-out waypoints are called in summary.json and in the warning.
LEFT_OUT = {
    "unreachable_waypoints": "unreachable in the plan",
    "gantry_offset_waypoints": "where the plan moves the gantry within a station (URScript cannot)",
    "colliding_waypoints": "in collision in the plan after its repairs",
    "unapproachable_waypoints": "at a run's end the arm cannot back off from along the gun axis",
}


class ProgramCheckError(RuntimeError):
    """A program read back differs from its plan: a defect of the writer (or of the reader), never bad input."""


@dataclass(frozen=True)
class Built:
    """One format's programs in memory.

    Attributes
    ----------
    fmt : str
    files : dict
        File name -> text, in the order a controller runs them (the main file first).
    program : CellProgram
        The moves they were written from, and the report of what was left out.
    seconds : float
        Time to build and write them.
    cell : object or None
        The robot they are for when it is not the job's gantry (``programs.arms.ArmCell``).
    """

    fmt: str
    files: dict
    program: CellProgram
    seconds: float
    cell: object = None


def check_format(fmt: str) -> str:
    if fmt not in PROGRAM_FORMATS:
        raise ConfigError(f"--format: {fmt!r} is not a program format; use one of {', '.join(PROGRAM_FORMATS)}")
    return fmt


def build(plan, job, fmt: str, strict: bool | None = None, cell=None) -> Built:
    """``fmt``'s program files of a plan, in memory (``programs.build.build_program``, then the writer);
    ``cell`` the robot when it is not the job's gantry (``programs.arms``).

    Raises
    ------
    InputError
        An unknown format; with ``strict``, a spray waypoint the program would leave out.
    """
    from sprayplan.programs.build import build_program

    check_format(fmt)
    start = time.perf_counter()
    if cell is not None and fmt == "urscript":
        raise ConfigError(
            f"--program urscript: {cell.name} is a robot of a cell; URScript is written for the gantry's UR arm "
            "(use rapid or krl)"
        )
    program = build_program(plan, job, fmt, strict, cell)
    if fmt == "urscript":
        from sprayplan.programs.urscript import write_urscript

        files = write_urscript(program, job)
    elif fmt == "rapid":
        from sprayplan.programs.rapid import write_rapid

        files = write_rapid(program, job, configurations(program, job, fmt, cell))
    else:
        from sprayplan.programs.krl import write_krl

        files = write_krl(program, job, configurations(program, job, fmt, cell))
    return Built(fmt, files, program, time.perf_counter() - start, cell)


def configurations(program: CellProgram, job, fmt: str, cell=None) -> dict:
    """The configuration data of every linear target (``id(move)`` -> RAPID ``(cf1, cf4, cf6, cfx)`` or KRL
    ``(S, T)``), from the joints each target stands for; ``cell`` the robot (default the job's gantry)."""
    from sprayplan.robots.stage import gantry_for

    cell = cell or Cell(gantry_for(job.kinematics))
    linear = [m for m, _ in program.sequence() if m.kind == LINEAR]
    if not linear:
        return {}
    q = np.array([m.joints for m in linear])
    values = cell.config_data(q, fmt)
    return {id(m): tuple(int(v) for v in row) for m, row in zip(linear, values)}


def read_programs(folder, job, fmt: str, external_axes: int = 3):
    """The programs in ``folder`` read back by ``fmt``'s strict reader (a ``model.ReadProgram``) for a robot
    with ``external_axes`` external axes (3: the gantry; a cell robot's 1 with a track, else 0)."""
    check_format(fmt)
    if fmt == "urscript":
        from sprayplan.programs.urscript import read_urscript

        return read_urscript(folder, job)
    if fmt == "rapid":
        from sprayplan.programs.rapid import read_rapid

        return read_rapid(folder, job, external_axes)
    from sprayplan.programs.krl import read_krl

    return read_krl(folder, job, external_axes)


def summary(built: Built, read, job, plan_name: str, source: str | None, result=None) -> dict:
    """What ``summary.json`` holds: the files with their size and move count, the totals, what was left out."""
    counts: dict = {}
    for move in read.moves:
        name = move.where.rsplit(":", 1)[0]
        counts[name] = counts.get(name, 0) + 1
    files = [
        {"file": name, "bytes": len(text.encode("ascii")), "lines": text.count("\n"),
         "moves": counts.get(name, 0)}
        for name, text in built.files.items()
    ]  # fmt: skip
    report = built.program.report
    out = {
        "format": SUMMARY_FORMAT,
        "version": 1,
        "sprayplan_version": __version__,
        "program_format": built.fmt,
        "part": plan_name,
        "plan": source,
        "files": files,
        "moves": len(read.moves),
        "linear_moves": sum(m.kind == LINEAR for m in read.moves),
        "joint_moves": sum(m.kind != LINEAR for m in read.moves),
        "bytes": sum(f["bytes"] for f in files),
        "left_out": {key: report[key] for key in LEFT_OUT},
        "counts": {k: v for k, v in report.items() if k not in LEFT_OUT},
        "settings": dict(_plain(job.export)),
        "seconds": round(built.seconds, 3),
    }
    if result is not None:
        out["check"] = {
            "ok": result.ok,
            "runs": result.runs,
            "waypoints": result.waypoints,
            "via_points": result.vias,
            "max_position_mm": result.max_position_mm,
            "max_angle_deg": result.max_angle_deg,
            "max_joint_rad": result.max_joint_rad,
            "max_speed_mm_s": result.max_speed_mm_s,
            "max_external_mm": result.max_external_mm,
            "max_gun_mm": result.max_gun_mm,
            "max_blend_share": result.max_blend_share,
        }
    return out


def _plain(section):
    import dataclasses

    for f in dataclasses.fields(section):
        value = getattr(section, f.name)
        yield f.name, list(value) if isinstance(value, tuple) else value


def warnings_of(built: Built) -> list[str]:
    """One line per kind of left-out spray waypoint: how many and where the first is (what the command line
    prints on stderr)."""
    lines = []
    for key, what in LEFT_OUT.items():
        found = built.program.report[key]
        if found:
            first = found[0]
            lines.append(
                f"{built.fmt}: {len(found)} spray waypoint{'s' if len(found) > 1 else ''} {what} left out with the "
                f"gun off (the first: station {first['station'] + 1}, stroke {first['stroke']}, waypoint "
                f"{first['waypoint']}, at {tuple(first['tcp_mm'])} mm; all in summary.json)"
            )
    return lines


def write_built(folder, builts: list[Built], plan, job, source: str | None = None) -> list[dict]:
    """Write each format's files into ``folder/<format>/`` all or nothing (``staged_folder``: the formats'
    folders go in together; other files in ``folder`` are left alone); each is read back in the temporary
    folder first and checked against ``plan``. Returns the summaries.

    Raises
    ------
    OutputError
        ``folder`` cannot be written (nothing is then created or changed).
    ProgramCheckError
        A program read back is not its plan (a bug; nothing is written).
    """
    from sprayplan.export.files import atomic_output, staged_folder
    from sprayplan.programs.check import check_program

    summaries = []
    with staged_folder(folder, tuple(b.fmt for b in builts), whole=False) as stage:
        for built in builts:
            target = Path(stage) / built.fmt
            target.mkdir()
            for name, text in built.files.items():
                with atomic_output(target / name, "w", encoding="ascii", newline="\n") as handle:
                    handle.write(text)
            axes = built.program.external_axes
            read = read_programs(target, job, built.fmt, axes)
            result = check_program(read, plan, job, built.cell)
            if not result.ok:
                raise ProgramCheckError(
                    f"the {built.fmt} program in {Path(folder) / built.fmt} read back differs from the plan "
                    f"({len(result.failures)} differences; "
                    f"the first: {result.failures[0]}): a defect, please report it"
                )
            data = summary(built, read, job, plan.name, source, result)
            with atomic_output(target / SUMMARY, "w", encoding="utf-8") as handle:
                json.dump(data, handle, indent=1)
                handle.write("\n")
            summaries.append(data)
    return summaries


def export_plan(plan, job, formats, folder, source: str | None = None, strict=None):
    """Build every format's programs of a plan (all refusals first), then write them into ``folder/<format>/``
    all or nothing. Returns ``(builts, summaries)``."""
    builts = [build(plan, job, fmt, strict) for fmt in formats]
    return builts, write_built(folder, builts, plan, job, source)


def default_folder(outdir) -> str:
    """Where ``sprayplan export OUT`` and ``plan --program`` put the programs: ``OUT/programs``."""
    return os.path.join(os.fspath(outdir), "programs")
