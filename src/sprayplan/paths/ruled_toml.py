"""Ruled-surface jobs (seed 001) read from TOML: the boundary curves and the path settings.

TOML schema (lengths in mm, angles in degrees in the file, radians inside)::

    name = "case 1"                 # optional; default: the file's stem
    [curve_a]                       # and [curve_b], both required; `type` is required
    type = "line"                   # start = [x, y, z], end = [x, y, z]
    type = "arc"                    # center = [x, y, z], radius (> 0), normal = [0, 0, 1] (default),
                                    # start_angle_deg, end_angle_deg (sweep = end - start, 0 < |sweep| <= 360)
    type = "arc"                    # or: start, mid, end = three points, the arc runs start -> mid -> end
    type = "circle"                 # center, radius, normal = [0, 0, 1], start_angle_deg = 0 (full turn, ccw)
    type = "point"                  # at = [x, y, z]
    type = "polyline"               # points = [[x, y] or [x, y, z], ...] (>= 2 distinct), z = 0 (for the 2D
                                    # points), closed = false (true: back to the first point)
    [path]                          # required
    spot_diameter_mm = 100.0        # paint spot on the surface; required unless `passes` is given
    overlap = 0.4                   # overlap ratio p of neighbouring spots, in [0, 1): spacing d =
                                    # spacing_for_overlap(p, spot_diameter_mm / 2) (seed 000's eq. 6)
    passes = 5                      # instead of `overlap`: exactly this many passes, edge to edge
    standoff_mm = 0.0               # gun tip to surface along the normal (0: the tables' surface points)
    direction = "rulings"           # "rulings": passes along the rulings from A to B; "across": along the
                                    # curves of constant v (from u = 0 to 1)
    step_mm = 10.0                  # default: rulings: only the two ends; across: the pass spacing
    zigzag = true                   # false: every pass runs the same way (A -> B, or u = 0 -> 1)
    gun_side = [0, 0, 1]            # or outward_from = [x, y, z] (not both)
    gun_axis = [0, 0, -1]           # optional: the gun held along this axis at every waypoint, whatever the
                                    # surface's normal (seed 001 holds it straight down); default -normal

Angles of an arc or circle are measured counter-clockwise about ``normal`` from the projection of world x onto
the curve's plane (world y when the normal is parallel to x).
"""

from __future__ import annotations

import math
import os
import tomllib
from pathlib import Path

import numpy as np

from sprayplan.errors import ConfigError, PartFileError
from sprayplan.io.cloud import read_file_bytes
from sprayplan.paths.ruled import RuledJob, RuledPathConfig
from sprayplan.paths.ruled_surface import Arc, Curve, Line, PointCurve, Polyline, RuledSurface


class _Table:
    """One TOML table being read: every error names the file and the dotted key."""

    def __init__(self, source, table, prefix: str):
        self.source, self.table, self.prefix = source, table, prefix

    def fail(self, problem: str):
        raise PartFileError(self.source, problem)

    def key(self, name: str) -> str:
        return f"{self.prefix}.{name}" if self.prefix else name

    def allow(self, names):
        unknown = sorted(set(self.table) - set(names))
        if unknown:
            where = f"[{self.prefix}]" if self.prefix else "the top level"
            self.fail(f"unknown key '{self.key(unknown[0])}' (known in {where}: {', '.join(sorted(names))})")

    def get(self, name: str, kind: str, default=..., optional=False):
        if name not in self.table:
            if default is ... and not optional:
                self.fail(f"missing key '{self.key(name)}'")
            return None if default is ... else default
        value = self.table[name]
        ok = {
            "number": lambda x: isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x),
            "integer": lambda x: isinstance(x, int) and not isinstance(x, bool),
            "string": lambda x: isinstance(x, str),
            "bool": lambda x: isinstance(x, bool),
            "vector": lambda x: (
                isinstance(x, list)
                and len(x) == 3
                and all(isinstance(c, (int, float)) and not isinstance(c, bool) and math.isfinite(c) for c in x)
            ),
            "points": lambda x: (
                isinstance(x, list)
                and all(
                    isinstance(p, list)
                    and len(p) in (2, 3)
                    and all(isinstance(c, (int, float)) and not isinstance(c, bool) and math.isfinite(c) for c in p)
                    for p in x
                )
            ),
            "table": lambda x: isinstance(x, dict),
        }[kind]
        if not ok(value):
            want = {
                "vector": "a list of three numbers [x, y, z]",
                "points": "a list of [x, y] or [x, y, z] points",
                "table": "a table",
                "bool": "true or false",
                "integer": "a whole number",
            }.get(kind, f"a {kind}")
            self.fail(f"'{self.key(name)}' must be {want}, got {value!r}")
        return float(value) if kind == "number" else value


_CURVE_KEYS = {
    "line": ("start", "end"),
    "arc": ("center", "radius", "normal", "start_angle_deg", "end_angle_deg"),
    "arc3": ("start", "mid", "end"),
    "circle": ("center", "radius", "normal", "start_angle_deg"),
    "point": ("at",),
    "polyline": ("points", "z", "closed"),
}


