"""ABB RAPID: a main module calling part modules of at most ``[export] rapid_max_lines`` lines, and a strict
reader of them.

Every linear target is an inline ``robtarget`` in the work object (mm; quaternion scalar first; configuration
data ``[cf1, cf4, cf6, cfx]`` from the plan's joints; the gantry in ``eax_a..eax_c`` in mm, ``9E+09`` for the
unused axes), with inline ``speeddata`` (TCP mm/s) and ``zonedata`` (``fine`` at a run's ends). Joint moves are
``MoveAbsJ`` to joint values in degrees. The gun: ``TriggIO`` (distance before the target, mm) on ``TriggL``; or,
with ``rapid_paint``, RobotWare Paint's ``SetBrush`` events (a coordinate of the work object) before ``PaintL``.
No ``%%%`` header is written. Layout and conventions: docs/programs.md.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from sprayplan import __version__
from sprayplan.programs.model import (
    JOINT,
    LINEAR,
    ProgramError,
    ReadMove,
    ReadProgram,
    fixed,
    fixed_down,
    matrix_from_wxyz,
    parse_number,
    quaternion_wxyz,
)
from sprayplan.programs.text import aggregate, chunks, numbers, program_lines, split_arguments

UNUSED = "9E+09"
SUFFIX = ".mod"
IND = "  "
#: The triggdata a move may use (a TriggL takes up to eight).
TRIGGERS = ("trGun1", "trGun2")
#: v_ori (deg/s), v_leax (mm/s), v_reax (deg/s) of the linear moves' speeddata (the values of RAPID's v100..).
LINEAR_SPEED_REST = ("500", "5000", "1000")


def _pos(values) -> str:
    return ",".join(fixed(v, 4) for v in values)


def _quat(matrix) -> str:
    return ",".join(fixed(v, 9) for v in quaternion_wxyz(matrix))


def _extax(external_mm) -> str:
    """eax_a..eax_f: the external axes in use (mm), the rest ``9E+09``."""
    return ",".join([fixed(v, 4) for v in external_mm] + [UNUSED] * (6 - len(external_mm)))


def robtarget(move, config, quaternion: str | None = None) -> str:
    """A robtarget literal; ``quaternion``: the orientation's text when already computed (:func:`_quaternions`)."""
    cf = ",".join(str(int(c)) for c in config)
    q = _quat(move.pose[:3, :3]) if quaternion is None else quaternion
    return f"[[{_pos(move.pose[:3, 3])}],[{q}],[{cf}],[{_extax(move.external_mm)}]]"


def _quaternions(moves) -> dict:
    """``id(move)`` -> the quaternion text of every linear move, computed at once."""
    linear = [m for m in moves if m.kind == LINEAR]
    if not linear:
        return {}
    q = quaternion_wxyz(np.array([m.pose[:3, :3] for m in linear]))
    return {id(m): ",".join(fixed(v, 9) for v in row) for m, row in zip(linear, q)}


def _zone(blend_mm: float) -> str:
    if blend_mm <= 0:
        return "fine"
    r, ori = fixed_down(blend_mm, 4), fixed_down(blend_mm / 10.0, 4)
    if float(r) == 0:
        return "fine"
    return f"[FALSE,{r},{r},{r},{ori},{r},{ori}]"


def write_rapid(cell, job, configs) -> dict[str, str]:
    """RAPID modules of a cell program: ``{file name: text}``, the main module first.

    ``configs``: per linear move (``id(move)``) its ``[cf1, cf4, cf6, cfx]`` (``programs.stage`` computes them
    for all moves at once).
    """
    cfg = job.export
    flat = cell.sequence()
    lines_of = lambda m: 1 + len(m.events) + (m.role == "home") + (m.wait_s > 0)
    parts = chunks([m for m, _ in flat], lines_of, cfg.rapid_max_lines - 12)
    notes = {id(m): note for m, note in flat if note}
    files = {}
    names = [f"{cfg.name}_{k + 1:03d}" for k in range(len(parts))]
    for name, part in zip(names, parts):
        files[name + SUFFIX] = _part_module(name, part, notes, cfg, configs)
    main = _main_module(cell, job, names)
    return {f"{cfg.name}_main{SUFFIX}": main, **files}


