"""The ``load`` stage: a part file in any supported format and unit -> a :class:`~sprayplan.types.Part` in mm.

Meshes: STL (ASCII and binary), OBJ, PLY and OFF. Point clouds: XYZ/TXT/CSV, PCD, PLY/OBJ/OFF files without
faces. Every reader is the package's own and strict (``io/stl.py``, ``io/ply.py``, ``io/off.py`` for OFF and
OBJ, ``io/cloud.py``, ``io/pcd.py``): a count a header declares must match what the file holds, and every face
index must name a vertex. A ``.gz`` suffix is decompressed first (``hull.stl.gz``).

After reading, :func:`check_part_arrays` checks what every format shares: finite coordinates no larger than
:data:`MAX_COORDINATE_MM` once in mm, face indices in range, normals of positive finite length, and a cloud of
3 or more points that are not all on one line.
"""

from __future__ import annotations

import gzip
import logging
import os
import zlib
from pathlib import Path

import numpy as np

from sprayplan.checks import MAX_COORDINATE_MM, check_input_file, first_bad_normal
from sprayplan.errors import ConfigError, PartFileError
from sprayplan.types import Part

log = logging.getLogger(__name__)

#: Length of one file unit in mm.
UNITS_MM = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "in": 25.4}

#: Rotations that turn a model whose up axis is y or x into the z-up part frame (right-handed, det +1).
UP_ROTATIONS = {
    "z": np.eye(3),
    "y": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]),  # +90 deg about x: y -> z
    "x": np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]]),  # -90 deg about y: x -> z
}

MESH_SUFFIXES = (".stl", ".obj", ".ply", ".off")
CLOUD_SUFFIXES = (".xyz", ".txt", ".csv", ".pcd")

#: Sizes outside this range (largest bounding-box side, mm) are unlikely for a painted part.
PLAUSIBLE_SIZE_MM = (20.0, 100_000.0)

#: A cloud whose second principal extent (root of the covariance's eigenvalue) is below this fraction of its
#: first lies on one line (float64 eigenvalues are good to about 1e-16 of the largest, so 1e-6 of the extent).
COLLINEAR_RATIO = 1e-6


def load_part(path: str | os.PathLike, *, units: str = "mm", up: str = "z") -> Part:
    """Read a part file and bring it into the part frame: mm, z up, degenerate triangles dropped.

    Parameters
    ----------
    path : str or PathLike
        A mesh (``.stl``, ``.obj``, ``.ply``, ``.off``) or point cloud (``.xyz``, ``.txt``, ``.csv``,
        ``.pcd``, ``.ply`` without faces), optionally gzipped (``.gz``).
    units : {"mm", "cm", "m", "in"}
        The length unit of the file's coordinates.
    up : {"z", "y", "x"}
        The file's up axis; a y-up or x-up model is rotated so that this axis becomes +z.

    Returns
    -------
    Part
        Vertices in mm. Meshes keep only triangles of positive area (the dropped ones are counted in the log)
        and only the vertices they use; duplicate vertices are merged.

    Raises
    ------
    PartFileError
        Missing, empty, unknown, broken or non-finite file content, or a mesh with no triangle of positive area.
    ConfigError
        An unknown unit or up axis.
    """
    if units not in UNITS_MM:
        raise ConfigError(f"unknown unit {units!r}: use one of {', '.join(UNITS_MM)}")
    if up not in UP_ROTATIONS:
        raise ConfigError(f"unknown up axis {up!r}: use one of z, y, x")
    name = os.fspath(path)
    vertices, faces, normals = read_part_file(name)
    check_part_arrays(vertices, faces, normals, name, units)
    vertices = vertices * UNITS_MM[units]
    rotation = UP_ROTATIONS[up]
    if up != "z":
        vertices = vertices @ rotation.T
        normals = None if normals is None else normals @ rotation.T
    if len(faces):
        vertices, faces = clean_mesh(vertices, faces, name)
        normals = None
    _warn_if_unit_looks_wrong(vertices, units, name)
    return Part(vertices=vertices, faces=faces, vertex_normals=normals, name=name)


