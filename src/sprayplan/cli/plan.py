"""The main job on the command line: ``sprayplan plan`` and ``sprayplan simulate`` (see ``cli.main``)."""

from __future__ import annotations

import json
import logging
import os
from pathlib import Path

from sprayplan.cli.common import (
    ProgressDisplay,
    check_count,
    check_folder_outputs,
    check_outputs,
    file_input,
    output_option,
    parse_direction,
    parse_edge_passes,
    stage,
)
from sprayplan.errors import ConfigError

log = logging.getLogger("sprayplan.cli")


def _job_config(args):
    """The job's settings: defaults, then the TOML file (-c), then the flags given on the command line."""
    from sprayplan.config import JobConfig, job_from_toml

    job = job_from_toml(args.config) if args.config else JobConfig()
    given = lambda *keys: {k: getattr(args, k) for k in keys if getattr(args, k, None) is not None}
    paths = given("spacing_mm", "spray_radius_mm", "overlap", "standoff_mm", "step_mm")
    if args.direction is not None:
        paths["direction"] = parse_direction(args.direction)
    if args.edge_passes is not None:
        paths["edge_passes"] = parse_edge_passes(args.edge_passes)
    if "spacing_mm" in paths and "overlap" in paths:
        raise ConfigError("give either --spacing-mm or --overlap, not both")
    changes = {
        "load": {
            **given("units", "up", "region"),
            **({"mask": tuple(args.mask)} if getattr(args, "mask", None) else {}),
        },
        "paths": paths,
        "ordering": given("tour"),
        "kinematics": {
            **({"robot": args.robot} if args.robot is not None else {}),
            **({"robot_file": args.robot_file} if getattr(args, "robot_file", None) is not None else {}),
        },
        "motion": given("speed_along"),
        "coating": given("process", "thickness_um", "tolerance_um"),
        "tuning": {"tune_speed": False} if getattr(args, "no_tune_speed", False) else {},
        "output": {**({"simulate": True} if args.simulate else {}), **given("samples"), **view_flags(args)},
    }
    if getattr(args, "collisions", False):
        changes["collision"] = {"check": True}
    if getattr(args, "seed", None) is not None:
        changes["stations"] = {"seed": args.seed}
        changes["ordering"] = changes["ordering"] | {"seed": args.seed}
    if args.mode is not None:
        changes["mode"] = args.mode
    if getattr(args, "program", None) or getattr(args, "strict", False):
        changes["export"] = {"programs": tuple(dict.fromkeys(args.program or job.export.programs))}
        changes["export"] |= {"strict": True} if args.strict else {}
    return job.replace(**{k: v for k, v in changes.items() if v or k == "mode"})


def view_flags(args) -> dict:
    """``[output]`` changes of ``--no-viewer`` and ``--no-report``."""
    out = {}
    if getattr(args, "no_viewer", False):
        out["viewer"] = False
    if getattr(args, "no_report", False):
        out["report"] = False
    return out


def run_plan(part_path: str, outdir: Path, job, quiet: bool = False) -> str:
    """Run the main job (``job.run_job``) with a progress display and write its files (all or nothing, in
    ``outdir``); returns the summary."""
    return summary_line(run_shown(part_path, job, quiet, outdir), outdir)


def run_shown(part_path, job, quiet: bool = False, outdir=None):
    """``job.run_job`` with the progress display; returns its result."""
    from sprayplan.job import run_job

    display = ProgressDisplay(quiet=quiet)
    try:
        result = run_job(part_path, job, outdir=outdir, progress=display)
    except BaseException:
        display.close(finished=False)
        raise
    display.close()
    return result


def _length_over_speed(totals: dict) -> str:
    """`` (length over speed 366 s)`` beside a timed cycle time; empty for an untimed plan."""
    value = totals.get("cycle_time_length_over_speed_s")
    return "" if value is None else f" (length over speed {value:.0f} s)"


