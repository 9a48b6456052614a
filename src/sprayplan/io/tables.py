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

POSE_COLUMNS = {
    "rotvec": ["x", "y", "z", "rx", "ry", "rz"],
    "matrix": ["x", "y", "z", "r11", "r12", "r13", "r21", "r22", "r23", "r31", "r32", "r33"],
}


def read_table(path: str | os.PathLike, columns: list[str]) -> np.ndarray:
    """Read the named columns of a CSV file with a header line, as floats.

    Raises
    ------
    PartFileError
        Missing file, missing columns, a value that is not a finite number (with its line).
    """
    name = os.fspath(path)
    try:
        with open(path, encoding="utf-8-sig") as handle:
            lines = [line.strip() for line in handle]
    except FileNotFoundError:
        raise PartFileError(name, "no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise PartFileError(name, f"cannot read ({exc})") from None
    lines = [(i + 1, line) for i, line in enumerate(lines) if line and not line.startswith("#")]
    if not lines:
        raise PartFileError(name, "file is empty")
    header = [h.strip().lower() for h in lines[0][1].split(",")]
    missing = [c for c in columns if c not in header]
    if missing:
        raise PartFileError(name, f"header has no column {', '.join(missing)} (expected {','.join(columns)})")
    index = [header.index(c) for c in columns]
    rows = []
    for number, line in lines[1:]:
        cells = [c.strip() for c in line.split(",")]
        if len(cells) != len(header):
            raise PartFileError(name, f"line {number} has {len(cells)} values, the header has {len(header)}")
        try:
            values = [float(cells[i]) for i in index]
        except ValueError:
            raise PartFileError(name, f"line {number}: a value is not a number") from None
        if not np.isfinite(values).all():
            raise PartFileError(name, f"line {number}: NaN or infinite value")
        rows.append(values)
    if not rows:
        raise PartFileError(name, "no data rows after the header")
    return np.array(rows)


def read_joints(path, dof: int) -> np.ndarray:
    """(n, dof) joint vectors, rad."""
    return read_table(path, [f"q{i + 1}" for i in range(dof)])


def read_poses(path, pose_format: str = "rotvec") -> np.ndarray:
    """(n, 4, 4) poses, mm."""
    table = read_table(path, POSE_COLUMNS[pose_format])
    out = np.zeros((len(table), 4, 4))
    out[:, :3, 3] = table[:, :3]
    out[:, 3, 3] = 1.0
    if pose_format == "rotvec":
        out[:, :3, :3] = Rotation.from_rotvec(table[:, 3:6]).as_matrix()
    else:
        matrices = table[:, 3:].reshape(-1, 3, 3)
        u, _, vt = np.linalg.svd(matrices)
        error = np.abs(matrices - u @ vt).max(axis=(1, 2))
        bad = np.flatnonzero(error > 1e-4)
        if len(bad):
            raise PartFileError(os.fspath(path), f"pose {bad[0] + 1}: the 3x3 part is not a rotation matrix")
        out[:, :3, :3] = u @ vt
    return out