def read_part_file(path: str) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Read a part file as it is (file units, file axes).

    Returns
    -------
    vertices : (n, 3) float
    faces : (m, 3) int
        ``(0, 3)`` for a point cloud.
    normals : (n, 3) float or None
        Per-point normals given by a point-cloud file.
    """
    from sprayplan.io.cloud import read_file_bytes

    path = check_input_file(path)  # a folder or a named pipe is refused before anything opens it
    file = Path(path)
    suffixes = [s.lower() for s in file.suffixes]
    gzipped = bool(suffixes) and suffixes[-1] == ".gz"
    suffix = (suffixes[-2] if len(suffixes) >= 2 else "") if gzipped else (suffixes[-1] if suffixes else "")
    if suffix not in MESH_SUFFIXES + CLOUD_SUFFIXES:
        known = " ".join(MESH_SUFFIXES + CLOUD_SUFFIXES)
        raise PartFileError(path, f"unknown file type {suffix or '(no extension)'!r}: use one of {known}")
    data = read_file_bytes(path)
    if gzipped:
        try:
            data = gzip.decompress(data)
        except (OSError, EOFError, zlib.error) as exc:
            raise PartFileError(path, f"not a valid gzip file ({exc})") from None
        except MemoryError:
            raise PartFileError(path, "the gzip file decompresses to more than the memory holds") from None
    if not data:
        raise PartFileError(path, "file is empty")
    empty_faces = np.zeros((0, 3), dtype=np.int64)
    if suffix == ".stl":
        from sprayplan.io.stl import parse_stl

        triangles = parse_stl(data, path)
        return triangles.reshape(-1, 3), np.arange(3 * len(triangles)).reshape(-1, 3), None
    if suffix in CLOUD_SUFFIXES:
        from sprayplan.io import cloud, pcd

        parser = pcd.parse_pcd if suffix == ".pcd" else cloud.parse_xyz
        points, normals = parser(data, path)
        return points, empty_faces, normals
    from sprayplan.io.off import parse_obj, parse_off
    from sprayplan.io.ply import parse_ply

    parse = {".ply": parse_ply, ".off": parse_off, ".obj": parse_obj}[suffix]
    vertices, faces = parse(data, path)
    return vertices, faces, None


def check_part_arrays(
    vertices: np.ndarray, faces: np.ndarray, normals: np.ndarray | None, name: str, units: str = "mm"
) -> None:
    """Check what every reader returns, before it is scaled: the faults each format shares, one message each.

    Parameters
    ----------
    vertices : (n, 3) float
        In the file's units.
    faces : (m, 3) int
        ``(0, 3)`` for a cloud.
    normals : (n, 3) float or None
        Normals stored in the file.
    name : str
        The file, first in every message.
    units : str
        The file's unit, for the bound on coordinates.

    Raises
    ------
    PartFileError
        No vertex; a NaN or infinite coordinate; a coordinate beyond ``MAX_COORDINATE_MM`` once in mm (naming
        the unit); a face index outside the vertices; a normal of zero or non-finite length (naming the point);
        a cloud of fewer than 3 points, or whose points coincide or lie on one line.
    """
    n = len(vertices)
    if n == 0:
        raise PartFileError(name, "file has no vertices")
    finite = np.isfinite(vertices).all(axis=1)
    if not finite.all():
        bad = ~finite
        raise PartFileError(
            name, f"vertex {int(np.argmax(bad)) + 1}: NaN or infinite coordinate ({int(bad.sum())} vertices)"
        )
    limit = MAX_COORDINATE_MM / UNITS_MM[units]  # in file units: scaling first could overflow to inf
    far = np.abs(vertices).max(axis=1) > limit
    if far.any():
        row = int(np.argmax(far))
        value = float(vertices[row][np.argmax(np.abs(vertices[row]))])
        raise PartFileError(
            name,
            f"vertex {row + 1}: coordinate {value:.6g} {units} is beyond the plausible {MAX_COORDINATE_MM:g} mm "
            f"({limit:g} {units}): a broken file or the wrong --units",
        )
    if len(faces) and (faces.min() < 0 or faces.max() >= n):
        raise PartFileError(name, f"a face refers to a vertex that does not exist (the file has {n})")
    if normals is not None:
        row = first_bad_normal(normals)
        if row is not None:
            raise PartFileError(name, f"point {row + 1}: its normal has {_normal_fault(normals[row])}")
    if len(faces) == 0:
        check_cloud_spread(vertices, name)


def _normal_fault(normal: np.ndarray) -> str:
    return "a NaN or infinite component" if not np.isfinite(normal).all() else "zero length (or too large to measure)"


def check_cloud_spread(points: np.ndarray, name: str) -> None:
    """Raise unless the cloud has 3 or more points that neither coincide nor all lie on one line."""
    n = len(points)
    if n < 3:
        raise PartFileError(name, f"point cloud of {n} point{'s' * (n != 1)}: a part needs at least 3")
    extent = float(np.ptp(points, axis=0).max())
    if extent == 0.0:
        raise PartFileError(name, f"degenerate point cloud: all {n} points coincide")
    centred = (points - points.mean(axis=0)) / extent
    variance = np.linalg.eigvalsh(centred.T @ centred / n)  # ascending
    if variance[1] <= COLLINEAR_RATIO**2 * variance[2]:
        raise PartFileError(name, f"degenerate point cloud: all {n} points lie on one line")


def clean_mesh(vertices: np.ndarray, faces: np.ndarray, name: str = "") -> tuple[np.ndarray, np.ndarray]:
    """Merge identical vertices, drop triangles of zero area and vertices no triangle uses.

    Parameters
    ----------
    vertices : (n, 3) float, mm
    faces : (m, 3) int
    name : str
        For the log line and the error message.

    Returns
    -------
    vertices : (k, 3) float, mm
    faces : (j, 3) int

    Raises
    ------
    PartFileError
        When no triangle of positive area is left.
    """
    unique, inverse = np.unique(vertices, axis=0, return_inverse=True)
    faces = inverse.reshape(-1)[faces]
    tri = unique[faces]
    area2 = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    scale = float(np.ptp(unique, axis=0).max()) if len(unique) else 0.0
    keep = area2 > (1e-12 * scale) ** 2 * 2.0
    dropped = int((~keep).sum())
    if dropped:
        log.info("%s: dropped %d degenerate (zero-area) triangles of %d", name, dropped, len(faces))
    faces = faces[keep]
    if len(faces) == 0:
        raise PartFileError(name, "mesh has no triangle of positive area")
    used = np.zeros(len(unique), dtype=bool)
    used[faces.reshape(-1)] = True
    remap = np.cumsum(used) - 1
    return unique[used], remap[faces]


def _warn_if_unit_looks_wrong(vertices: np.ndarray, units: str, name: str) -> None:
    size = float(np.ptp(vertices, axis=0).max()) if len(vertices) > 1 else 0.0
    low, high = PLAUSIBLE_SIZE_MM
    if low <= size <= high or size == 0.0:
        return
    file_size = size / UNITS_MM[units]
    likely = [u for u in UNITS_MM if u != units and low <= file_size * UNITS_MM[u] <= high]
    if not likely:
        return
    options = ", ".join(f"--units {u} makes it {file_size * UNITS_MM[u]:.4g} mm" for u in likely)
    log.warning(
        "%s: the part is %.4g mm across with --units %s, which is unlikely for a painted part; "
        "if the file is in another unit: %s",
        name,
        size,
        units,
        options,
    )