def _main_module(cell, job, names) -> str:
    cfg = job.export
    tool = cell.tool2flange
    cog = job_gun_position(job) if cell.gun_mm is None else cell.gun_mm
    lines = [
        f"MODULE {cfg.name}_main",
        f"{IND}! sprayplan {__version__}: spray program for {cell.name or 'the part'}, {_stations(cell)}",
        f"{IND}! mm, degrees; quaternions [w, x, y, z]; robtargets in the work object {cfg.rapid_wobj} ({cell.frame_note})",
        f"{IND}! {_axes_note(cell)}; cf1, cf4, cf6, cfx from the plan's joints (docs/programs.md)",
        f"{IND}PERS tooldata {cfg.rapid_tool} := [TRUE,[[{_pos(tool[:3, 3])}],[{_quat(tool[:3, :3])}]],"
        f"[{fixed(cfg.tool_mass_kg, 3)},[{_pos(cog)}],[1,0,0,0],0,0,0]];",
        f'{IND}PERS wobjdata {cfg.rapid_wobj} := [FALSE,TRUE,"",[[{_pos((0, 0, 0))}],[{_quat(np.eye(3))}]],'
        f"[[{_pos((0, 0, 0))}],[{_quat(np.eye(3))}]]];",
    ]
    if not cfg.rapid_paint:
        lines += [f"{IND}VAR triggdata {t};" for t in TRIGGERS]
    lines += [f"{IND}PROC main()", f"{IND * 2}ConfJ\\On;", f"{IND * 2}ConfL\\On;"]
    lines += [f"{IND * 2}SetDO {cfg.rapid_gun_signal}, 0;"] if not cfg.rapid_paint else []
    lines += [f"{IND * 2}{name};" for name in names]
    lines += [f"{IND * 2}SetDO {cfg.rapid_gun_signal}, 0;"] if not cfg.rapid_paint else []
    lines += [f"{IND}ENDPROC", "ENDMODULE", ""]
    return "\n".join(lines)


def _axes_note(cell) -> str:
    if cell.external_axes == 3:
        return "gantry in eax_a..eax_c (mm)"
    return cell.external_note


def _stations(cell) -> str:
    return f"{len(cell.stations)} station{'' if len(cell.stations) == 1 else 's'}"


def job_gun_position(job) -> np.ndarray:
    """The gun body's position on the flange (T_tool), mm: the tool load's centre of gravity."""
    from sprayplan.robots.stage import gantry_for

    return gantry_for(job.kinematics).gun.gun2flange[:3, 3]


def _part_module(name, moves, notes, cfg, configs) -> str:
    tool = f"{cfg.rapid_tool}\\WObj:={cfg.rapid_wobj}"
    body = []
    previous = None
    quaternions = _quaternions(moves)
    for move in moves:
        note = notes.get(id(move))
        if note:
            body.append(f"! {note}")
        if move.kind == JOINT:
            joints = ",".join(fixed(v, 6) for v in np.degrees(move.joints))
            speed = (f"[{fixed(cfg.transfer_speed_mm_s, 4)},{fixed(cfg.joint_speed_deg_s, 4)},"
                     f"{fixed(cfg.gantry_speed_mm_s, 4)},{fixed(cfg.joint_speed_deg_s, 4)}]")  # fmt: skip
            body.append(f"MoveAbsJ [[{joints}],[{_extax(move.external_mm)}]], {speed}, fine, {tool};")
        else:
            if move.wait_s > 0:
                body.append(f"WaitTime \\InPos, {fixed(move.wait_s, 3)};")
            target = robtarget(move, configs[id(move)], quaternions[id(move)])
            speed = f"[{fixed(move.speed_mm_s, 4)},{','.join(LINEAR_SPEED_REST)}]"
            zone = _zone(move.blend_mm)
            if cfg.rapid_paint:
                for distance, on in move.events:
                    axis, value = brush_plane(previous.pose[:3, 3], move.pose[:3, 3], distance)
                    brush = cfg.rapid_brush_on if on else cfg.rapid_brush_off
                    body.append(f"SetBrush {brush}\\{axis}:={fixed(value, 4)};")
                body.append(f"PaintL {target}, {speed}, {zone}, {tool};")
            elif move.events:
                for trig, (distance, on) in zip(TRIGGERS, move.events):
                    body.append(f"TriggIO {trig}, {fixed(distance, 4)}\\DOp:={cfg.rapid_gun_signal}, {int(on)};")
                trig = TRIGGERS[0] + "".join(
                    f"\\T{k + 1}:={t}" for k, t in enumerate(TRIGGERS[1 : len(move.events)], 1)
                )
                body.append(f"TriggL {target}, {speed}, {trig}, {zone}, {tool};")
            else:
                body.append(f"MoveL {target}, {speed}, {zone}, {tool};")
        previous = move
    lines = [f"MODULE {name}", f"{IND}PROC {name}()"] + [IND * 2 + line for line in body]
    return "\n".join(lines + [f"{IND}ENDPROC", "ENDMODULE", ""])


