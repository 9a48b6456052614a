"""The numpy forms of the film's hot loops, as they were before the compiled kernels (``coating.kernels``)
replaced them: the reference the kernels are checked against (tests/test_speed_kernels.py).

``occlusion_reference`` is ``coating.occlusion.compute_occlusion``'s raster method with every (view,
triangle) pair and every covered pixel as arrays; ``pairs_reference`` is each (sample, gun sample) pair's film
from a k-d tree ball query; ``deposit_reference`` the deposit matrix from those pairs, four COO entries a pair.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import sparse
from scipy.spatial import cKDTree

from sprayplan.coating.occlusion import Occlusion, _frames, _frustum_pairs, _project, _view_sample_pairs
from sprayplan.coating.thickness import _setup


def occlusion_reference(samples, vertices, faces, views, pattern_standoff_mm, half_width_mm, pixels=16, batch=256):
    """Hidden (view, sample) pairs of the raster method, in numpy."""
    n = len(samples.points)
    nv = len(views.position)
    if len(faces) == 0 or nv == 0:
        return Occlusion(views.of_gun, np.zeros(0, np.int64), np.zeros(nv, bool), n)
    tree = cKDTree(samples.points)
    tri = vertices[faces]
    origin = samples.points.mean(axis=0)
    frames = _frames(views, origin)
    sample_cols = (samples.points - origin).T.astype(np.float32)
    centres = tri.mean(axis=1)
    radius = float(np.linalg.norm(tri - centres[:, None, :], axis=2).max())
    corner_cols = (vertices - origin).T.astype(np.float32)
    centre_tree = cKDTree(centres)
    grid = (float(pattern_standoff_mm), float(half_width_mm), int(pixels))
    hidden = []
    for start in range(0, nv, batch):
        sl = slice(start, min(start + batch, nv))
        pv, pt, _ = _frustum_pairs(centres, centre_tree, radius, views, sl, pattern_standoff_mm)
        view_idx, sample_idx = _view_sample_pairs(views, sl, tree)
        zbuf = np.full((sl.stop - sl.start) * pixels * pixels, np.inf)
        _rasterise(corner_cols, faces, frames, pv, pt, sl.start, grid, zbuf)
        hid = _hidden_by_depth(zbuf, sample_cols, samples.normals, frames, sl.start, view_idx, sample_idx, grid)
        hidden.append(view_idx[hid].astype(np.int64) * n + sample_idx[hid])
    keys = np.sort(np.concatenate(hidden))
    has = np.zeros(nv, bool)
    has[np.unique(keys // max(n, 1))] = True
    return Occlusion(views.of_gun, keys, has, n, "raster")


def _rasterise(cols, faces, frames, pv, pt, first_view: int, grid, zbuf) -> None:
    """Rasterise (view, triangle) pairs into ``zbuf`` (pixel centres, perspective-correct 1/z)."""
    h, half, m = grid
    zs, xs, ys = [], [], []
    for c in range(3):
        z, x, y = _project(cols, faces[pt, c], frames, pv, h)
        zs.append(z)
        xs.append((x + half) * (m / (2.0 * half)))
        ys.append((y + half) * (m / (2.0 * half)))
    z, x, y = np.stack(zs, 1), np.stack(xs, 1), np.stack(ys, 1)
    ok = (z > 1.0).all(axis=1)
    x0 = np.clip(np.ceil(x.min(axis=1) - 0.5), 0, m).astype(np.int64)
    x1 = np.clip(np.floor(x.max(axis=1) - 0.5), -1, m - 1).astype(np.int64)
    y0 = np.clip(np.ceil(y.min(axis=1) - 0.5), 0, m).astype(np.int64)
    y1 = np.clip(np.floor(y.max(axis=1) - 0.5), -1, m - 1).astype(np.int64)
    nx, ny = x1 - x0 + 1, y1 - y0 + 1
    count = np.where(ok & (nx > 0) & (ny > 0), nx * ny, 0)
    total = int(count.sum())
    if total == 0:
        return
    owner = np.repeat(np.arange(len(pv)), count)
    offset = np.arange(total) - np.repeat(np.cumsum(count) - count, count)
    px = x0[owner] + offset % nx[owner]
    py = y0[owner] + offset // nx[owner]
    cx, cy = px + 0.5, py + 0.5
    ax, ay = x[owner, 0], y[owner, 0]
    bx, by = x[owner, 1], y[owner, 1]
    qx, qy = x[owner, 2], y[owner, 2]
    area = (bx - ax) * (qy - ay) - (by - ay) * (qx - ax)
    area = np.where(np.abs(area) > 1e-12, area, 1e-12)
    w1 = ((cx - ax) * (qy - ay) - (cy - ay) * (qx - ax)) / area
    w2 = ((bx - ax) * (cy - ay) - (by - ay) * (cx - ax)) / area
    w0 = 1.0 - w1 - w2
    eps = -1e-7
    inside = (w0 >= eps) & (w1 >= eps) & (w2 >= eps)
    inv_z = w0 / z[owner, 0] + w1 / z[owner, 1] + w2 / z[owner, 2]
    depth = 1.0 / np.maximum(inv_z, 1e-12)
    index = (pv[owner] - first_view) * (m * m) + py * m + px
    np.minimum.at(zbuf, index[inside], depth[inside])


def _hidden_by_depth(zbuf, cols, normals, frames, first_view, view_idx, sample_idx, grid) -> np.ndarray:
    """(p,) bool: pairs whose sample lies behind the depth map by more than the bias."""
    h, half, m = grid
    z, x, y = _project(cols, sample_idx, frames, view_idx, h)
    px = np.floor((x + half) * (m / (2.0 * half))).astype(np.int64)
    py = np.floor((y + half) * (m / (2.0 * half))).astype(np.int64)
    inside = (px >= 0) & (px < m) & (py >= 0) & (py < m) & (z > 1.0)
    index = (view_idx - first_view) * (m * m) + np.clip(py, 0, m - 1) * m + np.clip(px, 0, m - 1)
    front = zbuf[index]
    to_gun = np.take(frames[12:15], view_idx, axis=1) - np.take(cols, sample_idx, axis=1)
    dist = np.sqrt((to_gun * to_gun).sum(axis=0))
    cos_a = (to_gun * np.take(normals.T, sample_idx, axis=1)).sum(axis=0) / np.maximum(dist, 1e-6)
    cos_a = np.clip(cos_a, 0.05, 1.0)
    tan_a = np.sqrt(1.0 - cos_a**2) / cos_a
    pixel_on_surface = (2.0 * half / m) * z / h * math.sqrt(2.0)
    bias = 1.0 + pixel_on_surface * tan_a
    return inside & (z > front + bias)


def pairs_reference(setup, tree, vt, gt, sl: slice):
    """(sample, gun, film in mm) of every (sample, gun sample) pair within reach, gun samples ``sl``.

    Pairs come from a k-d tree ball query (``sparse_distance_matrix``, all in C); the formula of the module
    docstring is evaluated in float32 on coordinates relative to the samples' centroid (``vt``: samples'
    coordinates and normals; ``gt``: gun samples' tip, Q dt, axis and pattern axes), and returned in float64.
    """
    guns, pattern, reach = setup.guns, setup.pattern, setup.reach
    found = cKDTree(guns.aim[sl]).sparse_distance_matrix(tree, float(reach[sl].max()), output_type="ndarray")
    gun = found["i"].astype(np.int64) + sl.start
    sample = found["j"].astype(np.int64)
    keep = found["v"] <= reach[gun]
    gun, sample = gun[keep], sample[keep]
    px, py, pz, nx, ny, nz = np.take(vt, sample, axis=1)
    g = np.take(gt, gun, axis=1)
    vx, vy, vz = px - g[0], py - g[1], pz - g[2]  # gun tip -> sample
    z = vx * g[4] + vy * g[5] + vz * g[6]
    zs = np.where(z > 1e-6, z, np.float32(1.0))
    scale = np.float32(pattern.standoff_mm) / zs
    cos_term = -(vx * nx + vy * ny + vz * nz)
    if pattern.kind != "double_beta":  # a round pattern's density depends on r^2 = (|v|^2 - z^2) (h / z)^2 only
        r2 = (vx * vx + vy * vy + vz * vz - z * z) * (scale * scale)
        flux = pattern.radial_density(r2)
    else:
        x = (vx * g[7] + vy * g[8] + vz * g[9]) * scale
        y = (vx * g[10] + vy * g[11] + vz * g[12]) * scale
        flux = pattern.density(x, y)
    value = flux.astype(np.float32) * (scale * scale) * cos_term / zs * g[3]
    ok = (z > 1e-6) & (cos_term > 0) & setup.occlusion.visible(sample, gun)
    return sample, gun, np.where(ok, value, np.float32(0.0)).astype(np.float64)


def pair_rows_reference(setup):
    """The float32 rows ``pairs_reference`` reads (a column a sample)."""
    guns, samples = setup.guns, setup.samples
    origin = samples.points.mean(axis=0)
    vt = np.vstack([(samples.points - origin).T, samples.normals.T]).astype(np.float32)
    pos = guns.position - origin
    rows = [pos[:, 0], pos[:, 1], pos[:, 2], guns.volume_rate_mm3_s * guns.dt_s]
    rows += [guns.axis[:, 0], guns.axis[:, 1], guns.axis[:, 2]]
    if setup.pattern.kind == "double_beta":
        across = np.cross(guns.axis, guns.along)
        rows += [guns.along[:, 0], guns.along[:, 1], guns.along[:, 2], across[:, 0], across[:, 1], across[:, 2]]
    return vt, np.array(rows, dtype=np.float32)


def reference_setup(part, paths, process, config, samples=None):
    """``thickness._setup`` of the deposit matrix (the occlusion from the kernels, which
    ``occlusion_reference`` checks on its own) and a k-d tree over the samples."""
    setup = _setup(part, paths, process, None, config, None, nodes=True, samples=samples)
    return setup, cKDTree(setup.samples.points)


def film_reference(setup, tree):
    """The film per sample and the dry volume per stroke (``simulate``'s sums), in numpy."""
    vt, gt = pair_rows_reference(setup)
    n = len(setup.samples.points)
    film, deposit = np.zeros(n), np.zeros(setup.strokes)
    for start in range(0, len(setup.guns.position), setup.batch):
        sample, gun, value = pairs_reference(setup, tree, vt, gt, slice(start, start + setup.batch))
        film += np.bincount(sample, value, n)
        deposit += np.bincount(setup.guns.stroke[gun], value * setup.samples.area_mm2[sample], setup.strokes)
    return film, deposit


def deposit_reference(setup, tree):
    """The deposit matrix as the product of each batch's (samples x gun samples) film and (gun samples x
    waypoints) time shares, in scipy."""
    vt, gt = pair_rows_reference(setup)
    guns = setup.guns
    n, waypoints = len(setup.samples.points), int(guns.node.max()) + 1
    rows, cols, vals = [], [], []
    for start in range(0, len(guns.position), setup.batch):
        sample, gun, value = pairs_reference(setup, tree, vt, gt, slice(start, start + setup.batch))
        keep = value != 0.0
        sample, gun, value = sample[keep], gun[keep], value[keep]
        if not len(gun):
            continue
        lo, hi = int(gun.min()), int(gun.max()) + 1
        order = np.argsort(gun, kind="stable")
        indptr = np.r_[0, np.cumsum(np.bincount(gun[order] - lo, minlength=hi - lo))]
        film = sparse.csc_matrix((value[order], sample[order], indptr), shape=(n, hi - lo))
        share = sparse.csr_matrix(
            (guns.node_share[lo:hi].reshape(-1), guns.node[lo:hi].reshape(-1), np.arange(0, 4 * (hi - lo) + 1, 4)),
            shape=(hi - lo, waypoints),
        )
        batch = (film.tocsr() @ share).tocoo()
        keep = batch.data != 0.0
        rows.append(batch.row[keep])
        cols.append(batch.col[keep])
        vals.append(batch.data[keep])
    return sparse.coo_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, waypoints)
    ).tocsr()
