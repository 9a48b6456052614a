"""plan.json and waypoints.csv: the main job's output (schema in docs/plan-json.md; read back by
``export.plan_read``)."""

from __future__ import annotations

import json
import os

import numpy as np

from sprayplan import __version__
from sprayplan.config import job_to_dict
from sprayplan.export.files import atomic_output
from sprayplan.paths.speed import waypoint_speeds

FORMAT = "sprayplan.plan"
#: 2: the settings by stage (``config.job_to_dict``) instead of one [plan] table; floats at full precision;
#: every field of the Plan (``q9`` of unreachable waypoints included) and a ``film`` summary.
VERSION = 2
#: The versions :func:`read_plan` reads.
READS = (2,)

JOINTS = ["q1", "q2", "q3", "q4", "q5", "q6", "tx", "ty", "tz"]


def _clean(value):
    """JSON-ready: tuples to lists, numpy scalars to Python ones, NaN and inf to None."""
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    if isinstance(value, np.ndarray):
        return _clean(value.tolist())
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if np.isfinite(value) else None
    return value


def _floats(array):
    """Nested lists of Python floats at full precision (``json`` writes their repr, which reads back to the same
    bits), with None for NaN and inf."""
    array = np.asarray(array, dtype=np.float64)
    finite = np.isfinite(array)
    if finite.all():
        return array.tolist()
    return np.where(finite, array.astype(object), None).tolist()


def film_summary(report: dict) -> dict:
    """The compact form of a film report (``export.film.film_report``) kept in plan.json: the process, the spec,
    the statistics of the painted and of all samples (and the interior and measuring points when reported,
    without the points' indices) and the paint totals; not the per-stroke table."""
    out = {}
    for key in ("process", "spec", "painted", "all", "interior", "measuring_points", "paint"):
        if key in report:
            value = report[key]
            out[key] = {k: v for k, v in value.items() if k != "indices"} if isinstance(value, dict) else value
    return _clean(out)


def tip_speeds(stroke, job) -> np.ndarray:
    """(n,) gun-tip speed on the way to each waypoint of a stroke, mm/s (``sprayplan.paths.speed``)."""
    settings = job.motion
    if not stroke.spray_on:
        return np.full(len(stroke), settings.transfer_speed_mm_s)
    return waypoint_speeds(
        stroke.tcp,
        stroke.points,
        settings.gun_speed_mm_s,
        settings.speed_along,
        settings.max_speed_ratio,
        stroke.dwell,
    )


def plan_to_dict(plan, job, totals: dict, part_file: str | None = None, film: dict | None = None, timing=None) -> dict:
    """The JSON-ready form of a plan: everything :func:`plan_file_from_dict` reads back, and the derived keys a
    robot program wants (``tool_axis``, ``flow_ml_min``, ``speed_mm_s``, ``tcp_speed_mm_s``).

    ``film`` is the film report (``export.film.film_report``) or a summary of one (:func:`film_summary`).
    ``timing`` (``timing.stage.PlanTiming``, or the ``export.plan_read.WaypointTimes`` read back) adds each
    waypoint's ``t_s`` and ``achievable_speed_mm_s``.
    """
    from sprayplan.coating import load_preset

    flow = float(load_preset(job.coating.process).flow_ml_min)
    stations = []
    for place, st in enumerate(plan.stations):
        strokes, start = [], 0
        for i, s in enumerate(st.strokes):
            sl = slice(start, start + len(s))
            start += len(s)
            strokes.append(
                {
                    "index": i,
                    "spray_on": s.spray_on,
                    "kind": s.kind,
                    "layer": s.layer,
                    "tcp": _floats(s.tcp),
                    "tool_axis": _floats(-s.normals),
                    "points": _floats(s.points),
                    "normals": _floats(s.normals),
                    "on_part": s.on_part.tolist(),
                    "joints": _floats(st.q9[sl]),
                    "reachable": st.reachable[sl].tolist(),
                    "method": st.method[sl].tolist(),
                    "position_error_mm": _floats(st.position_error_mm[sl]),
                    "axis_error_deg": _floats(st.axis_error_deg[sl]),
                    "branch_change": st.branch_change[sl].tolist(),
                    "collision": st.collision[sl].tolist(),
                    "motion_collision": st.motion_collision[sl].tolist(),
                    "collision_distance_mm": _floats(st.collision_distance_mm[sl]),
                    "collision_with": st.collision_with[sl].tolist(),
                    "repair": st.repair[sl].tolist(),
                    "flow_ml_min": flow if s.spray_on else 0.0,
                    "speed_mm_s": job.motion.gun_speed_mm_s if s.spray_on else job.motion.transfer_speed_mm_s,
                    "tcp_speed_mm_s": _floats(tip_speeds(s, job)),
                    "dwell": _floats(s.dwell),
                }
            )
            if timing is not None:
                strokes[-1]["t_s"] = _floats(timing.t_s[place][sl])
                strokes[-1]["achievable_speed_mm_s"] = _floats(timing.speed_mm_s[place][sl])
        stations.append(
            {"order": place, "station": st.index, "platform_mm": _floats(st.platform_mm), "strokes": strokes}
        )
    return {
        "format": FORMAT,
        "version": VERSION,
        "sprayplan_version": __version__,
        "units": {"length": "mm", "angle": "rad", "time": "s", "errors": "mm and deg"},
        "part": plan.name,
        "part_file": part_file,
        "settings": _clean(job_to_dict(job)),
        "joints": list(JOINTS),
        "home_mm": _floats(plan.home_mm),
        "stations": stations,
        "unassigned_points": _floats(plan.unassigned),
        "totals": _clean(totals),
        "film": None if film is None else film_summary(film),
    }


