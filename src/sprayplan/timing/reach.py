"""TOPP-RA's reachability analysis (Pham & Pham 2018) for many joint paths at once, compiled.

The same problem as toppra's ``TOPPRA`` with the ``seidel`` solver, a ``JointAccelerationConstraint`` (its
default interpolation discretisation) and an upper bound on ``x = sd^2`` per grid point, solved rest to rest,
for a batch of paths: each path a loop over its own stages (``timing.kernels.reach_all``, numba; it replaced a
numpy form that ran the paths in lockstep, one array operation per grid index, with the same arithmetic: the
same numbers bit for bit, tests/test_timing_speed.py).

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

from sprayplan.timing.kernels import MAX_TRIES, ROW_TOL, SMALL, TINY, VAR_MAX, reach_all

__all__ = ["MAX_TRIES", "ROW_TOL", "SMALL", "TINY", "VAR_MAX", "reach_paths"]


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
    a_max = np.ascontiguousarray(a_max, dtype=float)
    start = np.concatenate([[0], np.cumsum([len(it[0]) for it in items])]).astype(np.int64)
    grid, d1, d2, x_bound = (
        np.ascontiguousarray(np.concatenate([it[k] for it in items]), dtype=float) for k in range(4)
    )
    x = np.empty(len(grid))
    failed = np.zeros(len(items), np.bool_)
    reach_all(grid, d1, d2, x_bound, start, a_max, x, failed)
    return [None if failed[p] else np.sqrt(x[start[p] : start[p + 1]]) for p in range(len(items))]
