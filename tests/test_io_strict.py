"""Strict readers (issue 13): every broken OBJ / PLY / OFF / ASCII STL, implausible coordinates, bad normals,
degenerate clouds, reflected poses and inputs that are not regular files end in a one-line PartFileError that
names the file (and the line, element or row where known); valid files keep loading."""

from __future__ import annotations

import os
import signal
import struct

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sprayplan.errors import PartFileError
from sprayplan.io.cloud import read_file_bytes, read_xyz
from sprayplan.io.load import load_part
from sprayplan.io.pcd import read_pcd
from sprayplan.io.tables import read_poses

QUAD = np.array([[0, 0, 0], [100, 0, 0], [100, 100, 0], [0, 100, 0]], dtype=float)


def write(tmp_path, name, data) -> str:
    path = tmp_path / name
    path.write_bytes(data if isinstance(data, bytes) else data.encode())
    return str(path)


def fails(path, *words, **kwargs) -> str:
    with pytest.raises(PartFileError) as info:
        load_part(path, **kwargs)
    message = str(info.value)
    assert message.startswith(f"{path}: "), message
    assert "\n" not in message
    for word in words:
        assert word in message, message
    return message


# --------------------------------------------------------------------------------------------------------
# OBJ

OBJ = "v 0 0 0\nv 100 0 0\nv 100 100 0\nv 0 100 0\nf 1 2 3\nf 1 3 4\n"


def test_obj_valid_with_corner_forms_polygons_and_negative_indices(tmp_path):
    part = load_part(write(tmp_path, "a.obj", OBJ))
    assert len(part.faces) == 2 and part.area == pytest.approx(1e4)
    quad = load_part(
        write(tmp_path, "q.obj", "v 0 0 0\nv 100 0 0\nv 100 100 0\nv 0 100 0\nvt 0 0\nvn 0 0 1\nf 1/1/1 2/1/1 3//1 4\n")
    )
    assert len(quad.faces) == 2 and quad.area == pytest.approx(1e4)
    # negative indices count back from the vertices defined so far, not from the file's last vertex
    text = "v 0 0 0\nv 100 0 0\nv 100 100 0\nf -3 -2 -1\nv 0 100 0\nv 500 500 500\nf 1 3 4\n"
    part = load_part(write(tmp_path, "n.obj", text))
    assert part.area == pytest.approx(1e4)
    assert np.ptp(part.vertices, axis=0).max() == pytest.approx(100.0)  # vertex 6 is used by no face


@pytest.mark.parametrize(
    "text, words",
    [
        (OBJ.replace("f 1 2 3", "f 0 2 3"), ["line 5", "index 0"]),
        (OBJ.replace("f 1 3 4", "f 1 3 9"), ["line 6", "index 9", "has 4"]),
        ("v 0 0 0\nv 1 0 0\nf -1 -2 -3\nv 0 1 0\n", ["line 3", "-3"]),
        (OBJ.replace("f 1 2 3", "f 1 2"), ["line 5", "at least 3"]),
        (OBJ.replace("v 100 0 0", "v 100 0"), ["line 2", "3 coordinates"]),
        (OBJ.replace("v 100 0 0", "v 1_00 0 0"), ["line 2", "1_00"]),
        (OBJ.replace("f 1 2 3", "f 1 2 x"), ["line 5", "'x'"]),
        ("# nothing\n", ["no vertices"]),
    ],
)
def test_broken_obj(tmp_path, text, words):
    fails(write(tmp_path, "bad.obj", text), *words)


# --------------------------------------------------------------------------------------------------------
# PLY

PLY_HEAD = (
    "ply\nformat {fmt} 1.0\nelement vertex {nv}\nproperty float x\nproperty float y\nproperty float z\n"
    "element face {nf}\nproperty list uchar int vertex_indices\nend_header\n"
)


def ply_ascii(nv=4, nf=2, faces="3 0 1 2\n3 0 2 3\n", verts=None) -> str:
    verts = "".join(" ".join(f"{v:g}" for v in p) + "\n" for p in QUAD) if verts is None else verts
    return PLY_HEAD.format(fmt="ascii", nv=nv, nf=nf) + verts + faces


