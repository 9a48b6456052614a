"""The film files of a plan: coating.json (the report), thickness.ply (a coloured mesh), thickness.csv."""

from __future__ import annotations

import json
import os
from dataclasses import dataclass

import numpy as np

from sprayplan.checks import check_input_file
from sprayplan.coating.thickness import CoatingResult
from sprayplan.config import JobConfig
from sprayplan.errors import PartFileError
from sprayplan.export.files import atomic_output, os_problem


def film_report(result, job: JobConfig, samples: int | None = None, chosen: dict | None = None) -> dict:
    """The film's report (``coating.coating_report``) against the job's spec (50 +- 5 um without a target)."""
    from sprayplan.coating.report import coating_report

    target = job.coating.thickness_um if job.coating.thickness_um is not None else 50.0
    report = coating_report(result, target_um=target, tolerance_um=job.coating.tolerance_um, samples=samples)
    report["process"] = job.coating.process
    if chosen:
        report["chosen"] = chosen
    return report


def write_coating(outdir, result, job: JobConfig, report: dict) -> list[str]:
    """Write OUTDIR/thickness.ply, thickness.csv and coating.json (the report, :func:`film_report`); returns
    the paths written."""
    target = job.coating.thickness_um if job.coating.thickness_um is not None else 50.0
    outdir = os.fspath(outdir)
    paths = [os.path.join(outdir, name) for name in ("thickness.ply", "thickness.csv", "coating.json")]
    write_thickness_ply(paths[0], result, target, job.coating.tolerance_um)
    write_thickness_csv(paths[1], result)
    with atomic_output(paths[2], "w", encoding="utf-8") as handle:
        json.dump(_finite(report), handle, indent=1)
        handle.write("\n")
    return paths


def _finite(value):
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    if isinstance(value, (float, np.floating)):
        return float(value) if np.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.ndarray):
        return _finite(value.tolist())
    return value


def write_thickness_csv(path: str | os.PathLike, result: CoatingResult) -> None:
    """Write ``x,y,z,thickness_um`` (mm, um), one row per surface sample."""
    table = np.column_stack([result.points, result.thickness_um])
    row = "%.6f,%.6f,%.6f,%.4f\n"  # the rows np.savetxt wrote, formatted a block of rows in one % operation
    with atomic_output(path, "w", newline="") as handle:
        handle.write("x,y,z,thickness_um\n")
        for start in range(0, len(table), _CSV_BLOCK):
            block = table[start : start + _CSV_BLOCK]
            handle.write((row * len(block)) % tuple(block.ravel().tolist()))


#: Rows of thickness.csv formatted at once (bounds the temporary Python floats).
_CSV_BLOCK = 1 << 16


def thickness_colours(thickness_um: np.ndarray, target_um: float = 50.0, tolerance_um: float = 5.0) -> np.ndarray:
    """(n, 3) uint8: blue (bare) -> cyan (thin) -> green (in spec) -> yellow -> red (twice the target)."""
    t = np.clip(np.asarray(thickness_um, float) / (2.0 * target_um), 0.0, 1.0)
    stops = np.array(
        [
            0.0,
            0.5 * (target_um - tolerance_um) / target_um,
            0.5,
            0.5 * (target_um + tolerance_um) / target_um + 0.1,
            1.0,
        ]
    )
    stops = np.maximum.accumulate(np.clip(stops, 0.0, 1.0))
    colours = np.array([[40, 40, 200], [0, 200, 220], [0, 190, 0], [240, 220, 0], [220, 0, 0]], float)
    return np.stack([np.interp(t, stops, colours[:, k]) for k in range(3)], axis=1).round().astype(np.uint8)


_PLY_FLOATS = ("x", "y", "z", "nx", "ny", "nz", "thickness_um", "area_mm2")


