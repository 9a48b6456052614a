"""plan.json and waypoints.csv: the main job's output (schema in docs/plan-json.md; read back by
``export.plan_read``)."""

from __future__ import annotations

import json
import os
from itertools import chain

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


#: The encoder of plan.json: ``json.dumps(value, separators=(",", ":"), allow_nan=False)``, made once.
_JSON = json.JSONEncoder(separators=(",", ":"), allow_nan=False)


def _floats_json(array) -> str:
    """The JSON text of :func:`_floats` of ``array``, the same characters as ``json.dumps`` writes for it
    (compact): ``str`` of a list writes each float's repr, as ``json`` does, with ``", "`` between the items (a
    float's repr holds no space)."""
    array = np.asarray(array, dtype=np.float64)
    finite = np.isfinite(array)
    if finite.all():
        return str(array.tolist()).replace(" ", "")
    return str(np.where(finite, array.astype(object), None).tolist()).replace(" ", "").replace("None", "null")


def _negated_json(text: str) -> str:
    """The JSON text of the negated array, from :func:`_floats_json`'s text of an array (a list, nested or
    not): a ``-`` put before every item, then taken off again before a list (or an empty list's end), a
    ``null`` and a number that had one (the repr of ``-x`` is the repr of ``x`` with its sign turned, -0.0
    included)."""
    text = text.replace(",", ",-").replace("[", "[-")
    return text.replace("-[", "[").replace("-]", "]").replace("--", "").replace("-null", "null")


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


#: The kinds of a stroke's entries (:func:`_stroke_fields`).
_AS_IS, _FLOATS, _NEGATED = 0, 1, 2


def _stroke_fields(place: int, st, i: int, s, sl: slice, job, flow: float, timing) -> list[tuple[str, object, int]]:
    """A stroke's entries in plan.json, in order: (key, value, kind): kind :data:`_FLOATS` for an array of
    floats that :func:`_floats` turns into lists, :data:`_NEGATED` for one whose negation goes in (the tool
    axis, the normals turned), :data:`_AS_IS` for a value that is JSON-ready as it is."""
    fields = [
        ("index", i, _AS_IS),
        ("spray_on", s.spray_on, _AS_IS),
        ("kind", s.kind, _AS_IS),
        ("layer", s.layer, _AS_IS),
        ("tcp", s.tcp, _FLOATS),
        ("tool_axis", s.normals, _NEGATED),
        ("points", s.points, _FLOATS),
        ("normals", s.normals, _FLOATS),
        ("on_part", s.on_part.tolist(), _AS_IS),
        ("joints", st.q9[sl], _FLOATS),
        ("reachable", st.reachable[sl].tolist(), _AS_IS),
        ("method", st.method[sl].tolist(), _AS_IS),
        ("position_error_mm", st.position_error_mm[sl], _FLOATS),
        ("axis_error_deg", st.axis_error_deg[sl], _FLOATS),
        ("branch_change", st.branch_change[sl].tolist(), _AS_IS),
        ("collision", st.collision[sl].tolist(), _AS_IS),
        ("motion_collision", st.motion_collision[sl].tolist(), _AS_IS),
        ("collision_distance_mm", st.collision_distance_mm[sl], _FLOATS),
        ("collision_with", st.collision_with[sl].tolist(), _AS_IS),
        ("repair", st.repair[sl].tolist(), _AS_IS),
        ("flow_ml_min", flow if s.spray_on else 0.0, _AS_IS),
        ("speed_mm_s", job.motion.gun_speed_mm_s if s.spray_on else job.motion.transfer_speed_mm_s, _AS_IS),
        ("tcp_speed_mm_s", tip_speeds(s, job), _FLOATS),
        ("dwell", s.dwell, _FLOATS),
    ]
    if timing is not None:
        fields.append(("t_s", timing.t_s[place][sl], _FLOATS))
        fields.append(("achievable_speed_mm_s", timing.speed_mm_s[place][sl], _FLOATS))
    return fields


