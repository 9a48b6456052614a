"""Tool poses at target points (seed 000, section 2.4, eq. 5: Rodrigues' rotation formula).

Convention: the gun's z axis points from the gun to the surface, i.e. along the negative outward normal, and
the gun tip stands at ``point + standoff_mm * normal``.
"""

from __future__ import annotations

import numpy as np

from sprayplan.surface.normals import unit

Z = np.array([0.0, 0.0, 1.0])


def rotation_from_z(axes: np.ndarray) -> np.ndarray:
    """Rotations that turn n0 = (0, 0, 1) onto each given axis (seed 000, eq. 5).

    Eq. 5 is Rodrigues' formula ``R = E cos(theta) + (1 - cos(theta)) r r^T + sin(theta) [r]_x`` with ``r`` the
    unit vector along ``n0 x n`` and ``theta`` the angle between n0 and n. (The printed ``r^T x r`` is the outer
    product r r^T, and r must be normalised for the formula to give a rotation; with r = n0 x n unnormalised
    the seed's "vector product" would scale the terms by sin(theta).) The parallel case gives the identity and
    the anti-parallel case, where the axis is undefined, a half turn about x.

    Parameters
    ----------
    axes : (n, 3) float
        Target directions (normalised here).

    Returns
    -------
    (n, 3, 3) float
        Proper rotations (det +1) with ``R @ n0 = axis``.
    """
    a = unit(np.atleast_2d(np.asarray(axes, dtype=float)))
    cross = np.cross(Z, a)
    sin = np.linalg.norm(cross, axis=1)
    cos = a[:, 2]
    r = np.divide(cross, sin[:, None], out=np.zeros_like(cross), where=sin[:, None] > 1e-12)
    skew = np.zeros((len(a), 3, 3))
    skew[:, 0, 1], skew[:, 0, 2], skew[:, 1, 2] = -r[:, 2], r[:, 1], -r[:, 0]
    skew[:, 1, 0], skew[:, 2, 0], skew[:, 2, 1] = r[:, 2], -r[:, 1], r[:, 0]
    rot = (
        np.eye(3)[None] * cos[:, None, None]
        + (1.0 - cos)[:, None, None] * np.einsum("ni,nj->nij", r, r)
        + sin[:, None, None] * skew
    )
    degenerate = sin <= 1e-12
    rot[degenerate & (cos > 0)] = np.eye(3)
    rot[degenerate & (cos < 0)] = np.diag([1.0, -1.0, -1.0])  # half turn about x
    return rot


def tool_poses(points: np.ndarray, normals: np.ndarray, standoff_mm: float) -> np.ndarray:
    """Gun poses in the part frame, ``tool2part`` (4x4): z axis along -normal, origin at the gun tip.

    Parameters
    ----------
    points : (n, 3) float, mm
        Target points on the surface.
    normals : (n, 3) float
        Outward unit normals.
    standoff_mm : float
        Distance from the gun tip to the surface along the normal.

    Returns
    -------
    (n, 4, 4) float
        Homogeneous transforms from the tool frame to the part frame.
    """
    points = np.asarray(points, dtype=float)
    out = np.zeros((len(points), 4, 4))
    out[:, :3, :3] = rotation_from_z(-np.asarray(normals, dtype=float))
    out[:, :3, 3] = points + standoff_mm * unit(np.asarray(normals, dtype=float))
    out[:, 3, 3] = 1.0
    return out
