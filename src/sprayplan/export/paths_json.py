"""paths.json: the strokes of a :class:`~sprayplan.types.Paths`, their settings and a summary.

Schema (see docs/paths-json.md): ``{"format": "sprayplan.paths", "version": 1, "units": "mm", "part": ...,
"settings": {...}, "summary": {...}, "strokes": [{"index", "layer", "spray_on", "points", "normals", "tcp",
"on_part", "rpy", "dwell"}, ...]}`` with strokes in execution order.
"""

from __future__ import annotations

import dataclasses
import json
import os

import numpy as np

from sprayplan import __version__
from sprayplan.checks import MAX_COORDINATE_MM
from sprayplan.errors import PartFileError
from sprayplan.export.files import atomic_output, read_json_file
from sprayplan.types import Paths, Stroke

FORMAT = "sprayplan.paths"
VERSION = 1


def summary(paths: Paths) -> dict:
    """Counts and lengths of a set of paths (mm)."""
    spray = paths.spray_strokes
    return {
        "strokes": len(spray),
        "transfers": len(paths.strokes) - len(spray),
        "waypoints": int(sum(len(s) for s in paths.strokes)),
        "spray_length_mm": round(paths.spray_length_mm, 3),
        "transfer_length_mm": round(paths.transfer_length_mm, 3),
    }


def paths_to_dict(paths: Paths, settings=None) -> dict:
    """The JSON-ready form of a set of paths."""
    if dataclasses.is_dataclass(settings):
        settings = dataclasses.asdict(settings)
    from sprayplan.surface.poses import rpy_from_matrix, stroke_frames

    strokes = []
    for i, s in enumerate(paths.strokes):
        rpy = rpy_from_matrix(stroke_frames(s.points, s.normals)) if len(s) >= 2 else np.zeros((len(s), 3))
        strokes.append(
            {
                "index": i,
                "layer": s.layer,
                "spray_on": s.spray_on,
                "points": np.round(s.points, 4).tolist(),
                "normals": np.round(s.normals, 7).tolist(),
                "tcp": np.round(s.tcp, 4).tolist(),
                "on_part": s.on_part.tolist(),
                "rpy": np.round(rpy, 7).tolist(),
                "dwell": np.round(s.dwell, 6).tolist(),
            }
        )
    return {
        "format": FORMAT,
        "version": VERSION,
        "sprayplan_version": __version__,
        "units": "mm",
        "part": paths.name,
        "settings": {"standoff_mm": paths.standoff_mm, "spacing_mm": paths.spacing_mm, **(settings or {})},
        "summary": summary(paths),
        "strokes": strokes,
    }


def write_paths_json(path: str | os.PathLike, paths: Paths, settings=None) -> None:
    """Write paths.json (atomically)."""
    data = paths_to_dict(paths, settings)
    with atomic_output(path, "w", encoding="utf-8") as handle:
        handle.write(json.dumps(data, separators=(",", ":")))
        handle.write("\n")


#: A normal read from a file may differ from unit length by this much (the writer writes full precision).
UNIT_TOL = 1e-3


def _check_stroke_arrays(name: str, k: int, points, normals, tcp) -> None:
    """Coordinates finite and within ``MAX_COORDINATE_MM``, normals of unit length: else a ``PartFileError``
    naming the file, the stroke and the waypoint (a NaN or zero normal would be solved as a pose)."""
    for field, values in (("points", points), ("tcp", tcp)):
        bad = ~(np.abs(values) <= MAX_COORDINATE_MM).all(axis=1)
        if bad.any():
            i = int(np.argmax(bad))
            raise PartFileError(
                name,
                f"stroke {k} waypoint {i}: {field} ({', '.join(f'{v:g}' for v in values[i])}) must be finite and"
                f" within {MAX_COORDINATE_MM:g} mm",
            )
    length = np.linalg.norm(normals, axis=1)
    bad = ~(np.abs(length - 1.0) <= UNIT_TOL)
    if bad.any():
        i = int(np.argmax(bad))
        raise PartFileError(
            name,
            f"stroke {k} waypoint {i}: normal ({', '.join(f'{v:g}' for v in normals[i])}) is not a unit vector",
        )


def read_paths_json(path: str | os.PathLike) -> Paths:
    """Read a paths.json written by :func:`write_paths_json`.

    Raises
    ------
    PartFileError
        When the file is missing, not JSON, or not a sprayplan paths file.
    """
    name = os.fspath(path)
    data = read_json_file(path, FORMAT, "paths")
    try:
        strokes = []
        for k, s in enumerate(data["strokes"]):
            points = np.array(s["points"], float).reshape(-1, 3)
            normals = np.array(s["normals"], float).reshape(-1, 3)
            tcp = np.array(s["tcp"], float).reshape(-1, 3)
            _check_stroke_arrays(name, k, points, normals, tcp)
            strokes.append(
                Stroke(
                    points,
                    normals,
                    tcp,
                    bool(s["spray_on"]),
                    np.array(s["on_part"], bool),
                    int(s["layer"]),
                    np.array(s["dwell"], float) if "dwell" in s else None,
                )
            )
        strokes = tuple(strokes)
        settings = data["settings"]
        return Paths(strokes, float(settings["standoff_mm"]), float(settings["spacing_mm"]), str(data.get("part", "")))
    except (KeyError, TypeError, ValueError) as exc:
        raise PartFileError(name, f"broken paths file: {exc}") from None
