"""Compiled loops of the timing stage (numba): the reachability analysis, the joint spline's values and the
dense checks' ratios.

The numpy forms these replace spent their time on temporaries and on Python's cost per grid index (the
reachability analysis ran its paths in lockstep, one array operation per stage). Here each path is a loop
over its own stages, and each sample a loop over its axes. The arithmetic is the numpy forms' own, step by
step in the same precision and order (no fused multiply-adds: numba does not contract without ``fastmath``),
NaN kept where numpy's ``min``/``max``/``minimum``/``maximum`` keep it, so the results are the same bit for
bit (tests/test_timing_speed.py checks them against the numpy forms and scipy's spline evaluation).

Every kernel is compiled once and cached on disk (``cache=True``), releases the GIL (``nogil=True``) and
divides as numpy does (``error_model="numpy"``: a division by zero gives inf or NaN, no exception).
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: toppra's seidel wrapper's bounds on u and x (``VAR_MIN``, ``VAR_MAX``).
VAR_MAX = 1e8
#: toppra's forward pass: the step back into the next set, and its retries (``TINY``, ``MAX_TRIES``).
TINY = 1e-8
MAX_TRIES = 10
#: toppra's test of the start (``SMALL``): x = 0 must lie within this of the first controllable set.
SMALL = 1e-5
#: The seidel solver's tolerance on a row (``TINY`` there): a forward step is feasible within it.
ROW_TOL = 1e-10


@njit(cache=True, nogil=True, inline="always")
def _min(a, b):
    """numpy's ``minimum`` of two floats (NaN if either is)."""
    return a if (a <= b or a != a) else b


@njit(cache=True, nogil=True, inline="always")
def _max(a, b):
    """numpy's ``maximum`` of two floats (NaN if either is)."""
    return a if (a >= b or a != a) else b


@njit(cache=True, nogil=True, error_model="numpy")
def reach_all(grid, d1, d2, x_bound, start, a_max, x_out, failed):
    """``timing.reach.reach_paths``'s analysis of every path: path p's grid points are rows ``start[p]`` to
    ``start[p + 1]`` of ``grid`` (N,), ``d1``, ``d2`` (N, dof) and ``x_bound`` (N,); x = sd^2 at them goes to
    the same rows of ``x_out``, and ``failed[p]`` is set where a stage is empty."""
    for p in range(len(start) - 1):
        lo, hi = start[p], start[p + 1]
        failed[p] = _reach_one(grid[lo:hi], d1[lo:hi], d2[lo:hi], x_bound[lo:hi], a_max, x_out[lo:hi])


