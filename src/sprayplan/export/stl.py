"""Binary STL files: the demo part written for the user (the reader is ``io.stl``)."""

from __future__ import annotations

import numpy as np

from sprayplan.io.stl import BINARY_HEADER_BYTES, BINARY_RECORD


def write_stl_binary(triangles: np.ndarray, header: bytes = b"sprayplan") -> bytes:
    """Encode triangles as a binary STL (normals from the winding).

    Parameters
    ----------
    triangles : (m, 3, 3) float
        Vertex coordinates.
    header : bytes
        Up to 80 bytes for the header; padded with spaces.

    Returns
    -------
    bytes
        The file's content.
    """
    triangles = np.asarray(triangles, dtype=np.float64)
    records = np.zeros(len(triangles), BINARY_RECORD)
    with np.errstate(invalid="ignore", over="ignore"):
        normal = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
        length = np.linalg.norm(normal, axis=1, keepdims=True)
    records["normal"] = np.divide(normal, length, out=np.zeros_like(normal), where=length > 0)
    records["vertices"] = triangles
    head = header[:BINARY_HEADER_BYTES].ljust(BINARY_HEADER_BYTES, b" ")
    return head + np.uint32(len(triangles)).tobytes() + records.tobytes()
