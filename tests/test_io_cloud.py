"""Tests of sprayplan.io.cloud and io.pcd: XYZ text and PCD (ascii, binary, binary_compressed) point clouds."""

from __future__ import annotations

import logging
import struct

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sprayplan.errors import PartFileError
from sprayplan.io.cloud import read_xyz
from sprayplan.io.pcd import _lzf_decompress, read_pcd

FUZZ = settings(
    max_examples=200,
    deadline=2000,  # ms: a parse that hangs or crawls fails the test
    database=None,  # write nothing into the repository
    suppress_health_check=[HealthCheck.too_slow],
)

# --------------------------------------------------------------------------------------------------------
# helpers that write files: an LZF encoder (two of them) and a PCD writer


def lzf_literal(data: bytes) -> bytes:
    """LZF encoding with literal runs only (valid LZF: every control byte < 32)."""
    out = bytearray()
    for start in range(0, len(data), 32):
        chunk = data[start : start + 32]
        out.append(len(chunk) - 1)
        out += chunk
    return bytes(out)


def lzf_greedy(data: bytes) -> bytes:
    """A small greedy LZF encoder that uses back-references (also overlapping ones)."""
    out = bytearray()
    literal = bytearray()

    def flush() -> None:
        out.extend(lzf_literal(bytes(literal)))
        literal.clear()

    last_seen: dict[bytes, int] = {}
    i = 0
    while i < len(data):
        key = data[i : i + 3]
        candidate = last_seen.get(key) if len(key) == 3 else None
        if len(key) == 3:
            last_seen[key] = i
        if candidate is not None and i - candidate <= 8192:
            length = 0
            limit = min(264, len(data) - i)
            while length < limit and data[candidate + length] == data[i + length]:
                length += 1
            if length >= 3:
                flush()
                offset, code = i - candidate - 1, length - 2
                if code < 7:
                    out.append((code << 5) | (offset >> 8))
                else:
                    out += bytes([(7 << 5) | (offset >> 8), code - 7])
                out.append(offset & 0xFF)
                i += length
                continue
        literal.append(data[i])
        i += 1
    flush()
    return bytes(out)


_NUMPY_KIND = {"F": "f", "I": "i", "U": "u"}


def pcd_bytes(fields, columns, kind, *, encoder=lzf_literal, width=None, height=1):
    """The bytes of a PCD file.

    fields: list of (name, TYPE, SIZE, COUNT); columns: name -> array of n rows (COUNT columns each).
    """
    n = len(np.asarray(columns[fields[0][0]]))
    width = n if width is None else width
    header = [
        "# .PCD v0.7 - Point Cloud Data file format",
        "VERSION 0.7",
        "FIELDS " + " ".join(f[0] for f in fields),
        "SIZE " + " ".join(str(f[2]) for f in fields),
        "TYPE " + " ".join(f[1] for f in fields),
        "COUNT " + " ".join(str(f[3]) for f in fields),
        f"WIDTH {width}",
        f"HEIGHT {height}",
        "VIEWPOINT 0 0 0 1 0 0 0",
        f"POINTS {n}",
        f"DATA {kind}",
    ]
    dtype = np.dtype([(f"f{i}", f"<{_NUMPY_KIND[t]}{s}", (c,)) for i, (_, t, s, c) in enumerate(fields)])
    records = np.zeros(n, dtype=dtype)
    for i, (name, _, _, count) in enumerate(fields):
        records[f"f{i}"] = np.asarray(columns[name]).reshape(n, count)
    head = ("\n".join(header) + "\n").encode()
    if kind == "binary":
        return head + records.tobytes()
    if kind == "binary_compressed":
        raw = b"".join(records[f"f{i}"].tobytes() for i in range(len(fields)))
        block = encoder(raw)
        return head + struct.pack("<II", len(block), len(raw)) + block
    rows = []
    for record in records:
        tokens = []
        for i, (_, letter, _, _) in enumerate(fields):
            for value in record[f"f{i}"]:
                tokens.append(repr(float(value)) if letter == "F" else str(int(value)))
        rows.append(" ".join(tokens))
    return head + ("\n".join(rows) + "\n").encode()