def summary_line(result, outdir) -> str:
    """What ``sprayplan plan`` prints: the plan's counts and lengths, and its film when it has one."""
    totals = result.totals
    line = (
        f"{totals['stations']} stations, {totals['strokes']} strokes, {totals['waypoints']} waypoints "
        f"({totals['unreachable_waypoints']} unreachable, {totals['unassigned_points']} unassigned), spray "
        f"{totals['spray_length_mm'] / 1000:.2f} m, transfer {totals['transfer_length_mm'] / 1000:.2f} m, gantry "
        f"{totals['platform_travel_mm'] / 1000:.2f} m, cycle {totals['cycle_time_s']:.0f} s{_length_over_speed(totals)}, planned in "
        f"{totals['planning_time_s']:.1f} s -> {outdir}/plan.json"
    )
    collisions = totals.get("collisions")
    if not collisions:
        line += "; collisions not checked (--collisions checks them)"
    elif collisions.get("checked") is False:
        line += f"\ncollisions: not checked ({collisions['reason']})"
    else:
        line += (
            f"\ncollisions: {collisions['flagged_waypoints']} waypoints and {collisions['flagged_motions']} motions "
            f"flagged, {collisions['repaired']} of {collisions['in_collision_before_repair']} repaired "
            f"(clearance {collisions['clearance_mm']:g} mm)"
        )
        if collisions.get("motions_repaired"):
            line += f"; {collisions['motions_repaired']} motions in strokes repaired"
        if collisions.get("transfers_in_collision"):
            line += (
                f"; transfers: {collisions['transfers_rerouted']} of {collisions['transfers_in_collision']} "
                f"re-routed, {collisions['transfers_flagged']} flagged"
            )
    if totals.get("floor_facing_left_out_mm2"):
        line += f"; surface facing the floor left out: {totals['floor_facing_left_out_mm2'] / 1e6:.4g} m2"
    if totals.get("covered_left_out_mm2"):
        line += f"; surface covered by other faces left out: {totals['covered_left_out_mm2'] / 1e6:.4g} m2"
    if totals.get("masked_left_out_mm2"):
        line += f"; surface masked (--mask) left out: {totals['masked_left_out_mm2'] / 1e6:.4g} m2"
    if result.film is not None:
        from sprayplan.export.film import film_report

        report = film_report(result.film, result.job, result.job.output.samples, result.chosen)
        line += "\n" + _coating_line(report, outdir)
    over = totals.get("speed_tuning", {}).get("within_limits", {}).get("over_spec", {})
    if over.get("area_mm2"):
        line += (
            f"\nspeeds within the joints' limits: {100 * over['share']:.1f}% of the tuned area above spec where the "
            f"gun cannot go fast enough (up to {over['max_um']:.1f} um; speed_tuning.within_limits in plan.json)"
        )
    return line


def _coating_line(report: dict, outdir) -> str:
    painted = report["painted"]
    return (
        f"film: mean {painted['mean_um']:.1f} um, std/mean {painted['cv']:.3f}, min {painted['min_um']:.1f}, "
        f"max {painted['max_um']:.1f}, {100 * painted['share_in_spec']:.1f}% of the painted area in "
        f"{report['spec']['target_um']:.0f} +- {report['spec']['tolerance_um']:.0f} um -> {outdir}/coating.json"
    )


def _check_samples(value) -> None:
    """``--samples``: a whole number >= 1 within the job's bound on it (``config.OutputConfig``)."""
    from sprayplan.config import OutputConfig

    check_count("--samples", value)
    try:
        OutputConfig(samples=value)
    except ConfigError as exc:
        raise ConfigError(f"--samples: {exc}") from None


