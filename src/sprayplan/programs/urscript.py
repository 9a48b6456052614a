"""URScript: one script per gantry station (split into parts beyond ``[export] ur_max_moves`` moves), a station
sequence file for the cell's PLC, and a strict reader of both.

A UR controller cannot drive the gantry: each script runs with the gantry standing at its station. It sets the
TCP (``set_tcp``, m and rotation vector), holds the part frame in the arm's base frame (``part_frame``; every
target is ``pose_trans(part_frame, p[...])``), waits for the PLC's "gantry in position" input, moves, and sets
the "done" output at its end; the last line calls the function the file defines. Spray moves are ``movep``
(constant TCP speed through blends), approaches and retracts ``movel``, transfers ``movej`` to the plan's
joints. The gun: ``set_standard_digital_out`` after a move runs where that move's blend begins (at its target
when it has none); a gun signal due elsewhere gets a via point on the straight segment whose blend begins
exactly there (docs/programs.md).
"""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import numpy as np

from sprayplan import __version__
from sprayplan.programs.build import BLEND_MARGIN_MM
from sprayplan.programs.model import (
    JOINT,
    LINEAR,
    Move,
    ProgramError,
    ReadMove,
    ReadProgram,
    fixed,
    fixed_down,
    matrix_from_rotvec,
    parse_number,
    rotvec,
)
from sprayplan.programs.text import chunks, program_lines

IND = "  "
SEQUENCE_HEADER = "step,station,script,x_mm,y_mm,z_mm"


def _p(pose, vector=None) -> str:
    """``p[x, y, z, rx, ry, rz]`` of a pose (m, rotation vector); ``vector``: its rotation vector when already
    computed."""
    pos = ", ".join(fixed(v / 1000.0, 7) for v in pose[:3, 3])
    rot = ", ".join(fixed(v, 9) for v in (rotvec(pose[:3, :3]) if vector is None else vector))
    return f"p[{pos}, {rot}]"


def script_name(cfg, order: int, part: int, parts: int) -> str:
    base = f"{cfg.name}_station_{order + 1:02d}"
    return base if parts == 1 else f"{base}_part_{part + 1}"


def write_urscript(cell, job) -> dict[str, str]:
    """URScript files of a cell program: ``{file name: text}``, the station sequence (``<name>_stations.csv``)
    first, then one script per station part in visiting order."""
    from sprayplan.robots.stage import gantry_for

    cfg = job.export
    gantry = gantry_for(job.kinematics)
    files, rows = {}, [SEQUENCE_HEADER, f"0,home,,{_mm(cell.home_mm)}"]
    for st in cell.stations:
        moves = with_via_points(list(st.moves), cfg.blend_share, cfg.blend_mm)
        parts = chunks(moves, lambda m: 1, cfg.ur_max_moves)
        part2base = np.linalg.inv(gantry.base2world(st.platform_mm)[0])
        for k, part in enumerate(parts):
            name = script_name(cfg, st.order, k, len(parts))
            files[name + ".script"] = _script(name, part, part2base, st, cell, job, (k, len(parts)))
            rows.append(f"{len(rows) - 1},{st.station},{name}.script,{_mm(st.platform_mm)}")
    rows.append(f"{len(rows) - 1},home,,{_mm(cell.home_mm)}")
    return {f"{cfg.name}_stations.csv": "\n".join(rows) + "\n", **files}


def _mm(values) -> str:
    return ",".join(fixed(v, 4) for v in values)