def brush_plane(start, end, distance_mm: float) -> tuple[str, float]:
    """The plane of a brush event ``distance_mm`` before ``end`` on the segment from ``start``: the axis along
    which the segment runs most (X, Y or Z of the work object) and the coordinate there."""
    start, end = np.asarray(start, float), np.asarray(end, float)
    direction = end - start
    axis = int(np.argmax(np.abs(direction)))
    point = end - distance_mm * direction / np.linalg.norm(direction)
    return "XYZ"[axis], float(point[axis])


# --- the reader ---------------------------------------------------------------------------------------------


def read_rapid(folder, job, external_axes: int = 3) -> ReadProgram:
    """Read a RAPID program folder written by :func:`write_rapid` back into moves, strictly: every line must be
    one the writer writes (comments aside); anything else is a :class:`ProgramError` naming the file and line.
    ``external_axes``: how many of eax_a..eax_f the robot has (the gantry 3, a track 1); the rest must be unused.
    """
    cfg = job.export
    folder = Path(folder)
    main_path = folder / f"{cfg.name}_main{SUFFIX}"
    tool, frame, calls = _read_main(main_path, cfg)
    moves: list = []
    files = [main_path.name]
    for call in calls:
        path = folder / f"{call}{SUFFIX}"
        files.append(path.name)
        moves += _read_part(path, call, cfg, external_axes)
    return ReadProgram("rapid", tool, frame, tuple(moves), (), tuple(files))


def _body(path: Path, module: str, proc: str):
    """The lines of ``MODULE module`` ... ``ENDMODULE`` (checked), split into the data lines before the PROC
    and the statements of ``PROC proc()``; comments dropped, indentation checked."""
    lines = [(n, line) for n, line in program_lines(path) if not line.strip().startswith("!")]
    if not lines or lines[0][1] != f"MODULE {module}":
        raise ProgramError(path, lines[0][0] if lines else 0, f"expected 'MODULE {module}' as the first line")
    if lines[-1][1] != "ENDMODULE":
        raise ProgramError(path, lines[-1][0], "expected 'ENDMODULE' as the last line")
    try:
        start = next(k for k, (_, line) in enumerate(lines) if line == f"{IND}PROC {proc}()")
    except StopIteration:
        raise ProgramError(path, 0, f"no 'PROC {proc}()'") from None
    if lines[-2][1] != f"{IND}ENDPROC":
        raise ProgramError(path, lines[-2][0], "expected 'ENDPROC' before 'ENDMODULE'")
    data, body = lines[1:start], lines[start + 1 : -2]
    for n, line in data:
        _indented(path, n, line, 1)
    for n, line in body:
        _indented(path, n, line, 2)
    return [(n, line.strip()) for n, line in data], [(n, line.strip()) for n, line in body]


def _indented(path, n, line, level):
    if not line.startswith(IND * level) or line[len(IND) * level] == " ":
        raise ProgramError(path, n, f"expected an indentation of {len(IND) * level} spaces")
    if line.endswith(" "):
        raise ProgramError(path, n, "trailing space")


