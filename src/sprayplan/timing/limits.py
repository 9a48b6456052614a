"""The speed and acceleration limits of the axes the timing stage drives."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sprayplan.errors import ConfigError
from sprayplan.robots.model import RobotModel, check_rate_limits


@dataclass(frozen=True)
class AxisLimits:
    """Speed and acceleration limits of each axis (rad/s and rad/s^2 on revolute axes, mm/s and mm/s^2 on
    linear ones).

    Attributes
    ----------
    velocity : (dof,) float
    acceleration : (dof,) float
    """

    velocity: np.ndarray
    acceleration: np.ndarray

    def __post_init__(self):
        n = len(np.asarray(self.velocity).reshape(-1))
        object.__setattr__(self, "velocity", check_rate_limits(self.velocity, "velocity limits", n))
        object.__setattr__(self, "acceleration", check_rate_limits(self.acceleration, "acceleration limits", n))

    @property
    def dof(self) -> int:
        return len(self.velocity)


def arm_limits(model: RobotModel, velocity_deg_s=None, acceleration_deg_s2=None) -> AxisLimits:
    """A robot model's joint limits, each overridden when given (deg/s, deg/s^2).

    Raises
    ------
    ConfigError
        The model has no limits and none are given (a robot TOML without ``max_velocity_deg_s``).
    """
    velocity = model.max_velocity if velocity_deg_s is None else np.radians(velocity_deg_s)
    acceleration = model.max_acceleration if acceleration_deg_s2 is None else np.radians(acceleration_deg_s2)
    for value, key in ((velocity, "max_velocity_deg_s"), (acceleration, "max_acceleration_deg_s2")):
        if value is None:
            raise ConfigError(f"robot {model.name} has no joint limits ({key}): timing needs them")
    return AxisLimits(velocity, acceleration)


def gantry_limits(model: RobotModel, timing, motion) -> AxisLimits:
    """The nine axes of the gantry robot (six arm joints, then x, y, z) from the job's ``[timing]`` and
    ``[motion]`` sections (``config.TimingConfig``, ``config.MotionConfig``)."""
    arm = arm_limits(model, timing.arm_max_velocity_deg_s, timing.arm_max_acceleration_deg_s2)
    if len(arm.velocity) != 6:
        raise ConfigError(f"robot {model.name} has {len(arm.velocity)} joints; the gantry carries a six-axis arm")
    gantry_v = timing.gantry_max_velocity_mm_s
    gantry_v = (motion.platform_speed_mm_s,) * 3 if gantry_v is None else gantry_v
    return AxisLimits(
        np.concatenate([arm.velocity, gantry_v]),
        np.concatenate([arm.acceleration, timing.gantry_max_acceleration_mm_s2]),
    )