XYZ_F4 = [("x", "F", 4, 1), ("y", "F", 4, 1), ("z", "F", 4, 1)]
PCD_KINDS = ["ascii", "binary", "binary_compressed"]


def random_points(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.uniform(-50.0, 50.0, size=(n, 3))


def as_f32(values: np.ndarray) -> np.ndarray:
    return np.asarray(values, dtype=np.float32).astype(np.float64)


def write(tmp_path, name: str, data: bytes):
    path = tmp_path / name
    path.write_bytes(data)
    return path


# --------------------------------------------------------------------------------------------------------
# the real files


def test_real_pcd_files_load_with_their_counts(testdata, caplog):
    folder = testdata / "pointclouds"
    for name, expected in [("pcl_car6.pcd", 10031), ("pcl_milk.pcd", 13704)]:
        raw = (folder / name).read_bytes()
        assert f"\nPOINTS {expected}\n".encode() in raw
        caplog.clear()
        with caplog.at_level(logging.INFO, logger="sprayplan.io.pcd"):
            points, normals = read_pcd(folder / name)
        # Both scans hold no NaN point (measured): all declared points come back and none is reported dropped.
        assert points.shape == (expected, 3)
        assert points.dtype == np.float64
        assert np.isfinite(points).all()
        assert normals is None
        assert not [r for r in caplog.records if "NaN" in r.getMessage()]
        # a real scan, not zeros or a constant
        assert np.ptp(points, axis=0).min() > 0.1


def test_reach_part_has_unit_normals(testdata):
    points, normals = read_pcd(testdata / "pointclouds" / "reach_part_normals_ascii.pcd")
    assert points.shape == (262, 3)
    assert normals is not None and normals.shape == (262, 3)
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-3)
    # first data row of the file
    np.testing.assert_allclose(points[0], [-0.15477885, -0.51307797, -0.003728545])
    np.testing.assert_allclose(normals[0], [0.60230958, -0.67133045, -0.43190104])
    # normals are not just a copy of some coordinate columns
    assert not np.allclose(normals, points)


def test_car6_compressed_equals_derived_xyz(testdata):
    folder = testdata / "pointclouds"
    points, _ = read_pcd(folder / "pcl_car6.pcd")
    reference, normals = read_xyz(folder / "pcl_car6.derived.xyz")
    assert normals is None
    assert reference.shape == points.shape == (10031, 3)
    # The PCD stores float32; the text has 6 decimals. A float32 value near |c| is off its decimal original
    # by at most |c| * eps32 / 2, and the 6-decimal text rounds by 5e-7: so the tolerance is
    # max|c| * eps32 + 1e-6 (about 9e-6 for coordinates up to ~69 m). Any wrong byte, wrong field order or a
    # row shift gives errors of centimetres or more.
    eps32 = float(np.finfo(np.float32).eps)
    tolerance = float(np.abs(reference).max()) * eps32 + 1e-6
    assert tolerance < 2e-5
    np.testing.assert_allclose(points, reference, rtol=0, atol=tolerance)


# --------------------------------------------------------------------------------------------------------
# LZF


@pytest.mark.parametrize(
    ("block", "decoded"),
    [
        (b"\x02abc", b"abc"),  # literal only
        (b"\x02abc" + bytes([1 << 5, 2]), b"abcabc"),  # back-reference, distance 3 = length 3: no overlap
        (b"\x00a" + bytes([7 << 5, 0, 0]), b"a" * 10),  # 1 literal + overlapping copy of 9 (length byte)
        (b"\x01ab" + bytes([2 << 5, 1]), b"ababab"),  # overlap with period 2
        (b"\x00z" + bytes([7 << 5, 255, 0]), b"z" * 265),  # longest back-reference: 264 bytes
    ],
)
def test_lzf_known_blocks(block, decoded):
    assert _lzf_decompress(block, len(decoded)) == decoded