def _plan_parts(plan, job, totals: dict, part_file, film, timing):
    """plan.json in three parts: the entries before ``stations`` (a dict), the stations (per station in
    visiting order: its entries before ``strokes``, with ``platform_mm`` still an array, and its strokes'
    :func:`_stroke_fields`), and the entries after them (a dict)."""
    from sprayplan.coating.stage import job_paint

    flow = float(job_paint(job).flow_ml_min)
    stations = []
    for place, st in enumerate(plan.stations):
        strokes, start = [], 0
        for i, s in enumerate(st.strokes):
            sl = slice(start, start + len(s))
            start += len(s)
            strokes.append(_stroke_fields(place, st, i, s, sl, job, flow, timing))
        stations.append(((place, st.index, st.platform_mm), strokes))
    head = {
        "format": FORMAT,
        "version": VERSION,
        "sprayplan_version": __version__,
        "units": {"length": "mm", "angle": "rad", "time": "s", "errors": "mm and deg"},
        "part": plan.name,
        "part_file": part_file,
        "settings": _clean(job_to_dict(job)),
        "joints": list(JOINTS),
        "home_mm": _floats(plan.home_mm),
    }
    tail = {
        "unassigned_points": _floats(plan.unassigned),
        "totals": _clean(totals),
        "film": None if film is None else film_summary(film),
    }
    return head, stations, tail


def _stroke_value(value, kind: int):
    """A stroke's entry (:func:`_stroke_fields`) as plan_to_dict holds it."""
    if kind == _FLOATS:
        return _floats(value)
    if kind == _NEGATED:
        return _floats(-value)
    return value


def plan_to_dict(plan, job, totals: dict, part_file: str | None = None, film: dict | None = None, timing=None) -> dict:
    """The JSON-ready form of a plan: everything :func:`plan_file_from_dict` reads back, and the derived keys a
    robot program wants (``tool_axis``, ``flow_ml_min``, ``speed_mm_s``, ``tcp_speed_mm_s``).

    ``film`` is the film report (``export.film.film_report``) or a summary of one (:func:`film_summary`).
    ``timing`` (``timing.stage.PlanTiming``, or the ``export.plan_read.WaypointTimes`` read back) adds each
    waypoint's ``t_s`` and ``achievable_speed_mm_s``.
    """
    head, stations, tail = _plan_parts(plan, job, totals, part_file, film, timing)
    stations = [
        {
            "order": place,
            "station": index,
            "platform_mm": _floats(platform),
            "strokes": [{key: _stroke_value(v, kind) for key, v, kind in fields} for fields in strokes],
        }
        for (place, index, platform), strokes in stations
    ]
    return {**head, "stations": stations, **tail}


def plan_json_text(plan, job, totals: dict, part_file: str | None = None, film: dict | None = None, timing=None) -> str:
    """plan.json's text (without its final newline): ``json.dumps(plan_to_dict(...), separators=(",", ":"),
    allow_nan=False)``, character for character, written without the dict: the stations' arrays of floats
    straight from numpy (:func:`_floats_json`), the rest by the same encoder.

    Raises
    ------
    TypeError, ValueError
        As ``json.dumps`` would: a value JSON cannot hold (a NaN or infinity outside the float arrays).
    """
    head, stations, tail = _plan_parts(plan, job, totals, part_file, film, timing)
    encode = _JSON.encode
    parts = []
    for (place, index, platform), strokes in stations:
        texts = []
        for fields in strokes:
            made = {}  # id of an array of floats: its text (the normals' for the tool axis too)
            items = []
            for key, v, kind in fields:
                if kind == _AS_IS:
                    text = encode(v)
                else:
                    text = made.get(id(v))
                    if text is None:
                        text = made[id(v)] = _floats_json(v)
                    if kind == _NEGATED:
                        text = _negated_json(text)
                items.append(f"{encode(key)}:{text}")
            texts.append("{" + ",".join(items) + "}")
        parts.append(
            f'{{"order":{encode(place)},"station":{encode(index)},"platform_mm":{_floats_json(platform)},'
            f'"strokes":[{",".join(texts)}]}}'
        )
    # head and tail are never empty: "{...}" each, joined around the stations as one object
    return f'{encode(head)[:-1]},"stations":[{",".join(parts)}],{encode(tail)[1:]}'


