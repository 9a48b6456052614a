"""The files of a cell plan (``sprayplan plan --cell``): what :func:`write_cell_plan` writes into OUTDIR, and
:func:`read_cell_plan`, which reads ``cell_plan.json`` back.

``cell_plan.json``
    ``format = "sprayplan-cell-plan"``, ``version = 2``; the cell (its robots, their base poses and tracks);
    the part's placement (``part2cell``); the areas (name, direction, surface, robot, the share it reaches,
    split or not); per robot its strokes in order, each with its kind and area, and per waypoint the gun
    tip, the gun's roll about its axis (``roll_deg``, deg), the normal, the time factor, the track position,
    the six joints (rad), whether it is reached and (with ``--collisions``) whether it collides, when the robot gets there (``t_s``) and the stroke's wait
    (``wait_s``) in the cell's schedule (``cells.schedule``), and where the schedule has the robot when the
    cycle starts and ends (``schedule_ends``: ``q_rad`` (2, 6), ``track_mm`` (2,); its programs start and end
    there; absent without a schedule); the run-ups and run-outs of its stretches (``leads``, ``cells.runups``:
    per lead its ``waypoint`` over the robot's strokes one after another, its ``side``, 0 a run-up into the
    waypoint, 1 a run-out after it, ``q_rad``, ``track_mm`` and its time ``t_s``; absent without run-ups); and
    the report (film over the whole body, per area, per robot, per seam; cycle times). mm, rad, s.
``waypoints.csv``
    One row a waypoint of every robot: ``robot, stroke, waypoint, kind, area, x_mm, y_mm, z_mm, nx, ny, nz,
    dwell, track_mm, roll_deg, q1..q6, reachable, collides, t_s`` (``q6`` empty for the five-axis R5150;
    ``collides`` 1 for a waypoint in collision, empty when the plan was not checked: ``--collisions``; ``t_s``
    the time the robot reaches the waypoint in the cell's schedule, empty without ``--collisions``).
``areas.csv``
    One row a face of the painted surface: ``face, area, direction, robot, robot_index``.
``areas.png``, ``film.png``, ``film_timed.png``
    Pictures: the robot of each face, the film, and the film at the robots' timed speeds (with a film target
    and timing) (``cells.pictures``).
``cell.html``
    The 3D viewer (``view.cell_html``): the film, each robot's faces, strokes, base and track, the waypoints
    unreached or in collision; one self-contained page.
``thickness.ply``, ``thickness.csv``, ``coating.json``
    The whole body's film, as ``sprayplan plan`` writes them (``export.film``); ``coating.json`` is the film
    part of the report.
"""

from __future__ import annotations

import json
import os

import numpy as np

from sprayplan.config import job_to_dict
from sprayplan.export.files import atomic_output

FORMAT = "sprayplan-cell-plan"
VERSION = 2
#: The versions :func:`read_cell_plan` reads: version 1 gave one roll a stroke (``roll_deg`` a number), version 2
#: one a waypoint (a transfer's ends take their neighbours' rolls: ``cells.work.joined_transfers``).
READ_VERSIONS = (1, 2)
#: The files a cell plan writes into its folder.
CELL_FILES = (
    "cell_plan.json", "waypoints.csv", "areas.csv", "areas.png", "thickness.ply", "thickness.csv", "coating.json",
    "film.png", "film_timed.png", "cell.html",
)  # fmt: skip
WAYPOINT_COLUMNS = [
    "robot", "stroke", "waypoint", "kind", "area", "x_mm", "y_mm", "z_mm", "nx", "ny", "nz", "dwell", "track_mm",
    "roll_deg", *(f"q{i + 1}" for i in range(6)), "reachable", "collides", "t_s",
]  # fmt: skip


def _clean(value):
    """JSON-ready: numpy to Python, NaN and inf to None."""
    if isinstance(value, dict):
        return {str(k): _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    if isinstance(value, np.ndarray):
        return _clean(value.tolist())
    if isinstance(value, (np.floating, float)):
        return float(value) if np.isfinite(value) else None
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (np.bool_,)):
        return bool(value)
    return value


