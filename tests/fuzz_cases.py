"""Tiny input files for the fuzz suite (tests/test_fuzz_cli.py): a small plate in every reader's format.

Every builder returns bytes (or text), so a case writes exactly the file it needs into its own folder. The
plate is 300 x 200 mm at z = 0, 48 triangles: big enough for a stroke or a target, small enough that a whole
``targets`` or ``paths`` run takes a few milliseconds.
"""

from __future__ import annotations

import json
import struct

import numpy as np


def plate_mesh(x1=300.0, y1=200.0, step=50.0, z=0.0, scale=1.0):
    """(vertices (n, 3), faces (m, 3)) of a flat grid plate, normals +z."""
    xs = np.arange(0.0, x1 + step / 2, step)
    ys = np.arange(0.0, y1 + step / 2, step)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    vertices = np.stack([gx.ravel(), gy.ravel(), np.full(gx.size, float(z))], axis=1) * scale
    nx, ny = len(xs), len(ys)
    i, j = np.meshgrid(np.arange(nx - 1), np.arange(ny - 1), indexing="ij")
    a = (i * ny + j).ravel()
    b, c, d = a + ny, a + ny + 1, a + 1
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return vertices, faces


def _fmt(v) -> str:
    return repr(float(v))


def stl_binary(vertices=None, faces=None) -> bytes:
    if vertices is None:
        vertices, faces = plate_mesh()
    tri = vertices[faces]
    out = bytearray(b"sprayplan fuzz plate".ljust(80, b" "))
    out += struct.pack("<I", len(tri))
    for t in tri:
        out += struct.pack("<12fH", 0.0, 0.0, 1.0, *t.ravel().tolist(), 0)
    return bytes(out)


def stl_ascii(vertices=None, faces=None, name="plate", upper=False, vertex_counts=None, endsolid=True) -> str:
    """ASCII STL; ``vertex_counts``: per facet, how many of its corners to write (default 3)."""
    if vertices is None:
        vertices, faces = plate_mesh()
    lines = [f"solid {name}"]
    for k, f in enumerate(faces):
        corners = [vertices[i] for i in f]
        if vertex_counts is not None:
            n = vertex_counts[k % len(vertex_counts)]
            corners = (corners * 2)[:n]
        lines += ["  facet normal 0 0 1", "    outer loop"]
        lines += [f"      vertex {_fmt(p[0])} {_fmt(p[1])} {_fmt(p[2])}" for p in corners]
        lines += ["    endloop", "  endfacet"]
    if endsolid:
        lines.append(f"endsolid {name}")
    text = "\n".join(lines) + "\n"
    if upper:
        text = "\n".join(_upper_keywords(line) for line in text.splitlines()) + "\n"
    return text


def _upper_keywords(line: str) -> str:
    keywords = {"solid", "facet", "normal", "outer", "loop", "vertex", "endloop", "endfacet", "endsolid"}
    return " ".join(w.upper() if w in keywords else w for w in line.split(" "))


def obj_text(vertices=None, faces=None, base=1) -> str:
    if vertices is None:
        vertices, faces = plate_mesh()
    lines = [f"v {_fmt(p[0])} {_fmt(p[1])} {_fmt(p[2])}" for p in vertices]
    lines += [f"f {a + base} {b + base} {c + base}" for a, b, c in faces]
    return "\n".join(lines) + "\n"


def off_text(vertices=None, faces=None, n_faces=None, face_rows=None) -> str:
    if vertices is None:
        vertices, faces = plate_mesh()
    rows = face_rows if face_rows is not None else [f"3 {a} {b} {c}" for a, b, c in faces]
    head = f"{len(vertices)} {len(faces) if n_faces is None else n_faces} 0"
    lines = ["OFF", head] + [f"{_fmt(p[0])} {_fmt(p[1])} {_fmt(p[2])}" for p in vertices] + rows
    return "\n".join(lines) + "\n"


def ply_ascii(vertices=None, faces=None, n_vertices=None, n_faces=None, vertex_rows=None, face_rows=None) -> str:
    if vertices is None:
        vertices, faces = plate_mesh()
    vrows = vertex_rows if vertex_rows is not None else [f"{_fmt(p[0])} {_fmt(p[1])} {_fmt(p[2])}" for p in vertices]
    frows = face_rows if face_rows is not None else [f"3 {a} {b} {c}" for a, b, c in faces]
    head = [
        "ply",
        "format ascii 1.0",
        f"element vertex {len(vertices) if n_vertices is None else n_vertices}",
        "property float x",
        "property float y",
        "property float z",
        f"element face {len(faces) if n_faces is None else n_faces}",
        "property list uchar int vertex_indices",
        "end_header",
    ]
    return "\n".join(head + vrows + frows) + "\n"


def ply_binary(vertices=None, faces=None) -> bytes:
    if vertices is None:
        vertices, faces = plate_mesh()
    head = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {len(vertices)}\nproperty float x\nproperty float y\nproperty float z\n"
        f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n"
    ).encode()
    body = b"".join(struct.pack("<3f", *p) for p in vertices)
    body += b"".join(struct.pack("<B3i", 3, *map(int, f)) for f in faces)
    return head + body


def xyz_text(points=None, normals=None) -> str:
    if points is None:
        vertices, _ = plate_mesh(step=25.0)
        points = vertices + np.array([0.0, 0.0, 0.0])
        points[:, 2] = 0.001 * points[:, 0]  # not quite flat
    if normals is None:
        return "\n".join(" ".join(_fmt(v) for v in p) for p in points) + "\n"
    return "\n".join(" ".join(_fmt(v) for v in (*p, *n)) for p, n in zip(points, normals, strict=True)) + "\n"


def pcd_ascii(points=None) -> str:
    if points is None:
        vertices, _ = plate_mesh(step=25.0)
        points = vertices
    head = [
        "# .PCD v0.7 - Point Cloud Data file format",
        "VERSION 0.7",
        "FIELDS x y z",
        "SIZE 4 4 4",
        "TYPE F F F",
        "COUNT 1 1 1",
        f"WIDTH {len(points)}",
        "HEIGHT 1",
        "VIEWPOINT 0 0 0 1 0 0 0",
        f"POINTS {len(points)}",
        "DATA ascii",
    ]
    return "\n".join(head + [" ".join(_fmt(v) for v in p) for p in points]) + "\n"


JOINTS_CSV = "q1,q2,q3,q4,q5,q6\n0,-1.2,1.1,-1.5,-1.57,0\n0.1,-1.0,1.0,-1.4,-1.57,0.2\n"
POSES_CSV = "x,y,z,rx,ry,rz\n400,100,300,3.1416,0,0\n420,100,300,3.1416,0,0\n"
POSES_MATRIX_CSV = "x,y,z,r11,r12,r13,r21,r22,r23,r31,r32,r33\n400,100,300,1,0,0,0,-1,0,0,0,-1\n"

CONFIG_TOML = """mode = "paths"
[load]
units = "mm"
[paths]
spray_radius_mm = 50.0
step_mm = 20.0
"""

RULED_TOML = """name = "fuzz case 1"
[curve_a]
type = "line"
start = [150, 100, 150]
end = [270, 140, 190]
[curve_b]
type = "line"
start = [150, 300, 150]
end = [270, 260, 190]
[path]
passes = 5
standoff_mm = 0
direction = "rulings"
"""


def json_bytes(data) -> bytes:
    return json.dumps(data).encode()