def _read_main(path: Path, cfg):
    data, body = _body(path, f"{cfg.name}_main", "main")
    tool = frame = None
    triggers = set()
    for n, line in data:
        where = (path, n)
        if line.startswith(f"PERS tooldata {cfg.rapid_tool} := ") and line.endswith(";"):
            value = aggregate(line[len(f"PERS tooldata {cfg.rapid_tool} := ") : -1], where)
            if not (isinstance(value, list) and len(value) == 3 and value[0] is True):
                raise ProgramError(*where, "tooldata must be [TRUE, [trans, rot], load]")
            tool = _frame(value[1], where)
            load = value[2]
            if not (isinstance(load, list) and len(load) == 6 and numbers(load[0:1], (1,), "mass", where)[0] > 0):
                raise ProgramError(*where, "the tool load must be [mass > 0, cog, aom, ix, iy, iz]")
        elif line.startswith(f"PERS wobjdata {cfg.rapid_wobj} := ") and line.endswith(";"):
            value = aggregate(line[len(f"PERS wobjdata {cfg.rapid_wobj} := ") : -1], where)
            if not (isinstance(value, list) and len(value) == 5 and value[:3] == [False, True, ""]):
                raise ProgramError(*where, 'wobjdata must be [FALSE, TRUE, "", uframe, oframe]')
            frame = _frame(value[3], where) @ _frame(value[4], where)
        elif not cfg.rapid_paint and line in (f"VAR triggdata {t};" for t in TRIGGERS):
            triggers.add(line.split()[2][:-1])
        else:
            raise ProgramError(*where, f"unknown declaration: {line[:60]!r}")
    if tool is None or frame is None:
        raise ProgramError(path, 0, f"no tooldata {cfg.rapid_tool} or wobjdata {cfg.rapid_wobj}")
    if not cfg.rapid_paint and triggers != set(TRIGGERS):
        raise ProgramError(path, 0, f"missing triggdata {', '.join(sorted(set(TRIGGERS) - triggers))}")
    calls = []
    fixed_lines = {"ConfJ\\On;", "ConfL\\On;", f"SetDO {cfg.rapid_gun_signal}, 0;"}
    for n, line in body:
        if line in fixed_lines and not (cfg.rapid_paint and line.startswith("SetDO")):
            continue
        match = re.fullmatch(rf"({cfg.name}_\d{{3}});", line)
        if not match:
            raise ProgramError(path, n, f"unknown statement: {line[:60]!r}")
        calls.append(match.group(1))
    return tool, frame, calls


def _frame(value, where) -> np.ndarray:
    if not (isinstance(value, list) and len(value) == 2):
        raise ProgramError(*where, "a frame must be [[x, y, z], [q1, q2, q3, q4]]")
    out = np.eye(4)
    out[:3, 3] = numbers(value[0], (3,), "a position", where)
    out[:3, :3] = _rotation(value[1], where)
    return out


def _rotation(value, where) -> np.ndarray:
    q = numbers(value, (4,), "a quaternion", where)
    if abs(np.linalg.norm(q) - 1.0) > 1e-6:
        raise ProgramError(*where, f"quaternion {q.tolist()} is not of unit length")
    return matrix_from_wxyz(q)


_N = r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?"
_I = r"[+-]?\d+"
_FAST = (
    rf"(MoveL|TriggL|PaintL) \[\[({_N}),({_N}),({_N})\],\[({_N}),({_N}),({_N}),({_N})\],\[({_I}),({_I}),({_I}),({_I})\],"
    rf"\[({_N}),({_N}),({_N}),9E\+09,9E\+09,9E\+09\]\], \[({_N}),({_N}),({_N}),({_N})\], (?:(trGun1(?:\\T2:=trGun2)?), )?"
    rf"(fine|\[FALSE,({_N}),({_N}),({_N}),({_N}),({_N}),({_N})\]), "
)


def _fast_linear(match, where, axes: int = 3):
    """(pose, external, config, speed, blend, triggers) of a linear move in the writer's own layout; ``axes``
    of eax_a..eax_c in use, the rest 9E+09."""
    g = match.groups()
    pose = np.eye(4)
    pose[:3, 3] = [float(v) for v in g[1:4]]
    q = np.array([float(v) for v in g[4:8]])
    if abs(np.linalg.norm(q) - 1.0) > 1e-6:
        raise ProgramError(*where, f"quaternion {q.tolist()} is not of unit length")
    pose[:3, :3] = matrix_from_wxyz(q)
    config = tuple(int(v) for v in g[8:12])
    if not 0 <= config[3] <= 7:
        raise ProgramError(*where, f"robconf must be 4 whole numbers, cfx 0 to 7, got {list(config)}")
    values = np.array([float(v) for v in g[12:15]])
    if np.any(values[axes:] != 9e9):
        raise ProgramError(*where, f"eax_{'abc'[axes]}..eax_f must be 9E+09 (unused)")
    external = values[:axes]
    speed = float(g[15])
    blend = 0.0 if g[20] == "fine" else _zone_values(np.array([float(v) for v in g[21:27]]), g[20], where)
    return pose, external, config, speed, blend, g[19]