def cmd_simulate(args) -> int:
    from sprayplan.coating.stage import simulate_plan
    from sprayplan.export.files import staged_folder
    from sprayplan.export.film import film_report, write_coating
    from sprayplan.export.job_files import FILM_FILES, VIEW_FILES
    from sprayplan.export.plan_read import read_plan_file
    from sprayplan.io.load import load_part
    from sprayplan.surface.region import painted_surface, select_region

    output_option(args.outdir, "OUTDIR")
    _check_samples(args.samples)
    outdir = Path(args.outdir)
    read = read_plan_file(outdir / "plan.json")  # checked whole before anything is written
    result, job = read.plan, read.job
    if args.thickness_um is not None or args.tolerance_um is not None:
        changes = {k: getattr(args, k) for k in ("thickness_um", "tolerance_um") if getattr(args, k) is not None}
        job = job.replace(coating=changes)
    part_file = args.part or read.part_file
    if not part_file:
        raise ConfigError("plan.json does not name its part file: give it with --part")
    if not result.strokes or not any(stroke.spray_on for stroke in result.strokes):
        raise ConfigError(f"{outdir / 'plan.json'}: the plan paints nothing (no spray strokes): no film to predict")
    views = view_flags(args)
    view = {"viewer": views.get("viewer", True), "report": views.get("report", True)}
    own = FILM_FILES + tuple(name for name, on in zip(VIEW_FILES, (view["viewer"], view["report"])) if on)
    inputs = [(part_file, "--part" if args.part else "part"), (outdir / "plan.json", "plan.json")]
    check_folder_outputs(outdir, own, "OUTDIR", inputs)
    part = select_region(load_part(part_file, units=job.load.units, up=job.load.up), job.load.region)
    # the surface the plan paints, as its region stage cut it
    part, _ = painted_surface(part, job.collision, job.load.mask)
    filmed = result
    if read.timing is not None and job.timing.film_at_timed_speeds:  # the film at the speeds the robot makes
        from sprayplan.timing.stage import real_plan

        filmed = real_plan(result, read.timing, job)
    with stage("coating"):
        film = simulate_plan(part, filmed, job)
    report = film_report(film, job, args.samples)
    with staged_folder(outdir, own, whole=False) as folder:  # the film files and their pictures, or none
        write_coating(folder, film, job, report)
        if view["viewer"] or view["report"]:
            from sprayplan.view.files import write_view_files
            from sprayplan.view.scene import make_scene

            scene = make_scene(result, job, read.totals, film, report, timing=read.timing)
            with stage("pictures"):
                write_view_files(folder, scene, **view)
    print(_coating_line(report, outdir))
    return 0


def cmd_plan(args) -> int:
    from sprayplan.export.job_files import JOB_FILES

    check_outputs([(args.output, "-o")], [], folder=True)
    _check_samples(args.samples)
    robot = getattr(args, "robot", None)
    ruled = getattr(args, "ruled", None)
    if ruled is not None and args.part is not None:
        raise ConfigError("give either a PART or --ruled SURFACE.toml, not both")
    if ruled is None and args.part is None:
        raise ConfigError("give a PART file (or --ruled SURFACE.toml with --robot)")
    if ruled is not None and (robot is None or robot.startswith("gantry-")):
        raise ConfigError("--ruled: give the fixed-base robot that paints it with --robot (r5150, ur5, ...)")
    if robot is not None and not robot.startswith("gantry-"):
        from sprayplan.cli.cells import cmd_plan_robot

        return cmd_plan_robot(args, _job_config)
    job = _job_config(args)
    if getattr(args, "cell", None) is not None:
        from sprayplan.cells import load_cell

        cell = load_cell(args.cell)
        if not cell.is_gantry:  # the gantry cell is this job, as without --cell
            from sprayplan.cli.cells import cmd_plan_cell

            return cmd_plan_cell(args, job, cell)
    if getattr(args, "seams", None) is not None:
        raise ConfigError("--seams: only with --cell (the seams between a cell's robots and areas)")
    inputs = [(args.part, "part"), (args.config, "-c"), (file_input(job.coating.process), "--process")]
    check_folder_outputs(args.output, JOB_FILES, "-o", inputs)
    if job.export.programs:
        programs = os.path.join(args.output, "programs")
        check_outputs(
            [(programs, "-o"), *((os.path.join(programs, f), "-o") for f in job.export.programs)], inputs, True
        )
    result = run_shown(args.part, job, getattr(args, "quiet", False), Path(args.output))
    _program_warnings(result)
    print(summary_line(result, Path(args.output)))
    for built in result.programs:
        from sprayplan.cli.export import summary_text
        from sprayplan.programs.stage import SUMMARY

        folder = os.path.join(args.output, "programs", built.fmt)
        with open(os.path.join(folder, SUMMARY), encoding="utf-8") as handle:
            print(summary_text(json.load(handle), folder))
    return 0


def _program_warnings(result) -> None:
    """What the robot programs left out, one line each on stderr."""
    import sys

    from sprayplan.programs.stage import warnings_of

    for built in result.programs:
        for line in warnings_of(built):
            print(f"sprayplan: warning: {line}", file=sys.stderr)
