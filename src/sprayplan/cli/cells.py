"""The cell commands of the command line: ``sprayplan cells`` and ``sprayplan areas`` (see ``cli.main``)."""

from __future__ import annotations

import math
import sys

from sprayplan.cli.common import check_outputs, file_input
from sprayplan.cli.common import stage as _stage

#: The columns of ``sprayplan areas -o FILE.csv``: one row a face of the part as loaded (a face split for the
#: areas, ``cells.plan.area_surface``: one row a piece).
AREA_COLUMNS = ["face", "area", "direction", "robot", "robot_index", "reach", "face_area_mm2"]


def cmd_cells(args) -> int:
    """List the cell presets, or describe one (a name or a cell .toml)."""
    from sprayplan.cells import list_cells, load_cell

    if args.cell is None:
        for name in list_cells():
            cell = load_cell(name)
            robots = ", ".join(f"{r.name} ({r.model})" for r in cell.robots)
            print(f"{name:12s} {len(cell.robots)} robot{'s' if len(cell.robots) > 1 else ''}: {robots}")
        print("(a cell .toml: see docs/cells.md; `sprayplan cells NAME` for details)")
        return 0
    cell = load_cell(args.cell, "cell")
    print(f"{cell.name}: {cell.description or 'a cell'}")
    print(f"  floor at z = {cell.floor_z_mm:g} mm; part aligned {cell.align}, centre at {list(cell.position_mm)} mm")
    for r in cell.robots:
        if r.is_gantry:
            print(f"  {r.name}: {r.model}, gun {r.tool} (a gantry: its stations are planned)")
            continue
        origin = ", ".join(f"{v:g}" for v in r.base2cell[:3, 3])
        track = ""
        if r.track is not None:
            axis = ", ".join(f"{v:g}" for v in r.track.axis)
            lo, hi = r.track.range_mm
            track = f", track along ({axis}) {lo:g} .. {hi:g} mm at {r.track.speed_mm_s:g} mm/s"
        if r.lift is not None:
            lo, hi = r.lift.range_mm
            track += f", lift {r.lift.above_part_mm:g} mm over the part's top within z {lo:g} .. {hi:g} mm"
        print(f"  {r.name}: {r.model}, gun {r.tool}, base at ({origin}) mm, reach {r.reach_mm:.0f} mm{track}")
    return 0