def ply_binary(faces=((0, 1, 2), (0, 2, 3)), nv=4, nf=None, order="<") -> bytes:
    fmt = "binary_little_endian" if order == "<" else "binary_big_endian"
    body = b"".join(struct.pack(order + "3f", *p) for p in QUAD)
    body += b"".join(struct.pack(f"{order}B{len(f)}i", len(f), *f) for f in faces)
    return PLY_HEAD.format(fmt=fmt, nv=nv, nf=len(faces) if nf is None else nf).encode() + body


@pytest.mark.parametrize("order", ["<", ">"])
def test_ply_valid_binary_ascii_and_mixed_polygons(tmp_path, order):
    for data in (ply_binary(order=order), ply_ascii(), ply_binary(faces=[(0, 1, 2, 3)], order=order)):
        part = load_part(write(tmp_path, "ok.ply", data))
        assert len(part.faces) == 2 and part.area == pytest.approx(1e4)
    mixed = ply_binary(faces=[(0, 1, 2), (0, 2, 3, 1)][:1] + [(0, 2, 3)], order=order)
    assert load_part(write(tmp_path, "m.ply", mixed)).area == pytest.approx(1e4)
    tri_quad = ply_ascii(nf=2, faces="3 0 1 2\n4 0 2 3 0\n")
    assert len(load_part(write(tmp_path, "tq.ply", tri_quad)).faces) <= 3


def test_a_signalling_nan_in_a_binary_ply_or_stl_is_one_error_and_no_warning(tmp_path, recwarn):
    """A byte flipped in a float32 coordinate can make a signalling NaN (exponent all ones, quiet bit clear):
    widened to float64 it raised numpy's 'invalid value encountered in cast' (the fuzz test met one in a PLY).
    Now, in a binary PLY or STL, only the reader's one-line error."""
    data = bytearray(ply_binary())
    at = data.index(b"end_header\n") + len(b"end_header\n")
    data[at : at + 4] = struct.pack("<I", 0x7F800001)  # the first vertex's x
    assert np.isnan(struct.unpack("<f", bytes(data[at : at + 4]))[0])
    fails(write(tmp_path, "snan.ply", bytes(data)), "NaN or infinite")
    from sprayplan.export.stl import write_stl_binary

    stl_data = bytearray(write_stl_binary(np.array([[[0.0, 0, 0], [100, 0, 0], [0, 100, 0]]])))
    stl_data[96:100] = struct.pack("<I", 0x7F800001)  # 80-byte header, count, normal: the first vertex's x
    fails(write(tmp_path, "snan.stl", bytes(stl_data)), "facet 1", "NaN or infinite")
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]


def test_ply_with_face_element_of_zero_rows_is_a_cloud(tmp_path):
    part = load_part(write(tmp_path, "c.ply", ply_ascii(nv=3, nf=0, faces="", verts="0 0 0\n100 0 0\n0 100 0\n")))
    assert not part.is_mesh and len(part.vertices) == 3


