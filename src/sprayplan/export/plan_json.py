"""plan.json and waypoints.csv: the main job's output (schema in docs/plan-json.md)."""

from __future__ import annotations

import json
import os

import numpy as np

from sprayplan import __version__
from sprayplan.config import job_from_dict, job_to_dict
from sprayplan.export.files import atomic_output, read_json_file
from sprayplan.paths.speed import waypoint_speeds

FORMAT = "sprayplan.plan"
VERSION = 1


def _clean(value):
    """JSON-ready: tuples to lists, NaN to None."""
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value


def _round(array, digits):
    """Rounded nested lists, with None for NaN."""
    rounded = np.round(np.asarray(array, dtype=float), digits)
    missing = ~np.isfinite(rounded)
    if not missing.any():
        return rounded.tolist()
    return np.where(missing, None, rounded.astype(object)).tolist()


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


def plan_to_dict(plan, job, totals: dict, part_file: str | None = None) -> dict:
    """The JSON-ready form of a plan."""
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
                    "tcp": _round(s.tcp, 4),
                    "tool_axis": _round(-s.normals, 7),
                    "points": _round(s.points, 4),
                    "normals": _round(s.normals, 7),
                    "on_part": s.on_part.tolist(),
                    "joints": _round(st.q9[sl], 7),
                    "reachable": st.reachable[sl].tolist(),
                    "method": st.method[sl].tolist(),
                    "position_error_mm": _round(st.position_error_mm[sl], 6),
                    "axis_error_deg": _round(st.axis_error_deg[sl], 6),
                    "branch_change": st.branch_change[sl].tolist(),
                    "flow_ml_min": flow if s.spray_on else 0.0,
                    "speed_mm_s": job.motion.gun_speed_mm_s if s.spray_on else job.motion.transfer_speed_mm_s,
                    "tcp_speed_mm_s": _round(tip_speeds(s, job), 3),
                    "dwell": _round(s.dwell, 6),
                }
            )
        stations.append(
            {"order": place, "station": st.index, "platform_mm": _round(st.platform_mm, 3), "strokes": strokes}
        )
    return {
        "format": FORMAT,
        "version": VERSION,
        "sprayplan_version": __version__,
        "units": {"length": "mm", "angle": "rad", "time": "s", "errors": "mm and deg"},
        "part": plan.name,
        "part_file": part_file,
        "settings": _clean(job_to_dict(job)),
        "joints": ["q1", "q2", "q3", "q4", "q5", "q6", "tx", "ty", "tz"],
        "home_mm": _round(plan.home_mm, 3),
        "stations": stations,
        "unassigned_points": _round(plan.unassigned, 4) if len(plan.unassigned) else [],
        "totals": _clean(totals),
    }


def write_plan(outdir, plan, job, totals: dict, part_file: str | None = None) -> list[str]:
    """Write OUTDIR/plan.json and OUTDIR/waypoints.csv (atomically); returns the paths written.

    ``part_file`` (the part's file, made absolute) lets ``sprayplan simulate OUTDIR`` load the part again.
    """
    outdir = os.fspath(outdir)
    data = plan_to_dict(plan, job, totals, None if part_file is None else os.path.abspath(part_file))
    plan_path = os.path.join(outdir, "plan.json")
    with atomic_output(plan_path, "w", encoding="utf-8") as handle:
        json.dump(data, handle, separators=(",", ":"))
        handle.write("\n")
    csv_path = os.path.join(outdir, "waypoints.csv")
    header = "station,stroke,waypoint,spray_on,x,y,z,ax,ay,az,q1,q2,q3,q4,q5,q6,tx,ty,tz,reachable,position_error_mm,axis_error_deg,speed_mm_s\n"
    with atomic_output(csv_path, "w", newline="") as handle:
        handle.write(header)
        for place, st in enumerate(plan.stations):
            start = 0
            for i, s in enumerate(st.strokes):
                n = len(s)
                q = st.q9[start : start + n]
                ok = st.reachable[start : start + n]
                table = np.column_stack(
                    [
                        np.full(n, place),
                        np.full(n, i),
                        np.arange(n),
                        np.full(n, int(s.spray_on)),
                        s.tcp,
                        -s.normals,
                        np.where(ok[:, None], q, np.nan),
                        ok.astype(int),
                        st.position_error_mm[start : start + n],
                        st.axis_error_deg[start : start + n],
                        tip_speeds(s, job),
                    ]
                )
                for row in table:
                    cells = (
                        [f"{int(v)}" for v in row[:4]]
                        + ["" if not np.isfinite(v) else f"{v:.10g}" for v in row[4:19]]
                        + [f"{int(row[19])}"]
                        + ["" if not np.isfinite(v) else f"{v:.6g}" for v in row[20:22]]
                        + [f"{row[22]:.6g}"]
                    )
                    handle.write(",".join(cells) + "\n")
                start += n
    return [plan_path, csv_path]


def read_plan(path) -> dict:
    """Read a plan.json (as a dict), checking its format."""
    return read_json_file(path, FORMAT, "plan")


def plan_from_dict(data: dict):
    """The Plan and JobConfig of a plan.json read with :func:`read_plan` (enough to simulate its film)."""
    from sprayplan.types import Plan, StationPlan, Stroke

    job = job_from_dict(data["settings"])
    stations = []
    for st in data["stations"]:
        strokes = []
        fields = {
            k: [] for k in ("joints", "reachable", "method", "position_error_mm", "axis_error_deg", "branch_change")
        }
        for s in st["strokes"]:
            strokes.append(
                Stroke(
                    np.array(s["points"], float),
                    np.array(s["normals"], float),
                    np.array(s["tcp"], float),
                    bool(s["spray_on"]),
                    np.array(s["on_part"], bool),
                    int(s["layer"]),
                    np.array(s["dwell"], float) if "dwell" in s else None,
                    s.get("kind", ""),
                )
            )
            for key, values in fields.items():
                values += s[key]
        n = len(fields["joints"])
        stations.append(
            StationPlan(
                int(st["station"]),
                np.array(st["platform_mm"], float),
                tuple(strokes),
                np.array(
                    [[np.nan] * 9 if q is None else [np.nan if v is None else v for v in q] for q in fields["joints"]],
                    float,
                ).reshape(n, 9),
                np.array(fields["reachable"], bool),
                np.array(fields["method"], object),
                _numbers(fields["position_error_mm"]),
                _numbers(fields["axis_error_deg"]),
                np.array(fields["branch_change"], bool),
            )
        )
    unassigned = np.array(data.get("unassigned_points") or np.zeros((0, 3)), float).reshape(-1, 3)
    return Plan(tuple(stations), np.array(data["home_mm"], float), unassigned, data.get("part", "")), job


def _numbers(values) -> np.ndarray:
    """A float array from JSON numbers, None read as NaN."""
    return np.array([np.nan if v is None else v for v in values], float)