def cmd_areas(args) -> int:
    """Split a part's surface into areas and give each to a robot of the cell (surface.areas)."""
    import numpy as np

    from sprayplan.cells import load_cell, place_part
    from sprayplan.cells.plan import area_surface
    from sprayplan.cells.reach import reach_matrix, reach_tilts
    from sprayplan.config import CollisionConfig
    from sprayplan.errors import ConfigError
    from sprayplan.export.files import staged_files
    from sprayplan.export.tables import write_table
    from sprayplan.io.load import load_part
    from sprayplan.surface.areas import assign_areas, segment_areas
    from sprayplan.surface.normals import oriented_part
    from sprayplan.surface.region import covered_faces, not_floor_facing, painted_surface

    check_outputs([(args.output, "-o")], [(args.part, "part"), (file_input(args.cell), "--cell")])
    if not (math.isfinite(args.standoff_mm) and args.standoff_mm >= 0):
        raise ConfigError(f"--standoff-mm: must be a number >= 0, got {args.standoff_mm}")
    if not (0.0 <= args.floor_facing_deg <= 90.0):
        raise ConfigError(f"--floor-facing-deg: must be in [0, 90], got {args.floor_facing_deg}")
    if not (0.0 <= args.min_share < 1.0):
        raise ConfigError(f"--min-share: must be in [0, 1), got {args.min_share}")
    tilt_deg = CollisionConfig().piece_tilt_deg if args.piece_tilt_deg is None else args.piece_tilt_deg
    if not (0.0 <= tilt_deg <= 60.0):
        raise ConfigError(f"--piece-tilt-deg: must be in [0, 60], got {args.piece_tilt_deg}")
    cell = load_cell(args.cell)
    with _stage("load"):
        part = load_part(args.part, units=args.units, up=args.up)
    if not part.is_mesh:
        raise ConfigError(f"{args.part}: areas are found on meshes only (this is a point cloud)")
    with _stage("place"):
        placed = place_part(part, cell)
        cell = placed.cell  # its lifts at their heights over this part
        placed = oriented_part(placed.part)  # as plan_cell orients it
        # the surface plan_cell paints (default [collision] settings but the floor's angle), and which faces
        # of the part as loaded it keeps
        surface = CollisionConfig(floor_facing_deg=args.floor_facing_deg)
        painted, _ = painted_surface(placed, surface)
        kept = not_floor_facing(placed, args.floor_facing_deg) & ~covered_faces(placed, surface.covered_mm)
        parent = np.arange(len(painted.faces))
        if len(cell.robots) > 1:  # its long faces split, as plan_cell splits them
            painted, parent = area_surface(painted)
    with _stage("areas"):
        areas = segment_areas(painted, min_share=args.min_share)
    arms = None
    if args.collisions:
        from sprayplan.cells.collide import cell_arms
        from sprayplan.collision.arms import arm_radii

        for r in cell.robots:
            arm_radii(r.model)
        with _stage("collision model"):
            arms = cell_arms(cell, placed, CollisionConfig(check=True))  # the whole body, as plan_cell
    with _stage("reach"):
        tilts = () if arms is None else reach_tilts(tilt_deg)  # as plan_cell tries them
        reach = reach_matrix(cell, painted, areas.face_normals, args.standoff_mm, arms=arms, tilts_deg=tilts)
        assigned = assign_areas(areas, painted.face_areas, reach)
    names = [r.name for r in cell.robots]
    index = np.flatnonzero(kept)[parent]
    fa = painted.face_areas
    rows = []
    for j, f in enumerate(index):
        k, r = int(areas.face_area[j]), int(assigned.face_robot[j])
        best = float(reach[r, j]) if r >= 0 else 0.0
        rows.append(
            [
                int(f),
                areas.names[k],
                areas.direction[k],
                names[r] if r >= 0 else "",
                r,
                round(best, 4),
                round(float(fa[j]), 3),
            ]
        )
    with staged_files([args.output]) as (temp,):
        write_table(temp, AREA_COLUMNS, rows)
    for k, name in enumerate(areas.names):
        r = int(assigned.area_robot[k])
        who = names[r] if r >= 0 else "no robot"
        split = " (split: part to another robot)" if assigned.split[k] else ""
        print(
            f"  {name:12s} {areas.area_mm2[k] / 1e6:7.3f} m^2 -> {who}, reaches {100 * assigned.area_share[k]:.1f} %{split}"
        )
    per_robot = ", ".join(f"{n} {a / 1e6:.2f} m^2" for n, a in zip(names, assigned.robot_area_mm2))
    left_out = len(placed.faces) - int(kept.sum())
    print(
        f"{len(areas)} areas of {painted.area / 1e6:.2f} m^2 on {cell.name}: {per_robot}; unreached "
        f"{assigned.unreached_mm2 / 1e6:.3f} m^2; {left_out} floor-facing or covered faces left out -> {args.output}"
    )
    return 0


def add_parsers(sub, common, add_load_options) -> None:
    """The ``cells`` and ``areas`` subcommands."""
    cells = sub.add_parser("cells", parents=[common], help="list the cell presets, or describe one (docs/cells.md)")
    cells.add_argument("cell", nargs="?", help="a cell preset's name or a cell .toml file")
    cells.set_defaults(func=cmd_cells)
    areas = sub.add_parser(
        "areas",
        parents=[common],
        help="split a part into areas of one surface direction and give each to a robot of a cell -> CSV",
        description="Automatic areas (seed 003, section 5): the part placed in the cell, its surface split into "
        "patches of one direction (islands merged), each patch given to the robot that reaches it best, split "
        "where none reaches it whole. Writes one row a face (a face longer than 200 mm split as the plan splits "
        "it, one row a piece): its area, direction and robot.",
    )
    areas.add_argument("part", help="a mesh file")
    areas.add_argument("-o", "--output", required=True, help="the CSV to write")
    areas.add_argument("--cell", default="line3", help="a cell preset (`sprayplan cells`) or a cell .toml")
    areas.add_argument("--standoff-mm", type=float, default=113.0, help="the gun's standoff (default 113)")
    areas.add_argument("--min-share", type=float, default=0.03, help="patches under this share are islands")
    areas.add_argument(
        "--floor-facing-deg",
        type=float,
        default=45.0,
        help="leave out surface facing more than this below the horizontal (default 45)",
    )
    areas.add_argument(
        "--collisions",
        action="store_true",
        help="count a face as reached only where a try of the robot is free of the part and the floor "
        "(the default [collision] settings; the industrial arms only)",
    )
    areas.add_argument(
        "--piece-tilt-deg",
        type=float,
        default=None,
        help="with --collisions: a face no try along its normal reaches free is tried with the gun tilted by up "
        "to this much, as the plan does (0-60; default [collision] piece_tilt_deg, 40)",
    )
    add_load_options(areas)
    areas.set_defaults(func=cmd_areas)