def test_lzf_far_back_reference():
    literal = bytes(range(256)) + bytes(range(44))  # 300 bytes
    block = lzf_literal(literal) + bytes([(3 << 5) | (299 >> 8), 299 & 0xFF])  # length 5, distance 300
    assert _lzf_decompress(block, 305) == literal + literal[:5]


@pytest.mark.parametrize(
    ("block", "size"),
    [
        (b"\x05ab", 6),  # literal runs past the end
        (b"\x00a" + bytes([1 << 5, 1]), 4),  # distance 2 from an output of 1 byte
        (b"\x00a" + bytes([7 << 5]), 10),  # back-reference cut off
        (b"\x00a" + bytes([1 << 5]), 10),  # distance byte missing
        (b"\x02abc", 2),  # longer than declared
        (b"\x02abc", 4),  # shorter than declared
    ],
)
def test_lzf_corrupt_blocks_are_rejected(block, size):
    with pytest.raises(ValueError):
        _lzf_decompress(block, size)


@given(
    st.lists(st.sampled_from([b"ab", b"abc", b"\x00\x00\x00\x00", b"xyz!", b"\x7f"]), max_size=200),
    st.binary(max_size=50),
)
@FUZZ
def test_lzf_greedy_round_trip(chunks, noise):
    data = b"".join(chunks) + noise
    assert _lzf_decompress(lzf_greedy(data), len(data)) == data


# --------------------------------------------------------------------------------------------------------
# PCD round trips


