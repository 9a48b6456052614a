"""The robot commands of the command line: ``sprayplan robots``, ``fk`` and ``ik`` (see ``cli.main``)."""

from __future__ import annotations

from sprayplan.cli.common import check_outputs, file_input, parse_numbers
from sprayplan.cli.common import stage as _stage
from sprayplan.errors import ConfigError


def _check_files(args, source: str, label: str) -> None:
    """Before anything runs: ``-o`` can be written and is none of the inputs."""
    inputs = [(source, label), (file_input(args.robot), "--robot"), (file_input(args.tool), "--tool")]
    check_outputs([(args.output, "-o")], inputs)


def _write_table(path, header, rows) -> None:
    from sprayplan.export.files import staged_files
    from sprayplan.export.tables import write_table

    with staged_files([path]) as (temp,):
        write_table(temp, header, rows)


def _robot(name: str):
    from sprayplan.robots.model import PRESETS, load_robot
    from sprayplan.robots.opw import PRESETS as OPW_PRESETS

    if name not in PRESETS and name != "gantry-ur5" and not name.lower().endswith(".toml"):
        known = ", ".join([*PRESETS, "gantry-ur5", *OPW_PRESETS])
        raise ConfigError(f"--robot {name!r} is not a known robot: use one of {known} or a robot .toml file")
    return load_robot("ur5" if name == "gantry-ur5" else name, "--robot")


def _tool_offset(args, robot):
    """gun2flange of --tool, else the robot model's own tool."""
    from sprayplan.robots.gantry import load_gun

    return load_gun(args.tool).gun2flange if args.tool else robot.tool2flange


def _opw_arm(args):
    """The OPW arm ``--robot`` names (a preset or a ``kind = "opw"`` TOML file) with ``--tool``, else None."""
    from sprayplan.robots.interface import robot_from_name
    from sprayplan.robots.opw import PRESETS, is_opw_file

    if args.robot in PRESETS or is_opw_file(args.robot):
        return robot_from_name(args.robot, args.tool)
    return None


def cmd_robots(args) -> int:
    """List the robot presets, or describe one robot (a preset name or an OPW arm's TOML file)."""
    import math

    from sprayplan.robots.interface import ROBOT_NAMES
    from sprayplan.robots.opw import LENGTHS, PRESETS, is_opw_file, load_opw

    if args.robot is None:
        kinds = {"r5150": "5 axes, D-H (seed 001)", "gantry-ur5": "9 axes, gantry + UR5 (seed 000)"}
        kinds["gantry-ur5e"] = "9 axes, gantry + UR5e"
        for name in ROBOT_NAMES:
            if name in PRESETS:
                params = load_opw(name)
                kind = f"6 axes, OPW industrial arm, wrist centre up to {params.reach_mm:.0f} mm from axis 2"
            else:
                kind = kinds.get(name, "6 axes, UR-type D-H")
            print(f"{name:20s} {kind}")
        print('(a robot .toml: a D-H table, or an OPW arm with kind = "opw"; `sprayplan robots NAME` for details)')
        return 0
    if args.robot not in ROBOT_NAMES and not args.robot.lower().endswith(".toml"):
        raise ConfigError(f"robot {args.robot!r} is not known: use one of {', '.join(ROBOT_NAMES)} or a robot .toml")
    if args.robot not in PRESETS and not is_opw_file(args.robot):
        return _describe_dh(args.robot)
    params = load_opw(args.robot, "robot")
    print(f"{params.name}: OPW arm (6 axes, spherical wrist)")
    print("  " + ", ".join(f"{key} {getattr(params, key):g} mm" for key in LENGTHS))
    rows = [
        ("offsets (deg)", [math.degrees(v) for v in params.offsets]),
        ("signs", list(params.signs)),
        ("lower (deg)", [math.degrees(v) for v in params.lower]),
        ("upper (deg)", [math.degrees(v) for v in params.upper]),
        ("max speed (deg/s)", [math.degrees(v) for v in params.max_speed]),
    ]
    for label, values in rows:
        shown = ", ".join("not published" if math.isnan(v) else f"{v:g}" for v in values)
        print(f"  {label:18s} {shown}")
    print(f"  source: {params.source}")
    return 0


def _describe_dh(name: str) -> int:
    """Print a D-H robot's table (a preset or a D-H .toml; a gantry's arm)."""
    import numpy as np

    from sprayplan.robots.model import load_robot

    model = load_robot(name.removeprefix("gantry-"), "robot")
    print(
        f"{name}: standard D-H table, {model.dof} axes" + (" (the gantry's arm)" if name.startswith("gantry-") else "")
    )
    for label, values in (
        ("d (mm)", model.d),
        ("a (mm)", model.a),
        ("alpha (deg)", np.degrees(model.alpha)),
        ("lower (deg)", np.degrees(model.lower)),
        ("upper (deg)", np.degrees(model.upper)),
    ):
        print(f"  {label:12s} " + ", ".join(f"{v:g}" for v in values))
    return 0