@pytest.mark.parametrize(
    "case, words",
    [
        ("binary cut in the middle", ["ends early", "'face'", "row 2"]),
        ("binary cut in the vertices", ["ends early", "'vertex'"]),
        ("faces declared, none held", ["ends early", "'face' declares 2 rows", "row 1"]),
        ("ascii fewer faces", ["ends early", "'face'"]),
        ("ascii fewer vertices", ["face"]),
        ("ascii short face list", ["ends early"]),
        ("ascii more rows than declared", ["after its last element", "fewer rows"]),
        ("binary more rows than declared", ["bytes after its last element"]),
        ("face index past the vertices", ["face 1 refers to vertex 7", "has 4"]),
        ("negative face index", ["face 2 refers to vertex -1"]),
        ("face of 2 indices", ["face 1 has 2 indices"]),
        ("count -3", ["'-3'", "whole number"]),
        ("count 4e9", ["'4e9'"]),
        ("count 4000000000", ["ends early", "4000000000"]),
        ("not a number", ["row 2", "'abc'"]),
        ("underscore", ["'1_0'"]),
        ("no end_header", ["end_header"]),
        ("no x", ["no x"]),
    ],
)
def test_broken_ply(tmp_path, case, words):
    good = ply_binary()
    data = {
        "binary cut in the middle": good[: len(good) - 5],
        "binary cut in the vertices": good[: good.index(b"end_header") + 11 + 20],
        "faces declared, none held": ply_ascii(faces=""),
        "ascii fewer faces": ply_ascii(faces="3 0 1 2\n"),
        "ascii fewer vertices": ply_ascii(verts="0 0 0\n100 0 0\n100 100 0\n"),
        "ascii short face list": ply_ascii(faces="3 0 1 2\n3 0 2\n"),
        "ascii more rows than declared": ply_ascii(faces="3 0 1 2\n3 0 2 3\n3 1 2 3\n"),
        "binary more rows than declared": good + struct.pack("<B3i", 3, 1, 2, 3),
        "face index past the vertices": ply_ascii(faces="3 0 1 7\n3 0 2 3\n"),
        "negative face index": ply_binary(faces=[(0, 1, 2), (0, 2, -1)]),
        "face of 2 indices": ply_ascii(faces="2 0 1\n3 0 2 3\n"),
        "count -3": ply_ascii(nf=-3),
        "count 4e9": ply_ascii(nf="4e9"),
        "count 4000000000": ply_binary(nf=4_000_000_000),
        "not a number": ply_ascii(verts="0 0 0\nabc 0 0\n100 100 0\n0 100 0\n"),
        "underscore": ply_ascii(verts="0 0 0\n1_0 0 0\n100 100 0\n0 100 0\n"),
        "no end_header": ply_ascii().replace("end_header", "end_head"),
        "no x": ply_ascii().replace("property float x", "property float w"),
    }[case]
    fails(write(tmp_path, "bad.ply", data), *words)


# --------------------------------------------------------------------------------------------------------
# OFF

OFF = "OFF\n4 2 0\n0 0 0\n100 0 0\n100 100 0\n0 100 0\n3 0 1 2\n3 0 2 3\n"


def test_off_valid_variants(tmp_path):
    for text in (
        OFF,
        OFF.replace("OFF\n4 2 0", "OFF 4 2 0"),
        "# comment\n" + OFF.replace("3 0 2 3", "3 0 2 3 255 0 0"),
        "COFF\n4 1 0\n0 0 0 1 1 1 1\n100 0 0 1 1 1 1\n100 100 0 1 1 1 1\n0 100 0 1 1 1 1\n4 0 1 2 3\n",
    ):
        part = load_part(write(tmp_path, "ok.off", text))
        assert len(part.faces) == 2 and part.area == pytest.approx(1e4)


@pytest.mark.parametrize(
    "text, words",
    [
        (OFF.replace("4 2 0", "4 -3 0"), ["line 2", "'4 -3 0'", "whole numbers"]),
        (OFF.replace("4 2 0", "4 4e9 0"), ["line 2", "4e9"]),
        (OFF.replace("4 2 0", "4 4000000000 0"), ["ends early", "4000000000 faces"]),
        (OFF.replace("3 0 1 2\n", "3 0 1\n"), ["line 7", "declares 3 indices", "has 2"]),
        (OFF.replace("3 0 1 2\n", "4 0 1 2\n"), ["line 7", "declares 4 indices", "has 3"]),
        (OFF.replace("3 0 1 2\n", "3 0 1 2 3 4\n"), ["line 7", "declares 3 indices"]),
        (OFF.replace("3 0 2 3\n", ""), ["ends early", "holds 4 and 1"]),
        (OFF + "3 1 2 3\n", ["line 9", "more lines"]),
        (OFF.replace("3 0 2 3", "3 0 2 9"), ["line 8", "vertex 9"]),
        (OFF.replace("3 0 2 3", "2 0 2"), ["line 8", "at least 3"]),
        (OFF.replace("100 0 0", "100 0"), ["line 4", "3 coordinates"]),
        (OFF.replace("100 0 0", "1_00 0 0"), ["line 4", "'1_00'"]),
        ("PFF\n4 2 0\n", ["not an OFF file"]),
    ],
)
def test_broken_off(tmp_path, text, words):
    fails(write(tmp_path, "bad.off", text), *words)


