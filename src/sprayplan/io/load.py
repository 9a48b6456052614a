"""The ``load`` stage: a part file in any supported format and unit -> a :class:`~sprayplan.types.Part` in mm.

Meshes: STL (ASCII and binary, own reader), OBJ, PLY and OFF (through trimesh). Point clouds: XYZ/TXT/CSV and
PCD (own readers), PLY files without faces. A ``.gz`` suffix is decompressed first (``hull.stl.gz``).
"""

from __future__ import annotations

import gzip
import logging
import os
import zlib
from pathlib import Path

import numpy as np

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
    file = Path(path)
    if not file.exists():
        raise PartFileError(path, "no such file")
    if file.is_dir():
        raise PartFileError(path, "is a folder, not a part file")
    suffixes = [s.lower() for s in file.suffixes]
    gzipped = bool(suffixes) and suffixes[-1] == ".gz"
    suffix = (suffixes[-2] if len(suffixes) >= 2 else "") if gzipped else (suffixes[-1] if suffixes else "")
    if suffix not in MESH_SUFFIXES + CLOUD_SUFFIXES:
        known = " ".join(MESH_SUFFIXES + CLOUD_SUFFIXES)
        raise PartFileError(path, f"unknown file type {suffix or '(no extension)'!r}: use one of {known}")
    try:
        data = file.read_bytes()
    except OSError as exc:
        raise PartFileError(path, f"cannot read: {exc.strerror or exc}") from None
    if gzipped:
        try:
            data = gzip.decompress(data)
        except (OSError, EOFError, zlib.error) as exc:
            raise PartFileError(path, f"not a valid gzip file ({exc})") from None
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
    return _read_with_trimesh(data, suffix, path)


def _read_with_trimesh(data: bytes, suffix: str, path: str):
    import trimesh

    try:
        loaded = trimesh.load(
            trimesh.util.wrap_as_stream(data),
            file_type=suffix[1:],
            process=False,
            # a missing .mtl or texture must not stop the geometry from loading
            resolver=_NoResolver(path),
        )
    except Exception as exc:  # a third-party parser on user input: any failure is the file's
        message = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise PartFileError(path, f"cannot parse {suffix[1:].upper()} file: {message}") from None
    if isinstance(loaded, trimesh.Scene):
        geometries = list(loaded.dump()) if loaded.geometry else []
        meshes = [g for g in geometries if isinstance(g, trimesh.Trimesh) and len(g.faces)]
        if meshes:
            loaded = trimesh.util.concatenate(meshes)
        else:
            clouds = [g for g in geometries if len(getattr(g, "vertices", []))]
            if not clouds:
                raise PartFileError(path, "file has no geometry")
            loaded = trimesh.PointCloud(np.vstack([c.vertices for c in clouds]))
    vertices = np.asarray(getattr(loaded, "vertices", np.zeros((0, 3))), dtype=np.float64).reshape(-1, 3)
    faces = np.asarray(getattr(loaded, "faces", np.zeros((0, 3))), dtype=np.int64).reshape(-1, 3)
    if len(vertices) == 0:
        raise PartFileError(path, "file has no vertices")
    if len(faces) and (faces.min() < 0 or faces.max() >= len(vertices)):
        raise PartFileError(path, "a face refers to a vertex that does not exist")
    bad = ~np.isfinite(vertices).all(axis=1)
    if bad.any():
        raise PartFileError(
            path, f"vertex {int(np.flatnonzero(bad)[0]) + 1}: NaN or infinite coordinate ({int(bad.sum())} vertices)"
        )
    return vertices, faces, None


class _NoResolver:
    """A trimesh resolver that finds nothing: OBJ materials and textures are appearance, not geometry."""

    def __init__(self, path: str):
        self.path = path
        self.said = False

    def get(self, name):
        if not self.said:
            log.info("%s: ignoring material/texture files (%s): only the geometry is used", self.path, name)
            self.said = True
        raise FileNotFoundError(name)

    __getitem__ = get

    def namespaced(self, namespace):
        return self

    def keys(self):
        return []

    def write(self, name, data):  # pragma: no cover - never asked to write
        raise FileNotFoundError(name)


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
