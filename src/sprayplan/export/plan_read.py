"""Reading plan.json back (the writer is ``export.plan_json``; schema in docs/plan-json.md).

Everything the :class:`~sprayplan.types.Plan` holds reads back bit for bit (``null`` as NaN), with the
settings, totals, part file and film summary, so that writing the plan read gives the same file. A missing
key or a value of the wrong type is a one-line :class:`~sprayplan.errors.PartFileError` naming the file and
the key (``stations[0].strokes[3].dwell``); keys derived from the others (``tool_axis``, ``flow_ml_min``,
``speed_mm_s``, ``tcp_speed_mm_s``, ``order``, a stroke's ``index``) are not read.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from sprayplan.checks import MAX_COORDINATE_MM
from sprayplan.errors import ConfigError, PartFileError
from sprayplan.export.files import read_json_file
from sprayplan.export.plan_json import FORMAT, READS
from sprayplan.types import Plan, StationPlan, Stroke

_MISSING = object()


@dataclass(frozen=True)
class PlanFile:
    """What a plan.json holds.

    Attributes
    ----------
    plan : Plan
    job : config.JobConfig
        The settings the plan was made with.
    totals : dict
        As written (``export.summary.plan_totals`` and the refine stage's summary).
    part_file : str or None
        The part's file (absolute), when the plan was made from one.
    film : dict or None
        The film summary (``export.plan_json.film_summary``), when the plan had a film.
    timing : WaypointTimes or None
        The waypoints' time stamps and achievable speeds, when the plan was timed.
    """

    plan: Plan
    job: object
    totals: dict
    part_file: str | None = None
    film: dict | None = None
    timing: WaypointTimes | None = None


@dataclass(frozen=True)
class WaypointTimes:
    """The time stamps of a timed plan read back, per station in visiting order (``timing.stage.PlanTiming``'s
    ``t_s`` and ``speed_mm_s``; NaN where the file has null).

    Attributes
    ----------
    t_s : tuple of (n,) float, s
    speed_mm_s : tuple of (n,) float, mm/s
    """

    t_s: tuple
    speed_mm_s: tuple


def read_plan(path) -> dict:
    """Read a plan.json (as a dict), checking its format and version (``plan_json.READS``)."""
    return read_json_file(path, FORMAT, "plan", READS)


def read_plan_file(path) -> PlanFile:
    """Read a plan.json into a :class:`PlanFile`.

    Raises
    ------
    PartFileError
        The file is missing, not JSON, of another format or version, misses a key or has a wrong value; the
        message names the file and the key.
    """
    return plan_file_from_dict(read_plan(path), os.fspath(path))


def plan_from_dict(data: dict, name: str = "plan.json"):
    """The Plan and JobConfig of a plan.json read with :func:`read_plan`."""
    read = plan_file_from_dict(data, name)
    return read.plan, read.job


def plan_file_from_dict(data: dict, name: str = "plan.json") -> PlanFile:
    """A :class:`PlanFile` from a plan.json's content (``name``: the file, for messages)."""
    from sprayplan.config import job_from_dict

    r = _Reader(name)
    r.check(data, "", dict)
    try:
        job = job_from_dict(r.get(data, "settings", dict))
    except (ConfigError, TypeError, ValueError) as exc:
        raise PartFileError(name, f"settings: {exc}") from None
    rows = r.get(data, "stations", list)
    stations = tuple(_station(r, st, f"stations[{i}]") for i, st in enumerate(rows))
    timing = _times(r, rows)
    home = r.floats(r.get(data, "home_mm", list), "home_mm", (), length=3, bounded=True)
    unassigned = r.floats(r.get(data, "unassigned_points", list), "unassigned_points", (3,))
    plan = r.build(Plan, "", stations, home, unassigned, r.get(data, "part", str))
    part_file = data.get("part_file")
    r.check(part_file, "part_file", (str, type(None)))
    film = data.get("film")
    r.check(film, "film", (dict, type(None)))
    return PlanFile(plan, job, r.get(data, "totals", dict), part_file, film, timing)


def _times(r: _Reader, rows: list) -> WaypointTimes | None:
    """The strokes' ``t_s`` and ``achievable_speed_mm_s`` (all strokes have both, or none has either)."""
    strokes = [(i, k, s) for i, st in enumerate(rows) for k, s in enumerate(st["strokes"])]
    timed = [("t_s" in s) + ("achievable_speed_mm_s" in s) for _, _, s in strokes]
    if not any(timed):
        return None
    times, speeds = [], []
    for i, st in enumerate(rows):
        t, v = [], []
        for k, s in enumerate(st["strokes"]):
            at = f"stations[{i}].strokes[{k}]"
            n = len(s["points"])
            t.append(r.floats(r.get(s, "t_s", list, at), f"{at}.t_s", (), n))
            v.append(r.floats(r.get(s, "achievable_speed_mm_s", list, at), f"{at}.achievable_speed_mm_s", (), n))
        times.append(np.concatenate(t) if t else np.zeros(0))
        speeds.append(np.concatenate(v) if v else np.zeros(0))
    return WaypointTimes(tuple(times), tuple(speeds))


#: The stroke arrays that place and time the gun: bounded by ``checks.MAX_COORDINATE_MM`` on reading, so that a
#: broken file cannot make the film's or the kinematics' arithmetic overflow.
_BOUNDED = ("points", "normals", "tcp", "dwell")

_STROKE_ARRAYS = (("points", (3,)), ("normals", (3,)), ("tcp", (3,)), ("dwell", ()))
_STATION_FLOATS = (("joints", (9,)), ("position_error_mm", ()), ("axis_error_deg", ()))


#: The collision stage's per-waypoint keys of a stroke (``StationPlan`` fields of the same names), optional.
_COLLISION = {
    "collision": bool,
    "motion_collision": bool,
    "collision_distance_mm": float,
    "collision_with": str,
    "repair": str,
}


def _station(r: _Reader, st, where: str) -> StationPlan:
    r.check(st, where, dict)
    strokes, methods = [], []
    keys = ("joints", "reachable", "position_error_mm", "axis_error_deg", "branch_change", *_COLLISION)
    parts: dict = {key: [] for key in keys}
    for i, s in enumerate(r.get(st, "strokes", list, where)):
        at = f"{where}.strokes[{i}]"
        r.check(s, at, dict)
        n = len(r.get(s, "points", list, at))
        arrays = {
            key: r.floats(r.get(s, key, list, at), f"{at}.{key}", tail, n, bounded=key in _BOUNDED)
            for key, tail in _STROKE_ARRAYS
        }
        strokes.append(
            r.build(
                Stroke,
                at,
                arrays["points"],
                arrays["normals"],
                arrays["tcp"],
                r.get(s, "spray_on", bool, at),
                r.flags(r.get(s, "on_part", list, at), f"{at}.on_part", n),
                r.get(s, "layer", int, at),
                arrays["dwell"],
                r.get(s, "kind", str, at),
            )
        )
        for key, tail in _STATION_FLOATS:
            parts[key].append(r.floats(r.get(s, key, list, at), f"{at}.{key}", tail, n))
        for key in ("reachable", "branch_change"):
            parts[key].append(r.flags(r.get(s, key, list, at), f"{at}.{key}", n))
        methods += r.strings(r.get(s, "method", list, at), f"{at}.method", n)
        for key, kind in _COLLISION.items():  # absent from files written before the collision checks
            if key not in s:
                empty = {bool: False, float: np.nan, str: ""}[kind]
                parts[key].append(np.full(n, empty, dtype=object if kind is str else kind))
            elif kind is bool:
                parts[key].append(r.flags(r.get(s, key, list, at), f"{at}.{key}", n))
            elif kind is float:
                parts[key].append(r.floats(r.get(s, key, list, at), f"{at}.{key}", (), n))
            else:
                parts[key].append(np.array(r.strings(r.get(s, key, list, at), f"{at}.{key}", n), dtype=object))
    joined = {key: np.concatenate(p) if p else np.zeros(0) for key, p in parts.items()}
    return r.build(
        StationPlan,
        where,
        r.get(st, "station", int, where),
        r.floats(r.get(st, "platform_mm", list, where), f"{where}.platform_mm", (), length=3, bounded=True),
        tuple(strokes),
        joined["joints"],
        joined["reachable"],
        np.array(methods, dtype=object),
        joined["position_error_mm"],
        joined["axis_error_deg"],
        joined["branch_change"],
        *(joined[key] for key in _COLLISION),
    )


_KIND_NAMES = {dict: "an object", list: "a list", str: "a string", int: "a whole number", bool: "true or false"}


class _Reader:
    """Checked access to a plan.json's content: every failure is a PartFileError naming the file and key."""

    def __init__(self, name: str):
        self.name = name

    def fail(self, where: str, problem: str):
        raise PartFileError(self.name, f"{where}: {problem}" if where else problem)

    def check(self, value, where: str, kind):
        kinds = kind if isinstance(kind, tuple) else (kind,)
        # bool is an int in Python, not in JSON: a whole number must not be true or false
        ok = any(type(value) is k if k in (int, bool) else isinstance(value, k) for k in kinds)
        if not ok:
            want = " or ".join(_KIND_NAMES.get(k, "null") for k in kinds)
            self.fail(where, f"must be {want}, got {_json_type(value)}")
        return value

    def get(self, table: dict, key: str, kind, where: str = ""):
        path = f"{where}.{key}" if where else key
        value = table.get(key, _MISSING)
        if value is _MISSING:
            self.fail("", f"missing key {path}")
        return self.check(value, path, kind)

    def floats(
        self, values: list, where: str, tail: tuple, length: int | None = None, bounded: bool = False
    ) -> np.ndarray:
        """A float array of shape (length, *tail) from JSON numbers, null read as NaN; ``bounded``: the gun's
        geometry (positions, normals, platform), which must lie within ``MAX_COORDINATE_MM``."""
        try:
            cells = np.array(values, dtype=object) if len(values) else np.zeros((0, *tail), dtype=object)
        except ValueError:
            cells = np.zeros((0, 0), dtype=object)  # ragged: reported below
        if cells.shape[1:] != tail or (length is not None and len(cells) != length):
            want = f"{'n' if length is None else length} " + ("numbers" if not tail else f"lists of {tail[0]} numbers")
            self.fail(where, f"must be {want}, got {_describe(values)}")
        bad = next((v for v in cells.flat if v is not None and type(v) not in (int, float)), _MISSING)
        if bad is not _MISSING:
            self.fail(where, f"must hold numbers or null, got {_json_type(bad)}")
        try:
            array = np.array(cells, dtype=np.float64).reshape(cells.shape)
        except OverflowError:
            self.fail(where, "holds a number too large for a float")
        with np.errstate(invalid="ignore"):
            beyond = np.abs(array) > MAX_COORDINATE_MM if bounded else np.zeros(array.shape, bool)
        if beyond.any():
            self.fail(where, f"holds {array[beyond].flat[0]:g}, beyond the plausible {MAX_COORDINATE_MM:g}")
        return array

    def flags(self, values: list, where: str, length: int) -> np.ndarray:
        return np.array(self._items(values, where, length, bool), dtype=bool)

    def strings(self, values: list, where: str, length: int) -> list:
        return self._items(values, where, length, str)

    def _items(self, values: list, where: str, length: int, kind) -> list:
        if len(values) != length:
            self.fail(where, f"must have {length} entries (one per waypoint), got {len(values)}")
        for v in values:
            if type(v) is not kind:
                self.fail(where, f"must hold {_KIND_NAMES[kind]}, got {_json_type(v)}")
        return values

    def build(self, cls, where: str, *args):
        """``cls(*args)``, its validation failures named by ``where``."""
        try:
            return cls(*args)
        except ValueError as exc:
            self.fail(where, str(exc))


def _json_type(value) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    return {dict: "an object", list: "a list", str: "a string", int: "a number", float: "a number"}.get(
        type(value), type(value).__name__
    )


def _describe(values) -> str:
    if not isinstance(values, list):
        return _json_type(values)
    lengths = sorted({len(v) if isinstance(v, list) else -1 for v in values})
    inner = ", ".join("non-lists" if n < 0 else f"lists of {n}" for n in lengths)
    return f"{len(values)} entries ({inner})" if values else "an empty list"
