"""The timing stage's compiled loops and its reuse of work give the numbers of the straightforward forms they
replaced, bit for bit (the timing stage's speed work: the same plans).

- ``timing.kernels.reach_all`` (through ``reach_paths``) against the numpy form of the reachability analysis
  that ran the paths in lockstep (kept here: :func:`reach_paths_numpy`), on the reach part's problems and on
  random ones (feasible, infeasible, with unbounded speeds);
- ``kernels.spline_values`` against scipy's evaluation of the toppra spline, its two derivatives included, at
  random points, at the knots and beyond the ends;
- ``kernels.dense_samples`` and ``kernels.dense_ratios`` against their numpy forms in ``timing.path``;
- ``time_paths`` as a whole against the same computation without the compiled loops and without the reuse
  of earlier evaluations, and against each stretch timed alone.
"""

from __future__ import annotations

import numpy as np
import pytest
import toppra

from sprayplan.timing import path as timing_path
from sprayplan.timing.kernels import dense_samples, spline_values
from sprayplan.timing.reach import MAX_TRIES, ROW_TOL, SMALL, TINY, VAR_MAX, reach_paths
from tests.helpers import reach_part_timing


def _same(a, b) -> bool:
    """The same float arrays bit for bit (NaNs at the same places, and the signs of zeros)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    return a.shape == b.shape and np.array_equal(a, b, equal_nan=True) and np.array_equal(np.signbit(a), np.signbit(b))


@pytest.fixture(scope="module")
def reach(testdata):
    """The reach part planned to the kinematics stage: its gantry, timing limits and stretches."""
    return reach_part_timing(testdata)


def _problems(gantry, limits, stretches):
    """Each stretch's first reachability problem (grid, q'(s), q''(s), sd^2 bound), as time_paths sets it."""
    slopes = timing_path._slope_function(gantry.gun_tip, gantry.gun_tip)
    out = []
    for q, cap in stretches:
        st = timing_path._Stroke(q, cap, limits, gantry.gun_tip, None)
        d1, d2 = st.path(st.grid, 1), st.path(st.grid, 2)
        x_max, _ = timing_path._bounds(d1, slopes([(st.path, st.grid, d1)])[0], st.grid, st.s_way, st.cap, limits)
        out.append((st.grid, d1, d2, x_max))
    return out


def _random_problems(rng, count, dof):
    """Reachability problems of random paths: smooth q'(s) and q''(s) of random size, bounds of sd^2 finite and
    infinite; some feasible, some not."""
    out = []
    for _ in range(count):
        n = int(rng.integers(2, 60))
        grid = np.concatenate([[0.0], np.cumsum(rng.uniform(1e-4, 0.2, n - 1))])
        phase = rng.uniform(0.0, 6.0, dof)
        d1 = np.sin(grid[:, None] * rng.uniform(0.5, 8.0, dof) + phase) * rng.uniform(0.0, 3.0, dof)
        d2 = np.cos(grid[:, None] * rng.uniform(0.5, 8.0, dof) + phase) * rng.uniform(0.0, 30.0, dof)
        d1[:, rng.integers(0, dof)] = 0.0  # an axis that does not move
        x_max = rng.uniform(0.05, 4.0, n)
        x_max[rng.random(n) < 0.3] = np.inf
        out.append((grid, d1, d2, x_max))
    return out


def test_reachability_kernel_is_the_numpy_form(reach):
    """The compiled analysis gives the lockstep numpy form's sd, bit for bit, or None where it gives None: on
    every first problem of the reach part and on random problems, batched as time_paths batches them."""
    gantry, limits, stretches = reach
    problems = _problems(gantry, limits, stretches)
    rng = np.random.default_rng(11)
    cases = [(problems, limits.acceleration)]
    for dof in (2, 6, 9):
        a_max = rng.uniform(0.5, 20.0, dof)
        cases.append((_random_problems(rng, 40, dof), a_max))
    cases.append((_random_problems(rng, 10, 3), np.array([-1.0, 1.0, 1.0])))  # no (u, x) meets the rows
    failed = solved = 0
    for items, a_max in cases:
        new = reach_paths(items, a_max)
        old = reach_paths_numpy(items, a_max)
        for a, b in zip(new, old):
            assert (a is None) == (b is None)
            if a is None:
                failed += 1
            else:
                solved += 1
                assert _same(a, b)
    assert failed and solved  # both kinds were compared


def test_spline_kernel_is_scipys_evaluation():
    """q(s), q'(s), q''(s) of toppra's spline from the kernel are scipy's values bit for bit: at random points,
    at every knot, at the ends and beyond them (the end polynomials extended), and NaN at NaN."""
    rng = np.random.default_rng(5)
    for n in (2, 3, 4, 17, 120):
        knots = np.concatenate([[0.0], np.cumsum(rng.uniform(1e-5, 0.3, n - 1))])
        path = toppra.SplineInterpolator(knots, rng.normal(size=(n, 9)).cumsum(axis=0))
        parts = timing_path._spline_parts(path)
        assert parts is not None
        s = np.concatenate(
            [np.sort(rng.uniform(knots[0], knots[-1], 500)), knots, rng.uniform(-1.0, knots[-1] + 1.0, 50), [np.nan]]
        )
        q, d1, d2 = (np.empty((len(s), 9)) for _ in range(3))
        spline_values(*parts, s, q, d1, d2)
        for order, values in enumerate((q, d1, d2)):
            assert _same(values, path(s, order))


def _timed_stroke(rng, n_way=12, dof=9):
    """A stroke with a random timing on its grid (``sd``, ``sdd``, ``dt`` as time_paths sets them, at rest at
    both ends) and random |p'(s)| at its grid points, for the dense check's samples."""
    q = rng.normal(size=(n_way, dof)).cumsum(axis=0)
    cap = np.full(n_way - 1, 300.0)
    limits = timing_path.AxisLimits(np.full(dof, 2.0), np.full(dof, 10.0))
    st = timing_path._Stroke(q, cap, limits, lambda x: x[:, :3] * 100.0, None)
    st.grid_slope = rng.uniform(10.0, 500.0, len(st.grid))
    sd = rng.uniform(0.05, 1.5, len(st.grid))
    sd[0] = sd[-1] = 0.0
    sd[2::7] = 0.0  # at rest inside too
    ds = np.diff(st.grid)
    st.sd = sd
    st.dt = 2.0 * ds / np.maximum(sd[:-1] + sd[1:], 1e-300)
    st.sdd = (sd[1:] ** 2 - sd[:-1] ** 2) / (2.0 * ds)
    st.done = False
    return st


@pytest.mark.parametrize("steps", [0, 1, 2, 4, 32, 7])
def test_dense_samples_kernel_is_the_numpy_form(steps):
    """The kernel's samples (positions, speeds, q'(s), q''(s)), the grid points it recognises and q(s) at the
    others are the numpy form's and the spline's, bit for bit, over all intervals and over a subset."""
    rng = np.random.default_rng(steps)
    frac = np.linspace(0.0, 1.0, steps + 1)
    st = _timed_stroke(rng)
    m, dof = len(frac), 9
    for rows in (np.arange(len(st.grid) - 1), np.flatnonzero(rng.random(len(st.grid) - 1) < 0.4)):
        total = len(rows) * m
        out = (np.empty(total), np.empty(total), np.empty((total, dof)), np.empty((total, dof)), np.empty(total))
        fresh, q_fresh, d1_fresh = np.empty(total, np.int64), np.empty((total, dof)), np.empty((total, dof))
        none = (np.empty((1, 1)), np.full(m, -1, np.int64))
        count = dense_samples(
            *st.spline, st.grid, st.sd, st.sdd, st.dt, rows, frac, st.grid_slope, *none, out, fresh, q_fresh, d1_fresh
        )
        s, v, d1, d2, known = timing_path._dense_samples_numpy(st, rows, frac)
        for a, b in zip(out[:4], (s, v, d1, d2)):
            assert _same(a, b)
        assert np.array_equal(fresh[:count], np.flatnonzero(known < 0))
        assert _same(out[4], np.where(known >= 0, st.grid_slope[known], np.nan))
        assert _same(q_fresh[:count], st.path(s[known < 0]))
        assert _same(d1_fresh[:count], d1[known < 0])
        assert (known[::m] >= 0).all()  # every first sample is its interval's first grid point


def _ratio_inputs(rng, k, m, dof):
    """Samples for the ratios: smooth in time (peaks inside the intervals), with plateaus, zeros and ties."""
    t = np.linspace(0.0, 1.0, m)
    shape = (k, m, dof)
    d1 = np.sin(rng.uniform(0.5, 6.0, (k, 1, dof)) * t[None, :, None] + rng.uniform(0.0, 6.0, (k, 1, dof)))
    d2 = np.cos(rng.uniform(0.5, 6.0, (k, 1, dof)) * t[None, :, None] + rng.uniform(0.0, 6.0, (k, 1, dof))) * 5.0
    d1 = np.broadcast_to(d1, shape).copy()
    d2 = np.broadcast_to(d2, shape).copy()
    d1[:, :, 0] = 0.0  # an axis that does not move
    d1[::5] = np.round(d1[::5], 1)  # plateaus: equal neighbours
    v = (np.sin(np.pi * t)[None, :] * rng.uniform(0.0, 2.0, (k, 1))).reshape(-1)
    slope = rng.uniform(50.0, 500.0, k * m)
    sdd = rng.normal(size=k) * 3.0
    cap = rng.uniform(100.0, 400.0, k)
    return d1.reshape(-1, dof), d2.reshape(-1, dof), v, sdd, slope, cap


@pytest.mark.parametrize("m", [1, 2, 3, 5, 33])
def test_dense_ratios_kernel_is_the_numpy_form(m):
    """The compiled ratios (the largest per interval, each local peak raised to its parabola's top) are the
    numpy form's bit for bit, NaN where a sample's ratio is NaN."""
    rng = np.random.default_rng(m)
    dof = 9
    limits = timing_path.AxisLimits(rng.uniform(0.5, 3.0, dof), rng.uniform(2.0, 20.0, dof))
    d1, d2, v, sdd, slope, cap = _ratio_inputs(rng, 300, m, dof)
    slope[7 * m] = np.nan  # a NaN in interval 7
    d2[11 * m + m // 2, 3] = np.nan  # and in interval 11
    new = timing_path._dense_ratios(d1, d2, v, sdd, slope, m, limits, cap)
    old = _dense_ratios_numpy(d1, d2, v, sdd, slope, m, limits, cap)
    for a, b in zip(new, old):
        assert _same(a, b)
    assert np.isnan(new[2][7]) and np.isnan(new[1][11]) and not np.isnan(new[0]).any()
    if m >= 5:  # some peak was raised above every sample
        r = np.abs(d1 * v[:, None]) / limits.velocity
        assert (new[0] > r.reshape(300, -1).max(axis=1)).any()


def _key(timings):
    return [
        (t.t_s, t.speed_mm_s, t.duration_s, t.rounds, t.stretch, tuple(t.worst.values()), t.grid_s, t.grid_t, t.grid_sd)
        for t in timings
    ]


def _assert_same_timings(a, b):
    for x, y in zip(_key(a), _key(b), strict=True):
        for u, v in zip(x, y, strict=True):
            assert _same(u, v)


def test_time_paths_without_the_kernels_and_the_reuse_is_the_same(reach, monkeypatch):
    """time_paths with the compiled spline and samples and the reuse of earlier |p'(s)| gives the timing it gives
    on scipy's spline evaluation and the numpy samples, every |p'(s)| found again (bit for bit), with exact
    tip speeds and with central differences, under tight limits (more rounds) too."""
    gantry, limits, stretches = reach
    tight = timing_path.AxisLimits(limits.velocity * 0.3, limits.acceleration * 0.2)
    cases = [
        (stretches, limits, gantry.gun_tip, {"tip_rate": gantry.gun_tip}),
        (stretches, tight, gantry.gun_tip, {"tip_rate": gantry.gun_tip, "max_rounds": 4, "check_steps": 3}),
        (stretches[:12], limits, lambda q: gantry.gun2world(q)[:, :3, 3], {}),
    ]
    fast = [timing_path.time_paths(paths, lim, tip, **kw) for paths, lim, tip, kw in cases]
    assert sum(t.rounds for t in fast[1]) > sum(t.rounds for t in fast[0])  # the tight case refines more
    monkeypatch.setattr(timing_path, "_spline_parts", lambda path: None)
    monkeypatch.setattr(timing_path, "_earlier_slopes", lambda st, frac: (np.empty((1, 1)), np.full(len(frac), -1)))
    plain = [timing_path.time_paths(paths, lim, tip, **kw) for paths, lim, tip, kw in cases]
    for a, b in zip(fast, plain):
        _assert_same_timings(a, b)


def test_time_paths_together_are_each_alone(reach):
    """Timed together (one forward-kinematics call for all waypoints, shared groups and batches), every stretch
    gets the timing it gets alone, bit for bit."""
    gantry, limits, stretches = reach
    together = timing_path.time_paths(stretches, limits, gantry.gun_tip, tip_rate=gantry.gun_tip)
    alone = [timing_path.time_path(q, cap, limits, gantry.gun_tip, tip_rate=gantry.gun_tip) for q, cap in stretches]
    _assert_same_timings(together, alone)


# The reachability analysis as it was in numpy (timing/reach.py before its loops were compiled): the reference
# the kernel must equal.


def reach_paths_numpy(items, a_max: np.ndarray) -> list:
    """``timing.reach.reach_paths`` as it was in numpy: the paths in lockstep, stage i of all of them at once."""
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


def _dense_ratios_numpy(d1, d2, v, sdd, slope, m: int, limits, cap_interval):
    """``timing.path._dense_ratios`` in numpy: the straightforward form the compiled one must equal."""
    speed = v[:, None]
    vel = d1 * speed
    acc = d1 * np.repeat(sdd, m)[:, None] + d2 * speed**2
    shape = (len(sdd), m, -1)
    rv = _peaks((np.abs(vel) / limits.velocity).reshape(shape))
    ra = _peaks((np.abs(acc) / limits.acceleration).reshape(shape))
    tip_speed = slope * np.abs(v)
    rc = _peaks((tip_speed.reshape(len(sdd), -1) / cap_interval[:, None])[:, :, None])
    return rv, ra, rc


def _peaks(r: np.ndarray) -> np.ndarray:
    """(k,) the largest value of each interval's samples ``r`` (k, m, a) (m samples evenly in time, a axes),
    each interior local maximum raised to the top of the parabola through it and its neighbours."""
    out = r.max(axis=(1, 2))
    if r.shape[1] >= 3:
        left, mid, right = r[:, :-2], r[:, 1:-1], r[:, 2:]
        bend = 2.0 * mid - left - right
        peak = (mid >= left) & (mid >= right) & (bend > 0)
        top = mid + np.where(peak, (right - left) ** 2 / (8.0 * np.where(peak, bend, 1.0)), 0.0)
        out = np.maximum(out, top.max(axis=(1, 2)))
    return out