def _curve(source, data, name: str) -> Curve:
    t = _Table(source, data.get(name), name)
    kind = t.get("type", "string")
    if kind == "arc" and "mid" in t.table:
        kind = "arc3"
    if kind not in _CURVE_KEYS:
        t.fail(f"'{name}.type' must be one of line, arc, circle, point, polyline, got {kind!r}")
    t.allow(("type",) + _CURVE_KEYS[kind])
    try:
        if kind == "line":
            return Line(t.get("start", "vector"), t.get("end", "vector"))
        if kind == "arc3":
            return Arc.through_points(t.get("start", "vector"), t.get("mid", "vector"), t.get("end", "vector"))
        if kind in ("arc", "circle"):
            center, radius = t.get("center", "vector"), t.get("radius", "number")
            normal = t.get("normal", "vector", [0.0, 0.0, 1.0])
            if kind == "circle":
                start = t.get("start_angle_deg", "number", 0.0)
                return Arc(center, radius, normal, math.radians(start), 2.0 * math.pi)
            start, end = t.get("start_angle_deg", "number"), t.get("end_angle_deg", "number")
            return Arc(center, radius, normal, math.radians(start), math.radians(end - start))
        if kind == "point":
            return PointCurve(t.get("at", "vector"))
        points, z = t.get("points", "points"), t.get("z", "number", 0.0)
        vertices = np.array([list(p) + [z] if len(p) == 2 else list(p) for p in points], dtype=float).reshape(-1, 3)
        if t.get("closed", "bool", False) and len(vertices):
            vertices = np.vstack([vertices, vertices[:1]])
        return Polyline(vertices)
    except ConfigError as err:
        t.fail(f"[{name}]: {err}")


def ruled_job_from_dict(data: dict, source: str | os.PathLike = "<dict>", name: str | None = None) -> RuledJob:
    """Build a :class:`RuledJob` from parsed TOML (the schema in the module docstring).

    Parameters
    ----------
    data : dict
        The parsed file.
    source : str or os.PathLike
        The file, named in every error.
    name : str or None
        Used when the file has no ``name``; default: ``source``'s stem.

    Raises
    ------
    PartFileError
        On an unknown, missing or mistyped key or an out-of-range value; the message names the file and key.
    """
    top = _Table(source, data, "")
    top.allow(("name", "curve_a", "curve_b", "path"))
    for key in ("curve_a", "curve_b", "path"):
        top.get(key, "table")
    curve_a, curve_b = _curve(source, data, "curve_a"), _curve(source, data, "curve_b")
    p = _Table(source, data["path"], "path")
    p.allow(
        (
            "spot_diameter_mm",
            "overlap",
            "passes",
            "standoff_mm",
            "direction",
            "step_mm",
            "zigzag",
            "gun_side",
            "outward_from",
            "gun_axis",
        )
    )
    if "passes" in p.table and "overlap" in p.table:
        p.fail("give either 'path.overlap' or 'path.passes', not both")
    if "gun_side" in p.table and "outward_from" in p.table:
        p.fail("give either 'path.gun_side' or 'path.outward_from', not both")
    settings = {
        "spot_diameter_mm": p.get("spot_diameter_mm", "number", optional=True),
        "overlap": p.get("overlap", "number", RuledPathConfig.overlap),
        "passes": p.get("passes", "integer", optional=True),
        "standoff_mm": p.get("standoff_mm", "number", RuledPathConfig.standoff_mm),
        "direction": p.get("direction", "string", RuledPathConfig.direction),
        "step_mm": p.get("step_mm", "number", optional=True),
        "zigzag": p.get("zigzag", "bool", RuledPathConfig.zigzag),
        "gun_axis": p.get("gun_axis", "vector", optional=True),
    }
    try:
        config = RuledPathConfig(**settings)
    except ConfigError as err:
        p.fail(f"[path]: {err}")
    try:
        surface = RuledSurface(
            curve_a,
            curve_b,
            p.get("gun_side", "vector", [0.0, 0.0, 1.0]),
            p.get("outward_from", "vector", optional=True),
        )
    except ConfigError as err:
        p.fail(f"[curve_a]/[curve_b]/[path]: {err}")
    title = top.get("name", "string", optional=True)
    return RuledJob(surface, config, title or name or Path(os.fspath(source)).stem)


def load_ruled(path: str | os.PathLike) -> RuledJob:
    """Read a ruled-surface job from a TOML file (schema: the module docstring).

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    RuledJob

    Raises
    ------
    PartFileError
        The file is missing or unreadable, is not valid TOML, or breaks the schema; the message names the file.
    """
    try:
        text = read_file_bytes(path).decode("utf-8")
    except UnicodeDecodeError:
        raise PartFileError(path, "not UTF-8 text") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise PartFileError(path, f"not valid TOML: {' '.join(str(err).split())}") from None
    return ruled_job_from_dict(data, path)