# --------------------------------------------------------------------------------------------------------
# ASCII STL

FACET = "facet normal 0 0 1\n outer loop\n  vertex 0 0 0\n  vertex 100 0 0\n  vertex 0 100 0\n endloop\nendfacet\n"
FACET2 = "facet normal 0 0 1\n outer loop\n  vertex 0 0 0\n  vertex 100 0 0\n endloop\nendfacet\n"
FACET4 = FACET.replace("  vertex 0 100 0\n", "  vertex 0 100 0\n  vertex 100 100 0\n")


def stl(body, name="part") -> str:
    return f"solid {name}\n{body}endsolid {name}\n"


def test_stl_case_insensitive_and_names_with_keywords(tmp_path):
    upper = stl(FACET.upper(), "PART").replace("solid", "SOLID")
    assert len(load_part(write(tmp_path, "u.stl", upper)).faces) == 1
    mixed = stl(FACET.replace("vertex", "Vertex").replace("facet normal", "Facet Normal"))
    assert len(load_part(write(tmp_path, "m.stl", mixed)).faces) == 1
    named = stl(FACET + FACET.replace("0 100 0", "0 0 100"), "my facet part with vertex 1 2 3 endloop")
    assert len(load_part(write(tmp_path, "n.stl", named)).faces) == 2
    tabs = stl(FACET.replace(" ", "\t").replace("\n", "\r\n"))
    assert len(load_part(write(tmp_path, "t.stl", tabs)).faces) == 1


@pytest.mark.parametrize(
    "text, words",
    [
        (stl(FACET2 + FACET4), ["line 6", "2 vertices", "exactly 3"]),
        (stl(FACET4 + FACET2), ["line 7", "4th vertex", "exactly 3"]),
        ("solid part\n" + FACET + FACET, ["truncated", "without 'endsolid'"]),
        (stl(FACET.replace("vertex 100 0 0", "vertex 1_000 0 0")), ["line 5", "'1_000'", "not a number"]),
        (stl(FACET) + "facet\n", ["line 10", "unexpected 'facet'"]),
        (stl(FACET.replace("outer loop", "outer")), ["line 4", "'vertex' where 'loop'"]),
        (stl(FACET) + "endsolid b\n", ["line 10", "'endsolid' without a 'solid'"]),
        (stl(FACET).replace("vertex 0 0 0", "vertex 0 0 1e400"), ["NaN or infinite"]),
    ],
)
def test_broken_ascii_stl(tmp_path, text, words):
    fails(write(tmp_path, "bad.stl", text), *words)


# --------------------------------------------------------------------------------------------------------
# coordinates, normals, degenerate clouds


def test_coordinates_beyond_a_plausible_size_name_the_unit(tmp_path):
    big = OBJ.replace("v 100 100 0", "v 2e4 100 0")
    assert np.ptp(load_part(write(tmp_path, "ok.obj", big)).vertices, axis=0).max() == pytest.approx(2e4)
    fails(write(tmp_path, "m.obj", big), "vertex 3", "20000 m", "1e+07 mm", "--units", units="m")
    fails(write(tmp_path, "huge.obj", OBJ.replace("v 100 100 0", "v 1e300 100 0")), "1e+300 mm")
    # 1e300 m overflows to inf when scaled: still the bound's message, with the unit
    fails(write(tmp_path, "o.obj", OBJ.replace("v 100 100 0", "v 1e300 100 0")), "1e+300 m ", units="m")
    fails(write(tmp_path, "c.xyz", "0 0 0\n1 0 0\n0 1 0\n0 0 2e7\n"), "vertex 4", "mm")
    fails(write(tmp_path, "inf.off", OFF.replace("100 0 0", "inf 0 0")), "NaN or infinite")