#: ``plan --cell`` options that belong to the gantry's plan and have no meaning in a cell of arms.
GANTRY_ONLY = ("robot", "robot_file", "mode", "tour")


def cmd_plan_robot(args, job_config) -> int:
    """``sprayplan plan PART --robot ur5 -o OUT``: a part painted by one fixed-base arm (``ur5``, ``ur5e``,
    ``r5150``, an industrial arm or a robot .toml) whose base frame is the part file's frame: a cell of one
    robot (:func:`sprayplan.cells.spec.single_robot_cell`), planned and written as ``plan --cell``."""
    from sprayplan.cells.spec import single_robot_cell
    from sprayplan.errors import ConfigError

    if getattr(args, "cell", None) is not None:
        raise ConfigError("--robot: give either --robot (one fixed-base arm) or --cell, not both")
    cell = single_robot_cell(args.robot)
    args.robot = None
    if getattr(args, "ruled", None) is not None:
        return _plan_ruled(args, cell)
    return cmd_plan_cell(args, job_config(args), cell)


def _plan_ruled(args, cell) -> int:
    """``plan --ruled SURFACE.toml --robot NAME``: the ruled surface's passes (``paths.ruled``) solved by the
    robot; cell_plan.json and waypoints.csv (joints at every waypoint: seed 001's tables 4 and 5)."""
    import os

    from sprayplan.cells.files import CELL_FILES, write_cell_plan
    from sprayplan.cells.plan import plan_strokes
    from sprayplan.cli.common import check_folder_outputs
    from sprayplan.errors import ConfigError, PartFileError
    from sprayplan.export.files import staged_folder
    from sprayplan.paths.ruled import ruled_paths
    from sprayplan.paths.ruled_toml import load_ruled

    check_folder_outputs(args.output, CELL_FILES, "-o", [(args.ruled, "--ruled"), (args.config, "-c")])
    job = load_ruled(args.ruled)
    try:
        paths = ruled_paths(job)
    except ConfigError as exc:
        raise PartFileError(args.ruled, str(exc)) from None
    plan = plan_strokes(paths.strokes, cell, job.name)
    with staged_folder(args.output, CELL_FILES) as folder:
        write_cell_plan(folder, plan)
    (work,) = plan.robots
    reached = int(work.reachable.sum())
    print(
        f"{job.name}: {sum(1 for s in work.strokes if s.spray_on)} passes, {work.waypoints} waypoints, {reached} "
        f"reached by {work.name} -> {os.path.join(args.output, 'waypoints.csv')}"
    )
    return 0


