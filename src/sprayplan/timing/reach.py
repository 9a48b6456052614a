"""TOPP-RA's reachability analysis (Pham & Pham 2018) for many joint paths at once, in numpy.

The same problem as toppra's ``TOPPRA`` with the ``seidel`` solver, a ``JointAccelerationConstraint`` (its
default interpolation discretisation) and an upper bound on ``x = sd^2`` per grid point, solved rest to rest,
for a batch of paths in lockstep: stage i of every path whose grid has more than i intervals is solved in one
array operation, so the Python cost is per grid index, not per grid point and path.

At stage i (grid point s_i, interval length D_i, variables u = sdd on the interval and x = sd^2 at s_i), the
constraints are toppra's: each axis's acceleration ``|a u + b x| <= a_max`` with ``(a, b) = (q'(s_i),
q''(s_i))`` (collocation) and ``(q'(s_{i+1}) + 2 D_i q''(s_{i+1}), q''(s_{i+1}))`` (at the interval's end,
``x + 2 D_i u`` being x there), ``0 <= x <= x_max``, toppra's variable bounds ``|u|, x <= 1e8``, and (to be
controllable) ``K_lo <= x + 2 D_i u <= K_hi`` with K the next stage's controllable set. Every row is linear in
(u, x); the backward pass's two LPs (the largest and the smallest x) are the two ends of the polygon's
projection on x, found exactly by eliminating u (Fourier-Motzkin: every row bounding u from above paired with
every row bounding it from below). The forward pass takes at each stage the largest u at the x reached,
then toppra's small step back into the next set (``max(x - 1e-8, 0.9999 x)``, clipped to K).

toppra's seidel solver accepts rows violated by less than 1e-10; the answers here are the exact optima, so the
two agree to rounding on well-posed stages. Where this analysis finds a stage empty (an infeasible or
uncontrollable path, or a forward step that fails even after toppra's ten retries), the path's entry is None:
the caller asks toppra itself (``timing.path``), so its answer and its failures stay toppra's.
"""

from __future__ import annotations

import numpy as np

#: toppra's seidel wrapper's bounds on u and x (``VAR_MIN``, ``VAR_MAX``).
VAR_MAX = 1e8
#: toppra's forward pass: the step back into the next set, and its retries (``TINY``, ``MAX_TRIES``).
TINY = 1e-8
MAX_TRIES = 10
#: toppra's test of the start (``SMALL``): x = 0 must lie within this of the first controllable set.
SMALL = 1e-5
#: The seidel solver's tolerance on a row (``TINY`` there): a forward step is feasible within it.
ROW_TOL = 1e-10