@njit(cache=True, nogil=True, error_model="numpy")
def _reach_one(grid, d1, d2, x_bound, a_max, x):
    """One path (``timing.reach``'s module docstring): the rows of each stage, the bounds on x of the pairs
    without K, the backward pass (the controllable sets) and the forward pass; True where a stage is empty."""
    n = len(grid) - 1
    dof = len(a_max)
    j = 2 * dof
    m = 2 * dof + 2
    # the rows of each stage: upper rows alpha u + beta_up x <= gamma_up, lower rows -alpha u + beta_lo x <=
    # gamma_lo; per axis its acceleration at the stage's grid point and at the interval's end, K's row (column
    # j, its gammas set by the backward pass), the u bound (column j + 1)
    alpha = np.empty((n, m))
    beta_up = np.empty((n, m))
    beta_lo = np.empty((n, m))
    gamma_up = np.empty((n, m))
    gamma_lo = np.empty((n, m))
    x_max = np.empty(n)
    delta = np.empty(n)
    for i in range(n):
        ds = grid[i + 1] - grid[i]
        two_ds = 2.0 * ds
        for a in range(dof):
            for k in range(2):
                if k == 0:
                    av, bv = d1[i, a], d2[i, a]
                else:
                    av, bv = d1[i + 1, a] + two_ds * d2[i + 1, a], d2[i + 1, a]
                sign = -1.0 if av < 0.0 else 1.0
                col = k * dof + a
                alpha[i, col] = abs(av)
                beta_up[i, col] = sign * bv
                beta_lo[i, col] = -sign * bv
                gamma_up[i, col] = a_max[a]
                gamma_lo[i, col] = a_max[a]
        alpha[i, j] = two_ds
        beta_up[i, j] = 1.0
        beta_lo[i, j] = -1.0
        alpha[i, j + 1] = 1.0
        beta_up[i, j + 1] = 0.0
        beta_lo[i, j + 1] = 0.0
        gamma_up[i, j + 1] = VAR_MAX
        gamma_lo[i, j + 1] = VAR_MAX
        x_max[i] = _min(x_bound[i], VAR_MAX)
        delta[i] = ds
    static_lo = np.empty(n)
    static_hi = np.empty(n)
    for i in range(n):
        static_lo[i], static_hi[i] = _static_row(alpha[i], beta_up[i], beta_lo[i], gamma_up[i], x_max[i], j)
    # the backward pass: the controllable set [k_lo, k_hi] of every stage
    k_lo = np.zeros(n + 1)
    k_hi = np.zeros(n + 1)
    failed = False
    for i in range(n - 1, -1, -1):
        hi_next, lo_next = k_hi[i + 1], k_lo[i + 1]
        gamma_up[i, j] = hi_next
        gamma_lo[i, j] = -lo_next
        two_d = 2.0 * delta[i]
        upper = np.inf
        lower = -np.inf
        for q in range(m):
            if q == j:
                continue
            al = alpha[i, q]
            # K's upper end (alpha 2 D, beta 1, gamma K_hi) with the lower row q
            c = two_d * beta_lo[i, q] + al
            r = two_d * gamma_lo[i, q] + al * hi_next
            bound = r / c
            if c > 0.0:
                upper = _min(upper, bound)
            elif c < 0.0:
                lower = _max(lower, bound)
            # the upper row q with K's lower end (alpha 2 D, beta -1, gamma -K_lo)
            c = two_d * beta_up[i, q] - al
            r = two_d * gamma_up[i, q] - al * lo_next
            bound = r / c
            if c > 0.0:
                upper = _min(upper, bound)
            elif c < 0.0:
                lower = _max(lower, bound)
        hi = _min(static_hi[i], upper)
        lo = _max(static_lo[i], lower)
        if not lo <= hi:
            failed = True
        k_lo[i] = lo
        k_hi[i] = hi
    if k_lo[0] > SMALL:
        failed = True
    # the forward pass: the largest u at the x reached, from rest
    x[0] = 0.0
    for i in range(n):
        xi = x[i]
        u = 0.0
        ok = False
        for _ in range(MAX_TRIES + 1):
            u, ok = _largest_u(alpha[i], beta_up[i], beta_lo[i], gamma_up[i], gamma_lo[i], xi)
            if ok:
                break
            xi = _max(xi - TINY, 0.999 * xi)
        if not ok:
            failed = True
        x[i] = xi
        nxt = xi + 2.0 * delta[i] * u
        nxt = _max(nxt - TINY, 0.9999 * nxt)
        x[i + 1] = _min(k_hi[i + 1], _max(k_lo[i + 1], nxt))
    return failed


@njit(cache=True, nogil=True, error_model="numpy")
def _static_row(alpha, beta_up, beta_lo, gamma_up, x_max, j):
    """One stage's bounds on x from the pairs of rows without K (``timing.reach._static_bounds``)."""
    pair = np.inf
    for f in range(j - 1):
        for s in range(f + 1, j):
            c = abs(alpha[f] * beta_lo[s] + alpha[s] * beta_up[f])
            r = alpha[f] * gamma_up[s] + alpha[s] * gamma_up[f]
            pair = _min(pair, r / c if c > 0.0 else np.inf)
    upper = np.inf
    lower = -np.inf
    for f in range(j):
        r = gamma_up[f] + alpha[f] * VAR_MAX
        for c in (beta_lo[f], beta_up[f]):
            bound = r / c
            if c > 0.0:
                upper = _min(upper, bound)
            elif c < 0.0:
                lower = _max(lower, bound)
    return _max(0.0, lower), _min(_min(x_max, pair), upper)


@njit(cache=True, nogil=True, error_model="numpy")
def _largest_u(alpha, beta_up, beta_lo, gamma_up, gamma_lo, x):
    """The largest u one stage's rows allow at x, and whether that u meets every row (within ``ROW_TOL``)."""
    up = np.inf
    low = -np.inf
    bad = False
    for q in range(len(alpha)):
        a = alpha[q]
        if a > 0.0:
            up = _min(up, (gamma_up[q] - beta_up[q] * x) / a)
            low = _max(low, (beta_lo[q] * x - gamma_lo[q]) / a)
        elif a == 0.0:
            if beta_up[q] * x - gamma_up[q] > ROW_TOL or beta_lo[q] * x - gamma_lo[q] > ROW_TOL:
                bad = True
    return up, (not bad) and low <= up + ROW_TOL * _max(1.0, abs(up))