def write_thickness_ply(
    path: str | os.PathLike, result: CoatingResult, target_um: float = 50.0, tolerance_um: float = 5.0
) -> None:
    """Write a binary little-endian PLY: vertices with ``nx ny nz``, ``thickness_um`` and ``area_mm2`` (floats:
    the film and the surface area each sample stands for) and a colour; read back by :func:`read_thickness_ply`.

    Faces are written when the samples are mesh vertices. Viewers that do not know the ``thickness_um``
    property show the colour (see :func:`thickness_colours`); MeshLab and CloudCompare also list it as a
    scalar field.
    """
    n = len(result.points)
    faces = np.asarray(result.faces, dtype=np.int32).reshape(-1, 3)
    vertex = np.empty(
        n,
        dtype=[
            ("x", "<f4"),
            ("y", "<f4"),
            ("z", "<f4"),
            ("nx", "<f4"),
            ("ny", "<f4"),
            ("nz", "<f4"),
            ("thickness_um", "<f4"),
            ("area_mm2", "<f4"),
            ("red", "u1"),
            ("green", "u1"),
            ("blue", "u1"),
        ],
    )
    for k, name in enumerate("xyz"):
        vertex[name] = result.points[:, k]
        vertex["n" + name] = result.normals[:, k]
    vertex["thickness_um"] = result.thickness_um
    vertex["area_mm2"] = result.area_mm2
    rgb = thickness_colours(result.thickness_um, target_um, tolerance_um)
    vertex["red"], vertex["green"], vertex["blue"] = rgb[:, 0], rgb[:, 1], rgb[:, 2]
    header = [
        "ply",
        "format binary_little_endian 1.0",
        "comment sprayplan coating: dry film thickness in um per vertex, lengths in mm",
        f"element vertex {n}",
        *[f"property float {name}" for name in _PLY_FLOATS],
        "property uchar red",
        "property uchar green",
        "property uchar blue",
    ]
    if len(faces):
        header += [f"element face {len(faces)}", "property list uchar int vertex_indices"]
    header.append("end_header")
    with atomic_output(path, "wb") as handle:
        handle.write(("\n".join(header) + "\n").encode("ascii"))
        handle.write(vertex.tobytes())
        if len(faces):
            table = np.empty(len(faces), dtype=[("count", "u1"), ("index", "<i4", (3,))])
            table["count"] = 3
            table["index"] = faces
            handle.write(table.tobytes())


@dataclass(frozen=True)
class FilmSurface:
    """The film a thickness.ply holds: samples (mm), unit normals, the area each stands for (mm^2; None in a
    file written before the area was), triangles over the samples ((0, 3) for a point cloud) and the film (um)."""

    points: np.ndarray
    normals: np.ndarray
    area_mm2: np.ndarray | None
    faces: np.ndarray
    thickness_um: np.ndarray


def read_thickness_ply(path: str | os.PathLike) -> FilmSurface:
    """Read a thickness.ply written by :func:`write_thickness_ply` (with or without ``area_mm2``).

    Raises
    ------
    PartFileError
        The file is missing, is not such a PLY, is cut short, or holds a face index out of range or a value
        that is not finite, naming the file.
    """
    name = check_input_file(path)
    try:
        with open(path, "rb") as handle:
            data = handle.read()
    except FileNotFoundError:
        raise PartFileError(name, "no such file") from None
    except OSError as exc:
        raise PartFileError(name, os_problem(exc)) from None
    end = data.find(b"end_header\n")
    if not data.startswith(b"ply\n") or end < 0:
        raise PartFileError(name, "not a sprayplan thickness.ply (no PLY header)")
    lines = data[:end].decode("ascii", "replace").splitlines()
    floats = tuple(line.split()[2] for line in lines if line.startswith("property float "))
    counts = {line.split()[1]: line.split()[2] for line in lines if line.startswith("element ")}
    if (
        "format binary_little_endian 1.0" not in lines
        or floats not in (_PLY_FLOATS, _PLY_FLOATS[:7])
        or not all(v.isdigit() for v in counts.values())
    ):
        raise PartFileError(name, "not a sprayplan thickness.ply (its header is not the one sprayplan writes)")
    n, m = int(counts.get("vertex", 0)), int(counts.get("face", 0))
    vertex = np.dtype([(f, "<f4") for f in floats] + [(c, "u1") for c in ("red", "green", "blue")])
    face = np.dtype([("count", "u1"), ("index", "<i4", (3,))])
    body = memoryview(data)[end + len(b"end_header\n") :]
    if len(body) != n * vertex.itemsize + m * face.itemsize:
        raise PartFileError(name, f"is {len(body)} bytes after its header, not the {n} vertices and {m} faces it names")
    v = np.frombuffer(body, vertex, n)
    f = np.frombuffer(body, face, m, offset=n * vertex.itemsize)
    columns = np.column_stack([v[k].astype(float) for k in floats]) if n else np.zeros((0, len(floats)))
    if not np.isfinite(columns).all():
        raise PartFileError(name, "holds a value that is not finite")
    faces = f["index"].astype(np.int64).reshape(-1, 3)
    if m and ((f["count"] != 3).any() or faces.min() < 0 or faces.max() >= n):
        raise PartFileError(name, "has a face that is not a triangle of its vertices")
    return FilmSurface(
        points=columns[:, 0:3],
        normals=columns[:, 3:6],
        area_mm2=columns[:, 7] if len(floats) == 8 else None,
        faces=faces,
        thickness_um=columns[:, 6],
    )