def reach_paths(items, a_max: np.ndarray) -> list:
    """Rest-to-rest parameterisations of many paths.

    Parameters
    ----------
    items : list of (grid (N+1,), d1 (N+1, dof), d2 (N+1, dof), x_max (N+1,))
        Each path's grid points, its first and second derivatives there, and the upper bound of sd^2 (inf: none).
    a_max : (dof,) float
        The axes' acceleration limits.

    Returns
    -------
    list of (N+1,) float or None
        sd at the grid points (toppra's ``sd_vec``), or None where a stage is empty (see the module docstring).
    """
    if not items:
        return []
    a_max = np.asarray(a_max, float)
    dof = len(a_max)
    stages = np.array([len(it[0]) - 1 for it in items])
    order = np.argsort(-stages, kind="stable")  # longest first: the paths still running at stage i are a prefix
    n_sorted = stages[order]
    longest = int(n_sorted[0])
    # active[i]: how many paths have a stage i; start[i]: where stage i's rows begin in the flat layout
    active = (n_sorted[None, :] > np.arange(longest)[:, None]).sum(axis=1)
    start = np.concatenate([[0], np.cumsum(active)])
    total = int(start[-1])
    m = 2 * dof + 2  # rows bounding u from above (and as many from below): 2 per axis, K's end, the u bound
    alpha = np.empty((total, m))  # the upper rows: alpha u + beta x <= gamma, alpha >= 0
    beta_up = np.empty((total, m))
    beta_lo = np.empty((total, m))  # the lower rows: -alpha u + beta_lo x <= gamma
    x_max = np.empty(total)
    delta = np.empty(total)
    for p, r in enumerate(order):
        grid, d1, d2, xb = items[r]
        n = len(grid) - 1
        rows = start[:n] + p
        ds = np.diff(grid)
        a_end = d1[1:] + 2.0 * ds[:, None] * d2[1:]
        for k, (a, b) in enumerate(((d1[:-1], d2[:-1]), (a_end, d2[1:]))):
            sign = np.where(a < 0.0, -1.0, 1.0)
            alpha[rows, k * dof : (k + 1) * dof] = np.abs(a)
            beta_up[rows, k * dof : (k + 1) * dof] = sign * b
            beta_lo[rows, k * dof : (k + 1) * dof] = -sign * b
        alpha[rows, 2 * dof] = 2.0 * ds
        beta_up[rows, 2 * dof] = 1.0
        beta_lo[rows, 2 * dof] = -1.0
        x_max[rows] = np.minimum(xb[:-1], VAR_MAX)
        delta[rows] = ds
    alpha[:, 2 * dof + 1] = 1.0
    beta_up[:, 2 * dof + 1] = 0.0
    beta_lo[:, 2 * dof + 1] = 0.0
    gamma_up = np.empty((total, m))
    gamma_lo = np.empty((total, m))
    gamma_up[:, : 2 * dof] = np.tile(a_max, 2)
    gamma_lo[:, : 2 * dof] = np.tile(a_max, 2)
    gamma_up[:, 2 * dof + 1] = VAR_MAX
    gamma_lo[:, 2 * dof + 1] = VAR_MAX
    # eliminating u: upper row j and lower row k give c x <= r with c = alpha_j beta_lo_k + alpha_k beta_up_j and
    # r = alpha_j gamma_lo_k + alpha_k gamma_up_j; the pairs without K's rows do not change from stage to stage
    static_lo, static_hi = _static_bounds(alpha, beta_up, beta_lo, gamma_up, x_max, dof)
    j = 2 * dof
    up_rows = np.r_[np.arange(j), j + 1]  # the rows paired with K's lower end (the axes', the u bound)
    k_lo = np.zeros((longest + 1, len(items)))
    k_hi = np.zeros((longest + 1, len(items)))
    failed = np.zeros(len(items), bool)
    for i in range(longest - 1, -1, -1):
        k = active[i]
        sl = slice(start[i], start[i] + k)
        hi_next, lo_next = k_hi[i + 1, :k], k_lo[i + 1, :k]
        gamma_up[sl, j] = hi_next
        gamma_lo[sl, j] = -lo_next
        al, two_d = alpha[sl][:, up_rows], 2.0 * delta[sl][:, None]
        # K's upper end (alpha 2 D, beta 1, gamma K_hi) with every other lower row (K's own is parallel)
        c1 = two_d * beta_lo[sl][:, up_rows] + al
        r1 = two_d * gamma_lo[sl][:, up_rows] + al * hi_next[:, None]
        # every other upper row with K's lower end (alpha 2 D, beta -1, gamma -K_lo)
        c2 = two_d * beta_up[sl][:, up_rows] - al
        r2 = two_d * gamma_up[sl][:, up_rows] - al * lo_next[:, None]
        c = np.concatenate([c1, c2], axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            bound = np.concatenate([r1, r2], axis=1) / c
        hi = np.minimum(static_hi[sl], np.where(c > 0.0, bound, np.inf).min(axis=1))
        lo = np.maximum(static_lo[sl], np.where(c < 0.0, bound, -np.inf).max(axis=1))
        failed[:k] |= ~(lo <= hi)
        k_lo[i, :k] = lo
        k_hi[i, :k] = hi
    failed |= k_lo[0] > SMALL
    # the forward pass: the largest u at the x reached, from rest
    x = np.zeros((longest + 1, len(items)))
    for i in range(longest):
        k = active[i]
        sl = slice(start[i], start[i] + k)
        al, bu, bl, gu, gl = alpha[sl], beta_up[sl], beta_lo[sl], gamma_up[sl], gamma_lo[sl]
        xi = x[i, :k].copy()
        for _ in range(MAX_TRIES + 1):
            u, ok = _largest_u(al, bu, bl, gu, gl, xi)
            if ok.all():
                break
            xi = np.where(ok, xi, np.maximum(xi - TINY, 0.999 * xi))
        failed[:k] |= ~ok
        x[i, :k] = xi
        nxt = xi + 2.0 * delta[sl] * u
        nxt = np.maximum(nxt - TINY, 0.9999 * nxt)
        x[i + 1, :k] = np.minimum(k_hi[i + 1, :k], np.maximum(k_lo[i + 1, :k], nxt))
    out = [None] * len(items)
    for p, r in enumerate(order):
        if not failed[p]:
            out[r] = np.sqrt(x[: n_sorted[p] + 1, p])
    return out


def _static_bounds(alpha, beta_up, beta_lo, gamma_up, x_max, dof: int, chunk: int = 2048):
    """Per stage, the bounds on x from the pairs of rows that do not involve K: two axes' rows (an upper row and
    the other's lower row, both ways round: the pair (j, k) gives c x <= r and (k, j) gives -c x <= r with the
    same r >= 0, so only the upper bound r / |c| counts, x being >= 0), and an axis's row with a u bound; with
    ``0 <= x <= x_max``."""
    j = 2 * dof
    first, second = np.triu_indices(j, 1)
    lo = np.zeros(len(alpha))
    hi = x_max.copy()
    for b in range(0, len(alpha), chunk):
        sl = slice(b, b + chunk)
        a, bu, bl, g = alpha[sl, :j], beta_up[sl, :j], beta_lo[sl, :j], gamma_up[sl, :j]
        c = np.abs(a[:, first] * bl[:, second] + a[:, second] * bu[:, first])
        r = a[:, first] * g[:, second] + a[:, second] * g[:, first]
        with np.errstate(divide="ignore", invalid="ignore"):
            pair = np.where(c > 0.0, r / c, np.inf).min(axis=1, initial=np.inf)
            # the u bound's upper row (alpha 1, beta 0, gamma VAR_MAX) with each axis's lower row, and each
            # axis's upper row with the u bound's lower row
            c = np.concatenate([bl, bu], axis=1)
            r = np.concatenate([g + a * VAR_MAX, a * VAR_MAX + g], axis=1)
            bound = r / c
        hi[sl] = np.minimum(np.minimum(hi[sl], pair), np.where(c > 0.0, bound, np.inf).min(axis=1))
        lo[sl] = np.maximum(lo[sl], np.where(c < 0.0, bound, -np.inf).max(axis=1))
    return lo, hi


def _largest_u(alpha, beta_up, beta_lo, gamma_up, gamma_lo, x):
    """The largest u the rows allow at x (k,), and whether that u meets every row (within ``ROW_TOL``)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        up = np.where(alpha > 0.0, (gamma_up - beta_up * x[:, None]) / alpha, np.inf).min(axis=1)
        low = np.where(alpha > 0.0, (beta_lo * x[:, None] - gamma_lo) / alpha, -np.inf).max(axis=1)
    flat = alpha == 0.0  # rows without u: x alone must meet them
    bad = (flat & ((beta_up * x[:, None] - gamma_up > ROW_TOL) | (beta_lo * x[:, None] - gamma_lo > ROW_TOL))).any(
        axis=1
    )
    ok = ~bad & (low <= up + ROW_TOL * np.maximum(1.0, np.abs(up)))
    return up, ok