@njit(cache=True, nogil=True, error_model="numpy")
def spline_values(breaks, c0, c1, c2, s, q, d1, d2):
    """A cubic spline q(s) and its two derivatives at the path positions ``s`` (k,), into ``q``, ``d1`` and
    ``d2`` (k, dof): the three piecewise polynomials' coefficients ``c0`` (4, n - 1, dof), ``c1`` (3, ...) and
    ``c2`` (2, ...) over ``breaks`` (n, increasing), evaluated as scipy's ``PPoly`` does (``evaluate_poly1``:
    the interval with ``breaks[i] <= s < breaks[i + 1]``, the last one closed, the end ones extended; with
    h = s - breaks[i], the powers of h by repeated products, the terms added from the constant one up to a sum
    started at 0)."""
    dof = d1.shape[1]
    i = 0
    for k in range(len(s)):
        i = _interval(breaks, s[k], i)
        if i < 0:
            q[k] = np.nan
            d1[k] = np.nan
            d2[k] = np.nan
            i = 0
            continue
        h = s[k] - breaks[i]
        hh = h * h
        for a in range(dof):
            q[k, a] = (((0.0 + c0[3, i, a]) + c0[2, i, a] * h) + c0[1, i, a] * hh) + c0[0, i, a] * (hh * h)
            d1[k, a] = ((0.0 + c1[2, i, a]) + c1[1, i, a] * h) + c1[0, i, a] * hh
            d2[k, a] = (0.0 + c2[1, i, a]) + c2[0, i, a] * h


@njit(cache=True, nogil=True, error_model="numpy")
def dense_samples(
    breaks, c0, c1, c2, grid, sd, sdd, dt, rows, frac, grid_slope, earlier, same_as, out, fresh, q_fresh, d1_fresh
):
    """A dense check's samples over the grid intervals ``rows`` of one path (``timing.path._dense_samples_numpy``):
    per interval k, ``m = len(frac)`` points evenly in time from s0 = grid[k] at speed sd[k], accelerating at
    sdd[k] for dt[k], the positions clipped to [s0, grid[k + 1]] (numpy's ``clip``); into ``out`` = (s, v,
    d1, d2, slope), row r's samples at r m to r m + m - 1: the position s, the speed sd, q'(s), q''(s), and
    the tip's |p'(s)| where it is known, NaN elsewhere. It is known where the sample is a grid point (the
    first sample at s0, the last at s1: ``grid_slope`` there) and where an earlier check of the same timing
    took the same sample (``same_as[t]``: the column of sample t in that check's |p'(s)| ``earlier`` (intervals,
    its samples), -1 for none: the same time fraction, so the same position). The other samples ("fresh":
    their |p'(s)| is to be found) are listed in ``fresh``, with q(s) and q'(s) in ``q_fresh`` and
    ``d1_fresh``; returns how many."""
    s_out, v_out, d1_out, d2_out, slope_out = out
    m = len(frac)
    dof = d1_out.shape[1]
    n = 0
    i = 0
    for r in range(len(rows)):
        k = rows[r]
        s0, s1, sd0, acc, span = grid[k], grid[k + 1], sd[k], sdd[k], dt[k]
        half = 0.5 * acc
        for t in range(m):
            j = r * m + t
            tau = span * frac[t]
            x = (s0 + sd0 * tau) + half * (tau * tau)
            if x == x:  # numpy's clip: the larger of x and s0, then the smaller of that and s1 (NaN kept)
                x = x if x > s0 else s0
                x = x if x < s1 else s1
            s_out[j] = x
            v_out[j] = sd0 + acc * tau
            i = _interval(breaks, x, i)
            if i < 0:
                d1_out[j] = np.nan
                d2_out[j] = np.nan
                i = 0
                known = -1
            else:
                h = x - breaks[i]
                hh = h * h
                for a in range(dof):
                    d1_out[j, a] = ((0.0 + c1[2, i, a]) + c1[1, i, a] * h) + c1[0, i, a] * hh
                    d2_out[j, a] = (0.0 + c2[1, i, a]) + c2[0, i, a] * h
                known = -1
                if t == 0 and x == s0:
                    known = k
                elif t == m - 1 and m > 1 and x == s1:
                    known = k + 1
            if known >= 0:
                slope_out[j] = grid_slope[known]
                continue
            if same_as[t] >= 0:
                slope_out[j] = earlier[k, same_as[t]]
                continue
            slope_out[j] = np.nan
            fresh[n] = j
            if x != x:
                q_fresh[n] = np.nan
            else:
                h = x - breaks[i]
                hh = h * h
                for a in range(dof):
                    q_fresh[n, a] = (((0.0 + c0[3, i, a]) + c0[2, i, a] * h) + c0[1, i, a] * hh) + c0[0, i, a] * (
                        hh * h
                    )
            for a in range(dof):
                d1_fresh[n, a] = d1_out[j, a]
            n += 1
    return n