def cmd_plan_cell(args, job, cell=None) -> int:
    """``sprayplan plan PART --cell NAME -o OUT``: a whole body painted by the robots of a cell
    (:func:`sprayplan.cells.plan.plan_cell`), written all or nothing into OUT (``cells.files``); ``cell`` one
    given already (``--robot``)."""
    import os

    from sprayplan.cells import load_cell
    from sprayplan.cells.files import CELL_FILES, write_cell_plan
    from sprayplan.cells.plan import plan_cell
    from sprayplan.cli.common import check_folder_outputs
    from sprayplan.errors import ConfigError
    from sprayplan.export.files import staged_folder
    from sprayplan.io.load import load_part

    for name in GANTRY_ONLY:
        value = getattr(args, name, None)
        if value not in (None, False, []):
            raise ConfigError(f"--{name.replace('_', '-')}: not available with --cell (a cell of arms is planned)")
    cell = load_cell(args.cell) if cell is None else cell
    if cell.is_gantry:
        raise ConfigError(f"--cell {cell.name}: the gantry cell is planned without --cell")
    formats = tuple(job.export.programs)
    if formats:
        _programs_possible(cell, formats)
    inputs = [(args.part, "part"), (args.config, "-c"), (file_input(getattr(args, "cell", None)), "--cell")]
    outputs = CELL_FILES + (("programs",) if formats else ())
    check_folder_outputs(args.output, outputs, "-o", inputs)
    with _stage("load"):
        part = load_part(args.part, units=job.load.units, up=job.load.up)
    if job.load.region is not None:
        raise ConfigError("--region: not available with --cell (the areas split the whole body)")
    from sprayplan.cli.common import ProgressDisplay

    display = ProgressDisplay(quiet=getattr(args, "quiet", False))
    try:
        plan = plan_cell(part, cell, job, progress=display, seams=args.seams or "feather")
    except BaseException:
        display.close(finished=False)
        raise
    display.close()
    target = job.coating.thickness_um if job.coating.thickness_um is not None else 50.0
    programs = []
    if formats:
        from sprayplan.programs.arms import build_cell_programs, write_cell_programs

        with _stage("programs"):
            programs = build_cell_programs(plan, plan.job or job, formats)  # every refusal before any writing
    summaries = []
    with staged_folder(args.output, outputs) as folder:
        write_cell_plan(folder, plan, target, job.coating.tolerance_um)
        if programs:
            summaries = write_cell_programs(os.path.join(folder, "programs"), programs, plan.job or job)
    for robot in programs:
        for built in robot.builts:
            from sprayplan.programs.stage import warnings_of

            for warning in warnings_of(built):
                print(f"sprayplan: {robot.robot}: {warning}", file=sys.stderr)
    from sprayplan.view.summary import open_surface, out_of_spec_causes

    report = plan.report
    robots = ", ".join(
        f"{name} {r['strokes']} strokes {r['waypoints']} waypoints ({r['unreached_waypoints']} unreached) "
        f"{r['cycle_time_s']:.0f} s"
        for name, r in report["robots"].items()
    )
    line = f"{cell.name}: {report['areas']} areas; {robots}; cycle {report['cycle_time_s']:.0f} s"
    if report.get("masked_left_out_mm2"):
        line += f"; surface masked (--mask) left out: {report['masked_left_out_mm2'] / 1e6:.4g} m2"
    film = report.get("film")
    if film:
        whole = film["whole"]
        line += (
            f"; film mean {whole['mean_um']:.1f} um, {100 * whole['share_in_spec']:.1f} % in spec{open_surface(film)}"
            f" ({film['report'].get('measuring_points', {}).get('count', 0)} measuring points:"
            f" {100 * film['report'].get('measuring_points', {}).get('share_in_spec', 0.0):.1f} % in spec)"
        )
        timed = film.get("at_timed_speeds")
        if timed:
            line += f"; at the robots' timed speeds {100 * timed['whole']['share_in_spec']:.1f} % in spec"
        fit = report.get("flow_fit")
        if fit:
            line += f" (flow fitted: {fit['flow_ml_min']:g} mL/min, {fit['gun_speed_mm_s']:.0f} mm/s)"
        if out_of_spec_causes(film):  # on a line of its own, after the film's figures
            line += f"\n{out_of_spec_causes(film)}"
    hits = report.get("collisions")
    if hits:
        gaps = ", ".join(f"{k} {'-' if v is None else f'{v:g} mm'}" for k, v in hits["robot_gap_mm"].items())
        line += (
            f"\ncollisions: {hits['waypoints_in_collision']} waypoints and {hits['motions_in_collision']} motions in "
            f"collision (clearance {hits['clearance_mm']:g} mm); robots kept apart {hits['robots_kept_apart']}"
            f" (least gaps of the swept spaces {gaps})"
        )
    schedule = report.get("schedule")
    if schedule:
        waits = ", ".join(f"{k} {v['waited_s']:g} s" for k, v in schedule["waits"].items())
        gaps = ", ".join(f"{k} {'-' if v is None else f'{v:g} mm'}" for k, v in schedule["least_gap_mm"].items())
        line += f"; schedule: waits {waits}, least gaps in time {gaps}"
    for data in summaries:
        motions = data["counts"].get("program_motions")
        checked = (
            f", {motions['motions_in_collision']} of {motions['motions_checked']} joint moves, approaches, "
            "retracts, run-ups and run-outs in collision"
            if motions
            else ""
        )
        print(
            f"{data['robot']} {data['program_format']}: {len(data['files'])} files, {data['moves']} moves{checked} -> "
            f"{os.path.join(args.output, 'programs', data['robot'], data['program_format'])}"
        )
    print(f"{line} -> {os.path.join(args.output, 'cell_plan.json')}")
    return 0


def _programs_possible(cell, formats) -> None:
    """Every robot of ``cell`` can have each of ``formats`` (six axes; its maker's format,
    ``programs.arms.format_refusal``): checked before the plan, so that a refusal costs no planning time."""
    from sprayplan.errors import ConfigError
    from sprayplan.programs.arms import format_refusal
    from sprayplan.robots.interface import robot_from_name

    for r in cell.robots:
        for fmt in formats:
            why = format_refusal(r.name, r.model, fmt)
            if why:
                raise ConfigError(f"--program {fmt}: {why}")
        dof = robot_from_name(r.model, None).dof
        if dof != 6:
            raise ConfigError(
                f"--program: robot {r.name} ({r.model}) has {dof} axes; RAPID and KRL programs are written for "
                "six-axis arms"
            )
