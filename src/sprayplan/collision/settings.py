"""Settings of the collision checks (``[collision]``; not yet a section of ``JobConfig``)."""

from __future__ import annotations

from dataclasses import dataclass

from sprayplan.config import Section, _at_least, _fail


@dataclass(frozen=True)
class CollisionConfig(Section):
    """How the cell's bodies are sized and how close they may come (``[collision]``).

    Attributes
    ----------
    clearance_mm : float
        The smallest gap allowed between the part and any link, the gun body, the carriage or the column
        (the spray cone in front of the nozzle is free space and never counts).
    floor_offset_mm : float
        The floor (a half-space) lies this far below the part's lowest point, when ``floor_z_mm`` is None.
    floor_z_mm : float or None
        The floor's height in the part frame, mm; must not be above the part's lowest point.
    gun_radius_mm : float
        The radius of the gun's capsule, from the flange to the nozzle.
    motion_step_mm : float
        Between two waypoints, the motion is checked at joint configurations no body point moves more than
        this between (see :mod:`sprayplan.collision.motion`); at most twice the clearance, so that no contact
        with the part between two checks can be missed.
    """

    SECTION = "collision"
    clearance_mm: float = 30.0
    floor_offset_mm: float = 1.0
    floor_z_mm: float | None = None
    gun_radius_mm: float = 30.0
    motion_step_mm: float = 10.0

    def _check(self):
        _at_least(CollisionConfig, "clearance_mm", self.clearance_mm, 0)
        _at_least(CollisionConfig, "floor_offset_mm", self.floor_offset_mm, 0)
        _at_least(CollisionConfig, "gun_radius_mm", self.gun_radius_mm, 0, strict=True)
        _at_least(CollisionConfig, "motion_step_mm", self.motion_step_mm, 0, strict=True)
        if self.clearance_mm > 0 and self.motion_step_mm > 2 * self.clearance_mm:
            raise _fail(
                CollisionConfig,
                "motion_step_mm",
                f"at most twice collision.clearance_mm ({2 * self.clearance_mm:g})",
                self.motion_step_mm,
            )