def _fk_opw(args, arm) -> int:
    from sprayplan.export.tables import pose_rows
    from sprayplan.io.tables import POSE_COLUMNS, read_joints

    q = read_joints(args.joints, 6)
    poses = arm.fk(q)
    _write_table(args.output, POSE_COLUMNS[args.pose_format], pose_rows(poses, args.pose_format).tolist())
    print(f"{len(q)} poses of the {'tool ' + args.tool if args.tool else 'flange'} ({arm.name}) -> {args.output}")
    return 0


def _write_all(args, robot_name: str, q, valid, singular, singular_column: str) -> int:
    """``ik --all``: one row per valid solution, columns pose, branch, q1..q6 and the singular flag."""
    n, k, dof = q.shape
    rows = [[i + 1, b, *q[i, b], int(singular[i, b])] for i in range(n) for b in range(k) if valid[i, b]]
    _write_table(args.output, ["pose", "branch", *(f"q{j + 1}" for j in range(dof)), singular_column], rows)
    print(f"{len(rows)} solutions for {n} poses ({robot_name}) -> {args.output}")
    return 0


def _ik_opw(args, arm, poses, seed) -> int:
    from sprayplan.robots.interface import follow_solutions

    sols = arm.ik(poses)
    names = [f"q{i + 1}" for i in range(6)]
    if args.all:
        return _write_all(args, arm.name, sols.q, sols.valid, sols.singular, "singular")
    q, branch = follow_solutions(arm, sols, seed)
    reasons = sols.pose_reason()
    rows = [
        [*(q[i] if branch[i] >= 0 else [None] * 6), int(branch[i] >= 0), int(branch[i]), reasons[i]]
        for i in range(len(poses))
    ]
    _write_table(args.output, [*names, "reachable", "branch", "reason"], rows)
    print(f"{int((branch >= 0).sum())} of {len(poses)} poses reachable ({arm.name}) -> {args.output}")
    return 0


def cmd_fk(args) -> int:
    from sprayplan.export.tables import pose_rows
    from sprayplan.io.tables import POSE_COLUMNS, read_joints
    from sprayplan.robots.model import fk

    _check_files(args, args.joints, "joints")
    arm = _opw_arm(args)
    if arm is not None:
        return _fk_opw(args, arm)
    robot = _robot(args.robot)
    q = read_joints(args.joints, robot.dof)
    poses = robot.base2world @ fk(robot, q) @ _tool_offset(args, robot)
    _write_table(args.output, POSE_COLUMNS[args.pose_format], pose_rows(poses, args.pose_format).tolist())
    print(f"{len(q)} poses of the {'tool ' + args.tool if args.tool else 'flange'} ({robot.name}) -> {args.output}")
    return 0


def _r5150_ik(robot, poses):
    """Position, pitch and roll of the R5150 from full poses; the 5-DOF arm reaches only some orientations."""
    import numpy as np

    from sprayplan.robots.gantry import pose_errors
    from sprayplan.robots.model import fk
    from sprayplan.robots.r5150 import r5150_ik

    theta1 = np.arctan2(poses[:, 1, 3], poses[:, 0, 3])
    c, s = np.cos(theta1), np.sin(theta1)
    # R = Rz(theta1) Rx(pi/2) Rz(pitch) Rx(pi/2) Rz(roll): undo the first two to read pitch and roll
    first = np.zeros((len(poses), 3, 3))
    first[:, 0, 0], first[:, 0, 2] = c, s
    first[:, 1, 0], first[:, 1, 2] = s, -c
    first[:, 2, 1] = 1.0
    rest = first.transpose(0, 2, 1) @ poses[:, :3, :3]
    pitch = np.arctan2(rest[:, 0, 2], -rest[:, 1, 2])
    roll = np.arctan2(rest[:, 2, 0], rest[:, 2, 1])
    solution = r5150_ik(poses[:, :3, 3], pitch, roll, elbow="auto", model=robot)
    reached = fk(robot, solution.q)
    position, _axis = pose_errors(reached, poses)
    angle = np.arccos(np.clip((np.einsum("nij,nij->n", reached[:, :3, :3], poses[:, :3, :3]) - 1) / 2, -1, 1))
    ok = solution.reachable & (position < 1e-6) & (angle < 1e-6)
    reason = np.where(solution.reachable & ~ok, "orientation not reachable by 5 axes", solution.reason)
    return solution.q, ok, reason


