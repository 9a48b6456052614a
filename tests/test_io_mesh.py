"""Loading meshes: every real test mesh loads, STL variants agree, units and up axes convert, bad files fail."""

from __future__ import annotations

import gzip
import logging

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from sprayplan.errors import ConfigError, PartFileError
from sprayplan.export.stl import write_stl_binary
from sprayplan.io.load import load_part
from sprayplan.io.stl import parse_stl

# (file, units, triangles in the file (tests/data/MANIFEST.md), largest side in mm after conversion)
MESHES = [
    ("reach_curved_part.ply", "m", 4049, 1590.9),
    ("noether_raw_scan_mesh.ply", "m", 56884, 1277.04),
    ("tray_bottom_mm_ascii.stl", "mm", 4520, 355.6),
    ("featuretype_binary.stl", "in", 3476, 5.0 * 25.4),
    ("bmw_m6_body_m_yup.ply", "m", 69930, 4870.0),
    ("gazebo_suv_body_m.ply", "m", 1210, 5020.1),
]


@pytest.mark.parametrize("name, units, triangles, size_mm", MESHES)
def test_every_test_mesh_loads(testdata, name, units, triangles, size_mm):
    path = testdata / "meshes" / name
    # the table's count, checked against an independent reader of the same file
    assert len(trimesh.load(path, process=False, force="mesh").faces) == triangles
    part = load_part(path, units=units)
    assert part.is_mesh
    # degenerate triangles may be dropped, never more than a handful of the file's
    assert triangles - 10 <= len(part.faces) <= triangles
    assert part.face_areas.min() > 0
    assert np.ptp(part.vertices, axis=0).max() == pytest.approx(size_mm, rel=1e-3)
    assert np.isfinite(part.vertices).all()


@pytest.fixture(scope="module")
def tray_bytes(testdata):
    return (testdata / "meshes" / "tray_bottom_mm_ascii.stl").read_bytes()


def test_ascii_and_binary_stl_give_the_same_triangles(tray_bytes):
    ascii_tri = parse_stl(tray_bytes, "tray")
    binary_tri = parse_stl(write_stl_binary(ascii_tri), "tray.bin")
    # binary STL stores float32: equal to the ASCII values rounded to float32
    np.testing.assert_array_equal(binary_tri, ascii_tri.astype(np.float32).astype(np.float64))
    assert len(ascii_tri) == 4520


def test_binary_stl_whose_header_starts_with_solid(tray_bytes):
    tri = parse_stl(tray_bytes, "tray")
    data = write_stl_binary(tri, header=b"solid but really binary")
    assert data.startswith(b"solid")
    np.testing.assert_array_equal(parse_stl(data, "x"), tri.astype(np.float32))


def test_crlf_lf_and_several_solid_blocks_agree(tray_bytes):
    assert b"\r\n" in tray_bytes
    lf = tray_bytes.replace(b"\r\n", b"\n")
    tri = parse_stl(tray_bytes, "crlf")
    np.testing.assert_array_equal(parse_stl(lf, "lf"), tri)
    # split the facets into two solid blocks
    body = lf[lf.index(b"\n") + 1 : lf.rindex(b"endsolid")]
    cut = body.index(b"endfacet", len(body) // 2) + len(b"endfacet\n")
    two = b"solid a\n" + body[:cut] + b"endsolid a\nsolid b\n" + body[cut:] + b"endsolid b\n"
    np.testing.assert_array_equal(parse_stl(two, "two"), tri)


def test_binary_featuretype_loads_with_merged_vertices(testdata):
    part = load_part(testdata / "meshes" / "featuretype_binary.stl", units="in")
    raw = parse_stl((testdata / "meshes" / "featuretype_binary.stl").read_bytes(), "f")
    # merging the soup's 3 m vertices leaves far fewer, and the triangles are unchanged
    assert len(part.vertices) < len(raw.reshape(-1, 3)) / 3
    np.testing.assert_allclose(part.area, _soup_area(raw) * 25.4**2, rtol=1e-9)


def _soup_area(tri):
    return 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum()


def test_units_scale_to_mm(testdata):
    path = testdata / "meshes" / "reach_curved_part.ply"
    in_m = load_part(path, units="m")
    in_cm = load_part(path, units="cm")
    np.testing.assert_allclose(in_m.vertices, in_cm.vertices * 100.0)


def test_warns_when_the_unit_looks_wrong(testdata, caplog):
    with caplog.at_level(logging.WARNING, logger="sprayplan"):
        load_part(testdata / "meshes" / "reach_curved_part.ply", units="mm")
    assert any("--units m" in r.getMessage() for r in caplog.records)
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="sprayplan"):
        load_part(testdata / "meshes" / "reach_curved_part.ply", units="m")
    assert not caplog.records


