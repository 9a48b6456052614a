"""Compiled loops of the film model (numba): the raster occlusion's depth maps and its hidden test.

The numpy forms these replace built every (view, triangle) pair and every covered pixel as arrays of
temporaries (several GB on a car body); here each view is a loop over the triangles near its frustum, found in
a uniform grid, and each triangle a loop over the pixels of its bounding box. The arithmetic is the numpy
forms' own, step by step in the same precision (float32 projections, float64 barycentric weights and depths),
so the depth maps and the hidden pairs are the same bit for bit (tests/test_speed_kernels.py checks this
against the numpy forms).

Every kernel is compiled once and cached on disk (``cache=True``) and releases the GIL (``nogil=True``), so
the callers run them on their own thread pools.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: Most cells of a uniform grid (``CellGrid``); a larger part gets larger cells.
MAX_GRID_CELLS = 4_000_000


class CellGrid:
    """Points sorted into the cells of a uniform grid: ``order[start[c]:start[c + 1]]`` are the points in
    cell c = (ix * ny + iy) * nz + iz, cells of side ``cell`` from ``low``; ``rank`` is the inverse of
    ``order``. The kernels read the points' data sorted the same way (``data[order]``), so that the points of
    neighbouring cells lie together in memory."""

    def __init__(self, points: np.ndarray, cell: float):
        points = np.asarray(points, float)
        low = points.min(axis=0) if len(points) else np.zeros(3)
        high = points.max(axis=0) if len(points) else np.zeros(3)
        extent = np.maximum(high - low, 1e-9)
        cell = max(float(cell), 1e-6)
        while np.prod(np.floor(extent / cell) + 1) > MAX_GRID_CELLS:
            cell *= 1.5
        dims = (np.floor(extent / cell) + 1).astype(np.int64)
        index = np.minimum(np.floor((points - low) / cell).astype(np.int64), dims - 1)
        key = (index[:, 0] * dims[1] + index[:, 1]) * dims[2] + index[:, 2]
        self.order = np.argsort(key, kind="stable").astype(np.int64)
        self.rank = np.empty_like(self.order)
        self.rank[self.order] = np.arange(len(self.order))
        self.start = np.zeros(int(np.prod(dims)) + 1, np.int64)
        np.cumsum(np.bincount(key, minlength=int(np.prod(dims))), out=self.start[1:])
        self.low = low.astype(np.float64)
        self.dims = dims
        self.cell = cell


@njit(cache=True, nogil=True)
def raster_depths(
    first,
    last,
    position,
    axis,
    aim,
    reach,
    aim_depth,
    centres,
    radius,
    grid_start,
    grid_low,
    grid_dims,
    grid_cell,
    corners,
    frames,
    h32,
    half32,
    to_pixel32,
    m,
    zbuf,
):
    """Depth maps of views ``first:last`` (``zbuf``, ``(last - first) * m * m``, filled with inf): every
    triangle that can hide a sample of the view rasterised at pixel centres with perspective-correct depth.
    ``centres`` (t, 3) and ``corners`` (t, 9: the three corners, float32, relative to the frames' origin) are
    the triangles' in the order of the grid over their centres.

    The triangles taken are those of ``occlusion._frustum_pairs``: centre within ``reach + radius`` of the
    aim point, or in the cone between the gun tip and the aim ball (depth along the axis in
    [0, aim depth - reach), off the axis by at most ``reach (depth + radius) / aim depth + radius``). The
    pixel loop is ``occlusion._rasterise``'s arithmetic (``h32``, ``half32``, ``to_pixel32`` the float32 forms
    of h, the map's half side and pixels per mm on the pattern plane).
    """
    one32 = np.float32(1e-6)
    tiny32 = np.float32(1e-12)
    point5 = np.float32(0.5)
    for v in range(first, last):
        base = (v - first) * m * m
        r = reach[v]
        depth_v = aim_depth[v]
        # the lateral bound of the cone at its far end, or the aim ball's radius
        far = r * max(depth_v - r + radius, 0.0) / max(depth_v, 1e-9) + radius
        grow = max(far, r + radius) + 1e-6
        lo = np.empty(3, np.int64)
        hi = np.empty(3, np.int64)
        for k in range(3):
            a = min(position[v, k], aim[v, k]) - grow
            b = max(position[v, k], aim[v, k]) + grow
            lo[k] = max(math.floor((a - grid_low[k]) / grid_cell), 0)
            hi[k] = min(math.floor((b - grid_low[k]) / grid_cell), grid_dims[k] - 1)
        for ix in range(lo[0], hi[0] + 1):
            for iy in range(lo[1], hi[1] + 1):
                row = (ix * grid_dims[1] + iy) * grid_dims[2]
                for iz in range(lo[2], hi[2] + 1):
                    c = row + iz
                    for t in range(grid_start[c], grid_start[c + 1]):
                        dx = centres[t, 0] - aim[v, 0]
                        dy = centres[t, 1] - aim[v, 1]
                        dz = centres[t, 2] - aim[v, 2]
                        take = math.sqrt(dx * dx + dy * dy + dz * dz) <= r + radius
                        if not take:
                            rx = centres[t, 0] - position[v, 0]
                            ry = centres[t, 1] - position[v, 1]
                            rz = centres[t, 2] - position[v, 2]
                            cz = rx * axis[v, 0] + ry * axis[v, 1] + rz * axis[v, 2]
                            if cz >= 0.0 and cz < depth_v - r:
                                lateral2 = (rx * rx + ry * ry + rz * rz) - cz * cz
                                within = r * max(cz + radius, 0.0) / max(depth_v, 1e-9) + radius
                                take = lateral2 <= within * within
                        if take:
                            _rasterise_one(
                                t, v, base, corners, frames, h32, half32, to_pixel32, m, one32, tiny32, point5, zbuf
                            )


@njit(cache=True, nogil=True, inline="always")
def _project_one(px, py, pz, frames, v, h32, one32):
    """``occlusion._project`` of one point: depth and pattern-plane x, y (float32)."""
    z = px * frames[0, v] + py * frames[1, v] + pz * frames[2, v] + frames[3, v]
    scale = h32 / (z if z > one32 else one32)
    x = (px * frames[4, v] + py * frames[5, v] + pz * frames[6, v] + frames[7, v]) * scale
    y = (px * frames[8, v] + py * frames[9, v] + pz * frames[10, v] + frames[11, v]) * scale
    return z, x, y


@njit(cache=True, nogil=True)
def _rasterise_one(t, v, base, corners, frames, h32, half32, to_pixel32, m, one32, tiny32, point5, zbuf):
    z0, x0, y0 = _project_one(corners[t, 0], corners[t, 1], corners[t, 2], frames, v, h32, one32)
    z1, x1, y1 = _project_one(corners[t, 3], corners[t, 4], corners[t, 5], frames, v, h32, one32)
    z2, x2, y2 = _project_one(corners[t, 6], corners[t, 7], corners[t, 8], frames, v, h32, one32)
    if not (z0 > 1.0 and z1 > 1.0 and z2 > 1.0):
        return
    ax = (x0 + half32) * to_pixel32
    bx = (x1 + half32) * to_pixel32
    qx = (x2 + half32) * to_pixel32
    ay = (y0 + half32) * to_pixel32
    by = (y1 + half32) * to_pixel32
    qy = (y2 + half32) * to_pixel32
    xa = min(min(ax, bx), qx) - point5
    xb = max(max(ax, bx), qx) - point5
    ya = min(min(ay, by), qy) - point5
    yb = max(max(ay, by), qy) - point5
    px0 = int(min(max(math.ceil(xa), 0.0), float(m)))
    px1 = int(min(max(math.floor(xb), -1.0), float(m - 1)))
    py0 = int(min(max(math.ceil(ya), 0.0), float(m)))
    py1 = int(min(max(math.floor(yb), -1.0), float(m - 1)))
    if px1 < px0 or py1 < py0:
        return
    bax = bx - ax
    qay = qy - ay
    bay = by - ay
    qax = qx - ax
    area = bax * qay - bay * qax
    if not abs(area) > tiny32:
        area = tiny32
    area64 = np.float64(area)
    for py in range(py0, py1 + 1):
        cy = py + 0.5
        cya = cy - ay
        for px in range(px0, px1 + 1):
            cx = px + 0.5
            cxa = cx - ax
            w1 = (cxa * qay - cya * qax) / area64
            w2 = (bax * cya - bay * cxa) / area64
            w0 = 1.0 - w1 - w2
            if w0 >= -1e-7 and w1 >= -1e-7 and w2 >= -1e-7:
                inv_z = w0 / z0 + w1 / z1 + w2 / z2
                depth = 1.0 / max(inv_z, 1e-12)
                k = base + py * m + px
                if depth < zbuf[k]:
                    zbuf[k] = depth


@njit(cache=True, nogil=True)
def hidden_by_depth(
    zbuf, cols, normals, frames, first, view_idx, sample_idx, h32, half32, to_pixel32, m, pixel_scale32, sqrt2_32
):
    """(p,) bool: ``occlusion._hidden_by_depth``, a pair at a time: the sample lies behind its pixel's depth
    by more than the bias (1 mm plus sqrt(2) pixel widths on the surface times the incidence's tangent)."""
    one32 = np.float32(1e-6)
    out = np.zeros(len(view_idx), np.bool_)
    for i in range(len(view_idx)):
        v = view_idx[i]
        s = sample_idx[i]
        z, x, y = _project_one(cols[0, s], cols[1, s], cols[2, s], frames, v, h32, one32)
        px = math.floor((x + half32) * to_pixel32)
        py = math.floor((y + half32) * to_pixel32)
        if not (px >= 0 and px < m and py >= 0 and py < m and z > 1.0):
            continue
        front = zbuf[(v - first) * m * m + py * m + px]
        tx = frames[12, v] - cols[0, s]
        ty = frames[13, v] - cols[1, s]
        tz = frames[14, v] - cols[2, s]
        dist = np.float32(math.sqrt(tx * tx + ty * ty + tz * tz))
        cos_a = (tx * normals[s, 0] + ty * normals[s, 1] + tz * normals[s, 2]) / max(dist, one32)
        cos_a = min(max(cos_a, 0.05), 1.0)
        tan_a = math.sqrt(1.0 - cos_a * cos_a) / cos_a
        pixel_on_surface = pixel_scale32 * z / h32 * sqrt2_32
        bias = 1.0 + pixel_on_surface * tan_a
        out[i] = z > front + bias
    return out


# ------------------------------------------------------------------------------------------ film pairs

#: Pattern kinds of the film kernels: a round pattern's density from r^2 by a power of (1 - r^2 / R^2) (flat,
#: parabolic, beta) or a Gaussian; the elliptical double-beta from (x, y).
ROUND_POWER, ROUND_GAUSSIAN, DOUBLE_BETA = 0, 1, 2


def pattern_code(pattern) -> tuple[int, np.ndarray]:
    """The film kernels' description of a ``SprayPattern``: its kind code and float32 parameters, each the
    float32 that numpy's arithmetic in ``SprayPattern.radial_density`` / ``density`` turns its Python float
    into (the scalars there are weak, so a float32 array keeps float32)."""
    f = np.float32
    if pattern.kind == "double_beta":
        return DOUBLE_BETA, np.array(
            [pattern.a_mm, pattern.b_mm, pattern.beta1 - 1.0, pattern.beta2 - 1.0, pattern.peak_integral, 0.0],
            dtype=f,
        )
    inv_r2 = 1.0 / (pattern.radius_mm * pattern.radius_mm)
    peak_inv = 1.0 / pattern.peak_integral
    if pattern.kind == "gaussian":
        return ROUND_GAUSSIAN, np.array([inv_r2, -0.5 / pattern.sigma_mm**2, peak_inv, 0.0, 0.0, 0.0], dtype=f)
    return ROUND_POWER, np.array([inv_r2, pattern.beta - 1.0, peak_inv, 0.0, 0.0, 0.0], dtype=f)


@njit(cache=True, nogil=True, inline="always")
def _power32(base, exponent):
    """``patterns._pow``: the common integer exponents by multiplication (float32)."""
    if exponent == 0.0:
        return np.float32(1.0)
    if exponent == 1.0:
        return base
    if exponent == 2.0:
        return base * base
    return base**exponent


@njit(cache=True, nogil=True)
def _mark_view(view, current, hidden_keys, view_has_hidden, n, rank, hidden):
    """Make ``hidden`` (n, in grid order) mark the samples hidden from ``view`` (``occlusion.Occlusion``'s
    sorted keys ``view * n + sample``), unmarking those of the view ``current`` marked before; returns
    ``view``."""
    if view == current:
        return current
    if current >= 0 and view_has_hidden[current]:
        base = np.int64(current) * n
        for i in range(_first_at_least(hidden_keys, base), _first_at_least(hidden_keys, base + n)):
            hidden[rank[hidden_keys[i] - base]] = False
    if view_has_hidden[view]:
        base = np.int64(view) * n
        for i in range(_first_at_least(hidden_keys, base), _first_at_least(hidden_keys, base + n)):
            hidden[rank[hidden_keys[i] - base]] = True
    return view


@njit(cache=True, nogil=True)
def _first_at_least(values, key):
    """The first index of sorted ``values`` whose value is at least ``key`` (``np.searchsorted``)."""
    lo, hi = 0, len(values)
    while lo < hi:
        mid = (lo + hi) >> 1
        if values[mid] < key:
            lo = mid + 1
        else:
            hi = mid
    return lo


@njit(cache=True, nogil=True)
def _pair_value(vt, gt, gun, s, kind, params, h32):
    """The film of one (sample, gun sample) pair, mm, before the visibility test: the formula of
    ``thickness``'s docstring in float32 on the rows of ``thickness._pair_rows`` (``vt`` (n, 6) with a row a
    sample, ``gt`` (7 or 13, k)); 0 when the sample lies behind the gun or faces away."""
    vx = vt[s, 0] - gt[0, gun]
    vy = vt[s, 1] - gt[1, gun]
    vz = vt[s, 2] - gt[2, gun]
    z = vx * gt[4, gun] + vy * gt[5, gun] + vz * gt[6, gun]
    small = np.float32(1e-6)
    zs = z if z > small else np.float32(1.0)
    scale = h32 / zs
    cos_term = -(vx * vt[s, 3] + vy * vt[s, 4] + vz * vt[s, 5])
    if not (z > small and cos_term > 0):
        return 0.0
    one = np.float32(1.0)
    zero = np.float32(0.0)
    if kind == DOUBLE_BETA:
        x = (vx * gt[7, gun] + vy * gt[8, gun] + vz * gt[9, gun]) * scale
        y = (vx * gt[10, gun] + vy * gt[11, gun] + vz * gt[12, gun]) * scale
        xa = x / params[0]
        sx = one - xa * xa
        inside = sx > zero
        s_safe = sx if inside else one
        yb = y / params[1]
        t = one - yb * yb / s_safe
        inside = inside and t > zero
        shape = _power32(s_safe, params[2]) * _power32(t if inside else one, params[3]) if inside else zero
        flux = shape / params[4]
    else:
        r2 = (vx * vx + vy * vy + vz * vz - z * z) * (scale * scale)
        u = r2 * params[0]
        if kind == ROUND_GAUSSIAN:
            shape = np.float32(math.exp(r2 * params[1])) if u < one else zero
        else:
            shape = _power32(one - u if u < one else one, params[1]) if u < one else zero
        flux = shape * params[2]
    return np.float64(flux * (scale * scale) * cos_term / zs * gt[3, gun])


@njit(cache=True, nogil=True)
def _cells(point, r, grid_low, grid_dims, grid_cell, lo, hi):
    for k in range(3):
        lo[k] = max(math.floor((point[k] - r - grid_low[k]) / grid_cell), 0)
        hi[k] = min(math.floor((point[k] + r - grid_low[k]) / grid_cell), grid_dims[k] - 1)


@njit(cache=True, nogil=True)
def _gun_pairs(
    g, aim, reach, points, grid_start, grid_low, grid_dims, grid_cell, vt, gt, kind, params, h32, hidden, lo, hi,
    pair_s, pair_v,
):  # fmt: skip
    """The film of gun sample ``g`` at every sample within its reach of its aim point, hidden ones (``hidden``)
    and zeros left out: ``(m, within, pair_s, pair_v)``, the first ``m`` of ``pair_s`` / ``pair_v`` (grown when
    full) the samples (in the grid's order) and their film, ``within`` the samples within reach."""
    r = reach[g]
    _cells(aim[g], r, grid_low, grid_dims, grid_cell, lo, hi)
    m = 0
    within = 0
    for ix in range(lo[0], hi[0] + 1):
        for iy in range(lo[1], hi[1] + 1):
            row = (ix * grid_dims[1] + iy) * grid_dims[2]
            for s in range(grid_start[row + lo[2]], grid_start[row + hi[2] + 1]):
                dx = points[s, 0] - aim[g, 0]
                dy = points[s, 1] - aim[g, 1]
                dz = points[s, 2] - aim[g, 2]
                if math.sqrt(dx * dx + dy * dy + dz * dz) > r:
                    continue
                within += 1
                value = _pair_value(vt, gt, g, s, kind, params, h32)
                if value == 0.0 or hidden[s]:
                    continue
                if m == len(pair_s):
                    pair_s = _grown_int(pair_s, m, 2 * m)
                    pair_v = _grown_float(pair_v, m, 2 * m)
                pair_s[m] = s
                pair_v[m] = value
                m += 1
    return m, within, pair_s, pair_v


@njit(cache=True, nogil=True)
def film_sums(
    first, last, aim, reach, points, rank, grid_start, grid_low, grid_dims, grid_cell, vt, gt, kind, params, h32,
    of_gun, hidden_keys, view_has_hidden, stroke, area, thickness, deposit,
):  # fmt: skip
    """The film of gun samples ``first:last`` added to ``thickness`` (per sample, mm) and the dry volume they
    leave to ``deposit`` (per stroke, mm^3): every sample within a gun sample's reach of its aim point, hidden
    pairs left out. The samples' ``points``, ``vt``, ``area`` and ``thickness`` are in the grid's order
    (``rank``: a sample's place in it). Returns the number of pairs."""
    n = len(points)
    lo = np.empty(3, np.int64)
    hi = np.empty(3, np.int64)
    pair_s = np.empty(1024, np.int64)
    pair_v = np.empty(1024, np.float64)
    hidden = np.zeros(n, np.bool_)
    view = -1
    count = 0
    for g in range(first, last):
        view = _mark_view(of_gun[g], view, hidden_keys, view_has_hidden, n, rank, hidden)
        m, within, pair_s, pair_v = _gun_pairs(
            g, aim, reach, points, grid_start, grid_low, grid_dims, grid_cell, vt, gt, kind, params, h32, hidden, lo,
            hi, pair_s, pair_v,
        )  # fmt: skip
        count += within
        for i in range(m):
            thickness[pair_s[i]] += pair_v[i]
            deposit[stroke[g]] += pair_v[i] * area[pair_s[i]]
    return count


#: Waypoints a deposit kernel sums at once (a gun sample's time is shared by at most three neighbours).
_SLOTS = 4


@njit(cache=True, nogil=True)
def deposit_entries(
    first, last, aim, reach, points, order, rank, grid_start, grid_low, grid_dims, grid_cell, vt, gt, kind, params,
    h32, of_gun, hidden_keys, view_has_hidden, node, share,
):  # fmt: skip
    """(sample, waypoint, mm) entries of the deposit matrix from gun samples ``first:last``: each pair's film
    (``_pair_value``, hidden pairs left out) times each of its gun sample's four waypoint shares, summed per
    (sample, waypoint) over the gun samples in ascending order, as ``thickness._deposit_entries``' sparse
    product sums them. A waypoint's sums are kept in one of ``_SLOTS`` slots (its samples in the order first
    met, each sample's place in a dense index) until a later waypoint needs the slot or the batch ends; zero
    sums are left out. The samples' ``points`` and ``vt`` are in the grid's order (``order``, ``rank``); the
    entries' rows are the samples' own indices."""
    n = len(points)
    lo = np.empty(3, np.int64)
    hi = np.empty(3, np.int64)
    owner = np.full(_SLOTS, -1, np.int64)
    used = np.zeros(_SLOTS, np.int64)
    place = np.zeros((_SLOTS, n), np.int32)  # 1 + the sample's place in the slot's list, 0 when not in it
    cap = 1024
    keys = np.empty((_SLOTS, cap), np.int64)
    sums = np.empty((_SLOTS, cap), np.float64)
    out_rows = np.empty(4096, np.int64)
    out_cols = np.empty(4096, np.int64)
    out_vals = np.empty(4096, np.float64)
    n_out = 0
    pair_s = np.empty(1024, np.int64)  # the pairs of one gun sample
    pair_v = np.empty(1024, np.float64)
    hidden = np.zeros(n, np.bool_)
    view = -1
    for g in range(first, last):
        view = _mark_view(of_gun[g], view, hidden_keys, view_has_hidden, n, rank, hidden)
        m, _, pair_s, pair_v = _gun_pairs(
            g, aim, reach, points, grid_start, grid_low, grid_dims, grid_cell, vt, gt, kind, params, h32, hidden, lo,
            hi, pair_s, pair_v,
        )  # fmt: skip
        if m == 0:
            continue
        for c in range(4):
            weight = share[g, c]
            if weight == 0.0:
                continue
            w = node[g, c]
            slot = w % _SLOTS
            if owner[slot] != w:
                if owner[slot] >= 0:
                    n_out, out_rows, out_cols, out_vals = _emit(
                        slot, owner, used, keys, sums, place, order, n_out, out_rows, out_cols, out_vals
                    )
                owner[slot] = w
            if used[slot] + m > keys.shape[1]:
                size = 2 * (used[slot] + m)
                grown_keys = np.empty((_SLOTS, size), np.int64)
                grown_sums = np.empty((_SLOTS, size), np.float64)
                for k in range(_SLOTS):
                    for i in range(used[k]):
                        grown_keys[k, i] = keys[k, i]
                        grown_sums[k, i] = sums[k, i]
                keys, sums = grown_keys, grown_sums
            for i in range(m):
                s = pair_s[i]
                at = place[slot, s]
                if at == 0:
                    k = used[slot]
                    keys[slot, k] = s
                    sums[slot, k] = 0.0 + pair_v[i] * weight
                    used[slot] = k + 1
                    place[slot, s] = k + 1
                else:
                    sums[slot, at - 1] += pair_v[i] * weight
    for slot in range(_SLOTS):
        if owner[slot] >= 0:
            n_out, out_rows, out_cols, out_vals = _emit(
                slot, owner, used, keys, sums, place, order, n_out, out_rows, out_cols, out_vals
            )
    return _grown_int(out_rows, n_out, n_out), _grown_int(out_cols, n_out, n_out), _grown_float(out_vals, n_out, n_out)


@njit(cache=True, nogil=True)
def _emit(slot, owner, used, keys, sums, place, order, n_out, out_rows, out_cols, out_vals):
    """Move one slot's non-zero sums to the output (growing it) and empty the slot."""
    k = used[slot]
    if n_out + k > len(out_rows):
        size = max(2 * len(out_rows), n_out + k)
        out_rows = _grown_int(out_rows, n_out, size)
        out_cols = _grown_int(out_cols, n_out, size)
        out_vals = _grown_float(out_vals, n_out, size)
    w = owner[slot]
    for i in range(k):
        s = keys[slot, i]
        place[slot, s] = 0
        if sums[slot, i] != 0.0:
            out_rows[n_out] = order[s]
            out_cols[n_out] = w
            out_vals[n_out] = sums[slot, i]
            n_out += 1
    used[slot] = 0
    owner[slot] = -1
    return n_out, out_rows, out_cols, out_vals


@njit(cache=True, nogil=True)
def _grown_int(values, n, size):
    """``values[:n]`` in a new int64 array of ``size`` elements."""
    out = np.empty(size, np.int64)
    for i in range(n):
        out[i] = values[i]
    return out


@njit(cache=True, nogil=True)
def _grown_float(values, n, size):
    """``values[:n]`` in a new float64 array of ``size`` elements."""
    out = np.empty(size, np.float64)
    for i in range(n):
        out[i] = values[i]
    return out


@njit(cache=True, nogil=True)
def _scatter_rows(rows, cols, vals, fill, indices, data):
    """Each entry ``(rows[i], cols[i], vals[i])`` put at its row's next free place (``fill``, advanced)."""
    for i in range(len(rows)):
        at = fill[rows[i]]
        indices[at] = cols[i]
        data[at] = vals[i]
        fill[rows[i]] = at + 1


@njit(cache=True, nogil=True)
def _sorted_summed_rows(indptr, indices, data):
    """Each row's entries sorted by column (stable) and repeated columns summed in that order, the rows moved
    down over the room freed (``indptr`` updated); returns the number of entries kept. Zeros are kept."""
    nnz = 0
    start = indptr[0]
    for r in range(len(indptr) - 1):
        end = indptr[r + 1]
        for i in range(start + 1, end):  # insertion sort: a row holds a few dozen entries
            c = indices[i]
            v = data[i]
            j = i - 1
            while j >= start and indices[j] > c:
                indices[j + 1] = indices[j]
                data[j + 1] = data[j]
                j -= 1
            indices[j + 1] = c
            data[j + 1] = v
        i = start
        while i < end:
            c = indices[i]
            x = data[i]
            i += 1
            while i < end and indices[i] == c:
                x += data[i]
                i += 1
            indices[nnz] = c
            data[nnz] = x
            nnz += 1
        start = end
        indptr[r + 1] = nnz
    return nnz


def csr_from_entries(batches, shape: tuple[int, int]):
    """The CSR matrix of ``(rows, cols, vals)`` entry batches, repeated (row, column) entries summed: scipy's
    ``coo_matrix((vals, (rows, cols)), shape).tocsr()`` of the concatenated batches, without the concatenated
    copies and the COO matrix.

    The same matrix bit for bit where no (row, column) repeats more than twice (a sum of two is the same in
    either order; scipy's sort of a row is not stable): the deposit matrix's entries are unique within a batch
    of gun samples and a waypoint's gun samples span at most two batches. Indices are int32 where they fit, as
    scipy's; the result is in canonical form (sorted, no repeats)."""
    from scipy import sparse

    n, m = shape
    counts = np.zeros(n, np.int64)
    for rows, _cols, _vals in batches:
        counts += np.bincount(rows, minlength=n)
    total = int(counts.sum())
    wide = max(total, n, m) > np.iinfo(np.int32).max
    index = np.int64 if wide else np.int32
    indptr = np.zeros(n + 1, np.int64)
    np.cumsum(counts, out=indptr[1:])
    del counts
    fill = indptr[:-1].copy()
    indices = np.empty(total, index)
    data = np.empty(total, np.float64)
    for rows, cols, vals in batches:
        _scatter_rows(rows, cols, vals, fill, indices, data)
    del fill
    nnz = _sorted_summed_rows(indptr, indices, data)
    if nnz < total:
        indices, data = indices[:nnz].copy(), data[:nnz].copy()
    matrix = sparse.csr_matrix((data, indices, indptr.astype(index)), shape=(n, m), copy=False)
    matrix.has_sorted_indices = True
    matrix.has_canonical_format = True
    return matrix
