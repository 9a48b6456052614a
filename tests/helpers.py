"""Independent geometric checks shared by the tests (not part of the package)."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from sprayplan.surface.normals import outward_face_normals
from sprayplan.types import Part


def barycentric_inside(points, triangles, tol=1e-9):
    """True where each point lies in its triangle's plane and inside it."""
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    n = np.cross(b - a, c - a)
    area2 = np.linalg.norm(n, axis=1)
    off_plane = np.abs(np.einsum("ij,ij->i", points - a, n)) / area2
    w_a = np.einsum("ij,ij->i", np.cross(c - b, points - b), n) / area2**2
    w_b = np.einsum("ij,ij->i", np.cross(a - c, points - c), n) / area2**2
    w_c = 1 - w_a - w_b
    scale = np.ptp(triangles.reshape(-1, 3), axis=0).max()
    return (off_plane <= tol * scale) & (w_a >= -tol) & (w_b >= -tol) & (w_c >= -tol)


def on_mesh(points, vertices, faces, tol=1e-9):
    """(n,) bool: which points lie on some triangle of the mesh (every face is tried)."""
    return containing_face(points, vertices, faces, tol) >= 0


def containing_face(points, vertices, faces, tol=1e-9):
    """(n,) int: a face each point lies on, -1 where none does.

    Every face whose centroid lies within the largest centroid-to-corner distance of a point is tried, so no
    containing face can be missed.
    """
    points = np.asarray(points, dtype=float)
    tri = vertices[faces]
    centre = tri.mean(axis=1)
    reach = np.linalg.norm(tri - centre[:, None, :], axis=2).max() * (1 + 1e-9) + tol
    lists = cKDTree(centre).query_ball_point(points, reach)
    counts = np.array([len(c) for c in lists])
    rows = np.repeat(np.arange(len(points)), counts)
    cols = np.concatenate([np.asarray(c, dtype=int) for c in lists]) if len(rows) else np.zeros(0, int)
    found = np.full(len(points), -1)
    if len(rows):
        inside = barycentric_inside(points[rows], tri[cols], tol)
        found[rows[inside]] = cols[inside]
    return found


def plate(xmin, xmax, ymin, ymax, step, z=0.0, flip=False) -> Part:
    """A flat rectangular grid mesh at height z, normals +z (or -z with ``flip``)."""
    xs = np.arange(xmin, xmax + step / 2, step)
    ys = np.arange(ymin, ymax + step / 2, step)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    vertices = np.stack([gx.ravel(), gy.ravel(), np.full(gx.size, float(z))], axis=1)
    nx, ny = len(xs), len(ys)
    i, j = np.meshgrid(np.arange(nx - 1), np.arange(ny - 1), indexing="ij")
    a = (i * ny + j).ravel()
    b, c, d = a + ny, a + ny + 1, a + 1
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return Part(vertices, faces[:, ::-1] if flip else faces, None, "plate")


def planned(part, job):
    """The plan of a part as the main job makes it before refinement (``run_job(..., until="kinematics")``),
    with the job's own spacing and gun speed: a film target, if the job has one, is not met first."""
    from sprayplan.job import run_job

    return run_job(part, job.replace(coating={"thickness_um": None}), until="kinematics").plan


def grid_box(n: int = 6, size=(400.0, 200.0, 100.0)) -> Part:
    """A closed box of ``n x n`` squares (two triangles each) a side, outward winding, centred on the origin."""
    vertices, faces = [], []
    half = np.asarray(size) / 2.0
    for axis in range(3):
        for sign in (1.0, -1.0):
            u, v = [a for a in range(3) if a != axis]
            base = len(vertices)
            for i in range(n + 1):
                for j in range(n + 1):
                    p = np.zeros(3)
                    p[axis] = sign * half[axis]
                    p[u] = -half[u] + 2 * half[u] * i / n
                    p[v] = -half[v] + 2 * half[v] * j / n
                    vertices.append(p)
            for i in range(n):
                for j in range(n):
                    a = base + i * (n + 1) + j
                    b, c, d = a + n + 1, a + n + 2, a + 1
                    faces += [[a, b, c], [a, c, d]]
    part = Part(np.array(vertices), np.array(faces), name="box")
    # duplicate corner vertices merged so that the sides share edges
    key = np.round(part.vertices, 6)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    fixed, _ = outward_face_normals(part.vertices[first], inverse.reshape(-1)[part.faces])
    return Part(part.vertices[first], fixed, name="box")


def spray_stretches(plan, job, min_waypoints=2, count=None):
    """The stretches of spray strokes the timing stage times (``timing.stage._spray_runs``: reachable, no joint
    jump) of at least ``min_waypoints`` waypoints, in plan order, each as (joints (n, 9), planned tip speeds
    (n - 1,)); the first ``count`` of them, or all."""
    import math

    from sprayplan.timing.stage import _spray_runs

    out = [
        (st.q9[idx[run]], cap[run[:-1]])
        for st, idx, cap, run in _spray_runs(plan, job.motion, math.radians(job.timing.joint_jump_deg))
        if len(run) >= min_waypoints
    ]
    return out if count is None else out[:count]


#: The gun on every surface normal (``[paths] gun_smooth_mm = 0``): the reach part's and the tray's plans with
#: unreachable spray waypoints, a station added for touch-ups and a program that leaves nothing out were built
#: with it; with the gun's axis smoothed (the default) the arm reaches all of the reach part, and the tests of
#: what is done with unreachable waypoints would have none to look at.
BARE_NORMALS = {"gun_smooth_mm": 0.0}
BARE_NORMALS_TOML = "[paths]\ngun_smooth_mm = 0.0\n"


def reach_part_timing(testdata):
    """The reach part (x > -250) planned to the kinematics stage: its gantry, timing limits and every stretch
    the timing times (:func:`spray_stretches`)."""
    from sprayplan.config import JobConfig
    from sprayplan.job import run_job
    from sprayplan.timing.stage import plan_limits

    job = JobConfig().replace(load={"units": "m", "region": "x > -250"}, output={"viewer": False, "report": False})
    state = run_job(testdata / "meshes" / "reach_curved_part.ply", job, until="kinematics")
    gantry = state.gantry()
    stretches = spray_stretches(state.plan, job)
    assert len(stretches) >= 10
    return gantry, plan_limits(gantry, job), stretches