def cell_plan_dict(plan) -> dict:
    """``cell_plan.json``'s content (module docstring)."""
    cell = plan.cell
    robots = []
    for cr in cell.robots:
        entry = {
            "name": cr.name,
            "model": cr.model,
            "tool": cr.tool,
            "base2cell": cr.base2cell,
            "reach_mm": cr.reach_mm,
        }
        if cr.track is not None:
            entry["track"] = {
                "axis": cr.track.axis,
                "range_mm": list(cr.track.range_mm),
                "speed_mm_s": cr.track.speed_mm_s,
            }
        robots.append(entry)
    a = plan.areas
    areas = (
        []
        if a is None
        else [
            {
                "name": a.names[k],
                "direction": a.direction[k],
                "area_mm2": round(float(a.area_mm2[k]), 3),
                "robot": cell.robots[r].name if (r := int(plan.assignment.area_robot[k])) >= 0 else None,
                "share_reached": round(float(plan.assignment.area_share[k]), 6),
                "split": bool(plan.assignment.split[k]),
            }
            for k in range(len(a or ()))
        ]
    )
    work = []
    for r in plan.robots:
        strokes, at = [], 0
        flags = r.collides
        for i, s in enumerate(r.strokes):
            n = len(s)
            strokes.append(
                {
                    "kind": s.kind,
                    "area": int(r.area[i]),
                    "roll_deg": np.round(r.roll_deg[at : at + n], 9),
                    "track_mm": np.round(r.track_mm[at : at + n], 6),
                    "tcp_mm": np.round(s.tcp, 6),
                    "normals": np.round(s.normals, 9),
                    "points_mm": np.round(s.points, 6),
                    "dwell": np.round(s.dwell, 9),
                    "q_rad": np.round(r.q[at : at + n], 12),
                    "reachable": r.reachable[at : at + n],
                    **({} if flags is None else {"collides": flags[at : at + n]}),
                    **({} if r.t_s is None else {"t_s": np.round(r.t_s[at : at + n], 6), "wait_s": r.wait_s[i]}),
                }
            )
            at += n
        ends = {}
        if r.ends_q is not None:
            ends = {"schedule_ends": {"q_rad": np.round(r.ends_q, 12), "track_mm": np.round(r.ends_track_mm, 6)}}
            if r.park_route_q is not None:
                ends["schedule_ends"]["park_route"] = {
                    "q_rad": np.round(r.park_route_q, 12),
                    "track_mm": np.round(r.park_route_track_mm, 6),
                }
        if r.lead_q is not None:
            ends["leads"] = _leads_entry(r)
        work.append({"name": r.name, "model": r.model, "strokes": strokes, **ends})
    return _clean(
        {
            "format": FORMAT,
            "version": VERSION,
            "cell": {"name": cell.name, "source": cell.source, "floor_z_mm": cell.floor_z_mm, "robots": robots},
            "part": {"name": plan.part.name if plan.part is not None else plan.name, "part2cell": plan.part2cell},
            "areas": areas,
            "robots": work,
            "report": plan.report,
            "timings_s": plan.timings_s,
            **({} if plan.job is None else {"settings": job_to_dict(plan.job)}),
        }
    )


def write_cell_plan(outdir, plan, target_um: float = 50.0, tolerance_um: float = 5.0) -> list[str]:
    """Write a cell plan's files into ``outdir`` (an existing folder; module docstring). Returns the paths."""
    from sprayplan.export.film import write_thickness_csv, write_thickness_ply
    from sprayplan.export.tables import write_table

    outdir = os.fspath(outdir)
    written = []
    path = os.path.join(outdir, "cell_plan.json")
    with atomic_output(path, "w", encoding="utf-8") as handle:
        handle.write(json.dumps(cell_plan_dict(plan), separators=(",", ":")))
        handle.write("\n")
    written.append(path)
    rows = []
    for r in plan.robots:
        at = 0
        flags = r.collides
        for i, s in enumerate(r.strokes):
            for j in range(len(s)):
                q = [*np.round(r.q[at + j], 9), *([None] * (6 - r.q.shape[1]))]
                rows.append(
                    [r.name, i, j, s.kind, int(r.area[i]), *np.round(s.tcp[j], 4), *np.round(s.normals[j], 6),
                     round(float(s.dwell[j]), 6), round(float(r.track_mm[at + j]), 4), round(float(r.roll_deg[at + j]), 9),
                     *q, int(r.reachable[at + j]), None if flags is None else int(flags[at + j]),
                     None if r.t_s is None else round(float(r.t_s[at + j]), 6)]
                )  # fmt: skip
            at += len(s)
    path = os.path.join(outdir, "waypoints.csv")
    write_table(path, WAYPOINT_COLUMNS, rows)
    written.append(path)
    if plan.areas is not None:
        names = [cr.name for cr in plan.cell.robots]
        fr = plan.assignment.face_robot
        area_rows = [
            [f, plan.areas.names[k], plan.areas.direction[k], names[fr[f]] if fr[f] >= 0 else "", int(fr[f])]
            for f, k in enumerate(plan.areas.face_area.tolist())
        ]
        path = os.path.join(outdir, "areas.csv")
        write_table(path, ["face", "area", "direction", "robot", "robot_index"], area_rows)
        written.append(path)
        from sprayplan.cells.pictures import areas_picture

        path = os.path.join(outdir, "areas.png")
        areas_picture(path, plan)
        written.append(path)
    if plan.film is not None:
        from sprayplan.cells.pictures import film_picture

        path = os.path.join(outdir, "film.png")
        film_picture(path, plan, target_um, tolerance_um)
        written.append(path)
        if getattr(plan, "timed_film", None) is not None:
            path = os.path.join(outdir, "film_timed.png")
            film_picture(path, plan, target_um, tolerance_um, timed=True)
            written.append(path)
        for name, write in (("thickness.ply", None), ("thickness.csv", write_thickness_csv)):
            path = os.path.join(outdir, name)
            if write is None:
                write_thickness_ply(path, plan.film, target_um, tolerance_um)
            else:
                write(path, plan.film)
            written.append(path)
        path = os.path.join(outdir, "coating.json")
        with atomic_output(path, "w", encoding="utf-8") as handle:
            json.dump(_clean(plan.report.get("film", {})), handle, indent=1)
            handle.write("\n")
        written.append(path)
    if plan.part is not None:
        from sprayplan.view.cell_html import cell_viewer_html

        path = os.path.join(outdir, "cell.html")
        page, _ = cell_viewer_html(plan, target_um, tolerance_um)
        with atomic_output(path, "w", encoding="utf-8") as handle:
            handle.write(page)
        written.append(path)
    return written