@pytest.mark.parametrize(
    "text, words",
    [
        ("x y z nx ny nz\n0 0 0 0 0 1\n1 0 0 0 0 0\n0 1 0 0 0 1\n", ["line 3", "zero length"]),
        ("x y z nx ny nz\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 nan 0 1\n", ["line 4", "NaN"]),
        ("x y z nx ny nz\n0 0 0 0 0 1e-12\n1 0 0 0 0 1\n0 1 0 0 0 1\n", ["line 2", "zero length"]),
    ],
)
def test_xyz_normals_of_zero_or_no_length(tmp_path, text, words):
    path = write(tmp_path, "n.xyz", text)
    with pytest.raises(PartFileError) as info:
        read_xyz(path)
    assert str(info.value).startswith(path) and all(w in str(info.value) for w in words)


def _pcd(normals: list[tuple[float, float, float]], kind: str) -> bytes:
    n = len(normals)
    head = (
        "VERSION .7\nFIELDS x y z normal_x normal_y normal_z\nSIZE 4 4 4 4 4 4\nTYPE F F F F F F\nCOUNT 1 1 1 1 1 1\n"
        f"WIDTH {n}\nHEIGHT 1\nPOINTS {n}\nDATA {kind}\n"
    ).encode()
    points = [(float(i), float(i * i % 7), 1.0) for i in range(n)]
    if kind == "ascii":
        return head + "".join(" ".join(map(str, p + q)) + "\n" for p, q in zip(points, normals)).encode()
    return head + b"".join(struct.pack("<6f", *p, *q) for p, q in zip(points, normals))


@pytest.mark.parametrize("kind, where", [("ascii", "line 11"), ("binary", "point 2 of 4")])
@pytest.mark.parametrize("bad", [(0.0, 0.0, 0.0), (float("nan"), 0.0, 1.0), (float("inf"), 0.0, 0.0)])
def test_pcd_normals_of_zero_or_no_length(tmp_path, kind, where, bad):
    normals = [(0.0, 0.0, 1.0), bad, (0.0, 0.0, 1.0), (0.0, 0.0, 1.0)]
    path = write(tmp_path, "n.pcd", _pcd(normals, kind))
    with pytest.raises(PartFileError, match=where) as info:
        read_pcd(path)
    assert str(info.value).startswith(path)


@pytest.mark.parametrize(
    "text, words",
    [
        ("0 0 0\n1 1 1\n", ["2 points", "at least 3"]),
        ("5 5 5\n5 5 5\n5 5 5\n5 5 5\n", ["coincide"]),
        ("0 0 0\n1 2 3\n2 4 6\n-1 -2 -3\n10 20 30\n", ["one line"]),
    ],
)
def test_degenerate_clouds(tmp_path, text, words):
    fails(write(tmp_path, "d.xyz", text), "degenerate" if "at least" not in words[-1] else "", *words)


def test_thin_but_planar_cloud_loads(tmp_path):
    text = "0 0 0\n1000 0 0\n0 0.01 0\n1000 0.01 0\n"
    assert len(load_part(write(tmp_path, "thin.xyz", text)).vertices) == 4


# --------------------------------------------------------------------------------------------------------
# pose tables


def _poses(rows) -> str:
    head = "x,y,z,r11,r12,r13,r21,r22,r23,r31,r32,r33\n"
    return head + "".join(",".join(f"{v:.9g}" for v in [0, 0, 0, *np.asarray(r).ravel()]) + "\n" for r in rows)


def test_pose_matrices_must_be_rotations(tmp_path):
    turn = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    ok = read_poses(write(tmp_path, "ok.csv", _poses([np.eye(3), turn + 2e-5])), "matrix")
    np.testing.assert_allclose(ok[1, :3, :3], turn, atol=1e-4)
    mirror = np.diag([1.0, 1.0, -1.0])
    path = write(tmp_path, "m.csv", "# poses\n" + _poses([np.eye(3), turn, mirror]))
    with pytest.raises(PartFileError, match=r"line 5 \(pose 3\).*determinant -1") as info:
        read_poses(path, "matrix")
    assert str(info.value).startswith(path)
    path = write(tmp_path, "s.csv", _poses([np.eye(3) * 1.01]))
    with pytest.raises(PartFileError, match=r"line 2 \(pose 1\).*not orthonormal.*tolerance 0.0001"):
        read_poses(path, "matrix")