def _script(name, moves, part2base, st, cell, job, part) -> str:
    cfg = job.export
    acc = fixed(cfg.linear_acceleration_mm_s2 / 1000.0, 4)
    jacc, jvel = fixed(np.radians(cfg.joint_acceleration_deg_s2), 6), fixed(np.radians(cfg.joint_speed_deg_s), 6)
    gun = cfg.ur_gun_output
    lines = [
        f"def {name}():",
        f"{IND}# sprayplan {__version__}: {cell.name or 'the part'}, station {st.order + 1} of {len(cell.stations)} "
        f"(plan station {st.station}), part {part[0] + 1} of {part[1]}",
        f"{IND}# the gantry stands at ({_mm(st.platform_mm)}) mm ({cfg.name}_stations.csv); units m, rad, m/s",
        f"{IND}set_tcp({_p(cell.tool2flange)})",
        f"{IND}part_frame = {_p(part2base)}",
        f"{IND}set_standard_digital_out({gun}, False)",
        f"{IND}set_standard_digital_out({cfg.ur_done_output}, False)",
        f"{IND}while not get_standard_digital_in({cfg.ur_ready_input}):",
        f"{IND * 2}sync()",
        f"{IND}end",
    ]
    linear = [m for m in moves if m.kind != JOINT]
    vectors = dict(zip(map(id, linear), rotvec(np.array([m.pose[:3, :3] for m in linear])))) if linear else {}
    for move in moves:
        if move.kind == JOINT:
            q = ", ".join(fixed(v, 8) for v in move.joints)
            lines.append(f"{IND}movej([{q}], a={jacc}, v={jvel}, r=0)")
            lines += [f"{IND}set_standard_digital_out({gun}, {on})" for _, on in move.events]
            continue
        verb = "movep" if move.role in ("spray", "via-spray") else "movel"
        v, r = fixed(move.speed_mm_s / 1000.0, 7), fixed_down(move.blend_mm / 1000.0, 7)
        lines.append(f"{IND}{verb}(pose_trans(part_frame, {_p(move.pose, vectors[id(move)])}), a={acc}, v={v}, r={r})")
        for _, on in move.events:  # where the move's blend begins (or at its target): with_via_points
            lines.append(f"{IND}set_standard_digital_out({gun}, {on})")
    lines += [
        f"{IND}set_standard_digital_out({gun}, False)",
        f"{IND}set_standard_digital_out({cfg.ur_done_output}, True)",
        "end",
        f"{name}()",
        "",
    ]
    return "\n".join(lines)


def with_via_points(moves: list[Move], share: float, blend_mm: float) -> list[Move]:
    """The moves with a via point for every gun event that is not at a target the robot stops at.

    An event d mm before a move's target gets a via point ``e = d - r`` before the target on the straight
    segment, with the blend radius ``r``: the via's blend, and the ``set_standard_digital_out`` after it, begin
    exactly at the event. With the events at d_1 < d_2 < ... before the target (d_0 = 0, the segment's length
    after the last), ``r_i = min(blend_mm, q min(d_i - d_(i-1), d_(i+1) - d_i))`` with ``q = share / (1 + share)``
    keeps every blend within ``share`` of its neighbouring segments and the path straight up to each event; the
    blends at the segment's two ends are reduced to fit. Afterwards every event lies ``blend_mm`` before its
    move's target."""
    q = share / (1.0 + share)
    out: list[Move] = []
    for move in moves:
        if move.kind != LINEAR or not move.events:
            out.append(move)
            continue
        previous = out[-1]
        length = float(np.linalg.norm(move.pose[:3, 3] - previous.pose[:3, 3]))
        end = dataclasses.replace(move, events=())
        ds = sorted(d for d, _ in move.events)
        states = [on for _, on in sorted(move.events, key=lambda e: e[0])]
        at_end = [on for d, on in zip(ds, states) if d <= 1e-9]
        if at_end:  # an event at the target itself: the robot stops there
            end = dataclasses.replace(end, blend_mm=0.0, events=tuple((0.0, on) for on in at_end))
        events = [(d, on) for d, on in zip(ds, states) if d > 1e-9]
        if previous.kind == JOINT or previous.blend_mm == 0:  # events at the stop point the move starts from
            at_start = [on for d, on in events if d >= length - 1e-9]
            if at_start:
                out[-1] = previous = dataclasses.replace(
                    previous, events=previous.events + tuple((0.0, on) for on in at_start)
                )
                events = [(d, on) for d, on in events if d < length - 1e-9]
        vias = events
        bounds = [0.0] + [d for d, _ in vias] + [length]
        pieces = []
        for i, (d, on) in enumerate(vias, 1):
            radius = max(
                0.0, min(blend_mm, q * min(bounds[i] - bounds[i - 1], bounds[i + 1] - bounds[i])) - BLEND_MARGIN_MM
            )
            e = d - radius
            fraction = 1.0 - e / length
            assert -1e-9 <= fraction <= 1 + 1e-9, (d, radius, length)
            pose = _interpolate(previous.pose, move.pose, min(max(fraction, 0.0), 1.0))
            pieces.append(Move(LINEAR, f"via-{move.role}", pose, move.joints, move.external_mm, move.speed_mm_s, radius,
                               ((radius, on),)))  # fmt: skip
        if pieces:
            e1, r1 = vias[0][0] - pieces[0].blend_mm, pieces[0].blend_mm
            end = dataclasses.replace(end, blend_mm=max(0.0, min(end.blend_mm, share * e1 - BLEND_MARGIN_MM, e1 - r1)))
            ek, dk = vias[-1][0] - pieces[-1].blend_mm, vias[-1][0]
            if previous.kind == LINEAR:
                out[-1] = dataclasses.replace(
                    previous,
                    blend_mm=max(0.0, min(previous.blend_mm, share * (length - ek) - BLEND_MARGIN_MM, length - dk)),
                )
        out += [*reversed(pieces), end]
    return out


