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
    return poses_at(points + standoff_mm * unit(np.asarray(normals, dtype=float)), normals)


def poses_at(tcp: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """(n, 4, 4) gun poses ``tool2part`` with the origin at given gun tip positions and z along -normal, turned
    about z as seed 000's eq. 5 (Rodrigues from (0, 0, 1)).

    Parameters
    ----------
    tcp : (n, 3) float, mm
        Gun tip positions.
    normals : (n, 3) float
        Outward unit normals of the surface the gun points at.
    """
    tcp = np.asarray(tcp, dtype=float)
    out = np.zeros((len(tcp), 4, 4))
    out[:, :3, :3] = rotation_from_z(-np.asarray(normals, dtype=float))
    out[:, :3, 3] = tcp
    out[:, 3, 3] = 1.0
    return out


def stroke_poses(stroke) -> np.ndarray:
    """(n, 4, 4) gun poses along a stroke (``tool2part``): origin at its gun tip positions, z along -normal.

    The roll about the gun's own axis does not change the spray, so it is not tied to the direction of travel:
    a stroke run backwards keeps its poses, and the flange (offset sideways from the gun axis by T_tool)
    stays where the station assignment put it.
    """
    return poses_at(stroke.tcp, stroke.normals)


def stroke_frames(points: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Gun orientations along a stroke: z along ``-normal``, x along the direction of travel.

    Parameters
    ----------
    points : (n, 3) float, mm
        Waypoints in travel order (n >= 2).
    normals : (n, 3) float
        Unit outward normals.

    Returns
    -------
    (n, 3, 3) float
        Rotation matrices (columns x, y, z of the tool frame in the part frame), proper and orthonormal. The
        travel direction at a waypoint is the central difference of its neighbours, projected onto the plane
        normal to the gun axis; where it vanishes (the gun moves along its own axis) the previous waypoint's x
        axis is kept.
    """
    points = np.asarray(points, dtype=float)
    z = -unit(np.asarray(normals, dtype=float))
    travel = np.gradient(points, axis=0) if len(points) >= 2 else np.zeros_like(points)
    x = travel - np.einsum("ij,ij->i", travel, z)[:, None] * z
    length = np.linalg.norm(x, axis=1)
    good = length > 1e-9
    if not good.any():
        x = np.cross(z, np.where(np.abs(z[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]]))
    else:
        index = np.maximum.accumulate(np.where(good, np.arange(len(x)), 0))
        first = int(np.argmax(good))
        index[:first] = first
        x = x[index]
        x = x - np.einsum("ij,ij->i", x, z)[:, None] * z
    x = unit(x)
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=2)


def rpy_from_matrix(rotation: np.ndarray) -> np.ndarray:
    """Roll-pitch-yaw angles of seed 001's eq. 9, ``R = Rot(x, psi_x) Rot(y, psi_y) Rot(z, psi_z)``.

    Parameters
    ----------
    rotation : (n, 3, 3) float

    Returns
    -------
    (n, 3) float, rad
        ``(psi_x, psi_y, psi_z)``; at ``psi_y = +-pi/2`` (gimbal lock) ``psi_z`` is set to 0.
    """
    r = np.asarray(rotation, dtype=float).reshape(-1, 3, 3)
    # R = Rx Ry Rz: r02 = sin(psi_y), r12 = -sin(psi_x) cos(psi_y), r22 = cos(psi_x) cos(psi_y),
    # r01 = -cos(psi_y) sin(psi_z), r00 = cos(psi_y) cos(psi_z)
    psi_y = np.arcsin(np.clip(r[:, 0, 2], -1.0, 1.0))
    locked = np.abs(r[:, 0, 2]) > 1.0 - 1e-12
    psi_x = np.where(locked, np.arctan2(r[:, 2, 1], r[:, 1, 1]), np.arctan2(-r[:, 1, 2], r[:, 2, 2]))
    psi_z = np.where(locked, 0.0, np.arctan2(-r[:, 0, 1], r[:, 0, 0]))
    return np.stack([psi_x, psi_y, psi_z], axis=1)


def matrix_from_rpy(angles: np.ndarray) -> np.ndarray:
    """Inverse of :func:`rpy_from_matrix`: ``Rot(x, psi_x) Rot(y, psi_y) Rot(z, psi_z)`` for (n, 3) angles."""
    a = np.asarray(angles, dtype=float).reshape(-1, 3)
    cx, sx = np.cos(a[:, 0]), np.sin(a[:, 0])
    cy, sy = np.cos(a[:, 1]), np.sin(a[:, 1])
    cz, sz = np.cos(a[:, 2]), np.sin(a[:, 2])
    one, zero = np.ones(len(a)), np.zeros(len(a))
    rx = np.stack([one, zero, zero, zero, cx, -sx, zero, sx, cx], 1).reshape(-1, 3, 3)
    ry = np.stack([cy, zero, sy, zero, one, zero, -sy, zero, cy], 1).reshape(-1, 3, 3)
    rz = np.stack([cz, -sz, zero, sz, cz, zero, zero, zero, one], 1).reshape(-1, 3, 3)
    return rx @ ry @ rz