# --------------------------------------------------------------------------------------------------------
# inputs that are not regular files: refused before they are opened (a FIFO would block forever)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes here")
@pytest.mark.parametrize(
    "name", ["part.stl", "part.ply", "part.obj", "cloud.xyz", "cloud.pcd", "poses.csv", "p.stl.gz"]
)
def test_named_pipe_is_refused_before_open(tmp_path, name):
    fifo = tmp_path / name
    os.mkfifo(fifo)
    signal.alarm(20)  # were the pipe opened, the test would block: end it with an error instead of hanging
    try:
        _read_every_way(fifo)
    finally:
        signal.alarm(0)


def _read_every_way(fifo):
    for read in (load_part, read_file_bytes, lambda p: read_poses(p, "rotvec")):
        with pytest.raises(PartFileError, match="named pipe") as info:
            read(fifo)
        assert str(info.value).startswith(str(fifo))


def test_folder_and_device_are_refused(tmp_path):
    folder = tmp_path / "part.stl"
    folder.mkdir()
    with pytest.raises(PartFileError, match="folder"):
        load_part(folder)
    with pytest.raises(PartFileError, match="folder"):
        read_poses(folder)
    if os.path.exists("/dev/null"):
        with pytest.raises(PartFileError, match="device"):
            read_file_bytes("/dev/null")


# --------------------------------------------------------------------------------------------------------
# fuzz: random corruptions of real files load as finite, in-range data or fail with a PartFileError

FUZZ = settings(max_examples=60, deadline=None, database=None, suppress_health_check=list(HealthCheck))


def _small_real_files(testdata):
    gazebo = (testdata / "meshes" / "gazebo_suv_body_m.ply").read_bytes()
    return {
        "suv.ply": gazebo,
        "quad.ply": ply_ascii().encode(),
        "quad.off": OFF.encode(),
        "quad.obj": OBJ.encode(),
        "tri.stl": stl(FACET + FACET.replace("0 100 0", "0 0 100")).encode(),
    }


@pytest.fixture(scope="module")
def real_files(testdata):
    return _small_real_files(testdata)


def _load_or_error(path, units="mm"):
    try:
        part = load_part(path, units=units)
    except PartFileError as exc:
        message = str(exc)
        assert message.startswith(f"{path}: ") and "\n" not in message
        return None
    assert np.isfinite(part.vertices).all() and np.abs(part.vertices).max() <= 1e7
    if part.is_mesh:
        assert part.faces.min() >= 0 and part.faces.max() < len(part.vertices)
    return part


@FUZZ
@given(
    st.sampled_from(sorted(["suv.ply", "quad.ply", "quad.off", "quad.obj", "tri.stl"])),
    st.integers(0, 10**9),
    st.lists(st.tuples(st.integers(0, 10**9), st.integers(0, 255)), max_size=6),
    st.sampled_from(["cut", "flip", "both", "insert"]),
)
def test_fuzz_corrupted_real_files(tmp_path_factory, real_files, name, cut, flips, how):
    data = bytearray(real_files[name])
    if how in ("cut", "both"):
        data = data[: cut % (len(data) + 1)]
    if how in ("flip", "both"):
        for pos, value in flips:
            if data:
                data[pos % len(data)] = value
    if how == "insert":
        for pos, value in flips:
            at = pos % (len(data) + 1)
            data[at:at] = bytes([value]) * (1 + value % 5)
    path = tmp_path_factory.mktemp("fuzz") / name
    path.write_bytes(bytes(data))
    _load_or_error(str(path), units="m" if name == "suv.ply" else "mm")


def test_every_unbroken_fuzz_base_loads(tmp_path, real_files):
    for name, data in real_files.items():
        path = write(tmp_path, name, data)
        assert _load_or_error(path, units="m" if name == "suv.ply" else "mm") is not None