def _interpolate(a: np.ndarray, b: np.ndarray, fraction: float) -> np.ndarray:
    """The pose ``fraction`` of the way from ``a`` to ``b``: position on the line, orientation by slerp (what a
    linear move does between its two targets)."""
    from scipy.spatial.transform import Rotation, Slerp

    out = np.eye(4)
    out[:3, 3] = a[:3, 3] + fraction * (b[:3, 3] - a[:3, 3])
    out[:3, :3] = Slerp([0.0, 1.0], Rotation.from_matrix([a[:3, :3], b[:3, :3]]))(fraction).as_matrix()
    return out


# --- the reader ---------------------------------------------------------------------------------------------

_POSE = r"p\[([^\[\]]*)\]"
_MOVEL = re.compile(rf"(movel|movep)\(pose_trans\(part_frame, {_POSE}\), a=(\S+), v=(\S+), r=(\S+)\)")
_MOVEJ = re.compile(r"movej\(\[([^\[\]]*)\], a=(\S+), v=(\S+), r=0\)")
_OUT = re.compile(r"set_standard_digital_out\((\d), (True|False)\)")


def read_urscript(folder, job) -> ReadProgram:
    """Read a URScript folder written by :func:`write_urscript` (the station sequence, then each script it
    names) back into moves, strictly: every line must be one the writer writes (comments aside); anything else
    is a :class:`ProgramError` naming the file and line."""
    cfg = job.export
    folder = Path(folder)
    sequence = folder / f"{cfg.name}_stations.csv"
    rows = _read_sequence(sequence)
    moves: list = []
    scripts = []
    tool = None
    for row in rows:
        if row["script"] is None:
            continue
        path = folder / row["script"]
        tcp, frame, found, io = _read_script(path, cfg)
        if tool is not None and np.abs(tcp - tool).max() > 1e-9:
            raise ProgramError(path, 0, "sets another TCP than the scripts before it")
        tool = tcp
        scripts.append({"file": path.name, "station": row["station"], "first": len(moves), "count": len(found),
                        "part_frame": frame, "gantry_mm": row["mm"], **io})  # fmt: skip
        moves += found
    if tool is None:
        raise ProgramError(sequence, 0, "names no script")
    files = (sequence.name, *(s["file"] for s in scripts))
    return ReadProgram("urscript", tool, scripts[0]["part_frame"], tuple(moves), tuple(scripts), files)


def _read_sequence(path: Path) -> list[dict]:
    lines = program_lines(path)
    if not lines or lines[0][1] != SEQUENCE_HEADER:
        raise ProgramError(path, 1, f"expected the header {SEQUENCE_HEADER!r}")
    rows = []
    for n, line in lines[1:]:
        cells = line.split(",")
        if len(cells) != 6 or cells[0] != str(len(rows)):
            raise ProgramError(path, n, f"expected step {len(rows)} and 6 cells, got {line[:60]!r}")
        home = cells[1] == "home"
        if home != (cells[2] == "") or (not home and not re.fullmatch(r"\d+", cells[1])):
            raise ProgramError(path, n, "a row is a home row (home, no script) or a station's number and script")
        if not home and not re.fullmatch(r"\w+\.script", cells[2]):
            raise ProgramError(path, n, f"not a script's name: {cells[2]!r}")
        mm = np.array([parse_number(c, (path, n)) for c in cells[3:]])
        rows.append({"station": None if home else int(cells[1]), "script": cells[2] or None, "mm": mm})
    if len(rows) < 2 or rows[0]["script"] or rows[-1]["script"]:
        raise ProgramError(path, 0, "the sequence must start and end at home")
    return rows