def read_cell_plan(path) -> dict:
    """``cell_plan.json`` read back, with each stroke's arrays as numpy arrays (``tcp_mm``, ``normals``,
    ``points_mm``, ``dwell``, ``track_mm``, ``q_rad``, ``reachable``) and the robots' ``base2cell`` as (4, 4).

    Raises
    ------
    PartFileError
        Not a cell plan, another version, or a broken file (the message names the file).
    """
    from sprayplan.errors import PartFileError
    from sprayplan.export.files import read_json_file

    data = read_json_file(path, FORMAT, "cell plan", versions=READ_VERSIONS)

    try:
        for r in data["cell"]["robots"]:
            r["base2cell"] = np.array(r["base2cell"], dtype=float).reshape(4, 4)
        data["part"]["part2cell"] = np.array(data["part"]["part2cell"], dtype=float).reshape(4, 4)
        for r in data["robots"]:
            for s in r["strokes"]:
                for key in ("tcp_mm", "normals", "points_mm"):
                    s[key] = np.array(s[key], dtype=float).reshape(-1, 3)
                s["dwell"] = np.array(s["dwell"], dtype=float)
                s["roll_deg"] = np.broadcast_to(np.asarray(s["roll_deg"], float), (len(s["tcp_mm"]),)).copy()
                s["track_mm"] = np.array(s["track_mm"], dtype=float)
                s["q_rad"] = np.array([[np.nan if v is None else v for v in row] for row in s["q_rad"]], float)
                s["q_rad"] = s["q_rad"].reshape(len(s["tcp_mm"]), -1)
                s["reachable"] = np.array(s["reachable"], dtype=bool)
                if "collides" in s:
                    s["collides"] = np.array(s["collides"], dtype=bool)
                if "t_s" in s:
                    s["t_s"] = np.array(s["t_s"], dtype=float)
    except (KeyError, TypeError, ValueError) as exc:
        raise PartFileError(path, f"not a readable cell plan ({exc})") from None
    return data


