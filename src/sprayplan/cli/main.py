"""The ``sprayplan`` command: ``main(argv=None)`` with one subcommand per job.

One error path: every expected failure (a bad file or option, a wrong command line, an output that cannot be
written) ends with one line on stderr, ``sprayplan: error: FILE or --option: problem``, exit code 2, and no
output created or changed; a bug ends with ``sprayplan: internal error: ...`` and exit code 1 (the traceback
with ``-v``); Ctrl-C with exit code 130. Library warnings are logged (shown with ``-v``), never printed.
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
import os
import signal
import sys
import threading
import time
import traceback
import warnings
from pathlib import Path

from sprayplan import __version__
from sprayplan.cli.common import (
    ArgumentParser,
    UsageError,
    check_outputs,
    output_option,
    parse_direction,
    parse_edge_passes,
    stage,
)
from sprayplan.errors import ConfigError, InputError, OutputError, PartFileError, StageError
from sprayplan.heap import reuse_freed_memory

log = logging.getLogger("sprayplan.cli")


def _add_load_options(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("part")
    group.add_argument(
        "--units", choices=["mm", "cm", "m", "in"], default="mm", help="length unit of the file (default mm)"
    )
    group.add_argument(
        "--up", choices=["z", "y", "x"], default="z", help="the file's up axis, turned to +z (default z)"
    )
    group.add_argument(
        "--region",
        help="keep only this region, in mm in the part frame: 'z > 1000', 'x < 500 and z > 1000', "
        "'box(x0,y0,z0,x1,y1,z1)'",
    )


def _add_target_options(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("targets")
    group.add_argument(
        "--fill",
        choices=["even", "point", "line"],
        default="even",
        help="even (default), or the seed's DFS point or line filling",
    )
    group.add_argument(
        "--spacing-mm", type=float, help="target spacing d in mm (instead of --spray-radius-mm and --overlap)"
    )
    group.add_argument("--spray-radius-mm", type=float, help="spray circle radius r in mm (default 50)")
    group.add_argument("--overlap", type=float, help="overlap ratio p of neighbouring spray circles (default 0.4)")
    group.add_argument(
        "--compress",
        choices=["surface", "grid", "none"],
        default="surface",
        help="surface (default): one real point per eq. 7 cell; grid: eq. 7 as printed",
    )
    group.add_argument(
        "--h-min-mm", type=float, help="DFS filling: minimum triangle height (default: half the spacing)"
    )
    group.add_argument(
        "--normals",
        choices=["face", "pca"],
        default="face",
        help="even fill: face normals (default) or PCA over neighbours",
    )
    group.add_argument("--normal-radius-mm", type=float, help="PCA neighbourhood radius (default: twice the spacing)")
    group.add_argument(
        "--orient",
        choices=["mesh", "centroid", "propagate"],
        help="how normals are turned outward (default: mesh for meshes, propagate for clouds)",
    )
    group.add_argument("--seed", type=int, default=0, help="random seed (default 0)")


def _targets_config(args):
    from sprayplan.config import TargetsConfig

    if args.spacing_mm is not None and (args.spray_radius_mm is not None or args.overlap is not None):
        raise ConfigError("give either --spacing-mm or --spray-radius-mm/--overlap, not both")
    extra = {}
    if args.spray_radius_mm is not None:
        extra["spray_radius_mm"] = args.spray_radius_mm
    if args.overlap is not None:
        extra["overlap"] = args.overlap
    return TargetsConfig(
        fill=args.fill,
        spacing_mm=args.spacing_mm,
        compress=args.compress,
        h_min_mm=args.h_min_mm,
        normals=args.normals,
        normal_radius_mm=args.normal_radius_mm,
        orient=args.orient,
        seed=args.seed,
        **extra,
    )


_stage = stage


def _run_targets(part_path: str, load_args, config):
    """The targets of a part: (targets, part, seconds)."""
    from sprayplan.io.load import load_part
    from sprayplan.surface.region import select_region
    from sprayplan.surface.targets import make_targets

    start = time.perf_counter()
    with _stage("load"):
        part = load_part(part_path, units=load_args.units, up=load_args.up)
    with _stage("region"):
        part = select_region(part, load_args.region)
    with _stage("targets"):
        targets = make_targets(part, config)
    return targets, part, time.perf_counter() - start


def _targets_line(targets, part, config, elapsed: float, output) -> str:
    area = f"{part.area / 1e6:.4g} m^2" if part.is_mesh else f"a cloud of {len(part.vertices)} points"
    return (
        f"{len(targets)} targets on {area} (fill {config.fill if part.is_mesh else 'cloud'}, "
        f"spacing {config.spacing:.4g} mm, compress {config.compress}) in {elapsed:.2f} s -> {output}"
    )


def cmd_targets(args) -> int:
    from sprayplan.export.files import staged_files, write_targets_csv

    check_outputs([(args.output, "-o")], [(args.part, "part")])
    config = _targets_config(args)
    targets, part, elapsed = _run_targets(args.part, args, config)
    with staged_files([args.output]) as (temp,):
        write_targets_csv(temp, targets)
    print(_targets_line(targets, part, config, elapsed, args.output))
    return 0


#: What ``sprayplan demo`` writes into its folder.
DEMO_FILES = ("roof.stl", "targets.csv")


def cmd_demo(args) -> int:
    from sprayplan.cli.plan import run_shown, summary_line
    from sprayplan.config import JobConfig, TargetsConfig
    from sprayplan.demo import DEMO_REGION, car_roof
    from sprayplan.export.files import atomic_output, staged_folder, write_targets_csv
    from sprayplan.export.job_files import JOB_FILES, write_job_files
    from sprayplan.export.stl import write_stl_binary

    check_outputs([(args.output, "-o")], [], folder=True)
    out = Path(args.output)
    # seed 003's film spec, 50 +- 5 um: the plan picks the stroke spacing and gun speed for it
    job = JobConfig().replace(
        load={"region": DEMO_REGION}, coating={"thickness_um": 50.0}, output={"simulate": True, "samples": 420}
    )
    roof = car_roof()
    lines = [f"demo part: {out / 'roof.stl'} ({len(roof.faces)} triangles, 2635 x 1959 mm above z = 1000 mm)"]
    with staged_folder(out, DEMO_FILES + JOB_FILES) as folder:  # all of it, or nothing
        with atomic_output(folder / "roof.stl", "wb") as handle:
            handle.write(write_stl_binary(roof.triangles, b"sprayplan demo car roof, mm, z up"))
        load_args = argparse.Namespace(units="mm", up="z", region=DEMO_REGION)
        config = TargetsConfig()
        targets, part, elapsed = _run_targets(str(folder / "roof.stl"), load_args, config)
        write_targets_csv(folder / "targets.csv", targets)
        lines.append(_targets_line(targets, part, config, elapsed, out / "targets.csv"))
        result = run_shown(str(folder / "roof.stl"), job, quiet=getattr(args, "quiet", False))
        # the part is named by where it will be, not by the staging folder it was planned from
        plan = dataclasses.replace(result.plan, name=os.fspath(out / "roof.stl"))
        result = dataclasses.replace(result, plan=plan)
        write_job_files(folder, result, part_file=os.path.abspath(out / "roof.stl"))
    lines.append(summary_line(result, out))
    print("\n".join(lines))
    return 0


def _path_config(args):
    from sprayplan.config import PathConfig

    if args.spacing_mm is not None and args.overlap is not None:
        raise ConfigError("give either --spacing-mm or --overlap, not both")
    options = dict(
        direction=parse_direction(args.direction),
        spacing_mm=args.spacing_mm,
        layers=args.layers,
        spacing_mode=args.spacing_mode,
        edge_margin_mm=args.edge_margin_mm,
        split_gap_mm=args.split_gap_mm,
        split_angle_deg=None
        if args.split_angle_deg is not None and args.split_angle_deg <= 0
        else args.split_angle_deg,
        interpolate=args.interpolate,
        points_per_section=args.points_per_section,
        slab_mm=args.slab_mm,
        cloud_normals=args.cloud_normals,
        cloud_smooth_mm=args.cloud_smooth_mm,
        rim_mm=args.rim_mm,
    )
    if args.edge_passes is not None:
        options["edge_passes"] = parse_edge_passes(args.edge_passes)
    for name in ("spray_radius_mm", "overlap", "standoff_mm", "step_mm"):
        if getattr(args, name) is not None:
            options[name] = getattr(args, name)
    if args.streamline_deg is not None:
        options["streamline_deg"] = tuple(args.streamline_deg)
    return PathConfig(**options)


def cmd_paths(args) -> int:
    from sprayplan.export.files import staged_files
    from sprayplan.export.paths_json import summary, write_paths_json

    start = time.perf_counter()
    output_option(args.table, "--table")
    if args.table is not None and not args.ruled:
        raise ConfigError("--table: the Cartesian table is written only with --ruled SURFACE.toml")
    outputs = [(args.output, "-o"), (args.table, "--table")]
    check_outputs(outputs, [(args.part, "part"), (args.ruled, "--ruled")])
    if args.ruled:
        from sprayplan.export.tables import write_table_csv
        from sprayplan.paths.ruled import ruled_paths
        from sprayplan.paths.ruled_toml import load_ruled

        if args.part:
            raise ConfigError("give either a PART or --ruled SURFACE.toml, not both")
        with _stage("ruled surface"):
            job = load_ruled(args.ruled)
            try:
                paths = ruled_paths(job)
            except ConfigError as exc:  # a bound on the file's settings: name the file
                raise PartFileError(args.ruled, str(exc)) from None
        settings = {"ruled": str(args.ruled)}
    else:
        from sprayplan.io.load import load_part
        from sprayplan.paths.planner import plan_paths
        from sprayplan.surface.region import select_region

        if not args.part:
            raise ConfigError("give a PART file (or --ruled SURFACE.toml)")
        config = _path_config(args)
        with _stage("load"):
            part = load_part(args.part, units=args.units, up=args.up)
        with _stage("region"):
            part = select_region(part, args.region)
        with _stage("paths"):
            paths = plan_paths(part, config)
        settings = {
            **dataclasses.asdict(config),
            "spacing_mm": config.spacing,
            "edge_margin_mm": config.margin,
            "split_gap_mm": config.gap,
            "units": args.units,
            "up": args.up,
            "region": args.region,
        }
    info = summary(paths)
    with staged_files([path for path, _ in outputs if path is not None]) as temps:  # both files, or neither
        write_paths_json(temps[0], paths, settings)
        if args.table:
            write_table_csv(temps[1], paths)
    print(
        f"{info['strokes']} strokes, spray {info['spray_length_mm'] / 1000:.3f} m, transfer "
        f"{info['transfer_length_mm'] / 1000:.3f} m, {info['waypoints']} waypoints in "
        f"{time.perf_counter() - start:.2f} s -> {args.output}"
    )
    return 0


from sprayplan.cli.batch import add_batch_parser  # noqa: E402 - batches of jobs
from sprayplan.cli.cells import add_parsers as add_cell_parsers  # noqa: E402 - the cell commands, own module
from sprayplan.cli.export import add_export_parser, program_format  # noqa: E402 - robot programs
from sprayplan.cli.plan import cmd_plan, cmd_simulate  # noqa: E402 - the main job's commands
from sprayplan.cli.robots import cmd_fk, cmd_ik, cmd_robots  # noqa: E402 - the robot commands, own module
from sprayplan.cli.view import cmd_view  # noqa: E402


def _add_edge_options(group) -> None:
    group.add_argument(
        "--edge-passes",
        metavar="N",
        help="passes past the part's edges along the strokes: auto (default: as many as still paint the part) "
        "or a number; 0: none",
    )


def build_parser() -> argparse.ArgumentParser:
    parser = ArgumentParser(
        prog="sprayplan",
        description="Turn a part's geometry into a spray-painting robot program.",
    )
    parser.add_argument("--version", action="version", version=f"sprayplan {__version__}")
    common = ArgumentParser(add_help=False)
    common.add_argument(
        "-v", "--verbose", action="store_true", default=argparse.SUPPRESS, help="log each stage and its time"
    )
    common.add_argument("-q", "--quiet", action="store_true", default=argparse.SUPPRESS, help="show errors only")
    parser.add_argument("-v", "--verbose", action="store_true", default=False, help="log each stage and its time")
    parser.add_argument("-q", "--quiet", action="store_true", default=False, help="show errors only")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    demo = sub.add_parser("demo", parents=[common], help="run the pipeline on the bundled car-roof part")
    demo.add_argument("-o", "--output", default="sprayplan-demo", help="output folder (default sprayplan-demo)")
    demo.set_defaults(func=cmd_demo)

    targets = sub.add_parser(
        "targets",
        parents=[common],
        help="target points with outward normals (CSV x,y,z,nx,ny,nz)",
        description="Target points on a part's surface with unit outward normals (seed 000, section 2).",
    )
    targets.add_argument(
        "part", help="mesh (.stl .obj .ply .off, optionally .gz) or point cloud (.xyz .txt .csv .pcd .ply)"
    )
    targets.add_argument("-o", "--output", required=True, help="output CSV file")
    _add_load_options(targets)
    _add_target_options(targets)
    targets.set_defaults(func=cmd_targets)

    paths = sub.add_parser(
        "paths",
        parents=[common],
        help="spray strokes by slicing (paths.json)",
        description="Spray strokes over a part by slicing it with parallel planes (seed 003), or over a ruled "
        "surface given in a TOML file (seed 001).",
    )
    paths.add_argument("part", nargs="?", help="mesh or point cloud file (as for 'targets')")
    paths.add_argument("-o", "--output", required=True, help="output paths.json")
    paths.add_argument("--ruled", help="a ruled surface TOML file instead of a part (see examples/ruled)")
    paths.add_argument("--table", help="with --ruled: also write the Cartesian table (CSV n,x,y,z)")
    _add_load_options(paths)
    group = paths.add_argument_group("paths")
    group.add_argument(
        "--direction", default="auto", help="slicing planes' normal: auto (default), x, y, z or 'dx,dy,dz'"
    )
    group.add_argument(
        "--spacing-mm", type=float, help="distance between strokes (default: from spray radius and overlap)"
    )
    group.add_argument("--layers", type=int, help="instead of a spacing: this many equally spaced planes")
    group.add_argument("--spray-radius-mm", type=float, help="spray circle radius (default 50)")
    group.add_argument("--overlap", type=float, help="overlap of neighbouring strokes (default 0.4)")
    group.add_argument(
        "--spacing-mode",
        choices=["surface", "uniform"],
        default="surface",
        help="surface (default): spacing measured on the part; uniform: equally spaced planes",
    )
    group.add_argument("--standoff-mm", type=float, help="gun tip to surface (default 113)")
    group.add_argument(
        "--edge-margin-mm", type=float, help="lead-in/lead-out past the edge (default: the spray radius)"
    )
    group.add_argument("--step-mm", type=float, help="waypoint spacing along a stroke (default 10)")
    group.add_argument(
        "--split-gap-mm", type=float, help="split strokes across gaps wider than this (default: spray diameter)"
    )
    group.add_argument(
        "--split-angle-deg",
        type=float,
        default=60.0,
        help="split strokes at corners sharper than this (default 60; 0: never)",
    )
    group.add_argument(
        "--streamline-deg", type=float, nargs=2, metavar=("MIN", "MAX"), help="angle-method streamlining thresholds"
    )
    group.add_argument(
        "--points-per-section",
        type=int,
        help="sample each section at this many points (003 eq. 13) instead of every --step-mm",
    )
    group.add_argument(
        "--interpolate",
        choices=["none", "line", "arc"],
        default="none",
        help="with --points-per-section: line or arc interpolation between them",
    )
    group.add_argument("--slab-mm", type=float, help="point clouds: half-thickness of each slice")
    group.add_argument(
        "--cloud-normals",
        choices=["triangles", "plane"],
        default="triangles",
        help="point clouds: neighbour-triangle (default) or plane-fit normals",
    )
    group.add_argument("--cloud-smooth-mm", type=float, help="point clouds: smoothing radius before slicing")
    _add_edge_options(group)
    group.add_argument(
        "--rim-mm",
        type=float,
        help="stroke ends turning over within this are not followed (default: half the spray radius; 0: all)",
    )
    paths.set_defaults(func=cmd_paths)

    robots = "ur5, ur5e, ur5-seed, r5150, an industrial arm (`sprayplan robots` lists them) or a robot .toml"
    robots_cmd = sub.add_parser(
        "robots", parents=[common], help="list the robot presets, or describe one (a name or an OPW arm's .toml)"
    )
    robots_cmd.add_argument("robot", nargs="?", help="an industrial arm's name or an OPW arm's .toml file")
    robots_cmd.set_defaults(func=cmd_robots)
    add_cell_parsers(sub, common, _add_load_options)
    fk_cmd = sub.add_parser("fk", parents=[common], help="forward kinematics: joints CSV -> poses CSV")
    fk_cmd.add_argument("joints", help="CSV with columns q1..q6 (rad; q1..q5 for r5150)")
    fk_cmd.add_argument("-o", "--output", required=True)
    fk_cmd.add_argument("--robot", default="ur5", help=robots)
    fk_cmd.add_argument("--pose-format", choices=["rotvec", "matrix"], default="rotvec")
    fk_cmd.add_argument("--tool", help="give the pose of this gun (wa101) instead of the flange")
    fk_cmd.set_defaults(func=cmd_fk)

    ik_cmd = sub.add_parser(
        "ik",
        parents=[common],
        help="inverse kinematics: poses CSV (or paths.json for gantry-ur5) -> joints CSV",
        description="Inverse kinematics. Rows of a poses CSV are a trajectory: each gets the branch nearest the "
        "previous row's joints. Unreachable poses give a row with empty joints and reachable=0.",
    )
    ik_cmd.add_argument("poses", help="CSV x,y,z,rx,ry,rz (mm, rotation vector) or a paths.json for gantry-ur5")
    ik_cmd.add_argument("-o", "--output", required=True)
    ik_cmd.add_argument("--robot", default="ur5", help=robots + ", or gantry-ur5 (nine axes, reads paths.json)")
    ik_cmd.add_argument("--pose-format", choices=["rotvec", "matrix"], default="rotvec")
    ik_cmd.add_argument("--tool", help="the poses are of this gun (wa101), not of the flange")
    ik_cmd.add_argument("--all", action="store_true", help="every valid branch: columns pose,branch,q1..q6")
    ik_cmd.add_argument("--seed-joints", help="'q1,...,q6': start the trajectory near these joints (rad)")
    ik_cmd.add_argument("--platform", default="auto", help="gantry-ur5: 'x,y,z' (mm) for every stroke, or auto")
    ik_cmd.set_defaults(func=cmd_ik)

    plan_cmd = sub.add_parser(
        "plan",
        parents=[common],
        help="the main job: paths, gantry stations, ordering, nine-axis kinematics -> OUTDIR/plan.json",
        description="Plan a whole spray program: load -> region -> paths (or target points) -> stations -> "
        "ordering -> kinematics. Settings: defaults, then -c FILE.toml (see examples/process.toml), then flags.",
    )
    plan_cmd.add_argument("part", nargs="?", help="mesh or point cloud file")
    plan_cmd.add_argument("-o", "--output", required=True, help="output folder (plan.json, waypoints.csv)")
    plan_cmd.add_argument("-c", "--config", help="process TOML file")
    group = plan_cmd.add_argument_group("part")
    group.add_argument("--units", choices=["mm", "cm", "m", "in"])
    group.add_argument("--up", choices=["z", "y", "x"])
    group.add_argument("--region")
    group.add_argument(
        "--mask",
        action="append",
        metavar="REGION",
        help="leave this region unpainted (masked), in mm in the part frame as --region's expressions; repeat "
        "for more; the part inside stays an obstacle and the film is judged on the rest",
    )
    group = plan_cmd.add_argument_group("plan")
    group.add_argument(
        "--robot",
        help="gantry-ur5 (default) or gantry-ur5e: seed 000's gantry and its arm; or one fixed-base arm (ur5, "
        "ur5e, r5150, an industrial arm of `sprayplan robots`, a robot .toml) with the part in its base frame",
    )
    group.add_argument(
        "--cell",
        help="plan a whole body in a cell of several robots: line3, sides2 (`sprayplan cells`) or a cell .toml "
        "(docs/cells.md); writes cell_plan.json instead of plan.json",
    )
    group.add_argument(
        "--ruled",
        metavar="SURFACE.toml",
        help="instead of a part: the passes over a ruled surface (seed 001; examples/ruled/), with --robot",
    )
    group.add_argument(
        "--seams",
        choices=["feather", "overlap"],
        help="with --cell: strokes stop where the surface goes on as another robot's or area's (feather, the "
        "default), or run on over it by their lead-out (overlap)",
    )
    group.add_argument(
        "--robot-file",
        help='a robot TOML for the arm on the gantry ([kinematics] robot_file: e.g. preset = "ur5" and its '
        "joint limits max_velocity_deg_s, max_acceleration_deg_s2)",
    )
    group.add_argument("--seed", type=int, help="random seed of the station cover and the tours (default 0)")
    group.add_argument(
        "--mode", choices=["paths", "points"], help="slicing strokes (default) or the seed's target points"
    )
    group.add_argument("--tour", choices=["auto", "ga", "exact", "keep"], help="ordering inside a station")
    group.add_argument("--direction", help="slicing direction (auto, x, y, z, 'dx,dy,dz')")
    group.add_argument("--spacing-mm", type=float)
    group.add_argument("--spray-radius-mm", type=float)
    group.add_argument("--overlap", type=float)
    group.add_argument("--standoff-mm", type=float)
    group.add_argument("--step-mm", type=float)
    _add_edge_options(group)
    group.add_argument(
        "--speed-along",
        choices=["surface", "tcp"],
        help="the gun speed is the paint's contact point's (default; the tip's speed varies per waypoint) "
        "or the gun tip's",
    )
    group = plan_cmd.add_argument_group("coating")
    group.add_argument(
        "--simulate", action="store_true", help="predict the film: thickness.ply, thickness.csv, coating.json"
    )
    group.add_argument(
        "--thickness-um", type=float, help="film target: choose spacing and gun speed to meet it (implies --simulate)"
    )
    group.add_argument("--tolerance-um", type=float, help="film spec: target +- this (default 5)")
    group.add_argument(
        "--no-tune-speed",
        action="store_true",
        help="with a target, keep the planned speeds (default: tune a time factor per waypoint to the film)",
    )
    group.add_argument("--process", help="spray process preset (seed000_circle, seed000_flat, bell003) or .toml")
    group.add_argument("--samples", type=int, help="also report the film at this many random points (seed 003: 420)")
    _add_view_options(plan_cmd.add_argument_group("pictures"))
    group = plan_cmd.add_argument_group("robot programs")
    group.add_argument(
        "--program", action="append", type=program_format, metavar="FORMAT",
        help="also write OUTDIR/programs/FORMAT/: urscript, rapid or krl (repeat for several; docs/programs.md)",
    )  # fmt: skip
    group.add_argument(
        "--strict", action="store_true",
        help="a left-out spray waypoint (with --program) or a waypoint left in collision (with --collisions) is an error",
    )  # fmt: skip
    group = plan_cmd.add_argument_group("collisions")
    group.add_argument(
        "--collisions", action="store_true",
        help="check every waypoint and motion against the part, the floor and the cell, repair, flag ([collision] check)",
    )  # fmt: skip
    plan_cmd.set_defaults(func=cmd_plan)

    sim = sub.add_parser("simulate", parents=[common], help="predict the film of a planned OUTDIR (coating.json)")
    sim.add_argument("outdir", help="a folder written by 'sprayplan plan'")
    sim.add_argument("--part", help="the part file (default: the one named in plan.json)")
    sim.add_argument("--thickness-um", type=float, help="film target (default: the plan's, else 50)")
    sim.add_argument("--tolerance-um", type=float, help="film spec: target +- this (default 5)")
    sim.add_argument("--samples", type=int, help="also report the film at this many random points (seed 003: 420)")
    _add_view_options(sim.add_argument_group("pictures"))
    sim.set_defaults(func=cmd_simulate)

    view = sub.add_parser(
        "view", parents=[common], help="draw a plan folder: OUTDIR/plan.html (3D viewer) and OUTDIR/report/ (PNGs)"
    )
    view.add_argument("outdir", help="a folder written by 'sprayplan plan'")
    _add_view_options(view)
    view.set_defaults(func=cmd_view)
    add_export_parser(sub, common)
    add_batch_parser(sub, common)
    return parser


def _add_view_options(group) -> None:
    group.add_argument("--no-viewer", action="store_true", help="do not write plan.html (the 3D viewer)")
    group.add_argument("--no-report", action="store_true", help="do not write report/ (PNG pictures and report.md)")


class _Formatter(logging.Formatter):
    def format(self, record):
        level = "" if record.levelno == logging.INFO else f"{record.levelname.lower()}: "
        return f"sprayplan: {level}{record.getMessage()}"


def _setup_logging(verbose: bool, quiet: bool) -> logging.Handler:
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(_Formatter())
    root = logging.getLogger("sprayplan")
    root.addHandler(handler)
    root.setLevel(logging.ERROR if quiet else logging.INFO if verbose else logging.WARNING)
    return handler


def _log_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """``warnings.showwarning`` while the command runs: a library's warning is a log line (shown with -v)."""
    logging.getLogger("sprayplan.warnings").info("%s: %s (%s:%s)", category.__name__, message, filename, lineno)


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def _expected(exc: BaseException) -> str | None:
    """The one line of an expected failure (bad input, an OS error on a path), None for a bug."""
    if isinstance(exc, StageError) and isinstance(exc.cause, OutputError):
        return str(exc.cause)  # an output that cannot be written: named as the user gave it, not by stage
    if isinstance(exc, InputError):
        return str(exc)
    if isinstance(exc, OSError):
        from sprayplan.export.files import os_problem

        name = exc.filename if exc.filename is not None else getattr(exc, "filename2", None)
        return f"{os.fspath(name)}: {os_problem(exc)}" if name is not None else os_problem(exc)
    return None