def write_plan(
    outdir, plan, job, totals: dict, part_file: str | None = None, film: dict | None = None, timing=None
) -> list[str]:
    """Write OUTDIR/plan.json and OUTDIR/waypoints.csv (atomically); returns the paths written.

    ``part_file`` (the part's file, made absolute) lets ``sprayplan simulate OUTDIR`` load the part again;
    ``film`` (the film report or its summary) is kept in plan.json as a summary; ``timing`` adds the time
    stamps (:func:`plan_to_dict`).
    """
    outdir = os.fspath(outdir)
    data = plan_to_dict(plan, job, totals, None if part_file is None else os.path.abspath(part_file), film, timing)
    plan_path = os.path.join(outdir, "plan.json")
    with atomic_output(plan_path, "w", encoding="utf-8") as handle:
        # one string, written once: the C encoder (json.dump writes piece by piece, several times slower)
        handle.write(json.dumps(data, separators=(",", ":"), allow_nan=False))
        handle.write("\n")
    csv_path = os.path.join(outdir, "waypoints.csv")
    write_waypoints_csv(csv_path, plan, job, timing)
    return [plan_path, csv_path]


def _cells(values, fmt: str, blank: bool = True) -> list[str]:
    """Each value formatted with ``fmt`` (a format spec such as ``".10g"``), or "" where it is not finite."""
    values = np.asarray(values, dtype=np.float64)
    out = [format(v, fmt) for v in values.tolist()]
    if blank:
        for k in np.flatnonzero(~np.isfinite(values)).tolist():
            out[k] = ""
    return out


def write_waypoints_csv(path, plan, job, timing=None) -> None:
    """Write waypoints.csv: one row per waypoint, for people (docs/plan-json.md); with ``timing``, each row's
    time stamp ``t_s`` and ``achievable_speed_mm_s`` (empty where unknown); then the collision stage's flags.

    Floats at 10 significant digits (``.10g``; errors, speed and clearance at 6), an empty cell where a value is
    not finite (the joints of an unreachable waypoint); each column is formatted at once and every row joined
    from them, the file written in one piece.
    """
    header = (
        "station,stroke,waypoint,spray_on,x,y,z,ax,ay,az,q1,q2,q3,q4,q5,q6,tx,ty,tz,reachable,position_error_mm,"
        "axis_error_deg,speed_mm_s"
    )
    header += ",t_s,achievable_speed_mm_s" if timing is not None else ""
    header += ",collision,motion_collision,collision_distance_mm,collision_with,repair\n"
    lines = [header]
    for place, st in enumerate(plan.stations):
        start = 0
        for i, s in enumerate(st.strokes):
            n = len(s)
            sl = slice(start, start + n)
            start += n
            if not n:
                continue
            ok = st.reachable[sl]
            floats = np.column_stack([s.tcp, -s.normals, np.where(ok[:, None], st.q9[sl], np.nan)])
            columns = [[f"{place},{i},{j},{int(s.spray_on)}" for j in range(n)]]
            columns += [_cells(floats[:, c], ".10g") for c in range(floats.shape[1])]
            columns.append([f"{int(v)}" for v in ok.tolist()])
            columns.append(_cells(st.position_error_mm[sl], ".6g"))
            columns.append(_cells(st.axis_error_deg[sl], ".6g"))
            columns.append(_cells(tip_speeds(s, job), ".6g", blank=False))
            if timing is not None:
                columns.append(_cells(timing.t_s[place][sl], ".10g"))
                columns.append(_cells(timing.speed_mm_s[place][sl], ".10g"))
            columns.append(
                [f"{int(c)},{int(m)}" for c, m in zip(st.collision[sl].tolist(), st.motion_collision[sl].tolist())]
            )
            columns.append(_cells(st.collision_distance_mm[sl], ".6g"))
            columns.append([str(w) for w in st.collision_with[sl].tolist()])
            columns.append([str(r) for r in st.repair[sl].tolist()])
            lines.append("\n".join(map(",".join, zip(*columns))) + "\n")
    with atomic_output(path, "w", newline="") as handle:
        handle.write("".join(lines))
