"""Joint-interpolated motions proven free in bulk (the proof :func:`sprayplan.collision.repair.flag_motions`
and the transfer routes of :mod:`sprayplan.collision.transfers` share).

Between two configurations whose least slacks are ``S_a`` and ``S_b`` (distance minus the pair's gap, over
every pair) and whose joint motion moves no body point more than ``B`` (:mod:`sprayplan.collision.motion`),
every configuration in between keeps a slack of at least ``(S_a + S_b - B) / 2``: each distance is
1-Lipschitz in the bodies' displacement, at most ``B s`` from one end and ``B (1 - s)`` from the other. Where
that is not negative the motion is free; the others are bisected, then checked on a fixed grid.
"""

from __future__ import annotations

import numpy as np

from sprayplan.collision.motion import motion_bound_mm

#: The margin over their gaps within which pairs are measured exactly for the motions' proof, mm: slacks are
#: known up to about this, and a motion moving bodies less than twice it is proven free at once.
MOTION_MARGIN_MM = 100.0
#: Bisections of the motions not proven at once, before the rest are walked on a grid.
BISECTIONS = 4
#: When the grid of every motion still open has at most this many configurations, it is checked at once instead
#: of bisected further: a check costs about as much for one configuration as for a few dozen (docs/benchmarks.md,
#: "Transfers re-routed").
GRID_AT_ONCE = 64


def end_slacks(cell, q9) -> np.ndarray:
    """(n,) mm: the least slack of each configuration, exact within :data:`MOTION_MARGIN_MM` of its gap (a
    lower bound beyond), as the proof needs it."""
    return cell.check(np.asarray(q9, dtype=float), margin_mm=MOTION_MARGIN_MM).slack_mm


def motion_hits(cell, q_a, q_b, slack_a=None, slack_b=None) -> np.ndarray:
    """(m,) bool: which of the joint-interpolated motions ``q_a[i] -> q_b[i]`` (each (m, 9)) are in collision.

    A motion is proven free when ``(S_a + S_b - B) / 2 >= 0``; the rest are split at their middle (the halves'
    bounds are ``B / 2``) up to :data:`BISECTIONS` times (or until the grid below would have at most
    :data:`GRID_AT_ONCE` configurations), all midpoints of a level checked in one call; what is still unproven
    is checked on a grid of ``ceil(B / motion_step_mm)`` steps (``collision.motion``'s fixed
    grid: a configuration between two checks is within half a step of one, so each check must keep half a
    step over its gaps), all in one call. A motion free by this keeps every pair at or above its gap
    everywhere. An end in collision makes the motion in collision. ``slack_a``, ``slack_b``: the ends'
    slacks from :func:`end_slacks`, when known.
    """
    q_a = np.atleast_2d(np.asarray(q_a, dtype=float))
    q_b = np.atleast_2d(np.asarray(q_b, dtype=float))
    m = len(q_a)
    if m == 0:
        return np.zeros(0, bool)
    slack_a = end_slacks(cell, q_a) if slack_a is None else np.asarray(slack_a, dtype=float)
    slack_b = end_slacks(cell, q_b) if slack_b is None else np.asarray(slack_b, dtype=float)
    hits = (slack_a < 0) | (slack_b < 0)
    index = np.flatnonzero(~hits)
    s0, s1 = np.zeros(len(index)), np.ones(len(index))
    a_slack, b_slack = slack_a[index], slack_b[index]
    total = motion_bound_mm(q_a[index], q_b[index], cell.reach_radii_mm) if len(index) else np.zeros(0)
    open_ = np.zeros(len(index), bool)
    step = cell.config.motion_step_mm
    for level in range(BISECTIONS + 1):
        bound = total * (s1 - s0)
        open_ = (a_slack + b_slack - bound) / 2.0 < 0
        if not open_.any() or level == BISECTIONS:
            break
        if np.maximum(1, np.ceil(bound[open_] / step - 1e-12)).sum() + open_.sum() <= GRID_AT_ONCE:
            break
        index, s0, s1, a_slack, b_slack, total = (v[open_] for v in (index, s0, s1, a_slack, b_slack, total))
        mid = (s0 + s1) / 2.0
        q_mid = q_a[index] + mid[:, None] * (q_b[index] - q_a[index])
        mid_slack = end_slacks(cell, q_mid)
        index = np.concatenate([index, index])
        s0, s1 = np.concatenate([s0, mid]), np.concatenate([mid, s1])
        a_slack, b_slack = np.concatenate([a_slack, mid_slack]), np.concatenate([mid_slack, b_slack])
        total = np.concatenate([total, total])
    # what is still open: every piece checked on a grid at most motion_step_mm of bound apart, all at once,
    # each check against its gaps plus half a step (every configuration between is within half a step of one)
    index, s0, s1, total = index[open_], s0[open_], s1[open_], total[open_]
    counts = np.maximum(1, np.ceil(total * (s1 - s0) / step - 1e-12)).astype(int)
    owner = np.repeat(np.arange(len(index)), counts + 1)
    within = np.arange(len(owner)) - np.repeat(np.cumsum(counts + 1) - (counts + 1), counts + 1)
    s = s0[owner] + (s1 - s0)[owner] * within / counts[owner]
    k = index[owner]
    if len(k):
        grid = q_a[k] + s[:, None] * (q_b[k] - q_a[k])
        hits[np.unique(k[cell.collides(grid, extra_mm=step / 2.0)])] = True
    return hits