def write_plan(
    outdir, plan, job, totals: dict, part_file: str | None = None, film: dict | None = None, timing=None
) -> list[str]:
    """Write OUTDIR/plan.json and OUTDIR/waypoints.csv (atomically); returns the paths written.

    ``part_file`` (the part's file, made absolute) lets ``sprayplan simulate OUTDIR`` load the part again;
    ``film`` (the film report or its summary) is kept in plan.json as a summary; ``timing`` adds the time
    stamps (:func:`plan_to_dict`).
    """
    outdir = os.fspath(outdir)
    text = plan_json_text(plan, job, totals, None if part_file is None else os.path.abspath(part_file), film, timing)
    plan_path = os.path.join(outdir, "plan.json")
    with atomic_output(plan_path, "w", encoding="utf-8") as handle:
        # one string, written once (the text of plan_to_dict's dict, made without building the dict)
        handle.write(text)
        handle.write("\n")
    csv_path = os.path.join(outdir, "waypoints.csv")
    write_waypoints_csv(csv_path, plan, job, timing)
    return [plan_path, csv_path]


def _cells(values, fmt: str, blank: bool = True) -> list[str]:
    """Each value formatted with ``fmt`` (a format spec such as ``".10g"``), or "" where it is not finite.

    ``format(v, fmt)`` of each, made by one ``%`` operation over all of them (``"%" + fmt`` formats a float as
    ``format`` does) and split at the line ends between them.
    """
    values = np.asarray(values, dtype=np.float64).ravel()
    bad = np.flatnonzero(~np.isfinite(values)).tolist() if blank else []
    if len(bad) == len(values):  # all empty (a clearance not measured), or none at all
        return [""] * len(values)
    out = (("%" + fmt + "\n") * len(values) % tuple(values.tolist())).split("\n")
    out.pop()  # after the last line end
    for k in bad:
        out[k] = ""
    return out


def write_waypoints_csv(path, plan, job, timing=None) -> None:
    """Write waypoints.csv: one row per waypoint, for people (docs/plan-json.md); with ``timing``, each row's
    time stamp ``t_s`` and ``achievable_speed_mm_s`` (empty where unknown); then the collision stage's flags.

    Floats at 10 significant digits (``.10g``; errors, speed and clearance at 6), an empty cell where a value is
    not finite (the joints of an unreachable waypoint); a stroke's rows are made by one ``%`` operation (a row's
    template repeated, over the values row by row), the file written in one piece.
    """
    header = (
        "station,stroke,waypoint,spray_on,x,y,z,ax,ay,az,q1,q2,q3,q4,q5,q6,tx,ty,tz,reachable,position_error_mm,"
        "axis_error_deg,speed_mm_s"
    )
    header += ",t_s,achievable_speed_mm_s" if timing is not None else ""
    header += ",collision,motion_collision,collision_distance_mm,collision_with,repair\n"
    # the float columns left empty where not finite, in their order in a row, and their formats
    formats = [".10g"] * 15 + [".6g", ".6g"] + ([".10g", ".10g"] if timing is not None else []) + [".6g"]
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
            floats = [s.tcp, -s.normals, np.where(ok[:, None], st.q9[sl], np.nan)]
            floats += [st.position_error_mm[sl], st.axis_error_deg[sl]]
            if timing is not None:
                floats += [timing.t_s[place][sl], timing.speed_mm_s[place][sl]]
            floats.append(st.collision_distance_mm[sl])
            table = np.column_stack(floats).astype(np.float64, copy=False)
            finite = np.isfinite(table).all(axis=0).tolist()
            # (format, values) per column, as in a row: a column with a value that is not finite goes in as
            # its cells (_cells), every other one as floats that the row's template formats
            cells = [
                ("%" + fmt, values) if whole else ("%s", _cells(values, fmt))
                for fmt, values, whole in zip(formats, table.T.tolist(), finite)
            ]
            columns = [(f"{place},{i},%d,{int(s.spray_on)}", list(range(n)))]  # the same station and stroke
            columns += cells[:15]
            columns.append(("%d", ok.tolist()))
            columns += cells[15:17]
            columns.append(("%.6g", np.asarray(tip_speeds(s, job), dtype=np.float64).tolist()))  # never empty
            columns += cells[17:-1]
            columns.append(("%d", st.collision[sl].tolist()))
            columns.append(("%d", st.motion_collision[sl].tolist()))
            columns.append(cells[-1])
            columns.append(("%s", [str(w) for w in st.collision_with[sl].tolist()]))
            columns.append(("%s", [str(r) for r in st.repair[sl].tolist()]))
            row = ",".join(fmt for fmt, _ in columns) + "\n"
            lines.append((row * n) % tuple(chain.from_iterable(zip(*(values for _, values in columns)))))
    with atomic_output(path, "w", newline="") as handle:
        handle.write("".join(lines))