@njit(cache=True, nogil=True, inline="always")
def _interval(breaks, x, hint):
    """The interval of x (scipy's ``find_interval``, extrapolating): -1 for NaN; ``hint``: where to look first
    (the interval of the sample before)."""
    last = len(breaks) - 2
    if x != x:
        return -1
    if x >= breaks[last + 1]:
        return last
    if x < breaks[0]:
        return 0
    if 0 <= hint <= last and breaks[hint] <= x < breaks[hint + 1]:
        return hint
    low, high = 0, last
    while low < high:  # the largest i with breaks[i] <= x
        mid = (low + high + 1) // 2
        if breaks[mid] <= x:
            low = mid
        else:
            high = mid - 1
    return low


@njit(cache=True, nogil=True, error_model="numpy")
def dense_ratios(d1, d2, v, sdd, slope, v_max, a_max, cap, m, rv, ra, rc):
    """the numpy form in tests/test_timing_speed.py (``_dense_ratios_numpy``): per grid interval i (samples i m to i m + m - 1), the largest ratio
    of joint speed |q' sd|, joint acceleration |q' sdd + q'' sd^2| and tip speed |p'| |sd| to its limit
    (``rv``, ``ra``, ``rc``; NaN if any ratio is, as numpy's ``max``), each interior local peak raised to its
    parabola's top (``_peaks``; a sample that is no peak is no larger than the largest one)."""
    dof = d1.shape[1]
    vel = np.empty((m, dof))
    acc = np.empty((m, dof))
    tip = np.empty((m, 1))
    for i in range(len(sdd)):
        top_v = top_a = top_c = -np.inf
        nan = False
        for t in range(m):
            k = i * m + t
            sd = v[k]
            sd2 = sd * sd
            for a in range(dof):
                x = abs(d1[k, a] * sd) / v_max[a]
                y = abs(d1[k, a] * sdd[i] + d2[k, a] * sd2) / a_max[a]
                vel[t, a] = x
                acc[t, a] = y
                top_v = x if x > top_v else top_v
                top_a = y if y > top_a else top_a
                nan |= (x != x) | (y != y)
            z = slope[k] * abs(sd) / cap[i]
            tip[t, 0] = z
            top_c = z if z > top_c else top_c
            nan |= z != z
        if nan:
            top_v, top_a, top_c = _largest(vel), _largest(acc), _largest(tip)
        rv[i] = _raised(vel, top_v)
        ra[i] = _raised(acc, top_a)
        rc[i] = _raised(tip, top_c)


@njit(cache=True, nogil=True, inline="always")
def _largest(r):
    """The largest of the samples ``r`` (m, a), NaN if any is (numpy's ``max``)."""
    out = r[0, 0]
    for t in range(r.shape[0]):
        for a in range(r.shape[1]):
            value = r[t, a]
            if value > out or value != value:
                out = value
    return out


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _raised(r, out):
    """``out`` (the largest of the samples ``r`` (m, a)) raised to the top of the parabola through each interior
    local peak along m and its two neighbours (the tests' ``_peaks`` of one interval)."""
    m, axes = r.shape
    for t in range(1, m - 1):
        for a in range(axes):
            mid = r[t, a]
            left = r[t - 1, a]
            right = r[t + 1, a]
            if mid >= left and mid >= right:
                bend = 2.0 * mid - left - right
                if bend > 0.0:
                    top = mid + (right - left) * (right - left) / (8.0 * bend)
                    if top > out or top != top:
                        out = top
    return out
