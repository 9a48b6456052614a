"""KUKA KRL: a main program calling subprograms of at most ``[export] krl_max_moves`` moves, each a ``.src`` with
its ``.dat``, and a strict reader of them.

Linear targets are ``E6POS`` in the base (the part frame): X, Y, Z in mm, A, B, C in degrees about Z, Y, X,
status S and turn T from the plan's joints, the gantry in E1..E3 (mm). Joint targets are ``E6AXIS`` (A1..A6 the
plan's joints in degrees, E1..E3 the gantry). ``$VEL.CP`` (m/s) and ``$APO.CDIS`` (mm) are set before the
``LIN`` they apply to when they change; a target with a blend radius is ``LIN ... C_DIS``. The gun:
``TRIGGER WHEN PATH=-d DELAY=0 DO $OUT[n]=TRUE`` before the ``LIN``, d mm before its target. Layout and
conventions: docs/programs.md.
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
    kuka_abc,
    matrix_from_abc,
    parse_number,
)
from sprayplan.programs.rapid import _stations
from sprayplan.programs.text import chunks, program_lines

IND = "  "
HEADER = ("&ACCESS RVP", "&REL 1")


def _frame_text(pose, abc=None) -> str:
    """``X ..,Y ..,Z ..,A ..,B ..,C ..`` of a pose; ``abc``: its A, B, C when already computed."""
    x, y, z = (fixed(v, 4) for v in pose[:3, 3])
    a, b, c = (fixed(v, 6) for v in (kuka_abc(pose[:3, :3]) if abc is None else abc))
    return f"X {x},Y {y},Z {z},A {a},B {b},C {c}"


def _external(external_mm) -> str:
    """E1..E6: the external axes in use (mm), the rest 0."""
    e = [fixed(v, 4) for v in external_mm] + ["0.0"] * (6 - len(external_mm))
    return ",".join(f"E{k + 1} {v}" for k, v in enumerate(e))


def e6pos(move, config, abc=None) -> str:
    s, t = (int(v) for v in config)
    return f"{{{_frame_text(move.pose, abc)},S {s},T {t},{_external(move.external_mm)}}}"


def e6axis(move) -> str:
    axes = ",".join(f"A{k + 1} {fixed(v, 6)}" for k, v in enumerate(np.degrees(move.joints)))
    return f"{{{axes},{_external(move.external_mm)}}}"


def write_krl(cell, job, configs) -> dict[str, str]:
    """KRL files of a cell program: ``{file name: text}``, the main ``.src`` first, then each subprogram's
    ``.src`` and ``.dat``. ``configs``: per linear move (``id(move)``) its ``[S, T]``."""
    cfg = job.export
    flat = cell.sequence()
    parts = chunks([m for m, _ in flat], lambda m: 1, cfg.krl_max_moves)
    notes = {id(m): note for m, note in flat if note}
    names = [f"{cfg.name}_{k + 1:03d}" for k in range(len(parts))]
    files = {f"{cfg.name}.src": _main(cell, job, names)}
    for name, part in zip(names, parts):
        src, dat = _sub(name, part, notes, cfg, configs)
        files[f"{name}.src"] = src
        files[f"{name}.dat"] = dat
    return files


def _main(cell, job, names) -> str:
    cfg = job.export
    out = f"$OUT[{cfg.krl_gun_output}]=FALSE"
    lines = [
        *HEADER,
        f"DEF {cfg.name}( )",
        ";FOLD INI",
        f"{IND}BAS (#INITMOV,0 )",
        ";ENDFOLD (INI)",
        f"{IND}; sprayplan {__version__}: spray program for {cell.name or 'the part'}, {_stations(cell)}",
        f"{IND}; mm, degrees (A, B, C about Z, Y, X), m/s; {_axes_note(cell)}; S, T from the plan's joints",
        f"{IND}; poses in the base {cfg.krl_base} ({cell.frame_note})",
        f"{IND}TOOL_DATA[{cfg.krl_tool}]={{{_frame_text(cell.tool2flange)}}}",
        f"{IND}BASE_DATA[{cfg.krl_base}]={{{_frame_text(np.eye(4))}}}",
        f"{IND}$TOOL=TOOL_DATA[{cfg.krl_tool}]",
        f"{IND}$BASE=BASE_DATA[{cfg.krl_base}]",
        f"{IND}{out}",
        f"{IND}BAS (#VEL_PTP,{fixed(cfg.ptp_velocity_pct, 3)} )",
        *[f"{IND}{name}( )" for name in names],
        f"{IND}{out}",
        "END",
        "",
    ]
    return "\n".join(lines)


def _axes_note(cell) -> str:
    if cell.external_axes == 3:
        return "E1..E3 the gantry (mm)"
    return cell.external_note


def _sub(name, moves, notes, cfg, configs) -> tuple[str, str]:
    src = [*HEADER, f"DEF {name}( )"]
    dat = [*HEADER, f"DEFDAT {name}"]
    speed = blend = None
    linear = [m for m in moves if m.kind != JOINT]
    abc = dict(zip(map(id, linear), kuka_abc(np.array([m.pose[:3, :3] for m in linear])))) if linear else {}
    for k, move in enumerate(moves, 1):
        note = notes.get(id(move))
        if note:
            src.append(f"{IND}; {note}")
        if move.kind == JOINT:
            dat.append(f"{IND}DECL E6AXIS XJ{k}={e6axis(move)}")
            src.append(f"{IND}PTP XJ{k}")
            continue
        dat.append(f"{IND}DECL E6POS XP{k}={e6pos(move, configs[id(move)], abc[id(move)])}")
        v = fixed(move.speed_mm_s / 1000.0, 7)
        if v != speed:
            src.append(f"{IND}$VEL.CP={v}")
            speed = v
        radius = fixed_down(move.blend_mm, 4)
        if float(radius) > 0 and radius != blend:
            blend = radius
            src.append(f"{IND}$APO.CDIS={blend}")
        if move.wait_s > 0:
            src.append(f"{IND}WAIT SEC {fixed(move.wait_s, 3)}")
        for distance, on in move.events:
            state = "TRUE" if on else "FALSE"
            src.append(f"{IND}TRIGGER WHEN PATH=-{fixed(distance, 4)} DELAY=0 DO $OUT[{cfg.krl_gun_output}]={state}")
        src.append(f"{IND}LIN XP{k}{' C_DIS' if float(radius) > 0 else ''}")
    return "\n".join(src + ["END", ""]), "\n".join(dat + ["ENDDAT", ""])


# --- the reader ---------------------------------------------------------------------------------------------


def read_krl(folder, job, external_axes: int = 3) -> ReadProgram:
    """Read a KRL program folder written by :func:`write_krl` back into moves, strictly: every line must be one
    the writer writes (comments aside); anything else is a :class:`ProgramError` naming the file and line.
    ``external_axes``: how many of E1..E6 the robot has (the gantry 3, a track 1); the rest must be 0."""
    cfg = job.export
    folder = Path(folder)
    main = folder / f"{cfg.name}.src"
    tool, base, calls = _read_main(main, cfg)
    moves: list = []
    files = [main.name]
    for call in calls:
        files += [f"{call}.src", f"{call}.dat"]
        moves += _read_sub(folder, call, cfg, external_axes)
    return ReadProgram("krl", tool, base, tuple(moves), (), tuple(files))


def _lines(path: Path) -> list[tuple[int, str]]:
    lines = program_lines(path)
    if [line for _, line in lines[:2]] != list(HEADER):
        raise ProgramError(path, 1, f"expected the header lines {' / '.join(HEADER)}")
    body = []
    for n, line in lines[2:]:
        if line.strip().startswith(";") and not line.strip().startswith((";FOLD", ";ENDFOLD")):
            continue  # a comment
        if line != line.rstrip():
            raise ProgramError(path, n, "trailing space")
        body.append((n, line))
    return body


def _block(path: Path, lines, opening: str, closing: str):
    if not lines or lines[0][1] != opening:
        raise ProgramError(path, lines[0][0] if lines else 0, f"expected {opening!r}")
    if lines[-1][1] != closing:
        raise ProgramError(path, lines[-1][0], f"expected {closing!r} as the last line")
    return lines[1:-1]


def _statement(path, n, line) -> str:
    if not line.startswith(IND) or line[len(IND)] == " ":
        raise ProgramError(path, n, f"expected an indentation of {len(IND)} spaces")
    return line[len(IND) :]


def _read_main(path: Path, cfg):
    lines = _block(path, _lines(path), f"DEF {cfg.name}( )", "END")
    ini = [";FOLD INI", f"{IND}BAS (#INITMOV,0 )", ";ENDFOLD (INI)"]
    if [line for _, line in lines[:3]] != ini:
        raise ProgramError(path, lines[0][0] if lines else 0, "expected the INI fold with BAS (#INITMOV,0 )")
    tool = base = None
    calls = []
    out = f"$OUT[{cfg.krl_gun_output}]=FALSE"
    set_tool = {f"$TOOL=TOOL_DATA[{cfg.krl_tool}]": "tool", f"$BASE=BASE_DATA[{cfg.krl_base}]": "base"}
    seen = set()
    for n, line in lines[3:]:
        text = _statement(path, n, line)
        where = (path, n)
        if text.startswith(f"TOOL_DATA[{cfg.krl_tool}]="):
            tool = _frame(text.split("=", 1)[1], where)
        elif text.startswith(f"BASE_DATA[{cfg.krl_base}]="):
            base = _frame(text.split("=", 1)[1], where)
        elif text in set_tool:
            seen.add(set_tool[text])
        elif text == out or re.fullmatch(r"BAS \(#VEL_PTP,\d+(\.\d+)? \)", text):
            if text.startswith("BAS"):
                pct = float(text[len("BAS (#VEL_PTP,") : -2])
                if not 0 < pct <= 100:
                    raise ProgramError(*where, f"a PTP speed must be 0 to 100 %, got {pct}")
        elif re.fullmatch(rf"{cfg.name}_\d{{3}}\( \)", text):
            calls.append(text[:-3])
        else:
            raise ProgramError(*where, f"unknown statement: {text[:60]!r}")
    if tool is None or base is None or seen != {"tool", "base"}:
        raise ProgramError(path, 0, f"the TOOL_DATA[{cfg.krl_tool}] and BASE_DATA[{cfg.krl_base}] must be set and used")
    return tool, base, calls


_FRAME_KEYS = ("X", "Y", "Z", "A", "B", "C")
_E = tuple(f"E{k}" for k in range(1, 7))


def _fields(text: str, keys: tuple, where) -> dict:
    """``{K v,K v,...}`` with exactly ``keys`` in that order, as numbers."""
    if not (text.startswith("{") and text.endswith("}")):
        raise ProgramError(*where, f"expected {{...}}, got {text[:60]!r}")
    items = text[1:-1].split(",")
    if len(items) != len(keys):
        raise ProgramError(*where, f"expected the fields {' '.join(keys)}, got {text[:80]!r}")
    out = {}
    for item, key in zip(items, keys):
        name, _, value = item.partition(" ")
        if name != key:
            raise ProgramError(*where, f"expected the field {key}, got {item[:20]!r}")
        out[key] = parse_number(value, where)
    return out


def _frame(text: str, where) -> np.ndarray:
    f = _fields(text, _FRAME_KEYS, where)
    return _pose(f)


def _pose(f: dict) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, 3] = (f["X"], f["Y"], f["Z"])
    pose[:3, :3] = matrix_from_abc([f["A"], f["B"], f["C"]])
    return pose


def _read_sub(folder: Path, name: str, cfg, axes: int = 3) -> list:
    dat_path, src_path = folder / f"{name}.dat", folder / f"{name}.src"
    targets = {}
    for n, line in _block(dat_path, _lines(dat_path), f"DEFDAT {name}", "ENDDAT"):
        text = _statement(dat_path, n, line)
        where = (dat_path, n)
        match = re.fullmatch(r"DECL (E6POS|E6AXIS) (X[PJ]\d+)=(\{.*\})", text)
        if not match or (match.group(1) == "E6POS") != match.group(2).startswith("XP"):
            raise ProgramError(*where, f"unknown declaration: {text[:60]!r}")
        if match.group(2) in targets:
            raise ProgramError(*where, f"{match.group(2)} declared twice")
        if match.group(1) == "E6POS":
            f = _fields(match.group(3), (*_FRAME_KEYS, "S", "T", *_E), where)
            if any(f[k] != int(f[k]) or f[k] < 0 for k in ("S", "T")) or f["S"] > 7 or f["T"] > 63:
                raise ProgramError(*where, f"S must be 0 to 7 and T 0 to 63, whole numbers: {text[:80]!r}")
            targets[match.group(2)] = (f, (int(f["S"]), int(f["T"])), _ext(f, where, axes))  # posed below, at once
        else:
            f = _fields(match.group(3), (*(f"A{k}" for k in range(1, 7)), *_E), where)
            joints = np.radians([f[f"A{k}"] for k in range(1, 7)])
            targets[match.group(2)] = (joints, _ext(f, where, axes))
    linear = [k for k, t in targets.items() if k.startswith("XP")]
    if linear:
        fields = [targets[k][0] for k in linear]
        poses = np.repeat(np.eye(4)[None], len(linear), axis=0)
        poses[:, :3, 3] = [[f["X"], f["Y"], f["Z"]] for f in fields]
        poses[:, :3, :3] = matrix_from_abc([[f["A"], f["B"], f["C"]] for f in fields])
        for k, pose in zip(linear, poses):
            targets[k] = (pose, *targets[k][1:])
    moves = []
    speed = blend = None
    pending: list = []
    used = set()
    wait = 0.0
    for n, line in _block(src_path, _lines(src_path), f"DEF {name}( )", "END"):
        text = _statement(src_path, n, line)
        where = (src_path, n)
        at = f"{src_path.name}:{n}"
        if text.startswith("$VEL.CP="):
            speed = parse_number(text[len("$VEL.CP=") :], where) * 1000.0
            if not speed > 0:
                raise ProgramError(*where, "$VEL.CP must be > 0")
        elif text.startswith("$APO.CDIS="):
            blend = parse_number(text[len("$APO.CDIS=") :], where)
            if not blend > 0:
                raise ProgramError(*where, "$APO.CDIS must be > 0")
        elif text.startswith("WAIT SEC ") and not pending and not wait:
            wait = parse_number(text[len("WAIT SEC ") :], where)
            if not wait > 0:
                raise ProgramError(*where, "a WAIT SEC must be > 0 s")
        elif match := re.fullmatch(
            rf"TRIGGER WHEN PATH=(-?\S+) DELAY=0 DO \$OUT\[{cfg.krl_gun_output}\]=(TRUE|FALSE)", text
        ):
            distance = -parse_number(match.group(1), where)
            if distance < 0:
                raise ProgramError(*where, "a gun trigger must be at or before the target (PATH <= 0)")
            pending.append((distance, match.group(2) == "TRUE"))
        elif match := re.fullmatch(r"(PTP|LIN) (X[PJ]\d+)( C_DIS)?", text):
            key = match.group(2)
            if key not in targets or key in used:
                raise ProgramError(*where, f"{key} is not declared in {dat_path.name}, or used twice")
            used.add(key)
            if match.group(1) == "PTP":
                if not key.startswith("XJ") or match.group(3) or pending or wait:
                    raise ProgramError(*where, f"not a statement sprayplan writes: {text!r}")
                joints, ext = targets[key]
                moves.append(ReadMove(JOINT, None, joints, ext, 0.0, 0.0, where=at))
            else:
                if not key.startswith("XP") or speed is None or (match.group(3) and blend is None):
                    raise ProgramError(
                        *where, f"{text!r}: a LIN to an E6POS with $VEL.CP (and $APO.CDIS) set before it"
                    )
                pose, config, ext = targets[key]
                r = blend if match.group(3) else 0.0
                moves.append(ReadMove(LINEAR, pose, None, ext, speed, r, tuple(pending), config, at, wait))
                pending, wait = [], 0.0
        else:
            raise ProgramError(*where, f"unknown statement: {text[:60]!r}")
    if wait:
        raise ProgramError(src_path, 0, "a WAIT SEC not followed by a LIN")
    if pending:
        raise ProgramError(src_path, 0, "a TRIGGER not followed by a LIN")
    if set(targets) != used:
        raise ProgramError(dat_path, 0, f"declared but not used: {', '.join(sorted(set(targets) - used))}")
    return moves


def _ext(f: dict, where, axes: int = 3) -> np.ndarray:
    unused = [f"E{k}" for k in range(axes + 1, 7)]
    if any(f[k] != 0 for k in unused):
        raise ProgramError(*where, f"{unused[0]}..E6 must be 0 (no such axes)")
    return np.array([f[f"E{k}"] for k in range(1, axes + 1)])