def cmd_ik(args) -> int:
    import numpy as np

    from sprayplan.io.tables import read_poses

    _check_files(args, args.poses, "poses")
    platform = None
    if args.platform and args.platform != "auto":
        platform = np.array(parse_numbers("--platform", args.platform, 3, "'x,y,z' (mm) or auto"))
    if args.robot == "gantry-ur5":
        return _ik_gantry(args, platform)
    arm = _opw_arm(args)
    robot = arm if arm is not None else _robot(args.robot)
    seed = None
    if args.seed_joints:
        what = "'" + ",".join(f"q{i + 1}" for i in range(robot.dof)) + "' (rad)"
        seed = np.array(parse_numbers("--seed-joints", args.seed_joints, robot.dof, what))
    if arm is not None:
        return _ik_opw(args, arm, read_poses(args.poses, args.pose_format), seed)
    poses = np.linalg.inv(robot.base2world) @ read_poses(args.poses, args.pose_format)
    poses = poses @ np.linalg.inv(_tool_offset(args, robot))
    names = [f"q{i + 1}" for i in range(robot.dof)]
    if robot.name == "r5150":
        q, ok, reason = _r5150_ik(robot, poses)
        rows = [[*(q[i] if ok[i] else [None] * 5), int(ok[i]), reason[i]] for i in range(len(q))]
        _write_table(args.output, [*names, "reachable", "reason"], rows)
        print(f"{int(ok.sum())} of {len(q)} poses reachable ({robot.name}) -> {args.output}")
        return 0
    from sprayplan.robots.ur_ik import ik_path, ur_ik

    if args.all:
        solutions = ur_ik(robot, poses)
        return _write_all(args, robot.name, solutions.q, solutions.valid, solutions.wrist_singular, "wrist_singular")
    path = ik_path(robot, poses, seed_q=seed)
    rows = [
        [
            *(path.q[i] if path.reachable[i] else [None] * 6),
            int(path.reachable[i]),
            int(path.branch[i]),
            int(path.branch_change[i]),
            int(path.jump[i]),
        ]
        for i in range(len(poses))
    ]
    _write_table(args.output, [*names, "reachable", "branch", "branch_change", "jump"], rows)
    print(
        f"{int(path.reachable.sum())} of {len(poses)} poses reachable, {int(path.branch_change.sum())} branch "
        f"changes, {int(path.jump.sum())} jumps ({robot.name}) -> {args.output}"
    )
    return 0


def _ik_gantry(args, fixed) -> int:
    import numpy as np

    from sprayplan.export.paths_json import read_paths_json
    from sprayplan.robots.gantry import build_gantry, solve_gantry_path
    from sprayplan.surface.poses import stroke_poses

    gantry = build_gantry("ur5", args.tool or "wa101")
    paths = read_paths_json(args.poses)
    if not any(stroke.spray_on for stroke in paths.strokes):
        raise ConfigError(f"{args.poses}: no spray strokes to solve")
    gun2world, platform, labels = [], [], []
    platforms = []
    for stroke in paths.strokes:
        flange = (stroke_poses(stroke) @ np.linalg.inv(gantry.gun.gun2flange))[:, :3, 3]
        platforms.append(fixed if fixed is not None else gantry.platform_for(flange) if stroke.spray_on else None)
    for k, stroke in enumerate(paths.strokes):
        gun2world.append(stroke_poses(stroke))
        if platforms[k] is None:  # a transfer: its first half from the stroke before, the rest from the next
            before = platforms[k - 1] if k > 0 else platforms[k + 1]
            after = platforms[k + 1] if k + 1 < len(platforms) else before
            half = len(stroke) // 2
            platform.append(
                np.vstack([np.repeat(before[None], half, 0), np.repeat(after[None], len(stroke) - half, 0)])
            )
        else:
            platform.append(np.repeat(platforms[k][None], len(stroke), axis=0))
        labels += [(k, i, stroke.spray_on) for i in range(len(stroke))]
    with _stage("kinematics"):
        result = solve_gantry_path(gantry, np.concatenate(gun2world), np.concatenate(platform))
    header = [
        "stroke",
        "waypoint",
        "spray_on",
        "q1",
        "q2",
        "q3",
        "q4",
        "q5",
        "q6",
        "tx",
        "ty",
        "tz",
        "reachable",
        "method",
        "region",
        "position_error_mm",
        "axis_error_deg",
        "branch_change",
        "jump",
    ]
    rows = []
    for j, (k, i, on) in enumerate(labels):
        joints = list(result.q9[j]) if result.reachable[j] else [None] * 9
        rows.append(
            [
                k,
                i,
                int(on),
                *joints,
                int(result.reachable[j]),
                result.method[j],
                int(result.region[j]),
                None if not result.reachable[j] else result.position_error_mm[j],
                None if not result.reachable[j] else result.axis_error_deg[j],
                int(result.branch_change[j]),
                int(result.jump[j]),
            ]
        )
    _write_table(args.output, header, rows)
    ok = result.reachable
    worst = np.nanmax(result.position_error_mm) if ok.any() else float("nan")
    print(
        f"{int(ok.sum())} of {len(ok)} waypoints reachable ({int((result.method == 'sqp').sum())} by SQP), "
        f"max position error {worst:.3g} mm, {int(result.branch_change.sum())} branch changes -> {args.output}"
    )
    return 0