def _read_script(path: Path, cfg):
    lines = program_lines(path)
    name = path.stem
    body = [(n, line) for n, line in lines if not line.strip().startswith("#")]
    if not body or body[0][1] != f"def {name}():":
        raise ProgramError(path, body[0][0] if body else 0, f"expected 'def {name}():' first")
    if len(body) < 3 or body[-1][1] != f"{name}()" or body[-2][1] != "end":
        raise ProgramError(path, body[-1][0] if body else 0, f"the script must end with 'end' and the call {name}()")
    tcp = frame = None
    moves: list = []
    io = {"gun": None, "ready": None, "done": None}
    k = 1
    statements = body[1:-2]
    while k - 1 < len(statements):
        n, line = statements[k - 1]
        where = (path, n)
        if not line.startswith(IND) or line[len(IND)] == " " or line != line.rstrip():
            raise ProgramError(*where, f"expected an indentation of {len(IND)} spaces and no trailing space")
        text = line[len(IND) :]
        k += 1
        if text.startswith("set_tcp(") and text.endswith(")") and tcp is None and not moves:
            tcp = _pose(text[len("set_tcp(") : -1], where)
        elif text.startswith("part_frame = ") and frame is None and not moves:
            frame = _pose(text[len("part_frame = ") :], where)
        elif text.startswith("while not get_standard_digital_in("):
            match = re.fullmatch(r"while not get_standard_digital_in\((\d)\):", text)
            after = [t for _, t in statements[k - 1 : k + 1]]
            if not match or after != [f"{IND * 2}sync()", f"{IND}end"] or moves or io["ready"] is not None:
                raise ProgramError(
                    *where, "the wait for the ready input must be 'while not ...: sync() end' before the moves"
                )
            io["ready"] = int(match.group(1))
            k += 2
        elif match := _OUT.fullmatch(text):
            _output(io, moves, int(match.group(1)), match.group(2) == "True", cfg, where)
        elif match := _MOVEJ.fullmatch(text):
            joints = _numbers(match.group(1), 6, where)
            _positive(match.group(2), match.group(3), where)
            moves.append(ReadMove(JOINT, None, joints, None, 0.0, 0.0, where=f"{path.name}:{n}"))
        elif match := _MOVEL.fullmatch(text):
            pose = _numbers(match.group(2), 6, where)  # a pose once every move is read (one conversion)
            _positive(match.group(3), match.group(4), where)
            v = parse_number(match.group(4), where) * 1000.0
            r = parse_number(match.group(5), where) * 1000.0
            if r < 0:
                raise ProgramError(*where, "a blend radius must be >= 0")
            moves.append(ReadMove(LINEAR, pose, None, None, v, r, where=f"{path.name}:{n}", config=(match.group(1),)))
        else:
            raise ProgramError(*where, f"unknown statement: {text[:60]!r}")
    linear = [k for k, m in enumerate(moves) if m.kind == LINEAR]
    if linear:
        values = np.array([moves[k].pose for k in linear])
        poses = np.repeat(np.eye(4)[None], len(linear), axis=0)
        poses[:, :3, 3] = values[:, :3] * 1000.0
        poses[:, :3, :3] = matrix_from_rotvec(values[:, 3:])
        for k, pose in zip(linear, poses):
            moves[k] = dataclasses.replace(moves[k], pose=pose)
    if tcp is None or frame is None or io["ready"] is None:
        raise ProgramError(path, 0, "set_tcp, part_frame and the wait for the ready input must come before the moves")
    if io["done"] is None:
        raise ProgramError(path, 0, "the script never sets its done output")
    io.pop("last", None)
    return tcp, frame, moves, io


def _output(io, moves, number, on, cfg, where) -> None:
    """A ``set_standard_digital_out``: the gun (an event of the move before it, at its blend's start) or the
    done output (off before the moves, on after them)."""
    was, io["last"] = io.get("last"), "gun off" if number == cfg.ur_gun_output and not on and moves else ""
    if number == cfg.ur_gun_output:
        io["gun"] = number
        if moves:
            last = moves[-1]
            moves[-1] = dataclasses.replace(last, events=last.events + ((last.blend_mm, on),))
        elif on:
            raise ProgramError(*where, "the gun is switched on before any move")
    elif number == cfg.ur_done_output and not moves and not on:
        io["done"] = None
    elif number == cfg.ur_done_output and on:
        io["done"] = number
        if was == "gun off" and moves:  # the gun's closing at the script's end is no move's event
            last = moves[-1]
            moves[-1] = dataclasses.replace(last, events=last.events[:-1])
    else:
        raise ProgramError(*where, f"set_standard_digital_out({number}, {on}): not the gun's or the done output")


def _positive(a: str, v: str, where) -> None:
    if not (parse_number(a, where) > 0 and parse_number(v, where) > 0):
        raise ProgramError(*where, "acceleration and speed must be > 0")


def _numbers(text: str, n: int, where) -> np.ndarray:
    cells = text.split(", ")
    if len(cells) != n:
        raise ProgramError(*where, f"expected {n} numbers, got {text[:60]!r}")
    return np.array([parse_number(c, where) for c in cells])


def _pose(text: str, where) -> np.ndarray:
    match = re.fullmatch(_POSE, text)
    if not match:
        raise ProgramError(*where, f"expected a pose p[x, y, z, rx, ry, rz], got {text[:60]!r}")
    values = _numbers(match.group(1), 6, where)
    pose = np.eye(4)
    pose[:3, 3] = values[:3] * 1000.0
    pose[:3, :3] = matrix_from_rotvec(values[3:])
    return pose