def cell_plan_from_file(path):
    """A cell plan folder's ``cell_plan.json`` as a ``cells.plan.CellPlan`` with what the robot programs need
    (the cell, each robot's strokes, joints, track positions, flags, waits, and ``job``: the settings it was made
    with); no part, areas or film.

    Raises
    ------
    PartFileError
        Not a readable cell plan, or one written before the settings were kept (plan it again).
    """
    from sprayplan.cells.plan import CellPlan, RobotWork
    from sprayplan.cells.spec import Cell, CellRobot, Track
    from sprayplan.config import job_from_dict
    from sprayplan.errors import ConfigError, PartFileError
    from sprayplan.types import Stroke

    data = read_cell_plan(path)
    if "settings" not in data:
        raise PartFileError(path, "holds no settings (written by an older sprayplan): plan it again")
    try:
        job = job_from_dict(data["settings"])
        robots = []
        for r in data["cell"]["robots"]:
            track = r.get("track")
            if track is not None:
                track = Track(np.asarray(track["axis"], float), tuple(track["range_mm"]), float(track["speed_mm_s"]))
            reach = r["reach_mm"] if r["reach_mm"] is not None else float("nan")
            robots.append(CellRobot(r["name"], r["model"], r["tool"], r["base2cell"], float(reach), track))
        cell = Cell(data["cell"]["name"], tuple(robots), float(data["cell"]["floor_z_mm"]))
        works = []
        for entry in data["robots"]:
            strokes, area, roll, track_mm, q, reach, hit, waits, times = [], [], [], [], [], [], [], [], []
            flags = all("collides" in st for st in entry["strokes"])
            timed = all("t_s" in st for st in entry["strokes"])
            for st in entry["strokes"]:
                kind = st["kind"]
                strokes.append(Stroke(st["points_mm"], st["normals"], st["tcp_mm"], spray_on=kind != "transfer",
                                      on_part=np.zeros(len(st["tcp_mm"]), bool) if kind == "transfer" else None,
                                      dwell=st["dwell"], kind=kind))  # fmt: skip
                area.append(st["area"])
                roll.append(st["roll_deg"])
                track_mm.append(st["track_mm"])
                q.append(np.nan_to_num(st["q_rad"]))
                reach.append(st["reachable"])
                hit.append(st.get("collides", np.zeros(len(st["tcp_mm"]), bool)))
                times.append(st.get("t_s", np.zeros(len(st["tcp_mm"]))))
                waits.append(st.get("wait_s") or 0.0)
            ends = entry.get("schedule_ends")
            leads = _leads_of(entry.get("leads"), sum(len(st["tcp_mm"]) for st in entry["strokes"]))
            works.append(
                RobotWork(
                    entry["name"], entry["model"], tuple(strokes), np.asarray(area, int), np.concatenate(track_mm),
                    np.concatenate(roll), np.concatenate(q), np.concatenate(reach),
                    np.concatenate(hit) if flags else None, np.concatenate(times) if timed else None,
                    np.asarray(waits, float) if timed else None,
                    None if ends is None else np.asarray(ends["q_rad"], float).reshape(2, -1),
                    None if ends is None else np.asarray(ends["track_mm"], float).reshape(2),
                    *leads,
                    *_park_route_of(ends),
                )
            )  # fmt: skip
    except (KeyError, TypeError, ValueError, ConfigError) as exc:
        raise PartFileError(path, f"not a readable cell plan ({exc})") from None
    name = data["part"]["name"]
    return CellPlan(cell, None, data["part"]["part2cell"], None, None, tuple(works), None, data["report"], {}, name,
                    job=job)  # fmt: skip


def _park_route_of(ends: dict | None) -> tuple:
    """``(park_route_q, park_route_track_mm)`` of a robot's ``schedule_ends`` (None, None without a route)."""
    route = None if ends is None else ends.get("park_route")
    if route is None:
        return None, None
    q = np.asarray(route["q_rad"], float)
    return q.reshape(len(q), -1), np.asarray(route["track_mm"], float).reshape(len(q))


def _leads_entry(work) -> dict:
    """A robot's run-ups and run-outs (``RobotWork.lead_q``) as cell_plan.json keeps them: for each, its
    waypoint (over the robot's strokes one after another), its side (0 a run-up before the waypoint, 1 a
    run-out after it), joints, track position and time (0 untimed)."""
    has = np.isfinite(work.lead_q).all(axis=2)
    way, side = np.nonzero(has)
    times = np.zeros(len(way)) if work.lead_s is None else work.lead_s[way, side]
    return {
        "waypoint": way,
        "side": side,
        "q_rad": np.round(work.lead_q[way, side], 12),
        "track_mm": np.round(work.lead_track_mm[way, side], 6),
        "t_s": np.round(times, 6),
    }


def _leads_of(entry, n: int) -> tuple:
    """``(lead_q, lead_track_mm, lead_s)`` of a cell_plan.json robot's ``leads`` (:func:`_leads_entry`); Nones
    without."""
    if entry is None:
        return None, None, None
    way = np.asarray(entry["waypoint"], int).reshape(-1)
    side = np.asarray(entry["side"], int).reshape(-1)
    q = np.asarray(entry["q_rad"], float).reshape(len(way), -1)
    if len(way) and (way.min() < 0 or way.max() >= n or not set(side.tolist()) <= {0, 1}):
        raise ValueError("a run-up of a waypoint the robot does not have")
    lead_q = np.full((n, 2, q.shape[1] if len(way) else 6), np.nan)
    lead_track, lead_s = np.full((n, 2), np.nan), np.zeros((n, 2))
    lead_q[way, side] = q
    lead_track[way, side] = np.asarray(entry["track_mm"], float).reshape(-1)
    lead_s[way, side] = np.asarray(entry["t_s"], float).reshape(-1)
    return lead_q, lead_track, lead_s
