"""The timing stage's batched reachability analysis and exact tip speeds give the timing toppra and finite
differences gave (issue 17: the same plans), with the limits still holding between grid points."""

from __future__ import annotations

import numpy as np
import pytest
import toppra
from toppra.constraint import JointAccelerationConstraint

from sprayplan.robots.gantry import Gantry
from sprayplan.timing import path as timing_path
from sprayplan.timing.limits import AxisLimits
from sprayplan.timing.reach import reach_paths
from tests.helpers import reach_part_timing

#: The relative agreement of time stamps asked of the batched analysis against toppra (issue 17's "the same
#: plans"): both solve the same LPs, toppra's seidel solver to a row tolerance of 1e-10, this one exactly; on
#: the demo roof the two differ by at most 3e-11 relative (docs/benchmarks.md).
SAME_TIME = 1e-6
#: Tip speeds: the old code took |p'(s)| by central differences over h = 1e-7 of s, good to about 1e-8 of
#: the speed (rounding of positions of ~1e3 mm over 2h); the new code differentiates the chain exactly.
SAME_SPEED = 1e-6


@pytest.fixture(scope="module")
def reach(testdata):
    """The reach part planned to the kinematics stage, its timing limits and every stretch the timing times."""
    return reach_part_timing(testdata)


def _tip(gantry):
    return lambda q: gantry.gun2world(q)[:, :3, 3]


def _toppra_sd(path, grid, x_max, limits):
    """The old computation: toppra's TOPPRA (seidel) with the speed bound and its joint acceleration
    constraint, rest to rest."""

    class Bound(toppra.constraint.LinearConstraint):
        def compute_constraint_params(self, path, gridpoints, *args, **kwargs):
            return None, None, None, None, None, None, np.column_stack([np.zeros(len(gridpoints)), x_max])

    constraints = [Bound(), JointAccelerationConstraint(limits.acceleration)]
    algorithm = toppra.algorithm.TOPPRA(constraints, path, gridpoints=grid, solver_wrapper="seidel")
    return algorithm.compute_parameterization(0.0, 0.0, return_data=True)[1]


def _problems(gantry, limits, stretches):
    """Each stretch's first toppra problem: its path, grid, derivatives and sd^2 bound (as time_paths sets it)."""
    slopes = timing_path._slope_function(_tip(gantry), gantry.gun_tip)
    out = []
    for q, cap in stretches:
        st = timing_path._Stroke(q, cap, limits, _tip(gantry), None)
        d1 = st.path(st.grid, 1)
        x_max, _ = timing_path._bounds(d1, slopes([(st.path, st.grid, d1)])[0], st.grid, st.s_way, st.cap, limits)
        out.append((st.path, st.grid, d1, st.path(st.grid, 2), x_max))
    return out


def _times(grid, sd):
    ds = np.diff(grid)
    return np.concatenate([[0.0], np.cumsum(2.0 * ds / np.maximum(sd[:-1] + sd[1:], 1e-300))])