@pytest.mark.parametrize("up", ["y", "x"])
def test_up_axis_turns_the_model_to_z_up(testdata, up):
    # the tray is a y-up model: 355.6 x 3.175 x 355.6 mm, thin along y
    tray = load_part(testdata / "meshes" / "tray_bottom_mm_ascii.stl")
    turned = load_part(testdata / "meshes" / "tray_bottom_mm_ascii.stl", up=up)
    extent = np.ptp(turned.vertices, axis=0)
    if up == "y":
        np.testing.assert_allclose(extent, [355.6, 355.6, 3.175], rtol=1e-9)
    else:
        np.testing.assert_allclose(extent, np.ptp(tray.vertices, axis=0)[[2, 1, 0]], rtol=1e-9)
    # a proper rotation: areas and edge lengths are unchanged
    assert turned.area == pytest.approx(tray.area, rel=1e-12)


def test_obj_with_missing_material_loads_as_geometry(tmp_path, caplog):
    obj = tmp_path / "panel.obj"
    obj.write_text(
        "mtllib missing.mtl\nusemtl paint\n"
        "v 0 0 0\nv 100 0 0\nv 100 100 0\nv 0 100 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
        "f 1/1 2/2 3/3\nf 1/1 3/3 4/4\n"
    )
    with caplog.at_level(logging.INFO, logger="sprayplan"):
        part = load_part(obj)
    assert len(part.faces) == 2
    assert part.area == pytest.approx(10000.0)
    assert any("ignoring material" in r.getMessage() for r in caplog.records)


def test_ply_without_faces_is_a_point_cloud(tmp_path):
    ply = tmp_path / "cloud.ply"
    points = np.random.default_rng(0).random((50, 3)) * 100
    header = (
        "ply\nformat ascii 1.0\nelement vertex 50\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
    )
    ply.write_text(header + "\n".join(" ".join(f"{v:.4f}" for v in p) for p in points) + "\n")
    part = load_part(ply)
    assert not part.is_mesh
    np.testing.assert_allclose(part.vertices, points, atol=1e-4)


def test_degenerate_triangles_are_dropped_and_counted(tmp_path, caplog):
    tri = np.array(
        [
            [[0, 0, 0], [100, 0, 0], [0, 100, 0]],
            [[0, 0, 0], [50, 0, 0], [100, 0, 0]],  # collinear: zero area
            [[5, 5, 5], [5, 5, 5], [5, 5, 5]],  # a point
        ],
        dtype=float,
    )
    path = tmp_path / "d.stl"
    path.write_bytes(write_stl_binary(tri))
    with caplog.at_level(logging.INFO, logger="sprayplan"):
        part = load_part(path)
    assert len(part.faces) == 1
    assert len(part.vertices) == 3
    assert any("dropped 2 degenerate" in r.getMessage() for r in caplog.records)


