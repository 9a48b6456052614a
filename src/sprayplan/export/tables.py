"""CSV tables for people and pendants: poses and joints (``sprayplan fk`` / ``ik``), seed 001's Cartesian table of
a ruled-surface job (``sprayplan paths --ruled --table``). The readers of the joint and pose tables are in
``io.tables``.
"""

from __future__ import annotations

import os

import numpy as np
from scipy.spatial.transform import Rotation

from sprayplan.export.files import atomic_output
from sprayplan.types import Paths


def pose_rows(poses: np.ndarray, pose_format: str = "rotvec") -> np.ndarray:
    """(n, 6) or (n, 12) rows for writing poses."""
    position = poses[:, :3, 3]
    if pose_format == "rotvec":
        return np.hstack([position, Rotation.from_matrix(poses[:, :3, :3]).as_rotvec()])
    return np.hstack([position, poses[:, :3, :3].reshape(-1, 9)])


def write_table(path, header: list[str], rows: list[list]) -> None:
    """Write a CSV atomically; ``None`` cells are left empty, floats at full useful precision."""

    def cell(value):
        if value is None:
            return ""
        if isinstance(value, (float, np.floating)):
            return f"{float(value):.10g}"
        return str(value)

    with atomic_output(path, "w", newline="") as handle:
        handle.write(",".join(header) + "\n")
        for row in rows:
            handle.write(",".join(cell(v) for v in row) + "\n")


def write_table_csv(path: str | os.PathLike, paths: Paths) -> None:
    """Write :func:`cartesian_table` as CSV with the header ``n,x,y,z``, rows numbered from 1 (mm)."""
    from sprayplan.paths.ruled import cartesian_table

    table = cartesian_table(paths)
    with atomic_output(path, "w", newline="") as handle:
        handle.write("n,x,y,z\n")
        for n, row in enumerate(table, start=1):
            handle.write(f"{n}," + ",".join(np.format_float_positional(x, precision=6, trim="-") for x in row) + "\n")