@pytest.fixture(scope="module")
def cloud_with_normals():
    points = random_points(300, seed=1)
    points[:, 2] = 0.25  # a flat part: the compressed z block is one long repeated pattern
    rng = np.random.default_rng(2)
    normals = rng.normal(size=(300, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return points, normals


@pytest.mark.parametrize(
    ("kind", "encoder"),
    [
        ("ascii", None),
        ("binary", None),
        ("binary_compressed", lzf_literal),
        ("binary_compressed", lzf_greedy),
    ],
)
def test_pcd_kinds_give_identical_arrays(tmp_path, cloud_with_normals, kind, encoder):
    points, normals = cloud_with_normals
    fields = XYZ_F4 + [("normal_x", "F", 4, 1), ("normal_y", "F", 4, 1), ("normal_z", "F", 4, 1)]
    columns = dict(zip("xyz", points.T)) | dict(zip(["normal_x", "normal_y", "normal_z"], normals.T))
    data = pcd_bytes(fields, columns, kind, encoder=encoder or lzf_literal)
    if encoder is lzf_greedy:  # the block really uses back-references
        block = data[data.index(b"binary_compressed\n") + 26 :]
        assert len(block) < 0.9 * len(points) * 24
    got_points, got_normals = read_pcd(write(tmp_path, "c.pcd", data))
    # float32 in the file: the exact float32 values come back, in the same order, whatever the encoding
    np.testing.assert_array_equal(got_points, as_f32(points))
    np.testing.assert_array_equal(got_normals, as_f32(normals))


def test_pcd_hand_made_block_with_overlapping_back_reference(tmp_path):
    # 4 points (1.5, 1.5, 1.5): the 48 uncompressed bytes are 12 times the float32 1.5 = 00 00 c0 3f.
    # Encoded as one literal of those 4 bytes and one back-reference of length 44 at distance 4.
    block = bytes([0x03, 0x00, 0x00, 0xC0, 0x3F, 0xE0, 44 - 2 - 7, 4 - 1])
    head = pcd_bytes(XYZ_F4, {"x": [0.0] * 4, "y": [0.0] * 4, "z": [0.0] * 4}, "binary_compressed")
    head = head[: head.index(b"binary_compressed\n") + 18]
    points, _ = read_pcd(write(tmp_path, "h.pcd", head + struct.pack("<II", len(block), 48) + block))
    np.testing.assert_array_equal(points, np.full((4, 3), 1.5))


@pytest.mark.parametrize("kind", PCD_KINDS)
def test_pcd_extra_fields_do_not_shift_xyz(tmp_path, kind):
    n = 40
    points = random_points(n, seed=3)
    rng = np.random.default_rng(4)
    fields = [
        ("rgb", "U", 4, 1),
        ("x", "F", 4, 1),
        ("uv", "F", 4, 2),
        ("y", "F", 8, 1),
        ("_", "U", 1, 3),
        ("intensity", "I", 2, 1),
        ("z", "F", 4, 1),
        ("curvature", "F", 4, 1),
    ]
    columns = {
        "rgb": rng.integers(0, 2**32, n, dtype=np.uint64),
        "x": points[:, 0],
        "uv": rng.uniform(-1e6, 1e6, (n, 2)),
        "y": points[:, 1],
        "_": np.zeros((n, 3)),
        "intensity": rng.integers(-30000, 30000, n),
        "z": points[:, 2],
        "curvature": rng.uniform(0, 1, n),
    }
    got, normals = read_pcd(write(tmp_path, "e.pcd", pcd_bytes(fields, columns, kind)))
    assert normals is None
    expected = np.column_stack([as_f32(points[:, 0]), points[:, 1], as_f32(points[:, 2])])  # y is F 8
    np.testing.assert_array_equal(got, expected)


@pytest.mark.parametrize("kind", PCD_KINDS)
def test_pcd_nan_points_are_dropped_and_counted(tmp_path, caplog, kind):
    points = random_points(20, seed=5)
    points[[0, 7, 13], :] = np.nan  # organised cloud: no return at 3 pixels
    points[4, 1] = np.nan  # one coordinate alone is enough to drop a point
    data = pcd_bytes(XYZ_F4, dict(zip("xyz", points.T)), kind, width=5, height=4)
    with caplog.at_level(logging.INFO, logger="sprayplan.io.pcd"):
        got, _ = read_pcd(write(tmp_path, "n.pcd", data))
    keep = np.isfinite(points).all(axis=1)
    np.testing.assert_array_equal(got, as_f32(points[keep]))
    assert any("4 of 20" in r.getMessage() for r in caplog.records)


def test_pcd_nan_normal_of_a_kept_point_is_an_error(tmp_path):
    # issue 13: a normal the file gives is trusted as the surface's direction; one with none is an error
    points = random_points(5, seed=6)
    normals = np.tile([0.0, 0.0, 1.0], (5, 1))
    normals[2] = np.nan
    fields = XYZ_F4 + [("normal_x", "F", 4, 1), ("normal_y", "F", 4, 1), ("normal_z", "F", 4, 1)]
    columns = dict(zip("xyz", points.T)) | dict(zip(["normal_x", "normal_y", "normal_z"], normals.T))
    with pytest.raises(PartFileError, match="point 3 of 5: NaN or infinite normal"):
        read_pcd(write(tmp_path, "nn.pcd", pcd_bytes(fields, columns, "binary")))
    # a NaN point (PCL's "no return") is dropped with its normal, whatever the normal is
    points[2] = np.nan
    columns = dict(zip("xyz", points.T)) | dict(zip(["normal_x", "normal_y", "normal_z"], normals.T))
    got, got_normals = read_pcd(write(tmp_path, "nn2.pcd", pcd_bytes(fields, columns, "binary")))
    assert got.shape == (4, 3) and got_normals.shape == (4, 3)


# --------------------------------------------------------------------------------------------------------
# XYZ


XYZ_POINTS = random_points(12, seed=7)


def _rows(separator: str, points=XYZ_POINTS) -> list[str]:
    return [separator.join(repr(float(v)) for v in row) for row in points]


def _xyz_variants() -> dict[str, bytes]:
    rows = _rows(" ")
    return {
        "spaces": ("\n".join(rows) + "\n").encode(),
        "no_final_newline": "\n".join(rows).encode(),
        "commas": ("\n".join(_rows(",")) + "\n").encode(),
        "comma_space_runs": ("\n".join(_rows(" , ")) + ",\n").encode(),
        "tabs": ("\n".join(_rows("\t")) + "\n").encode(),
        "mixed_runs": ("\n".join("  " + r.replace(" ", " \t,\t ", 1) + "\t" for r in rows) + "\n").encode(),
        "crlf": ("\r\n".join(rows) + "\r\n").encode(),
        "cr_only": ("\r".join(rows) + "\r").encode(),
        "bom_header_csv": ("\ufeffX,Y,Z\r\n" + "\r\n".join(_rows(",")) + "\r\n").encode("utf-8"),
        "comments_blank_lines": (
            "# exported by a scanner\n// units: m\n\n"
            + "\n".join(rows[:5])
            + "\n   # a comment in the middle\n\n"
            + "\n".join(rows[5:])
            + "\n//end\n"
        ).encode(),
        "header_after_comment": ("# c\nx y z\n" + "\n".join(rows) + "\n").encode(),
        "extra_columns_ignored": ("\n".join(r + " 17 0.5" for r in rows) + "\n").encode(),
        "header_reordered": (
            "z y x\n" + "\n".join(" ".join(repr(float(v)) for v in row[::-1]) for row in XYZ_POINTS) + "\n"
        ).encode(),
    }


@pytest.mark.parametrize("variant", sorted(_xyz_variants()))
def test_xyz_variants_parse_to_the_same_array(tmp_path, variant):
    points, normals = read_xyz(write(tmp_path, "p.xyz", _xyz_variants()[variant]))
    np.testing.assert_array_equal(points, XYZ_POINTS)  # repr() round-trips float64 exactly
    assert normals is None
    assert points.dtype == np.float64 and points.flags.c_contiguous


@pytest.mark.parametrize("names", ["x y z nx ny nz", "NX,NY,NZ,X,Y,Z", "normal_x normal_y normal_z x y z i"])
def test_xyz_header_names_select_normals(tmp_path, names):
    rng = np.random.default_rng(8)
    normals = rng.normal(size=(12, 3)) * 3.0  # not unit: taken because the header says so
    order = names.replace(",", " ").lower().split()
    table = {"x": XYZ_POINTS[:, 0], "y": XYZ_POINTS[:, 1], "z": XYZ_POINTS[:, 2], "i": np.arange(12.0)}
    table |= {"nx": normals[:, 0], "ny": normals[:, 1], "nz": normals[:, 2]}
    table |= {"normal_x": normals[:, 0], "normal_y": normals[:, 1], "normal_z": normals[:, 2]}
    separator = "," if "," in names else " "
    rows = [separator.join(repr(float(table[c][i])) for c in order) for i in range(12)]
    points, got = read_xyz(write(tmp_path, "n.xyz", (names + "\n" + "\n".join(rows) + "\n").encode()))
    np.testing.assert_array_equal(points, XYZ_POINTS)
    np.testing.assert_array_equal(got, normals)


def test_xyz_six_columns_without_header(tmp_path):
    rng = np.random.default_rng(9)
    unit = rng.normal(size=(12, 3))
    unit /= np.linalg.norm(unit, axis=1, keepdims=True)
    table = np.hstack([XYZ_POINTS, unit])
    text = "\n".join(" ".join(repr(float(v)) for v in row) for row in table) + "\n"
    points, normals = read_xyz(write(tmp_path, "u.xyz", text.encode()))
    np.testing.assert_array_equal(points, XYZ_POINTS)
    np.testing.assert_array_equal(normals, unit)
    # one normal a little off unit length among unit ones: still normals, as the file gave them
    table[3, 3:6] *= 1.01
    text = "\n".join(" ".join(repr(float(v)) for v in row) for row in table) + "\n"
    points, normals = read_xyz(write(tmp_path, "o.xyz", text.encode()))
    np.testing.assert_array_equal(normals, table[:, 3:6])
    # ... but one of zero length is an error naming its line
    table[3, 3:6] = 0.0
    text = "\n".join(" ".join(repr(float(v)) for v in row) for row in table) + "\n"
    with pytest.raises(PartFileError, match="line 4"):
        read_xyz(write(tmp_path, "z.xyz", text.encode()))
    # colours (or anything mostly not of unit length) in columns 3-5 are ignored
    table[:, 3:6] = rng.integers(0, 256, size=(12, 3))
    text = "\n".join(" ".join(repr(float(v)) for v in row) for row in table) + "\n"
    points, normals = read_xyz(write(tmp_path, "c.xyz", text.encode()))
    np.testing.assert_array_equal(points, XYZ_POINTS)
    assert normals is None


def test_xyz_large_file_with_comment_and_mixed_precision(tmp_path):
    # the vectorised path on a large file must give exactly what a per-line parse gives (speed: bench/)
    points = np.round(random_points(300_000, seed=10), 4)
    data = ("# big\n" + "\n".join(" ".join(f"{v:.4f}" for v in row) for row in points[:10]) + "\n").encode()
    data += b"\n".join(b"%.4f %.4f %.4f" % tuple(row) for row in points[10:].tolist()) + b"\n"
    path = write(tmp_path, "big.xyz", data)
    got, _ = read_xyz(path)
    np.testing.assert_allclose(got, points, rtol=0, atol=1e-9)


# --------------------------------------------------------------------------------------------------------
# bad input: PartFileError naming the file and the problem

_HEADER = (
    "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH {n}\nHEIGHT 1\n"
    "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA {kind}\n"
)


def _pcd(kind: str, body: bytes, n: int = 10, header: str = _HEADER) -> bytes:
    return header.format(n=n, kind=kind).encode() + body


_TEN_POINTS = np.arange(30, dtype="<f4").tobytes()  # 120 bytes: 10 points of x y z float32
_RAW_COMPRESSED = np.arange(30, dtype="<f4").reshape(10, 3).T.tobytes()

BAD_XYZ = {
    "empty": (b"", "empty"),
    "blank": (b" \r\n\t\n", "empty"),
    "only_comments": (b"# a\n// b\n", "no points"),
    "header_only": (b"x y z\n", "no points"),
    "word": (b"1 2 3\n4 five 6\n", "line 2: 'five' is not a number"),
    "word_after_comments_crlf": (b"# c\r\n\r\n1 2 3\r\n1 2 3q\r\n", "line 4"),
    "nan": (b"1 2 3\n4 nan 6\n", "line 2: NaN"),
    "inf": (b"1 2 3\n1 2 3\n4 -inf 6\n", "line 3: an infinite"),
    "overflow": (b"1 2 3\n4 1e999 6\n", "line 2: an infinite"),
    "uneven": (b"1 2 3\n4 5 6\n7 8 9 10\n", "line 3 has 4 values"),
    "two_columns": (b"1 2\n3 4\n", "at least 3"),
    "header_count": (b"x y z\n1 2 3 4\n", "header"),
    "underscore": (b"1 2 3\n1_0 2 3\n", "line 2"),
    "binary_garbage": (b"\x00\x01\x02 \xff\xfe 3\n", "line 1"),
}

BAD_PCD = {
    "empty": (b"", "empty"),
    "not_pcd": (b"1 2 3\n4 5 6\n", "no DATA"),
    "no_fields": (b"VERSION 0.7\nSIZE 4 4 4\nPOINTS 1\nDATA ascii\n1 2 3\n", "no FIELDS"),
    "no_z": (_pcd("ascii", b"1 2\n", 1, _HEADER.replace("x y z", "x y w")), "no z field"),
    "unknown_kind": (_pcd("binary_lz4", _TEN_POINTS), "unknown DATA kind 'binary_lz4'"),
    "data_without_kind": (b"FIELDS x y z\nDATA\n", "unknown DATA kind"),
    "binary_truncated": (_pcd("binary", _TEN_POINTS[:100]), "need 120 bytes, the file has 100"),
    "compressed_no_sizes": (_pcd("binary_compressed", b"\x01\x00"), "truncated"),
    "compressed_truncated": (
        _pcd("binary_compressed", struct.pack("<II", 200, 120) + lzf_literal(_RAW_COMPRESSED)[:50]),
        "expected 200 bytes, the file has 50",
    ),
    "compressed_wrong_size": (
        _pcd("binary_compressed", struct.pack("<II", 124, 100) + lzf_literal(_RAW_COMPRESSED)),
        "corrupt",
    ),
    "compressed_bad_reference": (
        _pcd("binary_compressed", struct.pack("<II", 4, 120) + b"\x00a\x3f\x10"),
        "corrupt",
    ),
    "compressed_short_output": (
        _pcd("binary_compressed", struct.pack("<II", 60, 120) + lzf_literal(_RAW_COMPRESSED[:58])),
        "corrupt",
    ),
    "ascii_word": (_pcd("ascii", b"1 2 3\n4 x 6\n", 2), "line 12: 'x' is not a number"),
    "ascii_columns": (_pcd("ascii", b"1 2 3 4\n5 6 7 8\n", 2), "line 11: 4 values"),
    "ascii_rows": (_pcd("ascii", b"1 2 3\n", 2), "declares 2 points"),
    "ascii_inf": (_pcd("ascii", b"1 2 3\n4 inf 6\n", 2), "line 12: infinite"),
    "binary_inf": (_pcd("binary", np.array([[1, 2, 3], [np.inf, 0, 0]], "<f4").tobytes(), 2), "point 2 of 2"),
    "all_nan": (_pcd("ascii", b"nan nan nan\nnan 1 2\n", 2), "no points"),
    "no_size": (_pcd("binary", _TEN_POINTS, header=_HEADER.replace("SIZE 4 4 4\n", "")), "no SIZE"),
    "bad_type": (_pcd("binary", _TEN_POINTS, header=_HEADER.replace("TYPE F F F", "TYPE F Q F")), "TYPE"),
    "half_float": (_pcd("binary", _TEN_POINTS, header=_HEADER.replace("SIZE 4 4 4", "SIZE 4 2 4")), "SIZE 2"),
    "size_count_mismatch": (
        _pcd("binary", _TEN_POINTS, header=_HEADER.replace("SIZE 4 4 4", "SIZE 4 4")),
        "SIZE has 2 values for 3 fields",
    ),
    "points_word": (
        _pcd("binary", _TEN_POINTS, header=_HEADER.replace("POINTS {n}", "POINTS ten")),
        "POINTS",
    ),
    "zero_points": (_pcd("binary", b"", 0), "no points"),
    "huge_points": (_pcd("binary", _TEN_POINTS, 10**15), "truncated"),
}


@pytest.mark.parametrize("case", sorted(BAD_XYZ))
def test_bad_xyz_raises_part_file_error(tmp_path, case):
    data, words = BAD_XYZ[case]
    path = write(tmp_path, f"bad_{case}.xyz", data)
    with pytest.raises(PartFileError) as info:
        read_xyz(path)
    message = str(info.value)
    assert message.startswith(f"{path}: ") and f"bad_{case}.xyz" in message
    assert words in message
    assert "\n" not in message


@pytest.mark.parametrize("case", sorted(BAD_PCD))
def test_bad_pcd_raises_part_file_error(tmp_path, case):
    data, words = BAD_PCD[case]
    path = write(tmp_path, f"bad_{case}.pcd", data)
    with pytest.raises(PartFileError) as info:
        read_pcd(path)
    message = str(info.value)
    assert message.startswith(f"{path}: ") and f"bad_{case}.pcd" in message
    assert words in message
    assert "\n" not in message


@pytest.mark.parametrize("reader", [read_xyz, read_pcd])
def test_missing_file_and_directory(tmp_path, reader):
    with pytest.raises(PartFileError, match="not found") as info:
        reader(tmp_path / "nothing_here.xyz")
    assert "nothing_here.xyz" in str(info.value)
    with pytest.raises(PartFileError, match="directory"):
        reader(tmp_path)


# --------------------------------------------------------------------------------------------------------
# fuzz: an array of finite points, or a PartFileError; nothing else, and no hang


@pytest.fixture(scope="module")
def fuzz_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("fuzz")


def check_contract(reader, path) -> None:
    try:
        points, normals = reader(path)
    except PartFileError as error:
        assert str(error).startswith(f"{path}: ") and "\n" not in str(error)
        return
    assert isinstance(points, np.ndarray) and points.dtype == np.float64
    assert points.ndim == 2 and points.shape[1] == 3 and points.shape[0] >= 1
    assert np.isfinite(points).all()
    if normals is not None:
        assert normals.shape == points.shape and normals.dtype == np.float64
        assert np.isfinite(normals).all()


def _valid_samples() -> list[tuple[str, bytes]]:
    points = random_points(6, seed=11)
    unit = np.tile([0.0, 0.6, 0.8], (6, 1))
    fields = XYZ_F4 + [("normal_x", "F", 4, 1), ("normal_y", "F", 4, 1), ("normal_z", "F", 4, 1)]
    columns = dict(zip("xyz", points.T)) | dict(zip(["normal_x", "normal_y", "normal_z"], unit.T))
    samples = [(".pcd", pcd_bytes(fields, columns, kind)) for kind in ("ascii", "binary")]
    samples.append((".pcd", pcd_bytes(fields, columns, "binary_compressed", encoder=lzf_greedy)))
    rows = b"\r\n".join(b"1.5,-2,3e1,0,0.6,0.8" for _ in range(6))
    samples.append((".xyz", b"# c\r\nx,y,z,nx,ny,nz\r\n" + rows))
    samples.append((".xyz", b"\xef\xbb\xbf1 2 3\n4\t5\t6\n// end\n"))
    return samples


SAMPLES = _valid_samples()


def test_fuzz_seeds_are_valid(fuzz_dir):
    for index, (suffix, data) in enumerate(SAMPLES):
        path = fuzz_dir / f"seed{index}{suffix}"
        path.write_bytes(data)
        points, _ = (read_pcd if suffix == ".pcd" else read_xyz)(path)
        assert len(points) >= 2


@given(st.binary(max_size=3000))
@FUZZ
def test_fuzz_random_bytes(fuzz_dir, data):
    path = fuzz_dir / "random.bin"
    path.write_bytes(data)
    check_contract(read_xyz, path)
    check_contract(read_pcd, path)


_TOKENS = ["1", "-2.5", "3e2", "nan", "inf", "x", "y", "z", "nx", "#", "//", "DATA", "ascii", "FIELDS"]
_SEPARATOR_TOKENS = [" ", ",", "\t", "\n", "\r\n", "\ufeff", ".", "_", "1e999"]


@given(
    st.one_of(
        st.text(max_size=400),
        st.lists(st.sampled_from(_TOKENS) | st.sampled_from(_SEPARATOR_TOKENS), max_size=80).map("".join),
    )
)
@FUZZ
def test_fuzz_random_text(fuzz_dir, text):
    path = fuzz_dir / "random.txt"
    path.write_bytes(text.encode("utf-8", "surrogatepass"))
    check_contract(read_xyz, path)
    check_contract(read_pcd, path)


@given(st.data())
@FUZZ
def test_fuzz_mutated_valid_files(fuzz_dir, data):
    suffix, original = data.draw(st.sampled_from(SAMPLES))
    mutated = bytearray(original)
    if data.draw(st.booleans()):
        mutated = mutated[: data.draw(st.integers(0, len(original)))]
    position = st.integers(0, max(len(mutated) - 1, 0))
    flips = data.draw(st.lists(st.tuples(position, st.integers(0, 255)), max_size=6))
    for position, value in flips:
        if position < len(mutated):
            mutated[position] = value
    path = fuzz_dir / f"mutated{suffix}"
    path.write_bytes(bytes(mutated))
    check_contract(read_pcd if suffix == ".pcd" else read_xyz, path)
