"""Point-to-point moves (transfers, station moves) time-optimal under the axes' limits, with ruckig.

A move starts and ends at rest. Ruckig's phase synchronisation makes every axis reach the target at the
same time on the straight line in joint space between the two joint vectors (the joint interpolation that the
robot programs' joint moves and the collision checks of motions assume), each axis within its speed and
acceleration limits (jerk unlimited: a second-order profile, as the strokes' toppra timing).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import ruckig

from sprayplan.timing.limits import AxisLimits


@dataclass(frozen=True)
class Move:
    """A point-to-point move.

    Attributes
    ----------
    duration_s : float
    trajectory : ruckig.Trajectory or None
        None for a move of no length.
    """

    duration_s: float
    trajectory: object = None

    def sample(self, times) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Positions, velocities and accelerations at times (k,) s: three (k, dof) arrays."""
        out = [self.trajectory.at_time(float(t)) for t in np.asarray(times, float)]
        return tuple(np.array([o[i] for o in out]) for i in range(3))


def point_to_point(start, target, limits: AxisLimits) -> Move:
    """The time-optimal rest-to-rest move from ``start`` to ``target`` (dof,) under ``limits``."""
    start = np.asarray(start, float)
    target = np.asarray(target, float)
    if np.abs(target - start).max(initial=0.0) < 1e-12:
        return Move(0.0)
    dof = len(start)
    otg = ruckig.Ruckig(dof)
    inp = ruckig.InputParameter(dof)
    inp.current_position = start.tolist()
    inp.current_velocity = [0.0] * dof
    inp.current_acceleration = [0.0] * dof
    inp.target_position = target.tolist()
    inp.target_velocity = [0.0] * dof
    inp.target_acceleration = [0.0] * dof
    inp.max_velocity = limits.velocity.tolist()
    inp.max_acceleration = limits.acceleration.tolist()
    inp.max_jerk = [np.inf] * dof
    inp.synchronization = ruckig.Synchronization.Phase
    trajectory = ruckig.Trajectory(dof)
    result = otg.calculate(inp, trajectory)
    if result not in (ruckig.Result.Working, ruckig.Result.Finished):
        raise RuntimeError(f"ruckig could not plan a move ({result})")
    return Move(float(trajectory.duration), trajectory)