def _read_part(path: Path, name: str, cfg, axes: int = 3) -> list:
    data, body = _body(path, name, name)
    if data:
        raise ProgramError(path, data[0][0], f"unknown declaration: {data[0][1][:60]!r}")
    tool = f"{cfg.rapid_tool}\\WObj:={cfg.rapid_wobj}"
    fast_move = re.compile(_FAST + re.escape(tool) + ";")
    moves, pending, previous, wait = [], {}, None, 0.0
    for n, line in body:
        where = (path, n)
        head, _, rest = line.partition(" ")
        if not line.endswith(";"):
            raise ProgramError(*where, f"a statement must end with ';': {line[:60]!r}")
        fast = fast_move.match(line) if head in ("MoveL", "TriggL", "PaintL") else None
        args = [] if fast else split_arguments(rest[:-1], where)
        if head == "WaitTime" and len(args) == 2 and args[0] == "\\InPos" and not pending and not wait:
            wait = _number(args[1], where)
            if not wait > 0:
                raise ProgramError(*where, "a WaitTime must be > 0 s")
        elif head == "MoveAbsJ" and not pending and not wait:
            _expect(len(args) == 4 and args[2] == "fine" and args[3] == tool, where, line)
            target = aggregate(args[0], where)
            _expect(isinstance(target, list) and len(target) == 2, where, line)
            joints = np.radians(numbers(target[0], (6,), "robax", where))
            ext = _extax_read(target[1], where, axes)
            speed = numbers(aggregate(args[1], where), (4,), "speeddata", where)
            moves.append(ReadMove(JOINT, None, joints, ext, float(speed[0]), 0.0, where=f"{path.name}:{n}"))
        elif head == "TriggIO" and not cfg.rapid_paint:
            _expect(len(args) == 3 and args[0] in TRIGGERS and args[2] in ("0", "1"), where, line)
            distance, _, signal = args[1].partition("\\DOp:=")
            _expect(signal == cfg.rapid_gun_signal, where, line)
            pending[args[0]] = (_nonnegative(distance, where), args[2] == "1")
        elif head == "SetBrush" and cfg.rapid_paint:
            _expect(len(args) == 1, where, line)
            brush, _, plane = args[0].partition("\\")
            axis, _, value = plane.partition(":=")
            _expect(
                axis in ("X", "Y", "Z") and brush in (str(cfg.rapid_brush_on), str(cfg.rapid_brush_off)), where, line
            )
            pending[len(pending)] = (axis, _number(value, where), brush == str(cfg.rapid_brush_on))
        elif (head, cfg.rapid_paint) in (("MoveL", False), ("TriggL", False), ("PaintL", True)):
            expect = 5 if head == "TriggL" else 4
            fast = fast_move.match(line)
            if fast and (fast.group(20) is not None) == (head == "TriggL"):
                pose, external, config, v, blend, trig = _fast_linear(fast, where, axes)
                speed = [v]
                args = [None, None, trig, None, tool] if head == "TriggL" else [None, None, None, tool]
            else:
                _expect(len(args) == expect and args[-1] == tool, where, line)
                pose, external, config = _robtarget(args[0], where, axes)
                speed = numbers(aggregate(args[1], where), (4,), "speeddata", where)
                blend = _zone_read(args[-2], where)
            _expect(speed[0] > 0, where, line)
            events = ()
            if head == "TriggL":
                events = _trigg_events(args[2], pending, where)
                pending = {}
            elif head == "MoveL":
                _expect(not pending, where, line)
            else:
                events = tuple(_brush_event(previous, pose, e, where) for e in pending.values())
                pending = {}
            moves.append(ReadMove(LINEAR, pose, None, external, float(speed[0]), blend, events, config,
                                  f"{path.name}:{n}", wait))  # fmt: skip
            wait = 0.0
        else:
            raise ProgramError(*where, f"unknown statement: {line[:60]!r}")
        previous = moves[-1] if moves else None
    if wait:
        raise ProgramError(path, body[-1][0] if body else 0, "a WaitTime not followed by a linear move")
    if pending:
        raise ProgramError(path, body[-1][0] if body else 0, "a trigger or brush event not used by a move")
    return moves


