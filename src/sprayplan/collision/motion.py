"""The motion between two waypoints, discretised so that no collision between two checks can be missed.

The arm moves between waypoints by joint interpolation ``q(s) = q_a + s (q_b - q_a)``, s in [0, 1]. Joint ``i``
turns every body it carries about its axis; a point at most ``R_i`` from that axis moves at most
``R_i |dq_i|`` while the joint turns by ``dq_i``, and the gantry moves every body by ``|dt|``. So no point of any
body moves more than

    bound(dq) = sum_i R_i |dq_i| + |dt|          (R_i from ``bodies.reach_radii_mm``, whatever the joints)

between two joint vectors ``dq`` apart. Distances are 1-Lipschitz in the bodies' displacement.

Fixed grid (:func:`motion_checks`): ``k = ceil(bound / step)`` equal joint steps, so consecutive checks are at
most ``step`` apart for every body point and every configuration in between is within ``step / 2`` of one of
them: a distance there is at most ``step / 2`` below the smaller of its two checked values.

Conservative advancement (``CellCollision.check_motion``, what the checks use): from a check whose least slack
over all pairs is ``S >= 0`` (slack: distance minus ``max(gap, step / 2)``, ``gap`` the pair's required gap),
the next check is ``max(step, S + step / 2)`` of bound further on. Where that is ``step`` the grid's argument
holds (both ends are checked); where it is longer, every distance in between is at least its value at the
check minus the displacement, ``>= max(gap, step / 2) + S - (S + step / 2)``. Either way a motion whose checks
all have ``S >= 0`` never touches anything in between and never comes closer to the part than
``clearance - step / 2``. The TCP against the floor is the same (the TCP is a body point; its reach is in
``R_i``). Far from everything the checks are far apart; near the part, ``step`` apart.

This is the linear joint motion a controller's ``movej`` makes. The spray strokes' ``movel`` follows a
straight TCP line instead; between waypoints a few millimetres apart the two differ by far less than the
step, and the step bound is not claimed for it.
"""

from __future__ import annotations

import math

import numpy as np


def motion_bound_mm(q_a, q_b, reach_radii_mm: np.ndarray) -> np.ndarray:
    """(n,) float, mm: the bound on any body point's displacement between nine-axis joint vectors.

    Parameters
    ----------
    q_a, q_b : (9,) or (n, 9) float
        q1..q6 rad, tx, ty, tz mm.
    reach_radii_mm : (6,) float
        ``R_i`` of the arm's joints (:func:`~sprayplan.collision.bodies.reach_radii_mm`).
    """
    dq = np.atleast_2d(np.asarray(q_b, dtype=float) - np.asarray(q_a, dtype=float))
    return np.abs(dq[:, :6]) @ np.asarray(reach_radii_mm, dtype=float) + np.linalg.norm(dq[:, 6:9], axis=1)


def motion_checks(q_a, q_b, reach_radii_mm: np.ndarray, step_mm: float) -> np.ndarray:
    """(k + 1, 9): the joint vectors at which the motion from ``q_a`` to ``q_b`` is checked, both ends
    included, ``k = max(1, ceil(bound / step_mm))`` equal steps apart (see the module docstring)."""
    q_a, q_b = np.asarray(q_a, dtype=float), np.asarray(q_b, dtype=float)
    bound = float(motion_bound_mm(q_a, q_b, reach_radii_mm)[0])
    k = max(1, math.ceil(bound / step_mm - 1e-12))
    s = np.linspace(0.0, 1.0, k + 1)[:, None]
    return q_a + s * (q_b - q_a)
