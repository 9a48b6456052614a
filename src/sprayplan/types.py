"""The data that flows between stages, defined once.

Every stage is a function that takes and returns these small frozen dataclasses of numpy arrays. Arrays are
made read-only on construction, so a stage can never change its input in place.

Units: mm for lengths, rad for angles, s for time. Normals point out of the part.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


def _frozen(array, dtype, shape_tail: tuple[int, ...], name: str) -> np.ndarray:
    out = np.array(array, dtype=dtype, copy=True)
    if out.ndim != 1 + len(shape_tail) or out.shape[1:] != shape_tail:
        want = ", ".join(["n", *map(str, shape_tail)])
        raise ValueError(f"{name} must have shape ({want}), got {out.shape}")
    out.flags.writeable = False
    return out


@dataclass(frozen=True)
class Part:
    """A part in the part frame, in mm, z up.

    Attributes
    ----------
    vertices : (n, 3) float, mm
        Mesh vertices, or the points of a point cloud.
    faces : (m, 3) int
        Triangles as indices into ``vertices``; ``(0, 3)`` for a point cloud.
    vertex_normals : (n, 3) float or None
        Unit normals given by the file (point clouds with normals); None when the file has none.
    name : str
        Where the part came from (a file name, or ``"demo:roof"``).
    """

    vertices: np.ndarray
    faces: np.ndarray
    vertex_normals: np.ndarray | None = None
    name: str = ""

    def __post_init__(self):
        object.__setattr__(self, "vertices", _frozen(self.vertices, np.float64, (3,), "vertices"))
        faces = np.asarray(self.faces).reshape(-1, 3) if np.size(self.faces) == 0 else self.faces
        object.__setattr__(self, "faces", _frozen(faces, np.int64, (3,), "faces"))
        if self.vertex_normals is not None:
            normals = _frozen(self.vertex_normals, np.float64, (3,), "vertex_normals")
            if len(normals) != len(self.vertices):
                raise ValueError("vertex_normals must have one row per vertex")
            object.__setattr__(self, "vertex_normals", normals)

    @property
    def is_mesh(self) -> bool:
        """True when the part has triangles, False for a point cloud."""
        return len(self.faces) > 0

    @property
    def triangles(self) -> np.ndarray:
        """(m, 3, 3) float, mm: the vertex coordinates of each face."""
        return self.vertices[self.faces]

    @property
    def face_areas(self) -> np.ndarray:
        """(m,) float, mm^2."""
        tri = self.triangles
        return 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)

    @property
    def area(self) -> float:
        """Total surface area in mm^2 (0 for a point cloud)."""
        return float(self.face_areas.sum()) if self.is_mesh else 0.0

    @property
    def bounds(self) -> np.ndarray:
        """(2, 3) float, mm: the lower and upper corners of the axis-aligned bounding box."""
        return np.stack([self.vertices.min(axis=0), self.vertices.max(axis=0)])


@dataclass(frozen=True)
class Targets:
    """Target points on the surface with their outward normals.

    Attributes
    ----------
    points : (n, 3) float, mm
        Points on the part's surface.
    normals : (n, 3) float
        Unit normals pointing out of the part.
    face_index : (n,) int
        The face each point lies on; -1 for points that are mesh vertices or cloud points.
    """

    points: np.ndarray
    normals: np.ndarray
    face_index: np.ndarray = field(default=None)  # type: ignore[assignment]

    def __post_init__(self):
        points = _frozen(self.points, np.float64, (3,), "points")
        normals = _frozen(self.normals, np.float64, (3,), "normals")
        if len(normals) != len(points):
            raise ValueError("points and normals must have the same length")
        index = np.full(len(points), -1) if self.face_index is None else self.face_index
        index = _frozen(np.asarray(index).reshape(-1), np.int64, (), "face_index")
        if len(index) != len(points):
            raise ValueError("face_index must have one entry per point")
        object.__setattr__(self, "points", points)
        object.__setattr__(self, "normals", normals)
        object.__setattr__(self, "face_index", index)

    def __len__(self) -> int:
        return len(self.points)

    def subset(self, index) -> Targets:
        """The targets selected by an index array or boolean mask, in that order."""
        return Targets(self.points[index], self.normals[index], self.face_index[index])