def _expect(ok: bool, where, line: str) -> None:
    if not ok:
        raise ProgramError(*where, f"not a statement sprayplan writes: {line[:80]!r}")


def _number(text: str, where) -> float:
    return parse_number(text, where)


def _nonnegative(text: str, where) -> float:
    value = _number(text, where)
    if value < 0:
        raise ProgramError(*where, f"a trigger distance must be >= 0, got {text}")
    return value


def _extax_read(value, where, axes: int = 3) -> np.ndarray:
    if not (isinstance(value, list) and len(value) == 6):
        raise ProgramError(*where, "extax must hold 6 values")
    names = "abcdef"
    ext = numbers(value[:axes], (axes,), f"eax_a..eax_{names[axes - 1]}", where) if axes else np.zeros(0)
    if any(v != 9e9 for v in numbers(value[axes:], (6 - axes,), f"eax_{names[axes]}..eax_f", where)):
        raise ProgramError(*where, f"eax_{names[axes]}..eax_f must be 9E+09 (unused)")
    return ext


def _robtarget(text: str, where, axes: int = 3):
    value = aggregate(text, where)
    if not (isinstance(value, list) and len(value) == 4):
        raise ProgramError(*where, "a robtarget must be [trans, rot, robconf, extax]")
    pose = np.eye(4)
    pose[:3, 3] = numbers(value[0], (3,), "trans", where)
    pose[:3, :3] = _rotation(value[1], where)
    conf = numbers(value[2], (4,), "robconf", where)
    if (conf != np.round(conf)).any() or not 0 <= conf[3] <= 7:
        raise ProgramError(*where, f"robconf must be 4 whole numbers, cfx 0 to 7, got {value[2]}")
    return pose, _extax_read(value[3], where, axes), tuple(int(c) for c in conf)


def _zone_read(text: str, where) -> float:
    if text == "fine":
        return 0.0
    zone = aggregate(text, where)
    if not (isinstance(zone, list) and len(zone) == 7 and zone[0] is False):
        raise ProgramError(*where, f"zonedata must be fine or [FALSE, 6 numbers], got {text[:60]!r}")
    return _zone_values(numbers(zone[1:], (6,), "zonedata", where), text, where)


def _zone_values(values: np.ndarray, text: str, where) -> float:
    if (values < 0).any() or values[0] <= 0 or not (values[[1, 2, 4]] == values[0]).all():
        raise ProgramError(
            *where, f"zonedata must give one path zone r > 0 (pzone_tcp, pzone_ori, pzone_eax, zone_leax), got {text}"
        )
    return float(values[0])


def _trigg_events(text: str, pending: dict, where) -> tuple:
    parts = text.split("\\")
    names = [parts[0]] + [p.partition(":=")[2] for p in parts[1:]]
    keys = [""] + [p.partition(":=")[0] for p in parts[1:]]
    if (
        keys != [""] + [f"T{k}" for k in range(2, len(names) + 1)]
        or set(names) != set(pending)
        or len(set(names)) != len(names)
    ):
        raise ProgramError(*where, f"the TriggL's triggers {text!r} must be those set just before it by TriggIO")
    return tuple(pending[name] for name in names)


def _brush_event(previous, pose, event, where) -> tuple:
    axis, value, on = event
    if previous is None:
        raise ProgramError(*where, "a brush event before the first move")
    k = "XYZ".index(axis)
    end = pose[:3, 3]
    if previous.pose is None:  # after a joint move the segment's start is not in the file: only at the target
        if abs(value - end[k]) > 1e-3:
            raise ProgramError(*where, "a brush event after a joint move must be at the move's target")
        return (0.0, on)
    start = previous.pose[:3, 3]
    span = end[k] - start[k]
    fraction = (value - start[k]) / span if span else np.nan
    if not (-1e-9 <= fraction <= 1 + 1e-9):
        raise ProgramError(*where, f"the brush event at {axis} = {value} is not on the move's segment")
    return (float((1 - fraction) * np.linalg.norm(end - start)), on)