@pytest.mark.parametrize(
    "content, words",
    [
        (b"", "empty"),
        (b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\n", "truncated"),
        (
            b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 zero 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid\n",
            "line 5",
        ),
        (
            b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 nan 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid\n",
            "NaN",
        ),
        (
            b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nendloop\nendfacet\nendsolid\n",
            "exactly 3",
        ),
        (b"solid x\nendsolid x\n", "no facets"),
        (b"\x00" * 50, "too short"),
    ],
)
def test_broken_stl_gives_a_clear_error(tmp_path, content, words):
    path = tmp_path / "bad.stl"
    path.write_bytes(content)
    with pytest.raises(PartFileError) as info:
        load_part(path)
    message = str(info.value)
    assert message.startswith(str(path)) and words in message
    assert "\n" not in message


def test_truncated_binary_stl_says_expected_and_actual_size(tmp_path, tray_bytes):
    data = write_stl_binary(parse_stl(tray_bytes, "t"))
    path = tmp_path / "cut.stl"
    path.write_bytes(data[:-7])
    with pytest.raises(PartFileError, match=f"4520 facets .*{len(data)} bytes.* {len(data) - 7} bytes"):
        load_part(path)


def test_mesh_with_only_degenerate_triangles_is_rejected(tmp_path):
    path = tmp_path / "flat.stl"
    path.write_bytes(write_stl_binary(np.array([[[0, 0, 0], [1, 1, 1], [2, 2, 2]]], dtype=float)))
    with pytest.raises(PartFileError, match="no triangle of positive area"):
        load_part(path)


def test_infinite_binary_coordinate_is_rejected(tmp_path):
    path = tmp_path / "inf.stl"
    path.write_bytes(write_stl_binary(np.array([[[0, 0, 0], [1, 0, 0], [np.inf, 1, 0]]], dtype=float)))
    with pytest.raises(PartFileError, match="facet 1: NaN or infinite"):
        load_part(path)


def test_missing_unknown_and_bad_gzip(tmp_path):
    with pytest.raises(PartFileError, match="no such file"):
        load_part(tmp_path / "nope.stl")
    (tmp_path / "part.step").write_text("ISO-10303-21;")
    with pytest.raises(PartFileError, match="unknown file type '.step'"):
        load_part(tmp_path / "part.step")
    (tmp_path / "part.stl.gz").write_bytes(b"not gzip at all")
    with pytest.raises(PartFileError, match="not a valid gzip"):
        load_part(tmp_path / "part.stl.gz")
    with pytest.raises(ConfigError):
        load_part(tmp_path / "part.stl.gz", units="furlong")


def test_gzipped_stl_equals_plain(tmp_path, tray_bytes):
    (tmp_path / "t.stl").write_bytes(tray_bytes)
    (tmp_path / "t.stl.gz").write_bytes(gzip.compress(tray_bytes))
    a, b = load_part(tmp_path / "t.stl"), load_part(tmp_path / "t.stl.gz")
    np.testing.assert_array_equal(a.vertices, b.vertices)
    np.testing.assert_array_equal(a.faces, b.faces)


def _parse_or_error(data: bytes):
    try:
        tri = parse_stl(data, "fuzz.stl")
    except PartFileError as exc:
        assert str(exc).startswith("fuzz.stl: ")
        return None
    assert tri.ndim == 3 and tri.shape[1:] == (3, 3)
    assert np.isfinite(tri).all()
    return tri


@settings(max_examples=300, deadline=2000)
@given(st.binary(max_size=400))
def test_fuzz_stl_random_bytes(data):
    result = _parse_or_error(data)
    assert result is None or result.shape[1:] == (3, 3)


@settings(max_examples=300, deadline=2000)
@given(
    st.integers(min_value=0, max_value=2000),
    st.lists(st.tuples(st.integers(0, 1999), st.integers(0, 255)), max_size=8),
    st.booleans(),
)
def test_fuzz_stl_mutated_files(cut, flips, binary):
    base = (
        b"solid f\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 1 0 0\n   vertex 0 1 0\n"
        b"  endloop\n endfacet\n facet normal 0 0 1\n  outer loop\n   vertex 1 0 0\n   vertex 1 1 0\n"
        b"   vertex 0 1 0\n  endloop\n endfacet\nendsolid f\n"
    )
    if binary:
        base = write_stl_binary(parse_stl(base, "b"), header=b"solid fuzz")
    data = bytearray(base[: min(cut, len(base))] if cut < len(base) else base)
    for pos, value in flips:
        if data:
            data[pos % len(data)] = value
    result = _parse_or_error(bytes(data))
    assert result is None or np.isfinite(result).all()