def _terminated(signum, frame):
    raise SystemExit(128 + signum)  # unwinds like Ctrl-C: the temporary outputs are removed on the way out


def _on_sigterm():
    """While the command runs, SIGTERM ends it through the normal clean-up; returns the handler it replaced."""
    if threading.current_thread() is not threading.main_thread():
        return None
    return signal.signal(signal.SIGTERM, _terminated)


def _naming_the_option(message: str, argv: list[str] | None) -> str:
    """The message led by the option it is about, when the user gave that option on the command line.

    Errors from the library name a setting as a config key (``paths.step_mm``, ``step_mm``, ``region``); the
    user typed ``--step-mm``. The first option given whose key appears in the message as a word leads it,
    unless the message names the option already.
    """
    import re

    given = [a.split("=", 1)[0] for a in (sys.argv[1:] if argv is None else argv) if a.startswith("--")]
    for flag in given:
        if flag in message:
            return message
    for flag in given:
        key = flag[2:].replace("-", "_")
        if len(key) > 2 and re.search(rf"(?<![\w-]){re.escape(key)}(?![\w-])", message):
            return f"{flag}: {message}"
    return message


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit code (0 ok, 2 bad input, 1 an internal error, 130 interrupted).

    Every expected failure is one line on stderr, ``sprayplan: error: FILE or --option: problem``, with exit
    code 2 and no output written; a bare ``sprayplan`` prints its usage on stderr (exit code 2).
    """
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except UsageError as exc:
        print(f"sprayplan: error: {_one_line(exc)}", file=sys.stderr)
        return 2
    if not getattr(args, "func", None):
        print(parser.format_usage().rstrip(), file=sys.stderr)
        return 2
    handler = _setup_logging(args.verbose, args.quiet)
    terminate = _on_sigterm()
    reuse_freed_memory()  # large arrays from freed memory, not fresh pages (sprayplan.heap)
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _log_warning
            return args.func(args)
    except KeyboardInterrupt:
        print("sprayplan: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:
        line = _expected(exc)
        if line is not None:
            print(f"sprayplan: error: {_one_line(_naming_the_option(str(line), argv))}", file=sys.stderr)
            return 2
        if args.verbose:
            traceback.print_exception(exc, file=sys.stderr)
        where = [note[len("sprayplan: ") :] for note in getattr(exc, "__notes__", ()) if note.startswith("sprayplan: ")]
        hint = "; ".join(part for part in (*where, None if args.verbose else "run with -v for the traceback") if part)
        print(
            f"sprayplan: internal error: {type(exc).__name__}: {_one_line(exc)}" + (f" ({hint})" if hint else ""),
            file=sys.stderr,
        )
        return 1
    finally:
        logging.getLogger("sprayplan").removeHandler(handler)
        if terminate is not None:
            signal.signal(signal.SIGTERM, terminate)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
