"""CSV files of joint vectors and poses read by ``sprayplan fk`` and ``sprayplan ik`` (written by ``export.tables``).

Joints: a header ``q1,q2,...`` (rad), one row per joint vector. Poses: a header ``x,y,z,rx,ry,rz`` (mm, and a
rotation vector in rad as a UR pendant shows it) or, with ``matrix``, ``x,y,z,r11,r12,r13,r21,r22,r23,r31,r32,
r33``; one row per pose.
"""

from __future__ import annotations

import os

import numpy as np
from scipy.spatial.transform import Rotation

from sprayplan.errors import PartFileError
from sprayplan.io.cloud import read_file_bytes

POSE_COLUMNS = {
    "rotvec": ["x", "y", "z", "rx", "ry", "rz"],
    "matrix": ["x", "y", "z", "r11", "r12", "r13", "r21", "r22", "r23", "r31", "r32", "r33"],
}

#: A pose's 3x3 part is a rotation when ``|R^T R - I|`` is at most this in every entry (a CSV's 6 decimals
#: give about 1e-6) and its determinant is positive: a reflection (determinant -1) is no pose a robot can take.
ROTATION_TOLERANCE = 1e-4


def read_table(path: str | os.PathLike, columns: list[str]) -> np.ndarray:
    """Read the named columns of a CSV file with a header line, as floats."""
    return _read_table(path, columns)[0]


def _read_table(path: str | os.PathLike, columns: list[str]) -> tuple[np.ndarray, list[int]]:
    """The named columns of a CSV file with a header line, as floats, and each row's line number.

    Raises
    ------
    PartFileError
        Missing file, missing columns, a value that is not a finite number (with its line).
    """
    name = os.fspath(path)
    data = read_file_bytes(name)  # a folder or a named pipe is refused before it is opened
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise PartFileError(name, f"cannot read ({exc})") from None
    lines = [line.strip() for line in text.split("\n")]
    lines = [(i + 1, line) for i, line in enumerate(lines) if line and not line.startswith("#")]
    if not lines:
        raise PartFileError(name, "file is empty")
    header = [h.strip().lower() for h in lines[0][1].split(",")]
    missing = [c for c in columns if c not in header]
    if missing:
        raise PartFileError(name, f"header has no column {', '.join(missing)} (expected {','.join(columns)})")
    index = [header.index(c) for c in columns]
    rows = []
    numbers = []
    for number, line in lines[1:]:
        cells = [c.strip() for c in line.split(",")]
        if len(cells) != len(header):
            raise PartFileError(name, f"line {number} has {len(cells)} values, the header has {len(header)}")
        try:
            values = [float(cells[i]) if "_" not in cells[i] else float("x") for i in index]  # no 1_000
        except ValueError:
            raise PartFileError(name, f"line {number}: a value is not a number") from None
        if not np.isfinite(values).all():
            raise PartFileError(name, f"line {number}: NaN or infinite value")
        rows.append(values)
        numbers.append(number)
    if not rows:
        raise PartFileError(name, "no data rows after the header")
    return np.array(rows), numbers


def read_joints(path, dof: int) -> np.ndarray:
    """(n, dof) joint vectors, rad."""
    return read_table(path, [f"q{i + 1}" for i in range(dof)])


def read_poses(path, pose_format: str = "rotvec") -> np.ndarray:
    """(n, 4, 4) poses, mm.

    With ``matrix``, each row's 3x3 part must be a rotation: orthonormal within ``ROTATION_TOLERANCE`` and of
    determinant +1 (a reflection, determinant -1, is refused); it is then made exactly orthonormal.

    Raises
    ------
    PartFileError
        Those of :func:`read_table`, and a matrix that is not a rotation (naming the line and the pose).
    """
    name = os.fspath(path)
    table, numbers = _read_table(path, POSE_COLUMNS[pose_format])
    out = np.zeros((len(table), 4, 4))
    out[:, :3, 3] = table[:, :3]
    out[:, 3, 3] = 1.0
    if pose_format == "rotvec":
        out[:, :3, :3] = Rotation.from_rotvec(table[:, 3:6]).as_matrix()
        return out
    matrices = table[:, 3:].reshape(-1, 3, 3)
    with np.errstate(over="ignore", invalid="ignore"):
        gram = np.einsum("nki,nkj->nij", matrices, matrices) - np.eye(3)
        error = np.abs(gram).max(axis=(1, 2))
        det = np.linalg.det(matrices)
    not_orthonormal = ~(error <= ROTATION_TOLERANCE)
    reflection = ~not_orthonormal & (det < 0)
    for bad, what in (
        (not_orthonormal, f"is not orthonormal (|R^T R - I| up to {{:.3g}}, tolerance {ROTATION_TOLERANCE:g})"),
        (reflection, "has determinant {:.3g}: a reflection, not a rotation"),
    ):
        if bad.any():
            row = int(np.argmax(bad))
            value = error[row] if bad is not_orthonormal else det[row]
            raise PartFileError(
                name, f"line {numbers[row]} (pose {row + 1}): the rotation matrix " + what.format(value)
            )
    u, _, vt = np.linalg.svd(matrices)
    out[:, :3, :3] = u @ vt
    return out
