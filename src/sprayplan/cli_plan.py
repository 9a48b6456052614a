"""The main job on the command line: ``sprayplan plan`` and ``sprayplan simulate`` (see ``cli.py``)."""

from __future__ import annotations

import dataclasses
import logging
import time
from pathlib import Path

from sprayplan.cli_common import parse_direction, parse_edge_passes, stage
from sprayplan.errors import ConfigError

log = logging.getLogger("sprayplan.cli")


def _job_config(args):
    """The job's settings: defaults, then the TOML file (-c), then the flags given on the command line."""
    from sprayplan.config import JobConfig, job_from_toml

    job = job_from_toml(args.config) if args.config else JobConfig()
    load = {k: getattr(args, k) for k in ("units", "up", "region") if getattr(args, k) is not None}
    plan = {
        k: getattr(args, k)
        for k in ("mode", "tour", "process", "thickness_um", "tolerance_um", "speed_along")
        if getattr(args, k, None) is not None
    }
    if getattr(args, "no_tune_speed", False):
        plan["tune_speed"] = False
    paths = {}
    for key in ("spacing_mm", "spray_radius_mm", "overlap", "standoff_mm", "step_mm"):
        if getattr(args, key, None) is not None:
            paths[key] = getattr(args, key)
    if args.direction is not None:
        paths["direction"] = parse_direction(args.direction)
    if args.edge_passes is not None:
        paths["edge_passes"] = parse_edge_passes(args.edge_passes)
    if "spacing_mm" in paths and "overlap" in paths:
        raise ConfigError("give either --spacing-mm or --overlap, not both")
    if args.robot is not None and args.robot != "gantry-ur5":
        raise ConfigError(f"sprayplan plan drives the gantry-ur5 (seed 000's nine axes), not {args.robot!r}")
    return dataclasses.replace(
        job,
        load=dataclasses.replace(job.load, **load),
        paths=dataclasses.replace(job.paths, **paths),
        plan=dataclasses.replace(job.plan, **plan),
    )


def run_plan(part_path: str, outdir: Path, job, simulate: bool = False, samples: int | None = None) -> str:
    from sprayplan.coating_stage import meet_thickness, simulate_plan, tune_plan, write_coating
    from sprayplan.io.load import load_part
    from sprayplan.io.plan_files import write_plan
    from sprayplan.pipeline import plan, plan_totals
    from sprayplan.surface.region import select_region

    start = time.perf_counter()
    job, chosen = meet_thickness(job)
    if chosen:
        log.info(
            "for %.4g um: spacing %.4g mm, gun speed %.4g mm/s",
            chosen["target_um"],
            chosen["spacing_mm"],
            chosen["gun_speed_mm_s"],
        )
    with stage("load"):
        part = load_part(part_path, units=job.load.units, up=job.load.up)
    with stage("region"):
        part = select_region(part, job.load.region)
    with stage("plan (paths, stations, ordering, kinematics)"):
        result = plan(part, job)
    tuned, film = {}, None
    if job.plan.thickness_um is not None and job.plan.tune_speed:
        with stage("speeds tuned to the film, touch-ups"):
            result, tuned, film = tune_plan(part, result, job)
    totals = plan_totals(result, job)
    if chosen:
        totals["chosen_for_thickness"] = chosen
    if tuned:
        totals["speed_tuning"] = tuned
    report = None
    if simulate and film is None:  # a tuned plan's film is known already
        with stage("coating"):
            film = simulate_plan(part, result, job)
    elapsed = time.perf_counter() - start
    totals["planning_time_s"] = round(elapsed, 3)
    write_plan(outdir, result, job, totals, part_path)
    if simulate:
        report = write_coating(outdir, film, job, samples, chosen)
    line = (
        f"{totals['stations']} stations, {totals['strokes']} strokes, {totals['waypoints']} waypoints "
        f"({totals['unreachable_waypoints']} unreachable, {totals['unassigned_points']} unassigned), spray "
        f"{totals['spray_length_mm'] / 1000:.2f} m, transfer {totals['transfer_length_mm'] / 1000:.2f} m, gantry "
        f"{totals['platform_travel_mm'] / 1000:.2f} m, cycle {totals['cycle_time_s']:.0f} s, planned in {elapsed:.1f} s "
        f"-> {outdir}/plan.json"
    )
    if report is not None:
        line += "\n" + _coating_line(report, outdir)
    return line


def _coating_line(report: dict, outdir) -> str:
    painted = report["painted"]
    return (
        f"film: mean {painted['mean_um']:.1f} um, std/mean {painted['cv']:.3f}, min {painted['min_um']:.1f}, "
        f"max {painted['max_um']:.1f}, {100 * painted['share_in_spec']:.1f}% of the painted area in "
        f"{report['spec']['target_um']:.0f} +- {report['spec']['tolerance_um']:.0f} um -> {outdir}/coating.json"
    )


def cmd_simulate(args) -> int:
    import dataclasses as dc

    from sprayplan.coating_stage import simulate_plan, write_coating
    from sprayplan.io.load import load_part
    from sprayplan.io.plan_files import plan_from_dict, read_plan
    from sprayplan.surface.region import select_region

    outdir = Path(args.outdir)
    data = read_plan(outdir / "plan.json")
    result, job = plan_from_dict(data)
    if args.thickness_um is not None or args.tolerance_um is not None:
        changes = {k: getattr(args, k) for k in ("thickness_um", "tolerance_um") if getattr(args, k) is not None}
        job = dc.replace(job, plan=dc.replace(job.plan, **changes))
    part_file = args.part or data.get("part_file")
    if not part_file:
        raise ConfigError("plan.json does not name its part file: give it with --part")
    part = select_region(load_part(part_file, units=job.load.units, up=job.load.up), job.load.region)
    with stage("coating"):
        film = simulate_plan(part, result, job)
    report = write_coating(outdir, film, job, args.samples)
    print(_coating_line(report, outdir))
    return 0


def cmd_plan(args) -> int:
    job = _job_config(args)
    print(
        run_plan(
            args.part,
            Path(args.output),
            job,
            simulate=args.simulate or job.plan.thickness_um is not None,
            samples=args.samples,
        )
    )
    return 0
