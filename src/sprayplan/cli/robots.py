"""The robot commands of the command line: ``sprayplan fk`` and ``sprayplan ik`` (see ``cli.main``)."""

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
    from sprayplan.robots.model import load_robot

    return load_robot("ur5" if name == "gantry-ur5" else name, "--robot")


def _tool_offset(args, robot):
    """gun2flange of --tool, else the robot model's own tool."""
    from sprayplan.robots.gantry import load_gun

    return load_gun(args.tool).gun2flange if args.tool else robot.tool2flange


def cmd_fk(args) -> int:
    from sprayplan.export.tables import pose_rows
    from sprayplan.io.tables import POSE_COLUMNS, read_joints
    from sprayplan.robots.model import fk

    _check_files(args, args.joints, "joints")
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
    robot = _robot(args.robot)
    seed = None
    if args.seed_joints:
        what = "'" + ",".join(f"q{i + 1}" for i in range(robot.dof)) + "' (rad)"
        seed = np.array(parse_numbers("--seed-joints", args.seed_joints, robot.dof, what))
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
        rows = [
            [i + 1, b, *solutions.q[i, b], int(solutions.wrist_singular[i, b])]
            for i in range(len(poses))
            for b in range(8)
            if solutions.valid[i, b]
        ]
        _write_table(args.output, ["pose", "branch", *names, "wrist_singular"], rows)
        print(f"{len(rows)} solutions for {len(poses)} poses ({robot.name}) -> {args.output}")
        return 0
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