def test_batched_reachability_is_toppras(reach):
    """On every stretch of the reach part, the batched analysis gives toppra's time stamps at the grid points
    (all stretches in one batch, of different lengths), and a batch of one gives the same as the whole batch."""
    gantry, limits, stretches = reach
    problems = _problems(gantry, limits, stretches)
    batched = reach_paths([(g, d1, d2, x) for _, g, d1, d2, x in problems], limits.acceleration)
    assert len({len(p[1]) for p in problems}) > 3  # lengths differ: the lockstep's prefixes are exercised
    for (path, grid, _, _, x_max), sd in zip(problems, batched):
        assert sd is not None
        old = _toppra_sd(path, grid, x_max, limits)
        t_new, t_old = _times(grid, sd), _times(grid, np.maximum(old, 0.0))
        np.testing.assert_allclose(t_new, t_old, rtol=SAME_TIME, atol=SAME_TIME * t_old[-1])
        # sd^2 within its bound everywhere, at rest at both ends
        assert (sd**2 <= np.minimum(x_max, 1e8) * (1 + 1e-12)).all()
        assert sd[0] == 0.0 and sd[-1] == 0.0
    for k in (0, len(problems) // 2, len(problems) - 1):
        _, g, d1, d2, x = problems[k]
        alone = reach_paths([(g, d1, d2, x)], limits.acceleration)[0]
        np.testing.assert_allclose(alone, batched[k], rtol=1e-12, atol=1e-15)


def test_batched_reachability_holds_the_acceleration_limits_at_the_grid_points(reach):
    """toppra's constraints at each grid interval (both ends' accelerations under the interval's constant sdd)
    hold on the batched answer, to what toppra's own forward pass allows (it steps x back by 1e-8 at every grid
    point, which moves an interval's sdd: about 2e-6 of the limit on these strokes, toppra's answer and this one
    alike)."""
    gantry, limits, stretches = reach
    for _, grid, d1, d2, x_max in _problems(gantry, limits, stretches[:8]):
        sd = reach_paths([(grid, d1, d2, x_max)], limits.acceleration)[0]
        x = sd**2
        u = np.diff(x) / (2.0 * np.diff(grid))
        for end in (slice(None, -1), slice(1, None)):
            acc = d1[end] * u[:, None] + d2[end] * x[end][:, None]
            assert (np.abs(acc) <= limits.acceleration * (1 + 1e-5)).all()


def test_an_empty_stage_is_left_to_toppra():
    """Rows no (u, x) meets (a negative acceleration bound): no answer, so the caller asks toppra."""
    grid = np.linspace(0.0, 1.0, 5)
    d1 = np.ones((5, 2))
    assert reach_paths([(grid, d1, np.zeros((5, 2)), np.full(5, np.inf))], np.array([-1.0, 1.0])) == [None]


def test_tip_and_its_rate_are_the_forward_kinematics():
    """``Gantry.gun_tip`` is gun2world's translation, and its rate the derivative along the joint rates (against
    central differences of gun2world, whose own error is about 1e-6 mm at this step)."""
    gantry = Gantry()
    rng = np.random.default_rng(7)
    q = np.column_stack([rng.uniform(-3.0, 3.0, (500, 6)), rng.uniform(-2000.0, 2000.0, (500, 3))])
    dq = rng.normal(size=q.shape)
    position, rate = gantry.gun_tip(q, dq)
    np.testing.assert_allclose(position, gantry.gun2world(q)[:, :3, 3], rtol=0, atol=1e-9)
    np.testing.assert_allclose(gantry.gun_tip(q), position, rtol=0, atol=0)
    h = 1e-6
    numeric = (gantry.gun2world(q + h * dq)[:, :3, 3] - gantry.gun2world(q - h * dq)[:, :3, 3]) / (2 * h)
    np.testing.assert_allclose(rate, numeric, rtol=0, atol=1e-5)


def test_time_paths_give_the_old_timing(reach, monkeypatch):
    """All stretches timed together (batched analysis, exact tip speeds) give the time stamps, tip speeds,
    rounds and stretches of the old computation: each stretch alone, toppra, finite differences."""
    gantry, limits, stretches = reach
    new = timing_path.time_paths(stretches, limits, gantry.gun_tip, tip_rate=gantry.gun_tip)

    def toppra_each(items, a_max):
        assert np.array_equal(a_max, limits.acceleration)
        return [None] * len(items)  # every stretch to toppra (time_paths' fallback is toppra itself)

    monkeypatch.setattr(timing_path, "reach_paths", toppra_each)
    old = [timing_path.time_path(q, cap, limits, _tip(gantry)) for q, cap in stretches]
    assert sum(t.rounds for t in old) > 0
    for a, b in zip(new, old):
        assert a.rounds == b.rounds
        assert len(a.grid_s) == len(b.grid_s)
        np.testing.assert_allclose(a.t_s, b.t_s, rtol=SAME_TIME, atol=SAME_TIME * b.duration_s)
        assert a.duration_s == pytest.approx(b.duration_s, rel=SAME_TIME)
        assert a.stretch == pytest.approx(b.stretch, rel=SAME_TIME)
        np.testing.assert_allclose(a.speed_mm_s, b.speed_mm_s, rtol=SAME_SPEED, atol=SAME_SPEED * b.speed_mm_s.max())


def test_dense_checks_in_groups_change_nothing(reach, monkeypatch):
    """The dense checks' samples taken a group of strokes at a time (bounded memory) give the same timing as all
    at once: here every stroke in a group of its own against the default groups."""
    gantry, limits, stretches = reach
    together = timing_path.time_paths(stretches, limits, gantry.gun_tip, tip_rate=gantry.gun_tip)
    monkeypatch.setattr(timing_path, "CHECK_BATCH", 1)
    alone = timing_path.time_paths(stretches, limits, gantry.gun_tip, tip_rate=gantry.gun_tip)
    for a, b in zip(alone, together):
        np.testing.assert_array_equal(a.t_s, b.t_s)
        np.testing.assert_array_equal(a.speed_mm_s, b.speed_mm_s)
        assert a.worst == b.worst


def test_limits_hold_on_the_resampled_batched_timing(reach):
    """The batched timing resampled 20000 times per stretch and differentiated numerically: every axis within its
    speed and acceleration limits, the tip within its planned speed (the dense check is as strict as before)."""
    gantry, limits, stretches = reach
    tip = _tip(gantry)
    fd_slack = 2e-3  # the finite differences' own error over steps of 1/20000 of a stretch (test_timing.py's)
    for timed, (_, cap) in zip(timing_path.time_paths(stretches[:8], limits, tip, tip_rate=gantry.gun_tip), stretches):
        assert max(timed.worst.values()) <= 1.0 + 1e-9
        t = np.linspace(0.0, timed.duration_s, 20001)
        qs, _, _ = timed.sample(t)
        dt = t[1] - t[0]
        assert (np.abs(np.diff(qs, axis=0)) / dt / limits.velocity).max() <= 1.0 + fd_slack
        assert (np.abs(np.diff(qs, 2, axis=0)) / dt**2 / limits.acceleration).max() <= 1.0 + fd_slack
        seg = np.clip(np.searchsorted(timed.t_s, 0.5 * (t[1:] + t[:-1]), side="right") - 1, 0, len(cap) - 1)
        v_tip = np.linalg.norm(np.diff(tip(qs), axis=0), axis=1) / dt
        assert (v_tip / cap[seg]).max() <= 1.0 + fd_slack


def test_loose_limits_reach_the_planned_speed():
    """A straight gantry stroke with limits far beyond it (toppra's u bound of 1e8 in play): length / speed."""
    gantry = Gantry()
    x = np.linspace(0.0, 500.0, 51)
    from sprayplan.robots.stage import HOME_JOINTS

    q = np.column_stack([np.tile(HOME_JOINTS, (51, 1)), x, np.zeros(51), np.full(51, 1500.0)])
    loose = AxisLimits(np.full(9, 1e6), np.full(9, 1e9))
    timed = timing_path.time_paths([(q, np.full(50, 400.0))], loose, gantry.gun_tip, tip_rate=gantry.gun_tip)[0]
    assert timed.duration_s == pytest.approx(500.0 / 400.0, rel=1e-5)
    np.testing.assert_allclose(timed.speed_mm_s[1:-1], 400.0, rtol=1e-5)
